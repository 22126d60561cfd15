"""
Car-like bases as ros2_controllers drive them: the steering controllers and the tricycle.

* ``ackermann_steering_controller`` and ``bicycle_steering_controller`` (steering_controllers_
  library): ``~/reference`` (geometry_msgs/TwistStamped; ``~/reference_unstamped`` Twist with
  ``use_stamped_vel: false``), ``~/odometry`` (nav_msgs/Odometry) and ``~/tf_odometry``
  (tf2_msgs/TFMessage, as theirs: remap it to /tf), ``odom_frame_id`` -> ``base_frame_id``;
  ``rear_wheels_names`` drive and ``front_wheels_names`` steer (``front_steering: false``: the
  other way round); ``wheelbase``, ``front_wheel_track`` and the wheel radii; stopped after
  ``reference_timeout`` simulated seconds without a reference.
* ``tricycle_controller``: ``~/cmd_vel`` (TwistStamped), ``~/odom`` and, with
  ``enable_odom_tf`` (off by default, as its own), the odom TF on /tf;
  ``traction_joint_name`` (the steered wheel that drives), ``steering_joint_name``,
  ``wheel_radius``, ``wheelbase``; ``cmd_vel_timeout`` in milliseconds, as its own; the
  ``traction.*`` and ``steering.*`` limits (:mod:`sim_node.core.control.limits`) once per
  update, and the wheel slowed while it is far from its angle (cos of the error; 0.01 beyond
  90 degrees), as the real one.

Steering joints take position commands, traction joints velocity commands, through the
interfaces the controller claims; odometry comes from the wheels, in simulated time.
"""

import math

from nav_msgs.msg import Odometry
from tf2_msgs.msg import TFMessage

from .controllers import BaseController, NO_EVENTS, publish_odometry
from ...core.control import controller_types as types
from ...core.control import limits, steering
from ...core.control.odometry import SteeringOdometry


class Steering(BaseController):
    """A car-like base's controller (see the module docstring)."""

    def make(self) -> None:
        p, self.type = self.params, types.REGISTRY[self.controller.kind]
        tricycle = self.type is types.Tricycle
        self.traction, self.steering = self.type.joints(p)
        self.length = p['wheelbase']
        self.radius = p[self.type.radius]
        self.track_width = p.get('rear_wheel_track') or p.get('front_wheel_track') or 0.0
        self.odometry = SteeringOdometry(self.length, self.radius, tricycle)
        self.limiters = (limits.traction(p), limits.steering(p)) if tricycle else None
        self.timeout = p['cmd_vel_timeout'] / 1000.0 if tricycle else p['reference_timeout']
        self.odom_frame, self.base_frame = p['odom_frame_id'], p['base_frame_id']
        stamped = p['use_stamped_vel']
        self.subscribe(stamped or tricycle, 'cmd_vel' if tricycle else (
            'reference' if stamped else 'reference_unstamped'))
        self.odom_pub = self.node.create_publisher(
            Odometry, '~/odom' if tricycle else '~/odometry', 10, **NO_EVENTS)
        self.tf_pub = None
        if p['enable_odom_tf']:  # the tricycle's default is false
            self.tf_pub = self.node.create_publisher(
                TFMessage, '/tf' if tricycle else '~/tf_odometry', 100, **NO_EVENTS)

    def activate(self, sample) -> None:
        super().activate(sample)
        self.history = [(0.0, 0.0), (0.0, 0.0)]  # (speed, angle) sent last, and before

    def _outputs(self, v: float, w: float) -> steering.Steered:
        if self.type is types.Ackermann:
            return steering.ackermann(self.length, self.track_width, self.radius, v, w)
        if self.type is types.Bicycle:
            return steering.bicycle(self.length, self.radius, v, w)
        return steering.tricycle(self.length, self.radius, v, w)

    def steer(self, v: float, w: float, dt: float, sample, index: dict) -> None:
        if self.limiters is None:
            self._drive(v, w)
            return
        out = self._outputs(v, w)  # the tricycle: one steered wheel that drives
        angle, speed = out.steering[0], out.traction[0]
        # As tricycle_controller: the wheel slows while it is far from its angle.
        off = abs(angle - float(sample.position[index[self.steering[0]]]))
        speed *= 1.0 if off < math.pi / 6 else 0.01 if off > math.pi / 2 else math.cos(off)
        (s0, a0), (s1, a1) = self.history
        speed = self.limiters[0].limit(speed, s0, s1, dt)
        angle = self.limiters[1].limit(angle, a0, a1, dt)
        self.history = [(speed, angle), (s0, a0)]
        self._send([angle], [speed])

    def _drive(self, v: float, w: float) -> None:
        out = self._outputs(v, w)
        self._send(list(out.steering), list(out.traction))

    def _send(self, angles: list, speeds: list) -> None:
        angles = angles * len(self.steering) if len(angles) == 1 else angles[:len(self.steering)]
        speeds = speeds * len(self.traction) if len(speeds) == 1 else speeds[:len(self.traction)]
        self.send(self.steering, angles, 'position')
        self.send(self.traction, speeds, 'velocity')

    def track(self, t: float, sample, index: dict) -> None:
        wheel = sum(sample.position[index[j]] for j in self.traction) / len(self.traction)
        angle = sum(sample.position[index[j]] for j in self.steering) / len(self.steering)
        self.odometry.update(t, wheel, angle)
        publish_odometry(self, t)
