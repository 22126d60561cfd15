"""
Mobile bases for nav2: ``<entity>/cmd_vel`` in, ``<entity>/odom`` and the odom TF out.

Every entity with a mobile base (:mod:`sim_node.core.control.bases`: wheels named left and right,
planar joints, or a URDF's Gazebo drive plugin) gets, made and removed with it:

* a subscription ``<entity>/cmd_vel``: geometry_msgs/Twist (nav2 Jazzy's default), or
  TwistStamped with ``cmd_vel_stamped``; a command not finite or beyond 50 m/s or 50 rad/s is
  refused, on /diagnostics. No command for ``cmd_vel_timeout`` simulated seconds stops the base;
* a publisher ``<entity>/odom`` (nav_msgs/Odometry) at ``odom_rate_hz``: frame
  ``<entity>/odom`` (where the base started), child ``<entity>``: the frame the odom TF goes
  to (REP 105, robot_localization and nav2's ``robot_base_frame``), twist in it;
  ``odom_source`` ``wheels`` (integrated from the wheel joints: drifts with slip) or
  ``ground_truth``; covariance diagonals ``odom_pose_covariance`` and ``odom_twist_covariance``;
* with ``odom_tf`` (default), ``world -> <entity>/odom -> <entity>`` on /tf in place of the
  ``world -> <entity>`` transform the node's /tf carries otherwise, so the tree stays a tree.

For a world with one robot, remap its topic to the plain one: ``-r rover/cmd_vel:=/cmd_vel``.
"""

import threading
from typing import Callable, Optional

from geometry_msgs.msg import Twist, TwistStamped
from msg_adapters import odometry
from msg_adapters.perception import interface_base
from nav_msgs.msg import Odometry
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from tf2_msgs.msg import TFMessage

from ..settings.params import Frames
from ...core.base import quat
from ...core.base.errors import SimError
from ...core.base.records import Snapshot
from ...core.control import bases
from ...core.control.odometry import BaseOdometry
from ...session import Loaded, Session


class _Base:
    """One entity's base: its spec, topics and odometry."""

    def __init__(self, spec: bases.BaseSpec, topic_base: str, sub, pub):
        self.spec, self.topic_base, self.sub, self.pub = spec, topic_base, sub, pub
        self.odometry = BaseOdometry(spec)
        self.start: Optional[tuple] = None  # (position, yaw) where its odom frame is
        self.stamp: Optional[float] = None  # the last one sent (never the same twice)
        self.said: set = set()  # notes on its commands said on /diagnostics, still true


class BaseControllers:
    """
    The base controllers of a node's entities (see the module docstring).

    :param session: the loaded simulation; :meth:`on_model` is its listener.
    :param params: a function of a parameter's name to its value.
    :param tf_elsewhere: told the frames whose world transform these publish.
    :param refused: called (topic, what, why, names) for a refused command.
    """

    def __init__(self, node, callback_group, session: Session, frames: Frames,
                 params: Callable, tf_elsewhere: Callable, refused: Callable):
        self._node, self._group, self._session = node, callback_group, session
        self._frames, self._param = frames, params
        self._tf_elsewhere, self._refused = tf_elsewhere, refused
        self._bases: dict = {}  # entity -> _Base
        self._loaded: Optional[Loaded] = None  # which world: told by the session (on_model)
        self._lock = threading.Lock()
        self._tf_pub = node.create_publisher(TFMessage, '/tf', 100)
        self._timer = node.create_timer(1.0 / float(params('odom_rate_hz')), self._publish,
                                        callback_group=MutuallyExclusiveCallbackGroup())

    def on_model(self, loaded: Optional[Loaded], snap: Optional[Snapshot]) -> None:
        """Listen to the session's new models: the bases of the model's entities."""
        self._loaded = loaded  # the odometry timer publishes from this world's snapshots
        found = {} if loaded is None or snap is None else loaded.world.bases()
        topics = {e.name: interface_base(e) for e in snap.info.entities} if snap else {}
        with self._lock:
            # A base keeps its topics while its entity and their names stay: a subscription
            # made anew is one a publisher must match again, and commands sent meanwhile were
            # lost (a base's cmd_vel was made anew at every spawn and delete of anything).
            for entity in [e for e, b in self._bases.items()
                           if e not in found or topics.get(e) != b.topic_base]:
                base = self._bases.pop(entity)
                self._node.destroy_subscription(base.sub)
                self._node.destroy_publisher(base.pub)
            for entity, spec in found.items():
                base = self._bases.get(entity)
                if base is None:
                    self._bases[entity] = self._make(spec, topics[entity])
                elif base.spec != spec:  # its wheels changed: its odometry starts again
                    base.spec, base.odometry = spec, BaseOdometry(spec)
            elsewhere = frozenset(self._bases) if self._param('odom_tf') else frozenset()
        self._tf_elsewhere(elsewhere)

    def close(self) -> None:
        self._node.destroy_timer(self._timer)
        with self._lock:
            for base in self._bases.values():
                self._node.destroy_subscription(base.sub)
                self._node.destroy_publisher(base.pub)
            self._bases.clear()

    def _make(self, spec: bases.BaseSpec, topic_base: str) -> _Base:
        stamped = bool(self._param('cmd_vel_stamped'))
        sub = self._node.create_subscription(
            TwistStamped if stamped else Twist, f'{topic_base}/cmd_vel',
            lambda msg: self._on_command(spec.entity, topic_base,
                                         msg.twist if stamped else msg), 10,
            callback_group=self._group,
            # No QoS event handlers: they are waitables, and one whose subscription was
            # destroyed (a base deleted) while the executor built its wait set ended the node
            # with InvalidHandle (seen once in CI, a spawn-tool test deleting its cart).
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        pub = self._node.create_publisher(
            Odometry, f'{topic_base}/odom', 10,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
        return _Base(spec, topic_base, sub, pub)

    def _on_command(self, entity: str, topic_base: str, twist) -> None:
        loaded = self._session.loaded
        if loaded is None:
            return
        try:
            notes = loaded.world.drive(entity, twist.linear.x, twist.linear.y,
                                       twist.angular.z, float(self._param('cmd_vel_timeout')))
        except SimError as exc:
            self._refused(f'{topic_base}/cmd_vel', 'velocity command', str(exc), [entity])
            return
        with self._lock:
            base = self._bases.get(entity)
            new = [n for n in notes if base is not None and n not in base.said]
            if base is not None:
                base.said = set(notes)  # said again once it has stopped being true
        for note in new:
            self._refused(f'{topic_base}/cmd_vel', 'velocity command', note, [entity],
                          verdict='taken in part')

    # ------------------------------------------------------------------ odometry

    def _publish(self) -> None:
        loaded = self._loaded
        if loaded is None or loaded.loop is None:
            return
        snap = loaded.loop.latest_snapshot()
        info = snap.info
        truth = self._param('odom_source') == 'ground_truth'
        with_tf = bool(self._param('odom_tf'))
        pose_cov = list(self._param('odom_pose_covariance'))
        twist_cov = list(self._param('odom_twist_covariance'))
        prefix, transforms = self._frames.prefix, []
        with self._lock:
            items = list(self._bases.items())
        joints = {n: i for i, n in enumerate(info.joint_names)}
        for entity, base in items:
            root = next((e.root_body for e in info.entities if e.name == entity), None)
            if root is None or base.stamp == snap.time:
                continue
            base.stamp = snap.time
            pos, q = snap.body_xpos[root], snap.body_xquat_wxyz[root]
            if base.start is None or (base.odometry.time or 0.0) > snap.time:  # a reset
                base.start = (pos.copy(), quat.yaw_of(q))
                base.odometry = BaseOdometry(base.spec)
            wheels = [joints.get(n) for n in base.spec.wheels]
            if truth or not wheels or None in wheels:
                base.odometry.from_pose(snap.time, pos, quat.yaw_of(q))
            else:
                base.odometry.from_wheels(snap.time, snap.joint_position[wheels])
            odom_pos, odom_q = odometry.base_pose(base.odometry, base.start, pos, q)
            frame = f'{prefix}{entity}/{base.spec.odom_frame}'
            child = prefix + entity  # the odom TF's child: one base frame (REP 105)
            msg = odometry.message(base.odometry, snap.time, frame, child, odom_pos, odom_q,
                                   pose_cov, twist_cov)
            with self._lock:  # a spawn's on_model may have destroyed its publisher meanwhile
                if self._bases.get(entity) is not base:
                    continue
                base.pub.publish(msg)
            if with_tf:
                where, turn = odometry.odom_frame_in_world(pos, q, odom_pos, odom_q)
                transforms += odometry.transforms(snap.time, self._frames.out_world, frame,
                                                  prefix + entity, where, turn, odom_pos,
                                                  odom_q)
        if transforms:
            self._tf_pub.publish(TFMessage(transforms=transforms))
