"""
What a view shows: the session's world now, its state, how to pause, play and step it; the rate.

Shared by the viewer window (:mod:`.window`) and the browser view (:mod:`.web`). Their one kind
of target is a :class:`~sim_node.session.Session`: a script's own world is shown through one
too (:meth:`Session.hold <sim_node.session.Session.hold>`), as MuJoCo's passive viewer is handed
its model and data from above.
"""

import time
from typing import Optional

from ..session import Loaded, PLAYING, Session, StateEvent

#: What a view shows as the state of a world its owner steps (no loop to pause or step).
OWNER_STEPPED = 'stepped by its owner'


class Source:
    """
    A view's target: a session's listener that records which world is loaded and its state.

    The session tells it of every new model and every change of state
    (:meth:`Session.add_listener`: ``on_model``, ``on_state``); it only records them, and the
    view's own thread shows them at its next frame, never asking the session. :meth:`close`
    detaches.
    """

    def __init__(self, session: Session):
        if not isinstance(session, Session):
            raise TypeError(f'a view shows a Session, not {session!r} (a script shows its own '
                            'world with Session.hold(world))')
        self.session = session
        self._loaded: Optional[Loaded] = session.loaded
        self._state: StateEvent = session.state_event()
        self._handle = session.add_listener(self._on_model, self._on_state, name='view')

    def _on_model(self, loaded: Optional[Loaded], snap) -> None:
        self._loaded = loaded

    def _on_state(self, event: StateEvent) -> None:
        self._state = event

    def close(self) -> None:
        self.session.remove_listener(self._handle)

    def current(self) -> tuple:
        """Return ``(world, loop)``; either may be None (nothing loaded; its owner steps it)."""
        loaded = self._loaded
        return (loaded.world, loaded.loop) if loaded is not None else (None, None)

    def state(self, loop) -> str:
        """Return the state to show: the session's last event (a failure shows its reason)."""
        if loop is None:
            return OWNER_STEPPED
        event = self._state
        return f'{event.state}: {event.reason}' if event.failed else event.state

    def playing(self) -> bool:
        """Whether the session plays (its last state event, not its loop's flag)."""
        return self._state.state == PLAYING

    def set_paused(self, paused: bool) -> None:
        self.session.pause() if paused else self.session.play()

    def step(self) -> None:
        self.session.step(1)


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
