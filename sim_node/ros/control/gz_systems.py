"""
The gz-sim systems of SDF models on the wire, on the topics a ros_gz_bridge user gives them.

For each entity whose SDF declares systems (:attr:`ModelInfo.gz_systems
<sim_node.core.base.records.ModelInfo>`), a :class:`SystemSet`: their laws
(:mod:`sim_node.core.control.gz_systems`) run on the stepping side at each joint sample of
theirs, and here:

* ``DiffDrive``, ``AckermannSteering``: geometry_msgs/Twist in on their ``cmd_vel`` topic;
  nav_msgs/Odometry out on ``odometry`` at ``odom_publish_frequency`` (simulated Hz), and the
  ``frame_id`` -> ``child_frame_id`` transform as tf2_msgs/TFMessage on their ``tf`` topic;
* ``JointPositionController``, ``JointController``: std_msgs/Float64 in on ``cmd_pos`` /
  ``cmd_vel``;
* ``JointTrajectoryController``: trajectory_msgs/JointTrajectory in, std_msgs/Float32 progress
  out (every :data:`PROGRESS_PERIOD` while a trajectory is followed);
* ``JointStatePublisher``: sensor_msgs/JointState of its joints (their SDF names) at its rate;
* ``PosePublisher``: tf2_msgs/TFMessage of the model's links (``<model>`` ->
  ``<model>::<link>``, in the model's root link frame) at its rate.

Messages are stamped with simulated time. ROS carries; the laws decide (house rule B10).
"""

import math
import threading
from typing import Callable, Optional

from geometry_msgs.msg import Twist
from msg_adapters import convert
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32, Float64, Header
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory

from .controllers import NO_EVENTS, NO_SUB_EVENTS, publish_odometry
from ...core.base import quat
from ...core.control import gz_systems, laws
from ...session import Loaded, Session

ZERO6 = [0.0] * 6
#: Simulated seconds between two progress messages of a trajectory being followed.
PROGRESS_PERIOD = 0.02


def _world_joint(entity: str, joint: str) -> str:
    return f'{entity}/{joint.replace("::", "/")}'


class _Odometry:
    """What :func:`publish_odometry` takes: a base system's publishers and frames."""

    def __init__(self, node: Node, system):
        self.odom_pub = node.create_publisher(Odometry, system.topics['odometry'], 10,
                                              **NO_EVENTS)
        self.tf_pub = node.create_publisher(TFMessage, system.topics['tf'], 10, **NO_EVENTS)
        self.odom_frame = system.frames['frame_id']
        self.base_frame = system.frames['child_frame_id']
        self.params = {'pose_covariance_diagonal': ZERO6, 'twist_covariance_diagonal': ZERO6}
        self.period = 1.0 / max(system.params.get('odom_publish_frequency', 50.0), 1e-3)
        self.next = -math.inf


class SystemSet:
    """
    One entity's gz-sim systems: their laws, their topics (see the module docstring).

    :param joints: the world's hinge and slide joints (a ball's state is no joint sample's).
    :param sample: ``sample(key, joints, rate_hz, sensors, tick)``, the world's joint sampling.
    :param world: returns the loaded world (for the pose publisher's snapshots).
    """

    def __init__(self, node: Node, entity: str, systems: tuple, timestep: float,
                 joints: tuple, sample: Callable, world: Callable):
        self.node, self.entity, self.world = node, entity, world
        known = set(joints)
        own = sorted({j for s in systems for j in s.joints
                      if _world_joint(entity, j) in known})
        self.laws = laws.Laws(own, lambda j, interface, v: v,
                              lambda j: _world_joint(entity, j))
        self.index = {j: i for i, j in enumerate(own)}
        self.key = f'gz:{entity}'
        self._sample = sample
        self._subs, self._pubs = [], []
        self._odometry: list = []  # (law, _Odometry)
        self._states: list = []  # (system, publisher, [next due])
        self._poses: list = []
        self._progress: list = []  # (law, publisher)
        rate = 0.0
        for k, system in enumerate(systems):
            law = gz_systems.law(system, timestep)
            if law is not None:
                law.activate()
                self.laws.put(f'{system.kind}_{k}', law)
                rate = max(rate, law.rate_hz)
            self._wire(system, law)
        if own and rate > 0:
            sample(self.key, [_world_joint(entity, j) for j in own], rate, False,
                   self.laws.tick)

    def _wire(self, system, law) -> None:
        node, kind = self.node, system.kind
        if kind in ('DiffDrive', 'AckermannSteering'):
            self._sub(Twist, system.topics['cmd_vel'],
                      lambda m, law=law: law.take(m.linear.x, m.angular.z))
            odo = _Odometry(node, system)
            self._pubs += [odo.odom_pub, odo.tf_pub]
            self._odometry.append((law, odo))
        elif kind in ('JointPositionController', 'JointController'):
            role = 'cmd_pos' if kind == 'JointPositionController' else 'cmd_vel'
            self._sub(Float64, system.topics[role], lambda m, law=law: law.take(m.data))
        elif kind == 'JointTrajectoryController':
            self._sub(JointTrajectory, system.topics['trajectory'],
                      lambda m, law=law: law.follow(_points(m)))
            pub = node.create_publisher(Float32, system.topics['progress'], 10, **NO_EVENTS)
            self._pubs.append(pub)
            self._progress.append((law, pub, [-math.inf]))
        elif kind == 'JointStatePublisher':
            pub = node.create_publisher(JointState, system.topics['joint_state'], 10,
                                        **NO_EVENTS)
            self._pubs.append(pub)
            self._states.append((system, pub, [-math.inf]))
        elif kind == 'PosePublisher':
            pub = node.create_publisher(TFMessage, system.topics['pose'], 10, **NO_EVENTS)
            self._pubs.append(pub)
            self._poses.append((system, pub, [-math.inf]))

    def _sub(self, kind, topic: str, take: Callable) -> None:
        # without QoS event handlers: a subscription destroyed with its model while the
        # executor waits on them ended the node (rclpy's InvalidHandle from spin)
        self._subs.append(self.node.create_subscription(kind, topic, take, 10,
                                                        **NO_SUB_EVENTS))

    def on_sample(self, sample) -> None:
        """Publish what is due at a joint sample's simulated time (the laws ran already)."""
        t = sample.time
        for law, odo in self._odometry:
            if t >= odo.next:
                odo.next = t + odo.period - 1e-9
                publish_odometry(odo, law.snapshot(), t)
        for law, pub, due in self._progress:
            if law.points and t >= due[0]:
                due[0] = t + PROGRESS_PERIOD - 1e-9
                pub.publish(Float32(data=float(law.progress)))
        for system, pub, due in self._states:
            if t >= due[0]:
                due[0] = t + 1.0 / system.rate_hz - 1e-9
                names = [j for j in system.joints if j in self.index]
                idx = [self.index[j] for j in names]
                pub.publish(JointState(
                    header=Header(stamp=convert.stamp(t)), name=names,
                    position=[float(sample.position[i]) for i in idx],
                    velocity=[float(sample.velocity[i]) for i in idx],
                    effort=[float(sample.effort[i]) for i in idx]))
        for system, pub, due in self._poses:
            if t >= due[0]:
                due[0] = t + 1.0 / system.rate_hz - 1e-9
                msg = self._link_poses(t)
                if msg is not None:
                    pub.publish(msg)

    def _link_poses(self, t: float) -> Optional[TFMessage]:
        world = self.world()
        if world is None:
            return None
        snap = world.snapshot()
        names = snap.info.body_names
        rec = next((e for e in snap.info.entities if e.name == self.entity), None)
        if rec is None:
            return None
        root = rec.root_body
        stamp = convert.stamp(t)
        out = []
        for b in rec.body_ids:
            pos, q = quat.to_frame(snap.body_xpos[root], snap.body_xquat_wxyz[root],
                                   snap.body_xpos[b], snap.body_xquat_wxyz[b])
            own = names[b][len(self.entity) + 1:] if b != root else \
                (snap.info.body_alias[root] or self.entity)[len(self.entity) + 1:] or 'link'
            out.append(convert.transform(self.entity, f'{self.entity}::{own.replace("/", "::")}',
                                         pos, q, stamp))
        return TFMessage(transforms=out)

    def close(self) -> None:
        self._sample(self.key, [], 0.0)
        for s in self._subs:
            self.node.destroy_subscription(s)
        for p in self._pubs:
            self.node.destroy_publisher(p)
        self._subs, self._pubs = [], []


def _points(msg: JointTrajectory) -> list:
    """Return a JointTrajectory's points as (seconds from its start, {joint: position})."""
    out = []
    for p in msg.points:
        t = float(p.time_from_start.sec) + 1e-9 * float(p.time_from_start.nanosec)
        values = [float(v) for v in p.positions]
        if len(values) == len(msg.joint_names) and all(np.isfinite(values)):
            out.append((t, dict(zip(msg.joint_names, values))))
    return out


class GzSystems:
    """The gz-sim systems of every entity of the loaded world: made and closed as they come."""

    def __init__(self, node: Node, session: Session):
        self.node, self.session = node, session
        self._sets: dict = {}  # entity -> (its systems, SystemSet)
        self._lock = threading.Lock()

    def _sample(self, key: str, joints: list, rate: float, sensors: bool = False,
                tick=None) -> None:
        loaded = self.session.loaded
        if loaded is not None:
            loaded.world.sample_joints(key, joints, rate, sensors, tick)

    def _world(self):
        loaded = self.session.loaded
        return loaded.world if loaded is not None else None

    def on_model(self, loaded: Optional[Loaded], snap) -> None:
        """Follow a new model (the session's listener): sets made, kept or closed."""
        info = None if snap is None else snap.info
        wanted = dict(info.gz_systems) if info is not None else {}
        with self._lock:
            gone = [e for e, (systems, _) in self._sets.items()
                    if wanted.get(e, (None, None))[1] != systems]
            closing = [self._sets.pop(e)[1] for e in gone]
        for s in closing:
            s.close()
        for entity, (_, systems) in wanted.items():
            with self._lock:
                if entity in self._sets:
                    continue
            try:
                made = SystemSet(self.node, entity, systems, info.timestep, info.joint_names,
                                 self._sample, self._world)
            except Exception as exc:  # noqa: B902 (one entity's systems stop no other's)
                self.node.get_logger().error(f'the gz-sim systems of {entity!r} are not run: '
                                             f'{exc}')
                continue
            with self._lock:
                self._sets[entity] = (systems, made)

    def on_samples(self, samples: list) -> None:
        """Publish for each set on its joint samples (the node's drain of the loop's)."""
        with self._lock:
            sets = {s.key: s for _, s in self._sets.values()}
        for sample in samples:
            s = sets.get(getattr(sample, 'key', None))
            if s is not None:
                s.on_sample(sample)

    def close(self) -> None:
        with self._lock:
            sets, self._sets = [s for _, s in self._sets.values()], {}
        for s in sets:
            s.close()
