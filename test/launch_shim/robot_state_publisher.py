"""
A stand-in for robot_state_publisher where ROS is not installed.

It publishes its ``robot_description`` parameter on ``robot_description`` as
robot_state_publisher does (std_msgs/String, reliable, transient local, depth 1), until stopped.
"""

import sys

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String


def main() -> None:
    rclpy.init(args=sys.argv)
    node = rclpy.create_node('robot_state_publisher')
    node.declare_parameter('robot_description', '')
    qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     reliability=ReliabilityPolicy.RELIABLE)
    pub = node.create_publisher(String, 'robot_description', qos)
    pub.publish(String(data=node.get_parameter('robot_description').value))
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass


if __name__ == '__main__':
    main()
