"""
Cameras, laser scans and sensors over the wire: a real node process, real subscribers.

What a ROS user checks: the default scene's camera shows up with image, depth and camera_info
stamped with simulation time; a ball placed by spawn_entity appears at the pixel that
camera_info and /tf_static predict, at the depth its distance gives; a spawned camera comes
and goes with its entity; a scene without cameras never loads an OpenGL driver.
"""

from pathlib import Path
import threading
import time

from conftest import SCENES, serve_node, wait_for, Watcher
import numpy as np
import pytest

CAM = 'cameras/overview'
W, H = 320, 240
BALL = np.array([0.75, -0.25, 0.95])  # above the table, in the overview camera's view
BALL_R = 0.05
# A glowing ball (evenly coloured: its pixels' centroid is where its centre projects).
BALL_MJCF = ('<mujoco><asset><material name="glow" rgba="1 0 1 1" emission="1" specular="0"/>'
             f'</asset><worldbody><body name="ball"><geom type="sphere" size="{BALL_R}" '
             'material="glow" contype="0" conaffinity="0"/></body></worldbody></mujoco>')
CAMERA_BOT = ('<mujoco><worldbody><body name="head"><geom type="box" size="0.05 0.05 0.05"/>'
              '<camera name="eye" pos="0 0 -0.06" fovy="60"/></body></worldbody></mujoco>')


@pytest.fixture(scope='module')
def node():
    yield from serve_node('real_time_factor:=1.0')


class Sensors:
    """Keeps the latest message of each sensor topic (sensor-data QoS, as the node offers)."""

    def __init__(self, topics: dict):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import qos_profile_sensor_data
        self.node = rclpy.create_node(f'sensors_{id(self):x}')
        self.latest, self.counts = {}, {}
        self.arrivals = {}  # topic -> [(monotonic time received, stamp)]
        self.lock = threading.Lock()
        for topic, msg_type in topics.items():
            self.node.create_subscription(msg_type, topic, self._keeper(topic),
                                          qos_profile_sensor_data)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self._stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _keeper(self, topic):
        def keep(msg):
            with self.lock:
                self.latest[topic] = msg
                self.counts[topic] = self.counts.get(topic, 0) + 1
                self.arrivals.setdefault(topic, []).append((time.monotonic(),
                                                            _sec(msg.header.stamp)))
        return keep

    def _spin(self):
        while not self._stop:
            self.executor.spin_once(timeout_sec=0.05)

    def after(self, topic: str, sim_time: float, timeout: float = 15.0):
        """Return the first message of `topic` stamped after `sim_time`."""
        def fresh():
            with self.lock:
                m = self.latest.get(topic)
            return m if m is not None and _sec(m.header.stamp) > sim_time else None
        return wait_for(fresh, timeout)

    def close(self):
        self._stop = True
        self.thread.join(2)
        self.executor.shutdown()
        self.node.destroy_node()


def _sec(t) -> float:
    return t.sec + t.nanosec * 1e-9


def _camera_topics():
    from sensor_msgs.msg import CameraInfo, Image, Imu, LaserScan
    return {f'{CAM}/image_raw': Image, f'{CAM}/camera_info': CameraInfo,
            f'{CAM}/depth/image_raw': Image, 'sensors/base_imu/imu': Imu,
            'lasers/base_lidar/scan': LaserScan}


@pytest.fixture
def sensors(node, rclpy_context):
    s = Sensors(_camera_topics())
    yield s
    s.close()


def test_the_default_scene_shows_its_camera_scan_and_imu_stamped_with_sim_time(
        sensors, watcher):
    now = wait_for(watcher.latest_clock)
    img = sensors.after(f'{CAM}/image_raw', now)
    info = sensors.after(f'{CAM}/camera_info', now)
    depth = sensors.after(f'{CAM}/depth/image_raw', now)
    assert (img.width, img.height, img.encoding, img.step) == (W, H, 'rgb8', 3 * W)
    assert len(img.data) == W * H * 3
    assert (depth.encoding, depth.step) == ('32FC1', 4 * W)
    d = np.frombuffer(bytes(depth.data), '<f4').reshape(H, W)
    assert np.isfinite(d).any() and np.all(d[np.isfinite(d)] > 0)
    # K from the camera's fovy (45 deg) at 320 x 240; plumb_bob with zero distortion.
    f = 0.5 * H / np.tan(np.radians(45) / 2)
    np.testing.assert_allclose(info.k, [f, 0, 159.5, 0, f, 119.5, 0, 0, 1])
    assert info.distortion_model == 'plumb_bob' and list(info.d) == [0.0] * 5
    for m in (img, info, depth):
        assert m.header.frame_id == 'overview_optical_frame'
        assert now < _sec(m.header.stamp) <= watcher.latest_clock() + 1e-9
    static = wait_for(lambda: watcher.tf_static.get('overview_optical_frame'))
    assert static[1] == 'world'
    assert watcher.tf_static['robot/base_lidar'][1] == 'robot'
    scan = sensors.after('lasers/base_lidar/scan', now)
    ranges = np.array(scan.ranges)
    assert scan.header.frame_id == 'robot/base_lidar' and len(ranges) == 360
    # The nearest table legs stand 0.28 m ahead and 0.45 m to each side of the scanner.
    near = ranges[np.isfinite(ranges)]
    assert len(near) > 4 and 0.45 < near.min() < 0.55
    imu = sensors.after('sensors/base_imu/imu', now)
    assert imu.header.frame_id == 'robot/base_imu'
    assert imu.linear_acceleration.z == pytest.approx(9.81, abs=1e-3)  # at rest: +g


def test_the_renderer_runs_below_the_physics(node, sensors, watcher):
    """When cores are short, images come later, not the physics or /tf (see test_node_scale)."""
    sensors.after(f'{CAM}/image_raw', wait_for(watcher.latest_clock))
    nice = {}  # thread id -> (name, niceness)
    for task in Path(f'/proc/{node.proc.pid}/task').iterdir():
        fields = (task / 'stat').read_text().rsplit(')', 1)[1].split()
        nice[int(task.name)] = ((task / 'comm').read_text().strip(), int(fields[16]))
    assert nice[node.proc.pid][1] == 0  # the node itself; the loop thread with it
    assert 10 in {n for _, n in nice.values()}  # the perception thread
    renderer = [n for name, n in nice.values() if name.startswith('llvmpipe')]  # Mesa's
    assert all(n == 10 for n in renderer)


def test_a_spawned_ball_appears_where_camera_info_and_tf_predict(sim, sensors, watcher):
    from sim_node.core.base import quat
    sim.spawn('ball', resource_string=BALL_MJCF, position=list(BALL))
    spawned_at = sim.entity_state('ball')['stamp']  # a simulated time the ball was there
    info = sensors.after(f'{CAM}/camera_info', spawned_at)
    img = sensors.after(f'{CAM}/image_raw', spawned_at)
    depth = sensors.after(f'{CAM}/depth/image_raw', spawned_at)
    _, parent, pos, q_xyzw = watcher.tf_static['overview_optical_frame']
    assert parent == 'world'
    q = np.array([q_xyzw[3], *q_xyzw[:3]])
    p = quat.rotate(quat.conj(q), BALL - np.array(pos))  # the ball in the optical frame
    fx, cx, fy, cy = info.k[0], info.k[2], info.k[4], info.k[5]
    u, v = fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy
    rgb = np.frombuffer(bytes(img.data), np.uint8).reshape(H, W, 3).astype(int)
    magenta = (rgb[..., 0] > 150) & (rgb[..., 2] > 150) & (rgb[..., 1] < 90)
    ys, xs = np.nonzero(magenta)
    assert len(xs) > 10, 'the ball is not in the image'
    centroid = (xs.mean(), ys.mean())
    assert abs(centroid[0] - u) < 0.3 and abs(centroid[1] - v) < 0.3, (centroid, (u, v))
    dist = np.linalg.norm(p)
    d = np.frombuffer(bytes(depth.data), '<f4').reshape(H, W)
    expected = p[2] * (dist - BALL_R) / dist
    assert d[int(round(v)), int(round(u))] == pytest.approx(expected, abs=0.01)


def test_no_image_drawn_before_a_reset_comes_after_its_reply(start_node, rclpy_context):
    """
    Publish no image drawn before a reset once the reset is answered.

    An image is drawn from the state at its stamp, then published: a reset in between makes
    it a picture of a past the world left.

    At a real-time factor of 1, simulated time since a reset can not run ahead of the wall
    clock since its request: a later image stamped ahead of that was drawn before the reset.
    Large images (a tenth of a second or more to draw here) leave a reset room to come between.
    """
    from sensor_msgs.msg import Image
    from sim_node.ros.client import SimClient
    start_node('real_time_factor:=1.0', 'camera_width:=1280', 'camera_height:=960',
               'camera_rate_hz:=30.0', namespace='/resets')
    topic = f'/resets/{CAM}/image_raw'
    eye = Sensors({topic: Image})
    sim = SimClient(namespace='resets', timeout_sec=30)
    try:
        stale = []
        for _ in range(12):
            eye.after(topic, 0.3, timeout=30)  # the world ran a while: its images say so
            asked = time.monotonic()
            sim.reset()
            answered = time.monotonic()
            time.sleep(0.3)
            with eye.lock:
                got = list(eye.arrivals[topic])
            stale += [(round(at - asked, 3), stamp) for at, stamp in got
                      if at > answered and stamp > at - asked + 0.05]
        assert not stale, f'images from before a reset, after its reply: {stale[:3]}'
    finally:
        sim.close()
        eye.close()


def test_a_spawned_camera_comes_and_goes_with_its_entity(sim, watcher, rclpy_context):
    from sensor_msgs.msg import Image
    topic = 'cameras/bot/eye/image_raw'
    eye = Sensors({topic: Image})
    try:
        sim.spawn('bot', resource_string=CAMERA_BOT, position=[0.75, 0.0, 1.5])
        img = eye.after(topic, wait_for(watcher.latest_clock))
        assert img.header.frame_id == 'bot/eye_optical_frame'
        assert wait_for(lambda: watcher.tf_static.get('bot/eye_optical_frame'))[1] == 'bot'
        assert eye.node.count_publishers('/' + topic) == 1
        sim.delete('bot')
        wait_for(lambda: eye.node.count_publishers('/' + topic) == 0)
        wait_for(lambda: 'bot/eye_optical_frame' not in watcher.tf_static)
    finally:
        eye.close()


def _node_topics(start_node, namespace: str, *params: str) -> tuple:
    """
    Start a node in a namespace of its own, without /clock; return it and the graph's topics.

    Its own namespace: the module's node (default scene) publishes cameras too.
    """
    proc = start_node(*params, 'publish_clock:=false', namespace=f'/{namespace}')
    w = Watcher(namespace=namespace)
    try:
        wait_for(lambda: w.joint_states is not None, 30)
        time.sleep(1.0)
        return proc, [name for name, _ in w.node.get_topic_names_and_types()]
    finally:
        w.close()


def test_a_scene_without_cameras_never_loads_an_opengl_driver(start_node, rclpy_context):
    proc, topics = _node_topics(start_node, 'plain', f'scene:={SCENES / "push_box.xml"}')
    assert '/plain/joint_states' in topics
    assert not [t for t in topics if t.startswith(('/plain/cameras/', '/plain/lasers/'))]
    maps = open(f'/proc/{proc.proc.pid}/maps').read()
    assert 'libEGL' not in maps and 'OSMesa' not in maps
    assert 'rendering with' not in proc.output()


def test_cameras_off_by_parameter(start_node, rclpy_context):
    proc, topics = _node_topics(start_node, 'blind', 'cameras:=[none]', 'lidar_sites:=[none]')
    assert not [t for t in topics if t.startswith(('/blind/cameras/', '/blind/lasers/'))]
    assert '/blind/sensors/base_imu/imu' in topics
    assert 'libEGL' not in open(f'/proc/{proc.proc.pid}/maps').read()


def test_points_on_request(start_node, rclpy_context):
    from sensor_msgs.msg import PointCloud2
    start_node('camera_points:=true', 'publish_clock:=false', namespace='/pts')
    cloud = Sensors({'pts/cameras/overview/points': PointCloud2})
    try:
        msg = cloud.after('pts/cameras/overview/points', 0.0, 30)
        assert (msg.width, msg.height) == (W, H)
        assert [f.name for f in msg.fields] == ['x', 'y', 'z', 'rgb']
        assert msg.header.frame_id == 'overview_optical_frame'
        xyz = np.frombuffer(bytes(msg.data), '<f4').reshape(H, W, 4)[..., :3]
        seen = xyz[np.isfinite(xyz[..., 2])]
        assert len(seen) > W * H / 2 and np.all(seen[:, 2] > 0)  # in front of the camera
    finally:
        cloud.close()


def test_without_a_usable_gl_backend_the_node_says_why_and_scans_on(start_node, rclpy_context,
                                                                    monkeypatch):
    from sensor_msgs.msg import LaserScan
    monkeypatch.setenv('MUJOCO_GL', 'glx')  # not headless: the node must refuse it clearly
    proc = start_node('publish_clock:=false', namespace='/nogl')
    scans = Sensors({'nogl/lasers/base_lidar/scan': LaserScan})
    try:
        wait_for(lambda: "cameras are off: MUJOCO_GL='glx' cannot render headless"
                 in proc.output(), 30)
        first = scans.after('nogl/lasers/base_lidar/scan', 0.0, 30)
        scans.after('nogl/lasers/base_lidar/scan', _sec(first.header.stamp), 10)
        assert proc.proc.poll() is None
    finally:
        scans.close()
