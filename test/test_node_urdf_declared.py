"""
Sensors a URDF declares in its ``<gazebo>`` tags publish, checked against the scene.

The scout of ``test_core_urdf_declared`` is spawned fixed to the world, facing a crate 0.55 m
ahead of its laser: the scan's range ahead, the camera's calibration (its vertical field of
view from the tag's horizontal one) and the IMU's gravity.
"""

import math

from conftest import serve_node, wait_for, Watcher
import pytest
from sensor_msgs.msg import CameraInfo, Imu, LaserScan, PointCloud2
from test_core_declared_lasers import EYES, RANGER
from test_core_declared_wrench import HANGER, MASS, ROLL
from test_core_urdf_declared import SCOUT

BOX = ('<mujoco><worldbody><body name="crate"><geom type="box" size="0.25 0.25 0.25"/>'
       '</body></worldbody></mujoco>')


@pytest.fixture(scope='module')
def node():
    yield from serve_node('lidar_range_max:=5.0')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


def latest(watch, msg_type, topic: str, timeout: float = 20.0):
    from rclpy.qos import qos_profile_sensor_data
    got = []
    sub = watch.node.create_subscription(msg_type, topic, got.append, qos_profile_sensor_data)
    try:
        wait_for(lambda: len(got) >= 2, timeout=timeout)
    finally:
        watch.node.destroy_subscription(sub)
    return got[-1]


def test_the_declared_laser_camera_and_imu_publish_what_the_scene_shows(sim, watch):
    sim.spawn('scout', resource_string=SCOUT, position=(2.0, -2.0, 0.1))
    sim.spawn('crate', resource_string=BOX, position=(3.0, -2.0, 0.25))
    # the laser: on the mount (0.2 m ahead of the base), the crate's face at x = 2.75
    scan = latest(watch, LaserScan, 'lasers/scout/scan_lidar/scan')
    ahead = round((0.0 - scan.angle_min) / scan.angle_increment)
    assert scan.header.frame_id == 'scout/mount'  # the link it is on, as gazebo_ros names it
    assert scan.ranges[ahead] == pytest.approx(2.75 - 2.2, abs=0.01)
    # the camera: its vertical field of view from the tag's horizontal one (1.2 rad, 4:3)
    info = latest(watch, CameraInfo, 'cameras/scout/front_cam/camera_info')
    fovy = 2 * math.atan(math.tan(0.6) * 480 / 640)
    assert info.k[4] == pytest.approx(info.height / (2 * math.tan(fovy / 2)), rel=1e-6)
    # the IMU: at rest on a fixed robot, gravity up
    imu = latest(watch, Imu, 'sensors/scout/imu_imu/imu')
    assert imu.linear_acceleration.z == pytest.approx(9.81, abs=0.05)


def test_declared_lasers_publish_on_their_topics_frames_sizes_and_rates(sim, watch):
    """RANGER (``test_core_declared_lasers``): before, every laser was the node's own."""
    from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    sim.spawn('ranger', resource_string=RANGER, position=(-2.0, 2.0, 0.1))
    got = []
    sub = watch.node.create_subscription(LaserScan, '/ranger/scan', got.append,
                                         qos_profile_sensor_data)
    try:
        # a scan comes when its time is due and the perception thread (below the loop in
        # priority) gets to it: a late first one shortens the span by up to a period, so the
        # span is two simulated seconds, not one
        wait_for(lambda: len(got) >= 32, timeout=60)
    finally:
        watch.node.destroy_subscription(sub)
    scan = got[-1]
    assert scan.header.frame_id == 'ranger/base_front_laser_link'
    assert len(scan.ranges) == 541 and scan.angle_min == pytest.approx(-2.356194, abs=1e-6)
    assert (scan.range_min, scan.range_max) == pytest.approx((0.2, 12.0))
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in got[1:]]
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert rate == pytest.approx(15.0, rel=0.1)  # its 15 Hz, in simulated time
    cloud = latest(watch, PointCloud2, '/points3d')
    assert (cloud.header.frame_id, cloud.height, cloud.width) == ('ranger/lidar3d_link', 16,
                                                                  360)
    # the IMU: its topic and link frame, 250 samples per simulated second, each stamped
    imus = []
    sub = watch.node.create_subscription(Imu, '/ranger/imu', imus.append, QoSProfile(
        depth=100, reliability=ReliabilityPolicy.BEST_EFFORT))
    try:
        wait_for(lambda: len(imus) >= 200, timeout=30)
    finally:
        watch.node.destroy_subscription(sub)
    assert imus[-1].header.frame_id == 'ranger/base_link'
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in imus[1:]]
    assert (len(stamps) - 1) / (stamps[-1] - stamps[0]) == pytest.approx(250.0, rel=0.02)
    assert imus[-1].linear_acceleration.z == pytest.approx(9.81, abs=0.5)
    # the camera: its size, its optical frame link, its camera_name's topics, 7 Hz
    images = []
    sub = watch.node.create_subscription(CameraInfo, '/ranger/head_front_camera/camera_info',
                                         images.append, qos_profile_sensor_data)
    try:
        wait_for(lambda: len(images) >= 10, timeout=60)
    finally:
        watch.node.destroy_subscription(sub)
    info = images[-1]
    assert (info.width, info.height, info.header.frame_id) == (
        400, 300, 'ranger/head_cam_optical_frame')
    assert info.k[0] == pytest.approx(200 / math.tan(0.6), rel=1e-3)  # its hfov of 1.2 rad
    # 7 Hz of simulated time, drawn when the perception thread gets to it: each image is due
    # at a multiple of 1/7 s and drawn at the first snapshot from then on; one the renderer
    # is late for is stamped late, or left out (cores short: "fewer if the renderer cannot
    # keep up", the physics never waits), so gaps vary under load (0.10-0.14 s seen in a
    # full run) but no period holds two images, and at least half of the periods hold one.
    # The node's own 10 Hz would put two into some period of 1/7 s.
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in images[1:]]
    periods = [math.floor(t * 7.0 + 1e-6) for t in stamps]
    assert periods == sorted(set(periods)), stamps  # one image per period at most
    assert len(periods) >= 0.5 * (periods[-1] - periods[0] + 1), stamps
    junk = latest(watch, LaserScan, 'lasers/ranger/junk_lidar/scan')  # the node's own
    assert len(junk.ranges) == 360 and junk.header.frame_id == 'ranger/base_link'


def test_a_declared_depth_camera_sends_grey_images_clipped_depth_and_points(sim, watch):
    """EYES (``test_core_declared_lasers``): a crate 1.2 m ahead, the sky beyond its 2 m."""
    import numpy as np
    from sensor_msgs.msg import Image
    sim.spawn('eyes', resource_string=EYES, position=(0.0, -3.0, 0.0))
    sim.spawn('wall', resource_string=BOX, position=(1.45, -3.0, 0.5))  # its face at x = 1.2
    grey = latest(watch, Image, '/eyes/depth_cam/image_raw')
    assert (grey.encoding, grey.width, grey.height, grey.step) == ('mono8', 160, 120, 160)
    depth = latest(watch, Image, '/eyes/depth_cam/depth/image_raw')
    assert (depth.encoding, depth.width, depth.height) == ('32FC1', 160, 120)
    metres = np.frombuffer(bytes(depth.data), '<f4').reshape(120, 160)
    assert metres[60, 80] == pytest.approx(1.2, abs=0.01)  # the crate, straight ahead
    # the floor to the crate's left: 1.23 m ahead at the bottom row, 3 m (beyond its far
    # clip of 2 m: +inf, as REP 118 has it) nearer the horizon
    assert metres[119, 133] == pytest.approx(0.5 / math.tan(math.atan(59.5 / 146.4)), rel=0.02)
    assert np.isposinf(metres[84, 133])
    cloud = latest(watch, PointCloud2, '/eyes/depth_cam/points')
    assert cloud.width * cloud.height == 160 * 120


def test_a_declared_force_torque_sensor_reads_m_g_in_its_frame_and_direction(sim, watch):
    """HANGER (``test_core_declared_wrench``): before, a sensor on a joint published nothing."""
    from geometry_msgs.msg import WrenchStamped
    sim.spawn('hanger', resource_string=HANGER, position=(-3.0, -3.0, 1.0))
    weight = MASS * 9.81
    child = latest(watch, WrenchStamped, '/hanger/wrist_ft')  # SDF's defaults
    assert child.header.frame_id == 'hanger/tool'
    # the tool pulls its parent down, seen from the tool's frame (rolled by ROLL about x)
    f = child.wrench.force
    assert (f.x, f.y, f.z) == pytest.approx(
        (0.0, -weight * math.sin(ROLL), -weight * math.cos(ROLL)), abs=0.02 * weight)
    held = latest(watch, WrenchStamped, 'sensors/hanger/held_ft/wrench')
    assert held.header.frame_id == 'hanger/base'
    f = held.wrench.force  # the parent holds it up, in the parent's (upright) frame
    assert (f.x, f.y, f.z) == pytest.approx((0.0, 0.0, weight), abs=0.02 * weight)


def test_contacts_of_a_declared_sensor_and_of_an_entity_asked_for_arrive_as_gazebos(sim, watch):
    """CRATE (``test_core_contacts``): its bumper plugin's topic; then any entity by parameter."""
    from rcl_interfaces.msg import ParameterType, ParameterValue
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from ros_gz_interfaces.msg import Contacts, Entity
    from test_core_contacts import CRATE, MASS as CRATE_MASS
    from test_node_conventions import set_param
    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)

    def heard(topic: str, n: int) -> list:
        got = []
        sub = watch.node.create_subscription(Contacts, topic, got.append, reliable)
        try:
            wait_for(lambda: len(got) >= n, timeout=30)
        finally:
            watch.node.destroy_subscription(sub)
        return got

    sim.spawn('crate', resource_string=CRATE, position=(3.0, 3.0, 0.1))
    got = heard('/crate/bumper', 12)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in got[1:]]
    assert (len(stamps) - 1) / (stamps[-1] - stamps[0]) == pytest.approx(20.0, rel=0.01)
    (contact,) = got[-1].contacts
    assert (contact.collision1.name, contact.collision2.name) == (
        'crate::base::base_collision', 'world::world::floor')
    assert contact.collision1.type == Entity.COLLISION
    n = len(contact.positions)
    assert n == len(contact.normals) == len(contact.depths) == len(contact.wrenches) > 0
    held = sum(w.body_1_wrench.force.z for w in contact.wrenches)
    assert held == pytest.approx(CRATE_MASS * 9.81, rel=0.02)
    assert contact.wrenches[0].body_1_name.data == 'crate::base'
    assert contact.normals[0].z == pytest.approx(-1.0)
    # any entity's contacts, asked for while the node runs
    value = ParameterValue(type=ParameterType.PARAMETER_STRING_ARRAY,
                           string_array_value=['crate'])
    assert set_param(sim, 'contact_entities', value).successful
    got = heard('contacts/crate', 3)
    assert {c.collision2.name for c in got[-1].contacts} == {'world::world::floor'}
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=-1.0)
    assert not set_param(sim, 'contact_rate_hz', value).successful


def test_the_readmes_list_of_a_robots_sensors_is_what_the_node_publishes(sim, watch):
    """Each line of the README's sensors block: topic, message type, frame id, rate."""
    import re
    from pathlib import Path
    import importlib
    text = (Path(__file__).resolve().parent.parent / 'README.md').read_text()
    block = re.search(r'<!-- sensors -->\n```text\n(.*?)```', text, re.S).group(1)
    if 'ranger' not in sim.entities():
        sim.spawn('ranger', resource_string=RANGER, position=(-2.0, 2.0, 0.1))
    rows = [line.split() for line in block.strip().splitlines()]
    assert len(rows) >= 5
    wait_for(lambda: {r[0] for r in rows} <= {
        n for n, _ in watch.node.get_topic_names_and_types()})
    types = dict(watch.node.get_topic_names_and_types())
    for topic, kind, frame, rate, hz in rows:
        (full,) = [t for t in types[topic] if t.endswith(f'/{kind}')]
        package, _, name = full.split('/')
        msg_type = getattr(importlib.import_module(f'{package}.msg'), name)
        msg = latest(watch, msg_type, topic, timeout=30)
        assert (topic, msg.header.frame_id) == (topic, frame)
        assert hz == 'Hz' and float(rate) > 0


def test_a_realsense_publishes_its_streams_where_its_plugin_names_them(sim, watch):
    """D435 (``test_core_realsense``): 1.2 m from a wall, on the plugin's topics and frames."""
    import numpy as np
    from sensor_msgs.msg import Image
    from test_core_realsense import D435, PREFIX
    sim.spawn('bot', resource_string=D435, position=(-3.0, 3.0, 0.0))  # the camera 1 m up
    sim.spawn('wall', resource_string=BOX, position=(-1.55, 3.0, 1.0))  # its face at x = -1.8
    color = latest(watch, Image, f'/{PREFIX}/color/image_raw')
    assert (color.header.frame_id, color.encoding, color.width) == (
        f'bot/{PREFIX}_color_optical_frame', 'rgb8', 160)
    info = latest(watch, CameraInfo, f'/{PREFIX}/color/camera_info')
    assert info.header.frame_id == f'bot/{PREFIX}_color_optical_frame'
    ired = latest(watch, Image, f'/{PREFIX}/infra1/image_raw')
    assert (ired.header.frame_id, ired.encoding) == (f'bot/{PREFIX}_infra1_optical_frame',
                                                     'mono8')
    depth = latest(watch, Image, f'/{PREFIX}/depth/image_raw')
    assert (depth.header.frame_id, depth.encoding, depth.step) == (
        f'bot/{PREFIX}_depth_optical_frame', '16UC1', 2 * 160)
    mm = np.frombuffer(bytes(depth.data), '<u2').reshape(120, 160)
    assert mm[60, 80] == pytest.approx(1200, abs=5)  # the wall, straight ahead
    assert mm[0, 0] == 0  # the sky, beyond its 3 m: nothing seen
    depth_info = latest(watch, CameraInfo, f'/{PREFIX}/depth/camera_info')
    assert depth_info.header.frame_id == f'bot/{PREFIX}_depth_optical_frame'
    cloud = latest(watch, PointCloud2, f'/{PREFIX}/depth/color/points')
    assert (cloud.header.frame_id, cloud.width, cloud.height) == (
        f'bot/{PREFIX}_depth_optical_frame', 160, 120)
    topics = [name for name, _ in watch.node.get_topic_names_and_types()]
    assert not [t for t in topics if f'{PREFIX}color' in t or f'{PREFIX}depth' in t], topics
    assert f'/{PREFIX}/color/depth/image_raw' not in topics  # an image stream alone


def test_an_openni_kinect_publishes_its_streams_where_its_plugin_names_them(sim, watch):
    """FACE (``test_core_openni``): Go1's face camera, 2 m from a wall, its cloud cut at 1.5 m."""
    import numpy as np
    from sensor_msgs.msg import Image
    from test_core_openni import FACE
    sim.spawn('dog', resource_string=FACE, position=(3.0, -3.0, 0.0))  # the camera 1 m up
    sim.spawn('wall', resource_string=BOX, position=(5.25, -3.0, 1.0))  # its face at x = 5
    color = latest(watch, Image, '/camera_face/color/image_raw')
    assert (color.header.frame_id, color.width) == ('dog/camera_optical_face', 160)
    assert latest(watch, CameraInfo, '/camera_face/color/camera_info').header.frame_id == \
        'dog/camera_optical_face'
    depth = latest(watch, Image, '/camera_face/depth/image_raw')
    assert (depth.header.frame_id, depth.encoding) == ('dog/camera_optical_face', '32FC1')
    metres = np.frombuffer(bytes(depth.data), '<f4').reshape(120, 160)
    assert metres[60, 80] == pytest.approx(2.0, abs=0.02)  # the wall, straight ahead
    cloud = latest(watch, PointCloud2, '/cam1/point_cloud_face')
    assert (cloud.header.frame_id, cloud.width, cloud.height) == ('dog/camera_optical_face',
                                                                  160, 120)
    offset = {f.name: f.offset for f in cloud.fields}['z']
    rows = np.frombuffer(bytes(cloud.data), np.uint8).reshape(-1, cloud.point_step)
    z = rows[:, offset:offset + 4].copy().view('<f4').reshape(120, 160)
    assert np.isnan(z[60, 80])  # the wall at 2 m: past the plugin's 1.5 m cutoff
    assert 0.1 < z[119, 80] < 1.5  # the floor just ahead, inside it
    topics = [name for name, _ in watch.node.get_topic_names_and_types()]
    assert not [t for t in topics if 'camera_face_ir' in t], topics


def test_a_p3d_plugin_publishes_its_links_ground_truth_as_gazebo_ros_p3d_does(sim, watch):
    # Issue 53, item 4: TIAGo's and PR2's ground truth. A box on the floor, spawned under a
    # namespace, with PR2's tags (frame map, offsets of 25.7 m, a noise of 0.01) and HyQ's
    # (relative to a link, at 250 Hz): their topics under the namespace, their frames, the
    # pose where the entity is plus the offsets, a rate of simulated time and the noise's
    # covariance.
    from nav_msgs.msg import Odometry
    from test_core_p3d import plugin, robot
    text = robot(
        plugin('truth', 'base_link', '<topicName>base_pose_ground_truth</topicName>'
               '<frameName>map</frameName><xyzOffsets>25.7 25.7 0</xyzOffsets>'
               '<gaussianNoise>0.01</gaussianNoise><updateRate>100.0</updateRate>'),
        plugin('mast', 'mast', '<frame_name>base_link</frame_name><update_rate>250</update_rate>'
               '<ros><remapping>odom:=mast_truth</remapping></ros>'))
    sim.spawn('probe', resource_string=text, position=(-2.0, 3.0, 0.1), namespace='truth')
    got = []
    sub = watch.node.create_subscription(Odometry, '/truth/base_pose_ground_truth', got.append,
                                         20)
    try:
        wait_for(lambda: len(got) >= 20, timeout=20)
    finally:
        watch.node.destroy_subscription(sub)
    msg = got[-1]
    assert (msg.header.frame_id, msg.child_frame_id) == ('map', 'probe/base_link')
    where = sim.entity_state('probe')['position']
    p = msg.pose.pose.position
    assert (p.x, p.y, p.z) == pytest.approx((where[0] + 25.7, where[1] + 25.7, where[2]),
                                            abs=0.005)
    assert list(msg.pose.covariance[::7]) == pytest.approx([1e-4] * 6)
    assert list(msg.twist.covariance[::7]) == pytest.approx([1e-4] * 6)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in got[-10:]]
    assert all(d == pytest.approx(0.01, abs=1e-6) for d in
               [b - a for a, b in zip(stamps, stamps[1:])])  # 100 Hz of simulated time
    mast = latest(watch, Odometry, '/truth/mast_truth')
    assert (mast.header.frame_id, mast.child_frame_id) == ('probe/base_link', 'probe/mast')
    m = mast.pose.pose.position
    assert (m.x, m.y, m.z) == pytest.approx((0.3, 0.0, 0.2), abs=1e-6)
    sim.delete('probe')
