"""
Planar laser scanners on sites, by MuJoCo's ray casting (``mj_multiRay``).

A scanner sweeps the plane of its site's x and y axes, angle 0 along x, counter-clockwise about
z (the REP 103 convention of sensor_msgs/LaserScan). Rays start at the site and never see the
body the site is on. Ranges follow REP 117: +inf where nothing is hit within range_max, -inf
for a hit closer than range_min.
"""

from dataclasses import dataclass
import fnmatch
import math
from typing import Sequence

import mujoco
import numpy as np

from ..errors import InvalidArgumentError
from ..world import World

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
class LaserReading:
    """One sweep: (samples,) ranges in metres, at simulated `time`."""

    site: str
    time: float
    ranges: np.ndarray


def scanner_sites(site_names: Sequence[str], patterns: Sequence[str]) -> tuple:
    """Return the site names that match one of `patterns` (shell-style)."""
    return tuple(n for n in site_names if any(fnmatch.fnmatchcase(n, p) for p in patterns if p))


class LaserScanner:
    """Casts the rays of every listed scanner site of a world in one visit under its lock."""

    def __init__(self, world: World, config: LaserConfig = LaserConfig()):
        self.world = world
        self.config = config
        a = config.angles()
        self._local = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)  # (n, 3)

    def scan(self, sites: Sequence[str]) -> list:
        """Return a :class:`LaserReading` per site of `sites` that still exists."""
        if not sites:
            return []
        return self.world.observe(lambda m, d, generation: self._cast(m, d, sites))

    def _cast(self, m: mujoco.MjModel, d: mujoco.MjData, sites: Sequence[str]) -> list:
        cfg, n = self.config, self.config.samples
        out = []
        for name in sites:
            s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
            if s < 0:
                continue  # deleted since the caller listed it
            vec = (self._local @ d.site_xmat[s].reshape(3, 3).T).reshape(-1)
            dist = np.empty(n)
            geom = np.empty(n, dtype=np.int32)
            mujoco.mj_multiRay(m, d, d.site_xpos[s].copy(), vec, None, 1,
                               int(m.site_bodyid[s]), geom, dist, None, n, cfg.range_max)
            ranges = np.where((dist < 0) | (dist > cfg.range_max), np.inf, dist)
            ranges[ranges < cfg.range_min] = -np.inf
            out.append(LaserReading(site=name, time=float(d.time), ranges=ranges))
        return out
