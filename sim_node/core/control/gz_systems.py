"""
The laws of the gz-sim systems a model's SDF declares, as Gazebo runs them.

A system's parameters are read from its plugin by :mod:`sim_node.core.models.sdf_systems`
(:class:`~sim_node.core.models.sdf_systems.GzSystem`); :func:`law` gives the law that runs it on
the stepping side at its rate of simulated time (:class:`~.laws.Laws`, as a robot's
ros2_control controllers run):

* ``DiffDrive``: :class:`~.laws.DiffDriveLaw` on its ``<left_joint>``s and ``<right_joint>``s
  (``<wheel_separation>``, ``<wheel_radius>``; the ``max_``/``min_`` ``linear``/``angular``
  velocity, acceleration and jerk limits, and the older ``max_velocity``, ...); a twist is held
  until the next (gz-sim's DiffDrive has no timeout); odometry from the first wheel of each side.
* ``AckermannSteering``: :class:`AckermannLaw`, the Ackermann steering controller's
  kinematics (:class:`~.laws.SteeringLaw`) on its ``<left_joint>``, ``<right_joint>``
  (traction) and their ``*_steering_joint``s, ``<wheel_base>``, ``<wheel_separation>``,
  ``<wheel_radius>``; each angle within ``<steering_limit>``, reached as gz-sim reaches it: the
  steering joint's velocity set to ``steer_p_gain`` (1) times its error.
* ``JointPositionController``: :class:`PidLaw` on position: gz-sim's PID (``p_gain`` 1,
  ``i_gain`` 0.1, ``d_gain`` 0.01, ``i_max``/``i_min`` 1, ``cmd_max``/``cmd_min`` 1000,
  ``cmd_offset``) as an effort each step, or with ``<use_velocity_commands>`` the joint's
  velocity; ``cmd_pos`` per joint.
* ``JointController``: :class:`PidLaw` on velocity: the joint held at the commanded velocity
  (gz-sim sets it), or with ``<use_force_commands>`` gz-sim's PID as an effort; ``cmd_vel``.
* ``JointTrajectoryController``: :class:`TrajectoryLaw`: a trajectory's points in time, each
  joint's PID (``position_p_gain`` ..., default the position's without a gain: the joint
  servoed there), its progress.
* ``JointStatePublisher``, ``PosePublisher``: no law; their publishers read the world.

ROS-free: the node's gz room (:mod:`sim_node.ros.control.gz_systems`) carries the topics.
"""

from typing import Optional, Sequence

from . import controller_types as types
from .laws import DiffDriveLaw, Law, SteeringLaw, Write
from ..models.sdf_systems import GzSystem, POSITION_PID


class PidLaw(Law):
    """
    gz-sim's joint controllers: a PID on a joint's position or velocity, or the value set.

    :param params: ``p_gain`` ... ``cmd_offset`` (see :data:`POSITION_PID`), ``direct`` (the
        joint's velocity or position commanded as it is, not through the PID's effort) and
        ``initial`` (its target before any command).
    :param position: it controls the position (JointPositionController), else the velocity.
    """

    def __init__(self, joints: Sequence[str], params: dict, position: bool, rate_hz: float):
        super().__init__(params, rate_hz)
        self.joints, self.position = tuple(joints), position
        self.target = float(params['initial'])
        self.restart()

    def restart(self) -> None:
        self.integral, self.last_error, self.last_time = 0.0, None, None

    def take(self, value: float) -> None:
        """Take a command (any thread): the position or velocity to reach."""
        with self.lock:
            self.target = float(value)

    def update(self, sample, index: dict) -> list:
        p = self.params
        if p['direct']:  # the joint set to it: a position servoed, a velocity held
            return [Write(self.joints, [self.target] * len(self.joints),
                          'position' if self.position else 'velocity')]
        i = index[self.joints[0]]
        now = float(sample.position[i] if self.position else sample.velocity[i])
        error = now - self.target  # gz-sim's PID takes the error as measured minus target
        dt = (sample.time - self.last_time) if self.last_time is not None else 0.0
        self.last_time = sample.time
        self.integral = min(max(self.integral + p['i_gain'] * error * dt, p['i_min']),
                            p['i_max'])
        derivative = (error - self.last_error) / dt if dt > 0 and self.last_error is not None \
            else 0.0
        self.last_error = error
        force = -(p['p_gain'] * error + self.integral + p['d_gain'] * derivative) \
            + p['cmd_offset']
        force = min(max(force, p['cmd_min']), p['cmd_max'])
        return [Write(self.joints, [force] * len(self.joints), 'effort')]


class TrajectoryLaw(Law):
    """
    gz-sim's JointTrajectoryController: a trajectory's points reached at their times.

    Between points each joint's target moves linearly; a joint with a PID gain is driven by
    gz-sim's PID as an effort, one without is servoed to its target. `progress` is the share
    of the trajectory's time gone (1 once its last point's time has passed).
    """

    def __init__(self, joints: Sequence[str], params: dict, rate_hz: float):
        super().__init__(params, rate_hz)
        self.joints = tuple(joints)
        self.points: list = []  # (seconds from the start, {joint: position})
        self.start: Optional[float] = None
        self.origin: dict = {}  # joint -> where it was when the trajectory started
        self.progress = 0.0
        self.pids = {}
        gains = params.get('gains', {})
        for k, j in enumerate(self.joints):
            if k < len(gains.get('p_gain', [])):
                pid = {g: (gains[g][k] if k < len(gains.get(g, [])) else POSITION_PID[g])
                       for g in POSITION_PID if g != 'cmd_offset'}
                self.pids[j] = PidLaw((j,), {**pid, 'cmd_offset': 0.0, 'direct': False,
                                             'initial': 0.0}, True, rate_hz)

    def follow(self, points: list) -> None:
        """Follow `points` [(seconds from now, {joint: position})] from the next update."""
        with self.lock:
            self.points = sorted(points, key=lambda p: p[0])
            self.start, self.progress = None, 0.0

    def update(self, sample, index: dict) -> list:
        if not self.points:
            return []
        if self.start is None:  # from where each joint is to the first point
            self.start = sample.time
            self.origin = {j: float(sample.position[index[j]]) for j in self.joints
                           if j in index}
        t = sample.time - self.start
        end = self.points[-1][0]
        self.progress = 1.0 if end <= 0 or t >= end else t / end
        targets = {}
        for j in self.joints:
            path = [(0.0, self.origin.get(j))] + [(pt, pos[j]) for pt, pos in self.points
                                                  if j in pos]
            if len(path) == 1 or path[0][1] is None:
                continue
            targets[j] = path[-1][1]
            for (t0, q0), (t1, q1) in zip(path, path[1:]):
                if t0 <= t < t1:
                    targets[j] = q0 + (q1 - q0) * (t - t0) / (t1 - t0)
                    break
        out = []
        servoed = tuple(j for j in targets if j not in self.pids)
        if servoed:
            out.append(Write(servoed, [targets[j] for j in servoed], 'position'))
        for j, pid in self.pids.items():
            if j in targets:
                pid.target = targets[j]
                out += pid.update(sample, index)
        return out


class AckermannLaw(SteeringLaw):
    """gz-sim's AckermannSteering: traction by velocity, steering by velocity on its error."""

    def _writes(self, angles: list, speeds: list) -> list:
        limit = self.params.get('steering_limit', 0.5)
        angles = [min(max(a, -limit), limit) for a in angles]
        self.steering_targets = angles
        return [Write(self.traction, list(speeds), 'velocity')]

    def update(self, sample, index: dict) -> list:
        writes = super().update(sample, index)
        targets = getattr(self, 'steering_targets', [0.0] * len(self.steering))
        gain = self.params.get('steer_p_gain', 1.0)
        rates = [gain * (t - float(sample.position[index[j]]))
                 for j, t in zip(self.steering, targets)]
        return writes + [Write(self.steering, rates, 'velocity')]


def velocity_joints(system: GzSystem) -> tuple:
    """Return the joints `system` commands by velocity (held by stiff velocity actuators)."""
    if system.kind == 'DiffDrive':
        return system.joints
    if system.kind == 'AckermannSteering':
        return tuple(system.params['traction_joints_names'] + system.params[
            'steering_joints_names'])
    if system.kind == 'JointController' and system.params.get('direct'):
        return system.joints
    return ()


def law(system: GzSystem, timestep: float) -> Optional[Law]:
    """Return the law that runs `system` (None: a publisher only), at its rate."""
    rate = system.rate_hz if system.rate_hz > 0 else 1.0 / timestep
    if system.kind == 'DiffDrive':
        return DiffDriveLaw(system.params, rate)
    if system.kind == 'AckermannSteering':
        return AckermannLaw(system.params, rate, types.Ackermann)
    if system.kind in ('JointPositionController', 'JointController'):
        return PidLaw(system.joints, system.params, system.kind == 'JointPositionController',
                      rate)
    if system.kind == 'JointTrajectoryController':
        return TrajectoryLaw(system.joints, system.params, rate)
    return None
