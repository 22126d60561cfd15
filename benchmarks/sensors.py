"""
A mobile manipulator's declared sensors: their rates kept, and what they cost.

``make bench-sensors`` (about a minute). The robot (written here, as a description package has
it) declares two lasers (541 rays over 270 degrees at 15 Hz), an IMU at 250 Hz and an RGB-D
camera (640 x 480 at 15 Hz). A node on the default scene spawns it:

* at real_time_factor 1, each sensor's messages per simulated second, from their stamps (the
  IMU's samples come in bursts; the camera is drawn by the CPU here);
* at real_time_factor 0, steps per second with the robot's sensors, over the same robot
  spawned without its sensor tags, side by side. Sensors keep their rates in simulated time:
  as fast as the physics goes, that is 250 IMU messages and 30 scans per simulated second
  (some 35,000 messages per wall second at 140 simulated seconds each), and that is what
  the ratio measures.

Verdicts (issue 43): the lasers and the IMU keep their declared rates (within 5%).
``BENCH_NODE_PARAMS='cameras:=[none]'`` passes parameters to the node (here: no camera).
"""

import os
from pathlib import Path
import random
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'benchmarks'))
from clocked_node import ClockedNode  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(120, 200)))
SECONDS = 8.0
TARGET = 0.95
_I = '<inertia ixx="0.05" iyy="0.05" izz="0.05" ixy="0" ixz="0" iyz="0"/>'


def _laser(name: str, yaw: float) -> str:
    return f"""<gazebo reference="{name}_link"><sensor type="ray" name="{name}">
      <update_rate>15</update_rate><ray><scan><horizontal><samples>541</samples>
      <min_angle>-2.356</min_angle><max_angle>2.356</max_angle></horizontal></scan>
      <range><min>0.05</min><max>25</max></range></ray>
      <plugin name="{name}" filename="libgazebo_ros_ray_sensor.so">
      <ros><remapping>~/out:={name}/scan</remapping></ros>
      <frame_name>{name}_link</frame_name></plugin></sensor></gazebo>"""


def robot(sensors: bool) -> str:
    """Return the mobile manipulator's URDF, with or without its sensor tags."""
    links = ''.join(
        f'<link name="{n}_link"><inertial><mass value="0.2"/>{_I}</inertial></link>'
        f'<joint name="{n}_joint" type="fixed"><parent link="base_link"/>'
        f'<child link="{n}_link"/><origin xyz="{x} 0 0.2" rpy="0 0 {yaw}"/></joint>'
        for n, x, yaw in (('front_laser', 0.3, 0), ('rear_laser', -0.3, 3.1416),
                          ('imu', 0, 0), ('head_camera', 0.2, 0)))
    tags = ''
    if sensors:
        tags = (_laser('front_laser', 0) + _laser('rear_laser', 3.1416) + """
      <gazebo reference="imu_link"><sensor type="imu" name="imu"><update_rate>250</update_rate>
        <plugin name="imu" filename="libgazebo_ros_imu_sensor.so">
        <ros><remapping>~/out:=imu/data</remapping></ros></plugin></sensor></gazebo>
      <gazebo reference="head_camera_link"><sensor type="depth" name="head_camera">
        <update_rate>15</update_rate><camera><horizontal_fov>1.05</horizontal_fov>
        <image><width>640</width><height>480</height></image></camera>
        <plugin name="head_camera" filename="libgazebo_ros_camera.so">
        <camera_name>head_camera</camera_name></plugin></sensor></gazebo>""")
    return (f'<robot name="mm"><link name="world"/><link name="base_link"><inertial>'
            f'<mass value="30"/>{_I}</inertial><collision><geometry><box size="0.6 0.5 0.3"/>'
            f'</geometry></collision></link><joint name="anchor" type="fixed">'
            f'<parent link="world"/><child link="base_link"/></joint>{links}{tags}</robot>')


class Node(ClockedNode):
    """A node on the default scene, the robot spawned, its sensors' stamps recorded."""

    TOPICS = {'front laser': ('/front_laser/scan', 'LaserScan', 15.0),
              'rear laser': ('/rear_laser/scan', 'LaserScan', 15.0),
              'IMU': ('/imu/data', 'Imu', 250.0),
              'camera': ('/head_camera/image_raw', 'Image', 15.0)}

    def __init__(self, rtf: float, sensors: bool):
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Image, Imu, LaserScan
        super().__init__('scene:=default', f'real_time_factor:={rtf}',
                         *os.environ.get('BENCH_NODE_PARAMS', '').split())
        self.stamps = {k: [] for k in self.TOPICS}
        types = {'LaserScan': LaserScan, 'Imu': Imu, 'Image': Image}
        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.BEST_EFFORT)
        for key, (topic, kind, _) in self.TOPICS.items():
            self.node.create_subscription(types[kind], topic, lambda m, k=key: self.stamps[
                k].append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9), qos)
        self.start()
        from sim_node.ros.client import SimClient
        self.sim = SimClient(timeout_sec=60)
        self.sim.spawn('mm', resource_string=robot(sensors), position=(3.0, 3.0, 0.2))
        time.sleep(2.0)

    def close(self) -> None:
        self.sim.close()
        super().close()


def main() -> int:
    print(f'[sensors] a mobile manipulator with two lasers, an IMU and an RGB-D camera; '
          f'{os.cpu_count()} cores')
    node = Node(1.0, sensors=True)
    try:
        for k in node.stamps:
            node.stamps[k].clear()
        rtf = node.rate(SECONDS)
        print(f'real_time_factor 1 asked, {rtf:.2f} held with every sensor on')
        achieved = {}
        for key, (topic, _, want) in Node.TOPICS.items():
            got = sorted(set(node.stamps[key]))
            rate = (len(got) - 1) / (got[-1] - got[0]) if len(got) > 2 else 0.0
            achieved[key] = (rate, want)
            print(f'{key:12s} {topic:26s} {rate:7.1f} per simulated second of {want:g}')
    finally:
        node.close()
    runs = {}
    for sensors in (False, True):
        node = Node(0.0, sensors=sensors)
        try:
            runs[sensors] = node.rate(SECONDS) / 0.002
        finally:
            node.close()
    print(f'steps per second at real_time_factor 0: without sensors {runs[False]:.0f}, with '
          f'them {runs[True]:.0f} ({runs[True] / runs[False]:.2f}x)')
    for key in ('front laser', 'rear laser', 'IMU'):
        rate, want = achieved[key]
        verdict(rate >= TARGET * want, f'{key} at {rate:.1f} of its declared {want:g} per '
                f'simulated second (target >= {TARGET * want:g})')
    summary()
    return 0


if __name__ == '__main__':
    sys.exit(main())
