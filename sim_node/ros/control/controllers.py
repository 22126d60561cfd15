"""
The controllers a robot's YAML names, with the ROS interfaces of ros2_controllers' ones.

Each loaded controller is a node named as the controller in the robot's namespace (so
``ros2 param get /<controller> joints`` answers), made when it is configured, with the topics
the real controller has relative to that name:

* ``joint_state_broadcaster``: ``/<ns>/joint_states`` (sensor_msgs/JointState) at its update
  rate of simulated time: the ``joints`` parameter's (else every ros2_control joint's) URDF
  names, then ``extra_joints`` (zeros);
* ``forward_command_controller`` and the JointGroup position, velocity and effort controllers:
  ``~/commands`` (std_msgs/Float64MultiArray, one value per joint, in the ``joints`` order),
  within the interfaces' ``min``/``max``;
* ``diff_drive_controller``: ``~/cmd_vel`` (geometry_msgs/TwistStamped, or Twist with
  ``use_stamped_vel: false``), stopped after ``cmd_vel_timeout`` simulated seconds without
  one; ``~/odom`` (nav_msgs/Odometry, ``odom_frame_id`` -> ``base_frame_id``, from the
  wheels) and, with ``enable_odom_tf``, that transform on ``/tf``, at ``publish_rate``; the
  twist is limited once per update by the ``linear.x`` and ``angular.z`` velocity,
  acceleration and jerk limits (:mod:`sim_node.core.control.limits`).
* ``joint_trajectory_controller``: :mod:`.jtc`.

A command that cannot be taken (a wrong length, a value not finite) is refused with its reason
logged and put on /diagnostics; the world steps on.
"""

import math
from typing import Optional

from geometry_msgs.msg import Twist, TwistStamped
from msg_adapters import convert, odometry
from nav_msgs.msg import Odometry
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage

from ...core.control import controller_types as types
from ...core.control import diff_drive, limits

NO_EVENTS = {'event_callbacks': PublisherEventCallbacks(use_default_callbacks=False)}
NO_SUB_EVENTS = {'event_callbacks': SubscriptionEventCallbacks(use_default_callbacks=False)}


class Runtime:
    """
    One controller's ROS side; `host` is its robot's manager (:mod:`.controller_manager`).

    :meth:`configure` makes its node and topics, :meth:`activate` / :meth:`deactivate` turn it
    on and off, :meth:`update` runs at its update rate with the joints' sample.
    """

    def __init__(self, host, controller):
        self.host, self.controller = host, controller
        self.node = None
        self.active = False
        self.next_update = -math.inf

    @property
    def name(self) -> str:
        return self.controller.name

    @property
    def params(self) -> dict:
        return self.controller.params

    def configure(self) -> None:
        self.destroy()
        self.node = self.host.make_node(self.name, self.params)
        self.make()

    def make(self) -> None:
        """Make the controller's publishers and subscriptions on :attr:`node`."""

    def activate(self, sample) -> None:
        self.active = True
        self.next_update = -math.inf

    def deactivate(self) -> None:
        self.active = False

    def after_reset(self, sample) -> None:
        """Start again from the state a reset of the world put the joints in (when active)."""
        self.activate(sample)

    def update(self, sample, index: dict) -> None:
        """Run once per update period with the joints' sample (`index`: URDF name -> i)."""

    def destroy(self) -> None:
        node = self.node
        self.release()
        if node is not None:
            self.host.drop_node(node)

    def release(self) -> None:
        """Let go of its node (which the caller destroys) and its action server if any."""
        server = getattr(self, 'server', None)
        if server is not None and self.node is not None:
            server.destroy()
        self.active = False
        self.node = None

    def refuse(self, topic: str, why: str, names=()) -> None:
        self.host.refused(f'{self.node.get_namespace().rstrip("/")}/{self.name}/{topic}',
                          f'{self.name} command', why, list(names))


class JointStateBroadcaster(Runtime):
    """joint_state_broadcaster: the joints' states on ``joint_states``."""

    def make(self) -> None:
        self.joints = tuple(self.controller.joints)
        self.extra = self.params['extra_joints']
        self.pub = self.node.create_publisher(JointState, self.host.topic('joint_states'), 10,
                                              **NO_EVENTS)

    def update(self, sample, index: dict) -> None:
        if self.pub.get_subscription_count() == 0:
            return  # nobody listens: nothing to build
        msg = JointState()
        msg.header.stamp = convert.stamp(sample.time)
        known = [j for j in self.joints if j in index]
        msg.name = known + list(self.extra)
        pad = [0.0] * len(self.extra)
        msg.position = [float(sample.position[index[j]]) for j in known] + pad
        msg.velocity = [float(sample.velocity[index[j]]) for j in known] + pad
        msg.effort = [float(sample.effort[index[j]]) for j in known] + pad
        self.pub.publish(msg)


class ForwardCommand(Runtime):
    """forward_command_controller and the JointGroup controllers: ``~/commands``."""

    def make(self) -> None:
        self.joints = tuple(self.controller.joints)
        self.interface = types.GROUPS.get(self.controller.kind) or self.params['interface_name']
        self.node.create_subscription(Float64MultiArray, '~/commands', self._on_command, 10,
                                      **NO_SUB_EVENTS)

    def _on_command(self, msg: Float64MultiArray) -> None:
        if not self.active:
            return  # an inactive controller writes nothing, as the real one
        values = list(msg.data)
        if len(values) != len(self.joints):
            self.refuse('commands', f'{len(values)} values for {len(self.joints)} joints '
                        f'{list(self.joints)}', self.joints)
            return
        if not all(math.isfinite(v) for v in values):
            self.refuse('commands', f'a value that is not finite: {values}', self.joints)
            return
        self.host.command(self.joints, values, self.interface)

    def deactivate(self) -> None:
        super().deactivate()
        self.host.hold(self.joints, self.interface)

    def after_reset(self, sample) -> None:
        super().after_reset(sample)
        self.host.hold(self.joints, self.interface)  # its last command went with the reset


class BaseController(Runtime):
    """
    What the base controllers share: a twist held until it is stale, sent once per update.

    The last twist taken on :attr:`topic` is held until it is older than ``timeout``
    (simulated s; 0: never), then the base stops; each update turns it into wheel commands
    (:meth:`steer`, through the subclass's limits and kinematics) and tracks the odometry
    (:meth:`track`). A subclass has ``odometry`` and ``timeout`` and makes its topics in
    :meth:`make`; :meth:`subscribe` takes the twist.
    """

    topic = 'cmd_vel'

    def subscribe(self, stamped: bool, topic: str) -> None:
        self.topic = topic
        self.node.create_subscription(TwistStamped if stamped else Twist, f'~/{topic}',
                                      self._on_twist, 10, **NO_SUB_EVENTS)

    def activate(self, sample) -> None:
        super().activate(sample)
        self.odometry.reset()
        self.command: Optional[tuple] = None  # (v, w, simulated time it came)
        self.last_update: Optional[float] = None

    def deactivate(self) -> None:
        super().deactivate()
        self._drive(0.0, 0.0)

    def _on_twist(self, msg) -> None:
        twist = msg.twist if isinstance(msg, TwistStamped) else msg
        v, w = twist.linear.x, twist.angular.z
        if not (math.isfinite(v) and math.isfinite(w)):
            self.refuse(self.topic, f'a twist that is not finite: ({v}, {w})')
            return
        if self.active:
            self.command = (v, w, self.host.sim_time())

    def update(self, sample, index: dict) -> None:
        t = sample.time
        period = 1.0 / self.controller.update_rate
        dt = t - self.last_update if self.last_update is not None else period
        self.last_update = t
        if self.command is not None and self.timeout > 0 and t - self.command[2] > self.timeout:
            self.command = None  # stale: the base stops
        v, w = self.command[:2] if self.command is not None else (0.0, 0.0)
        self.steer(v, w, dt, sample, index)
        self.track(t, sample, index)

    def send(self, joints: tuple, values: list, interface: str) -> None:
        """Command `joints` through `interface` (every update, as the real ones write)."""
        self.host.command(joints, values, interface)

    def steer(self, v: float, w: float, dt: float, sample, index: dict) -> None:
        """Send the wheel commands for the twist (v, w), `dt` after the last update."""
        self._drive(v, w)

    def track(self, t: float, sample, index: dict) -> None:
        """Take the wheels' sample into the odometry and publish it when due."""
        raise NotImplementedError

    def _drive(self, v: float, w: float) -> None:
        raise NotImplementedError


class DiffDrive(BaseController):
    """diff_drive_controller: ``~/cmd_vel`` in, ``~/odom`` and the odom TF out."""

    def make(self) -> None:
        p = self.params
        self.left, self.right = p['left_wheel_names'], p['right_wheel_names']
        self.geometry = diff_drive.Geometry.of(p)
        self.odometry = diff_drive.odometry(self.geometry)
        self.limiters = (limits.signed(p, 'linear.x'), limits.signed(p, 'angular.z'))
        self.timeout = p['cmd_vel_timeout']
        self.odom_frame, self.base_frame = p['odom_frame_id'], p['base_frame_id']
        self.period = 1.0 / p['publish_rate']
        self.next_publish = -math.inf
        self.subscribe(p['use_stamped_vel'], 'cmd_vel')
        self.odom_pub = self.node.create_publisher(Odometry, '~/odom', 10, **NO_EVENTS)
        self.tf_pub = (self.node.create_publisher(TFMessage, '/tf', 100, **NO_EVENTS)
                       if p['enable_odom_tf'] else None)

    def activate(self, sample) -> None:
        super().activate(sample)
        self.history = [(0.0, 0.0), (0.0, 0.0)]  # (v, w) sent last, and the time before

    def steer(self, v: float, w: float, dt: float, sample, index: dict) -> None:
        (v0, w0), (v1, w1) = self.history
        v = self.limiters[0].limit(v, v0, v1, dt)
        w = self.limiters[1].limit(w, w0, w1, dt)
        self.history = [(v, w), (v0, w0)]
        self._drive(v, w)

    def _drive(self, v: float, w: float) -> None:
        left, right = diff_drive.wheel_speeds(self.geometry, v, w)
        self.send(self.left + self.right, [left] * len(self.left) + [right] * len(self.right),
                  'velocity')

    def track(self, t: float, sample, index: dict) -> None:
        left = sum(sample.position[index[j]] for j in self.left) / len(self.left)
        right = sum(sample.position[index[j]] for j in self.right) / len(self.right)
        self.odometry.update(t, left, right)
        if t < self.next_publish:
            return
        self.next_publish = t + self.period - 1e-9
        publish_odometry(self, t)


def publish_odometry(ctl, t: float) -> None:
    """
    Publish a base controller's odometry (``ctl.odometry``, planar) at time `t`.

    On ``ctl.odom_pub`` from ``ctl.odom_frame`` to ``ctl.base_frame``, with the YAML's
    ``pose_covariance_diagonal`` and ``twist_covariance_diagonal`` (six finite values each,
    else zeros), and that transform on ``ctl.tf_pub`` when it has one.
    """
    o = ctl.odometry
    where = (o.x, o.y, 0.0)
    ctl.odom_pub.publish(odometry.message(
        o, t, ctl.odom_frame, ctl.base_frame, where, o.quat_wxyz(),
        ctl.params['pose_covariance_diagonal'], ctl.params['twist_covariance_diagonal']))
    if ctl.tf_pub is not None:
        ctl.tf_pub.publish(TFMessage(transforms=[convert.transform(
            ctl.odom_frame, ctl.base_frame, where, o.quat_wxyz(), convert.stamp(t))]))
