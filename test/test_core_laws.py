"""
Controllers' laws run on the stepping side in simulated time, without ROS (issue 51, item 2).

A robot's ros2_control controllers (a diff drive, a gripper) as the world runs them: their law
updates at the controller's update rate of simulated time on the thread that steps, however
fast the world steps and whether or not anybody reads the joint samples; timeouts and stall
checks are simulated seconds; a reset of state starts them again.
"""

import logging
from pathlib import Path
from xml.etree import ElementTree as ET

import controllers_corpus as corpus
import pytest
from sim_node.core.control import controller_types as types, laws, manager as core
from sim_node.core.models import controller_yaml, sources, urdf
from sim_node.core.records import RESET_STATE
from sim_node.core.world import World

EMPTY = str(Path(__file__).resolve().parent.parent / 'scenes' / 'empty.xml')


def _robot(tmp_path, model: str, yaml_text: str, name: str):
    """Spawn `model` (a URDF made with the YAML's path) and return (world, laws, law, rate)."""
    path = corpus.write(tmp_path, 'c.yaml', yaml_text)
    text = model(path)
    control = urdf.prepare(ET.fromstring(text)).ros2_control
    hardware = control.joints()
    doc = controller_yaml.load(path)
    manager = core.Manager(
        {f'{j.name}/{i}': lim for j in hardware.values() for i, lim in j.command.items()},
        tuple(f'{j.name}/{i}' for j in hardware.values() for i in j.state),
        controller_yaml.node_parameters([doc], 'controller_manager'),
        lambda n: controller_yaml.node_parameters([doc], n))
    assert manager.load(name)[0] and manager.configure(name)[0]
    controller = manager.controllers[name]
    world = World.from_file(EMPTY)
    entity = 'robot'
    world.spawn(entity, sources.from_model_text(text), position=(0, 0, 0.11))
    robot = laws.Laws(list(hardware), lambda j, i, v: hardware[j].within(i, v),
                      lambda j: f'{entity}/{j}')
    law = laws.law_for(types.REGISTRY[controller.kind], controller.params,
                       controller.update_rate)
    robot.put(name, law)
    world.sample_joints('robot', [f'{entity}/{j}' for j in hardware], manager.update_rate,
                        tick=robot.tick)
    return world, robot, law, manager.update_rate


def _drive(world, law, seconds: float, v: float = 0.3) -> None:
    """Send the twist (v, 0) every 0.2 s of simulated time for `seconds`."""
    for _ in range(round(seconds / 0.2)):
        law.take(v, 0.0)
        world.step(round(0.2 / world.timestep))


def _rolling_rover(tmp_path) -> tuple:
    """Return (world, laws, law) of the diff-drive rover after 1.2 s driven at 0.3 m/s."""
    world, robot, law, _ = _robot(tmp_path, corpus.diff_drive, corpus.DIFF_DRIVE_YAML,
                                  'diff_drive_base_controller')
    law.activate()
    world.step(5)
    _drive(world, law, 1.2)
    assert law.snapshot().x > 0.1
    return world, robot, law


def _wheel_speeds(world) -> tuple:
    states = world.get_joint_states()
    return states['robot/left_wheel_joint'][1], states['robot/right_wheel_joint'][1]


def test_a_diff_drive_law_drives_the_wheels_on_the_stepping_side_in_simulated_time(tmp_path):
    """
    Its twist turns the wheels with nobody draining samples; its timeout is simulated time.

    Steps are taken 200 at a time (0.2 s simulated each, far faster than real time, where the
    queue the node reads leaves samples out), the twist sent again before each as a 5 Hz
    publisher would: the law still updates at every 10 ms of simulated time (its odometry's
    time is the last), and the base goes at the twist asked.
    """
    world, robot, law, rate = _robot(tmp_path, corpus.diff_drive, corpus.DIFF_DRIVE_YAML,
                                     'diff_drive_base_controller')
    assert law.activate() == []
    world.step(10)
    updates = []
    law_update = law.update

    def counted(sample, index):
        updates.append(sample.time)
        return law_update(sample, index)

    law.update = counted
    start = world.time
    for _ in range(8):  # within the YAML's limits: 1 m/s, 0.5 m/s^2
        law.take(0.3, 0.0)
        world.step(200)
    span = world.time - start
    assert len(updates) >= int(span * rate) - 1  # every 10 ms of simulated time
    assert all(b - a > 0.0099 for a, b in zip(updates, updates[1:]))
    left, right = _wheel_speeds(world)
    assert abs(left - 3.0) < 0.3 and abs(right - 3.0) < 0.3  # 0.3 m/s on 0.1 m wheels
    odo = law.snapshot()
    assert abs(odo.time - updates[-1]) < 1e-9 and odo.vx > 0.25
    assert 0.3 < odo.x < 0.5  # ramped at 0.5 m/s^2 for 0.6 s, then 0.3 m/s
    world.step(1300)  # stale after cmd_vel_timeout (0.5 s simulated), then slowed to a stop
    left, right = _wheel_speeds(world)
    assert abs(left) < 0.2 and abs(right) < 0.2
    assert not robot.failures


def test_a_reset_of_state_starts_a_law_again_on_the_stepping_side(tmp_path):
    """After a reset the base stands: its twist dropped, its odometry from zero."""
    world, robot, law = _rolling_rover(tmp_path)
    world.reset(RESET_STATE)
    world.step(200)
    left, right = _wheel_speeds(world)
    assert abs(left) < 0.2 and abs(right) < 0.2  # not driven again by the twist of before
    assert abs(law.snapshot().x) < 0.01


def test_a_deactivated_law_is_not_updated_and_leaves_its_base_stopped(tmp_path):
    world, robot, law = _rolling_rover(tmp_path)
    stop = law.deactivate()
    assert [w.values for w in stop] == [[0.0, 0.0]]
    for names, values, mode in robot.world_writes(stop):
        world.command(names, values, mode)
    law.take(0.5, 0.0)  # inactive: not taken
    world.step(300)
    left, right = _wheel_speeds(world)
    assert abs(left) < 0.2 and abs(right) < 0.2


def test_a_gripper_law_decides_its_goal_in_simulated_time(tmp_path):
    """Reached within its tolerance; stalled on a block after stall_timeout simulated s."""
    world, robot, law, _ = _robot(tmp_path, corpus.gripper, corpus.GRIPPER_YAML,
                                  'gripper_controller')
    law.activate()
    world.step(5)
    goal, writes = law.start(0.01)
    for names, values, mode in robot.world_writes(writes):
        world.command(names, values, mode)
    for _ in range(200):
        world.step(10)
        if goal.done.is_set():
            break
    assert goal.how == 'reached' and abs(goal.position - 0.01) <= 0.002
    # a second goal preempts a first
    first, _ = law.start(0.02)
    second, writes = law.start(0.0)
    assert first.done.is_set() and first.how == 'ended' and not second.done.is_set()
    # a goal the finger cannot reach (held at 0 by a command of its own) stalls in 0.3 s
    world.command(['robot/left_finger_joint'], [0.0], 'position')
    world.step(1000)
    stalled, _ = law.start(0.05)  # its command not written: the finger stays
    t0 = world.time
    while not stalled.done.is_set() and world.time - t0 < 2.0:
        world.step(5)
    assert stalled.how == 'stalled'
    assert 0.3 <= world.time - t0 < 0.33  # stall_timeout 0.3 s of simulated time


def test_one_failing_law_stops_no_other_and_is_reported(tmp_path):
    world, robot, law = _rolling_rover(tmp_path)

    class Broken(laws.Law):

        def update(self, sample, index):
            raise RuntimeError('broken on purpose')

    broken = Broken({}, 100.0)
    robot.put('broken', broken)
    broken.activate()
    before = law.snapshot().x
    _drive(world, law, 1.0)
    assert robot.failures and robot.failures[-1][0] == 'broken'
    assert 'broken on purpose' in robot.failures[-1][1]
    assert law.snapshot().x > before + 0.2  # 0.3 m/s for 1 s: the base went on


FREE = '<hold_joints>false</hold_joints>'


def _hinge(world) -> float:
    return world.get_joint_states()['robot/hinge'][0]


def test_joints_no_controller_claims_are_held_still_and_let_go_joints_again(tmp_path):
    """gz_ros2_control's hold_joints: a boom gravity would swing down stays where it was."""
    world, robot, law, rate = _robot(tmp_path, lambda p: corpus.boom(p, FREE), corpus.BOOM_YAML,
                                     'boom_controller')  # not held at its spawn: the law holds
    holder = laws.HoldLaw(laws.held_interfaces({'hinge': {'position': (None, None)}}), rate)
    holder.activate()
    robot.put('(hold_joints)', holder)
    world.step(500)  # 1 s
    assert abs(_hinge(world)) < 0.01
    holder.claimed({'hinge'})  # a controller claims it, and (here) commands nothing
    world.command(['robot/hinge'], [0.5], 'position')
    world.step(500)
    assert _hinge(world) == pytest.approx(0.5, abs=0.01)  # the hold did not write over it
    world.command(['robot/hinge'], [0.0], 'effort')  # nobody holds it: it swings
    world.step(50)
    swinging = _hinge(world)
    assert abs(swinging - 0.5) > 0.02
    holder.claimed(set())  # let go: held where it is now
    world.step(500)
    assert _hinge(world) == pytest.approx(swinging, abs=0.05)
    world.reset(RESET_STATE)  # a reset: held again where the reset put it
    world.step(500)
    assert abs(_hinge(world)) < 0.01


def test_a_spawn_holds_a_boom_from_its_first_step_unless_its_plugin_says_not(tmp_path, caplog):
    world, *_ = _robot(tmp_path, lambda p: corpus.boom(p, FREE), corpus.BOOM_YAML,
                       'boom_controller')
    world.step(500)
    assert abs(_hinge(world)) > 0.5  # free, it swings down
    world, *_ = _robot(tmp_path, corpus.boom, corpus.BOOM_YAML, 'boom_controller')
    world.step(1)
    assert abs(_hinge(world)) < 1e-4  # held from the first step (no law runs here)
    world.step(499)
    assert abs(_hinge(world)) < 0.01
    for extra, hold in (('', True), ('<hold_joints>false</hold_joints>', False),
                        ('<hold_joints>0</hold_joints>', False),
                        ('<hold_joints>maybe</hold_joints>', True)):
        text = corpus.boom('c.yaml', extra)
        with caplog.at_level(logging.WARNING):
            assert urdf.prepare(ET.fromstring(text)).ros2_control.hold_joints is hold
    assert "<hold_joints> 'maybe' is not true or false" in caplog.text
