"""
Trajectories being followed: each entity's run, driven before every step (world lock held).

:class:`Runs` is the world's set, one per entity (a new one preempts): :meth:`Runs.drive` writes
each run's targets for the coming step (its joints' position servos, velocity interfaces with a
correction toward the target, or computed-torque PD through :class:`~.actuation.Outputs`) and
judges it (:class:`~.trajectory.Tracker`); :meth:`Runs.end` takes a run off its joints and says
where its PD joints are to be held. The joint commands (:class:`~.commands.Control`) own the
held commands and the binding to a model; they hold what :meth:`Runs.end` returns.
"""

import math
import threading
from typing import Optional

import mujoco
import numpy as np

from .actuation import Outputs, times_mass
from .trajectory import SUCCESSFUL, Tracker
from ..base.records import POSITION, VELOCITY
from ..compiled.index import ModelIndex


class Run:
    """A trajectory being followed, bound to one model's addresses (world lock held)."""

    def __init__(self, entity: str, tracker: Tracker):
        self.entity, self.tracker = entity, tracker
        self.done = threading.Event()
        self.qadr = self.dof = self.act = self.vact = self.vgear = self.out = None
        self.index = self.model = None
        self.steps = 0
        self.saturated = None  # per PD joint: steps its motor spent at its limit

    def count(self, at_limit: np.ndarray) -> None:
        self.steps += 1
        if self.saturated is None or len(self.saturated) != len(at_limit):
            self.saturated = np.zeros(len(at_limit), int)
        self.saturated += at_limit

    def saturation_note(self) -> str:
        """Which motors spent much of the run at their limit ('' if none did)."""
        if self.saturated is None or not self.steps or self.out is None:
            return ''
        names = [n for n, a, va in zip(self.tracker.trajectory.joints, self.act, self.vact)
                 if a < 0 and va < 0]
        notes = [f'{names[k]!r} ({self.saturated[k] / self.steps:.0%} of the steps at '
                 f'{max(abs(self.out.lo[k]), abs(self.out.hi[k])):.4g} N·m or N)'
                 for k in np.nonzero(self.saturated > self.steps // 10)[0]]
        if not notes:
            return ''
        return ('; the motors of ' + ', '.join(notes) + ' were at the limit their file gives '
                'them: the trajectory asks more than the actuators can give')

    def bind(self, index: ModelIndex, model: mujoco.MjModel) -> bool:
        """Take the addresses of its joints in `index`; False if one is gone."""
        joints = self.tracker.trajectory.joints
        if any(n not in index.joint_index for n in joints):
            return False
        idx = np.array([index.joint_index[n] for n in joints], dtype=int)
        self.qadr, self.dof = index.joint_qposadr[idx], index.joint_dofadr[idx]
        self.act = np.array([index.joint_actuators[i].get(POSITION, -1) for i in idx],
                            dtype=int)
        self.vact = np.array([index.joint_actuators[i].get(VELOCITY, -1) if a < 0 else -1
                              for i, a in zip(idx, self.act)], dtype=int)
        v = np.maximum(self.vact[self.vact >= 0], 0)
        self.vgear = model.actuator_gear[v, 0] if len(v) else np.zeros(0)
        self.out = Outputs(index, model, idx[(self.act < 0) & (self.vact < 0)])
        self.index, self.model = index, model
        return True


class Runs:
    """The trajectories being followed, by entity (see the module docstring)."""

    def __init__(self):
        self._runs: dict = {}  # entity -> Run

    def __bool__(self) -> bool:
        return bool(self._runs)

    def of(self, entity: str) -> Optional[Run]:
        return self._runs.get(entity)

    def every(self) -> list:
        return list(self._runs.values())

    def add(self, run: Run) -> None:
        self._runs[run.entity] = run

    def claiming(self, joint: str) -> list:
        """Return the runs that drive `joint`."""
        return [r for r in self._runs.values() if joint in r.tracker.trajectory.joints]

    def end(self, run: Run, code: int, message: str, data: mujoco.MjData, hold: bool,
            canceled: bool = False) -> dict:
        """
        Take a trajectory off its joints; return where its PD joints are to be held.

        :param hold: hold the trajectory's last point (it succeeded); else where they are.
        :returns: joint name -> position, for the joints without a position servo (a servo
            just keeps its target; a velocity interface stops).
        """
        if self._runs.get(run.entity) is run:
            del self._runs[run.entity]
        tracker = run.tracker
        if tracker.status.code is None:
            tracker.status.code, tracker.status.message = code, message
        tracker.status.canceled = canceled
        holds = {}
        if run.qadr is not None:
            run.out.release(data)
            where = np.array(tracker.trajectory.positions[-1] if hold
                             else data.qpos[run.qadr], dtype=float)
            for name, q, act in zip(tracker.trajectory.joints, where, run.act):
                if act < 0:
                    holds[name] = float(q)
            acts = run.act >= 0
            data.ctrl[run.act[acts]] = where[acts]
            data.ctrl[run.vact[run.vact >= 0]] = 0  # velocity interfaces stop; PD holds
        run.done.set()
        return holds

    def drive(self, model: mujoco.MjModel, data: mujoco.MjData, kp: float,
              kd: float) -> list:
        """
        Before one step: every trajectory's targets at this time, and its judgement.

        :returns: (run, holds) of each run that ended (:meth:`end`'s holds).
        """
        t = data.time
        ended = []
        for run in list(self._runs.values()):
            q, v = data.qpos[run.qadr], data.qvel[run.dof]
            status = run.tracker.status
            status.effort = data.qfrc_actuator[run.dof] + data.qfrc_applied[run.dof]
            code = run.tracker.judge(t, q, v)
            if code is not None:
                if code != SUCCESSFUL:
                    status.message += run.saturation_note()
                ended.append((run, self.end(run, code, status.message, data,
                                            hold=code == SUCCESSFUL)))
                continue
            qd, vd, ad = status.desired
            servo = run.act >= 0
            data.ctrl[run.act[servo]] = qd[servo]
            vel = run.vact >= 0  # a velocity interface: its velocity, corrected toward q*
            if vel.any():
                want = run.vgear * (vd[vel] + math.sqrt(kp) * (qd[vel] - q[vel]))
                lo, hi = model.actuator_ctrlrange[run.vact[vel]].T
                limited = model.actuator_ctrllimited[run.vact[vel]].astype(bool)
                data.ctrl[run.vact[vel]] = np.where(limited, np.clip(want, lo, hi), want)
            pd = ~servo & ~vel
            if pd.any():
                u = ad[pd] + kp * (qd[pd] - q[pd]) + kd * (vd[pd] - v[pd])
                tau = times_mass(model, data, run.out.dof, u) + data.qfrc_bias[run.out.dof]
                run.count(run.out.write(data, tau))
        return ended
