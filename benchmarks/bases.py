"""
Mobile bases: what driving a base and publishing its odometry costs the loop.

A node on the mobile scene at real_time_factor 0 (as fast as it goes): simulated seconds per
wall second from /clock while the rover drives in circles, first with its wheel speeds sent as
joint_commands (no base controller), then the same motion sent as cmd_vel at 20 Hz (the base
controller, odometry and the odom TF at 50 Hz); both over bare ``mj_step`` of the same scene
in this process, measured side by side. Then at real_time_factor 1: the odometry rate
held (messages per wall second over the 50 asked).

    make bench-bases
"""

import os
from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'benchmarks'))
from clocked_node import ClockedNode  # noqa: E402, I100
from verdict import verdict  # noqa: E402

TARGET_RATIO = 0.95  # driven over idle, steps per second
TARGET_ODOM = 0.9  # odometry messages per second over odom_rate_hz, at real_time_factor 1
SECONDS = 6.0
WHEELS = ((0.3 - 0.6 * 0.18) / 0.06, (0.3 + 0.6 * 0.18) / 0.06)  # rad/s, left and right


def bare_steps_per_second(scene: Path) -> float:
    import mujoco
    m = mujoco.MjModel.from_xml_path(str(scene))
    d = mujoco.MjData(m)
    d.ctrl[m.actuator('left_wheel_motor').id] = WHEELS[0]
    d.ctrl[m.actuator('right_wheel_motor').id] = WHEELS[1]
    mujoco.mj_step(m, d, 200)
    t0, n = time.perf_counter(), 0
    while time.perf_counter() - t0 < 3.0:
        mujoco.mj_step(m, d, 500)
        n += 500
    return n / (time.perf_counter() - t0)


class Node(ClockedNode):
    """A node on the mobile scene, and a client that drives its rover."""

    def __init__(self, rtf: float):
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import JointState
        super().__init__('scene:=mobile', f'real_time_factor:={rtf}', 'cameras:=[none]')
        self.odom = []
        self.node.create_subscription(Odometry, 'rover/odom',
                                      lambda m: self.odom.append(time.perf_counter()), 100)
        self.pub = self.node.create_publisher(Twist, 'rover/cmd_vel', 10)
        self.twist = Twist()
        self.twist.linear.x, self.twist.angular.z = 0.3, 0.6  # circles: never meets a wall
        # the same wheel speeds: (0.3 -+ 0.6 * 0.18) / 0.06 rad/s
        self.joints_pub = self.node.create_publisher(JointState, 'joint_commands', 10)
        self.joints = JointState(name=['left_wheel_joint', 'right_wheel_joint'],
                                 velocity=[WHEELS[0], WHEELS[1]])
        self.mode = ''  # 'joints', 'cmd_vel' or '' (idle)
        self._last = 0.0
        self.start()

    def tick(self) -> None:
        if self.mode and time.perf_counter() - self._last > 0.05:
            if self.mode == 'cmd_vel':
                self.pub.publish(self.twist)
            else:
                self.joints_pub.publish(self.joints)
            self._last = time.perf_counter()


def main() -> int:
    import rclpy
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(50 + os.getpid() % 50))
    sys.setswitchinterval(0.001)
    scene = ROOT / 'scenes' / 'mobile.xml'
    print(f'[bases] the mobile scene; {os.cpu_count()} cores')
    node = Node(0.0)
    try:
        node.mode = 'joints'
        time.sleep(1.0)
        plain = node.rate(SECONDS)
        node.mode = 'cmd_vel'
        time.sleep(1.0)
        driven = node.rate(SECONDS)
        node.mode = ''
    finally:
        node.close()
    timestep = 0.002
    bare = bare_steps_per_second(scene)
    print(f'bare mj_step, rover circling               {bare:10.0f} steps/s')
    print(f'node, wheel speeds on joint_commands       {plain / timestep:10.0f} steps/s  '
          f'({plain / timestep / bare:.2f}x bare)')
    print(f'node, cmd_vel: base controller, odometry   {driven / timestep:10.0f} steps/s  '
          f'({driven / timestep / bare:.2f}x bare)')
    verdict(driven / plain >= TARGET_RATIO, f'steps per second with the base controller over '
            f'without {driven / plain:.2f} (target >= {TARGET_RATIO})')
    node = Node(1.0)
    try:
        node.mode = 'cmd_vel'
        time.sleep(1.0)
        n0, t0 = len(node.odom), time.perf_counter()
        time.sleep(SECONDS)
        odom_rate = (len(node.odom) - n0) / (time.perf_counter() - t0)
    finally:
        node.close()
    rclpy.shutdown()
    verdict(odom_rate / 50.0 >= TARGET_ODOM, f'odometry at real_time_factor 1: '
            f'{odom_rate:.1f} messages/s of 50 asked (target >= {TARGET_ODOM * 50:.0f})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
