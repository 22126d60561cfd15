"""The stepping API: modes, state overwrite, run constraints, and its two rules."""

from conftest import DEFAULT_SCENE
import numpy as np
import pytest
from sim_node.core.errors import InvalidArgumentError, SimError
from sim_node.simulation import Simulation


def test_kinematic_mode_follows_the_command_exactly():
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    sim.step({'left_elbow': -1.0, 'left_shoulder': 0.4}, dt=0.1, mode='kinematic')
    st = sim.get_state()
    assert st['joints']['left_elbow'] == -1.0 and st['joints']['left_shoulder'] == 0.4
    assert st['joint_velocities']['left_elbow'] == 0.0


@pytest.mark.parametrize('mode', ['position', 'velocity', 'effort'])
def test_modes_move_the_joint(mode):
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    q0 = sim.get_state()['joints']['left_elbow']
    value = {'position': -0.8, 'velocity': -1.0, 'effort': -5.0}[mode]
    sim.step({'left_elbow': value}, dt=0.5, mode=mode)
    assert sim.get_state()['joints']['left_elbow'] < q0 - 0.1


def test_ctrl_as_array_and_bad_input():
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    sim.step([0.0, -0.5, 0.0, -0.5], dt=0.2, mode='position')
    with pytest.raises(InvalidArgumentError):
        sim.step([0.0], mode='position')
    with pytest.raises(InvalidArgumentError):
        sim.step({'left_elbow': float('nan')}, mode='position')
    with pytest.raises(InvalidArgumentError):
        sim.step(mode='teleport')


def test_state_overwrite_and_reset_without_rebuild():
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    gen = sim.world.generation
    sim.step(dt=0.5)
    st = sim.get_state()
    sim.set_state({'bodies': {'box_a': (np.array([0.7, 0.3, 0.8]), np.array([1., 0, 0, 0]))},
                   'joints': {'left_elbow': 0.1}})
    after = sim.get_state()
    assert np.allclose(after['bodies']['box_a'][0], [0.7, 0.3, 0.8])
    assert after['joints']['left_elbow'] == 0.1
    assert np.allclose(after['bodies']['box_b'][0], st['bodies']['box_b'][0])
    sim.reset()
    assert sim.time == 0.0 and sim.world.generation == gen


@pytest.mark.parametrize('bad', [
    {'joints': {'no_such_joint': 0.3}},
    {'joints': {'left_elbow': float('nan')}},
    {'bodies': {'no_such_body': ([0, 0, 1], [1, 0, 0, 0])}},
    {'bodies': {'box_b': ([0.9, 0.1, 0.9], [2, 0, 0, 0])}},  # not a unit quaternion
    {'body_velocities': {'table': ([0, 0, 1], [0, 0, 0])}},  # a static body cannot move
])
def test_a_bad_part_of_a_state_overwrite_changes_nothing(bad):
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    sim.step(dt=0.1)
    before = sim.world.get_state()
    state = {'bodies': {'box_a': (np.array([0.7, 0.3, 0.8]), np.array([1., 0, 0, 0]))},
             'joints': {'left_elbow': 0.2}}
    for key, part in bad.items():
        state.setdefault(key, {}).update(part)
    with pytest.raises(SimError):
        sim.set_state(state)
    after = sim.world.get_state()
    assert after.generation == before.generation
    assert np.array_equal(after.values, before.values)


def test_state_round_trip_keeps_the_model_and_a_static_body_can_be_moved():
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    sim.step(dt=0.2)
    gen = sim.world.generation
    sim.set_state(sim.get_state())  # static bodies at their own pose: no rebuild
    assert sim.world.generation == gen
    table = sim.get_state()['bodies']['table']
    sim.set_state({'bodies': {'table': (table[0] + [0, 0.5, 0], table[1])}})
    assert np.allclose(sim.get_state()['bodies']['table'][0], table[0] + [0, 0.5, 0])


def test_run_stops_at_the_constraint():
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    assert sim.run(max_steps=250) == 'max_steps'
    assert sim.world.step_count == 250
    assert sim.run(max_time=1.0) == 'max_time'
    assert sim.time == pytest.approx(1.0)
    with pytest.raises(InvalidArgumentError):
        sim.run()


def test_massless_body_is_static_and_welded_child_moves_with_parent():
    sim = Simulation.empty()
    sim.add_object('shelf', 'box', [0.2, 0.2, 0.02], position=[0, 0, 1.0], mass=0)
    sim.add_object('cart', 'box', [0.1, 0.1, 0.05], position=[1, 0, 0.5], mass=1.0)
    sim.add_body('lamp', 'cart', 'sphere', [0.03], position=[0, 0, 0.1], mass=0.1)
    sim.step(dt=1.0)
    st = sim.get_state()
    assert st['bodies']['shelf'][0][2] == pytest.approx(1.0)  # no mass: static
    assert 'cart/lamp' not in st['bodies']  # welded: part of the cart entity
    cart_z = st['bodies']['cart'][0][2]
    assert cart_z == pytest.approx(0.05, abs=0.01)
    with sim.world.locked() as (m, d):
        lamp_z = d.xpos[m.body('cart/lamp').id][2]
    assert lamp_z == pytest.approx(cart_z + 0.1, abs=1e-6)
