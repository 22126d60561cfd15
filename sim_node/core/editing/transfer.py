"""
The live state carried from one compiled model to another by element names.

What ``MjSpec.recompile`` does, for a model compiled on its own (outside the world lock): every
joint, actuator, body and equality of the new model that the old one has by name gets its
state (positions, velocities, warm start, applied forces, controls, activations, mocap poses,
whether a constraint is active); new ones start from the new model's defaults (a spawned
entity's spawn pose). Every element is named (``editor.name_unnamed``), so names identify them.
"""

from dataclasses import dataclass

import mujoco
import numpy as np

_OBJ = mujoco.mjtObj
_QPOS_SIZE = {int(mujoco.mjtJoint.mjJNT_FREE): 7, int(mujoco.mjtJoint.mjJNT_BALL): 4,
              int(mujoco.mjtJoint.mjJNT_SLIDE): 1, int(mujoco.mjtJoint.mjJNT_HINGE): 1}
_DOF_SIZE = {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3,
             int(mujoco.mjtJoint.mjJNT_SLIDE): 1, int(mujoco.mjtJoint.mjJNT_HINGE): 1}


def _names(m: mujoco.MjModel, obj, n: int) -> dict:
    out = {}
    for i in range(n):
        name = mujoco.mj_id2name(m, obj, i)
        if name:
            out[name] = i
    return out


def _pairs(old: mujoco.MjModel, new: mujoco.MjModel, obj, n_old: int, n_new: int) -> list:
    """Return (old id, new id) of the elements of one kind both models have by name."""
    before = _names(old, obj, n_old)
    return [(before[name], i) for name, i in _names(new, obj, n_new).items() if name in before]


@dataclass(frozen=True)
class Mapping:
    """Where each piece of one model's state goes in another: (source, destination) indices."""

    qpos: tuple
    dof: tuple
    actuators: tuple
    act: tuple
    bodies: tuple
    mocap: tuple
    equalities: tuple
    n_userdata: int


def _pair_arrays(pairs: list) -> tuple:
    src = np.asarray([a for a, _ in pairs], dtype=int)
    dst = np.asarray([b for _, b in pairs], dtype=int)
    return src, dst


def mapping(old: mujoco.MjModel, new: mujoco.MjModel) -> Mapping:
    """Match the elements of two models by name (slow part: name look-ups; no data needed)."""
    qpos_idx, dof_idx = ([], []), ([], [])
    for j0, j1 in _pairs(old, new, _OBJ.mjOBJ_JOINT, old.njnt, new.njnt):
        kind = int(new.jnt_type[j1])
        if kind != int(old.jnt_type[j0]):
            continue
        for (src, dst), adr0, adr1, size in (
                (qpos_idx, old.jnt_qposadr[j0], new.jnt_qposadr[j1], _QPOS_SIZE[kind]),
                (dof_idx, old.jnt_dofadr[j0], new.jnt_dofadr[j1], _DOF_SIZE[kind])):
            src.extend(range(adr0, adr0 + size))
            dst.extend(range(adr1, adr1 + size))
    actuators = _pairs(old, new, _OBJ.mjOBJ_ACTUATOR, old.nu, new.nu)
    act = []
    for a0, a1 in actuators:
        n0, n1 = old.actuator_actnum[a0], new.actuator_actnum[a1]
        if n0 == n1 and n0 > 0:
            s0, s1 = old.actuator_actadr[a0], new.actuator_actadr[a1]
            act.extend(zip(range(s0, s0 + n0), range(s1, s1 + n1)))
    bodies = _pairs(old, new, _OBJ.mjOBJ_BODY, old.nbody, new.nbody)
    mocap = [(old.body_mocapid[b0], new.body_mocapid[b1]) for b0, b1 in bodies
             if old.body_mocapid[b0] >= 0 and new.body_mocapid[b1] >= 0]
    return Mapping(
        qpos=(np.asarray(qpos_idx[0], dtype=int), np.asarray(qpos_idx[1], dtype=int)),
        dof=(np.asarray(dof_idx[0], dtype=int), np.asarray(dof_idx[1], dtype=int)),
        actuators=_pair_arrays(actuators), act=_pair_arrays(act), bodies=_pair_arrays(bodies),
        mocap=_pair_arrays(mocap),
        equalities=_pair_arrays(_pairs(old, new, _OBJ.mjOBJ_EQUALITY, old.neq, new.neq)),
        n_userdata=min(old.nuserdata, new.nuserdata))


def carry(m: Mapping, d_old: mujoco.MjData, d: mujoco.MjData) -> None:
    """Copy `d_old`'s state into `d` (fresh data of the new model) by a :func:`mapping`."""
    d.time = d_old.time
    d.qpos[m.qpos[1]] = d_old.qpos[m.qpos[0]]
    for field in ('qvel', 'qacc_warmstart', 'qfrc_applied'):
        getattr(d, field)[m.dof[1]] = getattr(d_old, field)[m.dof[0]]
    d.ctrl[m.actuators[1]] = d_old.ctrl[m.actuators[0]]
    d.act[m.act[1]] = d_old.act[m.act[0]]
    d.xfrc_applied[m.bodies[1]] = d_old.xfrc_applied[m.bodies[0]]
    d.mocap_pos[m.mocap[1]] = d_old.mocap_pos[m.mocap[0]]
    d.mocap_quat[m.mocap[1]] = d_old.mocap_quat[m.mocap[0]]
    d.eq_active[m.equalities[1]] = d_old.eq_active[m.equalities[0]]
    d.userdata[:m.n_userdata] = d_old.userdata[:m.n_userdata]


def transfer(old: mujoco.MjModel, d_old: mujoco.MjData, new: mujoco.MjModel) -> mujoco.MjData:
    """Return data for `new` holding `d_old`'s state wherever the two models share names."""
    d = mujoco.MjData(new)
    carry(mapping(old, new), d_old, d)
    return d


def same_state(m: mujoco.MjModel, a: mujoco.MjData, b: mujoco.MjData) -> bool:
    """Return True if two datas of one model hold the same integration state (for tests)."""
    spec = int(mujoco.mjtState.mjSTATE_INTEGRATION)
    sa, sb = (np.empty(mujoco.mj_stateSize(m, spec)) for _ in range(2))
    mujoco.mj_getState(m, a, sa, spec)
    mujoco.mj_getState(m, b, sb, spec)
    return bool(np.array_equal(sa, sb))
