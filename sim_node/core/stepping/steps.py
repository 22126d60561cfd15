"""
Stepping a world: the steps, the divergence check around them, and the loop's protocol.

:meth:`Stepping.step` is what :meth:`World.step <sim_node.core.world.World.step>` does. The
stepping loop (:class:`~.loop.SimLoop`) talks to a world through ``world.stepping`` only:
:meth:`Stepping.batch` (the steps, the clock and a snapshot in one hold of the world lock),
:meth:`Stepping.clock_since_batch` and :meth:`Stepping.wait_for_callers`. Those are not part of
``World``'s own surface: nobody but the loop needs them.
"""

import math
from typing import Callable, Optional

import mujoco
import numpy as np

from . import sampling
from .guard import clean
from .live import Live
from ..base.checks import check_finite
from ..base.errors import DivergenceError, InvalidArgumentError, SimError
from ..base.records import Clock, Snapshot
from ..compiled import state
from ..compiled.index import STATE_SPEC

ERR_STEPS = 'steps must be >= 1, got {n}'
#: How long the loop lets callers waiting for the world lock go first, at most, per batch. It
#: is time the world does not step: under a storm of edits there are always callers waiting,
#: and 50 ms here stalled /clock by 50-77 ms at a time (make bench-storm).
CALLERS_FIRST_SEC = 0.01


class Stepping:
    """Steps a :class:`~.live.Live` world under its lock."""

    def __init__(self, live: Live):
        self.live = live

    def step(self, n: int = 1, ctrl: Optional[np.ndarray] = None,
             then: Optional[Callable[[mujoco.MjModel, mujoco.MjData], None]] = None) -> int:
        """See :meth:`World.step <sim_node.core.world.World.step>`."""
        if n < 1:
            raise InvalidArgumentError(ERR_STEPS.format(n=n))
        # Once per Gym step and per loop batch: take a free lock directly. It is WorldLock's
        # own fast path without the context-manager calls, 0.25 us a step (1% of a
        # Reacher-v5 step); a contended lock goes through WorldLock as usual.
        lock = self.live.lock
        if lock.lock.acquire(blocking=False):
            try:
                return self.step_locked(int(n), ctrl, then)
            finally:
                lock.lock.release()
        with lock:
            return self.step_locked(int(n), ctrl, then)

    def kinematic(self, positions: dict, n: int = 1) -> int:
        """See :meth:`World.step_kinematic <sim_node.core.world.World.step_kinematic>`."""
        if n < 1:
            raise InvalidArgumentError(ERR_STEPS.format(n=n))
        live = self.live
        with live.lock:
            i = live.index.joints(positions.keys())
            targets = check_finite('joint positions', list(positions.values()))
            qadr, dadr = live.index.joint_qposadr[i], live.index.joint_dofadr[i]
            for _ in range(n):
                state.kinematic_step(live.model, live.data, qadr, dadr, targets)
            live.step_count += n
            live.cached = None
            live.stale_kinematics, live.stale_dynamics = False, True
            return live.step_count

    # ---------------------------------------------------------------- the loop's protocol

    def wait_for_callers(self, timeout: float = CALLERS_FIRST_SEC) -> None:
        """Let callers waiting for the world lock go first (the loop, before each batch)."""
        self.live.lock.wait_for_callers(timeout)

    def batch(self, n: int, snapshot: bool) -> Optional[Snapshot]:
        """
        For the loop: `n` steps, then the clock and, if asked, a snapshot, in one hold.

        One acquisition of the world lock per batch instead of three (clock, step, snapshot):
        under a storm of edits each acquisition can wait behind other callers, and the waits
        added up to stalls of 60-110 ms (``make bench-storm``). The clock after the steps is
        kept for :meth:`clock_since_batch`. Returns the snapshot, or None; raises as
        :meth:`step` does.
        """
        live = self.live
        with live.lock:
            self.step_locked(int(n), None, None, quiet=True)
            live.batch_clock = live.clock_locked()
            return live.snapshot_locked() if snapshot else None

    def clock_since_batch(self) -> Optional[Clock]:
        """
        Return the clock :meth:`batch` gave, if nothing changed the world since; else None.

        Without the lock: every write of the state (resets, set_state, ``locked()``, a new
        model) clears ``Live.cached`` under the lock before it changes time, step count or
        timestep, and only the loop, which asks, steps. A read racing a write is one from just
        before it, as a locked read made a moment earlier would be.
        """
        live = self.live
        return live.batch_clock if live.cached is not None else None

    # ---------------------------------------------------------------- under the lock

    def step_locked(self, n: int, ctrl: Optional[np.ndarray],
                    then: Optional[Callable[[mujoco.MjModel, mujoco.MjData], None]],
                    quiet: bool = False) -> int:
        """
        Step under the lock; see :meth:`step`.

        :param quiet: make no MuJoCo call but the steps themselves on a clean batch (the loop:
            each call gives the GIL away, and other threads kept it for up to 5 ms each time
            under a storm of edits, with the world lock held meanwhile). Same results.
        """
        live = self.live
        # The state after the last clean batch, if untouched since: it holds the previous
        # controls, so a replay writes `ctrl` again.
        before = live.cached
        live.batch_clock = None  # set again by batch(), the loop's way to step
        if ctrl is not None:
            live.ctrl[:] = ctrl
        m, d, control = live.model, live.data, live.control
        if control.has_staged:
            control.apply_staged(live.index, m, d)
            before = None
        if control.batched and control.before_batch(m, d):  # a base's command timed out
            before = None
        if before is None:
            before = np.empty(live.index.state_size)
            mujoco.mj_getState(m, d, before, STATE_SPEC)
            ctrl = None  # already in `before`
        sampler = live.sampler
        if sampler is None or sampler.generation != live.index.generation \
                or sampler.request is not live.contact_request \
                or sampler.joints is not live.joint_requests or sampler.resets != live.resets \
                or sampler.lasers is not live.laser_requests:
            sampler = live.sampler = sampling.Sampler(
                live.index, live.samples, live.contact_request, live.joint_requests,
                live.resets, live.laser_requests, live.laser_poses)
        if control.per_step:
            self._step_each(m, d, n, sampler)
        elif control.batched or sampler:
            # stop the batch where a base's command times out or a declared sensor samples
            # A laser's due times end no batch: the batch is stepped by rollout, which takes
            # the state at each (Sampler.roll).
            left = n
            while left > 0:
                k = left
                due = control.batch_deadline(d.time) if control.batched else math.inf
                if due != math.inf:
                    k = min(k, max(1, math.ceil((due - d.time) / m.opt.timestep + 1e-9)))
                due = sampler.next_due(float(d.time)) if sampler else math.inf
                if due != math.inf:
                    k = min(k, max(1, math.ceil((due - d.time) / m.opt.timestep - 1e-6)))
                if sampler and sampler.lasers_due_by(float(d.time) + k * m.opt.timestep):
                    sampler.roll(m, d, k)
                else:
                    mujoco.mj_step(m, d, k)
                left -= k
                ticked = False
                if sampler:
                    sampler.collect(m, d, lasers=False)
                    ticked = self._apply_ticks(sampler)
                if left and ((control.batched and control.before_batch(m, d)) or ticked) \
                        and control.per_step:
                    self._step_each(m, d, left, sampler)
                    left = 0
        else:
            mujoco.mj_step(m, d, n)
        if live.guard.diverged(m, d, quiet):
            self._diverged_locked(before, n, ctrl)
        live.step_count += n
        # The state after a clean batch: the next batch's starting point (unless something
        # changes it), and the fallback for divergence caused by values put in between steps
        # (e.g. through locked()). One buffer, overwritten in place: `before` is spent by now.
        if quiet and live.copy_state is not None:
            live.copy_state(live.good_buf)
        else:
            mujoco.mj_getState(m, d, live.good_buf, STATE_SPEC)
        live.last_good = live.cached = live.good_buf
        live.stale_kinematics = live.stale_dynamics = True
        if then is not None:
            then(m, d)
        return live.step_count

    def _step_each(self, m: mujoco.MjModel, d: mujoco.MjData, n: int, sampler) -> None:
        """Step `n` times with the controls applied before each step (and samples after)."""
        control = self.live.control
        for _ in range(n):
            control.apply(m, d)
            mujoco.mj_step(m, d)
            if sampler:
                sampler.collect(m, d)
                self._apply_ticks(sampler)

    def _apply_ticks(self, sampler) -> bool:
        """
        Apply the joint commands the samples' ticks returned (controllers' laws) at once.

        A command for a joint gone meanwhile is left out. Divergence's replay
        (:meth:`_diverged_locked`) does not write them again: it names the step, as before.
        Return whether there were any.
        """
        writes, sampler.writes = sampler.writes, []
        if not writes:
            return False
        live = self.live
        for names, values, mode in writes:
            try:
                live.control.stage(live.index, names, values, mode)
            except SimError:
                continue
        live.control.apply_staged(live.index, live.model, live.data)
        return True

    def _diverged_locked(self, before: np.ndarray, n: int, ctrl: Optional[np.ndarray]) -> None:
        live = self.live
        m, d, control = live.model, live.data, live.control
        k, good, report = live.guard.locate(
            m, d, before, n, ctrl, (lambda: control.apply(m, d)) if control.per_step else None)
        bad_step = live.step_count + k + 1
        report['step'] = bad_step
        live.step_count += k
        if not clean(good):
            # The bad values were put in between steps (e.g. through locked()): go back to
            # the state after the last clean batch.
            good = live.last_good if live.last_good is not None else good
        live.set_state_locked(good, live.step_count)
        report['entity'], report['body'] = self._culprit_locked(report['warnings'])
        where = (f' in entity {report["entity"]!r} (body {report["body"]!r})'
                 if report['entity'] else '')
        raise DivergenceError(f'physics diverged at step {bad_step} (t={report["time"]:.4f} s)'
                              f'{where}: {report["warnings"] or "non-finite state"}; restored '
                              'the state before it', bad_step, report)

    def _culprit_locked(self, warnings: dict) -> tuple:
        """
        Return (entity, body) that MuJoCo's bad-state warning points at, or ('', '').

        The warning's ``lastinfo`` is the bad dof (qacc, qvel) or qpos entry: dof -> body, or
        qpos entry -> joint -> body, then the body's entity.
        """
        m, idx = self.live.model, self.live.index
        body = -1
        for name in ('mjWARN_BADQACC', 'mjWARN_BADQVEL', 'mjWARN_BADQPOS'):
            i = warnings.get(name)
            if i is None:
                continue
            if name != 'mjWARN_BADQPOS' and 0 <= i < m.nv:
                body = int(m.dof_bodyid[i])
            elif name == 'mjWARN_BADQPOS' and 0 <= i < m.nq and m.njnt:
                joint = int(np.searchsorted(m.jnt_qposadr, i, side='right')) - 1
                body = int(m.jnt_bodyid[max(joint, 0)])
            if body > 0:
                break
        if body <= 0:
            return '', ''
        return idx.body_names[int(idx.info.body_root[body])], idx.body_names[body]
