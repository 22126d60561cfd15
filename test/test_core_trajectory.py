"""
Joint trajectories in the core: interpolation against theory, and the controller's behaviours.

Interpolation is checked against the conditions that define it (the points, their velocities
and accelerations), not against the implementation. Behaviours use the default scene's robot
(four hinge joints with position servos) and a spawned two-joint arm without actuators (PD).
"""

from conftest import DEFAULT_SCENE, TWO_JOINT_ARM
import numpy as np
import pytest
from sim_node.core.control import trajectory
from sim_node.core.control.trajectory import TrajectoryError
from sim_node.core.models import sources
from sim_node.core.records import RESET_STATE
from sim_node.core.world import World

ARM = ['left_shoulder', 'left_elbow']


def traj(times, positions, velocities=None, accelerations=None, start=0.0):
    q = np.asarray(positions, float)
    return trajectory.Trajectory(
        joints=('a', 'b')[:q.shape[1]], start=start, times=np.asarray(times, float),
        positions=q, velocities=None if velocities is None else np.asarray(velocities, float),
        accelerations=None if accelerations is None else np.asarray(accelerations, float),
        start_positions=np.zeros(q.shape[1]), start_velocities=np.zeros(q.shape[1]))


def test_positions_only_interpolate_linearly_from_the_start_state():
    tr = traj([1.0, 2.0], [[1.0], [3.0]])
    assert tr.sample(0.5)[0] == pytest.approx([0.5])  # from the start position 0
    assert tr.sample(1.5)[0] == pytest.approx([2.0])
    assert tr.sample(1.5)[1] == pytest.approx([2.0])  # the segment's slope
    assert tr.sample(5.0)[0] == pytest.approx([3.0])  # holds the last point after the end
    assert tr.sample(-1.0)[0] == pytest.approx([0.0])  # holds the start before it


def test_velocities_give_a_cubic_through_points_and_velocities():
    tr = traj([0.0, 2.0], [[0.0], [1.0]], velocities=[[0.5], [-0.25]])
    eps = 1e-6
    for t, q, v in ((0.0, 0.0, 0.5), (2.0 - eps, 1.0, -0.25)):
        qs, vs, _ = tr.sample(t)
        assert qs == pytest.approx([q], abs=1e-5) and vs == pytest.approx([v], abs=1e-4)
    # the velocity is the derivative of the position (a cubic, not a line)
    (q1, v1, _), (q2, _, _) = tr.sample(0.7), tr.sample(0.7 + 1e-6)
    assert (q2 - q1) / 1e-6 == pytest.approx(v1, rel=1e-4)
    assert tr.sample(1.0)[0] != pytest.approx([0.5])


def test_accelerations_give_a_quintic_through_points_velocities_and_accelerations():
    tr = traj([0.0, 1.0], [[0.0], [1.0]], velocities=[[0.0], [0.2]],
              accelerations=[[1.0], [-2.0]])
    eps = 1e-7
    q0, v0, a0 = tr.sample(0.0)
    q1, v1, a1 = tr.sample(1.0 - eps)
    assert (q0, v0, a0) == (pytest.approx([0.0]), pytest.approx([0.0]), pytest.approx([1.0]))
    assert q1 == pytest.approx([1.0], abs=1e-5) and v1 == pytest.approx([0.2], abs=1e-4)
    assert a1 == pytest.approx([-2.0], abs=1e-3)


@pytest.fixture
def world():
    return World.from_file(str(DEFAULT_SCENE))


def run_until_done(w, handle, seconds: float) -> None:
    for _ in range(int(seconds / w.timestep)):
        w.step(1)
        if handle.done:
            return


ARM_PD = TWO_JOINT_ARM
PD_JOINTS = ['arm/j1', 'arm/j2']


def test_a_three_point_trajectory_is_followed_and_ends_at_its_last_point(world):
    """A two-joint arm without actuators (PD with gravity fed forward) on a 1.2 s path."""
    w = world
    w.spawn('arm', sources.from_model_text(ARM_PD), (2.0, 2.0, 1.0))
    tol = {n: (0.01, 0.0, 0.0) for n in PD_JOINTS}
    h = w.follow_trajectory('arm', PD_JOINTS, [0.4, 0.8, 1.2],
                            [[0.3, -0.3], [0.6, -0.6], [0.8, -0.4]],
                            goal_tolerance=tol, goal_time_tolerance=0.5)
    t0, worst = w.time, 0.0
    for _ in range(int(2.0 / w.timestep)):
        w.step(1)
        st = h.status
        if st.desired:
            worst = max(worst, float(np.max(np.abs(st.desired[0] - st.actual[0]))))
        if h.done:
            break
    assert h.done and h.status.code == trajectory.SUCCESSFUL, h.status.message
    assert w.time - t0 <= 1.2 * 1.2 + 0.5
    js = w.get_joint_states()
    assert js['arm/j1'][0] == pytest.approx(0.8, abs=0.01)
    assert js['arm/j2'][0] == pytest.approx(-0.4, abs=0.01)
    # Critically damped at w = sqrt(kp) = 20 rad/s, the error after a velocity step dv peaks
    # at dv / (e w); the largest step here is j2's, from -0.75 to +0.5 rad/s at 0.8 s.
    w_n = np.sqrt(w.config.kp)
    assert worst < 1.2 * 1.25 / (np.e * w_n)
    w.step(500)  # and it holds there
    assert w.get_joint_states()['arm/j1'][0] == pytest.approx(0.8, abs=0.01)


def test_the_servos_of_the_default_robot_follow_too(world):
    """Its position servos (kp 60) take the targets; they sag a little under gravity."""
    w = world
    h = w.follow_trajectory('robot', ARM, [0.5, 1.0], [[0.0, 0.3], [0.0, 0.5]],
                            goal_tolerance={'left_elbow': (0.05, 0, 0)},
                            goal_time_tolerance=1.0)
    run_until_done(w, h, 3.0)
    assert h.status.code == trajectory.SUCCESSFUL, h.status.message
    assert w.get_joint_states()['left_elbow'][0] == pytest.approx(0.5, abs=0.05)


def test_a_joint_without_an_actuator_is_driven_by_pd_along_the_trajectory(world):
    w = world
    w.spawn('arm', sources.from_model_text(ARM_PD), (2.0, 2.0, 1.0))
    h = w.follow_trajectory('arm', PD_JOINTS, [1.0], [[0.5, -0.5]],
                            goal_tolerance={n: (0.01, 0, 0) for n in PD_JOINTS})
    run_until_done(w, h, 3.0)
    assert h.status.code == trajectory.SUCCESSFUL, h.status.message
    assert w.get_joint_states()['arm/j1'][0] == pytest.approx(0.5, abs=0.01)


@pytest.mark.parametrize('case', [
    {'joints': ['left_shoulder', 'nope'], 'code': trajectory.INVALID_JOINTS, 'text': 'nope'},
    {'joints': ['shoulder'], 'code': trajectory.INVALID_JOINTS, 'text': 'did you mean'},
    {'joints': ['left_shoulder', 'left_shoulder'], 'code': trajectory.INVALID_JOINTS,
     'text': 'twice'},
    {'times': [1.0, 1.0], 'code': trajectory.INVALID_GOAL, 'text': 'increase'},
    {'times': [], 'positions': [], 'code': trajectory.INVALID_GOAL, 'text': 'no points'},
    {'positions': [[0.1], [0.2]], 'code': trajectory.INVALID_GOAL,
     'text': '1 positions for 2'},
    {'positions': [[0.1, float('nan')], [0.2, 0.2]], 'code': trajectory.INVALID_GOAL,
     'text': 'non-finite'},
], ids=['unknown', 'hint', 'duplicate', 'times', 'empty', 'size', 'nan'])
def test_bad_goals_are_refused_with_the_controllers_codes(world, case):
    joints = case.get('joints', ARM)
    times = case.get('times', [0.5, 1.0])
    positions = case.get('positions', [[0.1] * len(joints), [0.2] * len(joints)])
    with pytest.raises(TrajectoryError) as err:
        world.follow_trajectory('robot', joints, times, positions)
    assert err.value.code == case['code'] and case['text'] in str(err.value)


def test_joints_of_another_entity_are_refused(world):
    w = world
    w.spawn('arm2', sources.from_model_text(
        '<mujoco><worldbody><body name="b"><joint name="j" axis="0 1 0"/>'
        '<geom size="0.05"/></body></worldbody></mujoco>'), (2.0, -2.0, 0.5))
    with pytest.raises(TrajectoryError) as err:
        w.follow_trajectory('robot', ['left_shoulder', 'arm2/j'], [1.0], [[0.1, 0.1]])
    assert err.value.code == trajectory.INVALID_JOINTS and 'one entity' in str(err.value)


def test_a_goal_that_ends_in_the_past_is_refused(world):
    world.step(500)  # 1 s
    with pytest.raises(TrajectoryError) as err:
        world.follow_trajectory('robot', ARM, [0.2], [[0.1, 0.1]], start_time=0.5)
    assert err.value.code == trajectory.OLD_HEADER_TIMESTAMP


def test_a_future_start_waits_for_its_simulated_time(world):
    w = world
    before = w.get_joint_states()['left_elbow'][0]
    h = w.follow_trajectory('robot', ARM, [0.5], [[-0.2, 0.1]], start_time=1.0)
    w.step(400)  # 0.8 s: not started, the joints hold where they were
    assert w.get_joint_states()['left_elbow'][0] == pytest.approx(before, abs=0.01)
    run_until_done(w, h, 2.0)
    assert h.status.code == trajectory.SUCCESSFUL
    assert w.time >= 1.5 - 1e-9


def test_a_new_goal_preempts_the_running_one(world):
    w = world
    first = w.follow_trajectory('robot', ARM, [2.0], [[1.0, 1.0]])
    w.step(200)
    second = w.follow_trajectory('robot', ARM, [0.5], [[-0.2, 0.0]])
    assert first.done and first.status.canceled
    assert first.status.code == trajectory.INVALID_GOAL
    run_until_done(w, second, 2.0)
    assert second.status.code == trajectory.SUCCESSFUL


def test_cancel_holds_the_joints_where_they_are(world):
    w = world
    h = w.follow_trajectory('robot', ARM, [2.0], [[-0.2, -1.5]])  # the elbow from 0.6
    w.step(400)
    h.cancel()
    assert h.done and h.status.canceled
    w.step(5)
    here = w.get_joint_states()['left_elbow'][0]
    w.step(500)
    assert -1.3 < here < 0.4  # stopped midway
    assert w.get_joint_states()['left_elbow'][0] == pytest.approx(here, abs=0.03)


def test_a_path_tolerance_violation_aborts_naming_the_joint(world):
    w = world
    h = w.follow_trajectory('robot', ARM, [0.05], [[2.0, 0.0]],  # far faster than the servo
                            path_tolerance={'left_shoulder': (0.05, 0, 0)})
    run_until_done(w, h, 1.0)
    assert h.status.code == trajectory.PATH_TOLERANCE_VIOLATED
    assert "'left_shoulder'" in h.status.message and 'position error' in h.status.message


def test_an_unreachable_goal_violates_the_goal_tolerance_after_its_time_tolerance(world):
    w = world
    # Far faster than the shoulder's servo (kp 60) can go under gravity: not there in time.
    h = w.follow_trajectory('robot', ARM, [0.01], [[2.4, 0.0]],
                            goal_tolerance={'left_shoulder': (0.001, 0, 0)},
                            goal_time_tolerance=0.3)
    run_until_done(w, h, 2.0)
    assert h.status.code == trajectory.GOAL_TOLERANCE_VIOLATED
    assert 'left_shoulder' in h.status.message
    assert w.time == pytest.approx(0.31, abs=0.01)


def test_a_point_outside_a_joints_range_is_refused_naming_the_joint_and_its_range(world):
    before = world.get_joint_states()['left_shoulder'][0]
    with pytest.raises(TrajectoryError) as err:
        world.follow_trajectory('robot', ARM, [0.5, 1.0], [[0.5, 0.0], [3.0, 0.0]])
    assert err.value.code == trajectory.INVALID_GOAL
    assert "point 1 puts joint 'left_shoulder' at 3" in str(err.value)
    assert '[-2.5, 2.5]' in str(err.value)
    assert world.get_joint_states()['left_shoulder'][0] == before


#: One hinge whose range leaves out where it starts (0), as some robot files have it.
OUTSIDE = """<mujoco><compiler angle="radian"/><worldbody><body name="b" pos="0 0 1">
  <joint name="j" axis="0 0 1" range="0.2 1.0"/><geom type="box" size="0.2 0.05 0.05" mass="1"/>
  </body></worldbody></mujoco>"""


def test_a_joint_already_outside_its_range_may_stay_there_or_go_in_but_not_further_out(world):
    w = world
    w.spawn('out', sources.from_model_text(OUTSIDE), (2.0, 2.0, 0.0))
    here = w.get_joint_states()['out/j'][0]
    assert here < 0.2
    w.follow_trajectory('out', ['out/j'], [0.1], [[here]])  # hold where it is
    w.follow_trajectory('out', ['out/j'], [0.5], [[0.5]])  # into the range
    with pytest.raises(TrajectoryError, match="'out/j' at -0.1"):
        w.follow_trajectory('out', ['out/j'], [0.5], [[-0.1]])


def motor_arm(limit: float) -> str:
    """Return the two-joint arm with a motor on each joint, limited to +-`limit` N m."""
    motors = ''.join(f'<motor joint="{j}" gear="2" ctrlrange="{-limit / 2} {limit / 2}"/>'
                     for j in ('j1', 'j2'))
    return TWO_JOINT_ARM.replace('</mujoco>', f'<actuator>{motors}</actuator></mujoco>')


def arm_torques(w, field: str) -> np.ndarray:
    """Return the arm's two joint torques in MjData `field` (qfrc_actuator, qfrc_applied)."""
    return w.read(lambda m, d: getattr(d, field)[[m.joint('arm/j1').dofadr[0],
                                                  m.joint('arm/j2').dofadr[0]]].copy())


def gravity_torque_j1() -> float:
    """Return what holding both 1 kg links level takes at j1: 9.81 * (0.15 + 0.45) N m."""
    return 9.81 * (0.15 + 0.45)


def test_a_motor_drives_the_trajectory_within_the_torque_its_file_gives_it(world):
    """Strong enough motors follow as PD does; the torque goes through them, not around."""
    w = world
    w.spawn('arm', sources.from_model_text(motor_arm(100.0)), (2.0, 2.0, 1.0))
    h = w.follow_trajectory('arm', PD_JOINTS, [0.5], [[0.3, -0.3]],
                            goal_tolerance={n: (0.01, 0, 0) for n in PD_JOINTS})
    run_until_done(w, h, 2.0)
    assert h.status.code == trajectory.SUCCESSFUL, h.status.message
    assert w.get_joint_states()['arm/j1'][0] == pytest.approx(0.3, abs=0.01)
    applied, actuated = arm_torques(w, 'qfrc_applied'), arm_torques(w, 'qfrc_actuator')
    assert np.allclose(applied, 0.0)  # nothing bypasses the motors
    assert abs(actuated[0]) > 0.5 * gravity_torque_j1() * np.cos(0.3)


def test_a_motor_too_weak_for_the_trajectory_is_reported_not_succeeded(world):
    """Motors of 2 N m cannot hold 1 kg links level: the goal aborts saying so."""
    w = world
    w.spawn('arm', sources.from_model_text(motor_arm(2.0)), (2.0, 2.0, 1.0))
    assert gravity_torque_j1() > 2.0
    h = w.follow_trajectory('arm', PD_JOINTS, [0.5, 1.0], [[0.0, 0.0], [0.2, 0.0]],
                            path_tolerance={n: (0.25, 0, 0) for n in PD_JOINTS})
    peak = 0.0
    for _ in range(int(2.0 / w.timestep)):
        w.step(1)
        peak = max(peak, float(np.abs(arm_torques(w, 'qfrc_actuator')).max()))
        if h.done:
            break
    assert h.status.code == trajectory.PATH_TOLERANCE_VIOLATED, h.status.message
    assert "the motors of 'arm/j1' (" in h.status.message  # the one that held the most
    assert 'than the actuators can give' in h.status.message
    assert peak <= 2.0 + 1e-9  # the limit held: the arm fell instead


def test_a_held_position_command_on_a_motor_joint_stays_within_its_limit(world):
    w = world
    w.spawn('arm', sources.from_model_text(motor_arm(2.0)), (2.0, 2.0, 1.0))
    w.command(PD_JOINTS, [0.0, 0.0], 'position')
    w.step(500)
    torque = arm_torques(w, 'qfrc_actuator')
    assert np.all(np.abs(torque) <= 2.0 + 1e-9)
    assert w.get_joint_states()['arm/j1'][0] > 0.3  # y-axis hinge: the arm hangs down


def test_open_loop_starts_from_the_last_command_and_closed_loop_from_the_joints(world):
    """
    A weak arm sags far below its command: open_loop decides where a new trajectory starts.

    With open_loop (joint_trajectory_controller's open_loop_control) a new trajectory starts
    from the held command, and a preempting one from the running one's target; without it,
    from where the joints are.
    """
    w = world
    w.spawn('arm', sources.from_model_text(motor_arm(2.0)), (2.0, 2.0, 1.0))
    w.command(PD_JOINTS, [0.0, 0.0], 'position')
    w.step(500)
    assert w.get_joint_states()['arm/j1'][0] > 0.3  # sagged: 2 N m cannot hold it level
    first = w.follow_trajectory('arm', PD_JOINTS, [2.0], [[0.4, 0.0]], open_loop=True)
    w.step(1)
    assert first.status.desired[0][0] == pytest.approx(0.0, abs=0.01)  # the held command
    w.step(499)
    target = float(first.status.desired[0][0])
    assert target == pytest.approx(0.2, abs=0.01)
    second = w.follow_trajectory('arm', PD_JOINTS, [2.0], [[-0.4, 0.0]], open_loop=True)
    w.step(1)
    assert second.status.desired[0][0] == pytest.approx(target, abs=0.01)
    measured = w.get_joint_states()['arm/j1'][0]
    assert measured - target > 0.2  # the arm is far from its target
    third = w.follow_trajectory('arm', PD_JOINTS, [2.0], [[0.0, 0.0]])
    w.step(1)
    assert third.status.desired[0][0] == pytest.approx(measured, abs=0.01)


def test_without_steps_nothing_moves_and_the_trajectory_waits(world):
    """Paused (no steps), simulated time stands still, and so does the trajectory."""
    w = world
    h = w.follow_trajectory('robot', ARM, [0.2], [[0.5, 0.5]])
    assert not h.wait(0.3)
    run_until_done(w, h, 2.0)
    assert h.status.code == trajectory.SUCCESSFUL


def test_a_joint_command_on_a_driven_joint_ends_the_trajectory(world):
    w = world
    h = w.follow_trajectory('robot', ARM, [2.0], [[1.0, 1.0]])
    w.step(100)
    w.command(['left_elbow'], [-0.3], 'position')
    w.step(1)
    assert h.done and not h.status.canceled and h.status.code == trajectory.INVALID_GOAL
    assert 'joint_commands' in h.status.message
    w.step(500)
    assert w.get_joint_states()['left_elbow'][0] == pytest.approx(-0.3, abs=0.02)


def test_a_reset_ends_the_trajectory(world):
    h = world.follow_trajectory('robot', ARM, [2.0], [[1.0, 1.0]])
    world.step(10)
    world.reset(RESET_STATE)
    assert h.done and h.status.code == trajectory.INVALID_GOAL


#: TWO_JOINT_ARM with a stiff, damped position servo on each joint.
SERVO_ARM = TWO_JOINT_ARM.replace(
    '</mujoco>', '<actuator><position joint="j1" kp="500" kv="20"/>'
    '<position joint="j2" kp="500" kv="20"/></actuator></mujoco>')


def test_a_reset_that_removes_the_driven_entity_ends_its_trajectory(world):
    """The arm and its joints leave with the spawned entities; the reset still succeeds."""
    world.spawn('arm', sources.from_model_text(SERVO_ARM), (2.0, 2.0, 1.0))
    world.command(PD_JOINTS, [0.2, 0.2], 'position')
    world.step(1)
    h = world.follow_trajectory('arm', PD_JOINTS, [2.0], [[1.0, 1.0]])
    world.step(10)
    world.reset()
    assert h.done and h.status.code == trajectory.INVALID_GOAL, h.status.message
    assert 'arm' not in world.get_joint_states() and 'arm/j1' not in world.get_joint_states()
    world.step(10)


def test_deleting_a_driven_entity_leaves_the_other_entities_servos_alone(world):
    """The ended trajectory's actuators were numbered before the delete: not written after it."""
    for name, y in (('x', 2.0), ('y', -2.0)):
        world.spawn(name, sources.from_model_text(SERVO_ARM), (2.0, y, 1.0))
    world.command(['y/j1', 'y/j2'], [-0.5, 0.4], 'position')
    world.step(1)
    h = world.follow_trajectory('x', ['x/j1', 'x/j2'], [2.0], [[1.0, 1.0]])
    world.step(2)  # y has barely started towards its targets
    world.delete('x')
    assert h.done and h.status.code == trajectory.INVALID_GOAL
    world.step(1000)
    js = world.get_joint_states()
    assert js['y/j1'][0] == pytest.approx(-0.5, abs=0.05)
    assert js['y/j2'][0] == pytest.approx(0.4, abs=0.05)
