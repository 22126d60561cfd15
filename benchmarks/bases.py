"""
Mobile bases: what driving a base and publishing its odometry costs the loop.

A node on the mobile scene at real_time_factor 0 (as fast as it goes): simulated seconds per
wall second from /clock with the scene idle; while the rover drives in circles with its wheel
speeds sent as joint_commands (no base controller); and while both of its bases (the rover,
in circles, and the omni, sideways and turning) are driven by cmd_vel at 20 Hz (base
controllers, their tracking loops, odometry and the odom TF at 50 Hz, the laser). All over
bare ``mj_step`` of the same scene file in this process, its actuators given the same
speeds, and bare MuJoCo also casting the rover's laser at its rate of simulated time; each
bare figure is the mean of one measurement just before that node starts and one just after it
ends (no node running then), so a machine whose speed drifts over the run's minutes (steal
time on a shared host) drifts both sides of a ratio alike, and the drift is printed. Then
the parts one at a time (issue 52): the same drive with the laser off, with ``record``
(every topic but images into a bag), and with both; the scans in that bag per simulated second
(none left out to keep the speed); and at real_time_factor 1 the odometry
rate held (messages per wall second over the 50 asked). Verdicts: the node with both
bases driven over bare MuJoCo with both driven >= 0.95 (issue 44), and the same with recording
on (issue 52); the node idle over bare MuJoCo idle is printed too.

    make bench-bases
"""

import os
from pathlib import Path
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'benchmarks'))
from clocked_node import ClockedNode  # noqa: E402, I100
from verdict import verdict  # noqa: E402

TARGET_RATIO = 0.95  # driven over idle, steps per second
TARGET_SCANS = 0.99  # scans in the recording per simulated second, over LASER_HZ
TARGET_ODOM = 0.9  # odometry messages per second over odom_rate_hz, at real_time_factor 1
SECONDS = 6.0
BARE_SECONDS = 2.0  # each measurement of bare MuJoCo: one just before a node, one just after
WHEELS = ((0.3 - 0.6 * 0.18) / 0.06, (0.3 + 0.6 * 0.18) / 0.06)  # rad/s, left and right
OMNI = (0.0, 0.1, 0.5)  # the omni base: sideways, turning (a circle: never meets a wall)
LASER_HZ = 10.0  # the node's lidar_rate_hz: scans per simulated second
NO_LASER = 'lidar_sites:=[none]'


def bare_steps_per_second(scene: Path, driven: bool = True, laser: bool = False,
                          seconds: float = BARE_SECONDS) -> float:
    """
    Return the steps per second of bare ``mj_step`` on the scene, its bases driven as asked.

    Driven: the wheel and omni actuators get the speeds the node's bases are commanded.

    `laser`: also cast the rover's laser as the node does, at its rate of simulated time
    (lidar_rate_hz 10, 360 rays over a turn, 10 m), from where it is at each due step.
    """
    import mujoco
    import numpy as np
    m = mujoco.MjModel.from_xml_path(str(scene))
    d = mujoco.MjData(m)
    if driven:
        d.ctrl[m.actuator('left_wheel_motor').id] = WHEELS[0]
        d.ctrl[m.actuator('right_wheel_motor').id] = WHEELS[1]
        d.ctrl[m.actuator('omni_y_motor').id] = OMNI[1]
        d.ctrl[m.actuator('omni_yaw_motor').id] = OMNI[2]
    site = m.site('rover_lidar').id
    angles = np.linspace(-np.pi, np.pi, 360)
    rays = np.stack([np.cos(angles), np.sin(angles), np.zeros(360)], axis=1)
    dist, geom = np.empty(360), np.empty(360, dtype=np.int32)
    every = round(1.0 / LASER_HZ / m.opt.timestep)  # steps between two scans
    mujoco.mj_step(m, d, 200)
    t0, n = time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds:
        if laser:
            mujoco.mj_step(m, d, every)
            mujoco.mj_kinematics(m, d)
            vec = (rays @ d.site_xmat[site].reshape(3, 3).T).reshape(-1)
            mujoco.mj_multiRay(m, d, d.site_xpos[site].copy(), vec, None, 1,
                               int(m.site_bodyid[site]), geom, dist, None, 360, 10.0)
            n += every
        else:
            mujoco.mj_step(m, d, 500)
            n += 500
    return n / (time.perf_counter() - t0)


def recorded_scans(bag: Path) -> tuple:
    """
    Return (scans, simulated seconds) of the rover's laser in a closed bag.

    The bag's messages are stamped with simulated time; its duration is theirs. A node that
    left scans out to keep its speed would show fewer than its rate here.
    """
    import yaml
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    counts = {t['topic_metadata']['name']: t['message_count']
              for t in info['topics_with_message_count']}
    return counts.get('/lasers/rover_lidar/scan', 0), info['duration']['nanoseconds'] / 1e9


class Node(ClockedNode):
    """A node on the mobile scene, and a client that drives its rover."""

    def __init__(self, rtf: float, *params: str):
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import JointState
        # cmd_vel_timeout 0: at real_time_factor 0 a command every 50 ms of wall time is seconds
        # of simulated time apart, and the bases would stand still between them
        super().__init__('scene:=mobile', f'real_time_factor:={rtf}', 'cameras:=[none]',
                         'cmd_vel_timeout:=0.0', *params)
        self.odom = []
        self.node.create_subscription(Odometry, 'rover/odom',
                                      lambda m: self.odom.append(time.perf_counter()), 100)
        self.pub = self.node.create_publisher(Twist, 'rover/cmd_vel', 10)
        self.twist = Twist()
        self.twist.linear.x, self.twist.angular.z = 0.3, 0.6  # circles: never meets a wall
        self.omni_pub = self.node.create_publisher(Twist, 'omni/cmd_vel', 10)
        self.omni = Twist()
        self.omni.linear.y, self.omni.angular.z = OMNI[1], OMNI[2]
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
                self.omni_pub.publish(self.omni)
            else:
                self.joints_pub.publish(self.joints)
            self._last = time.perf_counter()


def main() -> int:
    import rclpy
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(50 + os.getpid() % 50))
    sys.setswitchinterval(0.001)
    scene = ROOT / 'scenes' / 'mobile.xml'
    print(f'[bases] the mobile scene; {os.cpu_count()} cores; bare MuJoCo measured just before '
          f'and just after each node runs')
    drifts = []

    def around(run, *flavours):
        """
        Return run()'s result and bare MuJoCo's steps/s per flavour (kwargs), mean of two.

        Bare MuJoCo is measured just before the node starts and just after it ends, with no
        node running: on a shared machine the cores' speed drifts over a minute (steal time),
        and a ratio against a figure taken a minute away measures the drift as much as the node.
        """
        before = [bare_steps_per_second(scene, **f) for f in flavours]
        result = run()
        after = [bare_steps_per_second(scene, **f) for f in flavours]
        drifts.extend(b / a for a, b in zip(before, after))
        return result, [(a + b) / 2 for a, b in zip(before, after)]

    def first():
        node = Node(0.0)
        try:
            time.sleep(1.0)
            idle = node.rate(SECONDS)
            node.mode = 'joints'
            time.sleep(1.0)
            plain = node.rate(SECONDS)
            node.mode = 'cmd_vel'
            time.sleep(1.0)
            driven = node.rate(SECONDS)
            node.mode = ''
        finally:
            node.close()
        return idle, plain, driven

    (idle, plain, driven), (bare_idle, bare, bare_laser) = around(
        first, {'driven': False}, {}, {'laser': True})
    # The parts one at a time: the laser off, recording on (every topic but images).
    with tempfile.TemporaryDirectory(prefix='sim_bench_bases_') as tmp:
        runs = {}
        for label, params in (('no laser', (NO_LASER,)),
                              ('recording', (f'record:={Path(tmp) / "a"}',)),
                              ('recording, no laser', (f'record:={Path(tmp) / "b"}', NO_LASER))):
            def one(params=params):
                node = Node(0.0, *params)
                try:
                    node.mode = 'cmd_vel'
                    time.sleep(1.0)
                    return node.rate(SECONDS)
                finally:
                    node.close()
            rate, (its_bare,) = around(one, {})
            runs[label] = (rate, its_bare)
        written = sum(f.stat().st_size for f in (Path(tmp) / 'a').rglob('*') if f.is_file())
        scans, span = recorded_scans(Path(tmp) / 'a')
    timestep = 0.002
    print(f'bare mj_step, idle                         {bare_idle:10.0f} steps/s')
    print(f'bare mj_step, both bases driven            {bare:10.0f} steps/s')
    print(f'bare mj_step, driven, the laser cast too   {bare_laser:10.0f} steps/s  '
          f'({bare_laser / bare:.2f}x bare driven)')
    print(f'node, idle                                 {idle / timestep:10.0f} steps/s  '
          f'({idle / timestep / bare_idle:.2f}x bare idle)')
    print(f'node, rover wheel speeds on joint_commands {plain / timestep:10.0f} steps/s  '
          f'({plain / timestep / bare:.2f}x bare)')
    print(f'node, both bases on cmd_vel, odometry      {driven / timestep:10.0f} steps/s  '
          f'({driven / timestep / bare:.2f}x bare, {driven / timestep / bare_laser:.2f}x bare '
          f'with the laser)')
    for label, (rate, its_bare) in runs.items():
        print(f'node, both bases on cmd_vel, {label:20s}  {rate / timestep:10.0f} steps/s  '
              f'({rate / timestep / its_bare:.2f}x bare, {its_bare:.0f} around it)'
              + (f'; {written / 1e6:.1f} MB written' if label == 'recording' else ''))
    print(f'scans in the recording: {scans} over {span:.0f} simulated seconds, '
          f'{scans / span:.2f} per simulated second ({LASER_HZ:g} asked)')
    print(f'bare MuJoCo after a node over before it: {min(drifts):.2f}-{max(drifts):.2f} '
          "(the machine's drift within a measurement)")
    rate, its_bare = runs['recording']
    recorded = rate / timestep / its_bare  # over bare MuJoCo measured around its own node
    verdict(driven / timestep / bare >= TARGET_RATIO, f'steps per second with both bases '
            f'driven over bare MuJoCo on the scene file {driven / timestep / bare:.2f} '
            f'(target >= {TARGET_RATIO})')
    verdict(recorded >= TARGET_RATIO, f'the same with recording on '
            f'{recorded:.2f} (target >= {TARGET_RATIO})')
    verdict(scans / span >= TARGET_SCANS * LASER_HZ, f'every scan made at full speed: '
            f'{scans / span:.2f} per simulated second in the bag (target >= '
            f'{TARGET_SCANS * LASER_HZ:g})')
    # Idle and driven are different physics (moving contacts cost MuJoCo too): the node idle
    # is compared with bare MuJoCo idle, for information (issue 44's target is driven).
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
