"""
Magnetometers and NavSat receivers a robot file declares, sampled as the world steps.

Gazebo's ``magnetometer`` reads the world's magnetic field (SDF's ``<magnetic_field>``,
MuJoCo's ``opt.magnetic``) in the sensor's frame, tesla, as MuJoCo's own magnetometer does;
its ``navsat`` gives where the sensor is on the Earth: the world's frame is the local tangent
plane (east, north, up) of the point SDF's ``<spherical_coordinates>`` names (WGS84), and a
position in it is turned into latitude, longitude and altitude through the Earth-centred frame
(:func:`fix`), exactly, not by a flat-Earth approximation. A world that names no point is at
latitude 0, longitude 0, altitude 0, as Gazebo's default.

Each declared sensor (:class:`~..base.records.DeclaredGeo`) is sampled at its rate of simulated
time in the stepping loop, as IMUs are (:mod:`.sampling`), into the node's queue as a
:class:`GeoSample`.
"""

import math
from typing import NamedTuple

import mujoco
import numpy as np

#: WGS84's semi-major axis (m) and flattening.
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
_E2 = WGS84_F * (2.0 - WGS84_F)  # the first eccentricity, squared


class Origin(NamedTuple):
    """Where the world's origin is on the Earth: degrees, metres, and its heading (degrees)."""

    latitude_deg: float = 0.0
    longitude_deg: float = 0.0
    elevation: float = 0.0
    heading_deg: float = 0.0


class GeoSample(NamedTuple):
    """
    One magnetometer or NavSat sample at one simulated time.

    `value`: a magnetometer's field (3,) in tesla in its frame; a NavSat's (latitude deg,
    longitude deg, altitude m).
    """

    site: str
    kind: str
    time: float
    generation: int
    value: tuple


def _ecef(lat: float, lon: float, h: float) -> np.ndarray:
    """Return the Earth-centred, Earth-fixed position of a geodetic point (radians, metres)."""
    n = WGS84_A / math.sqrt(1.0 - _E2 * math.sin(lat) ** 2)
    return np.array([(n + h) * math.cos(lat) * math.cos(lon),
                     (n + h) * math.cos(lat) * math.sin(lon),
                     (n * (1.0 - _E2) + h) * math.sin(lat)])


def _geodetic(p: np.ndarray) -> tuple:
    """Return (latitude rad, longitude rad, height m) of an ECEF position (Bowring, iterated)."""
    x, y, z = (float(v) for v in p)
    lon = math.atan2(y, x)
    r = math.hypot(x, y)
    lat = math.atan2(z, r * (1.0 - _E2))
    h = 0.0
    for _ in range(8):  # converges to well under a millimetre in three or four
        n = WGS84_A / math.sqrt(1.0 - _E2 * math.sin(lat) ** 2)
        h = r / math.cos(lat) - n if abs(lat) < math.pi / 4 else z / math.sin(lat) - n * (1 - _E2)
        lat = math.atan2(z, r * (1.0 - _E2 * n / (n + h)))
    return lat, lon, h


def fix(position, origin: Origin) -> tuple:
    """
    Return (latitude deg, longitude deg, altitude m) of a world position.

    The world's x, y, z are east, north, up at `origin`; a heading turns its x axis from east
    towards north (counter-clockwise seen from above) by that angle.
    """
    h = math.radians(origin.heading_deg)
    x, y, z = (float(v) for v in position)
    east, north = x * math.cos(h) - y * math.sin(h), x * math.sin(h) + y * math.cos(h)
    lat0, lon0 = math.radians(origin.latitude_deg), math.radians(origin.longitude_deg)
    # The tangent plane's axes in the Earth-centred frame.
    e = np.array([-math.sin(lon0), math.cos(lon0), 0.0])
    n = np.array([-math.sin(lat0) * math.cos(lon0), -math.sin(lat0) * math.sin(lon0),
                  math.cos(lat0)])
    u = np.array([math.cos(lat0) * math.cos(lon0), math.cos(lat0) * math.sin(lon0),
                  math.sin(lat0)])
    p = _ecef(lat0, lon0, origin.elevation) + east * e + north * n + z * u
    lat, lon, alt = _geodetic(p)
    return math.degrees(lat), math.degrees(lon), alt


class Geo:
    """One declared magnetometer's or NavSat's schedule and what it reads of the data."""

    __slots__ = ('name', 'kind', 'site', 'period', 'origin', 'next')

    def __init__(self, decl, site: int, origin: Origin):
        self.name, self.kind, self.site, self.origin = decl.site, decl.kind, site, origin
        self.period = 1.0 / decl.rate_hz
        self.next = math.nan

    def take(self, m: mujoco.MjModel, d: mujoco.MjData, t: float, generation: int) -> GeoSample:
        """Read the sample of this time (the data's poses brought up to date)."""
        if self.kind == 'magnetometer':
            frame = d.site_xmat[self.site].reshape(3, 3)
            value = tuple(float(v) for v in frame.T @ m.opt.magnetic)
        else:
            value = fix(d.site_xpos[self.site], self.origin)
        return GeoSample(self.name, self.kind, t, generation, value)


def entries(info) -> list:
    """Return a :class:`Geo` for each declared magnetometer and NavSat of a model generation."""
    sites = {s.name: s.site_id for s in info.sites}
    origin = Origin(*info.spherical) if info.spherical else Origin()
    return [Geo(decl, sites[name], origin) for name, decl in info.geo.items() if name in sites]
