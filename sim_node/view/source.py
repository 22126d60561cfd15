"""
What a view shows: the world now, its state, how to pause, play and step it; the measured rate.

Shared by the viewer window (:mod:`.window`) and the browser view (:mod:`.web`), which show a
:class:`~sim_node.session.Session`, a :class:`~sim_node.core.loop.SimLoop` or a bare
:class:`~sim_node.core.world.World` alike.
"""

import time


class Source:
    """A view's target: the world now, its state, and how to pause, play and step it."""

    def __init__(self, target):
        from ..core.loop import SimLoop
        from ..core.world import World
        from ..session import Session
        self._session = target if isinstance(target, Session) else None
        self._loop = target if isinstance(target, SimLoop) else None
        self._world = target if isinstance(target, World) else None
        if self._session is None and self._loop is None and self._world is None:
            raise TypeError(f'a view shows a Session, a SimLoop or a World, not {target!r}')

    def current(self) -> tuple:
        """Return ``(world, loop)``; either may be None (nothing loaded; a bare world)."""
        if self._session is not None:
            loaded = self._session.loaded
            return (loaded.world, loaded.loop) if loaded is not None else (None, None)
        if self._loop is not None:
            return self._loop.world, self._loop
        return self._world, None

    def state(self, loop) -> str:
        if self._session is not None:
            return self._session.state
        if loop is None:
            return 'stepped by its owner'
        return 'paused' if loop.paused else 'playing'

    def set_paused(self, paused: bool) -> None:
        owner = self._session or self._loop
        if owner is not None:
            owner.pause() if paused else owner.play()

    def step(self) -> None:
        if self._session is not None:
            self._session.step(1)
        elif self._loop is not None:
            self._loop.step(1)


class RateMeter:
    """The measured real-time factor: simulated over wall time, over about a second."""

    def __init__(self):
        self._marks: list = []

    def update(self, sim_time: float) -> str:
        now = time.monotonic()
        if self._marks and sim_time < self._marks[-1][1]:
            self._marks = []  # a reset
        self._marks.append((now, sim_time))
        while len(self._marks) > 2 and now - self._marks[0][0] > 1.0:
            self._marks.pop(0)
        (t0, s0), (t1, s1) = self._marks[0], self._marks[-1]
        if t1 - t0 < 0.2:
            return '-'
        return f'{(s1 - s0) / (t1 - t0):.2f}x'


def framing(m, d) -> tuple:
    """
    Return ``(lookat, distance, azimuth, elevation)`` of a camera that frames the world.

    Everything but planes (an infinite floor would frame nothing), seen from the front left
    and above, as a person first wants to see a scene.
    """
    keep = m.geom_type != 0  # mjGEOM_PLANE
    return framing_of(d.geom_xpos[keep], m.geom_rbound[keep])


def framing_of(centres, radii) -> tuple:
    """Return :func:`framing`'s camera for balls at `centres` (n, 3) of `radii` (n,)."""
    import numpy as np
    if len(centres) == 0:
        return np.zeros(3), 5.0, 135.0, -25.0
    centres, radii = np.asarray(centres, dtype=float), np.asarray(radii, dtype=float)
    lo = (centres - radii[:, None]).min(axis=0)
    hi = (centres + radii[:, None]).max(axis=0)
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 0.5)
    return (lo + hi) / 2, 2.2 * radius, 135.0, -25.0


def camera_position(lookat, distance: float, azimuth: float, elevation: float):
    """Return where a camera with MuJoCo's free-camera angles (degrees) stands."""
    import numpy as np
    a, e = np.radians(azimuth), np.radians(elevation)
    return np.asarray(lookat) - distance * np.array(
        [np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
