"""
A mobile base's odometry on the plane, one integrator for every kind of base. ROS-free.

:class:`PlanarOdometry` is the pose (x, y, yaw) in the odometry frame (where the base started)
and the twist in the base's frame, advanced by what the base travelled in an interval: ``ds``
ahead while turning by ``dyaw``. It integrates as ros2_controllers' odometries do: along the
exact arc of constant curvature (exact for a constant command), by second-order Runge-Kutta
when the base hardly turns (|dyaw| < 1e-6, where the arc's radius is ill-conditioned).

What feeds it, each from its own wheels:

* :class:`DiffDriveOdometry`: left and right wheel angles, their radii and separation
  (diff_drive_controller's, and the node's own bases on wheels, :mod:`.bases`);
* :class:`SteeringOdometry`: the traction wheels' angle and the steering angle
  (the steering controllers' and tricycle_controller's);
* :class:`BaseOdometry`: a node base's wheels, or the simulation's ground truth.
"""

import math
from typing import Optional, Sequence

import numpy as np

from ..base import quat

#: Below this turn in one interval (rad) the arc is integrated by Runge-Kutta instead.
STRAIGHT = 1e-6


class PlanarOdometry:
    """A pose on the plane and a twist in the base's frame, advanced in simulated time."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        """Back to the origin at rest, with no time taken yet."""
        self.x = self.y = self.yaw = 0.0
        self.vx = self.vy = self.wz = 0.0
        self.time: Optional[float] = None

    def advance(self, t: float, ds: float, dyaw: float) -> None:
        """Travel `ds` ahead while turning `dyaw`, from the last time to `t` (simulated s)."""
        if abs(dyaw) < STRAIGHT:
            mid = self.yaw + dyaw / 2.0
            self.x += ds * math.cos(mid)
            self.y += ds * math.sin(mid)
        else:
            r = ds / dyaw
            self.x += r * (math.sin(self.yaw + dyaw) - math.sin(self.yaw))
            self.y -= r * (math.cos(self.yaw + dyaw) - math.cos(self.yaw))
        self.yaw = wrap(self.yaw + dyaw)
        dt = t - self.time if self.time is not None else 0.0
        if dt > 0:
            self.vx, self.vy, self.wz = ds / dt, 0.0, dyaw / dt
        self.time = t

    def quat_wxyz(self) -> np.ndarray:
        return quat.from_yaw(self.yaw)


class DiffDriveOdometry(PlanarOdometry):
    """
    From a differential drive's wheel angles (rad).

    :param left_radius, right_radius: the wheels' radii (m), signs folded in by the caller.
    :param separation: between the left and right wheels (m).
    """

    def __init__(self, left_radius: float, right_radius: float, separation: float):
        self.left_radius, self.right_radius = left_radius, right_radius
        self.separation = separation
        super().__init__()

    def reset(self) -> None:
        super().reset()
        self._wheels: Optional[tuple] = None  # (left, right) at self.time

    def update(self, t: float, left: float, right: float) -> None:
        """Take the left and right wheels' (mean) angles at simulated time `t`."""
        if self._wheels is None or self.time is None or t <= self.time:
            self._wheels, self.time = (left, right), t  # the first, or after a reset
            return
        l0, r0 = self._wheels
        self._wheels = (left, right)
        dl, dr = (left - l0) * self.left_radius, (right - r0) * self.right_radius
        self.advance(t, (dl + dr) / 2.0, (dr - dl) / self.separation)


class SteeringOdometry(PlanarOdometry):
    """
    From a car-like base's traction wheels and steering angle.

    :param length: the wheelbase (m); `radius` the traction wheels' (m).
    :param steered_traction: the traction wheel is the steered one (a tricycle): it travels
        along its own heading, not the base's.
    """

    def __init__(self, length: float, radius: float, steered_traction: bool):
        self.length, self.radius, self.steered_traction = length, radius, steered_traction
        super().__init__()

    def reset(self) -> None:
        super().reset()
        self._wheel: Optional[float] = None

    def update(self, t: float, wheel: float, steering: float) -> None:
        """Take the traction wheels' mean angle (rad) and the mean steering angle (rad)."""
        if self._wheel is None or self.time is None or t <= self.time:
            self._wheel, self.time = wheel, t
            return
        ds = (wheel - self._wheel) * self.radius
        self._wheel = wheel
        if self.steered_traction:
            ds, dyaw = ds * math.cos(steering), ds * math.sin(steering) / self.length
        else:
            dyaw = ds * math.tan(steering) / self.length
        self.advance(t, ds, dyaw)


class BaseOdometry(DiffDriveOdometry):
    """
    A node base's odometry (``<entity>/odom``): from its wheels, or from the ground truth.

    :param spec: its :class:`~.bases.BaseSpec` (wheel radius, separation, signs, the left
        wheels first).
    """

    def __init__(self, spec):
        self.spec = spec
        super().__init__(spec.radius, spec.radius, spec.separation)

    def reset(self) -> None:
        super().reset()
        self._origin: Optional[tuple] = None  # ground truth: the start (position, yaw)

    def from_wheels(self, t: float, angles: Sequence[float]) -> None:
        """Advance to time `t` from the wheel joints' angles (the left wheels, then the right)."""
        turned = np.asarray(angles, dtype=float) * np.asarray(self.spec.signs)
        n = len(self.spec.left)
        self.update(t, float(np.mean(turned[:n])), float(np.mean(turned[n:])))

    def from_pose(self, t: float, position: np.ndarray, yaw: float) -> None:
        """Advance to time `t` from the base's true planar pose in the world."""
        if self._origin is None or self.time is None or t < self.time:
            self._origin, self.time = (np.asarray(position, float)[:2].copy(), yaw), t
            self.x = self.y = self.yaw = 0.0
            return
        o, oyaw = self._origin
        c, s = math.cos(oyaw), math.sin(oyaw)
        rel = np.asarray(position, float)[:2] - o
        x, y = c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]
        new_yaw = wrap(yaw - oyaw)
        dt = t - self.time
        if dt > 0:
            dx, dy = x - self.x, y - self.y
            cy, sy = math.cos(self.yaw), math.sin(self.yaw)
            self.vx, self.vy = (cy * dx + sy * dy) / dt, (-sy * dx + cy * dy) / dt
            self.wz = wrap(new_yaw - self.yaw) / dt
        self.x, self.y, self.yaw, self.time = x, y, new_yaw, t


def wrap(a: float) -> float:
    """Return angle `a` in [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi
