"""
Joint commands: staged by any thread, held by joint *name*, bound to one model's addresses.

Commands survive recompiles because they are keyed by name: :meth:`Control.bind` turns the held
ones into arrays of the current :class:`~sim_node.core.compiled.index.ModelIndex` and drops
those whose joint no longer exists, while the others stay in force. The world calls every
method except :meth:`Control.stage` with its lock held.
"""

import threading
from typing import Optional, Sequence

import mujoco
import numpy as np

from . import bases, drives, interfaces
from .actuation import Outputs, times_mass
from .runs import Run, Runs
from .trajectory import INVALID_GOAL, SUCCESSFUL, Tracker
from ..base.checks import check_finite
from ..base.errors import InvalidArgumentError
from ..base.records import EFFORT, MODES, POSITION, VELOCITY
from ..compiled.index import ModelIndex

ERR_MODE = 'unknown command mode {mode!r}; use one of ' + ', '.join(MODES)
ERR_LENGTH = '{what}: {n} names but {m} values'
ERR_GAINS = 'gains must be >= 0, got kp={kp}, kd={kd}'
ERR_CLAIMED = ('joint {name!r} was commanded on joint_commands while the trajectory drove it: '
               'the trajectory gave its joints up (as to a second controller claiming them)')
ERR_PREEMPTED = 'Current goal cancelled due to new incoming action.'
ERR_CANCELED = 'canceled: the joints hold where they were'
ERR_RESET = 'the world was reset: the trajectory ended'
ERR_GONE = 'a joint of the trajectory left the world (its entity was deleted)'


class Control:
    """
    Staged and held joint commands and the PD law for joints without a matching actuator.

    Position and velocity commands use the joint's actuator of that kind if it has one (its
    ctrl is set once), otherwise PD torques recomputed before every step, in computed-torque
    form: ``M(q) (a* + kp (q* - q) + kd (v* - v)) + bias``, so the gains mean the same on a
    50 g finger and a 20 kg arm (kp = w^2, kd = 2 w). The torque goes through the joint's
    motor actuator where it has one, within that motor's ctrlrange and forcerange (what the
    robot's file says its motor can give), else through ``qfrc_applied`` (unlimited). Effort
    commands use a motor actuator or ``qfrc_applied`` directly.
    """

    def __init__(self, kp: float, kd: float):
        self._stage_lock = threading.Lock()
        self._staged: dict = {}  # joint name -> (mode, value), written by any thread
        self._held: dict = {}  # joint name -> (mode, value), PD/effort, held until replaced
        self.kp, self.kd = float(kp), float(kd)
        self._pd_out = Outputs.empty()  # where the current binding's PD torques go
        self._bound_index: Optional[ModelIndex] = None  # the index of the current binding
        self.per_step = False  # True when PD torques or servo targets change every step
        self.runs = Runs()  # trajectories being followed
        self.drives = drives.Drives()  # mobile bases driven
        self.servos = interfaces.Servos()  # gz_ros2_control robots' position servos

    # ---------------------------------------------------------------- any thread

    def stage(self, index: ModelIndex, names: Sequence[str], values: Sequence[float],
              mode: str) -> None:
        """
        Validate and stage commands; the world's next step applies them.

        :raises NotFoundError: an unknown joint; nothing is staged.
        :raises InvalidArgumentError: a non-finite value, a length mismatch or a bad mode.
        """
        if mode not in MODES:
            raise InvalidArgumentError(ERR_MODE.format(mode=mode))
        names = list(names)
        if len(names) != len(values):
            raise InvalidArgumentError(ERR_LENGTH.format(what='joint command', n=len(names),
                                                         m=len(values)))
        vals = check_finite(f'{mode} commands', values)
        index.joints(names)
        with self._stage_lock:
            for n, v in zip(names, vals):
                self._staged[n] = (mode, float(v))

    def held_copy(self) -> dict:
        """Return a copy of the held commands, for :meth:`restore_held`."""
        return dict(self._held)

    def restore_held(self, held: dict) -> None:
        """Put back held commands saved by :meth:`held_copy` (before the next :meth:`bind`)."""
        self._held = dict(held)

    @property
    def has_staged(self) -> bool:
        return bool(self._staged)  # read without the lock: a miss is applied next batch

    # ---------------------------------------------------------------- world lock held

    def set_gains(self, kp: float, kd: float, index: ModelIndex, model: mujoco.MjModel,
                  data: mujoco.MjData) -> None:
        kp_v, kd_v = check_finite('gains', [kp, kd], 2)
        if kp_v < 0 or kd_v < 0:
            raise InvalidArgumentError(ERR_GAINS.format(kp=kp, kd=kd))
        self.kp, self.kd = float(kp_v), float(kd_v)
        self.bind(index, model, data)

    def apply_staged(self, index: ModelIndex, model: mujoco.MjModel,
                     data: mujoco.MjData) -> None:
        with self._stage_lock:
            staged, self._staged = self._staged, {}
        ctrl = {}  # actuator -> value, written once the old binding let go of its outputs
        # A binding is remade only when what it is made of changed: a held command, a run
        # ended, another index. Commands to actuators alone (a controller's law writing its
        # wheels' speeds at every update) change none of it: remaking it cost 0.1 ms a time.
        changed = index is not self._bound_index
        for name, (mode, value) in staged.items():
            i = index.joint_index.get(name)
            if i is None:
                continue  # the joint was deleted after the command was staged
            for run in self.runs.claiming(name):
                self._end_run(run, INVALID_GOAL, ERR_CLAIMED.format(name=name), data,
                              hold=False)
                changed = True
            changed = self.servos.command(name, mode) or changed
            act = index.joint_actuators[i].get(mode)
            if act is not None:
                ctrl[act] = value
                changed = self._held.pop(name, None) is not None or changed
            elif self._held.get(name) != (mode, value):
                self._held[name] = (mode, value)
                changed = True
        if changed:
            self.bind(index, model, data)
        for act, value in ctrl.items():
            data.ctrl[act] = value

    def clear(self, index: ModelIndex, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Drop every staged and held command (PD torques stop; actuators keep their ctrl)."""
        with self._stage_lock:
            self._staged.clear()
        self._held.clear()
        for run in self.runs.every():
            self._end_run(run, INVALID_GOAL, ERR_RESET, data, hold=False)
        self.drives.stop_all()  # bases stop
        self.bind(index, model, data)
        self.servos.settle(model, data)  # the holding servos hold where the joints are now

    def bind(self, index: ModelIndex, model: mujoco.MjModel, data: mujoco.MjData,
             new_model: bool = False) -> None:
        """
        Turn the held commands into arrays of `index`.

        Commands for joints it does not have are dropped.

        :param new_model: `data` belongs to a model just recompiled: the previous binding's
            addresses mean nothing in it (recompile already carried its applied forces over).
        """
        if not new_model:
            self._pd_out.release(data)
        self._bound_index = index
        self._held = {n: c for n, c in self._held.items() if n in index.joint_index}
        items = [(index.joint_index[n], mode, v) for n, (mode, v) in self._held.items()]
        acts = index.joint_actuators
        # A velocity or effort command on a joint that only has a position servo: the servo's
        # target moves at the commanded velocity, or follows the joint (so the servo only
        # damps) while the effort goes through qfrc_applied.
        servo = [(acts[i][POSITION], i, mode, v) for i, mode, v in items
                 if mode in (VELOCITY, EFFORT) and POSITION in acts[i]]
        self._servo_act = np.array([a for a, _, _, _ in servo], dtype=int)
        self._servo_qpos = index.joint_qposadr[[i for _, i, _, _ in servo]].astype(int)
        self._servo_rate = np.array([v if mode == VELOCITY else np.nan
                                     for _, _, mode, v in servo], dtype=float)
        self._servo_range = model.actuator_ctrlrange[self._servo_act]
        self._servo_limited = model.actuator_ctrllimited[self._servo_act].astype(bool)
        items = [(i, mode, v) for i, mode, v in items
                 if not (mode == VELOCITY and POSITION in acts[i])]
        idx = np.array([i for i, _, _ in items], dtype=int)
        modes = [mode for _, mode, _ in items]
        target = np.array([v for _, _, v in items], dtype=float)
        is_pos = np.array([m == POSITION for m in modes], dtype=bool)
        is_eff = np.array([m == EFFORT for m in modes], dtype=bool)
        # Effort commands reach here only for joints without a motor: qfrc_applied.
        self._pd_out = Outputs(index, model, idx, motors=~is_eff)
        self._pd_qpos = index.joint_qposadr[idx]
        self._pd_is_pos = is_pos
        self._pd_pos_target = np.where(is_pos, target, 0.0)
        self._pd_vel_target = np.where([m == VELOCITY for m in modes], target, 0.0)
        self._pd_effort = np.where(is_eff, target, 0.0)
        self._pd_kp = np.where(is_pos, self.kp, 0.0)
        self._pd_kd = np.where(is_eff, 0.0, self.kd)
        self._pd_is_eff = is_eff
        for run in self.runs.every():
            if not run.bind(index, model):
                # Its addresses were the old model's: in `data` they are other joints' and
                # actuators' now (or out of range). Its joints are gone; nothing to hold.
                run.qadr = None
                self._end_run(run, INVALID_GOAL, ERR_GONE, data, hold=False, rebind=False)
        self.drives.bind(index, model)
        self.servos.apply(model)
        self._update_per_step()

    def _update_per_step(self) -> None:
        self.per_step = bool(len(self._pd_out) or len(self._servo_act) or self.runs
                             or self.drives.driving)

    # ---------------------------------------------------------------- mobile bases

    def command_base(self, spec: bases.BaseSpec, vx: float, vy: float, wz: float,
                     timeout: float, index: ModelIndex, model: mujoco.MjModel,
                     data: mujoco.MjData) -> bool:
        """
        Drive a base at (vx, vy, wz) in its frame from now (see :mod:`.drives`).

        :returns: whether controls changed (the same command again changes none).
        """
        changed = self.drives.command(spec, vx, vy, wz, timeout, index, model, data, self.kd)
        self._update_per_step()
        return changed

    @property
    def batched(self) -> bool:
        return self.drives.batched

    def before_batch(self, model: mujoco.MjModel, data: mujoco.MjData) -> bool:
        """
        Between batches of steps: the drives held by velocity actuators (their timeout).

        :returns: whether a control changed (a base stopped).
        """
        changed = self.drives.before_batch(model, data, self.kd)
        self._update_per_step()
        return changed

    def batch_deadline(self, now: float) -> float:
        """Return the earliest simulated time after `now` at which a batched base times out."""
        return self.drives.deadline(now)

    def drive_of(self, entity: str) -> Optional[drives.Drive]:
        return self.drives.of(entity)

    # ---------------------------------------------------------------- trajectories

    def start_run(self, entity: str, tracker: Tracker, index: ModelIndex,
                  model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """
        Follow a trajectory on an entity's joints from the next step on.

        It takes its joints from held commands and from a trajectory already running on the
        entity, which ends canceled (a new goal preempts the old one, as the controller does).
        """
        old = self.runs.of(entity)
        if old is not None:
            self._end_run(old, INVALID_GOAL, ERR_PREEMPTED, data, hold=False, canceled=True,
                          rebind=False)
        joints = tracker.trajectory.joints
        self.servos.engage(joints)
        self._held = {n: c for n, c in self._held.items() if n not in joints}
        self.runs.add(Run(entity, tracker))
        self.bind(index, model, data)

    def cancel_run(self, entity: str, run: Run, data: mujoco.MjData,
                   index: ModelIndex, model: mujoco.MjModel) -> None:
        """End a running trajectory as canceled: its joints hold where they are now."""
        if self.runs.of(entity) is run:
            self._end_run(run, SUCCESSFUL, ERR_CANCELED, data, hold=False, canceled=True,
                          rebind=False)
            self.bind(index, model, data)

    def run_of(self, entity: str) -> Optional[Run]:
        return self.runs.of(entity)

    def commanded(self, entity: str, names: Sequence[str], index: ModelIndex,
                  data: mujoco.MjData) -> tuple:
        """
        Return the positions and velocities last commanded to joints, (n,) each.

        For each joint: a position staged for the next step, else the running trajectory's
        target now, else a held position, else its position servo's target; a joint given no
        position is where it is now (joint_trajectory_controller's ``open_loop_control``
        starts a new trajectory from these).
        """
        idx = index.joints(names)
        q = data.qpos[index.joint_qposadr[idx]].astype(float)
        v = np.zeros(len(idx))
        run = self.runs.of(entity)
        desired = run.tracker.status.desired if run is not None else None
        ran = list(run.tracker.trajectory.joints) if desired else []
        with self._stage_lock:
            staged = dict(self._staged)
        for k, (name, i) in enumerate(zip(names, idx)):
            servo = index.joint_actuators[i].get(POSITION)
            if staged.get(name, ('',))[0] == POSITION:
                q[k] = staged[name][1]
            elif name in ran:
                q[k], v[k] = desired[0][ran.index(name)], desired[1][ran.index(name)]
            elif self._held.get(name, ('',))[0] == POSITION:
                q[k] = self._held[name][1]
            elif servo is not None:
                q[k] = data.ctrl[servo]
        return q, v

    def _end_run(self, run: Run, code: int, message: str, data: mujoco.MjData,
                 hold: bool, canceled: bool = False, rebind: bool = True) -> None:
        """
        Take a trajectory off its joints; they hold a position from the next step on.

        :param hold: hold the trajectory's last point (it succeeded); else where they are.
        """
        self._hold(self.runs.end(run, code, message, data, hold, canceled))
        if rebind and run.index is not None:
            self.bind(run.index, run.model, data)

    def _hold(self, holds: dict) -> None:
        """Hold PD joints a trajectory let go of where it left them (unless commanded since)."""
        for name, q in holds.items():
            self._held.setdefault(name, (POSITION, q))

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Before one step: PD torques and moving servo targets from the current state."""
        if self.runs:
            for run, holds in self.runs.drive(model, data, self.kp, self.kd):
                self._hold(holds)
                self.bind(run.index, run.model, data)
        if self.drives.driving:
            self.drives.every_step(model, data, self.kd)
            if not self.drives.driving:
                self._update_per_step()
        out = self._pd_out
        if len(out):
            q = data.qpos[self._pd_qpos]
            v = data.qvel[out.dof]
            err = np.where(self._pd_is_pos, self._pd_pos_target - q, 0.0)
            u = self._pd_kp * err + self._pd_kd * (self._pd_vel_target - v)
            tau = times_mass(model, data, out.dof, u) + data.qfrc_bias[out.dof]
            out.write(data, np.where(self._pd_is_eff, self._pd_effort, tau))
        if len(self._servo_act):
            follow = np.isnan(self._servo_rate)
            target = np.where(follow, data.qpos[self._servo_qpos],
                              data.ctrl[self._servo_act] + np.nan_to_num(self._servo_rate)
                              * model.opt.timestep)
            lo, hi = self._servo_range[:, 0], self._servo_range[:, 1]
            data.ctrl[self._servo_act] = np.where(self._servo_limited,
                                                  np.clip(target, lo, hi), target)
