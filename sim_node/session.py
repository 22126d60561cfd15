"""
The simulation that is loaded now: one owner for the world, its loop and its lifecycle. No ROS.

A :class:`Session` holds the loaded :class:`~sim_node.core.world.World` and its stepping
:class:`~sim_node.core.loop.SimLoop`, and swaps them as one (:meth:`Session.load`,
:meth:`Session.unload`). Its state is one machine, the single source of what
``get_simulation_state`` answers and of everything that shows it (/diagnostics, the `paused`
parameter, a window's overlay, the browser view). Every change of it, whoever asked for it or
whatever caused it, goes through one table (:data:`TRANSITIONS`, applied by
:meth:`Session._go`)::

    NO_WORLD --load--> STOPPED or PLAYING/PAUSED; --hold--> PLAYING (stepped by its owner)
    any --loading--> LOADING_WORLD --load--> ... ; --load_failed--> the state before
    STOPPED  --play--> PLAYING    --pause--> PAUSED   --play--> PLAYING
    PLAYING/PAUSED --stop--> STOPPED (paused, and reset: time, state, spawned entities)
    STOPPED/PAUSED --step--> PAUSED;  PLAYING --limit or diverged--> PAUSED
    any --failed--> FAILED (shown as STOPPED, with the reason) --stop or reset--> STOPPED/PAUSED
    any world --unload--> NO_WORLD

While a world loads the state shown is LOADING_WORLD; what happens meanwhile to the world that
still runs (a limit, a divergence) is applied to the state it goes back to if the load fails.

The loop reports, the session decides: the loop holds by itself when a limit is reached, the
physics diverges or it fails (it must not take another step), and reports it
(:meth:`SimLoop.take_reports <sim_node.core.loop.SimLoop.take_reports>`), waking the
session's thread, which applies the report at once; the session also takes the reports before it
answers any question or request, so its state never lags the loop's. :meth:`Session.set_state`
applies the standard's rules for a requested state (already there, not allowed, tried and
failed); :meth:`play` and :meth:`pause` are the lenient forms a parameter or a script uses.

Front-ends attach to a session instead of keeping their own copy of what is loaded: the ROS node,
a viewer window, a browser view and a recorder register listeners (:meth:`add_listener`) with up
to two named hooks, as dm_control's composer calls an entity's ``after_compile``:
``on_model(loaded, snapshot)`` with each new model (a load, a spawn, a delete, a reset of the
spawned entities, and ``None`` on unload) and ``on_state(event)`` with each
:class:`StateEvent` (every change of the state, or of why it is so). Each listener has a thread
and a mailbox of its own, so none can hold back the session or another listener: a model is
delivered as the newest one when the listener's turn comes (under a burst of edits the models
replaced before that are skipped, as a publisher would skip them); state events are delivered
each, in order. :meth:`sync` waits until every listener has seen the current model (a script or
test that must see the listeners' work before it goes on). Freed heap goes back to the system
from a listener of the same kind (:class:`~sim_node.core.base.memory.HeapTrimmer`).

Threads: the session's lock (which world, the lifecycle state) is taken before any world or
loop lock and never held while calling a listener; a mailbox's lock is a leaf.
"""

import contextlib
from dataclasses import replace
import logging
from pathlib import Path
import threading
import time
from typing import Callable, Iterator, NamedTuple, Optional

from .core.base.config import WorldConfig
from .core.base.errors import (AlreadyInStateError, IncorrectStateError, IncorrectTransitionError,
                               NoWorldError, StateTransitionError)
from .core.base.memory import HeapTrimmer
from .core.base.records import RESET_ALL
from .core.loop import SimLoop
from .core.models.sdf_files import Places
from .core.world import World
from .listeners import Listener, Mailbox, StateListener

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
#: In :data:`TRANSITIONS`: back to the state before the load began (a load that failed).
BEFORE_LOADING = 'before_loading'
_WORLD = (STOPPED, PAUSED, PLAYING, FAILED)
_ANY = (NO_WORLD,) + _WORLD
#: The lifecycle: (state, event) -> next state. Events are the loads (load_stopped,
#: load_paused, load_playing, hold, loading, load_failed, unload), the requests (play, pause,
#: stop, step, reset) and the loop's reports (limit, diverged, diverged_on, failed: see
#: ``SimLoop.take_reports``). A pair not here leaves the state as it is. While LOADING_WORLD,
#: the events of the world that still runs apply to the state it goes back to.
TRANSITIONS = {
    **{(s, 'loading'): LOADING_WORLD for s in _ANY},
    **{(s, 'load_stopped'): STOPPED for s in _ANY + (LOADING_WORLD,)},
    **{(s, 'load_paused'): PAUSED for s in _ANY + (LOADING_WORLD,)},
    **{(s, 'load_playing'): PLAYING for s in _ANY + (LOADING_WORLD,)},
    **{(s, 'hold'): PLAYING for s in _ANY + (LOADING_WORLD,)},
    (LOADING_WORLD, 'load_failed'): BEFORE_LOADING,
    **{(s, 'unload'): NO_WORLD for s in _WORLD},
    **{(s, 'play'): PLAYING for s in (STOPPED, PAUSED, PLAYING)},
    **{(s, 'pause'): PAUSED for s in (STOPPED, PAUSED, PLAYING)},
    **{(s, 'stop'): STOPPED for s in (STOPPED, PAUSED, PLAYING, FAILED)},
    **{(s, 'step'): PAUSED for s in (STOPPED, PAUSED)},
    (PLAYING, 'limit'): PAUSED, (PLAYING, 'diverged'): PAUSED,
    **{(s, 'failed'): FAILED for s in (STOPPED, PAUSED, PLAYING)},
    (FAILED, 'reset'): PAUSED,
}
#: Events after which nothing the loop did by itself is still the news: they clear the
#: state's reason and divergence report.
_CLEARS = frozenset({'load_stopped', 'load_paused', 'load_playing', 'hold', 'unload', 'play',
                     'stop', 'reset'})
#: Events that say why: the loop's reports.
_REPORTS = frozenset({'limit', 'diverged', 'diverged_on', 'failed'})

ERR_NO_WORLD = 'no world is loaded; call load_world first'
ERR_LOADING = 'a world is loading (LOADING_WORLD): ask again when load_world has answered'
ERR_NOT_REQUESTABLE = ('cannot set state {target!r}: ask for playing, paused or stopped (or '
                       'quit the simulator)')
ERR_ALREADY = 'already in that state'
ERR_HELD = ('this world is stepped by its owner (Session.hold), not by a loop: step it from '
            'the script that holds it')

#: How long the session's thread sleeps when nothing wakes it (a new model, a report of the
#: loop's, a load, a new listener each wake it at once): a safety net, not a poll.
IDLE_SEC = 1.0
#: How long the session's thread lets an edit's caller have the process before it reacts to
#: the new model: the listeners' work (Python, holding the interpreter's lock) delayed the
#: spawn's answer by 4-5 ms, more than a fifth of a small robot's round trip.
SETTLE_SEC = 0.01


class StateEvent(NamedTuple):
    """
    The session's state as a listener's ``on_state`` receives it.

    ``state`` is what ``get_simulation_state`` answers (a failed loop shows STOPPED);
    ``failed`` says the loop failed (only a stop, a reset or a load brings it back); ``reason``
    says why the simulation paused or stopped by itself (a limit, a divergence, a failure) or
    is '' ; ``divergence`` is the last divergence's report (step, time, entity, body, warnings
    and the policy's ``action``) until a play, stop, reset or load; ``cause`` is the event that
    made this state (``'play'``, ``'limit'``, ``'load_stopped'``...); ``seq`` counts events.
    """

    state: str
    failed: bool = False
    reason: str = ''
    divergence: Optional[dict] = None
    cause: str = ''
    seq: int = 0


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
        self._state = NO_WORLD  # written by _go only
        self._before_loading = NO_WORLD  # the state a failed load goes back to
        self._event = StateEvent(NO_WORLD)  # the newest, as listeners receive it
        self._loading = 0
        self._listeners: list = []  # Mailbox, in the order they were added
        self._seen_cv = threading.Condition()  # notified when a listener has seen a model
        self._wake = threading.Event()  # a load, an unload, a new listener, model or report
        self._closing = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._dispatched: tuple = ('never', None)  # the model key last handed to listeners
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
        loop = SimLoop(world, config, on_report=self._wake.set)
        if stopped:
            loop.hold()
        event = 'load_stopped' if stopped else 'load_paused' if loop.held else 'load_playing'
        loaded = Loaded(world, loop, name, uri)
        self._swap(loaded, event)
        loop.start()
        log.info('world %r loaded from %s: %d entities, dt=%g s, %s', name, uri or '(text)',
                 len(world.entities()), world.timestep, self.state)
        return loaded

    def hold(self, world: World, name: str = '', uri: str = '') -> Loaded:
        """
        Make `world` the loaded one, stepped by its owner (a script, a Gym env): no loop.

        The front-ends follow it as they follow a looped world (a window on a script's world);
        its state is PLAYING, and pausing, playing, stepping or stopping it is refused
        (:data:`ERR_HELD`): its owner decides. The old loop, if any, is stopped.
        """
        loaded = Loaded(world, None, name, uri)
        self._swap(loaded, 'hold')
        return loaded

    def _swap(self, new: Optional[Loaded], event: str) -> Optional[Loaded]:
        """Make `new` the loaded one by `event`; stop the old loop; wake the session's thread."""
        with self._lock:
            if new is None and self._loaded is None:
                raise NoWorldError(ERR_NO_WORLD)
            old, self._loaded = self._loaded, new
            self._go(event)
        if old is not None:
            old.world.remove_model_watcher(self._wake.set)
            if old.loop is not None:
                old.loop.stop()
            old.world.release_meshes(every=True)  # its deleted robots' kept meshes
        if new is not None:
            new.world.add_model_watcher(self._wake.set)
        self._wake.set()
        self._start_thread()
        return old

    def load_file(self, path: str, config: Optional[WorldConfig] = None,
                  stopped: bool = False, places: Optional[Places] = None,
                  paced_by_file: bool = False) -> Loaded:
        """
        Load an MJCF, URDF or SDF scene file (see :meth:`load`).

        The world is named by its file, or by the name an SDF world gives itself. Without a
        `config` (or with `paced_by_file`), the real-time factor an SDF world's ``<physics>``
        asks paces it.

        :param places: where an SDF world's ``model://`` URIs lead (see :meth:`World.from_file`).
        """
        p = Path(path)
        world = World.from_file(str(p), config or WorldConfig(), places)
        if (config is None or paced_by_file) and world.real_time_factor is not None:
            config = replace(world.config, real_time_factor=world.real_time_factor)
        return self.load(world, world.name or p.stem, p.resolve().as_uri(), stopped, config)

    @contextlib.contextmanager
    def loading(self) -> Iterator[None]:
        """
        While inside, the state is LOADING_WORLD (a load reads and compiles meanwhile).

        A :meth:`load` inside ends it; leaving without one (the load failed) goes back to the
        state before.
        """
        with self._lock:
            self._loading += 1
            if self._loading == 1:
                self._go('loading')
        try:
            yield
        finally:
            with self._lock:
                self._loading -= 1
                if self._loading == 0:
                    self._go('load_failed')  # nothing if a load took the state elsewhere

    def unload(self) -> Loaded:
        """Stop and drop the loaded world (NO_WORLD); :raises NoWorldError: none is loaded."""
        return self._swap(None, 'unload')

    def close(self) -> None:
        """Stop the loop, the session's and the listeners' threads (a world stays loaded)."""
        self._closing.set()
        self._wake.set()
        loaded = self._loaded
        if loaded is not None and loaded.loop is not None:
            # Short: a spawn still compiling holds the world lock and the loop waits for it.
            loaded.loop.stop(timeout=0.5)
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(2.0)
        with self._lock:
            listeners = list(self._listeners)
        for registered in listeners:
            registered.close()
        if self._trimmer is not None:
            self._trimmer.close()

    # ---------------------------------------------------------------- the lifecycle

    @property
    def state(self) -> str:
        """One of NO_WORLD, LOADING_WORLD, STOPPED, PAUSED, PLAYING."""
        with self._lock:
            self._take_reports_locked()
            return self._event.state

    def state_event(self) -> StateEvent:
        """Return the current :class:`StateEvent` (what ``on_state`` last delivered, or newer)."""
        with self._lock:
            self._take_reports_locked()
            return self._event

    def _take_reports_locked(self) -> None:
        """Decide on what the loop did by itself since it was last asked (session lock held)."""
        loaded = self._loaded
        if loaded is not None and loaded.loop is not None:
            for report in loaded.loop.take_reports():
                self._go(report.kind, report.reason, report.divergence)

    def _go(self, event: str, reason: str = '', divergence: Optional[dict] = None) -> str:
        """
        Apply `event` by :data:`TRANSITIONS`; tell the listeners (session lock held).

        The only place the state is written. A report (`reason`, `divergence`) is kept with
        the state until an event of :data:`_CLEARS`.
        """
        old = self._event
        if self._state == LOADING_WORLD and (LOADING_WORLD, event) not in TRANSITIONS:
            # The world that still runs while another loads: its state to go back to.
            self._before_loading = TRANSITIONS.get((self._before_loading, event),
                                                   self._before_loading)
        else:
            nxt = TRANSITIONS.get((self._state, event), self._state)
            if nxt == BEFORE_LOADING:
                nxt = self._before_loading
            elif nxt == LOADING_WORLD and self._state != LOADING_WORLD:
                self._before_loading = self._state
            self._state = nxt
        keep_reason = event not in _CLEARS
        if event in _REPORTS:
            why, div = reason, divergence if divergence is not None else (
                old.divergence if keep_reason else None)
        else:
            why = old.reason if keep_reason else ''
            div = old.divergence if keep_reason else None
        shown = STOPPED if self._state == FAILED else self._state
        failed = self._state == FAILED or (self._state == LOADING_WORLD
                                           and self._before_loading == FAILED)
        if (shown, failed, why, div) != (old.state, old.failed, old.reason, old.divergence):
            self._event = StateEvent(shown, failed, why, div, event, old.seq + 1)
            for registered in self._listeners:
                registered.offer_state(self._event)
        return self._state

    def status_message(self) -> str:
        """Why the simulation stopped or paused by itself, or a word when it lags; else ''."""
        with self._lock:
            self._take_reports_locked()
            loaded, reason = self._loaded, self._event.reason
        if reason or loaded is None or loaded.loop is None:
            return reason
        return loaded.loop.status().lag

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
                raise StateTransitionError(self._event.reason)
        # Outside the lock: a stop resets, which may compile (the spawned entities go).
        {PLAYING: self.play, PAUSED: self.pause, STOPPED: self.stop}[target]()

    def play(self) -> None:
        """Play (from STOPPED too); :raises IncorrectStateError: the loop failed."""
        with self._lock:
            loop = self.loop
            self._take_reports_locked()
            if self._state == FAILED:  # the state stays: only a stop or reset recovers
                raise IncorrectStateError(self._event.reason)
            loop.run()
            self._go('play')

    def pause(self) -> None:
        with self._lock:
            loop = self.loop
            self._take_reports_locked()
            loop.hold()
            self._go('pause')

    def stop(self) -> None:
        """Stop: pause and reset everything (time, state, spawned); a failed loop recovers."""
        with self._lock:
            loaded = self.require()
            self.loop.hold()
            loaded.loop.cancel_steps()
        loaded.world.reset(RESET_ALL)
        with self._lock:
            self._take_reports_locked()
            if self._state == FAILED:
                log.info('the simulation recovers (stopped): %s', self._event.reason)
            self._go('stop')
        loaded.loop.refresh_snapshot()

    def step(self, n: int, feedback: Optional[Callable[[int, int], None]] = None) -> int:
        """
        Run `n` steps while paused (or stopped: the simulation is then paused); block until done.

        Returns the steps taken; raises as
        :meth:`SimLoop.step <sim_node.core.loop.SimLoop.step>`, and
        IncorrectStateError while the loop has failed.
        """
        with self._lock:
            loop = self.loop
            self._take_reports_locked()
            if self._state == FAILED:
                raise IncorrectStateError(self._event.reason)
        done = loop.step(n, feedback=feedback)
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
                if self._state == FAILED:
                    log.info('the simulation recovers (paused): %s', self._event.reason)
                self._go('reset')
            loaded.loop.refresh_snapshot()

    def changed(self) -> None:
        """Say the world was written outside the loop: consumers get a fresh snapshot now."""
        loaded = self._loaded
        if loaded is not None and loaded.loop is not None:
            loaded.loop.refresh_snapshot()

    # ---------------------------------------------------------------- listeners

    def add_listener(self, on_model: Optional[Listener] = None,
                     on_state: Optional[StateListener] = None, name: str = '') -> object:
        """
        Add a listener of new models and states; return its handle.

        ``on_model(loaded, snapshot)`` is called with every new model and ``on_state(event)``
        with every :class:`StateEvent`, each from the listener's own thread. ``loaded`` and
        ``snapshot`` (of the new model) are None when nothing is loaded. A listener added while
        a world is loaded is given it, and the current state, first. A slow listener holds back
        nobody but itself; an exception is logged and the next event still comes.
        """
        label = name or getattr(on_model or on_state, '__qualname__', 'listener')
        registered = Mailbox(on_model, on_state, label, self._seen)
        with self._lock:
            self._listeners.append(registered)
            registered.offer_state(self._event)
        self._wake.set()
        self._start_thread()
        return registered

    def remove_listener(self, listener) -> None:
        """
        Stop calling a listener.

        `listener` is its handle, or a hook of it (compared by equality: the same bound method
        detaches).
        """
        with self._lock:
            gone = [r for r in self._listeners if listener in (r, r.on_model, r.on_state)]
            self._listeners = [r for r in self._listeners if r not in gone]
        for registered in gone:
            registered.close()

    def sync(self, timeout: float = 10.0) -> bool:
        """Wait until every listener has seen the model that is current now; False on timeout."""
        deadline = time.monotonic() + timeout
        while True:
            key = _key(self._loaded)
            with self._seen_cv:
                with self._lock:
                    behind = [r for r in self._listeners
                              if r.on_model is not None and r.seen != key]
                if not behind:
                    return True
                left = deadline - time.monotonic()
                if left <= 0 or self._thread is None:
                    return False
                self._wake.set()
                self._seen_cv.wait(min(left, 0.05))

    def _seen(self) -> None:
        with self._seen_cv:
            self._seen_cv.notify_all()

    # ---------------------------------------------------------------- the session's thread

    def _start_thread(self) -> None:
        with self._lock:
            if self._thread is not None or self._closing.is_set():
                return
            if self._trim_memory:  # a listener like the others, acting on its own thread
                self._trimmer = HeapTrimmer()
                self._listeners.append(Mailbox(self._trimmer.model_changed, None,
                                               'heap-trimmer', self._seen))
            self._thread = threading.Thread(target=self._watch, name='sim-session', daemon=True)
            self._thread.start()

    def _watch(self) -> None:
        """Apply the loop's reports and hand each new model to the listeners, when woken."""
        while not self._closing.is_set():
            try:
                self._wake.wait(IDLE_SEC)
                self._wake.clear()
                if self._closing.is_set():
                    return
                with self._lock:
                    self._take_reports_locked()
                self._dispatch_model()
                loaded = self._loaded
                if loaded is not None:  # at least every IDLE_SEC: deleted robots' meshes
                    loaded.world.release_meshes()
            except Exception:  # noqa: B902 (never die silently: say why, go on)
                log.exception('the session thread failed; it goes on')
                self._closing.wait(0.5)

    def _dispatch_model(self) -> None:
        """Offer the current model to every listener that has not been offered it."""
        loaded = self._loaded
        key = _key(loaded)
        with self._lock:
            behind = [r for r in self._listeners if r.offered != key]
        if not behind:
            return
        if loaded is not None and self._dispatched[0] is loaded.world:
            self._closing.wait(SETTLE_SEC)  # an edit: the editor answers its caller first
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
        self._dispatched = key
        with self._lock:
            behind = [r for r in self._listeners if r.offered != key]
        for registered in behind:
            registered.offer_model(key, loaded, snap)


def _key(loaded: Optional[Loaded]) -> tuple:
    """Return what a listener sees of a world: (world, generation); (None, None): none."""
    return (None, None) if loaded is None else (loaded.world, loaded.world.generation)
