"""
The node's eyes and senses: camera images, laser scans and MuJoCo sensors as ROS messages.

Cameras and scanners run on a thread of their own, paced by simulated time: the stepping loop
never waits for them (they visit the world lock only to copy poses, see
:meth:`~sim_node.core.world.World.observe`). Sensor values come from the loop's snapshots and
go out with joint_states. Publishers appear and disappear with the cameras, sites and sensors of
each model generation.
"""

import math
import os
import threading
from typing import Callable, Optional

from geometry_msgs.msg import WrenchStamped
from msg_adapters import perception as pm
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image, Imu, PointCloud2, Range
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage

from .contacts import ContactPublishers
from .geo import GeoPublishers
from .odometers import OdometerPublishers
from .scans import Scans
from ...core.base import quat
from ...core.base.config import PerceptionConfig
from ...core.base.records import DeclaredCamera, ModelInfo, NO_TOPIC, Snapshot
from ...core.cameras import CameraRig, select
from ...core.devices.contacts import ContactReport
from ...core.devices.rendering import RenderingUnavailableError
from ...core.lidar import LaserScanner, scanner_sites, sweep_of
from ...core.stepping.geo import GeoSample
from ...core.stepping.odometers import OdometerSample
from ...core.stepping.sampling import JointSample
from ...session import Loaded

#: For sensors sampled at their own rates: the samples of one publishing tick at 1 kHz fit.
SAMPLED_QOS = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)
SENSOR_TYPES = {'imu': (Imu, 'imu'), 'wrench': (WrenchStamped, 'wrench'),
                'range': (Range, 'range'), 'generic': (Float64MultiArray, 'values')}
#: Niceness of the camera and laser thread (and of the renderer threads it starts).
PERCEPTION_NICE = 10
#: Simulated time within this fraction of a period of a due time counts as due.
DUE_TOLERANCE = 1e-6


class Schedule:
    """Due times at multiples of a simulated period; a time that went back starts over."""

    def __init__(self, rate_hz: float):
        self.period = 1.0 / rate_hz
        self._next: Optional[float] = None
        self._last = -math.inf

    def due(self, sim_time: float) -> bool:
        if sim_time < self._last or self._next is None:
            self._next = sim_time  # first time, or after a reset
        self._last = sim_time
        return sim_time >= self._next - DUE_TOLERANCE * self.period

    def done(self, sim_time: float) -> None:
        self._next = (math.floor(sim_time / self.period + DUE_TOLERANCE) + 1) * self.period


class _ThreadState:
    """What the perception thread keeps between iterations."""

    def __init__(self, config: PerceptionConfig):
        self.rig: Optional[CameraRig] = None
        self.scanner: Optional[LaserScanner] = None
        self.world = None
        self.generation = None
        self.cams, self.sites = (), ()
        self.cam_due = Schedule(config.camera_rate_hz)
        self.cam_dues: dict = {}  # camera -> its own Schedule (a declared rate)
        self.scan_rates: dict = {}  # site -> its own rate (declared), Hz
        self.requested: Optional[dict] = None  # what the world was last asked to scan
        self.sweeps: dict = {}  # site -> its declared Sweep
        self.seen = -1


class Perception:
    """
    Publishers and the perception thread of a :class:`~sim_node.ros.node.SimNode`.

    :param session: the loaded simulation; :meth:`on_model` is its listener.
    """

    def __init__(self, node: Node, config: PerceptionConfig, world_frame: str,
                 frame_prefix: str, contact_entities: Callable[[], tuple] = tuple):
        self._node = node
        self.contacts = ContactPublishers(node, frame_prefix + world_frame, contact_entities)
        self.odometers = OdometerPublishers(node, frame_prefix + world_frame, frame_prefix)
        self.geo = GeoPublishers(node, frame_prefix)
        self.joint_samples: Callable = lambda samples: None  # told the loop's JointSamples
        self.config = config
        self._world_frame = frame_prefix + world_frame
        self._prefix = frame_prefix
        self._loaded: Optional[Loaded] = None  # which world: told by the session (on_model)
        self._tf_pub = node.create_publisher(TFMessage, '/tf', 100)
        # camera name -> (image, info, depth or None, points or None)
        self._camera_pubs: dict = {}
        self._camera_decl: dict = {}  # camera name -> its DeclaredCamera (None: the node's)
        self._sensor_pubs: dict = {}  # (kind, name) -> publisher
        self._sensor_generation = None
        self._sensor_frames: dict = {}
        self._sensor_declared: dict = {}  # (kind, name) -> (its DeclaredWrench, parent body)
        self._sensor_lock = threading.Lock()  # the publisher thread reads what sync_sensors sets
        # Held while images and scans are checked against the world's resets and published:
        # settle() waits for it, so a reset's reply comes after whatever was checked before it.
        self._publishing = threading.Lock()
        self._running = threading.Event()
        self.scans = Scans(node, config, frame_prefix, self._create_publisher, self._publishing,
                           self._resets, self._running)
        self._thread: Optional[threading.Thread] = None
        self._cameras_failed = ''

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        self._running.set()
        self._thread = threading.Thread(target=self._run, name='sim-perception', daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """
        Stop the thread; from then on it makes, destroys and publishes nothing.

        A first render under load (a large camera's context, Mesa's shaders) can outlast
        the join: the thread then goes on drawing, but every step of it that touches ROS is
        taken under ``_publishing`` and only while running, so once this returns nothing of
        it meets the node or the middleware being torn down.
        """
        self._running.clear()
        with self._publishing:  # a publication under way ends; none begins after
            pass
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None

    # ------------------------------------------------------------------ static frames

    def static_transforms(self, info: ModelInfo, sim_time: float, frames: tuple) -> list:
        """Frames of this generation's published cameras, sensor sites, scanners, own frames."""
        cams = select(info.cameras, self.config.cameras)
        sites = [s.site for s in info.sensors if s.kind in ('imu', 'wrench')]
        lasers = scanner_sites([s.name for s in info.sites], self.config.lidar_sites)
        sites += [s for s in info.sites if s.name in lasers]
        ranges = [s for s in info.sensors if s.kind == 'range']
        by_name = {s.name: s for s in info.sites}
        own = [(by_name[site], frame) for site, frame in info.sensor_frames if site in by_name]
        return pm.device_transforms(info, sim_time, frames, cams, sites, ranges, self._prefix,
                                    own)

    # ------------------------------------------------------------------ sensors

    def publish_sensors(self, snap: Snapshot) -> None:
        """
        Publish every sensor group of the snapshot's model (from the publisher thread).

        Nothing until :meth:`sync_sensors` has made the publishers of that model generation.
        The joint samples the loop took go to the controllers' publishers after the sensor lock
        is let go (their laws ran on the stepping side already,
        :mod:`sim_node.core.control.laws`; what they publish is theirs to pace).
        """
        info = snap.info
        joints: list = []
        try:
            self._publish_locked(snap, info, joints)
        finally:
            self.joint_samples(joints)  # controllers'

    def _publish_locked(self, snap: Snapshot, info: ModelInfo, joints: list) -> None:
        """Publish the sensors under the sensor lock; put the joint samples into `joints`."""
        with self._sensor_lock:
            if info.generation != self._sensor_generation:
                return
            data = snap.sensordata
            joints.extend(self._publish_samples(info))
            for sensor in info.sensors:
                pub = self._sensor_pubs[(sensor.kind, sensor.name)]
                frame = self._sensor_frames.get((sensor.kind, sensor.name), '')
                if sensor.kind == 'imu' and sensor.name in info.imus:
                    continue  # sampled at its own rate: _publish_samples
                if sensor.kind == 'imu':
                    pub.publish(pm.imu(sensor, data, snap.time, frame))
                elif sensor.kind == 'wrench':
                    declared = self._sensor_declared.get((sensor.kind, sensor.name))
                    msg = pm.wrench(sensor, data, snap.time, frame)
                    if declared is not None:
                        decl, parent = declared
                        turn = None
                        if decl.frame == 'parent' and parent is not None:
                            turn = quat.mul(quat.conj(snap.body_xquat_wxyz[parent]),
                                            snap.body_xquat_wxyz[sensor.site.body])
                        msg = pm.declared_wrench(msg, decl.sign, turn)
                    pub.publish(msg)
                elif sensor.kind == 'range':
                    pub.publish(pm.range_reading(sensor, data, snap.time, frame))
                else:
                    pub.publish(pm.generic(sensor, data))

    def _publish_samples(self, info: ModelInfo) -> list:
        """
        Publish the samples of declared IMUs and P3D plugins the loop took, each at its time.

        Returns the joint samples among them, for the controllers (not run here: see
        :meth:`publish_sensors`).
        """
        sim = self._loaded
        if sim is None:
            return []
        taken = sim.world.take_sensor_samples()
        for sample in taken:
            if isinstance(sample, (ContactReport, JointSample, OdometerSample, GeoSample)):
                if isinstance(sample, ContactReport) and sample.generation == info.generation:
                    self.contacts.publish(sample, info)
                elif isinstance(sample, OdometerSample):
                    self.odometers.publish(sample, info)
                elif isinstance(sample, GeoSample):
                    self.geo.publish(sample, info)
                continue
            site, t, q, gyro, acc = sample
            pub = self._sensor_pubs.get(('imu', site))
            decl = info.imus.get(site)
            if pub is None or decl is None:
                continue  # its model is gone
            if not decl.always_on and pub.get_subscription_count() == 0:
                continue
            pub.publish(pm.imu_sample(q, gyro, acc, t, self._sensor_frames[('imu', site)]))
        return [x for x in taken if isinstance(x, JointSample)]

    def on_model(self, loaded: Optional[Loaded], snap: Optional[Snapshot]) -> None:
        """
        Listen to the session's new models: the model's sensor publishers, the world rendered.

        The perception thread acts on the world at its next iteration.
        """
        self._loaded = loaded
        self.sync_sensors(snap.info if snap is not None else None)

    def sync_sensors(self, info: Optional[ModelInfo]) -> None:
        """
        Make the sensor publishers of a model generation (from the node's model thread).

        Publishers are made before the lock and destroyed after it, so the publisher thread
        waits for neither (92 touch sensors: 92 publishers).
        """
        sensors = () if info is None else info.sensors
        frames, declared, topics = {}, {}, {}
        for s in sensors:
            if s.kind == 'range':
                frames[(s.kind, s.name)] = pm.range_frame(info, s, self._prefix)
            elif s.site is not None:
                frames[(s.kind, s.name)] = pm.site_frame(info, s.site, self._prefix)
            imu = info.imus.get(s.name) if s.kind == 'imu' else None
            if imu is not None:  # an IMU a robot file declares
                frames[(s.kind, s.name)] = self._prefix + imu.frame
                if imu.topic:
                    topics[(s.kind, s.name)] = imu.topic
            decl = info.wrenches.get(s.name) if s.kind == 'wrench' else None
            if decl is not None:  # a force-torque sensor a robot file declares
                frames[(s.kind, s.name)] = self._prefix + decl.frame_id
                parent = info.body_names.index(decl.parent) if decl.parent in \
                    info.body_names else None
                declared[(s.kind, s.name)] = (decl, parent)
                if decl.topic:
                    topics[(s.kind, s.name)] = decl.topic

        def create(key):
            msg_type, leaf = SENSOR_TYPES[key[0]]
            default = f'sensors/{pm.topic_token(key[1])}/{leaf}'
            # a declared IMU's samples go out in bursts (those of one publishing tick)
            qos = SAMPLED_QOS if key[0] == 'imu' and key[1] in info.imus else \
                qos_profile_sensor_data
            try:
                return self._create_publisher(msg_type, topics.get(key, default), qos)
            except Exception as exc:  # noqa: B902 (a name rclpy refuses: ours instead)
                self._node.get_logger().warning(
                    f'sensor {key[1]!r}: topic {topics.get(key)!r} is refused ({exc}); '
                    f'publishing on {default}')
                return self._create_publisher(msg_type, default, qos_profile_sensor_data)
        keys = [(s.kind, s.name) for s in sensors]
        pubs = dict(self._sensor_pubs)
        for key in keys:
            if key not in pubs:
                pubs[key] = create(key)
        gone = [pubs.pop(k) for k in [k for k in pubs if k not in keys]]
        with self._sensor_lock:
            self._sensor_pubs = pubs
            self._sensor_frames = frames
            self._sensor_declared = declared
            self._sensor_generation = None if info is None else info.generation
        for pub in gone:
            self._node.destroy_publisher(pub)
        self.contacts.sync(info)
        self.odometers.sync(info)
        self.geo.sync(info)

    def _create_publisher(self, msg_type, topic: str, qos) -> Publisher:
        """
        Create a publisher that may be destroyed while the node runs.

        Without QoS event handlers: rclpy adds those to the executor's wait set as waitables,
        and its executor puts a waitable of a destroyed publisher into the next wait set anyway
        (``InvalidHandle: cannot use Destroyable because destruction was requested``, raised from
        ``spin()``, which ends the node). A publisher without them is never in a wait set, so it
        can be destroyed from any thread at any time: the one rule for everything that comes
        and goes with entities (all of it is publishers).
        """
        return self._node.create_publisher(
            msg_type, topic, qos,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

    def _sync(self, pubs: dict, keys: list, create: Callable) -> None:
        """
        Make `pubs` hold publishers for exactly `keys`.

        Destroy those of keys gone, create those of new ones with ``create(key)`` (a publisher,
        or a tuple of publishers and Nones).
        """
        for key in [k for k in pubs if k not in keys]:
            gone = pubs.pop(key)
            for pub in gone if isinstance(gone, tuple) else (gone,):
                if pub is not None:
                    self._node.destroy_publisher(pub)
        for key in keys:
            if key not in pubs:
                pubs[key] = create(key)

    # ------------------------------------------------------------------ cameras and lasers

    def _run(self) -> None:
        # Below the stepping loop and the publishers in the CPU's eyes: when cores are short,
        # images come later, not the physics or /tf (the renderer's own threads inherit it).
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), PERCEPTION_NICE)
        except OSError:  # not permitted here: run at the node's priority
            pass
        state = _ThreadState(self.config)
        try:
            while self._running.is_set():
                try:
                    self._iterate(state)
                except Exception as exc:  # never die silently, never stop for good
                    self._node.report_failure('cameras and lasers', exc)
                    if not self._node.context.ok():
                        break
                    self._running.wait(0.5)
        finally:
            if state.rig is not None:
                state.rig.close()

    def _iterate(self, st: '_ThreadState') -> None:
        """Wait for a newer snapshot; render and scan what is due at its simulated time."""
        sim = self._loaded
        if sim is None or sim.loop is None:
            self._running.wait(0.1)
            return
        if sim.world is not st.world:  # a world was loaded
            if st.rig is not None:
                st.rig.close()
            st.world, st.generation, st.seen, st.requested = sim.world, None, -1, None
            cfg = self.config
            st.rig = CameraRig(st.world, cfg.camera_width, cfg.camera_height, cfg.cameras,
                               cfg.camera_depth, cfg.camera_shadow_size)
            st.scanner = LaserScanner(st.world, self.scans.laser_config)
        seq, snap = sim.loop.wait_snapshot(st.seen, 0.1)
        if seq == st.seen:
            return
        st.seen = seq
        if snap.info.generation != st.generation:
            with self._publishing:
                if not self._running.is_set():
                    return
                st.cams, st.sites = self._sync_device_publishers(snap.info)
            st.generation = snap.info.generation
            declared = {n: d for n, d in snap.info.lasers.items() if n in st.sites}
            st.sweeps = {n: sweep_of(d, self.scans.laser_config) for n, d in declared.items()}
            st.scan_rates = {n: d.rate_hz for n, d in declared.items() if d.rate_hz}
        if st.cams and not self._cameras_failed:
            self._capture_due(st, snap)
        if st.sites or st.requested:
            self.scans.due(st, snap, self._current_info)

    def _capture_due(self, st: '_ThreadState', snap: Snapshot) -> None:
        """Render the cameras due at the snapshot's time, each at its own (declared) rate."""
        info = snap.info
        declared = info.cameras_declared
        due = []
        for cam in st.cams:
            decl = declared.get(cam.name)
            if decl is not None and decl.rate_hz and cam.name not in st.cam_dues:
                st.cam_dues[cam.name] = Schedule(decl.rate_hz)
            schedule = st.cam_dues.get(cam.name, st.cam_due)
            if not schedule.due(snap.time):
                continue
            if decl is not None and not decl.always_on and not any(
                    p is not None and p.get_subscription_count()
                    for p in self._camera_pubs.get(cam.name, ())):
                continue
            due.append(cam.name)
        for schedule in {id(x): x for x in [st.cam_dues.get(n, st.cam_due)
                                            for n in due]}.values():
            schedule.done(snap.time)
        if due:
            sizes = {n: (d.width, d.height) for n, d in declared.items() if d.width}
            self._publish_frames(st.rig, due, sizes,
                                 [n for n, d in declared.items() if d.depth])

    def _sync_device_publishers(self, info: ModelInfo) -> tuple:
        """Create and destroy camera and laser publishers for a new model generation."""
        cams = select(info.cameras, self.config.cameras)
        names = [s.name for s in info.sites]
        # a robot's declared lasers are its own: they publish whatever lidar_sites selects
        sites = tuple(dict.fromkeys(scanner_sites(names, self.config.lidar_sites)
                                    + tuple(n for n in names if n in info.lasers)))
        keys = [c.name for c in cams]
        for name in keys:  # a camera whose declaration changed gets its publishers anew
            if self._camera_decl.get(name) != info.cameras_declared.get(name) and \
                    name in self._camera_pubs:
                for pub in self._camera_pubs.pop(name):
                    if pub is not None:
                        self._node.destroy_publisher(pub)
            self._camera_decl[name] = info.cameras_declared.get(name)
        self._sync(self._camera_pubs, keys, lambda name: self._camera_publishers(
            name, info.cameras_declared.get(name)))
        self.scans.sync(info, sites)
        return cams, sites

    def _camera_publishers(self, name: str, declared=None) -> tuple:
        """(image or None, info, depth or None, points or None); topics as declared."""
        base = f'cameras/{pm.topic_token(name)}'
        if declared is not None and declared.topic:
            base = declared.topic  # camera_name/image_raw ..., as gazebo_ros' camera names them
        own = declared if declared is not None else DeclaredCamera(camera=name)
        qos = qos_profile_sensor_data
        create = self._create_publisher
        seen = own.depth  # a depth camera: depth and points
        depth = (self.config.camera_depth or seen) and own.depth_topic != NO_TOPIC
        points = own.points if own.points is not None else \
            seen or (depth and self.config.camera_points)
        image = own.image_topic or f'{base}/image_raw'
        return (None if image == NO_TOPIC else create(Image, image, qos),
                create(CameraInfo, own.info_topic or f'{base}/camera_info', qos),
                create(Image, own.depth_topic or f'{base}/depth/image_raw', qos)
                if depth else None,
                create(PointCloud2, own.points_topic or f'{base}/points', qos)
                if depth and points else None)

    def _publish_frames(self, rig: CameraRig, only=None, sizes=None, depth_for=()) -> None:
        try:
            frames = rig.capture(only, sizes, depth_for)
        except RenderingUnavailableError as exc:
            self._cameras_failed = str(exc)
            self._node.get_logger().error(f'cameras are off: {exc}')
            return
        info = self._current_info()
        with self._publishing:
            self._publish_checked(frames, info)

    def _publish_checked(self, frames: list, info: Optional[ModelInfo]) -> None:
        """Publish the frames still of the world's model and timeline (under _publishing)."""
        resets = self._resets()
        if not self._running.is_set():
            return  # stopped (see stop)
        for f in frames:
            pubs = self._camera_pubs.get(f.camera.name)
            if pubs is None or info is None or info.generation != f.generation:
                continue  # the model changed meanwhile: the next frame has it right
            if f.resets != resets:
                # drawn before a reset that came while it was drawn: its time is of a past
                # the world left (and settle() holds the reset's reply until this is done)
                continue
            decl = info.cameras_declared.get(f.camera.name)
            frame = (self._prefix + decl.frame if decl is not None and decl.frame
                     else pm.camera_frame(info, f.camera, self._prefix))
            image_pub, info_pub, depth_pub, points_pub = pubs
            if not f.camera.fixed:
                self._tf_pub.publish(pm.moving_camera_tf(frame, self._world_frame, f.pos,
                                                         f.quat_wxyz, f.time))
            if image_pub is not None:
                image_pub.publish(pm.image(f.rgb, f.time, frame,
                                           decl.encoding if decl is not None else 'rgb8'))
            height, width = f.rgb.shape[:2]
            info_pub.publish(pm.camera_info(f.intrinsics, width, height, f.time, frame))
            if f.depth is not None:
                self._publish_depth(f, decl, frame, depth_pub, points_pub)

    def _publish_depth(self, f, decl, frame: str, depth_pub, points_pub) -> None:
        """Publish a frame's depth image (32FC1 metres, a RealSense's 16UC1 mm) and points."""
        if depth_pub is not None:
            if decl is not None and decl.depth_mm:
                depth_pub.publish(pm.depth_image_mm(f.depth, f.time, frame, decl.clip))
            else:
                depth = f.depth if decl is None else pm.clipped(f.depth, decl.clip)
                depth_pub.publish(pm.depth_image(depth, f.time, frame))
        if points_pub is not None:
            clip = None if decl is None else (decl.points_clip or decl.clip)
            points_pub.publish(pm.points(pm.clipped(f.depth, clip), f.rgb, f.intrinsics,
                                         f.time, frame))

    def settle(self) -> None:
        """
        Wait until the images and scans being published have gone out.

        Called after a reset, before its reply: a reading checked against the world's resets
        before the reset is out by then, and every later one is checked after it (none drawn
        before the reset comes once the reset is answered).
        """
        with self._publishing:
            pass

    def _resets(self) -> int:
        """Return the world's resets of state so far (without the world lock: see settle)."""
        sim = self._loaded
        return -1 if sim is None else sim.world.resets

    def _current_info(self) -> Optional[ModelInfo]:
        sim = self._loaded
        return None if sim is None else sim.world.model_info
