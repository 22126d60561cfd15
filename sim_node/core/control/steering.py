"""
Car-like bases as ros2_controllers steer them: bicycle, Ackermann, tricycle. ROS-free.

A body twist (forward speed v, turn rate w) becomes steering angles and traction wheel speeds
for a base with steered front wheels and a ``wheelbase`` L between its axles (turning about a
point on the rear axle's line, radius v / w): :func:`bicycle`, :func:`ackermann`,
:func:`tricycle`. :class:`SteeringOdometry` turns the wheels' motion back into the base's pose,
as the controllers' odometry does (rear traction: the rear axle's speed; steered traction: the
wheel's speed along its heading).
"""

import math
from typing import NamedTuple

import numpy as np

from ..base import quat


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
    """Two steered front wheels on their own circles (left, right), two rear traction wheels."""
    if abs(v) < 1e-9:
        return Steered((0.0, 0.0), (0.0, 0.0))
    half = track / 2.0
    left = math.atan(w * length / (v - w * half))
    right = math.atan(w * length / (v + w * half))
    return Steered((left, right), ((v - w * half) / radius, (v + w * half) / radius))


def tricycle(length: float, radius: float, v: float, w: float) -> Steered:
    """One steered front wheel that also drives (tricycle_controller's)."""
    if abs(v) < 1e-9 and abs(w) < 1e-9:
        return Steered((0.0,), (0.0,))
    angle = math.atan2(w * length, v) if v >= 0 else math.atan2(-w * length, -v)
    speed = math.hypot(v, w * length) * (1.0 if v >= 0 else -1.0)
    return Steered((angle,), (speed / radius,))


class SteeringOdometry:
    """The base's pose (x, y, yaw) and twist (v, w) from its wheels, in simulated time."""

    def __init__(self, length: float, radius: float, steered_traction: bool):
        self.length, self.radius, self.steered_traction = length, radius, steered_traction
        self.x = self.y = self.yaw = self.v = self.w = 0.0
        self._last = None  # (time, traction wheel position)

    def reset(self) -> None:
        self.x = self.y = self.yaw = self.v = self.w = 0.0
        self._last = None

    def update(self, t: float, wheel: float, steering: float) -> None:
        """Take the traction wheels' mean position (rad) and the mean steering angle (rad)."""
        if self._last is None or t <= self._last[0]:
            self._last = (t, wheel)
            return
        t0, w0 = self._last
        self._last = (t, wheel)
        ds = (wheel - w0) * self.radius
        if self.steered_traction:  # the wheel's travel along its heading
            ds, dyaw = ds * math.cos(steering), ds * math.sin(steering) / self.length
        else:
            dyaw = ds * math.tan(steering) / self.length
        mid = self.yaw + dyaw / 2.0
        self.x += ds * math.cos(mid)
        self.y += ds * math.sin(mid)
        self.yaw = math.atan2(math.sin(self.yaw + dyaw), math.cos(self.yaw + dyaw))
        self.v, self.w = ds / (t - t0), dyaw / (t - t0)

    def quat_wxyz(self) -> np.ndarray:
        return quat.from_yaw(self.yaw)
