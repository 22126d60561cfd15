"""
The ROS skin: the rclpy node and everything else that imports rclpy or a message package.

Rooms by job, each with a map of its own: :mod:`.node` (the `sim` node itself: wiring,
parameters, start and shutdown, /diagnostics, the middleware's settings), :mod:`.services`
(simulation_interfaces' services and the simulate_steps action), :mod:`.topics` (what the node
publishes: /tf, joint_states, /clock, sensors, contacts, robot descriptions, bags),
:mod:`.commands` (the node's own command inputs: joint_commands, trajectories, mobile bases'
cmd_vel), :mod:`.control` (ros2_control on the wire: a controller manager per robot and the
ROS side of its controllers) and :mod:`.client` (what talks to a running node: the Python
client and the ``spawn`` tool); below them all, :mod:`.settings` (the node's parameters as one
table, and the services' quality of service). Nothing here does physics: every room converts,
calls the core or the session, and converts back.
"""
