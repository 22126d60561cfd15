"""
joint_trajectory_controller as a robot's YAML names it, with the real controller's interfaces.

``~/follow_joint_trajectory`` (control_msgs/FollowJointTrajectory), ``~/joint_trajectory``
(trajectory_msgs/JointTrajectory: a trajectory without a goal, preempting), and
``~/controller_state`` (control_msgs/JointTrajectoryControllerState) at its update rate of
simulated time. Its YAML's ``joints``, ``command_interfaces`` and ``state_interfaces``, the
``constraints`` (``goal_time``, ``stopped_velocity_tolerance``, ``<joint>.trajectory`` and
``<joint>.goal``: the default path and goal tolerances a goal's own replace), and
``allow_partial_joints_goal`` (else a goal must name every joint) and
``allow_nonzero_velocity_at_trajectory_end`` and ``open_loop_control`` (a new goal starts
from what was last commanded, not from the joints' state) are read. On activation it holds
the joints where they are; a new goal preempts the running one (aborted); deactivation
aborts it and holds. Goals run as the node's own trajectories do
(:mod:`sim_node.core.control.trajectory`: interpolated by the fields given, in simulated
time).
"""

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from msg_adapters import convert
from rclpy.action import CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from trajectory_msgs.msg import JointTrajectory

from .controllers import NO_EVENTS, NO_SUB_EVENTS, Runtime
from ..commands.trajectories import finish, LeavableActionServer, point, seconds, tolerances
from ...core.base.errors import SimError
from ...core.control import trajectory

ERR_PARTIAL = ('the goal names {given} of joints {joints}: a goal must name them all unless '
               'allow_partial_joints_goal is true')
ERR_UNKNOWN = "joints {names} are not this controller's ({joints})"


class TrajectoryController(Runtime):
    """joint_trajectory_controller (see the module docstring)."""

    def make(self) -> None:
        p = self.params
        self.joints = tuple(self.controller.joints)
        self.partial = p['allow_partial_joints_goal']
        self.end_velocity = p['allow_nonzero_velocity_at_trajectory_end']
        self.open_loop = p['open_loop_control']
        self.goal_time = p['constraints.goal_time']
        self.stopped = p['constraints.stopped_velocity_tolerance']
        self.path = {j: _number(p.get(f'constraints.{j}.trajectory')) for j in self.joints}
        self.goal = {j: _number(p.get(f'constraints.{j}.goal')) for j in self.joints}
        self.handle = None
        group = ReentrantCallbackGroup()
        self.server = LeavableActionServer(
            self.node, FollowJointTrajectory, '~/follow_joint_trajectory',
            execute_callback=self._execute, goal_callback=self._check,
            cancel_callback=lambda goal: CancelResponse.ACCEPT, callback_group=group)
        self.node.create_subscription(JointTrajectory, '~/joint_trajectory', self._on_topic, 10,
                                      **NO_SUB_EVENTS)
        self.state_pub = self.node.create_publisher(
            JointTrajectoryControllerState, '~/controller_state', 10, **NO_EVENTS)

    def activate(self, sample) -> None:
        super().activate(sample)
        self.handle = None
        self.host.hold(self.joints, 'position')  # where they are, as the real one starts

    def deactivate(self) -> None:
        super().deactivate()
        if self.handle is not None:
            self.handle.cancel()
        self.host.hold(self.joints, 'position')

    # ------------------------------------------------------------------ goals

    def _names(self, given) -> list:
        names = list(given)
        unknown = [n for n in names if n not in self.joints]
        if unknown:
            raise trajectory.TrajectoryError(trajectory.INVALID_JOINTS, ERR_UNKNOWN.format(
                names=unknown, joints=list(self.joints)))
        if not self.partial and set(names) != set(self.joints):
            raise trajectory.TrajectoryError(trajectory.INVALID_JOINTS, ERR_PARTIAL.format(
                given=names, joints=list(self.joints)))
        return names

    def _start(self, jt, goal=None, check: bool = False):
        if not self.active:
            raise trajectory.TrajectoryError(trajectory.INVALID_GOAL,
                                             f'controller {self.name!r} is not active')
        names = self._names(jt.joint_names)
        world = self.host.world()
        inner = [self.host.internal(n) for n in names]
        points = ([seconds(p.time_from_start) for p in jt.points],
                  [list(p.positions) for p in jt.points], [list(p.velocities) for p in jt.points],
                  [list(p.accelerations) for p in jt.points])
        start = seconds(jt.header.stamp)
        if check:
            return world.check_trajectory(self.host.entity, inner, *points, start_time=start,
                                          allow_end_velocity=self.end_velocity)
        path = tolerances(names, goal.path_tolerance if goal else (), 0.0)
        end = tolerances(names, goal.goal_tolerance if goal else (), 0.0)
        path = {self.host.internal(n): (v[0] or self.path[n] or 0.0, v[1], v[2])
                for n, v in path.items()}
        end = {self.host.internal(n): (v[0] or self.goal[n] or 0.0, v[1] or self.stopped, v[2])
               for n, v in end.items()}
        gtt = seconds(goal.goal_time_tolerance) if goal else 0.0
        self.handle = world.follow_trajectory(
            self.host.entity, inner, *points, start_time=start, path_tolerance=path,
            goal_tolerance=end, goal_time_tolerance=gtt if gtt > 0 else self.goal_time,
            allow_end_velocity=self.end_velocity, open_loop=self.open_loop)
        return self.handle

    def _check(self, goal) -> GoalResponse:
        try:
            self._start(goal.trajectory, goal, check=True)
        except (trajectory.TrajectoryError, SimError) as exc:
            self.refuse('follow_joint_trajectory', str(exc), goal.trajectory.joint_names)
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _on_topic(self, msg: JointTrajectory) -> None:
        if not msg.points:  # an empty trajectory stops the running one, as the real one
            if self.handle is not None:
                self.handle.cancel()
            return
        try:
            self._start(msg)
        except (trajectory.TrajectoryError, SimError) as exc:
            self.refuse('joint_trajectory', str(exc), msg.joint_names)

    def _execute(self, goal_handle):
        goal = goal_handle.request
        result = FollowJointTrajectory.Result()
        try:
            handle = self._start(goal.trajectory, goal)
        except (trajectory.TrajectoryError, SimError) as exc:
            goal_handle.abort()
            result.error_code = getattr(exc, 'code', trajectory.INVALID_GOAL)
            result.error_string = str(exc)
            return result
        names = list(goal.trajectory.joint_names)
        while not handle.wait(0.05):
            if goal_handle.is_cancel_requested:
                handle.cancel()
                break
            st = handle.status
            if st.desired and goal_handle.is_active:
                fb = FollowJointTrajectory.Feedback(joint_names=names)
                (qd, vd, ad), (q, v) = st.desired, st.actual
                fb.desired, fb.actual = point(qd, vd, ad), point(q, v)
                fb.error = point(qd - q, vd - v)
                fb.header.stamp = convert.clock(st.time).clock
                goal_handle.publish_feedback(fb)
        return finish(goal_handle, handle, result)

    # ------------------------------------------------------------------ state

    def update(self, sample, index: dict) -> None:
        if self.state_pub.get_subscription_count() == 0:
            return  # nobody listens: nothing to build (the real one's publisher skips too)
        q = [float(sample.position[index[j]]) for j in self.joints]
        v = [float(sample.velocity[index[j]]) for j in self.joints]
        e = [float(sample.effort[index[j]]) for j in self.joints]
        handle = self.handle
        st = handle.status if handle is not None else None
        if st is not None and st.desired and not handle.done:
            qd = dict(zip(handle.trajectory.joints, st.desired[0]))
            vd = dict(zip(handle.trajectory.joints, st.desired[1]))
            ref = [qd.get(self.host.internal(j), x) for j, x in zip(self.joints, q)]
            vref = [vd.get(self.host.internal(j), 0.0) for j in self.joints]
        else:
            ref, vref = q, [0.0] * len(q)
        msg = JointTrajectoryControllerState(
            joint_names=list(self.joints), reference=point(ref, vref), feedback=point(q, v),
            error=point([a - b for a, b in zip(ref, q)], [a - b for a, b in zip(vref, v)]),
            output=point(e=e), speed_scaling_factor=1.0)
        msg.header.stamp = convert.stamp(sample.time)
        self.state_pub.publish(msg)


def _number(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        and value > 0 else 0.0
