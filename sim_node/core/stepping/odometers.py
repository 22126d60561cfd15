"""
The P3D plugins' samples: a link's true pose and twist, taken in the stepping loop.

A robot file's P3D plugin (:class:`~..base.records.DeclaredOdometer`, :mod:`..models.p3d`)
asks for ground truth at a rate of simulated time, up to every step; snapshots come at a
wall-clock rate, so the loop takes these as it takes IMU samples (:mod:`.sampling`): at each
due time it brings the poses and velocities of the state just reached up to date (MuJoCo's
``mj_kinematics``, ``mj_comPos``, ``mj_comVel``: after a step, the data holds those of the
state before it) and copies the link's site pose and velocity into the node's queue.

Where the plugin names a link as its frame, the pose is the site's in that link's frame and
the twist the difference of their velocities, turned into that link's frame (as
gazebo_ros_p3d takes it: no transport term); the offsets then move and turn the pose. Each
twist component gets a Gaussian noise of the plugin's deviation, seeded by the site's name
(a run repeats).
"""

import math
from typing import NamedTuple, Optional
import zlib

import mujoco
import numpy as np

from ..base import quat

#: The most samples per simulated second of one plugin (``update_rate`` 0 means every step).
MAX_ODOMETER_RATE_HZ = 1000.0


class OdometerSample(NamedTuple):
    """One P3D sample: where the link was and how it moved, at one simulated time."""

    site: str
    time: float
    generation: int
    position: np.ndarray  # (3,) in the plugin's frame, offsets applied
    quat_wxyz: np.ndarray  # (4,)
    linear: np.ndarray  # (3,) m/s, in the plugin's frame, with its noise
    angular: np.ndarray  # (3,) rad/s


class Odometer:
    """One declared P3D plugin's schedule and what it reads of the data."""

    __slots__ = ('name', 'site', 'reference', 'period', 'decl', 'rng', 'next')

    def __init__(self, decl, site: int, reference: Optional[int], timestep: float):
        self.name, self.site, self.reference, self.decl = decl.site, site, reference, decl
        rate = decl.rate_hz if decl.rate_hz > 0 else 1.0 / timestep
        self.period = 1.0 / min(rate, MAX_ODOMETER_RATE_HZ)
        self.rng = np.random.default_rng(zlib.crc32(decl.site.encode()))
        self.next = math.nan

    def take(self, m: mujoco.MjModel, d: mujoco.MjData, t: float,
             generation: int) -> OdometerSample:
        """
        Read the sample of this time (the data's poses and velocities brought up to date).

        Its next due time is the sampler's to set, as for every other sample.
        """
        twist = np.empty(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, self.site, twist, 0)
        pos = d.site_xpos[self.site].copy()
        q = quat.from_matrix(d.site_xmat[self.site].reshape(3, 3))
        angular, linear = twist[:3], twist[3:]
        if self.reference is not None:
            ref = np.empty(6)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, self.reference, ref, 0)
            turn = quat.conj(d.xquat[self.reference])
            pos = quat.rotate(turn, pos - d.xpos[self.reference])
            q = quat.mul(turn, q)
            angular = quat.rotate(turn, angular - ref[:3])
            linear = quat.rotate(turn, linear - ref[3:])
        decl = self.decl
        pos = pos + np.asarray(decl.offset_pos)
        q = quat.mul(np.asarray(decl.offset_quat), q)
        if decl.noise > 0:
            linear = linear + self.rng.normal(0.0, decl.noise, 3)
            angular = angular + self.rng.normal(0.0, decl.noise, 3)
        return OdometerSample(self.name, t, generation, pos, q / np.linalg.norm(q),
                              np.array(linear, float), np.array(angular, float))


def entries(info) -> list:
    """Return an :class:`Odometer` for each P3D plugin of a model generation whose parts it has."""
    sites = {s.name: s.site_id for s in info.sites}
    bodies = {n: i for i, n in enumerate(info.body_names)}
    out = []
    for name, decl in info.odometers.items():
        reference = bodies.get(decl.reference) if decl.reference else None
        if name in sites and (reference is not None or not decl.reference):
            out.append(Odometer(decl, sites[name], reference, info.timestep))
    return out


def bring_up_to_date(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """Compute the poses and velocities of the data's state (after a step: of the one before)."""
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_comVel(m, d)
