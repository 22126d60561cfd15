"""
An SDF world's sensors over the wire (issue 54, item 3), on the topics gz-sim gives them.

A probe 2.9 m from a wall carries a lidar (0.15 m ahead of its link, 0.1 m up), an IMU, a
magnetometer, a NavSat receiver and a camera; a crate on the ground a contact sensor; a
weight hangs from an arm's joint with a force-torque sensor. Each is read where a ros_gz_bridge
user would bridge it (gz-sim's default topics, ``src/systems/sensors``' names) and checked
against the scene: the wall's distance, gravity, the world's field, its spherical
coordinates, the weight's m g.
"""

import math

from conftest import heard, serve_node, wait_for, Watcher
import pytest

LAT, LON, ELEVATION = -22.9, -43.2, 12.0
FIELD = (6e-06, 2.3e-05, -4.2e-05)
G, WEIGHT = 9.81, 2.0
BASE = '/world/sensors/model'
_I = '<inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia>'


def box(size: str) -> str:
    return f'<geometry><box><size>{size}</size></box></geometry>'


PROBE = f"""<model name="probe"><static>true</static><pose>0 0 0.5 0 0 0</pose>
  <link name="body"><inertial><mass>1</mass>{_I}</inertial>
    <visual name="v">{box("0.1 0.1 0.1")}</visual>
    <sensor name="lidar" type="gpu_lidar"><pose>0.15 0 0.1 0 0 0</pose>
      <update_rate>10</update_rate><lidar><scan><horizontal><samples>91</samples>
      <min_angle>-0.5</min_angle><max_angle>0.5</max_angle></horizontal></scan>
      <range><min>0.1</min><max>10</max></range></lidar></sensor>
    <sensor name="imu" type="imu"><topic>/probe/imu</topic><update_rate>100</update_rate>
    </sensor>
    <sensor name="mag" type="magnetometer"><update_rate>20</update_rate></sensor>
    <sensor name="gps" type="navsat"><update_rate>10</update_rate></sensor>
    <sensor name="cam" type="camera"><update_rate>5</update_rate><camera><image>
      <width>64</width><height>48</height></image></camera></sensor>
  </link></model>"""

WORLD = f"""<?xml version="1.0"?><sdf version="1.9"><world name="sensors">
  <physics name="p" type="ignored"><max_step_size>0.002</max_step_size></physics>
  <gravity>0 0 -{G}</gravity><magnetic_field>{" ".join(map(str, FIELD))}</magnetic_field>
  <spherical_coordinates><surface_model>EARTH_WGS84</surface_model>
    <world_frame_orientation>ENU</world_frame_orientation><latitude_deg>{LAT}</latitude_deg>
    <longitude_deg>{LON}</longitude_deg><elevation>{ELEVATION}</elevation>
    <heading_deg>0</heading_deg></spherical_coordinates>
  <include><uri>model://ground_plane</uri></include>
  <model name="wall"><static>true</static><pose>3 0 1 0 0 0</pose><link name="l">
    <collision name="c">{box("0.2 4 2")}</collision><visual name="v">{box("0.2 4 2")}</visual>
  </link></model>
  {PROBE}
  <model name="crate"><pose>0 3 0.1 0 0 0</pose><link name="l"><inertial><mass>1</mass>{_I}
    </inertial><collision name="c">{box("0.2 0.2 0.2")}</collision>
    <sensor name="bump" type="contact"><update_rate>20</update_rate>
      <contact><collision>c</collision></contact></sensor></link></model>
  <model name="arm"><pose>0 -3 0 0 0 0</pose>
    <link name="base"><pose>0 0 1.5 0 0 0</pose><inertial><mass>1</mass>{_I}</inertial>
    </link>
    <link name="weight"><pose>0 0 1.0 0 0 0</pose><inertial><mass>{WEIGHT}</mass>{_I}
    </inertial></link>
    <joint name="fix" type="fixed"><parent>world</parent><child>base</child></joint>
    <joint name="hang" type="revolute"><pose>0 0 0.5 0 0 0</pose><parent>base</parent>
      <child>weight</child><axis><xyz>1 0 0</xyz></axis>
      <sensor name="ft" type="force_torque"><update_rate>50</update_rate></sensor></joint>
  </model></world></sdf>"""


@pytest.fixture(scope='module')
def node(tmp_path_factory):
    folder = tmp_path_factory.mktemp('sdf_sensors')
    (folder / 'sensors.sdf').write_text(WORLD)
    yield from serve_node(f'scene:={folder / "sensors.sdf"}')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


def seconds(stamp) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def test_the_lidar_sees_the_wall_from_where_it_is_in_a_frame_of_its_own(watch):
    from sensor_msgs.msg import LaserScan
    from tf2_msgs.msg import TFMessage
    scan = heard(watch, LaserScan, f'{BASE}/probe/link/body/sensor/lidar/scan')[-1]
    assert scan.header.frame_id == 'probe/body/lidar' and len(scan.ranges) == 91
    ahead = round((0.0 - scan.angle_min) / scan.angle_increment)
    assert scan.ranges[ahead] == pytest.approx(2.9 - 0.15, abs=0.01)  # from the sensor
    from rclpy.qos import DurabilityPolicy, QoSProfile
    static = []
    sub = watch.node.create_subscription(
        TFMessage, '/tf_static', static.append,
        QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    try:
        wait_for(lambda: static, timeout=20)
    finally:
        watch.node.destroy_subscription(sub)
    frames = {t.child_frame_id: t for m in static for t in m.transforms}
    lidar = frames['probe/body/lidar']
    assert lidar.header.frame_id == 'probe'  # the link's frame (the entity's root)
    t = lidar.transform.translation
    assert (t.x, t.y, t.z) == pytest.approx((0.15, 0.0, 0.1), abs=1e-9)
    assert 'probe/body/imu' in frames and 'probe/body/gps' in frames


def test_the_imu_samples_gravity_at_its_rate_in_simulated_time(watch):
    from sensor_msgs.msg import Imu
    got = heard(watch, Imu, '/probe/imu', n=150)
    assert got[-1].header.frame_id == 'probe/body/imu'
    assert got[-1].linear_acceleration.z == pytest.approx(G, abs=0.05)
    stamps = sorted(seconds(m.header.stamp) for m in got)
    span = stamps[-1] - stamps[0]
    assert (len(stamps) - 1) / span == pytest.approx(100.0, rel=0.05)


def test_the_magnetometer_reads_the_worlds_field(watch):
    from sensor_msgs.msg import MagneticField
    msg = heard(watch, MagneticField, f'{BASE}/probe/link/body/sensor/mag/magnetometer')[-1]
    f = msg.magnetic_field
    assert (f.x, f.y, f.z) == pytest.approx(FIELD, abs=1e-12)
    assert msg.header.frame_id == 'probe/body/mag'


def test_the_navsat_is_at_the_worlds_coordinates(watch):
    from sensor_msgs.msg import NavSatFix
    fix = heard(watch, NavSatFix, f'{BASE}/probe/link/body/sensor/gps/navsat')[-1]
    assert (fix.latitude, fix.longitude) == pytest.approx((LAT, LON), abs=1e-9)
    assert fix.altitude == pytest.approx(ELEVATION + 0.5, abs=1e-6)  # the probe is 0.5 m up
    assert fix.status.status == fix.status.STATUS_FIX


def test_the_camera_sends_its_images_and_info_on_gz_sims_topics(watch):
    from sensor_msgs.msg import CameraInfo, Image
    image = heard(watch, Image, f'{BASE}/probe/link/body/sensor/cam/image', n=1)[-1]
    assert (image.width, image.height) == (64, 48)
    info = heard(watch, CameraInfo, f'{BASE}/probe/link/body/sensor/cam/camera_info', n=1)[-1]
    assert (info.width, info.height) == (64, 48)
    assert info.header.frame_id == image.header.frame_id


def test_the_crates_contact_sensor_reports_the_ground(watch):
    from ros_gz_interfaces.msg import Contacts
    msgs = heard(watch, Contacts, f'{BASE}/crate/link/l/sensor/bump/contact', n=3)
    assert any(c for m in msgs for c in m.contacts)
    names = {(c.collision1.name, c.collision2.name) for m in msgs for c in m.contacts}
    assert any('crate' in a and 'ground_plane' in b for a, b in names), names


def test_the_joints_force_torque_sensor_holds_the_weight(watch):
    from geometry_msgs.msg import WrenchStamped
    msg = heard(watch, WrenchStamped, f'{BASE}/arm/joint/hang/sensor/ft/forcetorque')[-1]
    f = msg.wrench.force
    assert math.sqrt(f.x ** 2 + f.y ** 2 + f.z ** 2) == pytest.approx(WEIGHT * G, rel=0.01)
