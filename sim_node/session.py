"""
The simulation that is loaded now: one owner for the world, its loop and its lifecycle. No ROS.

A :class:`Session` holds the loaded :class:`~sim_node.core.world.World` and its stepping
:class:`~sim_node.core.stepping.loop.SimLoop`, and swaps them as one (:meth:`Session.load`,
:meth:`Session.unload`). Its state is one machine, the single source of what
``get_simulation_state`` answers, written in one place (:data:`TRANSITIONS`, applied by
:meth:`Session._go`)::

    NO_WORLD --load--> STOPPED or PLAYING/PAUSED      (LOADING_WORLD while a load reads)
    STOPPED  --play--> PLAYING    --pause--> PAUSED   --play--> PLAYING
    PLAYING/PAUSED --stop--> STOPPED (paused, and reset: time, state, spawned entities)
    STOPPED/PAUSED --step--> PAUSED;  PLAYING --limit or diverged--> PAUSED
    any --failed--> FAILED (shown as STOPPED, with the reason) --stop or reset--> STOPPED/PAUSED
    any world --unload--> NO_WORLD

The loop reports, the session decides: the loop stops stepping by itself when a limit is
reached, the physics diverges or it fails (it must not take another step), and reports it
(:meth:`SimLoop.take_reports <sim_node.core.stepping.loop.SimLoop.take_reports>`); the session
takes those reports before it answers any question or request, so its state never lags the
loop's. :meth:`Session.set_state` applies the standard's rules for a requested state (already
there, not allowed, tried and failed); :meth:`play` and :meth:`pause` are the lenient forms a
parameter or a script uses.

Front-ends attach to a session instead of keeping their own copy of what is loaded: the ROS node,
a viewer window, a browser view and a recorder register listeners (:meth:`add_listener`), which
the session's ``sim-model`` thread calls with each new model: a load, a spawn, a delete, a reset
of the spawned entities, and ``None`` on unload. A listener sees the model that is current when
its turn comes: under a burst of edits the models replaced before that are skipped, as a
publisher would skip them; :meth:`sync` waits until every listener has seen the current one (a
script or test that must see the listeners' work before it goes on). A listener must not block:
one that has work to do records what changed and acts on its own thread. Freed heap goes back
to the system from a listener of the same kind (:class:`~sim_node.core.memory.HeapTrimmer`).

Threads: the session's lock (which world, the lifecycle state) is taken before any world or
loop lock and never held while calling a listener.
"""

import contextlib
import logging
from pathlib import Path
import threading
import time
from typing import Callable, Iterator, NamedTuple, Optional

from .core.config import WorldConfig
from .core.errors import (AlreadyInStateError, IncorrectStateError, IncorrectTransitionError,
                          NoWorldError, StateTransitionError)
from .core.memory import HeapTrimmer
from .core.records import RESET_ALL, Snapshot
from .core.stepping.loop import SimLoop
from .core.world import World

log = logging.getLogger(__name__)

NO_WORLD = 'no_world'
LOADING_WORLD = 'loading_world'
STOPPED = 'stopped'
PAUSED = 'paused'
PLAYING = 'playing'
#: The states a caller may ask for (:meth:`Session.set_state`).
REQUESTABLE = (PLAYING, PAUSED, STOPPED)
#: The loop failed (an internal error): shown as STOPPED, with the reason, until a stop, a
#: reset or a load brings it back.
FAILED = 'failed'
#: The lifecycle: (state, event) -> next state. Events are the requests (play, pause, stop,
#: step, reset) and the loop's reports (limit, diverged, failed: see ``SimLoop.take_reports``).
#: A pair not here leaves the state as it is.
TRANSITIONS = {
    **{(s, 'play'): PLAYING for s in (STOPPED, PAUSED, PLAYING)},
    **{(s, 'pause'): PAUSED for s in (STOPPED, PAUSED, PLAYING)},
    **{(s, 'stop'): STOPPED for s in (STOPPED, PAUSED, PLAYING, FAILED)},
    **{(s, 'step'): PAUSED for s in (STOPPED, PAUSED)},
    (PLAYING, 'limit'): PAUSED, (PLAYING, 'diverged'): PAUSED,
    **{(s, 'failed'): FAILED for s in (STOPPED, PAUSED, PLAYING)},
    (FAILED, 'reset'): PAUSED,
}

ERR_NO_WORLD = 'no world is loaded; call load_world first'
ERR_LOADING = 'a world is loading (LOADING_WORLD): ask again when load_world has answered'
ERR_NOT_REQUESTABLE = ('cannot set state {target!r}: ask for playing, paused or stopped (or '
                       'quit the simulator)')
ERR_ALREADY = 'already in that state'
ERR_HELD = ('this world is stepped by its owner (Session.hold), not by a loop: step it from '
            'the script that holds it')

#: How often the session's thread looks for a new world or model when nothing wakes it.
WATCH_SEC = 0.05
#: How long the session's thread lets an edit's caller have the process before it reacts to
#: the new model: the listeners' work (Python, holding the interpreter's lock) delayed the
#: spawn's answer by 4-5 ms, more than a fifth of a small robot's round trip.
SETTLE_SEC = 0.01

Listener = Callable[[Optional['Loaded'], Optional[Snapshot]], None]


class Loaded(NamedTuple):
    """A loaded world, its loop (None: its owner steps it, :meth:`Session.hold`), its origin."""

    world: World
    loop: Optional[SimLoop]
    name: str
    uri: str


class Session:
    """
    The loaded simulation (see the module docstring); usable as a context manager.

    :param trim_memory: give freed heap back to the system from the session's thread.
    """

    def __init__(self, trim_memory: bool = True):
        self._lock = threading.RLock()
        self._loaded: Optional[Loaded] = None
        self._state = NO_WORLD  # of the loaded world; LOADING_WORLD is self._loading > 0
        self._loading = 0
        self._listeners: list = []  # _Registered, in the order they were added
        self._seen_cv = threading.Condition()  # notified when listeners have seen a model
        self._wake = threading.Event()  # a load, an unload or a new listener
        self._closing = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._trim_memory = trim_memory
        self._trimmer: Optional[HeapTrimmer] = None

    def __enter__(self) -> 'Session':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- what is loaded

    @property
    def loaded(self) -> Optional[Loaded]:
        """Return the loaded world and loop, or None."""
        return self._loaded

    def require(self) -> Loaded:
        """Return what is loaded; :raises NoWorldError: nothing is."""
        loaded = self._loaded
        if loaded is None:
            raise NoWorldError(ERR_NO_WORLD)
        return loaded

    @property
    def world(self) -> World:
        return self.require().world

    @property
    def loop(self) -> SimLoop:
        """Return the loaded world's loop; :raises IncorrectStateError: its owner steps it."""
        loop = self.require().loop
        if loop is None:
            raise IncorrectStateError(ERR_HELD)
        return loop

    def load(self, world: World, name: str = '', uri: str = '', stopped: bool = False,
             config: Optional[WorldConfig] = None) -> Loaded:
        """
        Make `world` the loaded one, stepping on a loop of its own; the old loop is stopped.

        :param stopped: load it STOPPED (paused at its initial state), as ``load_world`` does;
            else playing or paused as its configuration (or `config`) says.
        """
        loop = SimLoop(world, config)
        if stopped:
            loop.pause()
        with self._lock:
            old, self._loaded = self._loaded, Loaded(world, loop, name, uri)
            self._state = STOPPED if stopped else PAUSED if loop.paused else PLAYING
        if old is not None and old.loop is not None:
            old.loop.stop()
        loop.start()
        self._wake.set()
        self._start_thread()
        log.info('world %r loaded from %s: %d entities, dt=%g s, %s', name, uri or '(text)',
                 len(world.entities()), world.timestep, self.state)
        return self._loaded

    def hold(self, world: World, name: str = '', uri: str = '') -> Loaded:
        """
        Make `world` the loaded one, stepped by its owner (a script, a Gym env): no loop.

        The front-ends follow it as they follow a looped world (a window on a script's world);
        its state is PLAYING, and pausing, playing, stepping or stopping it is refused
        (:data:`ERR_HELD`): its owner decides. The old loop, if any, is stopped.
        """
        with self._lock:
            old, self._loaded = self._loaded, Loaded(world, None, name, uri)
            self._state = PLAYING  # as its owner steps it
        if old is not None and old.loop is not None:
            old.loop.stop()
        self._wake.set()
        self._start_thread()
        return self._loaded

    def load_file(self, path: str, config: WorldConfig = WorldConfig(),
                  stopped: bool = False) -> Loaded:
        """Load an MJCF or URDF scene file (see :meth:`load`)."""
        p = Path(path)
        return self.load(World.from_file(str(p), config), p.stem, p.resolve().as_uri(),
                         stopped)

    @contextlib.contextmanager
    def loading(self) -> Iterator[None]:
        """While inside, the state is LOADING_WORLD (a load reads and compiles meanwhile)."""
        with self._lock:
            self._loading += 1
        try:
            yield
        finally:
            with self._lock:
                self._loading -= 1

    def unload(self) -> Loaded:
        """Stop and drop the loaded world (NO_WORLD); :raises NoWorldError: none is loaded."""
        with self._lock:
            old, self._loaded = self._loaded, None
            self._state = NO_WORLD
        if old is None:
            raise NoWorldError(ERR_NO_WORLD)
        if old.loop is not None:
            old.loop.stop()
        self._wake.set()
        return old

    def close(self) -> None:
        """Stop the loop and the session's thread (a world stays loaded, not stepping)."""
        self._closing.set()
        loaded = self._loaded
        if loaded is not None and loaded.loop is not None:
            # Short: a spawn still compiling holds the world lock and the loop waits for it.
            loaded.loop.stop(timeout=0.5)
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(2.0)
        if self._trimmer is not None:
            self._trimmer.close()

    # ---------------------------------------------------------------- the lifecycle

    @property
    def state(self) -> str:
        """One of NO_WORLD, LOADING_WORLD, STOPPED, PAUSED, PLAYING."""
        with self._lock:
            if self._loading:
                return LOADING_WORLD
            self._take_reports_locked()
            return STOPPED if self._state == FAILED else self._state

    def _take_reports_locked(self) -> None:
        """Decide on what the loop did by itself since it was last asked (session lock held)."""
        loaded = self._loaded
        if loaded is not None and loaded.loop is not None:
            for kind, _ in loaded.loop.take_reports():
                self._go(kind)

    def _go(self, event: str) -> str:
        """Apply `event` to the lifecycle by :data:`TRANSITIONS` (session lock held)."""
        self._state = TRANSITIONS.get((self._state, event), self._state)
        return self._state

    def status_message(self) -> str:
        """Why the simulation stopped or paused by itself, or a word when it lags; else ''."""
        loaded = self._loaded
        if loaded is None or loaded.loop is None:
            return ''
        status = loaded.loop.status()
        return status.stop_reason or status.lag

    def set_state(self, target: str) -> None:
        """
        Go to `target` (PLAYING, PAUSED or STOPPED) by the standard's rules.

        A step request in progress ends first (it is never left holding the simulation).

        :raises IncorrectTransitionError: another target, or a world is loading.
        :raises NoWorldError: no world is loaded.
        :raises AlreadyInStateError: the simulation is in `target` already.
        :raises StateTransitionError: the loop failed; only STOPPED brings it back.
        """
        if target not in REQUESTABLE:
            raise IncorrectTransitionError(ERR_NOT_REQUESTABLE.format(target=target))
        with self._lock:
            if self._loading:  # the standard: not until the world has loaded
                raise IncorrectTransitionError(ERR_LOADING)
            loop = self.loop
            loop.cancel_steps()
            self._take_reports_locked()
            failed = self._state == FAILED
            if self._state == target:  # STOPPED after a failure is FAILED: allowed, it resets
                raise AlreadyInStateError(ERR_ALREADY)
            if failed and target != STOPPED:
                raise StateTransitionError(loop.failure)
        # Outside the lock: a stop resets, which may compile (the spawned entities go).
        {PLAYING: self.play, PAUSED: self.pause, STOPPED: self.stop}[target]()

    def play(self) -> None:
        """Play (from STOPPED too); :raises IncorrectStateError: the loop failed."""
        with self._lock:
            loop = self.loop
            self._take_reports_locked()
            loop.play()  # raises while the loop has failed: the state stays
            self._go('play')

    def pause(self) -> None:
        with self._lock:
            loop = self.loop
            self._take_reports_locked()
            loop.pause()
            self._go('pause')

    def stop(self) -> None:
        """Stop: pause and reset everything (time, state, spawned); a failed loop recovers."""
        with self._lock:
            loaded = self.require()
            self.loop.pause()
            loaded.loop.cancel_steps()
        loaded.world.reset(RESET_ALL)
        with self._lock:
            self._take_reports_locked()
            loaded.loop.recover()
            self._go('stop')
        loaded.loop.refresh_snapshot()

    def step(self, n: int, feedback: Optional[Callable[[int, int], None]] = None) -> int:
        """
        Run `n` steps while paused (or stopped: the simulation is then paused); block until done.

        Returns the steps taken; raises as
        :meth:`SimLoop.step <sim_node.core.stepping.loop.SimLoop.step>`.
        """
        done = self.loop.step(n, feedback=feedback)
        with self._lock:
            self._take_reports_locked()
            self._go('step')  # no longer at the reset state
        return done

    def reset(self, scope: int = RESET_ALL) -> None:
        """Reset by scope bits (:meth:`World.reset`); a failed loop comes back, paused."""
        loaded = self.require()
        loaded.world.reset(scope)
        if loaded.loop is not None:
            with self._lock:
                self._take_reports_locked()
                loaded.loop.recover()
                self._go('reset')
            loaded.loop.refresh_snapshot()

    def changed(self) -> None:
        """Say the world was written outside the loop: consumers get a fresh snapshot now."""
        loaded = self._loaded
        if loaded is not None and loaded.loop is not None:
            loaded.loop.refresh_snapshot()

    # ---------------------------------------------------------------- listeners

    def add_listener(self, listener: Listener) -> None:
        """
        Call ``listener(loaded, snapshot)`` with every new model, from the session's thread.

        ``loaded`` and ``snapshot`` (of the new model) are None when nothing is loaded. A
        listener added while a world is loaded is called with it first. It must not block for
        long (it holds back the others); an exception is logged and the next model still comes.
        """
        with self._lock:
            self._listeners.append(_Registered(listener))
        self._wake.set()
        self._start_thread()

    def remove_listener(self, listener: Listener) -> None:
        """Stop calling `listener` (compared by equality: the same bound method detaches)."""
        with self._lock:
            self._listeners = [r for r in self._listeners if r.listener != listener]

    def sync(self, timeout: float = 10.0) -> bool:
        """Wait until every listener has seen the model that is current now; False on timeout."""
        deadline = time.monotonic() + timeout
        while True:
            key = _key(self._loaded)
            with self._seen_cv:
                with self._lock:
                    behind = [r for r in self._listeners if r.seen != key]
                if not behind:
                    return True
                left = deadline - time.monotonic()
                if left <= 0 or self._thread is None:
                    return False
                self._seen_cv.wait(min(left, WATCH_SEC))

    # ---------------------------------------------------------------- the session's thread

    def _start_thread(self) -> None:
        with self._lock:
            if self._thread is not None or self._closing.is_set():
                return
            if self._trim_memory:  # a listener like the others, acting on its own thread
                self._trimmer = HeapTrimmer()
                self._listeners.append(_Registered(self._trimmer.model_changed))
            self._thread = threading.Thread(target=self._watch, name='sim-model', daemon=True)
            self._thread.start()

    def _watch(self) -> None:
        """Call the listeners with each new model; give freed memory back when it is cheap."""
        while not self._closing.is_set():
            try:
                self._watch_once()
            except Exception:  # noqa: B902 (never die silently: say why, go on)
                log.exception('the session thread failed; it goes on')
                self._closing.wait(0.5)

    def _watch_once(self) -> None:
        loaded = self._loaded
        key = _key(loaded)
        with self._lock:
            behind = [r for r in self._listeners if r.seen != key]
        if not behind:  # wait for a new model, a load or an unload
            if loaded is None:
                self._wake.wait(WATCH_SEC)
            elif loaded.world.wait_new_model(key[1], WATCH_SEC) != key[1]:
                self._closing.wait(SETTLE_SEC)  # the editor answers its caller first
            self._wake.clear()
            return
        snap = None
        if loaded is not None and loaded.loop is not None:
            # The consumers of snapshots (the publishers) see the new model now, not at the
            # next batch of a paused loop.
            loaded.loop.refresh_snapshot()
            snap = loaded.loop.latest_snapshot()
        elif loaded is not None:
            snap = loaded.world.snapshot()
        if snap is not None:
            key = (loaded.world, snap.info.generation)
        for registered in behind:
            try:
                registered.listener(loaded, snap)
            except Exception:  # noqa: B902 (one listener must not stop the others)
                log.exception('a listener of new models failed: %r', registered.listener)
            registered.seen = key
        with self._seen_cv:
            self._seen_cv.notify_all()


def _key(loaded: Optional[Loaded]) -> tuple:
    """Return what a listener sees of a world: (world, generation); (None, None): none."""
    return (None, None) if loaded is None else (loaded.world, loaded.world.generation)


class _Registered:
    """A listener and the model it last saw."""

    __slots__ = ('listener', 'seen')

    def __init__(self, listener: Listener):
        self.listener = listener
        self.seen: tuple = ('never', None)
