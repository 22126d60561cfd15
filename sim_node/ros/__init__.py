"""The ROS skin: the rclpy node and everything else that imports rclpy or a message package."""
