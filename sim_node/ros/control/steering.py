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
interfaces the controller claims; odometry comes from the wheels, in simulated time. The law
(:class:`~sim_node.core.control.laws.SteeringLaw`) runs on the stepping side at the
controller's update rate; this module is its topics.
"""

from nav_msgs.msg import Odometry
from tf2_msgs.msg import TFMessage

from .controllers import BaseController, NO_EVENTS
from ...core.control import controller_types as types


class Steering(BaseController):
    """A car-like base's controller (see the module docstring); its law is SteeringLaw."""

    def make(self) -> None:
        p, kind = self.params, types.REGISTRY[self.controller.kind]
        tricycle = kind is types.Tricycle
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
