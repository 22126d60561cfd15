"""
ros2_control on the wire.

ros2_control on the wire, as a robot made for Gazebo expects it: :mod:`.controller_manager`
(a ``controller_manager`` node per robot with its services, and where its controllers are run
on each joint sample), :mod:`.controllers` (the ROS side of each controller type: its node,
topics and what it publishes; the broadcasters of joints, forward commands and diff drive),
:mod:`.jtc` (joint_trajectory_controller), :mod:`.gripper` (gripper action controllers),
:mod:`.steering` (Ackermann, bicycle and tricycle), :mod:`.broadcasters` (IMU and
force-torque broadcasters), :mod:`.topic_hardware` (topic_based_ros2_control's topics, for a
controller manager run beside `sim`) and :mod:`.gz_systems` (the gz-sim systems of SDF
models: their topics, their laws run at the joint samples). The controllers' bookkeeping and
types are ROS-free, in :mod:`sim_node.core.control`.
"""
