"""
FollowJointTrajectory over the wire, as MoveIt sends it, from a separate process.

The node runs the default scene in real time; a two-joint arm without actuators (PD) is spawned
by resource_string. Each behaviour of the controller is one test: success within the timing and
at the last point, the error codes, preemption, cancel, tolerances, pause, feedback and the
controller state, and the action server coming and going with its entity.
"""

import time

from conftest import action_client, serve_node, TWO_JOINT_ARM, wait_for, Watcher
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance, JointTrajectoryControllerState
import pytest
from rclpy.action.client import ClientGoalHandle
from sim_node.ros.commands.trajectories import duration
from trajectory_msgs.msg import JointTrajectoryPoint

ARM = TWO_JOINT_ARM
JOINTS = ['arm/j1', 'arm/j2']
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 4, 5, 6


@pytest.fixture(scope='module')
def node():
    yield from serve_node('trajectory_feedback_hz:=20.0')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


@pytest.fixture
def arm(sim, watch):
    """Return the module's client (world reset and playing) with the arm spawned."""
    from sensor_msgs.msg import JointState
    sim.spawn('arm', resource_string=ARM, position=(2.0, 2.0, 1.0))
    # Held level and still before each test: the arm has no actuators and would swing down.
    # The hold must be in force before a goal is sent, or arriving later it would claim the
    # goal's joints: sent once the node listens, and seen holding for half a simulated second
    # (unheld, the arm would have swung far down by then).
    pub = watch.node.create_publisher(JointState, 'joint_commands', 10)
    wait_for(lambda: pub.get_subscription_count() > 0, timeout=10)
    t0 = wait_for(lambda: arm_stamp(watch), timeout=10)  # the arm is in the world
    pub.publish(JointState(name=JOINTS, position=[0.0, 0.0]))
    client = action_client(watch.node, FollowJointTrajectory, 'arm/follow_joint_trajectory')
    assert client.wait_for_server(timeout_sec=15)
    wait_for(lambda: arm_stamp(watch) > t0 + 0.5 and abs(joint(watch, 'arm/j1')) < 0.01
             and abs(watch.joint_states.velocity[list(watch.joint_states.name).index(
                 'arm/j1')]) < 0.01, timeout=10)
    yield sim, client
    client.destroy()
    watch.node.destroy_publisher(pub)


def arm_stamp(watch) -> float:
    """Return the stamp of the latest joint_states if the arm is in it, else 0."""
    js = watch.joint_states
    if js is None or 'arm/j1' not in js.name:
        return 0.0
    return js.header.stamp.sec + js.header.stamp.nanosec * 1e-9


def goal(points, joints=JOINTS, stamp_sec: float = 0.0, goal_tol: float = 0.0,
         goal_time: float = 0.0, path_tol: float = 0.0):
    g = FollowJointTrajectory.Goal()
    g.trajectory.joint_names = list(joints)
    g.trajectory.header.stamp.sec = int(stamp_sec)
    for t, q in points:
        g.trajectory.points.append(JointTrajectoryPoint(positions=list(q),
                                                        time_from_start=duration(t)))
    if goal_tol:
        g.goal_tolerance = [JointTolerance(name=n, position=goal_tol) for n in joints]
    if path_tol:
        g.path_tolerance = [JointTolerance(name=n, position=path_tol) for n in joints]
    g.goal_time_tolerance = duration(goal_time)
    return g


def send(client, g, feedback=None) -> ClientGoalHandle:
    future = client.send_goal_async(g, feedback_callback=feedback)
    wait_for(future.done, timeout=10)
    handle = future.result()
    assert handle.accepted
    return handle


def result_of(handle: ClientGoalHandle, timeout: float = 20.0):
    future = handle.get_result_async()
    wait_for(future.done, timeout=timeout)
    res = future.result()
    return res.status, res.result


def joint(watch, name: str) -> float:
    js = watch.joint_states
    return js.position[list(js.name).index(name)]


def test_a_three_point_trajectory_succeeds_on_time_at_its_last_point(arm, watch):
    sim, client = arm
    feedback = []
    t0 = watch.latest_clock()
    h = send(client, goal([(0.4, (0.3, -0.3)), (0.8, (0.6, -0.6)), (1.2, (0.8, -0.4))],
                          goal_tol=0.01, goal_time=0.5), feedback.append)
    status, res = result_of(h)
    t1 = watch.latest_clock()
    assert status == STATUS_SUCCEEDED and res.error_code == 0, res.error_string
    assert t1 - t0 <= 1.2 * 1.2 + 0.5
    # Success comes when the tolerance is first met; the PD then settles there.
    wait_for(lambda: abs(joint(watch, 'arm/j1') - 0.8) < 0.01
             and abs(joint(watch, 'arm/j2') + 0.4) < 0.01, timeout=3)
    assert len(feedback) >= 5  # 20 Hz over about a second
    fb = feedback[-1].feedback
    assert list(fb.joint_names) == JOINTS and len(fb.desired.positions) == 2
    # along the interpolated path, PD gains kp 400, kd 40 per unit of joint inertia
    assert max(abs(e) for f in feedback for e in f.feedback.error.positions) < 0.05


R = FollowJointTrajectory.Result


@pytest.mark.parametrize('case', [
    {'joints': ['arm/j1', 'arm/nope'], 'code': R.INVALID_JOINTS, 'text': 'nope'},
    {'joints': ['j1'], 'code': R.INVALID_JOINTS, 'text': "did you mean 'arm/j1'"},
    {'joints': ['arm/j1', 'left_elbow'], 'code': R.INVALID_JOINTS, 'text': 'one entity'},
    {'points': [(1.0, (0.1, 0.1)), (1.0, (0.2, 0.2))], 'code': R.INVALID_GOAL,
     'text': 'increase'},
    {'points': [(1.0, (0.1,))], 'code': R.INVALID_GOAL, 'text': '1 positions for 2'},
    {'points': [], 'code': R.INVALID_GOAL, 'text': 'no points'},
    {'stamp': 1, 'code': R.OLD_HEADER_TIMESTAMP, 'text': 'past'},
    {'end_velocity': 0.5, 'code': R.INVALID_GOAL, 'text': 'must end at rest'},
], ids=['unknown', 'hint', 'two-entities', 'times', 'size', 'empty', 'old-stamp',
        'end-velocity'])
def test_bad_goals_are_rejected_as_the_controller_rejects_them_saying_why(arm, watch, case):
    """Rejected in the goal response (no result); the reason on /diagnostics and the log."""
    from diagnostic_msgs.msg import DiagnosticArray
    sim, client = arm
    wait_for(lambda: (watch.latest_clock() or 0) > 3.0, timeout=10)  # a stamp of 1 s is old
    got = []
    sub = watch.node.create_subscription(DiagnosticArray, '/diagnostics', got.append, 10)
    try:
        g = goal(case.get('points', [(0.5, (0.1, 0.1))]), joints=case.get('joints', JOINTS),
                 stamp_sec=case.get('stamp', 0))
        if 'end_velocity' in case:
            for p in g.trajectory.points:
                p.velocities = [case['end_velocity']] * 2
        future = client.send_goal_async(g)
        wait_for(future.done, timeout=10)
        assert not future.result().accepted

        def said() -> bool:
            return any(st.name.endswith(': arm/follow_joint_trajectory')
                       and case['text'] in st.message
                       and f"(error code {case['code']})" in st.message
                       and st.level == st.WARN for m in got for st in m.status)
        wait_for(said, timeout=10)
    finally:
        watch.node.destroy_subscription(sub)
    js = watch.joint_states  # and nothing moved
    assert abs(joint(watch, 'arm/j1')) < 0.01 and 'arm/j1' in js.name


def test_a_last_point_with_a_velocity_runs_when_the_parameter_allows_it(arm, watch):
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    sim, client = arm

    def allow(on: bool) -> None:
        req = SetParameters.Request(parameters=[Parameter(
            name='trajectory_allow_nonzero_velocity_at_end',
            value=ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=on))])
        assert sim.call('sim/set_parameters', SetParameters, req).results[0].successful
    allow(True)
    try:
        g = goal([(0.5, (0.2, 0.0))], goal_tol=0.05, goal_time=1.0)
        g.trajectory.points[0].velocities = [0.1, 0.0]
        status, res = result_of(send(client, g))
        assert status == STATUS_SUCCEEDED, res.error_string
    finally:
        allow(False)


def test_a_new_goal_preempts_the_running_one(arm, watch):
    sim, client = arm
    first = send(client, goal([(5.0, (1.0, -1.0))]))
    time.sleep(0.5)
    second = send(client, goal([(0.5, (-0.2, 0.2))], goal_tol=0.02, goal_time=1.0))
    status, res = result_of(first)
    assert status == STATUS_ABORTED
    assert res.error_code == FollowJointTrajectory.Result.INVALID_GOAL
    assert 'new incoming action' in res.error_string
    status, res = result_of(second)
    assert status == STATUS_SUCCEEDED and res.error_code == 0


def test_cancel_holds_the_joints_where_they_are(arm, watch):
    sim, client = arm
    h = send(client, goal([(4.0, (1.2, 0.0))]))
    time.sleep(1.5)
    future = h.cancel_goal_async()
    wait_for(future.done, timeout=5)
    status, _ = result_of(h)
    assert status == STATUS_CANCELED
    time.sleep(0.3)
    here = joint(watch, 'arm/j1')
    assert 0.1 < here < 1.1  # stopped midway
    time.sleep(1.0)
    assert abs(joint(watch, 'arm/j1') - here) < 0.005  # held, not drifting


def test_a_path_tolerance_violation_aborts_naming_the_joint(arm):
    sim, client = arm
    h = send(client, goal([(0.05, (2.0, 0.0))], path_tol=0.05))
    status, res = result_of(h)
    assert status == STATUS_ABORTED
    assert res.error_code == FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
    assert "'arm/j1'" in res.error_string and 'position error' in res.error_string


def test_a_goal_tolerance_violation_aborts_after_the_goal_time_tolerance(arm, watch):
    sim, client = arm
    # 0.5 rad in 10 ms, and then 0.2 s to be within a micro-radian: the PD cannot (path
    # tolerance off: -1, or the default 0.25 rad would end it on the way)
    h = send(client, goal([(0.01, (0.5, 0.0))], goal_tol=1e-6, goal_time=0.2, path_tol=-1.0))
    status, res = result_of(h)
    assert status == STATUS_ABORTED
    assert res.error_code == FollowJointTrajectory.Result.GOAL_TOLERANCE_VIOLATED
    assert 'goal tolerance' in res.error_string


# The behaviours joint_trajectory_controller's own action tests check
# (ros2_controllers, joint_trajectory_controller/test/test_trajectory_actions.cpp), here
# against this node over the wire.

def test_a_single_point_goal_succeeds_and_its_point_is_held(arm, watch):
    """As test_success_single_point_sendgoal: then it holds the point it reached."""
    sim, client = arm
    status, res = result_of(send(client, goal([(0.5, (0.4, -0.2))], goal_tol=0.01,
                                              goal_time=1.0)))
    assert status == STATUS_SUCCEEDED and res.error_code == R.SUCCESSFUL, res.error_string
    time.sleep(0.5)
    assert joint(watch, 'arm/j1') == pytest.approx(0.4, abs=0.01)
    assert joint(watch, 'arm/j2') == pytest.approx(-0.2, abs=0.01)


def test_a_goals_own_tolerances_apply_to_that_goal_alone(arm, watch):
    """As test_tolerances_via_actions: a goal's tolerances do not stay for the next goal."""
    sim, client = arm
    tight = goal([(0.2, (0.3, 0.0))], goal_tol=1e-7, goal_time=0.05, path_tol=-1.0)
    status, res = result_of(send(client, tight))
    assert res.error_code == R.GOAL_TOLERANCE_VIOLATED, res.error_string
    status, res = result_of(send(client, goal([(0.5, (0.1, 0.0))])))  # the defaults again
    assert status == STATUS_SUCCEEDED and res.error_code == R.SUCCESSFUL, res.error_string


def test_after_a_path_violation_the_joints_hold_where_it_left_them(arm, watch):
    """As test_state_tolerances_fail: aborted, then holding, not drifting."""
    sim, client = arm
    status, res = result_of(send(client, goal([(0.3, (1.0, 0.0))], path_tol=0.001)))
    assert res.error_code == R.PATH_TOLERANCE_VIOLATED
    time.sleep(0.3)
    here = joint(watch, 'arm/j1')
    assert abs(here) < 0.1  # stopped near where it started, not at 1.0
    time.sleep(0.5)
    assert abs(joint(watch, 'arm/j1') - here) < 0.005


def test_a_point_at_time_zero_far_from_the_joints_violates_the_path_at_once(arm, watch):
    """As test_no_time_from_start_state_tolerance_fail."""
    sim, client = arm
    status, res = result_of(send(client, goal([(0.0, (1.0, 0.0))], path_tol=0.01)))
    assert status == STATUS_ABORTED
    assert res.error_code == R.PATH_TOLERANCE_VIOLATED, res.error_string


def test_paused_the_trajectory_waits(arm, watch):
    sim, client = arm
    sim.pause()
    try:
        time.sleep(0.3)
        before = joint(watch, 'arm/j1')
        h = send(client, goal([(0.5, (before + 0.4, 0.0))], goal_tol=0.02, goal_time=1.0))
        time.sleep(1.0)
        assert abs(joint(watch, 'arm/j1') - before) < 1e-6  # time stood still, so did it
    finally:
        sim.play()
    status, res = result_of(h)
    assert status == STATUS_SUCCEEDED, res.error_string


def test_the_controller_state_is_published_while_a_goal_runs(arm, watch):
    sim, client = arm
    states = []
    sub = watch.node.create_subscription(JointTrajectoryControllerState, 'arm/controller_state',
                                         states.append, 10)
    try:
        # Long enough for the new subscription to be matched under a loaded CI machine (a 1 s
        # goal once ended before the subscription saw three states).
        h = send(client, goal([(3.0, (0.3, 0.3))]))
        wait_for(lambda: len(states) >= 3, timeout=10)
        result_of(h)
        s = states[-1]
        assert list(s.joint_names) == JOINTS and len(s.reference.positions) == 2
        assert len(s.feedback.positions) == 2 and s.speed_scaling_factor == 1.0
    finally:
        watch.node.destroy_subscription(sub)


def test_a_joint_command_on_a_driven_joint_ends_the_trajectory(arm, watch):
    sim, client = arm
    from sensor_msgs.msg import JointState
    pub = watch.node.create_publisher(JointState, 'joint_commands', 10)
    h = send(client, goal([(5.0, (1.0, 0.0))]))
    time.sleep(0.5)
    pub.publish(JointState(name=['arm/j2'], position=[-0.3]))
    status, res = result_of(h)
    assert status == STATUS_ABORTED and 'joint_commands' in res.error_string
    watch.node.destroy_publisher(pub)


def test_the_action_server_comes_and_goes_with_its_entity(arm, watch):
    from rclpy.action.graph import get_action_server_names_and_types_by_node
    sim, client = arm

    def names():  # the node's servers (our own client keeps the action's name in the graph)
        return {n for n, _ in get_action_server_names_and_types_by_node(watch.node, 'sim', '/')}
    wait_for(lambda: '/arm/follow_joint_trajectory' in names(), timeout=10)
    assert '/robot/follow_joint_trajectory' in names()  # the scene's robot has one too
    sim.delete('arm')
    wait_for(lambda: '/arm/follow_joint_trajectory' not in names(), timeout=10)


def test_a_refused_joint_command_is_reported_on_diagnostics_with_the_closest_names(arm, watch):
    """Not only in the node's log: /diagnostics says which joint and what was meant."""
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState
    got = []
    sub = watch.node.create_subscription(DiagnosticArray, '/diagnostics', got.append, 10)
    pub = watch.node.create_publisher(JointState, 'joint_commands', 10)
    try:
        def reported() -> bool:
            pub.publish(JointState(name=['j1'], position=[0.1]))
            return any(s.name.endswith(': joint_commands') and "did you mean 'arm/j1'"
                       in s.message and s.level == s.WARN for m in got for s in m.status)
        wait_for(reported, timeout=10, interval=0.3)
    finally:
        watch.node.destroy_subscription(sub)
        watch.node.destroy_publisher(pub)
