"""
Pure conversions between core values and ROS messages.

:mod:`.convert` (states, poses, stamps, the simulation state and entities), :mod:`.cdr`
(messages written straight to their wire form, for the big ones), :mod:`.tf_stream` (/tf of
successive snapshots, never a frame twice with one stamp), :mod:`.markers` (RViz markers per
geom), :mod:`.perception` (images, scans, points, IMU and wrench readings), :mod:`.contacts`
(Gazebo's contact reports), :mod:`.odometry` (a base's odometry and its TF) and
:mod:`.diagnostics` (the session's state and the loop's rate as /diagnostics). None imports
``rclpy.node``.
"""
