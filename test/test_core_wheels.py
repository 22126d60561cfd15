"""
Command interfaces held as Gazebo holds them (issue 53, item 3).

gz_ros2_control commands a velocity interface as a joint velocity command, a constraint the
joint meets whatever it carries, within its effort limit; and a position interface as a held
velocity of ``position_proportional_gain x update_rate x (command - position)``. Here a
ros2_control robot's wheel on a velocity interface gets a velocity actuator sized by the weight
it carries, and a position interface a servo of that law (``core/control/interfaces.py``).
These tests hold them to Gazebo's promise on the car of gz_ros2_control's Ackermann demo (145 kg
on four wheels) and on a boom that gravity pulls down, checked against theory: a wheel at the
speed asked, a car rolling at that speed times the radius and turning at ``v tan(phi) / L``, a
first-order lag of the plugin's rate, a torque within the URDF's effort, a command beyond any
bound capped and said.
"""

from dataclasses import replace
import logging
import math
from xml.etree import ElementTree as ET

import controllers_corpus as corpus
import numpy as np
import pytest
from sim_node.core.control import steering
from sim_node.core.models import ros2_control, sources, urdf
from sim_node.core.world import World

EMPTY = str(__import__('pathlib').Path(__file__).resolve().parent.parent / 'scenes' / 'empty.xml')
REAR = ('car/rear_left_wheel_joint', 'car/rear_right_wheel_joint')
STEER = ('car/left_wheel_steering_joint', 'car/right_wheel_steering_joint')
RADIUS, SPEED = 0.3, 0.5  # the demo's wheels; its example program's 0.5 m/s
OMEGA = SPEED / RADIUS


def _car(**limits) -> World:
    """Return a world with the demo's car standing on the floor, 0.3 s after its spawn."""
    world = World.from_file(EMPTY)
    world.spawn('car', sources.from_model_text(corpus.gz_car('/none.yaml', **limits)),
                position=(0, 0, 0.01))
    world.step(round(0.3 / world.timestep))
    return world


def _wheel_speeds(world: World) -> np.ndarray:
    states = world.get_joint_states()
    return np.array([states[j][1] for j in REAR])


def _car_speed(world: World) -> float:
    return float(np.linalg.norm(world.get_entity_state('car').linear_velocity[:2]))


@pytest.mark.parametrize('steer', [0.0, 0.6])
def test_a_velocity_interface_holds_a_cars_rear_wheels_within_2_percent_in_0_2_s(steer):
    # Both front wheels steered 0.6 rad, parallel (not on their own circles as Ackermann's
    # are): they scrub, and the rear wheels, both asked for one speed, carry that load.
    world = _car()
    world.command(list(STEER), [steer, steer], 'position')
    world.command(list(REAR), [OMEGA, OMEGA], 'velocity')
    world.step(round(0.2 / world.timestep))
    worst = 0.0
    for _ in range(round(1.8 / 0.01)):  # from 0.2 s to 2 s, every 10 ms
        worst = max(worst, float(np.max(np.abs(_wheel_speeds(world) / OMEGA - 1))))
        world.step(round(0.01 / world.timestep))
    assert worst <= 0.02
    if steer == 0.0:  # rolling without slip: the car goes at the wheels' speed times radius
        assert _car_speed(world) == pytest.approx(SPEED, rel=0.02)


@pytest.mark.parametrize('turn', [0.0, 0.3])
def test_a_bicycles_one_driven_wheel_is_held_whatever_its_name_and_it_turns_as_asked(turn):
    # A bicycle-model car (corpus.gz_bicycle): its one rear wheel drives the whole 145 kg and
    # its joint's name says neither left nor right. Gazebo holds its velocity command all the
    # same: the wheel within 2% from 0.2 s on, and the car at v and w = v tan(phi) / L.
    world = World.from_file(EMPTY)
    world.spawn('bike', sources.from_model_text(corpus.gz_bicycle('/none.yaml')),
                position=(0, 0, 0.01))
    world.step(round(0.3 / world.timestep))
    out = steering.bicycle(1.7, RADIUS, SPEED, turn)
    world.command(['bike/steering_joint'], list(out.steering), 'position')
    world.command(['bike/rear_wheel_joint'], list(out.traction), 'velocity')
    world.step(round(0.2 / world.timestep))
    worst = 0.0
    for _ in range(round(1.8 / 0.01)):
        wheel = world.get_joint_states()['bike/rear_wheel_joint'][1]
        worst = max(worst, abs(wheel / OMEGA - 1))
        world.step(round(0.01 / world.timestep))
    assert worst <= 0.02
    world.step(round(1.0 / world.timestep))  # the steering's lag of 0.1 s, well past
    state = world.get_entity_state('bike')
    assert np.linalg.norm(state.linear_velocity[:2]) == pytest.approx(SPEED, rel=0.05)
    assert state.angular_velocity[2] == pytest.approx(turn, rel=0.05, abs=0.005)


def test_a_velocity_interface_pushes_no_harder_than_its_urdf_effort_limit():
    world = _car(effort=30.0)
    world.command(list(REAR), [OMEGA, OMEGA], 'velocity')
    torques = []
    for _ in range(100):  # 0.2 s
        world.step(round(0.002 / world.timestep))
        torques.append(world.read(lambda m, d: np.abs(d.actuator_force).max()))
    assert max(torques) <= 30.0 + 1e-9
    assert max(torques) >= 29.0  # it pushes with all it may: the car is heavy for 30 N m
    # Two wheels of 30 N m push 145 kg and more (the wheels spin up too) with at most
    # 2 * 30 / 0.3 = 200 N: 0.28 m/s at most after 0.2 s, short of the 0.5 asked.
    assert 0.1 < _car_speed(world) < 2 * 30 / RADIUS / 145.2 * 0.2 + 0.01
    world.step(round(2.0 / world.timestep))
    assert _car_speed(world) == pytest.approx(SPEED, rel=0.02)  # and it gets there


def test_a_velocity_command_beyond_any_bound_is_capped_with_a_warning(caplog):
    declared = urdf.prepare(ET.fromstring(corpus.gz_car('/none.yaml', speed=12.0)))
    free = urdf.prepare(ET.fromstring(corpus.gz_car('/none.yaml')))
    limited = declared.ros2_control.joints()['rear_left_wheel_joint']
    wheel = free.ros2_control.joints()['rear_right_wheel_joint']
    bound = ros2_control.MAX_COMMAND_SPEED
    with caplog.at_level(logging.WARNING):
        assert limited.within('velocity', 1e9) == 12.0  # the URDF's <limit velocity>
        assert wheel.within('velocity', 1e9) == bound  # none given: the most any joint takes
        assert wheel.within('velocity', -1e9) == -bound
        assert wheel.within('velocity', math.nan) == 0.0
        assert wheel.within('velocity', 5.0) == 5.0 and limited.within('velocity', -12.0) == -12
        assert wheel.within('position', 1e9) == 1e9  # a position is not a speed
    said = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(said) == 2, said  # one per joint, not one per command (a controller's 100 Hz)
    assert "'rear_left_wheel_joint'" in said[0] and '1e+09' in said[0] and '12' in said[0]
    assert "'rear_right_wheel_joint'" in said[1] and 'no URDF <limit velocity>' in said[1]
    # The capped command held: the car goes, fast, and the world keeps stepping.
    world = _car()
    world.command(list(REAR), [wheel.within('velocity', 1e9)] * 2, 'velocity')
    world.step(round(2.0 / world.timestep))
    assert np.all(np.isfinite(world.get_state().values))
    assert _wheel_speeds(world) == pytest.approx([bound, bound], rel=0.02)


def _boom(plugin_extra: str = '', rate=None):
    """Return (world, hardware joint) of the boom, its manager's update rate `rate`."""
    source = sources.from_model_text(corpus.boom('/none.yaml', plugin_extra))
    control = source.urdf_notes.ros2_control
    source.urdf_notes.ros2_control = replace(control, update_rate=rate)
    world = World.from_file(EMPTY)
    world.spawn('boom', source, position=(0, 0, 0))
    return world, control


def _hinge(world) -> float:
    return float(world.get_joint_states()['boom/hinge'][0])


@pytest.mark.parametrize('gain, rate', [(None, None), (0.2, 50.0)])
def test_a_position_interface_lags_as_gz_ros2_controls_law_and_holds_under_gravity(gain, rate):
    # gz_ros2_control: the joint moves at gain x rate x (command - position), held whatever
    # it carries: q(t) = q* (1 - exp(-gain rate t)) from rest, then no sag under the beam's
    # weight (1 kg at 0.3 m: 2.9 N m). Defaults: gain 0.1, rate 100 Hz (the manager's).
    extra = f'<position_proportional_gain>{gain}</position_proportional_gain>' if gain else ''
    world, control = _boom(extra, rate)
    assert control.position_gain == (gain or 0.1)
    k = (gain or 0.1) * (rate or 100.0)  # 10 /s both ways: the same law, two spellings
    world.step(round(0.5 / world.timestep))  # held where it spawned, from its first step
    assert abs(_hinge(world)) < 1e-3
    world.command(['boom/hinge'], [0.5], 'position')
    start = world.time
    for t in (0.05, 0.1, 0.2, 0.3):
        world.step(round((start + t - world.time) / world.timestep))
        assert _hinge(world) == pytest.approx(0.5 * (1 - math.exp(-k * t)), abs=0.01)
    world.step(round(1.0 / world.timestep))
    assert _hinge(world) == pytest.approx(0.5, abs=2e-3)  # held up against gravity


def test_a_position_interface_a_controller_lets_go_is_free_and_a_bad_gain_is_said(caplog):
    with caplog.at_level(logging.WARNING):
        world, control = _boom('<hold_joints>false</hold_joints>'
                               '<position_proportional_gain>fast</position_proportional_gain>')
    assert control.position_gain == 0.1
    assert "<position_proportional_gain> 'fast' is not a positive number" in caplog.text
    world.step(round(0.5 / world.timestep))
    assert abs(_hinge(world)) > 0.5  # nothing commands it: it swings down, free
    world.command(['boom/hinge'], [0.0], 'position')
    world.step(round(1.0 / world.timestep))
    assert abs(_hinge(world)) < 0.02  # held, once commanded
    world.command(['boom/hinge'], [0.0], 'effort')  # an effort controller takes it: free
    world.step(round(0.3 / world.timestep))
    assert abs(_hinge(world)) > 0.2
    world.command(['boom/hinge'], [0.0], 'position')  # held again; then deleted, and a
    world.step(round(0.3 / world.timestep))  # boom spawned again under its name starts free
    world.delete('boom')
    source = sources.from_model_text(corpus.boom('/none.yaml', '<hold_joints>0</hold_joints>'))
    world.spawn('boom', source, position=(0, 0, 0))
    world.step(round(0.5 / world.timestep))
    assert abs(_hinge(world)) > 0.5


def test_the_demo_cars_steering_holds_its_angles_and_it_turns_as_the_geometry_says():
    # The Ackermann command of 0.5 m/s and 0.3 rad/s through the demo car's joints (its
    # steering by position, its rear wheels by velocity): the front tyres push the steering
    # back, Gazebo's position interface does not give way, nor does this one.
    world = _car()
    out = steering.ackermann(1.7, 1.0, RADIUS, SPEED, 0.3)  # (right, left) each
    world.command(['car/right_wheel_steering_joint', 'car/left_wheel_steering_joint'],
                  list(out.steering), 'position')
    world.command(['car/rear_right_wheel_joint', 'car/rear_left_wheel_joint'],
                  list(out.traction), 'velocity')
    world.step(round(2.0 / world.timestep))  # the law's lag: 0.1 s at 100 Hz
    states = world.get_joint_states()
    reached = [states[f'car/{side}_wheel_steering_joint'][0] for side in ('right', 'left')]
    assert reached == pytest.approx(list(out.steering), rel=0.01)
    twist = world.get_entity_state('car')
    assert twist.angular_velocity[2] == pytest.approx(0.3, rel=0.03)
    assert np.linalg.norm(twist.linear_velocity[:2]) == pytest.approx(SPEED, rel=0.02)
