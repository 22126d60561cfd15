"""
Just enough of ROS 2's ``launch`` to run this project's launch files where it is not installed.

``test/launch_shim/run.py`` loads a launch file with these, expands it for the arguments
given and starts its nodes as processes (see there).
"""


class LaunchDescription:
    """What a launch file returns: its entities."""

    def __init__(self, entities):
        self.entities = list(entities)
