"""
A differential drive as diff_drive_controller computes it: wheel speeds and odometry. ROS-free.

:func:`wheel_speeds` turns a body twist into left and right wheel speeds (rad/s) with the
YAML's wheel separation and radii (and their multipliers); :func:`odometry` gives the
odometry that integrates the wheels' positions into a pose in the odom frame
(:class:`~.odometry.DiffDriveOdometry`, in simulated time).
"""

from typing import NamedTuple

from .odometry import DiffDriveOdometry


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
                   * params.get('wheel_separation_multiplier', 1.0),
                   radius * params.get('left_wheel_radius_multiplier', 1.0),
                   radius * params.get('right_wheel_radius_multiplier', 1.0))


def odometry(geometry: Geometry) -> DiffDriveOdometry:
    """Return the odometry of a diff drive of this geometry (at the origin, at rest)."""
    return DiffDriveOdometry(geometry.left_radius, geometry.right_radius, geometry.separation)


def wheel_speeds(geometry: Geometry, v: float, w: float) -> tuple:
    """Return (left, right) wheel speeds (rad/s) for a forward speed `v` and a turn rate `w`."""
    half = geometry.separation / 2.0
    return (v - w * half) / geometry.left_radius, (v + w * half) / geometry.right_radius
