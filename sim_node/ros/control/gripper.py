"""
Gripper action controllers as ros2_controllers' have them: ``~/gripper_cmd``.

``position_controllers/GripperActionController`` and ``effort_controllers/...`` take
control_msgs/GripperCommand (a position, a max effort), ``parallel_gripper_action_controller``
control_msgs/ParallelGripperCommand (a JointState with the joint's position). Each drives its
``joint`` to the position (within the interface's min and max), and its law
(:class:`~sim_node.core.control.laws.GripperLaw`, on the stepping side at the controller's
update rate of simulated time) decides the goal: it succeeds with ``reached_goal`` once within
``goal_tolerance``; a finger that stops short (slower than ``stall_velocity_threshold`` for
``stall_timeout`` simulated seconds: it holds something) succeeds with ``stalled`` when
``allow_stalling``, else aborts; a new goal preempts the running one, and a reset of the world
or the controller's deactivation aborts it. The action's thread waits for the law's decision,
looking at ``action_monitor_rate`` (wall time) for a cancel.
"""

import math

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
        self.allow_stalling = p['allow_stalling']
        self.period = 1.0 / p['action_monitor_rate']
        self.server = LeavableActionServer(
            self.node, ParallelGripperCommand if self.parallel else GripperCommand,
            '~/gripper_cmd', execute_callback=self._execute, goal_callback=self._check,
            cancel_callback=lambda goal: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup())

    def activate(self, sample) -> None:
        super().activate(sample)
        self.law.activate()  # a goal running ends (a reset, a second activation)
        self.host.hold((self.joint,), 'position')

    def deactivate(self) -> None:
        super().deactivate()
        self.law.deactivate()

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
        goal, writes = self.law.start(self._target(goal_handle.request))
        self.host.write(writes)
        while not goal.done.wait(self.period):
            if goal_handle.is_cancel_requested or not self.active:
                self.law.drop(goal)
                break
        q, effort = goal.position, goal.effort
        if math.isnan(q):
            q, effort = self._state(self.host.latest)
        if goal_handle.is_cancel_requested:
            return self._end(goal_handle, q, effort, False, False, 'canceled')
        reached, stalled = goal.how == 'reached', goal.how == 'stalled'
        ok = reached or (stalled and self.allow_stalling)
        return self._end(goal_handle, q, effort, stalled, reached,
                         'succeed' if ok else 'aborted')

    def _state(self, sample) -> tuple:
        if sample is None:
            return math.nan, 0.0
        i = list(self.host.hardware).index(self.joint)
        return float(sample.position[i]), float(sample.effort[i])

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
