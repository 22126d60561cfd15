"""The ROS-free MuJoCo world: no rclpy or message imports here."""
