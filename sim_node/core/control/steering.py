"""
Car-like bases as ros2_controllers steer them: bicycle, Ackermann, tricycle. ROS-free.

A body twist (forward speed v, turn rate w) becomes steering angles and traction wheel speeds
for a base with steered front wheels and a ``wheelbase`` L between its axles (turning about a
point on the rear axle's line, radius v / w): :func:`bicycle`, :func:`ackermann`,
:func:`tricycle`. :class:`~.odometry.SteeringOdometry` turns the wheels' motion back into the
base's pose, as the controllers' odometry does (rear traction: the rear axle's speed; steered
traction: the wheel's speed along its heading).
"""

import math
from typing import NamedTuple


class Steered(NamedTuple):
    """Steering angles (rad) and traction wheel speeds (rad/s), in the YAML's joint order."""

    steering: tuple
    traction: tuple


def bicycle(length: float, radius: float, v: float, w: float) -> Steered:
    """One steered front wheel, one rear traction wheel."""
    if abs(v) < 1e-9:  # no speed: it cannot turn in place; the wheel keeps straight
        return Steered((0.0,), (0.0,))
    return Steered((math.atan(w * length / v),), (v / radius,))


def ackermann(length: float, track: float, radius: float, v: float, w: float) -> Steered:
    """
    Two steered front wheels on their own circles, two rear traction wheels: each (right, left).

    Jazzy's ackermann_steering_controller takes the first of ``rear_wheels_names`` and of
    ``front_wheels_names`` as the right wheel and the second as the left (its
    ``CMD_TRACTION_RIGHT_WHEEL`` is 0, ``CMD_STEER_RIGHT_WHEEL`` the first steering command),
    and so does this: a YAML that lists the left wheel first steers its inner wheel as the
    outer one, here as there.
    """
    if abs(v) < 1e-9:
        return Steered((0.0, 0.0), (0.0, 0.0))
    half = track / 2.0
    left = math.atan(w * length / (v - w * half))
    right = math.atan(w * length / (v + w * half))
    return Steered((right, left), ((v + w * half) / radius, (v - w * half) / radius))


def tricycle(length: float, radius: float, v: float, w: float) -> Steered:
    """One steered front wheel that also drives (tricycle_controller's)."""
    if abs(v) < 1e-9 and abs(w) < 1e-9:
        return Steered((0.0,), (0.0,))
    angle = math.atan2(w * length, v) if v >= 0 else math.atan2(-w * length, -v)
    speed = math.hypot(v, w * length) * (1.0 if v >= 0 else -1.0)
    return Steered((angle,), (speed / radius,))
