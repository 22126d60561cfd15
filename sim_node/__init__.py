"""
The `sim` ROS 2 node and its ROS-free MuJoCo core.

Layers, from the bottom up: :mod:`.core` (the MuJoCo world: models read from files, editing,
stepping, control law, devices; no ROS), :mod:`.session` (what is loaded now and its one
lifecycle) with :mod:`.listeners` (each listener's thread and mailbox), :mod:`.simulation` (a
small stepping API for scripts) and :mod:`.snapshot` (a PNG of a scene); the front-ends
:mod:`.gym` (Gymnasium environments), :mod:`.view` (a window, a browser view) and
:mod:`.record` (bags); and :mod:`.ros`, the rclpy node in rooms. :mod:`.client`,
:mod:`.qos` and :mod:`.gym_env` are older import paths kept for existing scripts.
"""
