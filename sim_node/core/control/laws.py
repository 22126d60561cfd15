"""
The laws of a robot's ros2_control controllers, run on the stepping side in simulated time.

A controller's ROS side (:mod:`sim_node.ros.control`) takes commands off its topics and actions
and hands them to its law; the law turns them into joint commands at the controller's
``update_rate`` of simulated time, as ros2_control's update loop does:

* :class:`DiffDriveLaw` (diff_drive_controller) and :class:`SteeringLaw` (the Ackermann and
  bicycle steering controllers, tricycle_controller): the last twist taken is held until it is
  older than the timeout (simulated s; 0: never), then the base stops; each update limits it
  (:mod:`.limits`), turns it into wheel commands (:mod:`.diff_drive`, :mod:`.steering`) and
  advances the odometry from the wheels (:mod:`.odometry`);
* :class:`GripperLaw` (the gripper action controllers): a goal's position is commanded, and each
  update decides it: reached within ``goal_tolerance``, or stalled (slower than
  ``stall_velocity_threshold`` for ``stall_timeout`` simulated seconds short of it).

How it runs: :class:`Laws` is one robot's set. Its :meth:`Laws.tick` is the ``tick`` the robot's
controller manager gives :meth:`World.sample_joints <sim_node.core.world.World.sample_joints>`:
the world calls it on the stepping thread, with its lock held, at every joint sample due (the
manager's update rate; samples the node's publishers never see included), and applies the
commands it returns before the next step. Each law has a lock of its own, taken briefly by the
stepping thread (inside the world lock) and by the ROS threads that give it commands (never
while they call the world): a command, an activation or a goal is seen by the next update.
A reset of the world's state (the sample's ``resets`` count goes up) starts every law again
from it on the stepping side, before its first update after it: bases stop, their odometry
starts from zero, a gripper's goal ends.

ROS-free: tested in test_core_laws.py without rclpy.
"""

import copy
import math
import threading
from typing import Callable, NamedTuple, Optional, Sequence

from . import controller_types as types
from . import diff_drive, limits, steering
from .odometry import SteeringOdometry


class Write(NamedTuple):
    """Commands for joints by the robot's own (URDF) names, through one command interface."""

    joints: tuple
    values: list
    interface: str


def _mean(sample, index: dict, joints: Sequence[str]) -> float:
    """Return the mean position of `joints` in `sample`."""
    return sum(float(sample.position[index[j]]) for j in joints) / len(joints)


class Law:
    """
    One controller's law: :meth:`update` from a joint sample to the commands it writes.

    ``active`` laws are updated (the ROS side's activate and deactivate say so); `rate_hz` is the
    controller's update rate, at most its manager's (the sample rate).
    """

    def __init__(self, params: dict, rate_hz: float):
        self.params, self.rate_hz = params, float(rate_hz)
        self.lock = threading.Lock()
        self.active = False
        self.next_update = -math.inf
        self.resets: Optional[int] = None  # the world's resets of state it started after

    def activate(self) -> list:
        """Start (again) from now; return the commands to write at once."""
        with self.lock:
            self.active = True
            self.next_update = -math.inf
            self.resets = None  # taken from its first sample
            self.restart()
        return []

    def deactivate(self) -> list:
        """Stop updating; return the commands that leave the joints safe (a base stops)."""
        with self.lock:
            self.active = False
        return []

    def restart(self) -> None:
        """Start again from the joints' state (activation, a reset): the lock is held."""

    def due(self, sample) -> bool:
        """Say whether `sample` is this law's to update on (its lock held)."""
        if not self.active:
            return False
        if self.resets is None:
            self.resets = sample.resets
        elif sample.resets > self.resets:
            self.resets = sample.resets
            self.next_update = -math.inf
            self.restart()
        if sample.time < self.next_update:
            return False
        self.next_update = sample.time + 1.0 / self.rate_hz - 1e-9
        return True

    def update(self, sample, index: dict) -> list:
        """Return the commands (:class:`Write`) for this sample (its lock held)."""
        return []


class HoldLaw(Law):
    """
    Hold still the joints no active controller claims, as gz_ros2_control's ``hold_joints``.

    At its first sample and after each reset of the world's state, and when a controller lets
    a joint go: a joint with a position interface is held where it is, one with a velocity
    interface (and no position one) at zero speed. gz_ros2_control commands such joints a
    velocity of zero; a position held from where the joint is, is that here. A joint with an
    effort interface alone is left free (this has no velocity command for it).

    :param joints: joint -> 'position' or 'velocity', the interface it is held through.
    """

    def __init__(self, joints: dict, rate_hz: float):
        super().__init__({}, rate_hz)
        self.joints = dict(joints)
        self.free = set(self.joints)  # the joints no active controller claims
        self.pending: set = set()  # those to hold at the next update

    def restart(self) -> None:
        self.pending = set(self.free)

    def claimed(self, joints: set) -> None:
        """Say which joints active controllers claim now (any thread): those let go are held."""
        with self.lock:
            free = set(self.joints) - set(joints)
            self.pending = (self.pending | (free - self.free)) & free
            self.free = free

    def due(self, sample) -> bool:
        return super().due(sample) and bool(self.pending)

    def update(self, sample, index: dict) -> list:
        todo, self.pending = sorted(self.pending & self.free), set()
        at = tuple(j for j in todo if self.joints[j] == 'position')
        still = tuple(j for j in todo if self.joints[j] == 'velocity')
        return [w for w in (Write(at, [float(sample.position[index[j]]) for j in at],
                                  'position'),
                            Write(still, [0.0] * len(still), 'velocity')) if w.joints]


def held_interfaces(command: dict) -> dict:
    """Return joint -> the interface :class:`HoldLaw` holds it through (joint -> interfaces)."""
    out = {}
    for joint, interfaces in command.items():
        if 'position' in interfaces:
            out[joint] = 'position'
        elif 'velocity' in interfaces:
            out[joint] = 'velocity'
    return out


class BaseLaw(Law):
    """
    What the base controllers share: a twist held until it is stale, written every update.

    A subclass sets ``odometry`` and ``timeout`` and writes :meth:`steer` and :meth:`track`.
    """

    timeout = 0.0

    def take(self, v: float, w: float) -> None:
        """Take a twist (m/s ahead, rad/s about z; any thread): the next update stamps it."""
        with self.lock:
            if self.active:
                self.command = (float(v), float(w), None)

    def restart(self) -> None:
        self.odometry.reset()
        self.command: Optional[tuple] = None  # (v, w, simulated time it was first seen)
        self.last_update: Optional[float] = None
        self.history = [(0.0, 0.0), (0.0, 0.0)]  # the last output and the one before it

    def deactivate(self) -> list:
        super().deactivate()
        return self.drive(0.0, 0.0)

    def update(self, sample, index: dict) -> list:
        t = sample.time
        dt = t - self.last_update if self.last_update is not None else 1.0 / self.rate_hz
        self.last_update = t
        if self.command is not None and self.command[2] is None:
            self.command = (self.command[0], self.command[1], t)
        if self.command is not None and self.timeout > 0 and t - self.command[2] > self.timeout:
            self.command = None  # stale: the base stops
        v, w = self.command[:2] if self.command is not None else (0.0, 0.0)
        writes = self.steer(v, w, dt, sample, index)
        self.track(t, sample, index)
        return writes

    def snapshot(self):
        """Return a copy of the odometry now (any thread), for its message."""
        with self.lock:
            return copy.copy(self.odometry)

    def steer(self, v: float, w: float, dt: float, sample, index: dict) -> list:
        """Return the wheel commands for the twist (v, w), `dt` after the last update."""
        return self.drive(v, w)

    def drive(self, v: float, w: float) -> list:
        """Return the wheel commands for the twist (v, w) as it is, unlimited."""
        raise NotImplementedError

    def track(self, t: float, sample, index: dict) -> None:
        """Take the wheels' sample into the odometry."""
        raise NotImplementedError


class DiffDriveLaw(BaseLaw):
    """diff_drive_controller's: the twist limited, the wheels' speeds, their odometry."""

    def __init__(self, params: dict, rate_hz: float):
        super().__init__(params, rate_hz)
        p = params
        self.left, self.right = tuple(p['left_wheel_names']), tuple(p['right_wheel_names'])
        self.geometry = diff_drive.Geometry.of(p)
        self.odometry = diff_drive.odometry(self.geometry)
        self.limiters = (limits.signed(p, 'linear.x'), limits.signed(p, 'angular.z'))
        self.timeout = p['cmd_vel_timeout']
        self.restart()

    def steer(self, v: float, w: float, dt: float, sample, index: dict) -> list:
        (v0, w0), (v1, w1) = self.history
        v = self.limiters[0].limit(v, v0, v1, dt)
        w = self.limiters[1].limit(w, w0, w1, dt)
        self.history = [(v, w), (v0, w0)]
        return self.drive(v, w)

    def drive(self, v: float, w: float) -> list:
        left, right = diff_drive.wheel_speeds(self.geometry, v, w)
        return [Write(self.left + self.right,
                      [left] * len(self.left) + [right] * len(self.right), 'velocity')]

    def track(self, t: float, sample, index: dict) -> None:
        self.odometry.update(t, _mean(sample, index, self.left), _mean(sample, index, self.right))


class SteeringLaw(BaseLaw):
    """
    A car-like base's: steering joints by position, traction joints by velocity.

    The tricycle's outputs are limited (``traction.*``, ``steering.*``) and its wheel slowed
    while it is far from its angle (cos of the error; 0.01 beyond 90 degrees), as
    tricycle_controller does; its ``cmd_vel_timeout`` is in milliseconds, as its own.
    """

    def __init__(self, params: dict, rate_hz: float, kind):
        super().__init__(params, rate_hz)
        p, self.type = params, kind
        tricycle = kind is types.Tricycle
        self.traction, self.steering = (tuple(j) for j in kind.joints(p))
        self.length = p['wheelbase']
        self.radius = p[kind.radius]
        self.track_width = p.get('rear_wheel_track') or p.get('front_wheel_track') or 0.0
        self.odometry = SteeringOdometry(self.length, self.radius, tricycle)
        self.limiters = (limits.traction(p), limits.steering(p)) if tricycle else None
        self.timeout = p['cmd_vel_timeout'] / 1000.0 if tricycle else p['reference_timeout']
        self.restart()

    def _outputs(self, v: float, w: float) -> steering.Steered:
        if self.type is types.Ackermann:
            return steering.ackermann(self.length, self.track_width, self.radius, v, w)
        if self.type is types.Bicycle:
            return steering.bicycle(self.length, self.radius, v, w)
        return steering.tricycle(self.length, self.radius, v, w)

    def steer(self, v: float, w: float, dt: float, sample, index: dict) -> list:
        if self.limiters is None:
            return self.drive(v, w)
        out = self._outputs(v, w)  # the tricycle: one steered wheel that drives
        angle, speed = out.steering[0], out.traction[0]
        off = abs(angle - float(sample.position[index[self.steering[0]]]))
        speed *= 1.0 if off < math.pi / 6 else 0.01 if off > math.pi / 2 else math.cos(off)
        (s0, a0), (s1, a1) = self.history
        speed = self.limiters[0].limit(speed, s0, s1, dt)
        angle = self.limiters[1].limit(angle, a0, a1, dt)
        self.history = [(speed, angle), (s0, a0)]
        return self._writes([angle], [speed])

    def drive(self, v: float, w: float) -> list:
        out = self._outputs(v, w)
        return self._writes(list(out.steering), list(out.traction))

    def _writes(self, angles: list, speeds: list) -> list:
        n, m = len(self.steering), len(self.traction)
        angles = angles * n if len(angles) == 1 else angles[:n]
        speeds = speeds * m if len(speeds) == 1 else speeds[:m]
        return [Write(self.steering, angles, 'position'),
                Write(self.traction, speeds, 'velocity')]

    def track(self, t: float, sample, index: dict) -> None:
        self.odometry.update(t, _mean(sample, index, self.traction),
                             _mean(sample, index, self.steering))


class GripperGoal:
    """A gripper goal as its law decides it: `done` is set once `how` is known."""

    def __init__(self, target: float):
        self.target = target
        self.done = threading.Event()
        self.how = ''  # 'reached', 'stalled' or 'ended' (preempted, deactivated, a reset)
        self.position = math.nan
        self.effort = 0.0
        self.slow_since: Optional[float] = None

    def end(self, how: str) -> None:
        self.how = how
        self.done.set()


class GripperLaw(Law):
    """The gripper action controllers': a goal decided in simulated time at each update."""

    def __init__(self, params: dict, rate_hz: float):
        super().__init__(params, rate_hz)
        p = params
        self.joint = p['joint']
        self.tolerance = p['goal_tolerance']
        self.stall_speed = p['stall_velocity_threshold']
        self.stall_time = p['stall_timeout']
        self.goal: Optional[GripperGoal] = None

    def start(self, target: float) -> tuple:
        """Start a goal (preempting the running one); return it and the command to write."""
        goal = GripperGoal(float(target))
        with self.lock:
            if self.goal is not None:
                self.goal.end('ended')
            self.goal = goal
        return goal, [Write((self.joint,), [goal.target], 'position')]

    def drop(self, goal: GripperGoal) -> None:
        """Stop deciding `goal` (canceled); the finger stays commanded where it was sent."""
        with self.lock:
            if self.goal is goal:
                self.goal = None
        goal.end(goal.how or 'ended')

    def restart(self) -> None:
        if self.goal is not None:
            self.goal.end('ended')
            self.goal = None

    def deactivate(self) -> list:
        writes = super().deactivate()
        with self.lock:
            self.restart()
        return writes

    def update(self, sample, index: dict) -> list:
        goal = self.goal
        if goal is None:
            return []
        i = index[self.joint]
        q, v = float(sample.position[i]), float(sample.velocity[i])
        goal.position, goal.effort = q, float(sample.effort[i])
        if abs(q - goal.target) <= self.tolerance:
            goal.end('reached')
        else:
            slow = abs(v) < self.stall_speed
            goal.slow_since = (goal.slow_since if goal.slow_since is not None else sample.time) \
                if slow else None
            if slow and sample.time - goal.slow_since >= self.stall_time:
                goal.end('stalled')
        if goal.done.is_set():
            self.goal = None
        return []


def law_for(kind, params: dict, rate_hz: float) -> Optional[Law]:
    """Return the law of a controller type's class (None: a type whose ROS side is all)."""
    if kind is types.DiffDrive:
        return DiffDriveLaw(params, rate_hz)
    if kind in (types.Ackermann, types.Bicycle, types.Tricycle):
        return SteeringLaw(params, rate_hz, kind)
    if kind is types.Gripper:
        return GripperLaw(params, rate_hz)
    return None


class Laws:
    """
    One robot's laws, updated at its joint samples (:meth:`tick`, the stepping side).

    :param joints: the sampled joints by the robot's names, in the samples' order.
    :param within: (joint, interface, value) -> the value within that interface's limits.
    :param internal: a robot joint's name -> the world's.
    """

    def __init__(self, joints: Sequence[str], within: Callable, internal: Callable):
        self.index = {j: i for i, j in enumerate(joints)}
        self.within, self.internal = within, internal
        self._laws: dict = {}  # controller name -> Law; replaced whole, never changed in place
        self.failures: list = []  # (controller, repr of the exception): the latest few

    def put(self, name: str, law: Optional[Law]) -> None:
        """Add, replace or (None) remove a controller's law."""
        laws = dict(self._laws)
        if law is None:
            laws.pop(name, None)
        else:
            laws[name] = law
        self._laws = laws

    def world_writes(self, writes: Sequence[Write]) -> list:
        """Return `writes` as the world takes them: its joint names, within the limits."""
        return [([self.internal(j) for j in w.joints],
                 [self.within(j, w.interface, v) for j, v in zip(w.joints, w.values)],
                 w.interface) for w in writes]

    def tick(self, sample) -> list:
        """Update the laws due at `sample`; return their commands as the world takes them."""
        out = []
        for name, law in self._laws.items():
            with law.lock:
                if not law.due(sample):
                    continue
                try:
                    out += self.world_writes(law.update(sample, self.index))
                except Exception as exc:  # noqa: B902 (one controller's failure stops no other)
                    self.failures = (self.failures + [(name, repr(exc))])[-5:]
        return out
