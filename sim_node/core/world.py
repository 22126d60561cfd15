"""
The MuJoCo world while it runs: one MjModel/MjData, its lock, stepping, reading and reset.

This is the run phase: the world keeps the lock, the current model, data, index and generation,
and its public methods lock, validate and delegate: addresses to :mod:`.index`, joint commands
to :mod:`.control`, the divergence check to :mod:`.guard`, state reads and writes to
:mod:`.state` (and :mod:`.world_writes`). The edit phase (spawn, delete, contact, mass, the
spec and its tables, the one commit path and compaction) is :mod:`.world_edits` over
:mod:`.design`. The threading contract is in the package docstring (``sim_node.core``).
"""

import contextlib
from pathlib import Path
import threading
from typing import Callable, Iterator, Optional, Sequence, TypeVar

import mujoco
import numpy as np

from . import assets, checks, description, editor, guard
from . import index as model_index
from . import sources, state, trajectory
from .checks import check_finite
from .config import WorldConfig
from .control import Control
from .design import Design
from .errors import (DivergenceError, FeatureUnsupportedError, IncorrectStateError,
                     InvalidArgumentError, InvalidPoseError, ResourceParseError)
from .guard import clean, DivergenceGuard
from .index import ModelIndex, STATE_SPEC
from .lock import WorldLock
from .records import (Clock, EntityRecord, EntityState, ModelInfo, PhysicsState, RESET_ALL,
                      RESET_SPAWNED, RESET_STATE, RESET_TIME, Snapshot)
from .world_edits import WorldEdits
from .world_writes import StateWrites

T = TypeVar('T')

ERR_STATE_GENERATION = ('this state was taken from model generation {got}, the world is now at '
                        'generation {now} (an entity was spawned or deleted since)')
ERR_SCOPE = ('reset scope {scope} has bits no simulator defines: use 0 (all), 255 (all) or a '
             'combination of 1 (time), 2 (state) and 4 (spawned)')
ERR_STEPS = 'steps must be >= 1, got {n}'
ERR_NO_DESCRIPTION = ('entity {name!r} has no hinge or slide joints: only robots have a robot '
                      'description')
#: How long the loop lets callers waiting for the world lock go first, at most, per batch. It
#: is time the world does not step: under a storm of edits there are always callers waiting,
#: and 50 ms here stalled /clock by 50-77 ms at a time (make bench-storm).
CALLERS_FIRST_SEC = 0.01
ERR_FRAME = ('the pose is given in frame {frame!r}, which is not known: use the world frame '
             "('' or 'world') or the name of an entity")

_SCOPE_BITS = RESET_TIME | RESET_STATE | RESET_SPAWNED
_NO_AUTORESET = int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)


class World(StateWrites, WorldEdits):
    """
    A MuJoCo world that can change while it runs.

    Thread-safe; see ``sim_node.core``.

    Build with :meth:`from_file` or :meth:`from_string`.
    """

    def __init__(self, spec: mujoco.MjSpec, config: WorldConfig = WorldConfig(),
                 source: str = ''):
        self.config = config
        self.source = source
        self._lock_cm = WorldLock()
        self._edit_lock = threading.Lock()  # structural edits take turns (see _change)
        self._queue_lock = threading.Lock()  # a leaf: the edits waiting for _edit_lock
        self._queued: list = []
        self._lock = self._lock_cm.lock
        self._control = Control(config.kp, config.kd)
        self._guard = DivergenceGuard()
        # Disable MuJoCo's whole-world auto-reset on NaN: divergence is ours to report.
        spec.option.disableflags |= _NO_AUTORESET
        if config.timestep > 0:
            spec.option.timestep = float(config.timestep)
        guard.route_mujoco_warnings()
        assets.set_mesh_cache(config.mesh_cache_mb)
        sources.warn_radian_like_ranges(spec, f'the scene {source}'.strip())
        editor.name_unnamed(spec)
        arena = ((config.arena_base_bytes, config.arena_bytes_per_body)
                 if spec.memory == -1 else None)  # the scene left it to MuJoCo's default
        # The edit phase's state, replaced whole by each structural edit (.design).
        self._design, model = Design.start(spec, arena)
        self._generation = 0
        self._step_count = 0
        self._snapshot_seq = 0
        self._batch_clock: Optional[Clock] = None  # see clock_since_batch
        self._adopt_locked(model, mujoco.MjData(model))
        self._reset_state_locked(keep_time=False)

    @classmethod
    def from_file(cls, path: str, config: WorldConfig = WorldConfig()) -> 'World':
        """Load an MJCF (or URDF) scene file."""
        sources.check_path(path, None)
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except ValueError as exc:
            raise ResourceParseError(f'cannot load the scene: {exc}') from None
        return cls(spec, config, source=str(path))

    @classmethod
    def from_string(cls, xml: str, config: WorldConfig = WorldConfig()) -> 'World':
        """Load an MJCF (or URDF) scene from text."""
        try:
            spec = mujoco.MjSpec.from_string(xml)
        except ValueError as exc:
            raise ResourceParseError(f'cannot parse scene: {exc}') from None
        return cls(spec, config, source='<string>')

    # ---------------------------------------------------------------- locking

    def _locked(self) -> WorldLock:
        """Return the world lock, counting waiters so the loop can step aside for them."""
        return self._lock_cm

    def holds_lock(self) -> bool:
        """Whether the calling thread holds the world lock (is inside :meth:`locked`)."""
        return self._lock._is_owned()

    def wait_for_callers(self, timeout: float = CALLERS_FIRST_SEC) -> None:
        """Use by the loop: let callers waiting for the lock go first."""
        self._lock_cm.wait_for_callers(timeout)

    @contextlib.contextmanager
    def locked(self) -> Iterator[tuple]:
        """
        Direct access to ``(model, data)`` under the world lock, for advanced use.

        Anything changed here is the caller's responsibility; the loop is held off meanwhile.
        """
        with self._locked():
            self._cached = None  # the caller may change anything
            try:
                yield self._model, self._data
            finally:  # even when the caller's block raised, after changing something
                self._stale_kinematics = self._stale_dynamics = True

    def read(self, read: Callable[[mujoco.MjModel, mujoco.MjData], T]) -> T:
        """
        Return what `read` returns, called with (model, data) under the world lock.

        The current model and data as they are (after a step, body poses are a step behind:
        see :meth:`_kinematics_locked`); `read` must change nothing and keep neither.
        """
        with self._locked():
            return read(self._model, self._data)

    def observe(self, read: Callable[[mujoco.MjModel, mujoco.MjData, int], T]) -> T:
        """
        Call ``read(model, data, generation)`` under the world lock with poses up to date.

        For sensors that look at the world (cameras, ray casts): body, geom, site and camera
        poses describe the current state. `read` must change nothing and be quick: the loop
        waits meanwhile.
        """
        with self._locked():
            self._kinematics_locked()
            mujoco.mj_camlight(self._model, self._data)
            return read(self._model, self._data, self._index.generation)

    # ---------------------------------------------------------------- introspection

    @property
    def generation(self) -> int:
        with self._locked():
            return self._index.generation

    @property
    def model_info(self) -> ModelInfo:
        with self._locked():
            return self._index.info

    @property
    def timestep(self) -> float:
        with self._locked():
            return float(self._model.opt.timestep)

    @property
    def time(self) -> float:
        with self._locked():
            return float(self._data.time)

    def clock(self) -> Clock:
        """Return the time, step count and timestep, read together."""
        with self._locked():
            return self._clock_locked()

    def _clock_locked(self) -> Clock:
        return Clock(float(self._data.time), self._step_count, float(self._model.opt.timestep))

    @property
    def step_count(self) -> int:
        """Step since the last time reset."""
        with self._locked():
            return self._step_count

    def entities(self) -> list:
        """Every entity (:class:`EntityRecord`), in model order."""
        with self._locked():
            return list(self._index.entities)

    def entity(self, name: str) -> EntityRecord:
        with self._locked():
            return self._index.entity(name)

    def spawned_names(self) -> list:
        """Return the entities spawned since load (the ones that can be deleted)."""
        with self._locked():
            return list(self._design.spawned)

    def joint_names(self) -> list:
        """Hinge and slide joints, the ones joint commands and joint_states cover."""
        with self._locked():
            return list(self._index.joint_names)

    def robot_description(self, name: str, mesh_dir: Optional[str] = None) -> str:
        """
        Return the URDF of an entity with joints or spawned from URDF (:mod:`.description`).

        Built outside the world lock from the current model (models are replaced, never changed
        in place, by edits). :param mesh_dir: where mesh geometry is written as STL (None: meshes
        are left out).
        """
        with self._locked():
            rec = self._index.entity(name)
            spawned = self._design.spawned.get(name)
            model, info = self._model, self._index.info
        if spawned is not None and spawned.urdf:
            return description.renamed_urdf(spawned.urdf, name)
        if not info.body_alias[rec.root_body]:
            raise InvalidArgumentError(ERR_NO_DESCRIPTION.format(name=name))
        return description.from_model(model, rec.body_ids, info.body_alias[rec.root_body],
                                      info.body_mount[rec.root_body],
                                      None if mesh_dir is None else Path(mesh_dir))

    def entity_bounds(self, name: str, local: bool = False) -> tuple:
        """
        Axis-aligned bounds of an entity's geoms: (min (3,), max (3,)).

        In the world frame, or with `local` in the entity's own (root body) frame.
        """
        with self._locked():
            rec = self._index.entity(name)
            self._kinematics_locked()
            return state.bounds(self._model, self._data, rec, local)

    # ---------------------------------------------------------------- snapshots and state

    def snapshot(self) -> Snapshot:
        """Return an immutable copy for publishers, with the model info of its generation."""
        with self._locked():
            return self._snapshot_locked()

    def _snapshot_locked(self) -> Snapshot:
        if self._stale_kinematics:
            # Body poses only: a third of _kinematics_locked's cost (1,000 bodies at 200 Hz),
            # which stays due for readers of velocities.
            mujoco.mj_kinematics(self._model, self._data)
        self._snapshot_seq += 1
        return state.snapshot(self._data, self._index, self._step_count, self._snapshot_seq)

    def get_state(self) -> PhysicsState:
        """Return the full integration state, like the older systems' ``getState``."""
        with self._locked():
            values = np.empty(self._index.state_size)
            mujoco.mj_getState(self._model, self._data, values, STATE_SPEC)
            return PhysicsState(generation=self._index.generation, step=self._step_count,
                                values=values)

    def set_state(self, physics_state: PhysicsState) -> None:
        """Overwrite the full state with one from :meth:`get_state` of the same generation."""
        with self._locked():
            if physics_state.generation != self._index.generation:
                raise IncorrectStateError(ERR_STATE_GENERATION.format(
                    got=physics_state.generation, now=self._index.generation))
            values = np.asarray(physics_state.values, dtype=float)
            if values.shape != (self._index.state_size,) or not clean(values):
                raise InvalidArgumentError(checks.ERR_NOT_FINITE.format(
                    what='state values', value=f'{values.size} values'))
            self._set_state_locked(values, physics_state.step)

    def _set_state_locked(self, values: np.ndarray, step: int) -> None:
        mujoco.mj_setState(self._model, self._data, values, STATE_SPEC)
        self._step_count = step
        self._forward_locked()

    def get_entity_state(self, name: str, reference: str = '') -> EntityState:
        """
        Pose, twist and acceleration of the entity's root body origin.

        In the world or `reference`'s frame (see :func:`state.entity_state`).
        """
        with self._locked():
            rec = self._index.entity(name)
            self._dynamics_locked()
            frame = self._frame_locked(reference) if reference else None
            return state.entity_state(self._model, self._data, rec, frame)

    def _frame_locked(self, name: str) -> tuple:
        rec = self._index.entity(name)
        self._kinematics_locked()
        return state.body_pose(self._data, rec.root_body)

    def _pose_frame_locked(self, name: str) -> tuple:
        """Return the pose of the frame a written pose is given in; unknown: an invalid pose."""
        if name not in self._index.entity_by_name:
            raise InvalidPoseError(ERR_FRAME.format(frame=name[:200]))
        return self._frame_locked(name)

    def get_joint_states(self) -> dict:
        """Name -> (position, velocity, effort) for every hinge and slide joint."""
        snap = self.snapshot()
        return {n: (float(p), float(v), float(e)) for n, p, v, e in zip(
            snap.info.joint_names, snap.joint_position, snap.joint_velocity,
            snap.joint_effort)}

    # ---------------------------------------------------------------- control

    def command(self, names: Sequence[str], values: Sequence[float], mode: str) -> None:
        """
        Stage joint commands.

        The next step applies them, and they hold until replaced or until their joint is deleted
        (see :class:`~sim_node.core.control.Control`).

        :raises NotFoundError: an unknown joint; nothing is staged.
        :raises InvalidArgumentError: a non-finite value, a length mismatch or a bad mode.
        """
        with self._locked():
            index = self._index
        self._control.stage(index, names, values, mode)

    def follow_trajectory(self, entity: str, joint_names: Sequence[str],
                          times: Sequence[float], positions: Sequence[Sequence[float]],
                          velocities: Sequence[Sequence[float]] = (),
                          accelerations: Sequence[Sequence[float]] = (),
                          start_time: float = 0.0, path_tolerance: Optional[dict] = None,
                          goal_tolerance: Optional[dict] = None,
                          goal_time_tolerance: float = 0.0) -> 'TrajectoryHandle':
        """
        Drive an entity's joints along a trajectory in simulated time (a new one preempts).

        :param times: (k,) seconds after the start of each point, increasing.
        :param positions: (k, n); `velocities` and `accelerations` empty or (k, n): the
            fields given choose linear, cubic or quintic interpolation.
        :param start_time: simulated time of the start (0: now); a trajectory that would end
            before now is refused.
        :param path_tolerance: joint -> (position, velocity, acceleration) limits on the
            error along the way; goal_tolerance likewise at the end; 0 or absent: not checked.
        :param goal_time_tolerance: how long after the end the goal tolerance may take to be
            met (0: no limit).
        :raises TrajectoryError: with FollowJointTrajectory's error code.
        """
        with self._locked():
            index, d = self._index, self._data
            known = dict(zip(index.joint_names, index.info.joint_entity))
            t, q, v, a = trajectory.check(joint_names, times, positions, velocities,
                                          accelerations, known, entity)
            now = float(d.time)
            start = now if start_time <= 0 else float(start_time)
            if start + t[-1] < now:
                raise trajectory.TrajectoryError(trajectory.OLD_HEADER_TIMESTAMP,
                                                 trajectory.ERR_OLD.format(end=start + t[-1],
                                                                           now=now))
            idx = index.joints(joint_names)
            names = tuple(joint_names)
            traj = trajectory.Trajectory(
                joints=names, start=start, times=t, positions=q, velocities=v,
                accelerations=a, start_positions=d.qpos[index.joint_qposadr[idx]].copy(),
                start_velocities=(d.qvel[index.joint_dofadr[idx]].copy() if v is not None
                                  else np.zeros(len(names))),
                path_tolerance=_tolerance(names, path_tolerance),
                goal_tolerance=_tolerance(names, goal_tolerance),
                goal_time_tolerance=max(0.0, float(goal_time_tolerance)))
            tracker = trajectory.Tracker(traj)
            self._control.start_run(entity, tracker, index, self._model, d)
            self._cached = None
            return TrajectoryHandle(self, entity, self._control.run_of(entity))

    def _cancel_trajectory(self, handle: 'TrajectoryHandle') -> None:
        with self._locked():
            self._control.cancel_run(handle.entity, handle.run, self._data, self._index,
                                     self._model)
            self._cached = None

    def set_gains(self, kp: float, kd: float) -> None:
        """PD gains for joints commanded without a matching actuator."""
        with self._locked():
            self._control.set_gains(kp, kd, self._index, self._model, self._data)
            self._cached = None

    # ---------------------------------------------------------------- stepping

    def step(self, n: int = 1, ctrl: Optional[np.ndarray] = None,
             then: Optional[Callable[[mujoco.MjModel, mujoco.MjData], None]] = None) -> int:
        """
        Advance `n` steps (applying staged commands first); returns the step count.

        :param ctrl: (nu,) actuator controls to set first, for callers that own the world
            (the Gym environment); the caller checks them (finite, within +-1e10).
        :param then: called as ``then(model, data)`` after the steps, under the same hold of
            the world lock (a vector env copies what its task reads); it must change nothing.
        :raises DivergenceError: the physics diverged; the world is back at the state before
            the bad step and ``error.step`` names it.
        """
        if n < 1:
            raise InvalidArgumentError(ERR_STEPS.format(n=n))
        # Once per Gym step and per loop batch: take a free lock directly. It is WorldLock's
        # own fast path without the context-manager calls, 0.25 us a step (1% of a
        # Reacher-v5 step); a contended lock goes through WorldLock as usual.
        if self._lock.acquire(blocking=False):
            try:
                return self._step_locked(int(n), ctrl, then)
            finally:
                self._lock.release()
        with self._lock_cm:
            return self._step_locked(int(n), ctrl, then)

    def step_batch(self, n: int, snapshot: bool) -> Optional[Snapshot]:
        """
        For the loop: `n` steps, then the clock and, if asked, a snapshot, in one hold.

        One acquisition of the world lock per batch instead of three (clock, step, snapshot):
        under a storm of edits each acquisition can wait behind other callers, and the waits
        added up to stalls of 60-110 ms (``make bench-storm``). The clock after the steps is
        kept for :meth:`clock_since_batch`. Returns the snapshot, or None; raises as
        :meth:`step` does.
        """
        with self._lock_cm:
            self._step_locked(int(n), None, None, quiet=True)
            self._batch_clock = self._clock_locked()
            return self._snapshot_locked() if snapshot else None

    def clock_since_batch(self) -> Optional[Clock]:
        """
        Return the clock :meth:`step_batch` gave, if nothing changed the world since; else None.

        Without the lock: every write of the state (resets, set_state, ``locked()``, a new
        model) clears ``_cached`` under the lock before it changes time, step count or timestep,
        and only the loop, which asks, steps. A read racing a write is one from just before it,
        as a locked read made a moment earlier would be.
        """
        return self._batch_clock if self._cached is not None else None

    def _step_locked(self, n: int, ctrl: Optional[np.ndarray],
                     then: Optional[Callable[[mujoco.MjModel, mujoco.MjData], None]],
                     quiet: bool = False) -> int:
        """
        Step under the lock; see :meth:`step`.

        :param quiet: make no MuJoCo call but the steps themselves on a clean batch (the loop:
            each call gives the GIL away, and other threads kept it for up to 5 ms each time
            under a storm of edits, with the world lock held meanwhile). Same results.
        """
        # The state after the last clean batch, if untouched since: it holds the previous
        # controls, so a replay writes `ctrl` again.
        before = self._cached
        self._batch_clock = None  # set again by step_batch, the loop's way to step
        if ctrl is not None:
            self._ctrl[:] = ctrl
        m, d, control = self._model, self._data, self._control
        if control.has_staged:
            control.apply_staged(self._index, m, d)
            before = None
        if before is None:
            before = np.empty(self._index.state_size)
            mujoco.mj_getState(m, d, before, STATE_SPEC)
            ctrl = None  # already in `before`
        if control.per_step:
            for _ in range(n):
                control.apply(m, d)
                mujoco.mj_step(m, d)
        else:
            mujoco.mj_step(m, d, n)
        if self._guard.diverged(m, d, quiet):
            self._diverged_locked(before, n, ctrl)
        self._step_count += n
        # The state after a clean batch: the next batch's starting point (unless something
        # changes it), and the fallback for divergence caused by values put in between steps
        # (e.g. through locked()). One buffer, overwritten in place: `before` is spent by now.
        if quiet and self._copy_state is not None:
            self._copy_state(self._good_buf)
        else:
            mujoco.mj_getState(m, d, self._good_buf, STATE_SPEC)
        self._last_good = self._cached = self._good_buf
        self._stale_kinematics = self._stale_dynamics = True
        if then is not None:
            then(m, d)
        return self._step_count

    def _diverged_locked(self, before: np.ndarray, n: int, ctrl: Optional[np.ndarray]) -> None:
        m, d, control = self._model, self._data, self._control
        k, good, report = self._guard.locate(
            m, d, before, n, ctrl, (lambda: control.apply(m, d)) if control.per_step else None)
        bad_step = self._step_count + k + 1
        report['step'] = bad_step
        self._step_count += k
        if not clean(good):
            # The bad values were put in between steps (e.g. through locked()): go back to
            # the state after the last clean batch.
            good = self._last_good if self._last_good is not None else good
        self._set_state_locked(good, self._step_count)
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
        m, idx = self._model, self._index
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

    def step_kinematic(self, positions: dict, n: int = 1) -> int:
        """
        Advance `n` steps with no physics (see :func:`state.kinematic_step`).

        The named hinge/slide joints take `positions` exactly at every step; returns the step
        count.
        """
        if n < 1:
            raise InvalidArgumentError(ERR_STEPS.format(n=n))
        with self._locked():
            i = self._index.joints(positions.keys())
            targets = check_finite('joint positions', list(positions.values()))
            qadr, dadr = self._index.joint_qposadr[i], self._index.joint_dofadr[i]
            for _ in range(n):
                state.kinematic_step(self._model, self._data, qadr, dadr, targets)
            self._step_count += n
            self._cached = None
            self._stale_kinematics, self._stale_dynamics = False, True
            return self._step_count

    def _kinematics_locked(self) -> None:
        """
        Bring body poses and velocities up to the current state before reading them.

        mj_step computes them before integrating, so afterwards they describe the state one
        step earlier than qpos, qvel and time (MuJoCo's convention, kept for the Gym
        environment's observations as in Gymnasium). Recomputing them changes no state.
        """
        if self._stale_kinematics:
            m, d = self._model, self._data
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            mujoco.mj_comVel(m, d)
            self._stale_kinematics = False

    def _dynamics_locked(self) -> None:
        """
        Bring accelerations up to date too, as :meth:`_kinematics_locked` does poses.

        mj_forward, then the body accelerations mj_objectAcceleration reads. Changes no state
        either.
        """
        m, d = self._model, self._data
        if self._stale_dynamics:
            mujoco.mj_forward(m, d)
            self._stale_kinematics = self._stale_dynamics = False
        mujoco.mj_rnePostConstraint(m, d)

    def _forward_locked(self) -> None:
        """After writing state: derived quantities now, warnings taken as seen."""
        self._cached = None
        mujoco.mj_forward(self._model, self._data)
        self._stale_kinematics = self._stale_dynamics = False
        self._guard.note()

    # ---------------------------------------------------------------- reset

    def reset(self, scope: int = RESET_ALL) -> None:
        """
        Reset by scope bits.

        RESET_TIME (time and step count to 0), RESET_STATE (the `home` keyframe or the initial
        state; held commands are dropped), RESET_SPAWNED (delete everything spawned since load). 0
        and RESET_ALL do all three.
        """
        if scope != RESET_ALL and not 0 <= scope <= _SCOPE_BITS:
            raise FeatureUnsupportedError(ERR_SCOPE.format(scope=scope))
        scope = _SCOPE_BITS if scope in (0, RESET_ALL) else scope
        if scope & RESET_SPAWNED:
            with self._locked():
                anything = bool(self._design.spawned)
            if anything:  # built outside the lock like every removal; the state below
                self._change(lambda: self._plan_removal_locked(list(self._design.spawned)))
        with self._locked():
            if scope & RESET_STATE:
                self._reset_state_locked(keep_time=not scope & RESET_TIME)
            elif scope & RESET_TIME:
                self._data.time = 0.0
                self._step_count = 0
                self._cached = None

    def _reset_state_locked(self, keep_time: bool) -> None:
        m, d = self._model, self._data
        t, steps = d.time, self._step_count
        self._control.clear(self._index, m, d)
        key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, 'home')
        if key >= 0:
            mujoco.mj_resetDataKeyframe(m, d, key)
        else:
            mujoco.mj_resetData(m, d)
        if keep_time:
            d.time, self._step_count = t, steps
        else:
            self._step_count = 0
        self._forward_locked()

    def _adopt_locked(self, model: mujoco.MjModel, data: mujoco.MjData,
                      index: Optional[ModelIndex] = None) -> None:
        """
        Switch everything to a new model and data together (index, control, guard).

        :param index: the model's index if it was built beforehand (outside the lock) for
            this generation and spawned table.
        """
        self._model, self._data = model, data
        if index is None or index.generation != self._generation:
            index = model_index.build(model, self._generation, self._design.spawned)
        self._index: ModelIndex = index
        self._ctrl = data.ctrl
        self._good_buf = np.empty(self._index.state_size)
        self._copy_state = state.state_copier(model, data, STATE_SPEC)
        self._last_good = None  # its layout belongs to the old model
        self._control.bind(self._index, model, data, new_model=True)
        # Derived quantities (xpos, contacts) are zero until mj_forward runs.
        self._guard.bind(data)
        self._forward_locked()


def _tolerance(names: tuple, given: Optional[dict]) -> trajectory.Tolerance:
    """(n,) limits per joint from joint -> (position, velocity, acceleration); 0: unchecked."""
    tol = trajectory.Tolerance.none(len(names))
    for i, name in enumerate(names):
        p, v, a = (given or {}).get(name, (0.0, 0.0, 0.0))
        tol.position[i], tol.velocity[i], tol.acceleration[i] = (max(0.0, float(x))
                                                                 for x in (p, v, a))
    return tol


class TrajectoryHandle:
    """A trajectory a world follows: wait for it, read how it goes, cancel it."""

    def __init__(self, world: World, entity: str, run):
        self.world, self.entity, self.run = world, entity, run

    @property
    def status(self) -> trajectory.Status:
        """Return the latest judgement: desired and actual, and the outcome once decided."""
        return self.run.tracker.status

    @property
    def trajectory(self) -> trajectory.Trajectory:
        return self.run.tracker.trajectory

    def wait(self, timeout: Optional[float] = None) -> bool:
        """Block until the trajectory has ended (True) or `timeout` wall seconds passed."""
        return self.run.done.wait(timeout)

    @property
    def done(self) -> bool:
        return self.run.done.is_set()

    def cancel(self) -> None:
        """End it now; the joints hold where they are (nothing if it has ended already)."""
        self.world._cancel_trajectory(self)
