"""The MuJoCo world: one MjSpec/MjModel/MjData, its entities, and every change to them.

Threading contract (see HOUSE_STYLE.md): the world owns one lock and every public method takes
it; helpers that assume it is held end in ``_locked``. Only :meth:`World.step` (called by the
stepping loop, or by a script that owns the world) advances physics. Joint commands go to a
staging buffer that the next step applies. Structural changes (spawn, delete, reset, set-state,
physics parameters) are validated first, then applied between steps, all or nothing.
"""

import contextlib
import logging
import math
import re
import threading
from typing import Iterable, Iterator, Optional, Sequence

import mujoco
import numpy as np

from . import sources
from .config import WorldConfig
from .errors import (DivergenceError, IncorrectStateError, InvalidArgumentError,
                     InvalidPoseError, NameInvalidError, NameNotUniqueError,
                     NamespaceInvalidError, NotFoundError, ResourceParseError)
from .types import (DYNAMIC, EFFORT, MODES, POSITION, RESET_SPAWNED, RESET_STATE, RESET_TIME,
                    ROBOT, STATIC, VELOCITY, EntityRecord, EntityState, GeomVisual, ModelInfo,
                    PhysicsState, Snapshot)

log = logging.getLogger(__name__)

NAME_RE = re.compile(r'^[A-Za-z_][A-Za-z0-9_\-]{0,127}$')
NAMESPACE_RE = re.compile(r'^/?([A-Za-z_][A-Za-z0-9_]*)(/[A-Za-z_][A-Za-z0-9_]*)*$')
# Above this MuJoCo treats a value as divergent (mjMAXVAL); refuse it as input.
MAX_ABS_VALUE = 1e10

ERR_UNKNOWN_ENTITY = 'no entity named {name!r}; existing: {names}'
ERR_UNKNOWN_JOINT = 'no commandable (hinge or slide) joint named {name!r}'
ERR_NAME = ("invalid name {name!r}: use letters, digits, '_' or '-', starting with a letter "
            "or '_', at most 128 characters")
ERR_NAMESPACE = 'invalid namespace {ns!r}: use a ROS namespace such as /robot1'
ERR_DUPLICATE = 'an entity named {name!r} exists; pick another name or allow renaming'
ERR_NOT_FINITE = '{what} must be finite numbers, got {value}'
ERR_TOO_LARGE_VALUE = '{what} must be smaller than {limit:g} in magnitude, got {value}'
ERR_QUAT = 'orientation must be a unit quaternion (norm {norm:.6f}); normalize it'
ERR_LENGTH = '{what}: {n} names but {m} values'
ERR_MODE = 'unknown command mode {mode!r}; use one of ' + ', '.join(MODES)
ERR_STATIC_TWIST = ('{name!r} is a {category} entity welded to the world: it cannot have a '
                    'velocity (only its pose can be set)')
ERR_STATE_GENERATION = ('this state was taken from model generation {got}, the world is now at '
                        'generation {now} (an entity was spawned or deleted since)')
ERR_INTERPENETRATION = ('at this pose {name!r} would overlap {other!r} by {depth:.4f} m; move '
                        'it, or allow interpenetration')
ERR_NOT_SPAWNED = '{name!r} is part of the loaded scene; only spawned entities can be deleted'


def _check_finite(what: str, values: Sequence[float], n: Optional[int] = None) -> np.ndarray:
    arr = np.asarray(values, dtype=float).reshape(-1)
    if n is not None and arr.size != n:
        raise InvalidArgumentError(f'{what} needs {n} values, got {arr.size}')
    if not np.all(np.isfinite(arr)):
        raise InvalidArgumentError(ERR_NOT_FINITE.format(what=what, value=arr.tolist()))
    if np.any(np.abs(arr) > MAX_ABS_VALUE):
        raise InvalidArgumentError(ERR_TOO_LARGE_VALUE.format(what=what, limit=MAX_ABS_VALUE,
                                                              value=arr.tolist()))
    return arr


def _clean(state: np.ndarray) -> bool:
    """True if a state vector has nothing MuJoCo would call divergent."""
    return bool(np.all(np.isfinite(state)) and np.max(np.abs(state), initial=0) < MAX_ABS_VALUE)


def check_quat(quat_wxyz: Sequence[float], tol: float = 1e-3) -> np.ndarray:
    """Validate a (4,) w,x,y,z quaternion: finite and of unit norm (within `tol`)."""
    q = _check_finite('orientation', quat_wxyz, 4)
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > tol:
        raise InvalidPoseError(ERR_QUAT.format(norm=norm))
    return q / norm


def check_pose(position: Sequence[float], quat_wxyz: Sequence[float]) -> tuple:
    try:
        pos = _check_finite('position', position, 3)
    except InvalidArgumentError as exc:
        raise InvalidPoseError(str(exc)) from None
    try:
        return pos, check_quat(quat_wxyz)
    except InvalidArgumentError as exc:
        raise InvalidPoseError(str(exc)) from None


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(out, np.asarray(v, float), np.asarray(q, float))
    return out


def quat_conj(q: np.ndarray) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def restitution_to_dampratio(restitution: float) -> float:
    """Damping ratio of a linear spring-damper contact whose coefficient of restitution is e.

    e = exp(-zeta * pi / sqrt(1 - zeta^2))  =>  zeta = -ln(e) / sqrt(pi^2 + ln(e)^2);
    e = 0 maps to zeta = 1 (MuJoCo's default, critically damped), e -> 1 to a small zeta.
    """
    e = min(max(restitution, 1e-4), MAX_RESTITUTION)
    ln_e = math.log(e)
    return min(1.0, -ln_e / math.sqrt(math.pi ** 2 + ln_e ** 2))


_MUJOCO_LOG = logging.getLogger('sim_node.mujoco')


def _log_mujoco_warning(message: str) -> None:
    _MUJOCO_LOG.warning('MuJoCo: %s', message)


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warning text to logging (the node forwards it to the ROS log) instead
    of stderr and a MUJOCO_LOG.TXT in the working directory; unless the application has
    installed a handler of its own (the handler is process-wide)."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_log_mujoco_warning)


_STATE = int(mujoco.mjtState.mjSTATE_INTEGRATION)  # an int: cheaper to pass per step
_BAD_WARNINGS = [int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQVEL),
                 int(mujoco.mjtWarning.mjWARN_BADQACC)]

# Enum membership must be tested on ints: numpy ints and MuJoCo enums do not hash alike.
_ONE_DOF_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_JOINT_TRN = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))

# Contact time constant used with a restitution (s). Measured (ball dropped 1 m, dt 1-2 ms):
# with 0.04 s the bounce height follows e^2 monotonically up to e = 0.8; shorter time
# constants or higher e gain energy (a lightly damped stiff contact), so e is capped at 0.8.
RESTITUTION_TIMECONST = 0.04
MAX_RESTITUTION = 0.8


class World:
    """A MuJoCo world that can change while it runs. Thread-safe; see the module docstring.

    Build with :meth:`from_file` or :meth:`from_string`.
    """

    def __init__(self, spec: mujoco.MjSpec, config: WorldConfig = WorldConfig(),
                 source: str = ''):
        self.config = config
        self.source = source
        self._lock = threading.Lock()
        # Callers waiting for the lock; the loop steps aside for them (a Lock is not fair).
        self._waiting = 0
        self._waiting_cv = threading.Condition(threading.Lock())
        self._loop_waiting = False
        self._lock_cm = _WorldLock(self)
        self._stage_lock = threading.Lock()
        self._staged: dict = {}
        self._kp = float(config.kp)
        self._kd = float(config.kd)
        # Disable MuJoCo's whole-world auto-reset on NaN: divergence is ours to report.
        spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        if config.timestep > 0:
            spec.option.timestep = float(config.timestep)
        route_mujoco_warnings()
        self._spec = spec
        sources.warn_radian_like_ranges(spec, f'the scene {source}'.strip())
        try:
            self._model = spec.compile()
        except ValueError as exc:
            raise ResourceParseError(f'the scene does not compile: {exc}') from None
        self._data = mujoco.MjData(self._model)
        self._generation = 0
        self._step_count = 0
        self._spawned: dict = {}  # name -> {'frame', 'assets', 'description', 'namespace'}
        self._overrides: dict = {}  # entity -> {'friction':..., 'restitution':...}
        self._default_friction: Optional[np.ndarray] = None
        self._default_restitution: Optional[float] = None
        self._commands: dict = {}  # joint name -> (mode, value), held until replaced
        self._stale_kinematics = False  # body poses lag qpos by a step (see _kinematics_locked)
        self._stale_dynamics = False
        self._last_good: Optional[np.ndarray] = None  # state after the last clean batch
        self._cached: Optional[np.ndarray] = None  # the current state, while untouched
        self._note_warnings_locked()
        self._reset_state_locked(keep_time=False)
        self._rebuild_locked()

    # ---------------------------------------------------------------- construction

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

    # ---------------------------------------------------------------- introspection

    @property
    def generation(self) -> int:
        return self._generation

    @property
    def model_info(self) -> ModelInfo:
        return self._info

    @property
    def timestep(self) -> float:
        return float(self._model.opt.timestep)

    @property
    def time(self) -> float:
        return float(self._data.time)

    @property
    def step_count(self) -> int:
        """Steps since the last time reset."""
        return self._step_count

    def entities(self) -> list:
        """Every entity (:class:`EntityRecord`), in model order."""
        return list(self._info.entities)

    def entity(self, name: str) -> EntityRecord:
        for rec in self._info.entities:
            if rec.name == name:
                return rec
        raise NotFoundError(ERR_UNKNOWN_ENTITY.format(
            name=name, names=[e.name for e in self._info.entities]))

    def joint_names(self) -> list:
        """Hinge and slide joints, the ones joint commands and joint_states cover."""
        return list(self._info.joint_names)

    def entity_bounds(self, name: str) -> tuple:
        """Axis-aligned bounds of an entity's geoms in the world frame: (min (3,), max (3,))."""
        with self._locked():
            rec = self.entity(name)
            self._kinematics_locked()
            m, d = self._model, self._data
            lo = np.full(3, np.inf)
            hi = np.full(3, -np.inf)
            for g in rec.geom_ids:
                half = m.geom_aabb[g, 3:]
                center = m.geom_aabb[g, :3]
                if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
                    continue
                rot = d.geom_xmat[g].reshape(3, 3)
                c = d.geom_xpos[g] + rot @ center
                ext = np.abs(rot) @ half
                lo = np.minimum(lo, c - ext)
                hi = np.maximum(hi, c + ext)
            if not np.all(np.isfinite(lo)):
                pos = d.xpos[rec.root_body].copy()
                return pos, pos
            return lo, hi

    # ---------------------------------------------------------------- snapshots

    def snapshot(self) -> Snapshot:
        with self._locked():
            return self._snapshot_locked()

    def _snapshot_locked(self) -> Snapshot:
        self._kinematics_locked()
        d = self._data
        effort = d.qfrc_actuator[self._joint_dofadr] + d.qfrc_applied[self._joint_dofadr]
        return Snapshot(generation=self._generation, step=self._step_count, time=float(d.time),
                        joint_position=d.qpos[self._joint_qposadr].copy(),
                        joint_velocity=d.qvel[self._joint_dofadr].copy(),
                        joint_effort=effort,
                        body_xpos=d.xpos.copy(), body_xquat_wxyz=d.xquat.copy())

    def get_state(self) -> PhysicsState:
        """The full integration state, like the older systems' ``getState``."""
        with self._locked():
            return self._get_state_locked()

    def _get_state_locked(self) -> PhysicsState:
        values = np.empty(self._state_size)
        mujoco.mj_getState(self._model, self._data, values, _STATE)
        return PhysicsState(generation=self._generation, step=self._step_count, values=values)

    def set_state(self, state: PhysicsState) -> None:
        """Overwrite the full state with one from :meth:`get_state` of the same generation."""
        with self._locked():
            if state.generation != self._generation:
                raise IncorrectStateError(ERR_STATE_GENERATION.format(
                    got=state.generation, now=self._generation))
            values = np.asarray(state.values, dtype=float)
            if not np.all(np.isfinite(values)):
                raise InvalidArgumentError(ERR_NOT_FINITE.format(what='state', value='...'))
            self._set_state_locked(values, state.step)

    def _set_state_locked(self, values: np.ndarray, step: int) -> None:
        self._cached = None
        mujoco.mj_setState(self._model, self._data, values, mujoco.mjtState.mjSTATE_INTEGRATION)
        self._step_count = step
        mujoco.mj_forward(self._model, self._data)
        self._note_warnings_locked()

    # ---------------------------------------------------------------- entity state

    def get_entity_state(self, name: str, reference: str = '') -> EntityState:
        """Pose and twist of the entity's root body, in the world or `reference`'s frame."""
        with self._locked():
            rec = self.entity(name)
            self._dynamics_locked()
            m, d = self._model, self._data
            b = rec.root_body
            vel, acc = np.zeros(6), np.zeros(6)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, vel, 0)
            mujoco.mj_objectAcceleration(m, d, mujoco.mjtObj.mjOBJ_BODY, b, acc, 0)
            pos, quat = d.xpos[b].copy(), d.xquat[b].copy()
            ang, lin = vel[:3].copy(), vel[3:].copy()
            ang_acc, lin_acc = acc[:3].copy(), acc[3:].copy()
            if not m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
                # MuJoCo's is an accelerometer's (gravity shows as +g at rest): make it the
                # coordinate acceleration.
                lin_acc += m.opt.gravity
            if reference:
                rpos, rquat = self._frame_locked(reference)
                inv = quat_conj(rquat)
                pos = quat_rotate(inv, pos - rpos)
                quat = quat_mul(inv, quat)
                lin, ang = quat_rotate(inv, lin), quat_rotate(inv, ang)
                lin_acc, ang_acc = quat_rotate(inv, lin_acc), quat_rotate(inv, ang_acc)
            return EntityState(position=pos, quat_wxyz=quat, linear_velocity=lin,
                               angular_velocity=ang, time=float(d.time),
                               linear_acceleration=lin_acc, angular_acceleration=ang_acc)

    def _frame_locked(self, name: str) -> tuple:
        rec = self.entity(name)
        self._kinematics_locked()
        return self._data.xpos[rec.root_body].copy(), self._data.xquat[rec.root_body].copy()

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
            rec = self.entity(name)
            pos, quat, lin, ang = self._check_target_locked(rec, position, quat_wxyz,
                                                            linear_velocity, angular_velocity)
            if reference:
                rpos, rquat = self._frame_locked(reference)
                if pos is not None:
                    pos = rpos + quat_rotate(rquat, pos)
                    quat = quat_mul(rquat, quat)
                lin = None if lin is None else quat_rotate(rquat, lin)
                ang = None if ang is None else quat_rotate(rquat, ang)
            if not rec.has_free_joint:
                self._refuse_static_twist(rec, lin, ang)
                if pos is not None:
                    self._move_welded_locked(rec, pos, quat)
                return
            self._set_free_body_locked(rec, pos, quat, lin, ang)
            mujoco.mj_forward(self._model, self._data)

    def _check_target_locked(self, rec: EntityRecord, position, quat_wxyz, linear,
                             angular) -> tuple:
        """Checked (pos, quat, lin, ang) for an entity's root body, None where not given; a
        pose given by one half keeps the current other half."""
        pos = quat = lin = ang = None
        if position is not None or quat_wxyz is not None:
            self._kinematics_locked()
            d, root = self._data, rec.root_body
            pos, quat = check_pose(position if position is not None else d.xpos[root],
                                   quat_wxyz if quat_wxyz is not None else d.xquat[root])
        if linear is not None:
            lin = _check_finite('linear velocity', linear, 3)
        if angular is not None:
            ang = _check_finite('angular velocity', angular, 3)
        return pos, quat, lin, ang

    @staticmethod
    def _refuse_static_twist(rec: EntityRecord, lin, ang) -> None:
        """An entity welded to the world cannot be given a non-zero twist."""
        if any(v is not None and np.any(v != 0) for v in (lin, ang)):
            raise IncorrectStateError(ERR_STATIC_TWIST.format(name=rec.name,
                                                              category=rec.category))

    def _set_free_body_locked(self, rec: EntityRecord, pos, quat, lin, ang) -> None:
        """Write checked world-frame values (or None) into a free body's joint."""
        m, d = self._model, self._data
        jnt = m.body_jntadr[rec.root_body]
        qadr, dadr = m.jnt_qposadr[jnt], m.jnt_dofadr[jnt]
        if pos is not None:
            d.qpos[qadr:qadr + 3] = pos
            d.qpos[qadr + 3:qadr + 7] = quat
        body_quat = d.qpos[qadr + 3:qadr + 7].copy()
        if lin is not None:
            d.qvel[dadr:dadr + 3] = lin
        if ang is not None:
            # A free joint's angular velocity is in the body frame.
            d.qvel[dadr + 3:dadr + 6] = quat_rotate(quat_conj(body_quat), ang)
        self._cached = None

    def overwrite(self, poses: Optional[dict] = None, twists: Optional[dict] = None,
                  joint_positions: Optional[dict] = None,
                  joint_velocities: Optional[dict] = None) -> None:
        """Overwrite any parts of the state at once, in the world frame: ``poses``
        {entity: (position, quat_wxyz)}, ``twists`` {entity: (linear, angular)}, and
        {joint: value} for hinge/slide joint positions and velocities.

        Everything is checked before anything changes, so an error changes nothing. An
        entity without a free joint given its current pose stays put (no rebuild); given
        another pose it is moved as :meth:`set_entity_state` does (model rebuilt, state
        kept), and a non-zero twist for it is refused.
        """
        poses, twists = poses or {}, twists or {}
        joint_positions, joint_velocities = joint_positions or {}, joint_velocities or {}
        with self._locked():
            d = self._data
            targets = {}  # entity -> (record, pos, quat, lin, ang), all checked
            for n in (*poses, *twists):
                rec = self.entity(n)
                targets[n] = (rec, *self._check_target_locked(
                    rec, *poses.get(n, (None, None)), *twists.get(n, (None, None))))
            q_adr, q_values = self._joint_targets_locked('position', joint_positions, True)
            v_adr, v_values = self._joint_targets_locked('velocity', joint_velocities, False)
            welded_moves = []
            for rec, pos, quat, lin, ang in targets.values():
                if rec.has_free_joint:
                    continue
                self._refuse_static_twist(rec, lin, ang)
                root = rec.root_body
                if pos is not None and not (
                        np.allclose(pos, d.xpos[root], rtol=0, atol=1e-9)
                        and abs(abs(float(np.dot(quat, d.xquat[root]))) - 1.0) < 1e-12):
                    welded_moves.append((rec, pos, quat))
            # Apply: direct writes first, then the moves that rebuild the model.
            for rec, pos, quat, lin, ang in targets.values():
                if rec.has_free_joint:
                    self._set_free_body_locked(rec, pos, quat, lin, ang)
            d.qpos[q_adr] = q_values
            d.qvel[v_adr] = v_values
            self._cached = None
            mujoco.mj_forward(self._model, d)
            for rec, pos, quat in welded_moves:
                self._move_welded_locked(rec, pos, quat)

    def _move_welded_locked(self, rec: EntityRecord, pos: np.ndarray, quat: np.ndarray) -> None:
        body = self._spec.body(self._info.body_names[rec.root_body])
        frame = self._spawned.get(rec.name, {}).get('frame')
        if frame is not None:
            # A spawned body's pose is relative to its attachment frame.
            frame.pos, frame.quat = [0, 0, 0], [1, 0, 0, 0]
        body.pos, body.quat = pos.tolist(), quat.tolist()
        self._recompile_locked()

    def set_joint_positions(self, positions: dict) -> None:
        """Set hinge/slide joint positions by name (velocities are kept)."""
        self._set_joints('position', positions, use_qpos=True)

    def set_joint_velocities(self, velocities: dict) -> None:
        self._set_joints('velocity', velocities, use_qpos=False)

    def _set_joints(self, what: str, values: dict, use_qpos: bool) -> None:
        with self._locked():
            adr, vals = self._joint_targets_locked(what, values, use_qpos)
            (self._data.qpos if use_qpos else self._data.qvel)[adr] = vals
            self._cached = None
            mujoco.mj_forward(self._model, self._data)

    def _joint_targets_locked(self, what: str, values: dict, use_qpos: bool) -> tuple:
        """Checked (qpos or qvel addresses, values) for {joint: value}."""
        idx = self._joint_indices_locked(values.keys())
        vals = _check_finite(f'joint {what}s', list(values.values()))
        return (self._joint_qposadr[idx] if use_qpos else self._joint_dofadr[idx]), vals

    def get_joint_states(self) -> dict:
        """name -> (position, velocity, effort) for every hinge and slide joint."""
        snap = self.snapshot()
        return {n: (float(p), float(v), float(e)) for n, p, v, e in zip(
            self._info.joint_names, snap.joint_position, snap.joint_velocity,
            snap.joint_effort)}

    def _joint_indices_locked(self, names: Iterable[str]) -> np.ndarray:
        idx = []
        for n in names:
            i = self._joint_index.get(n)
            if i is None:
                raise NotFoundError(ERR_UNKNOWN_JOINT.format(name=n))
            idx.append(i)
        return np.asarray(idx, dtype=int)

    # ---------------------------------------------------------------- control

    def command(self, names: Sequence[str], values: Sequence[float], mode: str) -> None:
        """Stage joint commands; the next step applies them, and they hold until replaced.

        Position and velocity commands use the joint's actuator of that kind if the scene has
        one (its ctrl is set), otherwise PD torques through ``qfrc_applied`` with gains
        ``kp``/``kd``. Effort commands use a motor actuator or ``qfrc_applied`` directly.

        :raises NotFoundError: an unknown joint; nothing is staged.
        :raises InvalidArgumentError: a non-finite value, a length mismatch or a bad mode.
        """
        if mode not in MODES:
            raise InvalidArgumentError(ERR_MODE.format(mode=mode))
        names = list(names)
        if len(names) != len(values):
            raise InvalidArgumentError(ERR_LENGTH.format(what='joint command', n=len(names),
                                                         m=len(values)))
        vals = _check_finite(f'{mode} commands', values)
        unknown = [n for n in names if n not in self._joint_index]
        if unknown:
            raise NotFoundError(ERR_UNKNOWN_JOINT.format(name=unknown[0]))
        with self._stage_lock:
            for n, v in zip(names, vals):
                self._staged[n] = (mode, float(v))

    def clear_commands(self) -> None:
        """Drop every staged and held joint command (PD torques stop, actuators keep ctrl)."""
        with self._locked():
            self._clear_commands_locked()

    def _clear_commands_locked(self) -> None:
        with self._stage_lock:
            self._staged.clear()
        self._commands.clear()
        self._data.qfrc_applied[:] = 0
        self._rebuild_control_locked()

    def set_gains(self, kp: float, kd: float) -> None:
        """PD gains for joints commanded without a matching actuator."""
        kp_v, kd_v = _check_finite('gains', [kp, kd], 2)
        if kp_v < 0 or kd_v < 0:
            raise InvalidArgumentError(f'gains must be >= 0, got kp={kp}, kd={kd}')
        with self._locked():
            self._kp, self._kd = float(kp_v), float(kd_v)
            self._rebuild_control_locked()

    def _apply_staged_locked(self) -> None:
        if not self._staged:  # the common case, read without the lock: a command staged
            return            # meanwhile is applied before the next batch instead
        with self._stage_lock:
            if not self._staged:
                return
            staged, self._staged = self._staged, {}
        for name, (mode, value) in staged.items():
            if name not in self._joint_index:
                continue  # the joint was deleted after the command was staged
            act = self._joint_actuators[self._joint_index[name]].get(mode)
            if act is not None:
                self._data.ctrl[act] = value
                self._commands.pop(name, None)
            else:
                self._commands[name] = (mode, value)
        self._rebuild_control_locked()

    def _rebuild_control_locked(self) -> None:
        """Index arrays for PD/effort joints; rebuilt on a new command or a new generation."""
        d = self._data
        self._cached = None  # ctrl or qfrc_applied may change here
        prev = getattr(self, '_pd_dof', np.zeros(0, int))
        d.qfrc_applied[prev] = 0
        items = [(self._joint_index[n], mode, v) for n, (mode, v) in self._commands.items()
                 if n in self._joint_index]
        # A velocity or effort command on a joint that only has a position servo: the servo's
        # target moves at the commanded velocity, or follows the joint (so the servo only
        # damps) while the effort goes through qfrc_applied.
        servo = [(self._joint_actuators[i].get(POSITION), i, mode, v) for i, mode, v in items
                 if mode in (VELOCITY, EFFORT) and POSITION in self._joint_actuators[i]]
        self._servo_act = np.array([a for a, _, _, _ in servo], dtype=int)
        self._servo_qpos = self._joint_qposadr[[i for _, i, _, _ in servo]] if servo else \
            np.zeros(0, int)
        self._servo_rate = np.array([v if mode == VELOCITY else np.nan
                                     for _, _, mode, v in servo], dtype=float)
        self._servo_range = self._model.actuator_ctrlrange[self._servo_act] if servo else \
            np.zeros((0, 2))
        self._servo_limited = self._model.actuator_ctrllimited[self._servo_act].astype(bool) \
            if servo else np.zeros(0, bool)
        items = [(i, mode, v) for i, mode, v in items
                 if not (mode == VELOCITY and POSITION in self._joint_actuators[i])]
        idx = np.array([i for i, _, _ in items], dtype=int)
        self._pd_dof = self._joint_dofadr[idx] if len(idx) else np.zeros(0, int)
        self._pd_qpos = self._joint_qposadr[idx] if len(idx) else np.zeros(0, int)
        modes = [mode for _, mode, _ in items]
        target = np.array([v for _, _, v in items], dtype=float)
        is_pos = np.array([m == POSITION for m in modes], dtype=bool)
        is_eff = np.array([m == EFFORT for m in modes], dtype=bool)
        self._pd_is_pos = is_pos
        self._pd_pos_target = np.where(is_pos, target, 0.0)
        self._pd_vel_target = np.where([m == VELOCITY for m in modes], target, 0.0)
        self._pd_effort = np.where(is_eff, target, 0.0)
        # Gains act per unit of the joint's own inertia (dof_M0), so one pair of defaults is
        # stable on a 50 g finger and on a 20 kg arm; gravity/Coriolis is fed forward.
        m0 = self._model.dof_M0[self._pd_dof] if len(idx) else np.zeros(0)
        self._pd_kp = np.where(is_pos, self._kp * m0, 0.0)
        self._pd_kd = np.where(is_eff, 0.0, self._kd * m0)
        self._pd_bias = ~is_eff
        # PD torques and moving servo targets are recomputed before every single step.
        self._per_step_control = bool(len(self._pd_dof) or len(self._servo_act))

    def _apply_pd_locked(self) -> None:
        d = self._data
        dof = self._pd_dof
        q = d.qpos[self._pd_qpos]
        v = d.qvel[dof]
        err = np.where(self._pd_is_pos, self._pd_pos_target - q, 0.0)
        d.qfrc_applied[dof] = (self._pd_kp * err + self._pd_kd * (self._pd_vel_target - v)
                               + self._pd_effort + np.where(self._pd_bias, d.qfrc_bias[dof], 0.0))
        if len(self._servo_act):
            follow = np.isnan(self._servo_rate)
            target = np.where(follow, d.qpos[self._servo_qpos],
                              d.ctrl[self._servo_act] + np.nan_to_num(self._servo_rate)
                              * self._model.opt.timestep)
            lo, hi = self._servo_range[:, 0], self._servo_range[:, 1]
            d.ctrl[self._servo_act] = np.where(self._servo_limited, np.clip(target, lo, hi),
                                               target)

    # ---------------------------------------------------------------- stepping

    def step(self, n: int = 1, ctrl: Optional[np.ndarray] = None) -> int:
        """Advance `n` steps (applying staged commands first); returns the step count.

        :param ctrl: (nu,) actuator controls to set first, for callers that own the world
            (the Gym environment); the caller checks them (finite, within +-1e10).

        :raises DivergenceError: the physics diverged; the world is back at the last good
            state (the one before the bad step) and ``error.step`` names the bad step.
        """
        if n < 1:
            raise InvalidArgumentError(f'steps must be >= 1, got {n}')
        # This runs once per Gym step and per loop batch: take a free lock directly. It is
        # _WorldLock's own fast path without the context-manager calls, 0.25 us a step
        # (1% of a Reacher-v5 step); a contended lock goes through _WorldLock as usual.
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
        if self._staged:
            self._apply_staged_locked()
            before = None
        m, d = self._model, self._data
        if before is None:
            before = self._get_state_locked().values
            ctrl = None  # already in `before`
        if self._per_step_control:
            for _ in range(n):
                self._apply_pd_locked()
                mujoco.mj_step(m, d)
        else:
            mujoco.mj_step(m, d, n)
        if self._diverged_locked():
            self._locate_divergence_locked(before, n, ctrl)
        self._step_count += n
        # The state after a clean batch: the next batch's starting point (unless something
        # changes it), and the fallback for divergence caused by values put in between steps
        # (e.g. through locked()). One buffer, overwritten in place: `before` is spent by now.
        mujoco.mj_getState(m, d, self._good_buf, _STATE)
        self._last_good = self._cached = self._good_buf
        self._stale_kinematics = self._stale_dynamics = True
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

    def _diverged_locked(self) -> bool:
        """True if MuJoCo calls the state bad (NaN, inf or beyond 1e10 in qpos, qvel or qacc);
        logs other new warnings. Runs after every batch, so the common case is three C calls
        and one comparison.
        """
        m, d = self._model, self._data
        # mj_step checks qpos and qvel only at the start of the next step; the integrator may
        # have just carried a bad acceleration into them. Check them now, as MuJoCo would.
        mujoco.mj_checkPos(m, d)
        mujoco.mj_checkVel(m, d)
        warn = self._warn_view
        if warn.tobytes() == self._warnings_bytes:
            return False
        changed = warn != self._warnings
        if changed[_BAD_WARNINGS].any():
            return True
        for i in np.nonzero(changed)[0]:
            log.warning('MuJoCo warning %s (info %d)', mujoco.mjtWarning(i).name,
                        d.warning[i].lastinfo)
        self._note_warnings_locked()
        return False

    def _note_warnings_locked(self) -> None:
        """Take the current warning counters as seen (new ones are what _diverged looks for)."""
        self._warnings = self._data.warning.number.copy()
        self._warnings_bytes = self._warnings.tobytes()

    def _locate_divergence_locked(self, before: np.ndarray, n: int,
                                  ctrl: Optional[np.ndarray]) -> None:
        """Replay the batch one step at a time to find the bad step; end at the state before.

        :param ctrl: the batch's controls, if `before` does not hold them yet.
        """
        m, d = self._model, self._data
        self._set_state_locked(before, self._step_count)
        if ctrl is not None:
            d.ctrl[:] = ctrl
        for k in range(n):
            good = self._get_state_locked().values
            if self._per_step_control:
                self._apply_pd_locked()
            mujoco.mj_step(m, d)
            if self._diverged_locked() or k == n - 1:
                break
        warn = d.warning.number
        changed = {mujoco.mjtWarning(i).name: int(d.warning[i].lastinfo)
                   for i in np.nonzero(warn != self._warnings)[0]}
        bad_step = self._step_count + k + 1
        report = {'step': bad_step, 'time': float(d.time), 'warnings': changed,
                  'nonfinite_qpos': int(np.count_nonzero(~np.isfinite(d.qpos))),
                  'nonfinite_qvel': int(np.count_nonzero(~np.isfinite(d.qvel)))}
        self._step_count += k
        if not _clean(good):
            # The bad values were put in between steps (e.g. through locked()): go back to
            # the state before the batch that was last stepped successfully.
            good = self._last_good if self._last_good is not None else good
        self._set_state_locked(good, self._step_count)
        raise DivergenceError(f'physics diverged at step {bad_step} (t={report["time"]:.4f} s): '
                              f'{changed or "non-finite state"}; restored the state before it',
                              bad_step, report)

    # ---------------------------------------------------------------- reset

    def reset(self, scope: int = 255) -> None:
        """Reset by scope bits: RESET_TIME, RESET_STATE (the `home` keyframe or the initial
        state), RESET_SPAWNED (delete everything spawned since load); RESET_ALL does all.
        The model is rebuilt only when spawned entities must go."""
        if not 0 <= scope <= 255:
            raise InvalidArgumentError(f'reset scope must be 0..255, got {scope}')
        if scope == 0:
            scope = 255
        with self._locked():
            if scope & RESET_SPAWNED:
                doomed = list(self._spawned)
                for name in doomed:
                    self._remove_spawned_from_spec_locked(name)
                if doomed:
                    self._recompile_locked()
            if scope & RESET_STATE:
                self._clear_commands_locked()
                self._reset_state_locked(keep_time=not scope & RESET_TIME)
            elif scope & RESET_TIME:
                self._cached = None
                self._data.time = 0.0
                self._step_count = 0

    def _reset_state_locked(self, keep_time: bool) -> None:
        m, d = self._model, self._data
        self._cached = None
        t, steps = d.time, self._step_count
        key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, 'home')
        if key >= 0:
            mujoco.mj_resetDataKeyframe(m, d, key)
        else:
            mujoco.mj_resetData(m, d)
        if keep_time:
            d.time, self._step_count = t, steps
        else:
            self._step_count = 0
        mujoco.mj_forward(m, d)
        self._warnings = d.warning.number.copy()

    # ---------------------------------------------------------------- spawn and delete

    def unique_name(self, base: str) -> str:
        taken = {e.name for e in self._info.entities} | set(self._info.body_names)
        base = base if NAME_RE.match(base or '') else 'entity'
        if base not in taken:
            return base
        i = 1
        while f'{base}_{i}' in taken:
            i += 1
        return f'{base}_{i}'

    def spawn(self, name: str, source: sources.SpawnSource,
              position: Sequence[float] = (0.0, 0.0, 0.0),
              quat_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0), reference: str = '',
              allow_renaming: bool = False, namespace: str = '',
              allow_interpenetration: Optional[bool] = None) -> str:
        """Add an entity at a pose (world frame, or `reference` entity's frame) while running.

        Its root body is named `name`; its other bodies and elements ``name/<original>``.
        All or nothing: on any error the world is exactly as before.

        :returns: the entity's name (differs from `name` only when renaming was allowed).
        """
        pos, quat = check_pose(position, quat_wxyz)
        if namespace and not NAMESPACE_RE.match(namespace):
            raise NamespaceInvalidError(ERR_NAMESPACE.format(ns=namespace))
        if not allow_renaming and not NAME_RE.match(name or ''):
            raise NameInvalidError(ERR_NAME.format(name=name))
        overlap_ok = (self.config.allow_interpenetration if allow_interpenetration is None
                      else allow_interpenetration)
        with self._locked():
            taken = {e.name for e in self._info.entities} | set(self._info.body_names)
            if name in taken or not name:
                if not allow_renaming:
                    raise NameNotUniqueError(ERR_DUPLICATE.format(name=name))
                name = self.unique_name(name or source.kind)
            if reference:
                rpos, rquat = self._frame_locked(reference)
                pos, quat = rpos + quat_rotate(rquat, pos), quat_mul(rquat, quat)
            # Validate on a copy: a failed compile breaks a spec, so the live one is touched
            # only once the copy compiled and passed the overlap check.
            trial = self._spec.copy()
            self._attach(trial, name, source, pos, quat)
            try:
                trial_model = trial.compile()
            except ValueError as exc:
                raise ResourceParseError(f'spawning {name!r} does not compile: {exc}') from None
            if not overlap_ok:
                self._check_overlap_locked(trial_model, name)
            frame, assets = self._attach(self._spec, name, source, pos, quat)
            self._spawned[name] = {'frame': frame, 'assets': assets, 'namespace': namespace,
                                   'description': source.description}
            try:
                self._recompile_locked()
            except ResourceParseError:
                self._remove_spawned_from_spec_locked(name)
                self._recompile_locked()
                raise
            self._apply_defaults_to_locked(name)
            return name

    def _attach(self, spec: mujoco.MjSpec, name: str, source: sources.SpawnSource,
                pos: np.ndarray, quat: np.ndarray) -> tuple:
        child = source.spec.copy()
        root = child.worldbody.first_body()
        if not root.name:
            root.name = 'root'
        old_root = f'{name}/{root.name}'
        frame = spec.worldbody.add_frame(pos=pos.tolist(), quat=quat.tolist())
        body = frame.attach_body(root, f'{name}/', '')
        body.name = name
        _rename_body_references(spec, old_root, name)
        if source.assets:
            spec.assets = {**spec.assets, **source.assets}
        return frame, tuple(source.assets)

    def _check_overlap_locked(self, model: mujoco.MjModel, name: str) -> None:
        data = mujoco.MjData(model)
        live_m, live_d = self._model, self._data
        data.qpos[:live_m.nq] = live_d.qpos
        data.mocap_pos[:live_m.nmocap] = live_d.mocap_pos
        data.mocap_quat[:live_m.nmocap] = live_d.mocap_quat
        mujoco.mj_fwdPosition(model, data)
        root = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        new = set(range(root, model.nbody)) if root >= 0 else set()
        tol = self.config.interpenetration_tolerance
        for c in data.contact[:data.ncon]:
            b1, b2 = model.geom_bodyid[c.geom[0]], model.geom_bodyid[c.geom[1]]
            if (b1 in new) != (b2 in new) and c.dist < -tol:
                other = c.geom[1] if b1 in new else c.geom[0]
                other_name = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, other)
                              or mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY,
                                                   model.geom_bodyid[other]) or 'world')
                raise InvalidPoseError(ERR_INTERPENETRATION.format(name=name, other=other_name,
                                                                   depth=-c.dist))

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
        pos, quat = check_pose(position, quat_wxyz)
        ax = _check_finite('axis', axis, 3)
        if not NAME_RE.match(name or ''):
            raise NameInvalidError(ERR_NAME.format(name=name))
        if joint not in (None, 'hinge', 'slide'):
            raise InvalidArgumentError(f"joint must be None, 'hinge' or 'slide', got {joint!r}")
        # Validate the geometry with the same rules as a primitive spawn.
        sources.primitive(shape, size, mass=mass or None, rgba=rgba, static=True)
        with self._locked():
            if parent not in self._info.body_names:
                raise NotFoundError(f'no body named {parent!r}')
            root = self._root_entity_of_locked(parent)
            if root not in self._spawned:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=root))
            full = f'{root}/{name}'
            if full in self._info.body_names:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=full))
            trial = self._spec.copy()
            self._add_child(trial, parent, full, shape, size, pos, quat, mass, joint, ax, rgba)
            try:
                trial.compile()
            except ValueError as exc:
                raise ResourceParseError(f'adding {full!r} does not compile: {exc}') from None
            self._add_child(self._spec, parent, full, shape, size, pos, quat, mass, joint, ax,
                            rgba)
            self._recompile_locked()
            return full

    @staticmethod
    def _add_child(spec, parent, full, shape, size, pos, quat, mass, joint, axis, rgba) -> None:
        n = {'box': 3, 'sphere': 1, 'cylinder': 2, 'capsule': 2}[shape]
        body = spec.body(parent).add_body(name=full, pos=pos.tolist(), quat=quat.tolist())
        if joint:
            body.add_joint(name=f'{full}/joint', axis=axis.tolist(), type=getattr(
                mujoco.mjtJoint, 'mjJNT_HINGE' if joint == 'hinge' else 'mjJNT_SLIDE'))
        geom = body.add_geom(name=f'{full}/geom', size=list(map(float, size)) + [0.0] * (3 - n),
                             type=getattr(mujoco.mjtGeom, f'mjGEOM_{shape.upper()}'),
                             rgba=list(map(float, rgba)))
        if mass:
            geom.mass = float(mass)

    def _root_entity_of_locked(self, body_name: str) -> str:
        b = self._info.body_names.index(body_name)
        return self._info.body_names[self._info.body_root[b]]

    def delete(self, name: str) -> None:
        """Remove a spawned entity with its joints, geoms, actuators, sensors, equality
        constraints, contact pairs and excludes; everything else keeps its state exactly."""
        with self._locked():
            self.entity(name)
            if name not in self._spawned:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=name))
            self._remove_spawned_from_spec_locked(name)
            self._recompile_locked()

    def _remove_spawned_from_spec_locked(self, name: str) -> None:
        rec = self._spawned.pop(name)
        self._overrides.pop(name, None)
        self._spec.delete(self._spec.body(name))
        self._spec.delete(rec['frame'])
        if rec['assets']:
            self._spec.assets = {k: v for k, v in self._spec.assets.items()
                                 if k not in rec['assets']}

    def _recompile_locked(self) -> None:
        try:
            model, data = self._spec.recompile(self._model, self._data)
        except ValueError as exc:
            raise ResourceParseError(f'the model does not compile: {exc}') from None
        self._model, self._data = model, data
        self._generation += 1
        self._last_good = self._cached = None  # their layout belongs to the old model
        # Derived quantities (xpos, contacts) are zero until mj_forward runs.
        mujoco.mj_forward(model, data)
        self._note_warnings_locked()
        self._rebuild_locked()

    # ---------------------------------------------------------------- physics parameters

    def set_gravity(self, gravity: Sequence[float]) -> None:
        g = _check_finite('gravity', gravity, 3)
        with self._locked():
            self._spec.option.gravity = g.tolist()
            self._recompile_locked()

    def set_timestep(self, timestep: float) -> None:
        (dt,) = _check_finite('timestep', [timestep], 1)
        if not 0 < dt <= 0.1:
            raise InvalidArgumentError(f'timestep must be in (0, 0.1] s, got {timestep}')
        with self._locked():
            self._spec.option.timestep = float(dt)
            self._recompile_locked()

    def set_integrator(self, integrator: str) -> None:
        names = {'euler': 'mjINT_EULER', 'rk4': 'mjINT_RK4', 'implicit': 'mjINT_IMPLICIT',
                 'implicitfast': 'mjINT_IMPLICITFAST'}
        if integrator not in names:
            raise InvalidArgumentError(f'unknown integrator {integrator!r}; use one of '
                                       + ', '.join(names))
        with self._locked():
            self._spec.option.integrator = int(getattr(mujoco.mjtIntegrator,
                                                       names[integrator]))
            self._recompile_locked()

    def set_friction(self, name: str, sliding: float, torsional: Optional[float] = None,
                     rolling: Optional[float] = None) -> None:
        """Friction of every geom of an entity (MuJoCo's three coefficients)."""
        with self._locked():
            rec = self.entity(name)
            cur = (self._model.geom_friction[rec.geom_ids[0]] if rec.geom_ids
                   else np.array([1.0, 0.005, 0.0001]))
            f = _check_finite('friction', [sliding, cur[1] if torsional is None else torsional,
                                           cur[2] if rolling is None else rolling], 3)
            if np.any(f < 0):
                raise InvalidArgumentError(f'friction must be >= 0, got {f.tolist()}')
            self._overrides.setdefault(name, {})['friction'] = f
            self._apply_contact_locked([name])
            self._recompile_locked()

    def set_restitution(self, name: str, restitution: float) -> None:
        """Bounciness of an entity's geoms in [0, 0.8]; see :func:`restitution_to_dampratio`."""
        e = self._check_restitution(restitution)
        with self._locked():
            self.entity(name)
            self._overrides.setdefault(name, {})['restitution'] = e
            self._apply_contact_locked([name])
            self._recompile_locked()

    def set_default_contact(self, friction: Optional[Sequence[float]] = None,
                            restitution: Optional[float] = None) -> None:
        """Global friction (3 values) and/or restitution for every geom without its own."""
        f = None if friction is None else _check_finite('friction', friction, 3)
        e = None if restitution is None else self._check_restitution(restitution)
        with self._locked():
            if f is not None:
                self._default_friction = f
            if e is not None:
                self._default_restitution = e
            self._apply_contact_locked([r.name for r in self._info.entities], world=True)
            self._recompile_locked()

    @staticmethod
    def _check_restitution(restitution: float) -> float:
        (e,) = _check_finite('restitution', [restitution], 1)
        if not 0.0 <= e <= MAX_RESTITUTION:
            raise InvalidArgumentError(
                f'restitution must be in [0, {MAX_RESTITUTION}], got {restitution}')
        return float(e)

    def _apply_contact_locked(self, names: list, world: bool = False) -> None:
        targets = [(n, self.entity(n).geom_ids) for n in names]
        if world:
            targets.append(('', tuple(np.nonzero(self._model.geom_bodyid == 0)[0])))
        for name, geom_ids in targets:
            own = self._overrides.get(name, {})
            friction = own.get('friction', self._default_friction)
            restitution = own.get('restitution', self._default_restitution)
            for g in geom_ids:
                geom = self._spec.geom(self._geom_spec_names[g]) if self._geom_spec_names[
                    g] else None
                if geom is None:
                    continue
                if friction is not None:
                    geom.friction = list(map(float, friction))
                if restitution is not None:
                    geom.solref = [RESTITUTION_TIMECONST, restitution_to_dampratio(restitution)]

    def _apply_defaults_to_locked(self, name: str) -> None:
        if self._default_friction is not None or self._default_restitution is not None:
            self._apply_contact_locked([name])
            self._recompile_locked()

    def set_mass(self, name: str, mass: float) -> None:
        """Total mass of an entity (kg); each body's mass and inertia scale by one factor.

        A body without mass is static: giving a static (jointless) entity a mass frees it
        (it gets a free joint and falls), and a mass of 0 welds a free object to the world.
        """
        (m_new,) = _check_finite('mass', [mass], 1)
        if m_new < 0:
            raise InvalidArgumentError(f'mass must be >= 0, got {mass}')
        with self._locked():
            rec = self.entity(name)
            body = self._spec.body(name)
            if m_new == 0:
                if rec.category == ROBOT:
                    raise IncorrectStateError(f'{name!r} is a robot: give it a positive mass')
                if rec.has_free_joint:
                    for j in list(body.joints):
                        self._spec.delete(j)
                self._recompile_locked()
                return
            if rec.category == STATIC:
                body.add_freejoint(name=f'{name}/free')
                self._recompile_locked()
                rec = self.entity(name)
            m = self._model
            total = float(sum(m.body_mass[b] for b in rec.body_ids))
            if total <= 0:
                raise IncorrectStateError(f'{name!r} has no mass to scale')
            k = m_new / total
            for b in rec.body_ids:
                bs = self._spec.body(self._info.body_names[b])
                bs.explicitinertial = True
                bs.mass = float(m.body_mass[b] * k)
                bs.inertia = (m.body_inertia[b] * k).tolist()
                bs.ipos = m.body_ipos[b].tolist()
                bs.iquat = m.body_iquat[b].tolist()
            self._recompile_locked()

    # ---------------------------------------------------------------- model tables

    def _rebuild_locked(self) -> None:
        """Rebuild every name/index table for a new model generation."""
        m = self._model
        self._state_size = mujoco.mj_stateSize(m, _STATE)
        # Where ctrl sits in the state vector (mjtState order: time, qpos, qvel, act,
        # warm start, ctrl, ...).
        before_ctrl = mujoco.mj_stateSize(m, int(_STATE) & (
            int(mujoco.mjtState.mjSTATE_TIME) | int(mujoco.mjtState.mjSTATE_QPOS)
            | int(mujoco.mjtState.mjSTATE_QVEL) | int(mujoco.mjtState.mjSTATE_ACT)
            | int(mujoco.mjtState.mjSTATE_WARMSTART)))
        self._ctrl_slice = slice(before_ctrl, before_ctrl + m.nu)
        names = []
        for b in range(m.nbody):
            n = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
            names.append('world' if b == 0 else (n or f'body_{b}'))
        parent = m.body_parentid.copy()
        has_joint = m.body_jntnum > 0
        jids = [j for j in range(m.njnt) if int(m.jnt_type[j]) in _ONE_DOF_JOINTS]
        jnames = tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f'joint_{j}'
                       for j in jids)
        self._joint_index = {n: i for i, n in enumerate(jnames)}
        self._joint_qposadr = m.jnt_qposadr[jids].astype(int) if jids else np.zeros(0, int)
        self._joint_dofadr = m.jnt_dofadr[jids].astype(int) if jids else np.zeros(0, int)
        self._joint_actuators = self._classify_actuators(m, jids)
        self._geom_spec_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or ''
                                 for g in range(m.ngeom)]
        # Unnamed geoms cannot be looked up in the spec: name them once, then rebuild.
        if not all(self._geom_spec_names):
            for body in [self._spec.worldbody] + list(self._spec.bodies):
                for i, geom in enumerate(body.geoms):
                    if not geom.name:
                        geom.name = f'{body.name or "world"}/geom_{i}'
            self._model, self._data = self._spec.recompile(m, self._data)
            mujoco.mj_forward(self._model, self._data)
            return self._rebuild_locked()
        # Views into this MjData, and the state buffer, for the per-step path.
        d = self._data
        self._ctrl, self._qvel, self._warn_view = d.ctrl, d.qvel, d.warning.number
        self._good_buf = np.empty(self._state_size)
        root_of = np.zeros(m.nbody, dtype=int)
        for b in range(1, m.nbody):  # parents come before children
            root_of[b] = b if parent[b] == 0 else root_of[parent[b]]
        self._info = ModelInfo(
            generation=self._generation, timestep=float(m.opt.timestep),
            body_names=tuple(names), body_parent=parent, body_root=root_of,
            body_has_joint=has_joint,
            body_local_pos=m.body_pos.copy(), body_local_quat_wxyz=m.body_quat.copy(),
            joint_names=jnames, joint_ids=np.asarray(jids, dtype=int),
            geoms=self._geom_visuals(m, names),
            entities=self._entity_records(m, names, root_of))
        self._rebuild_control_locked()

    @staticmethod
    def _classify_actuators(m: mujoco.MjModel, jids: list) -> list:
        """For each commandable joint: {mode: actuator id} for single-joint actuators."""
        by_joint = {j: {} for j in jids}
        for a in range(m.nu):
            if m.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
                continue
            j = m.actuator_trnid[a, 0]
            if j not in by_joint or m.actuator_dyntype[a] != mujoco.mjtDyn.mjDYN_NONE:
                continue
            bias = m.actuator_biasprm[a]
            if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE:
                mode = EFFORT
            elif bias[1] != 0:
                mode = POSITION
            elif bias[2] != 0:
                mode = VELOCITY
            else:
                continue
            by_joint[j].setdefault(mode, a)
        return [by_joint[j] for j in jids]

    @staticmethod
    def _geom_visuals(m: mujoco.MjModel, body_names: list) -> tuple:
        types = {int(mujoco.mjtGeom.mjGEOM_PLANE): 'plane', int(mujoco.mjtGeom.mjGEOM_SPHERE):
                 'sphere', int(mujoco.mjtGeom.mjGEOM_CAPSULE): 'capsule',
                 int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): 'ellipsoid',
                 int(mujoco.mjtGeom.mjGEOM_CYLINDER): 'cylinder',
                 int(mujoco.mjtGeom.mjGEOM_BOX): 'box', int(mujoco.mjtGeom.mjGEOM_MESH): 'mesh'}
        out = []
        for g in range(m.ngeom):
            kind = types.get(int(m.geom_type[g]))
            rgba = m.geom_rgba[g].copy()
            if m.geom_matid[g] >= 0:
                rgba = m.mat_rgba[m.geom_matid[g]].copy()
            if kind is None or m.geom_group[g] > 2 or rgba[3] <= 0:
                continue
            verts = faces = None
            if kind == 'mesh':
                mid = m.geom_dataid[g]
                va, vn = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
                fa, fn = m.mesh_faceadr[mid], m.mesh_facenum[mid]
                verts = m.mesh_vert[va:va + vn].copy()
                faces = m.mesh_face[fa:fa + fn].copy()
            out.append(GeomVisual(
                name=mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f'geom_{g}',
                body=int(m.geom_bodyid[g]), type=kind, size=tuple(m.geom_size[g]),
                pos=tuple(m.geom_pos[g]), quat_wxyz=tuple(m.geom_quat[g]), rgba=tuple(rgba),
                mesh_vertices=verts, mesh_faces=faces))
        return tuple(out)

    def _entity_records(self, m: mujoco.MjModel, names: list, root_of: np.ndarray) -> tuple:
        """One record per top-level body; grouped with index arrays (O(n), not O(n^2))."""
        jroot = root_of[m.jnt_bodyid]
        groot = root_of[m.geom_bodyid]
        trn_joint = np.isin(m.actuator_trntype, _JOINT_TRN)
        aroot = np.where(trn_joint, jroot[np.where(trn_joint, m.actuator_trnid[:, 0], 0)], -1) \
            if m.nu else np.zeros(0, int)
        free = int(mujoco.mjtJoint.mjJNT_FREE)
        recs = []
        for root in np.nonzero(m.body_parentid == 0)[0][1:] if m.nbody > 1 else []:
            root = int(root)
            joints = tuple(int(j) for j in np.nonzero(jroot == root)[0])
            acts = tuple(int(a) for a in np.nonzero(aroot == root)[0])
            has_free = any(m.jnt_type[j] == free and m.jnt_bodyid[j] == root for j in joints)
            other_joints = any(m.jnt_type[j] != free for j in joints)
            category = ROBOT if other_joints or acts else DYNAMIC if has_free else STATIC
            name = names[root]
            sp = self._spawned.get(name, {})
            recs.append(EntityRecord(
                name=name, category=category, root_body=root,
                body_ids=tuple(int(b) for b in np.nonzero(root_of == root)[0]),
                joint_ids=joints, geom_ids=tuple(int(g) for g in np.nonzero(groot == root)[0]),
                actuator_ids=acts, spawned=name in self._spawned,
                description=sp.get('description', 'from the scene'),
                namespace=sp.get('namespace', ''), has_free_joint=has_free))
        return tuple(recs)


class _WorldLock:
    """Context manager for the world lock (a class: cheaper than a generator per step)."""

    __slots__ = ('_w', '_counted')

    def __init__(self, world: 'World'):
        self._w = world
        self._counted = False  # written and read only by the thread holding the lock

    def __enter__(self) -> None:
        w = self._w
        if w._lock.acquire(blocking=False):
            self._counted = False  # never waited: nobody needs to step aside for us
            return
        with w._waiting_cv:
            w._waiting += 1
        w._lock.acquire()
        self._counted = True

    def __exit__(self, *exc) -> None:
        w = self._w
        counted = self._counted
        w._lock.release()
        if not counted:
            return
        with w._waiting_cv:
            w._waiting -= 1
            if w._loop_waiting and not w._waiting:
                w._waiting_cv.notify_all()


def _rename_body_references(spec: mujoco.MjSpec, old: str, new: str) -> None:
    """After renaming a body, repoint every element that names it."""
    body_types = (int(mujoco.mjtObj.mjOBJ_BODY), int(mujoco.mjtObj.mjOBJ_XBODY))
    for ex in spec.excludes:
        if ex.bodyname1 == old:
            ex.bodyname1 = new
        if ex.bodyname2 == old:
            ex.bodyname2 = new
    for eq in spec.equalities:
        if int(eq.objtype) in body_types:
            if eq.name1 == old:
                eq.name1 = new
            if eq.name2 == old:
                eq.name2 = new
    for s in spec.sensors:
        if int(s.objtype) in body_types and s.objname == old:
            s.objname = new
        if int(s.reftype) in body_types and s.refname == old:
            s.refname = new
    for a in spec.actuators:
        if a.trntype == mujoco.mjtTrn.mjTRN_BODY and a.target == old:
            a.target = new
    for c in list(spec.cameras) + list(spec.lights):
        if c.targetbody == old:
            c.targetbody = new
