"""
A differential drive as diff_drive_controller computes it: wheel speeds and odometry. ROS-free.

:func:`wheel_speeds` turns a body twist into left and right wheel speeds (rad/s) with the
YAML's wheel separation and radii (and their multipliers); :class:`WheelOdometry` integrates
the wheels' positions into a pose in the odom frame (second-order Runge-Kutta, exact arcs for
a turning base, as the controller's odometry does), in simulated time.
"""

import math
from typing import NamedTuple

import numpy as np

from ..base import quat


class Geometry(NamedTuple):
    """A diff drive's wheel separation and wheel radii (m), multipliers applied."""

    separation: float
    left_radius: float
    right_radius: float

    @classmethod
    def of(cls, params: dict) -> 'Geometry':
        """From diff_drive_controller's parameters (``wheel_separation``, ``*_multiplier``)."""
        radius = float(params['wheel_radius'])
        return cls(float(params['wheel_separation'])
                   * float(params.get('wheel_separation_multiplier', 1.0)),
                   radius * float(params.get('left_wheel_radius_multiplier', 1.0)),
                   radius * float(params.get('right_wheel_radius_multiplier', 1.0)))


def wheel_speeds(geometry: Geometry, v: float, w: float) -> tuple:
    """Return (left, right) wheel speeds (rad/s) for a forward speed `v` and a turn rate `w`."""
    half = geometry.separation / 2.0
    return (v - w * half) / geometry.left_radius, (v + w * half) / geometry.right_radius


class WheelOdometry:
    """The base's pose (x, y, yaw) and twist (v, w) from its wheels, in simulated time."""

    def __init__(self, geometry: Geometry):
        self.geometry = geometry
        self.x = self.y = self.yaw = self.v = self.w = 0.0
        self._last = None  # (time, left position, right position)

    def reset(self) -> None:
        self.x = self.y = self.yaw = self.v = self.w = 0.0
        self._last = None

    def update(self, t: float, left: float, right: float) -> None:
        """Take the wheels' mean positions (rad) at simulated time `t`."""
        if self._last is None or t <= self._last[0]:
            self._last = (t, left, right)
            return
        t0, l0, r0 = self._last
        self._last = (t, left, right)
        dl = (left - l0) * self.geometry.left_radius
        dr = (right - r0) * self.geometry.right_radius
        ds, dyaw = (dl + dr) / 2.0, (dr - dl) / self.geometry.separation
        mid = self.yaw + dyaw / 2.0  # second-order Runge-Kutta
        self.x += ds * math.cos(mid)
        self.y += ds * math.sin(mid)
        self.yaw = math.atan2(math.sin(self.yaw + dyaw), math.cos(self.yaw + dyaw))
        dt = t - t0
        self.v, self.w = ds / dt, dyaw / dt

    def quat_wxyz(self) -> np.ndarray:
        return quat.from_yaw(self.yaw)
