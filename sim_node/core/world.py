"""The MuJoCo world: one MjSpec/MjModel/MjData, its entities, and every change to them.

The world keeps the lock, the model generation and the recompile, and its public methods lock,
validate and delegate: addresses to :mod:`.index`, joint commands to :mod:`.control`, the
divergence check to :mod:`.guard`, spec edits to :mod:`.editor`, state reads and writes to
:mod:`.state`. The threading contract is in the package docstring (``sim_node.core``).
"""

import contextlib
import logging
import threading
from typing import Callable, Iterator, Optional, Sequence

import mujoco
import numpy as np

from . import checks, editor, index as model_index, quat, sources, state
from .checks import check_finite, check_pose
from .config import WorldConfig
from .control import Control
from .errors import (DivergenceError, IncorrectStateError, InvalidArgumentError,
                     InvalidPoseError, NameNotUniqueError, ResourceParseError)
from .guard import DivergenceGuard, clean
from .index import STATE_SPEC, ModelIndex
from .types import (RESET_ALL, RESET_SPAWNED, RESET_STATE, RESET_TIME, ROBOT, STATIC,
                    EntityRecord, EntityState, ModelInfo, PhysicsState, Snapshot)

log = logging.getLogger(__name__)

ERR_DUPLICATE = 'an entity or body named {name!r} exists; pick another name or allow renaming'
ERR_STATIC_TWIST = ('{name!r} is a {category} entity welded to the world: it cannot have a '
                    'velocity (only its pose can be set)')
ERR_STATE_GENERATION = ('this state was taken from model generation {got}, the world is now at '
                        'generation {now} (an entity was spawned or deleted since)')
ERR_INTERPENETRATION = ('at this pose {name!r} would overlap {other!r} by {depth:.4f} m; move '
                        'it, or allow interpenetration')
ERR_NOT_SPAWNED = '{name!r} is part of the loaded scene; only spawned entities can be deleted'
ERR_COMPILE = 'the model does not compile: {err}'
ERR_SCOPE = ('reset scope {scope} has undefined bits: use 0 (all), 255 (all) or a combination '
             'of 1 (time), 2 (state) and 4 (spawned)')
ERR_STEPS = 'steps must be >= 1, got {n}'
ERR_ROBOT_WELD = '{name!r} is a robot: give it a positive mass'
ERR_NO_MASS = '{name!r} has no mass to scale'

_SCOPE_BITS = RESET_TIME | RESET_STATE | RESET_SPAWNED
_NO_AUTORESET = int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
_MUJOCO_LOG = logging.getLogger('sim_node.mujoco')


def _log_mujoco_warning(message: str) -> None:
    _MUJOCO_LOG.warning('MuJoCo: %s', message)


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warning text to logging (the node forwards it to the ROS log) instead
    of stderr and a MUJOCO_LOG.TXT in the working directory; unless the application has
    installed a handler of its own (the handler is process-wide)."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_log_mujoco_warning)


class World:
    """A MuJoCo world that can change while it runs. Thread-safe; see ``sim_node.core``.

    Build with :meth:`from_file` or :meth:`from_string`.
    """

    def __init__(self, spec: mujoco.MjSpec, config: WorldConfig = WorldConfig(),
                 source: str = ''):
        self.config = config
        self.source = source
        self._lock = threading.RLock()
        # Callers waiting for the lock; the loop steps aside for them (a Lock is not fair).
        self._waiting = 0
        self._waiting_cv = threading.Condition(threading.Lock())
        self._loop_waiting = False
        self._lock_cm = _WorldLock(self)
        self._control = Control(config.kp, config.kd)
        self._guard = DivergenceGuard()
        # Disable MuJoCo's whole-world auto-reset on NaN: divergence is ours to report.
        spec.option.disableflags |= _NO_AUTORESET
        if config.timestep > 0:
            spec.option.timestep = float(config.timestep)
        route_mujoco_warnings()
        sources.warn_radian_like_ranges(spec, f'the scene {source}'.strip())
        editor.name_unnamed(spec)
        try:
            model = spec.compile()
        except ValueError as exc:
            raise ResourceParseError(f'the scene does not compile: {exc}') from None
        self._spec = spec
        self._spawned: dict = {}  # name -> {'frame': name, 'assets': tuple, 'description'}
        self._overrides: dict = {}  # entity -> {'friction': (3,), 'restitution': float}
        self._default_friction: Optional[np.ndarray] = None
        self._default_restitution: Optional[float] = None
        self._generation = 0
        self._step_count = 0
        self._snapshot_seq = 0
        self._adopt_locked(model, mujoco.MjData(model))
        self._reset_state_locked(keep_time=False)

    @classmethod
    def from_file(cls, path: str, config: WorldConfig = WorldConfig()) -> 'World':
        """Load an MJCF (or URDF) scene file."""
        sources.check_path(path, None)
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except ValueError as exc:
            raise ResourceParseError(f'cannot load scene {path}: {exc}') from None
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

    def _locked(self) -> '_WorldLock':
        """The world lock, counting waiters so the loop can step aside for them."""
        return self._lock_cm

    def wait_for_callers(self, timeout: float = 0.05) -> None:
        """Used by the loop: let callers waiting for the lock go first."""
        with self._waiting_cv:
            if self._waiting:
                self._loop_waiting = True
                self._waiting_cv.wait_for(lambda: self._waiting == 0, timeout)
                self._loop_waiting = False

    @contextlib.contextmanager
    def locked(self) -> Iterator[tuple]:
        """Direct access to ``(model, data)`` under the world lock, for advanced use.

        Anything changed here is the caller's responsibility; the loop is held off meanwhile.
        """
        with self._locked():
            self._cached = None  # the caller may change anything
            yield self._model, self._data
            self._stale_kinematics = self._stale_dynamics = True

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

    @property
    def step_count(self) -> int:
        """Steps since the last time reset."""
        with self._locked():
            return self._step_count

    def entities(self) -> list:
        """Every entity (:class:`EntityRecord`), in model order."""
        with self._locked():
            return list(self._index.entities)

    def entity(self, name: str) -> EntityRecord:
        with self._locked():
            return self._index.entity(name)

    def joint_names(self) -> list:
        """Hinge and slide joints, the ones joint commands and joint_states cover."""
        with self._locked():
            return list(self._index.joint_names)

    def entity_bounds(self, name: str) -> tuple:
        """Axis-aligned bounds of an entity's geoms in the world frame: (min (3,), max (3,))."""
        with self._locked():
            rec = self._index.entity(name)
            self._kinematics_locked()
            return state.bounds(self._model, self._data, rec)

    # ---------------------------------------------------------------- snapshots and state

    def snapshot(self) -> Snapshot:
        """An immutable copy for publishers, with the model info of its generation."""
        with self._locked():
            self._kinematics_locked()
            self._snapshot_seq += 1
            return state.snapshot(self._data, self._index, self._step_count,
                                  self._snapshot_seq)

    def get_state(self) -> PhysicsState:
        """The full integration state, like the older systems' ``getState``."""
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
        """Pose, twist and acceleration of the entity's root body origin, in the world or
        `reference`'s frame (see :func:`state.entity_state`)."""
        with self._locked():
            rec = self._index.entity(name)
            self._dynamics_locked()
            frame = self._frame_locked(reference) if reference else None
            return state.entity_state(self._model, self._data, rec, frame)

    def _frame_locked(self, name: str) -> tuple:
        rec = self._index.entity(name)
        self._kinematics_locked()
        return state.body_pose(self._data, rec.root_body)

    def set_entity_state(self, name: str, position: Optional[Sequence[float]] = None,
                         quat_wxyz: Optional[Sequence[float]] = None,
                         linear_velocity: Optional[Sequence[float]] = None,
                         angular_velocity: Optional[Sequence[float]] = None,
                         reference: str = '') -> None:
        """Set the pose and/or twist of an entity's root body (world frame or `reference`).

        A free body is moved through its free joint. A welded entity (static object or
        fixed-base robot) can be moved (its model is rebuilt, keeping all state) but its
        twist must be zero.
        """
        with self._locked():
            self._overwrite_locked({name: (position, quat_wxyz)},
                                  {name: (linear_velocity, angular_velocity)}, {}, {},
                                  reference)

    def overwrite(self, poses: Optional[dict] = None, twists: Optional[dict] = None,
                  joint_positions: Optional[dict] = None,
                  joint_velocities: Optional[dict] = None) -> None:
        """Overwrite any parts of the state at once, in the world frame: ``poses``
        {entity: (position, quat_wxyz)}, ``twists`` {entity: (linear, angular)}, and
        {joint: value} for hinge/slide joint positions and velocities.

        Everything is checked before anything changes, so an error changes nothing. An
        entity without a free joint given its current pose stays put (no rebuild); given
        another pose it is moved (model rebuilt, state kept), and a non-zero twist for it is
        refused.
        """
        with self._locked():
            self._overwrite_locked(poses or {}, twists or {}, joint_positions or {},
                                  joint_velocities or {}, '')

    def _overwrite_locked(self, poses: dict, twists: dict, joint_positions: dict,
                         joint_velocities: dict, reference: str) -> None:
        idx, d = self._index, self._data
        self._kinematics_locked()
        frame = self._frame_locked(reference) if reference else None
        targets = {}  # entity -> (record, pos, quat, lin, ang), checked, in the world frame
        for n in (*poses, *twists):
            rec = idx.entity(n)
            targets[n] = (rec, *self._check_target_locked(
                rec, *poses.get(n, (None, None)), *twists.get(n, (None, None)), frame))
        q_adr, q_values = self._joint_targets_locked('position', joint_positions, True)
        v_adr, v_values = self._joint_targets_locked('velocity', joint_velocities, False)
        welded_moves = []
        for rec, pos, q, lin, ang in targets.values():
            if rec.has_free_joint:
                continue
            if any(v is not None and np.any(v != 0) for v in (lin, ang)):
                raise IncorrectStateError(ERR_STATIC_TWIST.format(name=rec.name,
                                                                  category=rec.category))
            root = rec.root_body
            if pos is not None and not (
                    np.allclose(pos, d.xpos[root], rtol=0, atol=1e-9)
                    and abs(abs(float(np.dot(q, d.xquat[root]))) - 1.0) < 1e-12):
                welded_moves.append((rec, pos, q))
        if welded_moves:  # all moves in one rebuild, before the direct writes
            self._edit_locked(lambda spec: [editor.place_root(
                spec, rec.name, self._frame_of(spec, rec.name), pos, q)
                for rec, pos, q in welded_moves])
        for rec, pos, q, lin, ang in targets.values():
            if rec.has_free_joint:
                state.write_free_body(self._model, self._data, rec, pos, q, lin, ang)
        self._data.qpos[q_adr] = q_values
        self._data.qvel[v_adr] = v_values
        self._forward_locked()

    def _check_target_locked(self, rec: EntityRecord, position, quat_wxyz, linear, angular,
                             frame: Optional[tuple]) -> tuple:
        """Checked world-frame (pos, quat, lin, ang), None where not given; a pose given by
        one half keeps the current other half."""
        pos = q = lin = ang = None
        if position is not None or quat_wxyz is not None:
            cur_pos, cur_q = state.body_pose(self._data, rec.root_body)
            if frame is not None:
                cur_pos, cur_q = quat.to_frame(*frame, cur_pos, cur_q)
            pos, q = check_pose(cur_pos if position is None else position,
                                cur_q if quat_wxyz is None else quat_wxyz)
            if frame is not None:
                pos, q = quat.from_frame(*frame, pos, q)
        if linear is not None:
            lin = check_finite('linear velocity', linear, 3)
        if angular is not None:
            ang = check_finite('angular velocity', angular, 3)
        if frame is not None:
            lin = None if lin is None else quat.rotate(frame[1], lin)
            ang = None if ang is None else quat.rotate(frame[1], ang)
        return pos, q, lin, ang

    def set_joint_positions(self, positions: dict) -> None:
        """Set hinge/slide joint positions by name (velocities are kept)."""
        with self._locked():
            self._overwrite_locked({}, {}, positions, {}, '')

    def set_joint_velocities(self, velocities: dict) -> None:
        with self._locked():
            self._overwrite_locked({}, {}, {}, velocities, '')

    def _joint_targets_locked(self, what: str, values: dict, use_qpos: bool) -> tuple:
        """Checked (qpos or qvel addresses, values) for {joint: value}."""
        i = self._index.joints(values.keys())
        vals = check_finite(f'joint {what}s', list(values.values()))
        return (self._index.joint_qposadr if use_qpos else self._index.joint_dofadr)[i], vals

    def get_joint_states(self) -> dict:
        """name -> (position, velocity, effort) for every hinge and slide joint."""
        snap = self.snapshot()
        return {n: (float(p), float(v), float(e)) for n, p, v, e in zip(
            snap.info.joint_names, snap.joint_position, snap.joint_velocity,
            snap.joint_effort)}

    # ---------------------------------------------------------------- control

    def command(self, names: Sequence[str], values: Sequence[float], mode: str) -> None:
        """Stage joint commands; the next step applies them, and they hold until replaced or
        until their joint is deleted (see :class:`~sim_node.core.control.Control`).

        :raises NotFoundError: an unknown joint; nothing is staged.
        :raises InvalidArgumentError: a non-finite value, a length mismatch or a bad mode.
        """
        with self._locked():
            index = self._index
        self._control.stage(index, names, values, mode)

    def set_gains(self, kp: float, kd: float) -> None:
        """PD gains for joints commanded without a matching actuator."""
        with self._locked():
            self._control.set_gains(kp, kd, self._index, self._model, self._data)
            self._cached = None

    # ---------------------------------------------------------------- stepping

    def step(self, n: int = 1, ctrl: Optional[np.ndarray] = None) -> int:
        """Advance `n` steps (applying staged commands first); returns the step count.

        :param ctrl: (nu,) actuator controls to set first, for callers that own the world
            (the Gym environment); the caller checks them (finite, within +-1e10).
        :raises DivergenceError: the physics diverged; the world is back at the state before
            the bad step and ``error.step`` names it.
        """
        if n < 1:
            raise InvalidArgumentError(ERR_STEPS.format(n=n))
        # Once per Gym step and per loop batch: take a free lock directly. It is _WorldLock's
        # own fast path without the context-manager calls, 0.25 us a step (1% of a
        # Reacher-v5 step); a contended lock goes through _WorldLock as usual.
        if self._lock.acquire(blocking=False):
            try:
                return self._step_locked(int(n), ctrl)
            finally:
                self._lock.release()
        with self._lock_cm:
            return self._step_locked(int(n), ctrl)

    def _step_locked(self, n: int, ctrl: Optional[np.ndarray]) -> int:
        # The state after the last clean batch, if untouched since: it holds the previous
        # controls, so a replay writes `ctrl` again.
        before = self._cached
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
        if self._guard.diverged(m, d):
            self._diverged_locked(before, n, ctrl)
        self._step_count += n
        # The state after a clean batch: the next batch's starting point (unless something
        # changes it), and the fallback for divergence caused by values put in between steps
        # (e.g. through locked()). One buffer, overwritten in place: `before` is spent by now.
        mujoco.mj_getState(m, d, self._good_buf, STATE_SPEC)
        self._last_good = self._cached = self._good_buf
        self._stale_kinematics = self._stale_dynamics = True
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
        raise DivergenceError(f'physics diverged at step {bad_step} (t={report["time"]:.4f} s): '
                              f'{report["warnings"] or "non-finite state"}; restored the state '
                              'before it', bad_step, report)

    def step_kinematic(self, positions: dict, n: int = 1) -> int:
        """Advance `n` steps with no physics (see :func:`state.kinematic_step`): the named
        hinge/slide joints take `positions` exactly at every step; returns the step count."""
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
        """Bring body poses and velocities up to the current state before reading them.

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
        """As :meth:`_kinematics_locked`, and accelerations too (mj_forward, then the body
        accelerations mj_objectAcceleration reads). Changes no state either."""
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
        """Reset by scope bits: RESET_TIME (time and step count to 0), RESET_STATE (the
        `home` keyframe or the initial state; held commands are dropped), RESET_SPAWNED
        (delete everything spawned since load). 0 and RESET_ALL do all three."""
        if scope != RESET_ALL and not 0 <= scope <= _SCOPE_BITS:
            raise InvalidArgumentError(ERR_SCOPE.format(scope=scope))
        scope = _SCOPE_BITS if scope in (0, RESET_ALL) else scope
        with self._locked():
            if scope & RESET_SPAWNED and self._spawned:
                doomed = dict(self._spawned)
                self._edit_locked(lambda spec: [editor.remove(
                    spec, n, spec.frame(meta['frame']), meta['assets'])
                    for n, meta in doomed.items()], spawned={}, overrides={
                    k: v for k, v in self._overrides.items() if k not in doomed})
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

    # ---------------------------------------------------------------- model edits

    def _edit_locked(self, edit: Callable[[mujoco.MjSpec], object],
                     check: Optional[Callable[[mujoco.MjModel, mujoco.MjData], None]] = None,
                     spawned: Optional[dict] = None, overrides: Optional[dict] = None) -> None:
        """Apply `edit` to a copy of the spec and recompile it with the live state; only if
        that compiles (and `check` passes) does the copy become the world. A failed compile
        or check leaves the world, its spec and its generation exactly as they were.

        :param spawned: the spawned-entity table that goes with the edited spec.
        :param overrides: likewise, per-entity contact settings.
        """
        trial = self._spec.copy()
        edit(trial)
        try:
            model, data = trial.recompile(self._model, self._data)
        except ValueError as exc:
            raise ResourceParseError(ERR_COMPILE.format(err=exc)) from None
        if check is not None:
            check(model, data)
        self._spec = trial
        if spawned is not None:
            self._spawned = spawned
        if overrides is not None:
            self._overrides = overrides
        self._generation += 1
        self._adopt_locked(model, data)

    def _adopt_locked(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Switch everything to a new model and data together (index, control, guard)."""
        self._model, self._data = model, data
        self._index: ModelIndex = model_index.build(model, self._generation, self._spawned)
        self._ctrl = data.ctrl
        self._good_buf = np.empty(self._index.state_size)
        self._last_good = None  # its layout belongs to the old model
        self._control.bind(self._index, model, data, new_model=True)
        # Derived quantities (xpos, contacts) are zero until mj_forward runs.
        self._guard.bind(data)
        self._forward_locked()

    def _frame_of(self, spec: mujoco.MjSpec, name: str):
        meta = self._spawned.get(name)
        return spec.frame(meta['frame']) if meta else None

    def unique_name(self, base: str) -> str:
        """`base`, or `base_<n>` with the smallest n not taken by an entity or body."""
        with self._locked():
            return self._unique_name_locked(base)

    def _unique_name_locked(self, base: str) -> str:
        taken = self._index.body_ids
        base = base if checks.NAME_RE.match(base or '') else 'entity'
        name, i = base, 0
        while name in taken:
            i += 1
            name = f'{base}_{i}'
        return name

    def spawn(self, name: str, source: sources.SpawnSource,
              position: Sequence[float] = (0.0, 0.0, 0.0),
              quat_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0), reference: str = '',
              allow_renaming: bool = False, namespace: str = '',
              allow_interpenetration: Optional[bool] = None) -> str:
        """Add an entity at a pose (world frame, or `reference` entity's frame) while running.

        Its root body is named `name`; every other element ``name/<original>`` (unnamed ones
        get ``name/<kind>_<i>``). All or nothing: on any error the world is exactly as
        before. The namespace is checked but not used: the node's topics are per world.

        :returns: the entity's name (differs from `name` only when renaming was allowed).
        """
        pos, q = check_pose(position, quat_wxyz)
        checks.check_namespace(namespace)
        if not allow_renaming:
            checks.check_name(name)
        overlap_ok = (self.config.allow_interpenetration if allow_interpenetration is None
                      else allow_interpenetration)
        with self._locked():
            if not name or name in self._index.body_ids:
                if not allow_renaming:
                    raise NameNotUniqueError(ERR_DUPLICATE.format(name=name))
                name = self._unique_name_locked(name or source.kind)
            if reference:
                pos, q = quat.from_frame(*self._frame_locked(reference), pos, q)
            meta = {'frame': f'{name}/__spawn_frame', 'assets': tuple(source.assets),
                    'description': source.description}

            def edit(spec: mujoco.MjSpec) -> None:
                frame, _ = editor.attach(spec, name, source, pos, q)
                frame.name = meta['frame']
                if self._default_friction is not None or self._default_restitution is not None:
                    geoms = [g.name for g in spec.body(name).find_all(mujoco.mjtObj.mjOBJ_GEOM)]
                    editor.apply_contact(spec, geoms, *self._contact_of({}))

            def check(model: mujoco.MjModel, data: mujoco.MjData) -> None:
                hit = editor.find_overlap(model, data, name,
                                          self.config.interpenetration_tolerance)
                if hit is not None:
                    raise InvalidPoseError(ERR_INTERPENETRATION.format(
                        name=name, other=hit[0], depth=hit[1]))

            self._edit_locked(edit, None if overlap_ok else check,
                              spawned={**self._spawned, name: meta})
            return name

    def add_body(self, name: str, parent: str, shape: str, size: Sequence[float],
                 position: Sequence[float] = (0.0, 0.0, 0.0),
                 quat_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0), mass: float = 0.0,
                 joint: Optional[str] = None, axis: Sequence[float] = (0.0, 0.0, 1.0),
                 rgba: Sequence[float] = (0.7, 0.7, 0.7, 1.0)) -> str:
        """Add a body with one geom under an existing body of a spawned entity, while running.

        :param parent: name of the parent body (an entity or one of its bodies).
        :param position: in the parent's frame.
        :param joint: None (welded: the body becomes part of its parent), 'hinge' or 'slide'
            about/along `axis` (in the body frame).
        :param mass: kg; 0 uses the geom's default density.
        """
        pos, q = check_pose(position, quat_wxyz)
        ax = check_finite('axis', axis, 3)
        checks.check_name(name)
        if joint not in (None, 'hinge', 'slide'):
            raise InvalidArgumentError(f"joint must be None, 'hinge' or 'slide', got {joint!r}")
        full_size = sources.primitive_size(shape, size)
        colour = sources.check_rgba(rgba)
        sources.check_mass(mass)
        with self._locked():
            root = self._index.entity_of_body(parent)
            if root not in self._spawned:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=root))
            full = f'{root}/{name}'
            if full in self._index.body_ids:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=full))
            self._edit_locked(lambda spec: editor.add_child(
                spec, parent, full, shape, full_size, pos, q, mass, joint, ax, colour))
            return full

    def delete(self, name: str) -> None:
        """Remove a spawned entity with its joints, geoms, actuators, sensors, equality
        constraints, contact pairs, excludes and joint commands; everything else keeps its
        state exactly."""
        with self._locked():
            self._index.entity(name)
            meta = self._spawned.get(name)
            if meta is None:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=name))
            self._edit_locked(
                lambda spec: editor.remove(spec, name, spec.frame(meta['frame']),
                                           meta['assets']),
                spawned={k: v for k, v in self._spawned.items() if k != name},
                overrides={k: v for k, v in self._overrides.items() if k != name})

    # ---------------------------------------------------------------- physics parameters

    def set_gravity(self, gravity: Sequence[float]) -> None:
        g = check_finite('gravity', gravity, 3)
        with self._locked():
            self._edit_locked(lambda spec: setattr(spec.option, 'gravity', g.tolist()))

    def set_timestep(self, timestep: float) -> None:
        (dt,) = check_finite('timestep', [timestep], 1)
        if not 0 < dt <= 0.1:
            raise InvalidArgumentError(f'timestep must be in (0, 0.1] s, got {timestep}')
        with self._locked():
            self._edit_locked(lambda spec: setattr(spec.option, 'timestep', float(dt)))

    def set_friction(self, name: str, sliding: float, torsional: Optional[float] = None,
                     rolling: Optional[float] = None) -> None:
        """Friction of every geom of an entity (MuJoCo's three coefficients); it wins over
        surfaces without friction of their own (see :func:`editor.apply_contact`)."""
        with self._locked():
            rec = self._index.entity(name)
            cur = (self._model.geom_friction[rec.geom_ids[0]] if rec.geom_ids
                   else np.array([1.0, 0.005, 0.0001]))
            f = check_finite('friction', [sliding, cur[1] if torsional is None else torsional,
                                          cur[2] if rolling is None else rolling], 3)
            if np.any(f < 0):
                raise InvalidArgumentError(f'friction must be >= 0, got {f.tolist()}')
            self._set_override_locked(name, 'friction', f)

    def set_restitution(self, name: str, restitution: float) -> None:
        """Bounciness in [0, 0.8] of an entity's geoms: a bounce off any surface without a
        restitution of its own has that coefficient (see :func:`editor.apply_contact`)."""
        e = self._check_restitution(restitution)
        with self._locked():
            self._index.entity(name)
            self._set_override_locked(name, 'restitution', e)

    def _set_override_locked(self, name: str, key: str, value) -> None:
        own = {**self._overrides.get(name, {}), key: value}
        geoms = [self._index.geom_names[g] for g in self._index.entity(name).geom_ids]
        self._edit_locked(lambda spec: editor.apply_contact(
            spec, geoms, *self._contact_of(own)), overrides={**self._overrides, name: own})

    def _contact_of(self, own: dict) -> tuple:
        """(friction, restitution, priority) for geoms with settings `own` (maybe none)."""
        return (own.get('friction', self._default_friction),
                own.get('restitution', self._default_restitution),
                editor.OWN_CONTACT_PRIORITY if own else 0)

    def set_default_contact(self, friction: Optional[Sequence[float]] = None,
                            restitution: Optional[float] = None) -> None:
        """Global friction (3 values) and/or restitution for every geom without its own."""
        f = None if friction is None else check_finite('friction', friction, 3)
        e = None if restitution is None else self._check_restitution(restitution)
        with self._locked():
            old = self._default_friction, self._default_restitution
            self._default_friction = old[0] if f is None else f
            self._default_restitution = old[1] if e is None else e
            idx = self._index
            groups = [([idx.geom_names[g] for g in r.geom_ids], self._overrides.get(r.name, {}))
                      for r in idx.entities]
            groups.append(([n for g, n in enumerate(idx.geom_names)
                            if self._model.geom_bodyid[g] == 0], {}))
            try:
                self._edit_locked(lambda spec: [editor.apply_contact(
                    spec, geoms, *self._contact_of(own)) for geoms, own in groups])
            except Exception:
                self._default_friction, self._default_restitution = old
                raise

    @staticmethod
    def _check_restitution(restitution: float) -> float:
        (e,) = check_finite('restitution', [restitution], 1)
        if not 0.0 <= e <= editor.MAX_RESTITUTION:
            raise InvalidArgumentError(
                f'restitution must be in [0, {editor.MAX_RESTITUTION}], got {restitution}')
        return float(e)

    def set_mass(self, name: str, mass: float) -> None:
        """Total mass of an entity (kg); each body's mass and inertia scale by one factor.

        A body without mass is static: giving a static (jointless) entity a mass frees it
        where it is (it gets a free joint and falls), and a mass of 0 welds a free object to
        the world where it is now.
        """
        (m_new,) = check_finite('mass', [mass], 1)
        if m_new < 0:
            raise InvalidArgumentError(f'mass must be >= 0, got {mass}')
        with self._locked():
            rec = self._index.entity(name)
            if m_new == 0:
                if rec.category == ROBOT:
                    raise IncorrectStateError(ERR_ROBOT_WELD.format(name=name))
                if rec.has_free_joint:
                    self._kinematics_locked()
                    pos, q = state.body_pose(self._data, rec.root_body)
                    self._edit_locked(lambda spec: (
                        editor.place_root(spec, name, self._frame_of(spec, name), pos, q),
                        editor.weld(spec, rec)))
                return
            total = float(sum(self._model.body_mass[b] for b in rec.body_ids))
            if total <= 0:
                raise IncorrectStateError(ERR_NO_MASS.format(name=name))
            model, index = self._model, self._index
            self._edit_locked(lambda spec: (
                editor.free(spec, rec) if rec.category == STATIC else None,
                editor.scale_mass(spec, model, index, rec, m_new / total)))


class _WorldLock:
    """Context manager for the world lock (a class: cheaper than a generator per step).

    The lock is reentrant; each acquisition records whether it had to wait (and so was
    counted as a waiter), innermost last. Only the thread holding the lock touches the record.
    """

    __slots__ = ('_w', '_counted')

    def __init__(self, world: 'World'):
        self._w = world
        self._counted: list = []

    def __enter__(self) -> None:
        w = self._w
        if w._lock.acquire(blocking=False):
            self._counted.append(False)  # never waited: nobody needs to step aside for us
            return
        with w._waiting_cv:
            w._waiting += 1
        w._lock.acquire()
        self._counted.append(True)

    def __exit__(self, *exc) -> None:
        w = self._w
        counted = self._counted.pop()
        w._lock.release()
        if not counted:
            return
        with w._waiting_cv:
            w._waiting -= 1
            if w._loop_waiting and not w._waiting:
                w._waiting_cv.notify_all()
