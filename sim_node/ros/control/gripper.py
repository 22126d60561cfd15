"""
Gripper action controllers as ros2_controllers' have them: ``~/gripper_cmd``.

``position_controllers/GripperActionController`` and ``effort_controllers/...`` take
control_msgs/GripperCommand (a position, a max effort), ``parallel_gripper_action_controller``
control_msgs/ParallelGripperCommand (a JointState with the joint's position). Each drives its
``joint`` to the position (within the interface's min and max) and watches it at
``action_monitor_rate`` (wall time): it succeeds with ``reached_goal`` once within
``goal_tolerance``; a finger that stops short (slower than ``stall_velocity_threshold`` for
``stall_timeout`` simulated seconds: it holds something) succeeds with ``stalled`` when
``allow_stalling``, else aborts; a new goal preempts the running one.
"""

import math
import threading

from control_msgs.action import GripperCommand, ParallelGripperCommand
from rclpy.action import CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from sensor_msgs.msg import JointState

from .controllers import Runtime
from ..commands.trajectories import LeavableActionServer
from ...core.control import controller_types as types


class GripperAction(Runtime):
    """A gripper action controller (see the module docstring)."""

    def make(self) -> None:
        p = self.params
        self.joint = p['joint']
        self.parallel = self.controller.kind == types.PARALLEL_GRIPPER
        self.tolerance = p['goal_tolerance']
        self.stall_speed = p['stall_velocity_threshold']
        self.stall_time = p['stall_timeout']
        self.allow_stalling = p['allow_stalling']
        self.period = 1.0 / p['action_monitor_rate']
        self.goal_id = 0
        self._lock = threading.Lock()
        self.server = LeavableActionServer(
            self.node, ParallelGripperCommand if self.parallel else GripperCommand,
            '~/gripper_cmd', execute_callback=self._execute, goal_callback=self._check,
            cancel_callback=lambda goal: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup())

    def activate(self, sample) -> None:
        super().activate(sample)
        self.host.hold((self.joint,), 'position')

    def _target(self, goal):
        if not self.parallel:
            return goal.command.position
        cmd = goal.command
        if list(cmd.name) not in ([], [self.joint]) or len(cmd.position) != 1:
            return None
        return cmd.position[0]

    def _check(self, goal) -> GoalResponse:
        target = self._target(goal)
        if not self.active or target is None or not math.isfinite(target):
            self.refuse('gripper_cmd', f'{self.name} is not active' if not self.active else
                        f'a goal with no finite position for {self.joint!r}', [self.joint])
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _execute(self, goal_handle):
        target = self._target(goal_handle.request)
        with self._lock:
            self.goal_id += 1
            mine = self.goal_id
        self.host.command((self.joint,), (target,), 'position')
        slow_since = None
        while True:
            sample = self.host.latest
            q, v, effort, t = self._state(sample)
            reached = abs(q - target) <= self.tolerance
            slow_since = (slow_since if slow_since is not None else t) \
                if abs(v) < self.stall_speed and not reached else None
            stalled = slow_since is not None and t - slow_since >= self.stall_time
            if mine != self.goal_id or not self.active or goal_handle.is_cancel_requested:
                return self._end(goal_handle, q, effort, False, False,
                                 'canceled' if goal_handle.is_cancel_requested else 'aborted')
            if reached or stalled:
                ok = reached or self.allow_stalling
                return self._end(goal_handle, q, effort, stalled, reached,
                                 'succeed' if ok else 'aborted')
            threading.Event().wait(self.period)

    def _state(self, sample) -> tuple:
        if sample is None:
            return math.nan, 0.0, 0.0, 0.0
        i = list(self.host.hardware).index(self.joint)
        return (float(sample.position[i]), float(sample.velocity[i]),
                float(sample.effort[i]), sample.time)

    def _end(self, goal_handle, q: float, effort: float, stalled: bool, reached: bool,
             how: str):
        if self.parallel:
            result = ParallelGripperCommand.Result(stalled=stalled, reached_goal=reached)
            result.state = JointState(name=[self.joint], position=[q], effort=[effort])
        else:
            result = GripperCommand.Result(position=q, effort=effort, stalled=stalled,
                                           reached_goal=reached)
        if how == 'succeed':
            goal_handle.succeed()
        elif how == 'canceled':
            goal_handle.canceled()
        else:
            goal_handle.abort()
        return result
