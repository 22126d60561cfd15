"""Gymnasium environments: registered ids, env checker, determinism, vector envs."""

import subprocess
import sys

import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import numpy as np
import pytest
import sim_node.gym_env  # noqa: F401  (registers the ids here; see the next test for without)

IDS = ['sim/PushBox-v0', 'sim/Reach-v0']


def test_make_works_without_importing_anything_first():
    code = ('import gymnasium; e = gymnasium.make("sim/PushBox-v0"); '
            'print(e.reset(seed=0)[0].shape)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd='/')
    assert out.returncode == 0, out.stderr
    assert '(10,)' in out.stdout


@pytest.mark.parametrize('env_id', IDS)
def test_env_checker_passes(env_id):
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize('env_id', IDS)
def test_same_seed_same_actions_same_observations_and_rewards(env_id):
    def rollout():
        env = gym.make(env_id)
        obs, _ = env.reset(seed=123)
        env.action_space.seed(7)
        out = [obs]
        for _ in range(30):
            obs, r, term, trunc, _ = env.step(env.action_space.sample())
            out.append(np.append(obs, r))
        return out
    a, b = rollout(), rollout()
    assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_reset_restores_instead_of_rebuilding():
    env = gym.make('sim/Reach-v0').unwrapped
    gen = env.world.generation
    o1, _ = env.reset(seed=5)
    for _ in range(10):
        env.step(env.action_space.sample())
    o2, _ = env.reset(seed=5)
    assert np.array_equal(o1, o2) and env.world.generation == gen


def test_actions_follow_control_ranges():
    env = gym.make('sim/PushBox-v0').unwrapped
    assert np.allclose(env.action_space.low, [-0.5, -0.5])
    assert np.allclose(env.action_space.high, [0.5, 0.5])


@pytest.mark.parametrize('bad', [[np.nan, 0.0], [0.0, np.inf], [1e11, 0.0], [0.1], 0.1])
def test_a_bad_action_is_refused_and_changes_nothing(bad):
    """
    NaN, inf or > 1e10 would make MuJoCo zero every actuator; a wrong shape would be broadcast.

    Each is a ValueError, and the world is where it was.
    """
    env = gym.make('sim/PushBox-v0').unwrapped
    env.reset(seed=3)
    env.step(np.array([0.2, -0.1]))
    before = env.world.get_state()
    with pytest.raises(ValueError, match='action must'):
        env.step(np.asarray(bad))
    after = env.world.get_state()
    assert after.step == before.step and np.array_equal(after.values, before.values)
    # Out of range but finite is fine: MuJoCo clamps it to the control range.
    env.step(np.array([5.0, -5.0]))
    assert env.world.step_count == before.step + env.task.frame_skip


def test_pushing_toward_the_goal_improves_the_reward():
    env = gym.make('sim/PushBox-v0').unwrapped
    obs, _ = env.reset(seed=1)
    r0 = env.world.read(env.task.reward)
    for _ in range(150):  # a scripted policy: get behind the box, push it to the goal
        tip, box, goal = obs[0:2], obs[4:6], obs[8:10]
        direction = (goal - box) / (np.linalg.norm(goal - box) + 1e-9)
        behind = box - 0.06 * direction
        aim = behind if np.linalg.norm(tip - behind) > 0.02 else goal
        obs, r, term, _, _ = env.step(np.clip(5 * (aim - tip), -0.5, 0.5))
        if term:
            break
    assert r > r0


def test_async_vector_env():
    envs = gym.vector.AsyncVectorEnv([lambda: gym.make('sim/Reach-v0')] * 2)
    try:
        obs, _ = envs.reset(seed=[1, 2])
        assert obs.shape == (2, 14)
        obs, rewards, *_ = envs.step(envs.action_space.sample())
        assert rewards.shape == (2,)
    finally:
        envs.close()


def test_observations_come_from_the_world_after_a_recompile():
    """A spawn into env.world replaces its model and data: the env reads the new ones."""
    from sim_node.core import sources
    env = gym.make('sim/PushBox-v0').unwrapped
    env.reset(seed=0)
    env.step(env.action_space.low)  # the model and data of before the spawn are in use here
    env.world.spawn('crate', sources.primitive('box', [0.05, 0.05, 0.05]), (3.0, 3.0, 0.5))
    first = env.step(env.action_space.high)[0]
    second = env.step(env.action_space.high)[0]
    assert not np.array_equal(first[:2], second[:2])  # the pusher moves in the live world
    qpos = env.world.read(lambda m, d: d.qpos[:2].copy())
    assert np.array_equal(second[:2], qpos)
    env.close()
