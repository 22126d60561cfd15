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
  acceleration and jerk limits (:mod:`sim_node.core.control.limits`). Its law (the timeout,
  the limits, the wheels' speeds, the odometry) runs on the stepping side at its update rate
  of simulated time (:mod:`sim_node.core.control.laws`), this its topics only.
* ``joint_trajectory_controller``: :mod:`.jtc`.

A command that cannot be taken (a wrong length, a value not finite) is refused with its reason
logged and put on /diagnostics; the world steps on.
"""

import math

from geometry_msgs.msg import Twist, TwistStamped
from msg_adapters import convert, odometry
from nav_msgs.msg import Odometry
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage

from ...core.control import controller_types as types, laws

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
        self.law = None  # its law on the stepping side, if its type has one
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
        self.law = laws.law_for(types.REGISTRY.get(self.controller.kind), self.params,
                                self.controller.update_rate)
        self.make()
        self.host.put_law(self.name, self.law)

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
        if self.law is not None:
            self.host.put_law(self.name, None)
            self.law.deactivate()
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
    What the base controllers' ROS sides share: a twist taken, odometry published.

    The law (:class:`~sim_node.core.control.laws.BaseLaw`: the timeout, the limits, the
    kinematics, the odometry) runs on the stepping side; this takes the twists on
    :attr:`topic` (:meth:`subscribe`) and publishes the law's odometry every ``period`` of
    simulated time (0: at every update). A subclass makes its topics in :meth:`make`.
    """

    topic = 'cmd_vel'
    period = 0.0

    def subscribe(self, stamped: bool, topic: str) -> None:
        self.topic = topic
        self.node.create_subscription(TwistStamped if stamped else Twist, f'~/{topic}',
                                      self._on_twist, 10, **NO_SUB_EVENTS)

    def activate(self, sample) -> None:
        super().activate(sample)
        self.next_publish = -math.inf
        self.host.write(self.law.activate())

    def deactivate(self) -> None:
        super().deactivate()
        self.host.write(self.law.deactivate())

    def _on_twist(self, msg) -> None:
        twist = msg.twist if isinstance(msg, TwistStamped) else msg
        v, w = twist.linear.x, twist.angular.z
        if not (math.isfinite(v) and math.isfinite(w)):
            self.refuse(self.topic, f'a twist that is not finite: ({v}, {w})')
            return
        if self.active:
            self.law.take(v, w)

    def update(self, sample, index: dict) -> None:
        if sample.time < self.next_publish:
            return
        self.next_publish = sample.time + self.period - 1e-9
        publish_odometry(self, self.law.snapshot(), sample.time)


class DiffDrive(BaseController):
    """diff_drive_controller: ``~/cmd_vel`` in, ``~/odom`` and the odom TF out."""

    def make(self) -> None:
        p = self.params
        self.odom_frame, self.base_frame = p['odom_frame_id'], p['base_frame_id']
        self.period = 1.0 / p['publish_rate']
        self.subscribe(p['use_stamped_vel'], 'cmd_vel')
        self.odom_pub = self.node.create_publisher(Odometry, '~/odom', 10, **NO_EVENTS)
        self.tf_pub = (self.node.create_publisher(TFMessage, '/tf', 100, **NO_EVENTS)
                       if p['enable_odom_tf'] else None)


def publish_odometry(ctl, o, t: float) -> None:
    """
    Publish a base controller's odometry `o` (planar, its law's) of simulated time `t`.

    On ``ctl.odom_pub`` from ``ctl.odom_frame`` to ``ctl.base_frame``, with the YAML's
    ``pose_covariance_diagonal`` and ``twist_covariance_diagonal`` (six finite values each,
    else zeros), and that transform on ``ctl.tf_pub`` when it has one. The stamp is the
    odometry's own time (its last update, on the stepping side) once it has one.
    """
    t = o.time if o.time is not None else t
    where = (o.x, o.y, 0.0)
    ctl.odom_pub.publish(odometry.message(
        o, t, ctl.odom_frame, ctl.base_frame, where, o.quat_wxyz(),
        ctl.params['pose_covariance_diagonal'], ctl.params['twist_covariance_diagonal']))
    if ctl.tf_pub is not None:
        ctl.tf_pub.publish(TFMessage(transforms=[convert.transform(
            ctl.odom_frame, ctl.base_frame, where, o.quat_wxyz(), convert.stamp(t))]))
