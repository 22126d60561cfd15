"""
Reading and writing the state of one (model, data).

Snapshots, entity states, free-body writes, bounds, and the kinematic step. Plain functions; the
world calls them with its lock held and derived quantities up to date (see
``World._kinematics_locked``).
"""

from typing import Callable, Optional

import mujoco
import numpy as np

from .index import ModelIndex
from ..base import quat
from ..base.records import EntityRecord, EntityState, Snapshot

_XBODY = int(mujoco.mjtObj.mjOBJ_XBODY)  # a body's own frame (mjOBJ_BODY: its centre of mass)
_NO_GRAVITY = int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
_PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)


#: mj_getState's parts that are plain MjData arrays, by state bit (mjtState), in its order.
_STATE_ARRAYS = {
    int(mujoco.mjtState.mjSTATE_QPOS): 'qpos', int(mujoco.mjtState.mjSTATE_QVEL): 'qvel',
    int(mujoco.mjtState.mjSTATE_ACT): 'act',
    int(mujoco.mjtState.mjSTATE_WARMSTART): 'qacc_warmstart',
    int(mujoco.mjtState.mjSTATE_CTRL): 'ctrl',
    int(mujoco.mjtState.mjSTATE_QFRC_APPLIED): 'qfrc_applied',
    int(mujoco.mjtState.mjSTATE_XFRC_APPLIED): 'xfrc_applied',
    int(mujoco.mjtState.mjSTATE_EQ_ACTIVE): 'eq_active',
    int(mujoco.mjtState.mjSTATE_MOCAP_POS): 'mocap_pos',
    int(mujoco.mjtState.mjSTATE_MOCAP_QUAT): 'mocap_quat',
    int(mujoco.mjtState.mjSTATE_USERDATA): 'userdata',
}
_TIME = int(mujoco.mjtState.mjSTATE_TIME)


def state_copier(model: mujoco.MjModel, data: mujoco.MjData,
                 spec: int) -> Optional[Callable[[np.ndarray], None]]:
    """
    Return ``copy(out)``: ``mj_getState(model, data, out, spec)`` done with numpy, or None.

    The same values in the same order, without a MuJoCo call: every MuJoCo call releases the
    GIL, and getting it back took up to a switch interval (5 ms) each while other threads ran
    Python (the node's loop under a storm of edits). None when a part of the state is not a
    plain array of `data` (history, plugin or plasticity state): use ``mj_getState`` then.

    Made with one MuJoCo call (the whole state's size): each part's size is its array's, and
    a part of another kind is there if they fall short of the whole. A new model's commit
    makes one with the world lock held (it asked MuJoCo part by part before: 16 calls, each
    a wait for the GIL back under a storm of spawns).
    """
    parts, offset = [], 0
    for i in range(int(mujoco.mjtState.mjNSTATE)):
        bit = 1 << i
        if not spec & bit or (bit != _TIME and bit not in _STATE_ARRAYS):
            continue
        if bit == _TIME:
            parts.append((offset, None))
            offset += 1
            continue
        array = getattr(data, _STATE_ARRAYS[bit]).reshape(-1)  # a view: (nbody, 6) etc.
        if array.size:
            parts.append((offset, array))
            offset += array.size
    if offset != mujoco.mj_stateSize(model, spec):
        return None  # a part that is no array of the data's (or not this layout)
    spans = [(a, a + (1 if array is None else array.size), array) for a, array in parts]

    def copy(out: np.ndarray) -> None:
        for a, b, array in spans:
            out[a:b] = data.time if array is None else array
    return copy


def snapshot(data: mujoco.MjData, index: ModelIndex, step: int, seq: int) -> Snapshot:
    """Return an immutable copy of what publishers need (body poses, joint states)."""
    dof = index.joint_dofadr
    return Snapshot(generation=index.generation, step=step, time=float(data.time),
                    joint_position=data.qpos[index.joint_qposadr],
                    joint_velocity=data.qvel[dof],
                    joint_effort=data.qfrc_actuator[dof] + data.qfrc_applied[dof],
                    body_xpos=data.xpos.copy(), body_xquat_wxyz=data.xquat.copy(), seq=seq,
                    info=index.info, sensordata=data.sensordata.copy())


def entity_state(model: mujoco.MjModel, data: mujoco.MjData, rec: EntityRecord,
                 frame: Optional[tuple] = None) -> EntityState:
    """
    Pose, twist and acceleration of an entity's root body origin.

    In the world frame or in `frame` = (position (3,), quat_wxyz (4,)). Needs velocities and
    accelerations up to date.

    Twist and acceleration are those of the body's origin (the point its pose gives), not of
    its centre of mass, so what :func:`write_free_body` writes reads back unchanged.
    """
    b = rec.root_body
    vel, acc = np.zeros(6), np.zeros(6)
    mujoco.mj_objectVelocity(model, data, _XBODY, b, vel, 0)
    mujoco.mj_objectAcceleration(model, data, _XBODY, b, acc, 0)
    pos, q = data.xpos[b].copy(), data.xquat[b].copy()
    ang, lin, ang_acc, lin_acc = vel[:3], vel[3:], acc[:3], acc[3:]
    if not model.opt.disableflags & _NO_GRAVITY:
        # MuJoCo's is an accelerometer's (gravity shows as +g at rest): make it the
        # coordinate acceleration.
        lin_acc = lin_acc + model.opt.gravity
    if frame is not None:
        fpos, fquat = frame
        pos, q = quat.to_frame(fpos, fquat, pos, q)
        inv = quat.conj(fquat)
        ang, lin, ang_acc, lin_acc = (quat.rotate(inv, v) for v in (ang, lin, ang_acc, lin_acc))
    return EntityState(position=pos, quat_wxyz=q, linear_velocity=np.array(lin),
                       angular_velocity=np.array(ang), time=float(data.time),
                       linear_acceleration=np.array(lin_acc),
                       angular_acceleration=np.array(ang_acc))


def body_pose(data: mujoco.MjData, body: int) -> tuple:
    """(position (3,), quat_wxyz (4,)) of a body in the world, copied."""
    return data.xpos[body].copy(), data.xquat[body].copy()


def write_free_body(model: mujoco.MjModel, data: mujoco.MjData, rec: EntityRecord,
                    pos: Optional[np.ndarray], q: Optional[np.ndarray],
                    lin: Optional[np.ndarray], ang: Optional[np.ndarray]) -> None:
    """Write checked world-frame values (None: keep) into an entity's free joint."""
    jnt = model.body_jntadr[rec.root_body]
    qadr, dadr = model.jnt_qposadr[jnt], model.jnt_dofadr[jnt]
    if pos is not None:
        data.qpos[qadr:qadr + 3] = pos
        data.qpos[qadr + 3:qadr + 7] = q
    if lin is not None:
        data.qvel[dadr:dadr + 3] = lin
    if ang is not None:
        # A free joint's angular velocity is in the body frame.
        data.qvel[dadr + 3:dadr + 6] = quat.rotate(quat.conj(data.qpos[qadr + 3:qadr + 7]),
                                                   ang)


def bounds(model: mujoco.MjModel, data: mujoco.MjData, rec: EntityRecord,
           local: bool = False) -> tuple:
    """
    Axis-aligned bounds of an entity's geoms (infinite planes left out).

    In the world frame, or with `local` in the root body's frame (the entity's canonical
    link frame, where GetEntityBounds gives them: they do not change as the entity moves).
    (min (3,), max (3,)); the root body's position (or origin) twice when it has no such geom.
    """
    root = rec.root_body
    frame_rot = data.xmat[root].reshape(3, 3) if local else np.eye(3)
    frame_pos = data.xpos[root] if local else np.zeros(3)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for g in rec.geom_ids:
        if model.geom_type[g] == _PLANE:
            continue
        rot = frame_rot.T @ data.geom_xmat[g].reshape(3, 3)
        c = frame_rot.T @ (data.geom_xpos[g] - frame_pos) + rot @ model.geom_aabb[g, :3]
        ext = np.abs(rot) @ model.geom_aabb[g, 3:]
        lo, hi = np.minimum(lo, c - ext), np.maximum(hi, c + ext)
    if not np.all(np.isfinite(lo)):
        pos = np.zeros(3) if local else data.xpos[root].copy()
        return pos, pos
    return lo, hi


def kinematic_step(model: mujoco.MjModel, data: mujoco.MjData, qposadr: np.ndarray,
                   dofadr: np.ndarray, targets: np.ndarray) -> None:
    """
    One step with no physics.

    Time advances by the timestep, the joints at `qposadr` take `targets` exactly and their
    velocities are the change over the step, every other velocity is zero and nothing else moves
    (no gravity, contacts or actuators). Body poses and the sensors that depend on positions and
    velocities are recomputed.
    """
    dt = model.opt.timestep
    change = targets - data.qpos[qposadr]
    data.qvel[:] = 0
    data.qvel[dofadr] = change / dt
    data.qpos[qposadr] = targets
    data.time += dt
    mujoco.mj_fwdPosition(model, data)
    mujoco.mj_sensorPos(model, data)
    mujoco.mj_fwdVelocity(model, data)
    mujoco.mj_sensorVel(model, data)
