"""
The stepping loop: one thread that advances a :class:`World` at a fixed step.

* Real-time factor 1.0 paces simulated time to the wall clock (2.0: twice as fast; 0: as fast
  as possible). Pacing sleeps to absolute deadlines outside the world lock and re-syncs after a
  stall instead of bursting to catch up.
* :meth:`SimLoop.hold` and :meth:`SimLoop.run`; :meth:`SimLoop.step` runs N steps while it
  holds and blocks until done. A holding loop waits on a condition: no CPU.
* Termination constraints (max steps, max simulated time) make the loop hold: it stops after
  the first step whose time is >= max_sim_time (see :func:`time_reached`).
* Divergence makes it hold (or its policy acts); the world is back at the last good state.
* What it did by itself (a limit, a divergence, an internal error) it reports
  (:meth:`SimLoop.take_reports`, and its ``on_report`` hook at once); it keeps no lifecycle of
  its own. Playing, paused, stopped or failed, and why, is its owner's to decide: a
  :class:`~sim_node.session.Session` turns the reports into its one state.
* Every ``1/snapshot_rate_hz`` wall seconds (and after every change) the loop makes an
  immutable :class:`~sim_node.core.records.Snapshot` that consumers read from any thread.
"""

import atexit
import collections
import logging
import math
import threading
import time
from typing import Callable, Optional
import weakref

from .base.config import WorldConfig
from .base.errors import (DivergenceError, IncorrectStateError, InvalidArgumentError,
                          OperationFailedError, SimError)
from .base.records import Clock, LoopStatus, Report, RESET_STATE, Snapshot
from .stepping.rate import RateWindow
from .stepping.snapshots import Snapshots
from .world import World

log = logging.getLogger(__name__)

#: What the loop reports having done by itself (:class:`~sim_node.core.records.Report`).
LIMIT = 'limit'
DIVERGED = 'diverged'
DIVERGED_ON = 'diverged_on'
FAILED = 'failed'
#: Reports kept for an owner that does not ask (a loop run on its own): the newest only.
REPORTS_KEPT = 16
# Longest the loop holds the world lock per batch when running as fast as possible (s).
MAX_BATCH_WALL_SEC = 0.005
MAX_BATCH_STEPS = 1000
#: Divergence policies and what each did, for the stop reason.
ACTIONS = {'pause': 'paused', 'remove': 'removed that entity and played on',
           'reset': 'reset the state and played on'}

# Simulated time is a sum of timesteps, with rounding error: a time within this fraction of a
# step of a limit counts as having reached it (so T = 100 steps never needs a 101st).
TIME_TOLERANCE_STEPS = 1e-3


def time_reached(time_sec: float, limit_sec: float, timestep: float) -> bool:
    """Return True once `time_sec` is at or past `limit_sec` (within a thousandth of a step)."""
    return time_sec >= limit_sec - TIME_TOLERANCE_STEPS * timestep


def steps_until(time_sec: float, limit_sec: float, timestep: float) -> int:
    """Step until the first step whose time is >= `limit_sec` (0 if already there)."""
    return max(0, math.ceil((limit_sec - time_sec) / timestep - TIME_TOLERANCE_STEPS))


ERR_FAILED = ('the stepping loop failed ({error}); reset the simulation or load a world to '
              'recover')
ERR_INTERRUPTED = ('the step request was ended by a state request after {done} of {n} '
                   'steps')
ERR_STEP_WHILE_PLAYING = 'the simulation is playing; pause it before stepping'
ERR_BUSY = 'another step request is still running'
ERR_NOT_RUNNING = 'the stepping loop is not running'
ERR_STEP_UNDER_LOCK = ('step() called inside World.locked(): the loop steps under the world lock, '
                       'so it would wait for ever; leave the block first')


_RUNNING: 'weakref.WeakSet' = weakref.WeakSet()


@atexit.register
def _stop_running_loops() -> None:
    """Stop loops still stepping at interpreter exit (a script that never called stop())."""
    for loop in list(_RUNNING):
        loop.stop()


class SimLoop:
    """
    Steps a world on its own thread.

    Start with :meth:`start`, end with :meth:`stop`. What watches it (a window, a browser
    view, a recorder) attaches from above, through a :class:`~sim_node.session.Session`.

    :param on_report: called with no argument, from the loop's thread and holding none of its
        locks, each time it reports something (:meth:`take_reports`): its owner's wake-up. It
        must not block (a session sets an event).
    """

    def __init__(self, world: World, config: Optional[WorldConfig] = None,
                 on_report: Optional[Callable[[], None]] = None):
        cfg = config or world.config
        self.world = world
        self._rtf = float(cfg.real_time_factor)
        self._max_steps = int(cfg.max_steps)
        self._max_sim_time = float(cfg.max_sim_time)
        self._snapshot_period = 1.0 / cfg.snapshot_rate_hz if cfg.snapshot_rate_hz > 0 else 0.0
        self._resync = float(cfg.resync_after_sec)
        if cfg.divergence_policy not in ACTIONS:
            raise InvalidArgumentError(f'divergence_policy must be one of {sorted(ACTIONS)}, '
                                       f'got {cfg.divergence_policy!r}')
        self._policy = cfg.divergence_policy
        self._cv = threading.Condition()
        self._held = bool(cfg.paused)  # told to hold (or holding after a report)
        self._stopping = False
        self._pending_steps = 0
        self._in_batch = False  # the loop thread is running a batch it decided on
        self._steps_done_cv = threading.Condition(self._cv)
        #: What the loop did by itself, for its owner to decide on (:meth:`take_reports`).
        self._reports: collections.deque = collections.deque(maxlen=REPORTS_KEPT)
        self.on_report = on_report
        self._cancelled_left: Optional[int] = None  # steps a cancelled request had left
        self._request_divergence: Optional[dict] = None  # met by the running step request
        self._thread: Optional[threading.Thread] = None
        self._snapshots = Snapshots(world.snapshot())
        self._batch = 1
        self._deadline = time.perf_counter()
        self._last_snapshot = 0.0
        self._rate = RateWindow()
        self._told = True  # on_report was called for every report so far

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        if self._thread is not None:
            return
        # Daemon, so an interpreter exit never hangs on it; stop() joins it properly, and at
        # exit every running loop is stopped before the interpreter tears MuJoCo down under it.
        self._thread = threading.Thread(target=self._run, name='sim-loop', daemon=True)
        _RUNNING.add(self)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        with self._cv:
            self._stopping = True
            self._cv.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # ------------------------------------------------------------------ control

    def hold(self) -> None:
        """
        Hold: take no step until :meth:`run` (or :meth:`step`); a step request in progress ends.

        When it returns no step runs any more: a batch already under way (at most about
        :data:`MAX_BATCH_WALL_SEC`) has ended, so a reset or a state write that follows is what
        a paused world shows. (Called inside :meth:`World.locked`, it cannot wait for that batch,
        which needs the lock: the batch runs once the lock is let go.)
        """
        with self._cv:
            self._cancel_steps_locked()
            self._held = True
            self._drop_reports_locked(LIMIT, DIVERGED)  # this hold supersedes them
            self._cv.notify_all()
            # Not on the loop's thread, nor under the world lock (the batch needs it).
            if threading.get_ident() != getattr(self._thread, 'ident', None) \
                    and not self.world.holds_lock():
                while self._in_batch:
                    self._cv.wait()

    def cancel_steps(self) -> None:
        """
        End a step request in progress.

        Its caller gets an IncorrectStateError saying how many steps were done. A simulator must
        never be held by one request for ever.
        """
        with self._cv:
            self._cancel_steps_locked()

    def _cancel_steps_locked(self) -> None:
        if self._pending_steps:
            self._cancelled_left, self._pending_steps = self._pending_steps, 0
            self._steps_done_cv.notify_all()

    def run(self) -> None:
        """Step (paced by the real-time factor) until told to hold; limits still apply."""
        with self._cv:
            self._cancel_steps_locked()
            self._held = False
            self._reports.clear()  # this run supersedes the holds the loop made itself
            self._cv.notify_all()

    @property
    def held(self) -> bool:
        """Whether the loop holds (told to, or by itself after a report): no step is due."""
        return self._held

    def take_reports(self) -> list:
        """
        Return, and forget, what the loop did by itself since it was last asked, oldest first.

        Each is a :class:`~sim_node.core.records.Report`: :data:`LIMIT` (a termination
        constraint made it hold), :data:`DIVERGED` (divergence made it hold),
        :data:`DIVERGED_ON` (its divergence policy acted and it steps on), :data:`FAILED` (an
        internal error made it hold). The loop acts at once (it must not take another step);
        its owner (a :class:`~sim_node.session.Session`) decides what that means for its
        lifecycle. A later :meth:`run` or :meth:`hold` supersedes the holds reported before it.
        """
        with self._cv:
            reports = list(self._reports)
            self._reports.clear()
            return reports

    def _report_locked(self, report: Report) -> None:
        """Keep `report` for :meth:`take_reports` (``_cv`` held; the owner is told after)."""
        self._reports.append(report)
        self._told = False

    def _tell_owner(self) -> None:
        """Call ``on_report`` once for what was reported (no lock of the loop's held)."""
        hook = self.on_report
        if hook is not None and not self._told:
            self._told = True
            hook()

    def _drop_reports_locked(self, *kinds: str) -> None:
        self._reports = collections.deque((r for r in self._reports if r[0] not in kinds),
                                          maxlen=REPORTS_KEPT)

    def set_real_time_factor(self, rtf: float) -> None:
        if not (rtf >= 0 and rtf < float('inf')):
            raise InvalidArgumentError(f'real_time_factor must be >= 0 and finite, got {rtf}')
        with self._cv:
            self._rtf = float(rtf)
            self._cv.notify_all()

    @property
    def real_time_factor(self) -> float:
        return self._rtf

    def set_limits(self, max_steps: int = 0, max_sim_time: float = 0.0) -> None:
        """Termination constraints; 0 disables each."""
        if max_steps < 0 or not max_sim_time >= 0:
            raise InvalidArgumentError('max_steps and max_sim_time must be >= 0')
        with self._cv:
            self._max_steps, self._max_sim_time = int(max_steps), float(max_sim_time)

    def step(self, n: int = 1, timeout: Optional[float] = None,
             feedback: Optional[Callable[[int, int], None]] = None) -> int:
        """
        Run `n` steps while the loop holds; block until they are done.

        Returns steps completed.

        :param feedback: called as ``feedback(completed, remaining)`` from this thread.
        :raises OperationFailedError: the loop is stepping on its own (not held).
        :raises IncorrectStateError: the loop is not running.
        :raises DivergenceError: the physics diverged during these steps.
        """
        if n < 1:
            raise InvalidArgumentError(f'steps must be >= 1, got {n}')
        if self.world.holds_lock():  # the loop needs the world lock to step: it would never
            raise IncorrectStateError(ERR_STEP_UNDER_LOCK)  # come, and the caller wait for ever
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cv:
            if not self._held:
                raise OperationFailedError(ERR_STEP_WHILE_PLAYING)
            if not self.running:
                raise IncorrectStateError(ERR_NOT_RUNNING)
            if self._pending_steps:
                raise IncorrectStateError(ERR_BUSY)
            self._pending_steps = n
            self._cancelled_left = None
            self._request_divergence = None
            self._cv.notify_all()
            last = n
            while self._pending_steps and not self._stopping:
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    break
                self._steps_done_cv.wait(0.1 if left is None else min(left, 0.1))
                if feedback is not None and self._pending_steps != last:
                    last = self._pending_steps
                    self._cv.release()  # the caller's code runs with no lock of ours held
                    try:
                        feedback(n - last, last)
                    finally:
                        self._cv.acquire()
            remaining = self._pending_steps
            self._pending_steps = 0
            if self._cancelled_left is not None:
                done, self._cancelled_left = n - self._cancelled_left, None
                raise IncorrectStateError(ERR_INTERRUPTED.format(done=done, n=n))
            if self._request_divergence is not None:
                div, self._request_divergence = self._request_divergence, None
                raise DivergenceError(f'physics diverged at step {div["step"]}', div['step'],
                                      div)
        return n - remaining

    def _after_divergence(self, report: dict) -> str:
        """Apply the divergence policy; returns what was done: 'pause', 'remove' or 'reset'."""
        policy = self._policy
        try:
            if policy == 'remove' and report.get('entity') in self.world.spawned_names():
                self.world.delete(report['entity'])
                log.warning('removed %r, where the physics diverged; playing on',
                            report['entity'])
                return 'remove'
            if policy == 'reset':
                self.world.reset(RESET_STATE)
                log.warning('reset the state after the physics diverged; playing on')
                return 'reset'
        except SimError as exc:  # the policy could not act: pause, as by default
            log.error('divergence policy %r failed: %s', policy, exc)
        return 'pause'

    # ------------------------------------------------------------------ status, snapshots

    def status(self) -> LoopStatus:
        """Where the loop is and how fast it steps (the lifecycle is its owner's)."""
        snap = self._snapshots.latest
        with self._cv:
            held = self._held or not self.running
            return LoopStatus(step=snap.step, time=snap.time, real_time_factor=self._rtf,
                              held=held, achieved_real_time_factor=self._rate.achieved,
                              lag='' if held else self._rate.lag_message)

    def latest_snapshot(self) -> Snapshot:
        return self._snapshots.latest

    def wait_snapshot(self, after_seq: int, timeout: float) -> tuple:
        """Block until a snapshot newer than `after_seq` exists; returns (seq, snapshot)."""
        return self._snapshots.wait(after_seq, timeout)

    def refresh_snapshot(self) -> None:
        """Make a snapshot now (after a spawn, reset or set-state while paused)."""
        self._snapshots.offer(self.world.snapshot())

    # ------------------------------------------------------------------ the loop

    def _limit_reason(self, w: Clock) -> str:
        if self._max_steps and w.step_count >= self._max_steps:
            return f'max_steps reached ({self._max_steps} steps)'
        if self._max_sim_time and time_reached(w.time, self._max_sim_time, w.timestep):
            return f'max_sim_time reached ({self._max_sim_time} s)'
        return ''

    def _steps_to_limit(self, w: Clock) -> int:
        n = MAX_BATCH_STEPS
        if self._max_steps:
            n = min(n, self._max_steps - w.step_count)
        if self._max_sim_time:
            n = min(n, steps_until(w.time, self._max_sim_time, w.timestep))
        return max(n, 1)

    def _run(self) -> None:
        while not self._stopping:
            try:
                self._iterate()
            except Exception as exc:  # never die silently: hold, say why, let the owner decide
                log.exception('the stepping loop failed')
                with self._cv:
                    self._held = True
                    self._report_locked(Report(FAILED, ERR_FAILED.format(error=repr(exc))))
                    self._pending_steps = 0
                    self._steps_done_cv.notify_all()
            self._tell_owner()  # outside every lock of the loop's (see on_report)

    def _iterate(self) -> None:
        """
        Wait until stepping is due, run one batch of steps, hand out a snapshot.

        The world lock is never taken while ``_cv`` is held (the lock order, docs/threading.md):
        what the batch needs of the world is read before. A batch takes the world lock once:
        the clock comes from the batch before unless something changed the world since
        (``world.stepping.clock_since_batch``), and the snapshot is made in the batch's hold.
        """
        with self._cv:
            idle = not self._stopping and self._held and not self._pending_steps
        if idle:
            # Consumers see the state the loop stopped in, not one from before the pause.
            self.refresh_snapshot()
        clock = self.world.stepping.clock_since_batch() or self.world.clock()
        with self._cv:
            if not self._stopping and self._held and not self._pending_steps:
                while not self._stopping and self._held and not self._pending_steps:
                    self._cv.wait()
                self._deadline = time.perf_counter()
                self._rate.restart()  # a pause is not lag
                return  # the world may have changed meanwhile (a reset): read it again
            if self._stopping:
                return
            stepping_request = self._held
            rtf = self._rtf
            reason = '' if stepping_request else self._limit_reason(clock)
            if reason:
                self._held = True
                self._report_locked(Report(LIMIT, reason))
                log.info('loop holds: %s', reason)
                return
            if stepping_request:
                n = min(self._pending_steps, self._batch)
            elif rtf > 0:
                period = clock.timestep / rtf
                lag = time.perf_counter() - self._deadline
                if lag < 0:
                    # Sleep to the absolute deadline outside the world lock; a pause, stop
                    # or new rate wakes us early.
                    self._cv.wait(-lag)
                    return
                if lag > self._resync:
                    self._deadline = time.perf_counter()  # stalled: re-sync, don't burst
                    lag = 0.0
                n = min(self._batch, int(lag / period) + 1)
            else:
                n = self._batch
            if not stepping_request:
                n = min(n, self._steps_to_limit(clock))
            # A step request's last batch is shown by a snapshot before its caller hears.
            last_request_batch = stepping_request and self._pending_steps <= n
            self._in_batch = True  # pause() waits for it: no step after pause() returned
        try:
            self._batch_of(n, clock, rtf, stepping_request, last_request_batch)
        finally:
            with self._cv:
                self._in_batch = False
                self._cv.notify_all()

    def _batch_of(self, n: int, clock, rtf: float, stepping_request: bool,
                  last_request_batch: bool) -> None:
        """Run one batch of `n` steps decided by :meth:`_iterate`; hand out its snapshot."""
        self.world.stepping.wait_for_callers()
        t0 = time.perf_counter()
        try:
            snap = self.world.stepping.batch(n, last_request_batch or (
                t0 - self._last_snapshot >= self._snapshot_period))
        except DivergenceError as exc:
            log.error('%s', exc)
            action = self._after_divergence(exc.report)
            with self._cv:
                self._held = self._held or action == 'pause'
                divergence = dict(exc.report, action=action)
                if self._pending_steps:
                    self._request_divergence = divergence
                self._report_locked(Report(DIVERGED if action == 'pause' else DIVERGED_ON,
                                           f'{exc}; {ACTIONS[action]}', divergence))
                self._pending_steps = 0
                self._steps_done_cv.notify_all()
            self.refresh_snapshot()
            return
        now = time.perf_counter()
        if snap is not None:
            self._last_snapshot = now
            self._snapshots.offer(snap)
        if stepping_request:
            with self._cv:
                last_batch = self._pending_steps <= n
            if last_batch and snap is None:  # a cancel meanwhile left fewer steps to do
                self.refresh_snapshot()
            with self._cv:
                self._pending_steps = max(0, self._pending_steps - n)
                self._steps_done_cv.notify_all()
        elif rtf > 0:
            self._deadline += n * clock.timestep / rtf
        # Every batch holds the lock for about MAX_BATCH_WALL_SEC at most, whatever asked
        # for it (full speed, catching up with a high factor, a step request), so snapshots
        # and callers are never held off longer.
        per_step = (now - t0) / n
        self._batch = max(1, min(MAX_BATCH_STEPS,
                                 int(MAX_BATCH_WALL_SEC / max(per_step, 1e-7))))
        if not stepping_request:
            self._rate.batch(now, n, rtf, clock.timestep, per_step)
