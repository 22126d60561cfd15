"""
Joint torques from Python: through a joint's motor within its limits, or ``qfrc_applied``.

Shared by the joint commands and trajectories (:mod:`.commands`) and the mobile bases
(:mod:`.bases`); called with the world lock held, before a step.
"""

from typing import Optional

import mujoco
import numpy as np

from ..base.records import EFFORT
from ..compiled.index import ModelIndex

NONE_INT = np.zeros(0, int)


def times_mass(model: mujoco.MjModel, data: mujoco.MjData, dof: np.ndarray,
               u: np.ndarray) -> np.ndarray:
    """Return (M(q) x)[dof] for x = `u` on `dof` and 0 elsewhere (the last step's M)."""
    x = np.zeros(model.nv)
    x[dof] = u
    out = np.empty(model.nv)
    mujoco.mj_mulM(model, data, out, x)
    return out[dof]


class Outputs:
    """
    Where the PD torques of some joints go: each joint's motor actuator, or qfrc_applied.

    A motor (a single-joint actuator without bias or dynamics, of fixed gain) takes
    ``ctrl = torque / (gain * gear)`` within its ctrlrange and forcerange; a joint without
    one takes the torque through ``qfrc_applied``, unlimited.
    """

    def __init__(self, index: ModelIndex, model: mujoco.MjModel, idx: np.ndarray,
                 motors: Optional[np.ndarray] = None):
        self.dof = index.joint_dofadr[idx].astype(int)
        act = np.array([index.joint_actuators[i].get(EFFORT, -1) for i in idx], dtype=int)
        if motors is not None:
            act = np.where(motors, act, -1)
        n = len(act)
        self.scale, self.lo, self.hi = np.ones(n), np.full(n, -np.inf), np.full(n, np.inf)
        for k in np.nonzero(act >= 0)[0]:
            a = act[k]
            gear = model.actuator_gear[a, 0]
            scale = model.actuator_gainprm[a, 0] * gear
            if model.actuator_gaintype[a] != mujoco.mjtGain.mjGAIN_FIXED or scale == 0:
                act[k] = -1
                continue
            # The joint torques the motor can give: ctrlrange times gain and gear, forcerange
            # times gear, whichever is narrower.
            lo, hi = -np.inf, np.inf
            if model.actuator_ctrllimited[a]:
                lo, hi = sorted(model.actuator_ctrlrange[a] * scale)
            if model.actuator_forcelimited[a]:
                f_lo, f_hi = sorted(model.actuator_forcerange[a] * gear)
                lo, hi = max(lo, f_lo), min(hi, f_hi)
            self.scale[k], self.lo[k], self.hi[k] = scale, lo, hi
        self.act, self.motor = act, act >= 0

    @classmethod
    def empty(cls) -> 'Outputs':
        out = cls.__new__(cls)
        out.dof = out.act = NONE_INT
        out.scale = out.lo = out.hi = np.zeros(0)
        out.motor = np.zeros(0, bool)
        return out

    def __len__(self) -> int:
        return len(self.dof)

    def write(self, data: mujoco.MjData, tau: np.ndarray) -> np.ndarray:
        """Apply joint torques `tau`; return which joints' motors are at their limit."""
        given = np.clip(tau, self.lo, self.hi)
        m = self.motor
        data.qfrc_applied[self.dof[~m]] = given[~m]
        data.ctrl[self.act[m]] = given[m] / self.scale[m]
        return given != tau

    def release(self, data: mujoco.MjData) -> None:
        """Stop every torque this binding wrote."""
        m = self.motor
        data.qfrc_applied[self.dof[~m]] = 0
        data.ctrl[self.act[m]] = 0
