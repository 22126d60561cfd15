"""The `sim` ROS 2 node and its ROS-free MuJoCo core."""
