"""
The `sim` node itself.

:mod:`.node` (``SimNode``: its parts wired to one session, start and shutdown), :mod:`.main`
(``ros2 run sim node``: the executor, signals, the exit status; :mod:`.entry` runs before it
and its imports), :mod:`.status` (/diagnostics, the `paused` parameter and the core's log
lines, following the session's states), :mod:`.instances` (one simulator per name) and
:mod:`.middleware` (process settings made before rclpy starts, with ``fastdds_profiles.xml``).
Its parameters are declared from :mod:`sim_node.ros.settings`, which every room shares.
"""
