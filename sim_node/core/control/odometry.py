"""
A mobile base's odometry: its pose in its odometry frame, from its wheels or the ground truth.

ROS-free, used by the node's ``<entity>/odom`` (:mod:`sim_node.ros.commands.bases`).
"""

from dataclasses import dataclass, field
import math
from typing import Optional

import numpy as np


@dataclass
class Odometry:
    """
    A base's pose in its odometry frame (where it started), from wheels or from ground truth.

    Wheel odometry integrates each interval along an arc of constant curvature (exact for a
    constant command), as diff_drive_controller does; twist in the base's frame.
    """

    spec: 'BaseSpec'  # noqa: F821 (.bases.BaseSpec: imports this module)
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0
    time: Optional[float] = None
    _wheels: Optional[np.ndarray] = None
    _origin: Optional[tuple] = None  # ground truth: the start pose (position, yaw)
    _last: Optional[tuple] = field(default=None)

    def from_wheels(self, t: float, angles: np.ndarray) -> None:
        """Advance to time `t` from the wheel joints' angles (left then right)."""
        angles = np.asarray(angles, dtype=float)
        if self._wheels is None or self.time is None or t < self.time:
            self._wheels, self.time = angles.copy(), t
            return
        dt = t - self.time
        turn = (angles - self._wheels) * np.asarray(self.spec.signs) * self.spec.radius
        self._wheels, self.time = angles.copy(), t
        n = len(self.spec.left)
        dl, dr = float(np.mean(turn[:n])), float(np.mean(turn[n:]))
        ds, dth = (dl + dr) / 2, (dr - dl) / self.spec.separation
        if abs(dth) < 1e-9:
            dx, dy = ds * math.cos(self.yaw + dth / 2), ds * math.sin(self.yaw + dth / 2)
        else:
            r = ds / dth
            dx = r * (math.sin(self.yaw + dth) - math.sin(self.yaw))
            dy = -r * (math.cos(self.yaw + dth) - math.cos(self.yaw))
        self.x, self.y, self.yaw = self.x + dx, self.y + dy, _wrap(self.yaw + dth)
        if dt > 0:
            self.vx, self.vy, self.wz = ds / dt, 0.0, dth / dt

    def from_pose(self, t: float, position: np.ndarray, yaw: float) -> None:
        """Advance to time `t` from the base's true planar pose in the world."""
        if self._origin is None or self.time is None or t < self.time:
            self._origin, self.time = (np.asarray(position, float)[:2].copy(), yaw), t
            self._last = (self._origin[0].copy(), yaw)
            self.x = self.y = self.yaw = 0.0
            return
        o, oyaw = self._origin
        c, s = math.cos(oyaw), math.sin(oyaw)
        rel = np.asarray(position, float)[:2] - o
        x, y = c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]
        new_yaw = _wrap(yaw - oyaw)
        dt = t - self.time
        if dt > 0:
            dx, dy = x - self.x, y - self.y
            cy, sy = math.cos(self.yaw), math.sin(self.yaw)
            self.vx, self.vy = (cy * dx + sy * dy) / dt, (-sy * dx + cy * dy) / dt
            self.wz = _wrap(new_yaw - self.yaw) / dt
        self.x, self.y, self.yaw, self.time = x, y, new_yaw, t


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi
