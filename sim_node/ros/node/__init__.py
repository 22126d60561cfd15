"""
The `sim` node itself.

The `sim` node itself: :mod:`.node` (``SimNode``: its parts wired to one session, start and
shutdown), :mod:`.main` (``ros2 run sim node``: the executor, signals, the exit status),
:mod:`.params` and :mod:`.parameter_table` (every parameter, declared from one table that
also writes docs/parameters.md), :mod:`.status` (/diagnostics, the `paused` parameter and the
core's log lines, following the session's states), :mod:`.instances` (one simulator per name),
:mod:`.middleware` (process settings made before rclpy starts, with ``fastdds_profiles.xml``)
and :mod:`.qos` (the services' quality of service, shared with clients).
"""
