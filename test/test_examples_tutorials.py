"""The tutorials in examples/, run headless, with the outcome each one promises."""

import importlib.util
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / 'examples'


def run_example(name: str) -> dict:
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f'{name}.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main()


def test_ball_bounces_higher_with_a_higher_default_restitution():
    r = run_example('ball_drop')
    assert r['restitution_0.7'] > r['plain'] + 0.2


def test_block_only_falls_once_it_has_mass():
    r = run_example('block_gets_mass')
    assert r['z_without_mass'] == pytest.approx(1.0)
    assert r['z_with_mass'] == pytest.approx(0.05, abs=0.01)


def test_lower_friction_slides_further_higher_restitution_bounces_higher():
    r = run_example('friction_restitution')
    s, b = r['slides'], r['bounces']
    assert s[0] > s[1] > s[2] > 10 * max(s[3:])
    assert all(later > earlier for earlier, later in zip(b, b[1:]))


def test_push_stack_swap_then_reset_reproduces_the_first_run():
    r = run_example('push_stack')
    assert r['swap_ok'] and r['same_after_reset']
    assert r['moved'] > 0.02


def test_default_scene_stops_at_max_steps():
    r = run_example('default_10k')
    assert r['steps'] == 10_000 and r['time'] == pytest.approx(20.0)
    assert 'max_steps' in r['reason']


def test_world_built_while_running_and_arm_follows_commands():
    r = run_example('build_in_code')
    assert r['entities'] == {'base': 'robot', 'crate': 'dynamic'}  # the arm is part of base
    assert r['crate_z'] == pytest.approx(0.05, abs=0.01)
    assert r['mean_tracking_error'] < 0.2
