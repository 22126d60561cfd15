"""
A mobile base's odometry as nav2 reads it: nav_msgs/Odometry and the odom TF (pure: no rclpy).

The one Odometry builder: the node's own bases (``<entity>/odom``) and the base controllers
(diff_drive_controller's ``~/odom``, the steering controllers') both send :func:`message`;
a P3D plugin's ground truth is :func:`ground_truth`.

REP 105: ``<entity>/odom`` is where the base started (its pose then, turned about z only); the
odometry is the base's pose in it, twist in the base's own frame. The TF tree stays a tree: the
world -> odom transform absorbs what the odometry gets wrong (its drift), and odom -> the
entity's frame replaces the world -> entity transform /tf otherwise carries.
"""

from typing import Sequence

from nav_msgs.msg import Odometry
import numpy as np
from sim_node.core.base import quat
from sim_node.core.control.odometry import PlanarOdometry

from . import convert


def base_pose(odo: PlanarOdometry, start: tuple, position: np.ndarray,
              quat_wxyz: np.ndarray) -> tuple:
    """
    Return the base's pose in its odom frame: (position (3,), quaternion wxyz (4,)).

    x, y and yaw are the odometry's; height, roll and pitch the base's true ones (odometry on
    a plane has none), relative to `start` (position, yaw) where the odom frame is.
    """
    true_yaw = quat.yaw_of(quat_wxyz)
    tilt = quat.mul(quat.from_yaw(-true_yaw), quat_wxyz)  # roll and pitch only
    return (np.array([odo.x, odo.y, float(position[2]) - float(start[0][2])]),
            quat.mul(quat.from_yaw(odo.yaw), tilt))


def odom_frame_in_world(position: np.ndarray, quat_wxyz: np.ndarray, pos_odom: np.ndarray,
                        quat_odom: np.ndarray) -> tuple:
    """Return where the odom frame is in the world, so world -> odom -> base is the truth."""
    inv = quat.conj(quat_odom)
    q = quat.mul(quat_wxyz, inv)
    return position - quat.rotate(q, pos_odom), q


def message(odo: PlanarOdometry, stamp: float, frame: str, child: str, pos: np.ndarray,
            quat_wxyz: np.ndarray, pose_covariance: Sequence[float],
            twist_covariance: Sequence[float]) -> Odometry:
    """Return nav_msgs/Odometry: pose in `frame`, twist in `child` (covariance diagonals)."""
    msg = Odometry()
    msg.header.stamp = convert.stamp(stamp)
    msg.header.frame_id, msg.child_frame_id = frame, child
    msg.pose.pose = convert.pose_to_msg(pos, quat_wxyz)
    msg.twist.twist.linear.x, msg.twist.twist.linear.y = float(odo.vx), float(odo.vy)
    msg.twist.twist.angular.z = float(odo.wz)
    for k in range(6):
        msg.pose.covariance[7 * k] = float(pose_covariance[k])
        msg.twist.covariance[7 * k] = float(twist_covariance[k])
    return msg


def transforms(stamp: float, world: str, odom: str, base: str, odom_pos: np.ndarray,
               odom_quat: np.ndarray, pos: np.ndarray, quat_wxyz: np.ndarray) -> list:
    """Return world -> odom and odom -> base as TransformStamped."""
    t = convert.stamp(stamp)
    return [convert.transform(world, odom, odom_pos, odom_quat, t),
            convert.transform(odom, base, pos, quat_wxyz, t)]


def ground_truth(sample, frame: str, child: str, noise: float) -> Odometry:
    """
    Return a P3D plugin's sample as gazebo_ros_p3d sends it.

    The pose and the twist both in `frame` (the world's, or the plugin's reference link's:
    not the child's own, as the plugin has it); covariance diagonals of ``noise ** 2``.

    :param sample: a :class:`~sim_node.core.stepping.odometers.OdometerSample`.
    """
    msg = Odometry()
    msg.header.stamp = convert.stamp(sample.time)
    msg.header.frame_id, msg.child_frame_id = frame, child
    msg.pose.pose = convert.pose_to_msg(sample.position, sample.quat_wxyz)
    t = msg.twist.twist
    t.linear.x, t.linear.y, t.linear.z = (float(v) for v in sample.linear)
    t.angular.x, t.angular.y, t.angular.z = (float(v) for v in sample.angular)
    var = float(noise) ** 2
    for k in range(6):
        msg.pose.covariance[7 * k] = var
        msg.twist.covariance[7 * k] = var
    return msg
