"""
FollowJointTrajectory on robot files, checked as an independent client checks it.

Two arms spawned by URI into the default scene at real_time_factor 1: robosuite's Panda (seven
motors of 12-80 N m) and Gymnasium's pusher (seven motors of 2 N m: it was made for a world
without gravity, and in this one it cannot hold its own arm up). The client knows only the
released interfaces: it reads ``joint_states`` (positions and stamps), ``/clock`` and the
action's result, and judges against the linear interpolation between the goal's knots in
simulated time. The Panda follows; the pusher is reported as unable to, never as a success; a
pause holds a driven arm still while a goal waits; a cancel leaves the joints where it found
them.
"""

from pathlib import Path
import sys
import threading
import time

from conftest import action_client, serve_node, wait_for, Watcher
from control_msgs.action import FollowJointTrajectory
import gymnasium
import numpy as np
import pytest
from sensor_msgs.msg import JointState
from sim_node.ros.commands.trajectories import duration
from trajectory_msgs.msg import JointTrajectoryPoint

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
import corpus  # noqa: E402, I100

GYM = Path(gymnasium.__file__).parent / 'envs' / 'mujoco' / 'assets'
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6
R = FollowJointTrajectory.Result
OFFSETS = (0.15, 0.3, 0.2)  # rad, at 1, 2 and 3 s: the independent client's goal


@pytest.fixture(scope='module')
def node():
    folder = corpus.fetch()
    yield from serve_node(f'resource_paths:=["{folder}", "{GYM}"]')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    w.history = []  # every joint_states: (stamp, {name: (position, effort)})
    lock = threading.Lock()

    def keep(msg):
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        effort = list(msg.effort) or [0.0] * len(msg.name)
        with lock:
            w.history.append((stamp, dict(zip(msg.name, zip(msg.position, effort)))))
    w.node.create_subscription(JointState, 'joint_states', keep, 100)
    yield w
    w.close()


def panda_uri() -> str:
    return next(m for m in corpus.MODELS if 'panda' in m.path).file.as_uri()


def pusher_uri() -> str:
    return (GYM / 'pusher_v5.xml').as_uri()


@pytest.fixture
def robot(sim, watch, request):
    """Spawn one arm, wait until it has come to rest; yield (client, action client, joints)."""
    which = request.param
    name = sim.spawn(which, uri=panda_uri() if which == 'panda' else pusher_uri(),
                     position=(2.0, 2.0, 0.0 if which == 'panda' else 0.6))
    wait_for(lambda: watch.history and any(n.startswith(name + '/')
                                           for n in watch.history[-1][1]), timeout=20)
    joints = [n for n in watch.history[-1][1] if n.startswith(name + '/')
              and 'slide' not in n][:7]  # the arm's seven joints, not the pusher's puck

    def at_rest() -> bool:
        # Still over half a second of simulated time (a wall-clock pause proves nothing on a
        # loaded host: joint_states may not have come at all), by the messages' own stamps.
        time.sleep(0.1)
        stamp, last = watch.history[-1]
        before = [m for s, m in watch.history if s <= stamp - 0.5 and joints[0] in m]
        if not before or joints[0] not in last:
            return False
        return max(abs(last[j][0] - before[-1][j][0]) for j in joints) < 1e-3
    wait_for(at_rest, timeout=20, interval=0.0)
    client = action_client(watch.node, FollowJointTrajectory, f'{name}/follow_joint_trajectory')
    assert client.wait_for_server(timeout_sec=15)
    yield sim, client, joints
    client.destroy()
    sim.delete(name)


def positions(watch, joints) -> np.ndarray:
    last = watch.history[-1][1]
    return np.array([last[j][0] for j in joints])


def ranges(watch, joints) -> np.ndarray:
    """Each joint's range, from the entity's robot_description (URDF)."""
    import xml.etree.ElementTree as ET
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String
    got = []
    sub = watch.node.create_subscription(
        String, joints[0].split('/')[0] + '/robot_description', got.append,
        QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    try:
        wait_for(lambda: got, timeout=15)
    finally:
        watch.node.destroy_subscription(sub)
    urdf = ET.fromstring(got[0].data)
    return np.array([(float(urdf.find(f"joint[@name='{j}']/limit").get('lower')),
                      float(urdf.find(f"joint[@name='{j}']/limit").get('upper')))
                     for j in joints])


def inward_goal(watch, joints, q0, lead: float = 0.0):
    """
    Return the client's three-point goal, its knots and its start in simulated time.

    Each joint's offsets point into its range. With a `lead`, the goal starts that long after
    the latest /clock (a stamp in the future: the client knows when it starts); else on arrival.
    """
    rng = ranges(watch, joints)
    stamp = watch.latest_clock() + lead if lead else 0.0  # after the ranges came, not before
    sign = np.where(q0 + max(OFFSETS) + 0.05 < rng[:, 1], 1.0, -1.0)
    knots = [q0 + k * sign for k in OFFSETS]
    g = FollowJointTrajectory.Goal()
    g.trajectory.joint_names = list(joints)
    g.trajectory.header.stamp.sec = int(stamp)
    g.trajectory.header.stamp.nanosec = int(round((stamp - int(stamp)) * 1e9))
    for t, q in zip((1.0, 2.0, 3.0), knots):
        g.trajectory.points.append(JointTrajectoryPoint(positions=list(q),
                                                        time_from_start=duration(t)))
    return g, knots, stamp


def send(client, g):
    future = client.send_goal_async(g)
    wait_for(future.done, timeout=10)
    return future.result()


def result_of(handle, timeout: float = 30.0):
    future = handle.get_result_async()
    wait_for(future.done, timeout=timeout)
    return future.result().status, future.result().result


def deviation(watch, joints, start: float, q0, knots) -> float:
    """Worst |joint_states - linear interpolation of the knots| from `start` to the end."""
    kt = [0.0, 1.0, 2.0, 3.0]
    kq = np.array([q0] + list(knots))
    worst = 0.0
    for stamp, msg in list(watch.history):
        t = stamp - start
        if t < 0 or t > 3.0:
            continue
        want = np.array([np.interp(t, kt, kq[:, i]) for i in range(len(joints))])
        worst = max(worst, float(np.abs(np.array([msg[j][0] for j in joints]) - want).max()))
    return worst


@pytest.mark.parametrize('robot', ['panda'], indirect=True)
def test_the_panda_follows_the_interpolated_path_and_ends_on_its_last_point(robot, watch):
    sim, client, joints = robot
    q0 = positions(watch, joints)
    g, knots, start = inward_goal(watch, joints, q0, lead=3.0)
    accepted = send(client, g)
    # Three seconds ahead of the /clock this client has seen: its own lag under load (its
    # thread behind on a flood of joint_states) must not make the goal start in the past.
    assert watch.latest_clock() < start, 'the goal came after its own start: a slow test host'
    status, res = result_of(accepted)
    assert status == SUCCEEDED and res.error_code == R.SUCCESSFUL, res.error_string
    # Computed-torque PD at kp 400: a velocity step of 0.15 rad/s lags by 0.15 / (e 20).
    assert deviation(watch, joints, start, q0, knots) < 0.03
    time.sleep(0.5)
    assert np.abs(positions(watch, joints) - knots[-1]).max() < 0.01


@pytest.mark.parametrize('robot', ['pusher'], indirect=True)
def test_the_pusher_cannot_follow_and_is_told_so_not_succeeded(robot, watch):
    sim, client, joints = robot
    q0 = positions(watch, joints)
    g, _, _ = inward_goal(watch, joints, q0, lead=3.0)
    status, res = result_of(send(client, g))
    assert status == ABORTED, res.error_string
    assert res.error_code == R.PATH_TOLERANCE_VIOLATED
    assert 'than the actuators can give' in res.error_string
    # Its motors gave what their file allows (2 N m), no more: the arm sagged instead.
    efforts = [abs(msg[j][1]) for _, msg in watch.history if joints[0] in msg for j in joints]
    assert max(efforts) <= 2.0 + 1e-6


@pytest.mark.parametrize('robot', ['pusher'], indirect=True)
def test_a_goal_past_a_joints_range_is_rejected(robot, watch):
    sim, client, joints = robot
    q0 = positions(watch, joints)
    g, _, _ = inward_goal(watch, joints, q0)
    elbow = joints.index('pusher/r_elbow_flex_joint')  # range [-2.32, 0]
    for p in g.trajectory.points:
        p.positions[elbow] = 0.3
    assert not send(client, g).accepted


@pytest.mark.parametrize('robot', ['panda', 'pusher'], indirect=True)
def test_paused_a_driven_arm_stays_still_while_its_goal_waits(robot, watch):
    sim, client, joints = robot
    sim.pause()
    try:
        time.sleep(0.3)  # what was published before the pause has arrived
        clock, before = watch.latest_clock(), positions(watch, joints)
        g, _, _ = inward_goal(watch, joints, before)
        handle = send(client, g)
        assert handle.accepted
        time.sleep(1.5)
        assert watch.latest_clock() == clock
        assert np.array_equal(positions(watch, joints), before)
    finally:
        sim.play()
    result_of(handle)


@pytest.mark.parametrize('robot', ['panda'], indirect=True)
def test_a_cancel_leaves_the_joints_where_it_found_them(robot, watch):
    sim, client, joints = robot
    q0 = positions(watch, joints)
    g, knots, _ = inward_goal(watch, joints, q0)
    handle = send(client, g)
    time.sleep(1.5)
    future = handle.cancel_goal_async()
    wait_for(future.done, timeout=10)
    status, res = result_of(handle)
    assert status == CANCELED and res.error_code == R.SUCCESSFUL
    time.sleep(0.3)
    here = positions(watch, joints)
    assert np.abs(here - q0).max() > 0.05  # it had moved
    time.sleep(1.0)
    assert np.abs(positions(watch, joints) - here).max() < 0.005
