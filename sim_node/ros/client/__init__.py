"""
What talks to a running node.

What talks to a running node: :mod:`.sim_client` (``SimClient``, a small Python client of the
node's services for scripts and tests) and :mod:`.spawn` (``ros2 run sim spawn``, as Gazebo's
``create``).

``from sim_node.ros.client import SimClient`` keeps working: the client's public names are
re-exported here.
"""

from .sim_client import SimClient, SimServiceError  # noqa: F401 (the public path)
