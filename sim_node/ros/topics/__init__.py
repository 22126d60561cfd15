"""
What the node publishes.

What the node publishes: :mod:`.publishing` (/tf, /tf_static, markers, joint_states and /clock
from the loop's snapshots, on threads of their own), :mod:`.perception` (cameras, laser scans,
IMUs and MuJoCo sensors as ROS messages, on its thread), :mod:`.scans` (the lasers' publishers
and scans, cast from the poses the loop took at their due times), :mod:`.contacts` (contact
reports as Gazebo's contact sensor sends them), :mod:`.odometers` (P3D plugins' ground truth as
odometry), :mod:`.geo` (magnetometers and NavSat receivers), :mod:`.descriptions`
(``<entity>/robot_description`` for RViz and MoveIt), :mod:`.rviz_config` (RViz
configurations) and :mod:`.recording` (the ``record`` parameter: what goes out, written into
rosbag2 bags).
"""
