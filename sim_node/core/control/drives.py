"""
Driving a mobile base: a velocity command in the base's frame held by its wheels or joints.

A :class:`Drive` turns a command ``(vx, vy, wz)`` (:class:`Command`, checked by
:func:`check_command`) into wheel speeds (``v -+ wz s / 2`` over ``r``), joint velocities of
the planar joints, or the floating root's velocity (planar move, as Gazebo's plugin sets it),
for a base :mod:`.bases` found. Wheels and planar joints go through their velocity actuators
(``ctrl = gear * speed``, within ``ctrlrange``) where they have one, else a velocity loop
``M (kd (w* - w)) + bias`` through their motor (within its limits) or ``qfrc_applied``. The
command itself is a target for the base's own motion: a tracking loop (:meth:`Drive._track`,
every :data:`TRACK_PERIOD` of simulated time) adds what casters, slip and friction loss take,
within :data:`TRACK_LIMIT` times the command. Wheel speed and acceleration are limited; no
command for :data:`COMMAND_TIMEOUT` simulated seconds stops the base, as
diff_drive_controller does, on time even inside a batch of steps. It is physics: the base
pushes, slips and stops at walls. :class:`Drives` is the world's set of driven bases, each
filed by what it needs next (every step, or a look between batches for its timeout). ROS-free;
the world lock is held around every call.
"""

from dataclasses import dataclass
import math
from typing import Optional

import mujoco
import numpy as np

from .bases import BaseSpec, DIFF_DRIVE, PLANAR_FREE
from ..base import quat
from ..base.errors import InvalidArgumentError

_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
#: Seconds of simulated time without a command after which a base stops.
COMMAND_TIMEOUT = 0.5
#: What a drive needs after a step (see :meth:`Drive.apply`).
EVERY_STEP, EVERY_BATCH = 'step', 'batch'
#: The tracking loop (:meth:`Drive._track`): integral gain (1/s), the most it adds (times the
#: command, axis by axis: an axis commanded 0 gets nothing), the longest interval it
#: integrates at once (s).
TRACK_GAIN, TRACK_LIMIT, TRACK_DT_MAX = 8.0, 10.0, 0.05
#: Simulated seconds between two runs of a base's tracking loop (20 Hz: it only trims what the
#: velocity actuators hold, every step, in MuJoCo).
TRACK_PERIOD = 0.05
#: The largest command taken (m/s, rad/s): beyond is no base's, and would blow the physics up.
MAX_SPEED, MAX_TURN = 50.0, 50.0
NOTE_SIDEWAYS = ('{entity!r} is a differential drive: it cannot move sideways, so vy={vy:g} '
                 'is ignored')
NOTE_BEYOND = ('{entity!r} cannot move as commanded: it needs more than its actuators give '
               '(their control range, or more than the tracking loop adds); it moves as far '
               'as they take it')
ERR_COMMAND = ('a base command must be finite, |linear| <= {speed:g} m/s and |angular| <= '
               '{turn:g} rad/s; got vx={vx}, vy={vy}, wz={wz}')


class Drive:
    """
    One base's controller, bound to one model's addresses (world lock held, before each step).

    :param kd: the velocity loop's gain per unit of joint inertia (1/s), for joints without a
        velocity actuator.
    """

    def __init__(self, spec: BaseSpec):
        self.spec = spec
        self.command = Command()
        self.speeds = np.zeros(len(spec.wheels) if spec.kind == DIFF_DRIVE else 3)
        self.integral: Optional[np.ndarray] = None  # the velocity loops' integral terms
        self.changed = True  # the last apply wrote controls other than those in force
        self._index = None
        #: The tracking loop's correction of the command (vx, vy, wz) (see :meth:`_track`).
        self.trim = [0.0, 0.0, 0.0]
        #: Whether the last command needed more than the model's actuators give.
        self.saturated = False
        self._seen: Optional[float] = None
        self._fresh = False  # whether its command was in force at the last apply

    def due(self, now: float) -> bool:
        """
        Whether it needs an :meth:`apply` between batches at simulated time `now`.

        Its velocity actuators hold the speeds meanwhile: it is due when its command times
        out, and every :data:`TRACK_PERIOD` for the tracking loop (a controller's update rate),
        not before every batch (two bases cost the loop 17% of its speed that way).
        """
        cmd = self.command
        fresh = cmd.timeout <= 0 or now - cmd.time <= cmd.timeout
        return fresh != self._fresh or (fresh and (
            self._seen is None or now - self._seen >= TRACK_PERIOD))

    def bind(self, index, model: mujoco.MjModel) -> bool:
        """Take the addresses of its joints in `index`; False if one is gone."""
        from .actuation import Outputs
        from ..base.records import VELOCITY
        names = self.spec.wheels if self.spec.kind == DIFF_DRIVE else self.spec.planar
        if self.spec.kind == PLANAR_FREE:
            root = index.entity_by_name.get(self.spec.entity)
            if root is None or not model.body_jntnum[root.root_body]:
                return False
            j = model.body_jntadr[root.root_body]
            if int(model.jnt_type[j]) != _FREE:
                return False
            self.free_dof = int(model.jnt_dofadr[j])
            self._index = index
            return True
        if any(n not in index.joint_index for n in names):
            return False
        idx = np.array([index.joint_index[n] for n in names], dtype=int)
        self.dof = index.joint_dofadr[idx]
        self.jids = index.joint_ids[idx]
        # the body whose motion is the base's: the wheels' parent, the planar hinge's body
        self.body = int(model.body_parentid[model.jnt_bodyid[self.jids[0]]]
                        if self.spec.kind == DIFF_DRIVE else model.jnt_bodyid[self.jids[2]])
        acts = np.array([index.joint_actuators[i].get(VELOCITY, -1) for i in idx], dtype=int)
        self.act = acts
        a = np.maximum(acts, 0)
        self.gear = np.where(acts >= 0, model.actuator_gear[a, 0] if model.nu else 1.0, 1.0)
        # The velocity actuators as plain numbers, read between batches (numpy's per-call cost
        # on arrays of two or three is most of a drive's time otherwise)
        self._actuated = [(k, int(acts[k]), float(self.gear[k]),
                           bool(model.actuator_ctrllimited[acts[k]]),
                           *(float(v) for v in model.actuator_ctrlrange[acts[k]]))
                          for k in range(len(acts)) if acts[k] >= 0]
        self._all_actuated = len(self._actuated) == len(acts)
        self.out = Outputs(index, model, idx[acts < 0])
        # The loop pushes the robot, not just the wheel: its gain counts the robot's mass as
        # each wheel carries it (m r^2 / wheels), or a 2 g wheel would not drag a 6 kg cart.
        self.reflected = 0.0
        if self.spec.kind == DIFF_DRIVE:
            root = index.entity_by_name[self.spec.entity].root_body
            self.reflected = (float(model.body_subtreemass[root]) * self.spec.radius ** 2
                              / len(names))
        torque = self.spec.max_wheel_torque
        if math.isfinite(torque):
            self.out.lo = np.maximum(self.out.lo, -torque)
            self.out.hi = np.minimum(self.out.hi, torque)
        self._index = index
        return True

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData, kd: float) -> Optional[str]:
        """
        Drive toward the command; return what it needs next.

        :returns: :data:`EVERY_STEP` (a ramp, a velocity loop, a floating root's velocity),
            :data:`EVERY_BATCH` (velocity actuators hold the speeds: only the timeout is
            watched, between batches of steps) or None (stopped: nothing to do).
        """
        from .actuation import times_mass
        spec, cmd = self.spec, self.command
        fresh = cmd.timeout <= 0 or data.time - cmd.time <= cmd.timeout
        self._fresh = fresh
        vx, vy, wz = (cmd.vx, cmd.vy, cmd.wz) if fresh else (0.0, 0.0, 0.0)
        if spec.kind != PLANAR_FREE:
            vx, vy, wz = self._track(model, data, vx, vy, wz)
        if spec.kind == PLANAR_FREE:
            yaw = _body_yaw(data, model.dof_bodyid[self.free_dof])
            c, s = math.cos(yaw), math.sin(yaw)
            d = self.free_dof
            data.qvel[d], data.qvel[d + 1] = c * vx - s * vy, s * vx + c * vy
            data.qvel[d + 5] = wz
            return EVERY_STEP if fresh else None
        if spec.kind == DIFF_DRIVE:
            # In scalars: a handful of wheels, where numpy's cost per call is most of the
            # work, and the stepping loop runs this between its steps.
            n = len(spec.left)
            half = wz * spec.separation / 2
            top = spec.max_wheel_speed
            step = spec.max_wheel_acceleration * model.opt.timestep
            values, ramp = [], False  # ramp: a wheel is not at its target speed yet
            for i, (sign, now) in enumerate(zip(spec.signs, self.speeds.tolist())):
                target = min(max(sign * (vx - half if i < n else vx + half) / spec.radius,
                                 -top), top)
                speed = now + min(max(target - now, -step), step)
                ramp = ramp or speed != target
                values.append(speed)
            self.speeds = np.array(values)
        else:  # planar joints: the slides' velocities that move the base at (vx, vy)
            base = model.jnt_bodyid[self.jids[2]]
            yaw = _body_yaw(data, base)
            c, s = math.cos(yaw), math.sin(yaw)
            wx, wy = c * vx - s * vy, s * vx + c * vy
            (a0, a1), (b0, b1) = data.xaxis[self.jids[0]][:2], data.xaxis[self.jids[1]][:2]
            det = a0 * b1 - b0 * a1  # the two slides' axes: not parallel (found so)
            values = [(wx * b1 - b0 * wy) / det, (a0 * wy - wx * a1) / det,
                      wz * math.copysign(1.0, data.xaxis[self.jids[2]][2])]
            self.speeds, ramp = np.array(values), False
        changed = False
        for k, a, gear, limited, lo, hi in self._actuated:
            want = gear * values[k]
            ctrl = min(max(want, lo), hi) if limited else want
            if abs(ctrl - want) > 1e-9:
                self.saturated = True
            if data.ctrl[a] != ctrl:
                data.ctrl[a] = ctrl
                changed = True
        self.changed = changed
        if self._all_actuated:
            if ramp:
                return EVERY_STEP  # a ramp runs
            return EVERY_BATCH if fresh or any(values) else None
        acts = self.act >= 0
        if (~acts).any():
            dof = self.out.dof
            err = self.speeds[~acts] - data.qvel[dof]
            # PI: a load (a dragging caster, a slope) leaves no lasting speed error, as a
            # velocity-controlled joint has none. Integral time 4 / kd; it stops growing while
            # the torque is at its limit.
            if self.integral is None or len(self.integral) != len(err):
                self.integral = np.zeros(len(err))
            u = kd * (err + kd / 4 * self.integral)
            tau = times_mass(model, data, dof, u) + self.reflected * u + data.qfrc_bias[dof]
            limited = self.out.write(data, tau)
            self.integral = np.where(limited, self.integral,
                                     self.integral + err * model.opt.timestep)
        if (~acts).any() or ramp:
            return EVERY_STEP  # a velocity loop holds the wheels, or a ramp runs
        return EVERY_BATCH if fresh or any(values) else None

    def _track(self, model: mujoco.MjModel, data: mujoco.MjData, vx: float, vy: float,
               wz: float) -> tuple:
        """
        Return the command corrected so that the base moves as commanded, in its frame.

        A wheel's speed is not the base's: casters drag, wheels slip (a skid-steer turns by
        slipping), a joint's friction loss holds back what its velocity actuator gives. An
        integral of the base's own velocity error (gain :data:`TRACK_GAIN`, measured at the
        base body in simulated time) adds what they take, within :data:`TRACK_LIMIT` times the
        command axis by axis; where that is not enough (or an actuator's range clips),
        :attr:`saturated` says so. A stopped command (zeros, or timed out) clears it: a base at
        rest is held by its wheels, not by a remembered correction.
        """
        now = float(data.time)
        dt = 0.0 if self._seen is None else min(max(now - self._seen, 0.0), TRACK_DT_MAX)
        self._seen = now
        want = (vx, 0.0 if self.spec.kind == DIFF_DRIVE else vy, wz)
        if not any(want):
            self.trim = [0.0, 0.0, 0.0]
            self.saturated = False
            return 0.0, 0.0, 0.0
        vx_world, vy_world, turn = planar_velocity(model, data, self.body)
        yaw = _body_yaw(data, self.body)
        c, s = math.cos(yaw), math.sin(yaw)
        have = (c * vx_world + s * vy_world, -s * vx_world + c * vy_world, turn)
        out, trims, saturated = [], [], False
        for w, h, t in zip(want, have, self.trim):
            bound = TRACK_LIMIT * abs(w)
            t += TRACK_GAIN * (w - h) * dt
            if abs(t) > bound:
                saturated = saturated or w != 0.0
                t = math.copysign(bound, t)
            trims.append(t)
            out.append(w + t)
        self.trim, self.saturated = trims, saturated
        return out[0], out[1], out[2]

    def release(self, data: mujoco.MjData) -> None:
        """Stop what it wrote (the entity is gone or its joints changed)."""
        if self.spec.kind != PLANAR_FREE and self._index is not None:
            self.out.release(data)
            data.ctrl[self.act[self.act >= 0]] = 0


def planar_velocity(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> tuple:
    """
    Return a body's (vx, vy, wz) at its centre of mass in world axes, from ``cvel``.

    What ``mj_objectVelocity`` gives for the body (its linear x, y and angular z: at the
    body's inertial frame, ``xipos``), without calling MuJoCo:
    each call gives the GIL away, and the stepping loop, which runs the tracking loops
    between its steps, waits to get it back from whichever thread took it (the mobile scene's
    two bases at real_time_factor 0, ``make bench-bases``). ``cvel`` is the body's velocity
    at its tree's centre of mass; moved to the body's own ``p``: ``v + w x (p - c)``.
    """
    w = data.cvel[body].tolist()  # [angular, linear]
    p = data.xipos[body].tolist()
    c = data.subtree_com[model.body_rootid[body]].tolist()
    rx, ry, rz = p[0] - c[0], p[1] - c[1], p[2] - c[2]
    return (w[3] + w[1] * rz - w[2] * ry, w[4] + w[2] * rx - w[0] * rz, w[2])


def _body_yaw(data: mujoco.MjData, body: int) -> float:
    return quat.yaw_of(data.xquat[body])


def check_command(vx: float, vy: float, wz: float) -> tuple:
    """Return a command as floats, or raise InvalidArgumentError (not finite, too large)."""
    from ..base.errors import InvalidArgumentError
    try:
        values = tuple(float(v) for v in (vx, vy, wz))
    except (TypeError, ValueError):
        values = (math.nan,) * 3
    if not all(math.isfinite(v) for v in values) or max(abs(values[0]), abs(values[1])) > \
            MAX_SPEED or abs(values[2]) > MAX_TURN:
        raise InvalidArgumentError(ERR_COMMAND.format(speed=MAX_SPEED, turn=MAX_TURN, vx=vx,
                                                      vy=vy, wz=wz))
    return values


@dataclass
class Command:
    """A velocity command in the base's frame, at simulated time `time`; 0 timeout: none."""

    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0
    time: float = -math.inf
    timeout: float = COMMAND_TIMEOUT


class Drives:
    """The world's driven bases, by entity, filed by what each needs next (world lock held)."""

    def __init__(self):
        self._drives: dict = {}  # entity -> Drive
        self._driving: set = set()  # the drives that need every step now
        self._batched: set = set()  # the drives that need a look between batches of steps

    def of(self, entity: str) -> Optional[Drive]:
        return self._drives.get(entity)

    @property
    def driving(self) -> bool:
        """Say whether a drive needs every step now (a ramp, a velocity loop)."""
        return bool(self._driving)

    @property
    def batched(self) -> bool:
        return bool(self._batched)

    def command(self, spec: BaseSpec, vx: float, vy: float, wz: float, timeout: float,
                index, model: mujoco.MjModel, data: mujoco.MjData, kd: float) -> bool:
        """
        Drive a base at (vx, vy, wz) in its frame from now.

        :returns: whether controls changed (the same command again changes none).
        :raises InvalidArgumentError: the base's joints are gone from `index`.
        """
        drive = self._drives.get(spec.entity)
        if drive is None or drive.spec != spec:
            if drive is not None:
                drive.release(data)
            drive = Drive(spec)
            if not drive.bind(index, model):
                raise InvalidArgumentError(f'the base of {spec.entity!r} lost its joints')
            self._drives[spec.entity] = drive
        drive.command = Command(vx, vy, wz, float(data.time), timeout)
        need = drive.apply(model, data, kd)
        self._place(spec.entity, need)
        return drive.changed or need == EVERY_STEP

    def every_step(self, model: mujoco.MjModel, data: mujoco.MjData, kd: float) -> None:
        """Before one step: the drives that need it."""
        for entity in list(self._driving):
            self._place(entity, self._drives[entity].apply(model, data, kd))

    def before_batch(self, model: mujoco.MjModel, data: mujoco.MjData, kd: float) -> bool:
        """
        Between batches of steps: the drives held by velocity actuators (their timeout).

        :returns: whether a control changed (a base stopped).
        """
        changed = False
        for entity in list(self._batched):
            drive = self._drives[entity]
            if not drive.due(float(data.time)):
                continue
            self._place(entity, drive.apply(model, data, kd))
            changed = changed or drive.changed
        return changed

    def deadline(self, now: float) -> float:
        """Return the earliest simulated time after `now` at which a batched base times out."""
        due = [d.command.time + d.command.timeout for d in map(self._drives.get, self._batched)
               if d.command.timeout > 0 and d.command.time + d.command.timeout >= now]
        return min(due, default=math.inf)

    def bind(self, index, model: mujoco.MjModel) -> None:
        """Take the addresses of a new model; a base whose joints are gone is dropped."""
        for entity, drive in list(self._drives.items()):
            if not drive.bind(index, model):
                del self._drives[entity]  # gone (its old addresses mean nothing now)
                self._place(entity, None)

    def stop_all(self) -> None:
        """Every base stops (a reset): no command, no speed, no integral."""
        for drive in self._drives.values():
            drive.command = Command()
            drive.speeds[:] = 0
            drive.integral = None
        self._driving.clear()
        self._batched.clear()

    def _place(self, entity: str, need: Optional[str]) -> None:
        """File a drive under what it needs next (:meth:`Drive.apply`)."""
        self._driving.discard(entity)
        self._batched.discard(entity)
        if need == EVERY_STEP:
            self._driving.add(entity)
        elif need == EVERY_BATCH:
            self._batched.add(entity)
