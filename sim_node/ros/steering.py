"""
Car-like bases as ros2_controllers drive them: the steering controllers and the tricycle.

* ``ackermann_steering_controller`` and ``bicycle_steering_controller`` (steering_controllers_
  library): ``~/reference`` (geometry_msgs/TwistStamped; ``~/reference_unstamped`` Twist with
  ``use_stamped_vel: false``), ``~/odometry`` (nav_msgs/Odometry) and ``~/tf_odometry``
  (tf2_msgs/TFMessage, as theirs: remap it to /tf), ``odom_frame_id`` -> ``base_frame_id``;
  ``rear_wheels_names`` drive and ``front_wheels_names`` steer (``front_steering: false``: the
  other way round); ``wheelbase``, ``front_wheel_track`` and the wheel radii; stopped after
  ``reference_timeout`` simulated seconds without a reference.
* ``tricycle_controller``: ``~/cmd_vel`` (TwistStamped), ``~/odom`` and the odom TF on /tf;
  ``traction_joint_name`` (the steered wheel that drives), ``steering_joint_name``,
  ``wheel_radius``, ``wheelbase``; ``cmd_vel_timeout`` in milliseconds, as its own.

Steering joints take position commands, traction joints velocity commands, through the
interfaces the controller claims; odometry comes from the wheels, in simulated time.
"""

import math
from typing import Optional

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from tf2_msgs.msg import TFMessage

from .controllers import BaseController, NO_EVENTS, NO_SUB_EVENTS, publish_odometry
from ..core.control import controller_types as types
from ..core.control import steering


class Steering(BaseController):
    """A car-like base's controller (see the module docstring)."""

    def make(self) -> None:
        p, kind = self.params, self.controller.kind
        self.traction, self.steering = types.steering_joints(kind, p)
        self.length = float(p['wheelbase'])
        radius = {types.ACKERMANN: 'rear_wheels_radius', types.BICYCLE: 'rear_wheel_radius',
                  types.TRICYCLE: 'wheel_radius'}[kind]
        self.radius = float(p[radius])
        self.track = float(p.get('rear_wheel_track') or p.get('front_wheel_track') or 0.0)
        self.odometry = steering.SteeringOdometry(self.length, self.radius,
                                                  kind == types.TRICYCLE)
        tricycle = kind == types.TRICYCLE
        timeout = p.get('cmd_vel_timeout', 500) if tricycle else p.get('reference_timeout', 1.0)
        self.timeout = float(timeout) / (1000.0 if tricycle else 1.0)
        self.odom_frame = str(p.get('odom_frame_id', 'odom'))
        self.base_frame = str(p.get('base_frame_id', 'base_link'))
        self.command: Optional[tuple] = None
        stamped = p.get('use_stamped_vel', True) is not False
        topic = '~/reference' if stamped else '~/reference_unstamped'
        topic = '~/cmd_vel' if tricycle else topic
        self.node.create_subscription(TwistStamped if stamped or tricycle else Twist, topic,
                                      self._on_twist, 10, **NO_SUB_EVENTS)
        self.odom_pub = self.node.create_publisher(
            Odometry, '~/odom' if tricycle else '~/odometry', 10, **NO_EVENTS)
        self.tf_pub = None
        if p.get('enable_odom_tf', True) is not False:
            self.tf_pub = self.node.create_publisher(
                TFMessage, '/tf' if tricycle else '~/tf_odometry', 100, **NO_EVENTS)
        self.topic = topic.lstrip('~/')

    def _on_twist(self, msg) -> None:
        twist = msg.twist if isinstance(msg, TwistStamped) else msg
        v, w = twist.linear.x, twist.angular.z
        if not (math.isfinite(v) and math.isfinite(w)):
            self.refuse(self.topic, f'a twist that is not finite: ({v}, {w})')
            return
        if self.active:
            self.command = (v, w, self.host.sim_time())
            self._drive(v, w)

    def _drive(self, v: float, w: float) -> None:
        kind = self.controller.kind
        if kind == types.ACKERMANN:
            out = steering.ackermann(self.length, self.track, self.radius, v, w)
        elif kind == types.BICYCLE:
            out = steering.bicycle(self.length, self.radius, v, w)
        else:
            out = steering.tricycle(self.length, self.radius, v, w)
        angles = list(out.steering) * len(self.steering) if len(out.steering) == 1 \
            else list(out.steering)[:len(self.steering)]
        speeds = list(out.traction) * len(self.traction) if len(out.traction) == 1 \
            else list(out.traction)[:len(self.traction)]
        self.host.command(self.steering, angles, 'position')
        self.host.command(self.traction, speeds, 'velocity')

    def update(self, sample, index: dict) -> None:
        t = sample.time
        self.stop_if_stale(t)
        wheel = sum(sample.position[index[j]] for j in self.traction) / len(self.traction)
        angle = sum(sample.position[index[j]] for j in self.steering) / len(self.steering)
        self.odometry.update(t, wheel, angle)
        publish_odometry(self, t)
