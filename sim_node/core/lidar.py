"""
Planar laser scanners on sites, by MuJoCo's ray casting (``mj_multiRay``).

A scanner sweeps the plane of its site's x and y axes, angle 0 along x, counter-clockwise about
z (the REP 103 convention of sensor_msgs/LaserScan). Rays start at the site and never see the
body the site is on. Ranges follow REP 117: +inf where nothing is hit within range_max, -inf
for a hit closer than range_min. A scanner a robot file declares (:class:`Sweep`, from its
:class:`~sim_node.core.records.DeclaredLaser`) sweeps as declared: its own angles, samples and
ranges, a vertical sweep (rings, tilted up by their angle: a 3D lidar) and Gaussian noise on
each range, seeded by the site's name so that a run repeats.

Two ways to scan: :meth:`LaserScanner.scan` casts now, under the world lock; :meth:`cast`
casts the poses the stepping side took at each laser's due times (:meth:`.world.World.
scan_lasers`) against a data of its own, holding no lock: the way a node keeps each laser's
rate in simulated time, its stamps exact, whatever its perception thread is doing.
"""

from dataclasses import dataclass
import fnmatch
import math
from typing import Mapping, Optional, Sequence
import zlib

import mujoco
import numpy as np

from .base.errors import InvalidArgumentError
from .world import World

ERR_CONFIG = ('laser scan settings: need samples >= 1, angle_min <= angle_max, '
              '0 <= range_min < range_max (finite); got {cfg}')


@dataclass(frozen=True)
class LaserConfig:
    """What every scanner of a world sweeps (angles in radians, ranges in metres)."""

    angle_min: float = -math.pi
    angle_max: float = math.pi
    samples: int = 360
    range_min: float = 0.05
    range_max: float = 10.0

    def __post_init__(self):
        ok = (self.samples >= 1 and math.isfinite(self.angle_min)
              and math.isfinite(self.angle_max) and self.angle_min <= self.angle_max
              and 0 <= self.range_min < self.range_max < math.inf)
        if not ok:
            raise InvalidArgumentError(ERR_CONFIG.format(cfg=self))

    @property
    def angle_increment(self) -> float:
        if self.samples == 1:
            return 0.0
        return (self.angle_max - self.angle_min) / (self.samples - 1)

    def angles(self) -> np.ndarray:
        """Return (samples,) ray angles from angle_min to angle_max inclusive."""
        return self.angle_min + self.angle_increment * np.arange(self.samples)


@dataclass(frozen=True)
class Sweep:
    """
    What one scanner sweeps: its horizontal config, vertical rings, noise.

    :param vertical: (rings, lowest angle, highest angle) in radians; None: one plane.
    :param noise: (mean, standard deviation) in metres; None: none.
    """

    config: LaserConfig
    vertical: Optional[tuple] = None
    noise: Optional[tuple] = None

    def vertical_angles(self) -> np.ndarray:
        if not self.vertical:
            return np.zeros(1)
        n, lo, hi = self.vertical
        return np.array([lo]) if n == 1 else np.linspace(lo, hi, int(n))

    def directions(self) -> np.ndarray:
        """Return (rings * samples, 3) unit rays in the site's frame, ring by ring."""
        h = self.config.angles()
        v = self.vertical_angles()
        cv, sv = np.cos(v)[:, None], np.sin(v)[:, None]
        return np.stack([cv * np.cos(h)[None, :], cv * np.sin(h)[None, :],
                         np.broadcast_to(sv, (len(v), len(h)))], axis=2).reshape(-1, 3)


def sweep_of(declared, default: LaserConfig) -> Sweep:
    """
    Return the :class:`Sweep` of a declared laser, the node's `default` where it declares none.

    :param declared: a :class:`~sim_node.core.records.DeclaredLaser` (checked already).
    """
    def pick(value, fallback):
        return fallback if value is None else value
    try:
        config = LaserConfig(
            angle_min=pick(declared.angle_min, default.angle_min),
            angle_max=pick(declared.angle_max, default.angle_max),
            samples=int(pick(declared.samples, default.samples)),
            range_min=pick(declared.range_min, default.range_min),
            range_max=pick(declared.range_max, default.range_max))
    except InvalidArgumentError:  # its range with the node's other end: the node's own
        config = default
    return Sweep(config, declared.vertical if declared.vertical and declared.vertical[0] > 1
                 else None, declared.noise)


@dataclass(frozen=True)
class LaserReading:
    """
    One sweep: ranges in metres, at simulated `time`.

    (samples,) for a planar scanner; (rings, samples) for a 3D one (:attr:`Sweep.vertical`).
    """

    site: str
    time: float
    ranges: np.ndarray
    sweep: Optional[Sweep] = None


def scanner_sites(site_names: Sequence[str], patterns: Sequence[str]) -> tuple:
    """Return the site names that match one of `patterns` (shell-style)."""
    return tuple(n for n in site_names if any(fnmatch.fnmatchcase(n, p) for p in patterns if p))


class LaserScanner:
    """Casts scanner sites' rays: now (:meth:`scan`), or from the poses taken (:meth:`cast`)."""

    def __init__(self, world: World, config: LaserConfig = LaserConfig()):
        self.world = world
        self.config = config
        self._default = Sweep(config)
        self._rays: dict = {}  # Sweep -> (n, 3) directions in the site frame
        self._noise: dict = {}  # site -> its random generator
        self._scratch: Optional[tuple] = None  # (model, its MjData for cast)

    def scan(self, sites: Sequence[str], sweeps: Optional[Mapping[str, Sweep]] = None) -> list:
        """
        Return a :class:`LaserReading` per site of `sites` that still exists.

        :param sweeps: site -> its own :class:`Sweep` (declared); else the scanner's config.
        """
        if not sites:
            return []
        sweeps = sweeps or {}
        return self.world.observe(lambda m, d, generation: self._scan(m, d, sites, sweeps))

    def cast(self, poses: Sequence, sweeps: Optional[Mapping[str, Sweep]] = None,
             resets: Optional[int] = None) -> list:
        """
        Return a :class:`LaserReading` per pose of the world's current model, in order.

        Each pose (:class:`~.stepping.sampling.LaserPose`) says where its laser and every geom
        were at its time, or gives the state then (worked out here: ``mj_kinematics`` on a
        scratch data of the model); the rays are cast there, holding no lock. A pose of
        another model generation (a spawn or a delete came since) is left out, as is one from
        before a reset when `resets` (the world's count now) is given.

        :param sweeps: site -> its own :class:`Sweep` (declared); else the scanner's config.
        """
        if not poses:
            return []
        sweeps = sweeps or {}
        m, generation = self.world.live_model()
        if self._scratch is None or self._scratch[0] is not m:
            self._scratch = (m, mujoco.MjData(m))
        d = self._scratch[1]
        out = []
        for pose in poses:
            if pose.generation != generation or (resets is not None and pose.resets != resets):
                continue
            s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, pose.site)
            if s < 0:
                continue
            if pose.state is not None:  # a state: where everything was, worked out here
                mujoco.mj_setState(m, d, pose.state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
                mujoco.mj_kinematics(m, d)
                if m.nflex:
                    mujoco.mj_flex(m, d)
                origin, frame = d.site_xpos[s], d.site_xmat[s].reshape(3, 3)
            else:
                d.geom_xpos[:], d.geom_xmat[:] = pose.geom_xpos, pose.geom_xmat
                d.xipos[:], d.ximat[:] = pose.xipos, pose.ximat
                d.flexvert_xpos[:] = pose.flexvert_xpos
                origin, frame = pose.origin, pose.frame
            out.append(self._reading(m, d, pose.site, s, origin, frame, pose.time,
                                     sweeps.get(pose.site, self._default)))
        return out

    def _scan(self, m: mujoco.MjModel, d: mujoco.MjData, sites: Sequence[str],
              sweeps: Mapping[str, Sweep]) -> list:
        out = []
        for name in sites:
            s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
            if s < 0:
                continue  # deleted since the caller listed it
            out.append(self._reading(m, d, name, s, d.site_xpos[s],
                                     d.site_xmat[s].reshape(3, 3), float(d.time),
                                     sweeps.get(name, self._default)))
        return out

    def _reading(self, m: mujoco.MjModel, d: mujoco.MjData, name: str, s: int,
                 origin: np.ndarray, frame: np.ndarray, t: float,
                 sweep: Sweep) -> LaserReading:
        """Cast `sweep` from `origin` turned by `frame` against the geoms where `d` has them."""
        cfg = sweep.config
        local = self._rays.get(sweep)
        if local is None:
            local = self._rays[sweep] = sweep.directions()
        n = len(local)
        vec = (local @ np.asarray(frame).T).reshape(-1)
        dist = np.empty(n)
        geom = np.empty(n, dtype=np.int32)
        mujoco.mj_multiRay(m, d, np.array(origin, dtype=float), vec, None, 1,
                           int(m.site_bodyid[s]), geom, dist, None, n, cfg.range_max)
        hit = (dist >= 0) & (dist <= cfg.range_max)
        if sweep.noise is not None:
            rng = self._noise.get(name)
            if rng is None:  # seeded by its name: a run repeats
                rng = self._noise[name] = np.random.default_rng(zlib.crc32(name.encode()))
            mean, std = sweep.noise
            dist = np.where(hit, dist + rng.normal(mean, std, n), dist)
        ranges = np.where(hit, dist, np.inf)
        ranges[hit & (ranges < cfg.range_min)] = -np.inf
        ranges = np.minimum(ranges, np.where(hit, cfg.range_max, np.inf))
        if sweep.vertical is not None:
            ranges = ranges.reshape(-1, cfg.samples)
        return LaserReading(site=name, time=t, ranges=ranges, sweep=sweep)
