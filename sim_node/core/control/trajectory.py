"""
Joint trajectories as ros2_control's joint_trajectory_controller runs them, in simulated time.

A :class:`Trajectory` is checked once (:func:`check`), then sampled at any simulated time:
before its start it holds the state it started from, between points it interpolates by the
fields the points give (positions only: linear; with velocities: cubic; with accelerations:
quintic), after its last point it holds that point. A first point later than the start is
reached from the state the joints were in when the trajectory started, as the controller does.

:class:`Tracker` judges a running trajectory against its tolerances (path: every step; goal:
from the end on, within the goal time tolerance) the way the controller does; 0 means a
tolerance is not checked. ROS-free: the node turns FollowJointTrajectory goals into these.
"""

from dataclasses import dataclass, field
import math
from typing import Callable, Optional, Sequence

import numpy as np

from ..base import checks

# FollowJointTrajectory's error codes (the controller's meaning; the node maps them 1:1).
SUCCESSFUL, INVALID_GOAL, INVALID_JOINTS, OLD_HEADER_TIMESTAMP = 0, -1, -2, -3
PATH_TOLERANCE_VIOLATED, GOAL_TOLERANCE_VIOLATED = -4, -5

ERR_EMPTY = 'the trajectory has no points'
ERR_NO_JOINTS = 'the trajectory names no joints'
ERR_DUPLICATE = 'the trajectory names joint {name!r} twice'
ERR_UNKNOWN = 'unknown joint {name!r}{hint}'
ERR_ENTITIES = ('the trajectory names joints of {entities}: one goal drives one entity '
                "(send one goal to each entity's follow_joint_trajectory)")
ERR_OTHER_ENTITY = 'joint {name!r} belongs to {other!r}, not to {entity!r}'
ERR_TIMES = ('time_from_start must increase from point to point: point {i} is at {t:g} s, '
             'point {prev} at {p:g} s')
ERR_NEGATIVE = 'point {i} has a negative time_from_start ({t:g} s)'
ERR_SIZE = 'point {i} has {n} {field} for {m} joints'
ERR_NOT_FINITE = 'point {i} has a non-finite {field} value'
ERR_RANGE = ('point {i} puts joint {name!r} at {q:.6g}, outside its range [{lo:.6g}, {hi:.6g}]: '
             'no actuator can take it there')
#: How far beyond its range a point may put a joint (rad or m) without being refused: a joint
#: resting on its limit sits that little way past it (MuJoCo's limits are soft).
RANGE_MARGIN = 1e-3
ERR_END_VELOCITY = ('the last point gives joint {name!r} a velocity of {v:.6g}: a trajectory '
                    'must end at rest (allow_nonzero_velocity_at_trajectory_end is off, as in '
                    "the controller's default)")
ERR_OLD = ('the trajectory ends at {end:.6f} s of simulated time, before now ({now:.6f} s): '
           'its header stamp is in the past')


class TrajectoryError(ValueError):
    """A goal that cannot run: ``code`` is FollowJointTrajectory's error code."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class Tolerance:
    """Per-joint limits on |error| (0: not checked), (n,) each."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @classmethod
    def none(cls, n: int) -> 'Tolerance':
        return cls(np.zeros(n), np.zeros(n), np.zeros(n))


@dataclass
class Trajectory:
    """
    A checked trajectory for `joints`, starting at simulated time `start`.

    :param times: (k,) seconds from `start`, increasing.
    :param positions: (k, n); velocities and accelerations (k, n) or None.
    :param start_positions: (n,) where the joints were when the trajectory was accepted
        (the first segment starts there when the first point is later than `start`).
    """

    joints: tuple
    start: float
    times: np.ndarray
    positions: np.ndarray
    velocities: Optional[np.ndarray]
    accelerations: Optional[np.ndarray]
    start_positions: np.ndarray
    start_velocities: np.ndarray
    path_tolerance: Tolerance = field(default=None)
    goal_tolerance: Tolerance = field(default=None)
    goal_time_tolerance: float = 0.0

    @property
    def end(self) -> float:
        return self.start + float(self.times[-1])

    def sample(self, t: float) -> tuple:
        """Return (positions, velocities, accelerations), each (n,), at simulated time `t`."""
        n = len(self.joints)
        zeros = np.zeros(n)
        rel = t - self.start
        if rel < 0 and self.times[0] > 0:
            return self.start_positions.copy(), zeros, zeros
        if rel >= self.times[-1]:
            return (self.positions[-1].copy(), self._vel(-1, zeros), self._acc(-1, zeros))
        k = int(np.searchsorted(self.times, rel, side='right'))  # first point after rel
        if k == 0:  # before the first point: from the start state
            t0, q0, v0, a0 = 0.0, self.start_positions, self.start_velocities, zeros
        else:
            t0, q0, v0, a0 = (float(self.times[k - 1]), self.positions[k - 1],
                              self._vel(k - 1, zeros), self._acc(k - 1, zeros))
        t1, q1, v1, a1 = (float(self.times[k]), self.positions[k], self._vel(k, zeros),
                          self._acc(k, zeros))
        return _interpolate(rel - t0, t1 - t0, q0, v0, a0, q1, v1, a1,
                            self.velocities is not None, self.accelerations is not None)

    def _vel(self, k: int, default: np.ndarray) -> np.ndarray:
        return default if self.velocities is None else self.velocities[k]

    def _acc(self, k: int, default: np.ndarray) -> np.ndarray:
        return default if self.accelerations is None else self.accelerations[k]


def _interpolate(s: float, T: float, q0, v0, a0, q1, v1, a1, with_vel: bool,
                 with_acc: bool) -> tuple:
    """Position, velocity, acceleration at `s` into a segment of duration `T`."""
    if T <= 0:
        return q1.copy(), v1.copy(), a1.copy()
    if with_acc:  # quintic: positions, velocities and accelerations at both ends
        T2, T3, T4, T5 = T * T, T ** 3, T ** 4, T ** 5
        c0, c1, c2 = q0, v0, a0 / 2
        c3 = (20 * (q1 - q0) - (8 * v1 + 12 * v0) * T - (3 * a0 - a1) * T2) / (2 * T3)
        c4 = (30 * (q0 - q1) + (14 * v1 + 16 * v0) * T + (3 * a0 - 2 * a1) * T2) / (2 * T4)
        c5 = (12 * (q1 - q0) - 6 * (v1 + v0) * T - (a0 - a1) * T2) / (2 * T5)
        q = c0 + c1 * s + c2 * s ** 2 + c3 * s ** 3 + c4 * s ** 4 + c5 * s ** 5
        v = c1 + 2 * c2 * s + 3 * c3 * s ** 2 + 4 * c4 * s ** 3 + 5 * c5 * s ** 4
        a = 2 * c2 + 6 * c3 * s + 12 * c4 * s ** 2 + 20 * c5 * s ** 3
        return q, v, a
    if with_vel:  # cubic Hermite: positions and velocities at both ends
        T2, T3 = T * T, T ** 3
        c2 = (3 * (q1 - q0) - (2 * v0 + v1) * T) / T2
        c3 = (2 * (q0 - q1) + (v0 + v1) * T) / T3
        q = q0 + v0 * s + c2 * s ** 2 + c3 * s ** 3
        v = v0 + 2 * c2 * s + 3 * c3 * s ** 2
        return q, v, 2 * c2 + 6 * c3 * s
    rate = (q1 - q0) / T  # linear
    return q0 + rate * s, rate, np.zeros_like(rate)


def check(joint_names: Sequence[str], times: Sequence[float], positions: Sequence[Sequence],
          velocities: Sequence[Sequence], accelerations: Sequence[Sequence],
          known: dict, entity: str) -> tuple:
    """
    Check a goal's joints and points; return them as arrays.

    :returns: (times (k,), positions (k, n), velocities or None, accelerations or None).

    :param known: every commandable joint name -> the entity it belongs to.
    :param entity: the entity whose controller got the goal.
    :raises TrajectoryError: INVALID_JOINTS or INVALID_GOAL, with the joint or point named.
    """
    names = list(joint_names)
    if not names:
        raise TrajectoryError(INVALID_JOINTS, ERR_NO_JOINTS)
    for i, name in enumerate(names):
        if name in names[:i]:
            raise TrajectoryError(INVALID_JOINTS, ERR_DUPLICATE.format(name=name))
        owner = known.get(name)
        if owner is None:
            raise TrajectoryError(INVALID_JOINTS, ERR_UNKNOWN.format(
                name=name, hint=checks.closest_hint(name, [j for j, e in known.items()
                                                    if e == entity])))
    owners = sorted({known[n] for n in names})
    if len(owners) > 1:
        raise TrajectoryError(INVALID_JOINTS, ERR_ENTITIES.format(
            entities=' and '.join(repr(o) for o in owners)))
    if owners[0] != entity:
        raise TrajectoryError(INVALID_JOINTS, ERR_OTHER_ENTITY.format(
            name=names[0], other=owners[0], entity=entity))
    k, n = len(times), len(names)
    if not k:
        raise TrajectoryError(INVALID_GOAL, ERR_EMPTY)
    t = np.asarray(times, dtype=float)
    for i in range(k):
        if not math.isfinite(t[i]) or t[i] < 0:
            raise TrajectoryError(INVALID_GOAL, ERR_NEGATIVE.format(i=i, t=t[i]))
        if i and t[i] <= t[i - 1]:
            raise TrajectoryError(INVALID_GOAL,
                                  ERR_TIMES.format(i=i, t=t[i], prev=i - 1, p=t[i - 1]))
    arrays = []
    for label, rows, required in (('positions', positions, True),
                                  ('velocities', velocities, False),
                                  ('accelerations', accelerations, False)):
        sizes = [len(r) for r in rows]
        if not required and not any(sizes):
            arrays.append(None)
            continue
        for i, size in enumerate(sizes):
            if size != n:
                raise TrajectoryError(INVALID_GOAL, ERR_SIZE.format(i=i, n=size, field=label,
                                                                    m=n))
        a = np.asarray(rows, dtype=float).reshape(k, n)
        bad = np.where(~np.isfinite(a).all(axis=1))[0]
        if len(bad):
            raise TrajectoryError(INVALID_GOAL, ERR_NOT_FINITE.format(i=int(bad[0]),
                                                                      field=label))
        arrays.append(a)
    if arrays[2] is not None and arrays[1] is None:
        raise TrajectoryError(INVALID_GOAL, 'accelerations are given without velocities')
    return (t, *arrays)


def plan(index, model, data, entity: str, joint_names: Sequence[str], times: Sequence[float],
         positions: Sequence[Sequence], velocities: Sequence[Sequence],
         accelerations: Sequence[Sequence], start_time: float,
         path_tolerance: Optional[dict], goal_tolerance: Optional[dict],
         goal_time_tolerance: float, allow_end_velocity: bool = False,
         start_state: Optional[Callable[[], tuple]] = None) -> 'Trajectory':
    """
    Check a goal against a world's joints and plan it.

    :param index: the model's :class:`~sim_node.core.compiled.index.ModelIndex`.

    Starts from the joints' state now, or from what `start_state()` returns once the goal is
    checked ((positions, velocities) in `joint_names` order: what was last commanded). See
    :meth:`World.follow_trajectory <sim_node.core.world.World.follow_trajectory>` for the
    arguments. Call with the world lock.
    A point that puts a limited joint outside its range is refused (INVALID_GOAL), unless the
    joint is outside it already and the point is no further out; so is a last point with a
    velocity, unless `allow_end_velocity` (joint_trajectory_controller's
    ``allow_nonzero_velocity_at_trajectory_end``, off by default).

    :raises TrajectoryError: with FollowJointTrajectory's error code.
    """
    known = dict(zip(index.joint_names, index.info.joint_entity))
    t, q, v, a = check(joint_names, times, positions, velocities, accelerations, known, entity)
    now = float(data.time)
    start = now if start_time <= 0 else float(start_time)
    if start + t[-1] < now:
        raise TrajectoryError(OLD_HEADER_TIMESTAMP, ERR_OLD.format(end=start + t[-1], now=now))
    idx = index.joints(joint_names)
    names = tuple(joint_names)
    start_q = data.qpos[index.joint_qposadr[idx]].copy()
    _check_ranges(model, index.joint_ids[idx], names, q, start_q)
    start_v = data.qvel[index.joint_dofadr[idx]].copy()
    if start_state is not None:
        start_q, start_v = (np.array(x, dtype=float) for x in start_state())
    if v is not None and not allow_end_velocity and np.any(v[-1] != 0):
        j = int(np.nonzero(v[-1])[0][0])
        raise TrajectoryError(INVALID_GOAL, ERR_END_VELOCITY.format(name=names[j], v=v[-1, j]))
    return Trajectory(
        joints=names, start=start, times=t, positions=q, velocities=v, accelerations=a,
        start_positions=start_q,
        start_velocities=start_v if v is not None else np.zeros(len(names)),
        path_tolerance=_tolerance(names, path_tolerance),
        goal_tolerance=_tolerance(names, goal_tolerance),
        goal_time_tolerance=max(0.0, float(goal_time_tolerance)))


def _check_ranges(model, jids: np.ndarray, names: tuple, q: np.ndarray,
                  start_q: np.ndarray) -> None:
    """Refuse a point that puts a limited joint outside its range (further than it is now)."""
    limited = model.jnt_limited[jids].astype(bool)
    lo = np.minimum(model.jnt_range[jids, 0], start_q) - RANGE_MARGIN
    hi = np.maximum(model.jnt_range[jids, 1], start_q) + RANGE_MARGIN
    out = limited & ((q < lo) | (q > hi))
    if out.any():
        i, j = (int(x[0]) for x in np.nonzero(out))
        lo_j, hi_j = model.jnt_range[jids[j]]
        raise TrajectoryError(INVALID_GOAL, ERR_RANGE.format(i=i, name=names[j], q=q[i, j],
                                                             lo=lo_j, hi=hi_j))


def _tolerance(names: tuple, given: Optional[dict]) -> Tolerance:
    """(n,) limits per joint from joint -> (position, velocity, acceleration); 0: unchecked."""
    tol = Tolerance.none(len(names))
    for i, name in enumerate(names):
        p, v, a = (given or {}).get(name, (0.0, 0.0, 0.0))
        tol.position[i], tol.velocity[i], tol.acceleration[i] = (max(0.0, float(x))
                                                                 for x in (p, v, a))
    return tol


@dataclass
class Status:
    """Where a running trajectory stands: its outcome once decided (``code`` not None)."""

    code: Optional[int] = None
    message: str = ''
    canceled: bool = False  # ended by a cancel or a newer goal, not by itself
    desired: tuple = ()
    actual: tuple = ()
    time: float = 0.0
    effort: tuple = ()  # (n,) the joint torques the actuators and PD gave in the last step


class Tracker:
    """Judges one trajectory against its tolerances, step by step (world lock held)."""

    def __init__(self, trajectory: Trajectory):
        self.trajectory = trajectory
        self.status = Status()
        self._sampled = False  # the path tolerance holds from the first sample on

    def judge(self, t: float, q: np.ndarray, v: np.ndarray) -> Optional[int]:
        """Record the state at time `t`; return the outcome code once decided."""
        tr = self.trajectory
        qd, vd, ad = tr.sample(t)
        self.status.desired, self.status.actual, self.status.time = (qd, vd, ad), (q, v), t
        if self.status.code is not None:
            return self.status.code
        if t >= tr.start and (t < tr.end or not self._sampled):
            # Along the way, and at the first sample even when that is the end: a single
            # point at time 0 far from where the joints are violates the path at once.
            self._sampled = True
            bad = _violation(tr.joints, tr.path_tolerance, qd - q, vd - v)
            if bad:
                return self._decide(PATH_TOLERANCE_VIOLATED, 'path tolerance ' + bad)
        if t < tr.end:
            return None
        bad = _violation(tr.joints, tr.goal_tolerance, qd - q, vd - v)
        if not bad:
            return self._decide(SUCCESSFUL, '')
        late = t - tr.end
        if tr.goal_time_tolerance > 0 and late > tr.goal_time_tolerance:
            return self._decide(GOAL_TOLERANCE_VIOLATED, f'goal tolerance {bad} '
                                f'{late:.3f} s after the end (goal_time_tolerance '
                                f'{tr.goal_time_tolerance:g} s)')
        return None

    def _decide(self, code: int, message: str) -> int:
        self.status.code, self.status.message = code, message
        return code


def _violation(joints: tuple, tol: Tolerance, dq: np.ndarray, dv: np.ndarray) -> str:
    """'' when within `tol`; else which joint is off and by how much."""
    for label, err, lim in (('position', dq, tol.position), ('velocity', dv, tol.velocity)):
        over = np.where((lim > 0) & (np.abs(err) > lim))[0]
        if len(over):
            j = int(over[0])
            return (f'violated by joint {joints[j]!r}: {label} error {abs(err[j]):.4g} over '
                    f'{lim[j]:.4g}')
    return ''


class TrajectoryHandle:
    """A trajectory a world follows: wait for it, read how it goes, cancel it."""

    def __init__(self, world: 'World', entity: str, run):  # noqa: F821 (core.world)
        self.world, self.entity, self.run = world, entity, run

    @property
    def status(self) -> Status:
        """Return the latest judgement: desired and actual, and the outcome once decided."""
        return self.run.tracker.status

    @property
    def trajectory(self) -> Trajectory:
        return self.run.tracker.trajectory

    def wait(self, timeout: Optional[float] = None) -> bool:
        """Block until the trajectory has ended (True) or `timeout` wall seconds passed."""
        return self.run.done.wait(timeout)

    @property
    def done(self) -> bool:
        return self.run.done.is_set()

    def cancel(self) -> None:
        """End it now; the joints hold where they are (nothing if it has ended already)."""
        self.world.cancel_trajectory(self)
