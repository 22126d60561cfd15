"""Pure conversions between core values and ROS messages."""
