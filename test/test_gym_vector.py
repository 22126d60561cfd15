"""SimVectorEnv: gymnasium.make_vec of the sim/ ids, against N separate envs, Gymnasium's way."""

import gymnasium as gym
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers import TimeLimit
import numpy as np
import pytest
from sim_node.gym import env as gym_env
from sim_node.gym.env import SimEnv
from sim_node.gym.vector import SimVectorEnv

IDS = list(gym_env.TASKS)


def assert_same_info(ours: dict, theirs: dict):
    assert set(ours) == set(theirs)
    for key, value in theirs.items():
        if isinstance(value, dict):
            assert_same_info(ours[key], value)
        elif value.dtype == object:  # final_obs: one array per env, None where none
            for a, b in zip(ours[key], value):
                assert (a is None and b is None) or np.array_equal(a, b), key
        else:
            assert ours[key].dtype == value.dtype, key
            assert np.array_equal(ours[key], value), key


def run_side_by_side(ours, theirs, steps: int, seed: int = 5) -> int:
    """Step both with the same actions; assert every output is the same; return episodes ended."""
    o1, i1 = ours.reset(seed=seed)
    o2, i2 = theirs.reset(seed=seed)
    assert np.array_equal(o1, o2)
    assert_same_info(i1, i2)
    rng = np.random.default_rng(0)
    space = ours.single_action_space
    ended = 0
    for _ in range(steps):
        actions = rng.uniform(space.low, space.high,
                              size=(ours.num_envs,) + space.shape).astype(np.float32)
        a = ours.step(actions)
        b = theirs.step(actions)
        for x, y, what in zip(a[:4], b[:4], ('obs', 'reward', 'terminated', 'truncated')):
            assert np.array_equal(x, y), what
        assert_same_info(a[4], b[4])
        ended += int((a[2] | a[3]).sum())
    return ended


@pytest.mark.parametrize('env_id', IDS)
def test_make_vec_gives_our_vector_env_with_the_single_envs_spaces(env_id):
    envs = gym.make_vec(env_id, num_envs=3)
    single = gym.make(env_id)
    try:
        assert isinstance(envs.unwrapped, SimVectorEnv)
        assert envs.metadata['autoreset_mode'] == AutoresetMode.NEXT_STEP
        assert envs.single_observation_space == single.observation_space
        assert envs.single_action_space == single.action_space
        obs, info = envs.reset(seed=0)
        assert obs.shape == (3,) + single.observation_space.shape
        assert info['_is_success'].all() and info['is_success'].dtype == bool
    finally:
        envs.close()
        single.close()


@pytest.mark.parametrize('env_id', IDS)
def test_n_worlds_step_exactly_as_n_separate_envs_seeded_seed_plus_i(env_id):
    """Against Gymnasium's SyncVectorEnv over gymnasium.make: N separate envs, one by one."""
    kwargs = {'max_episode_steps': 7}  # episodes end (truncated) and autoreset in the run
    ours = gym.make_vec(env_id, num_envs=3, num_threads=2, **kwargs)
    theirs = gym.make_vec(env_id, num_envs=3, vectorization_mode='sync', **kwargs)
    try:
        assert run_side_by_side(ours, theirs, steps=24) >= 9
    finally:
        ours.close()
        theirs.close()


def test_same_step_autoreset_matches_gymnasiums():
    mode = {'autoreset_mode': AutoresetMode.SAME_STEP}
    ours = gym.make_vec('sim/PushBox-v0', num_envs=2, max_episode_steps=5, **mode)
    theirs = gym.make_vec('sim/PushBox-v0', num_envs=2, max_episode_steps=5,
                          vectorization_mode='sync', vector_kwargs=mode)
    try:
        assert run_side_by_side(ours, theirs, steps=12) >= 4
    finally:
        ours.close()
        theirs.close()


class EndsSoon(gym_env.PushBoxTask):
    """PushBox whose episodes end (terminated) once the box is within 20 cm of the goal."""

    SUCCESS = 0.2


def test_terminated_episodes_reset_as_gymnasium_resets_them():
    ours = SimVectorEnv(EndsSoon, 4, max_episode_steps=40)
    theirs = gym.vector.SyncVectorEnv(
        [lambda: TimeLimit(SimEnv(EndsSoon()), 40) for _ in range(4)])
    try:
        ours.reset(seed=11)
        run_side_by_side(ours, theirs, steps=60, seed=11)
        # Some episodes ended by termination, not only by the time limit.
        ours.reset(seed=11)
        terminated = 0
        for _ in range(60):
            terminated += ours.step(ours.action_space.sample())[2].sum()
        assert terminated > 0
    finally:
        ours.close()
        theirs.close()


def test_threads_change_nothing_but_speed():
    outs = []
    for threads in (1, 2):
        envs = gym.make_vec('sim/Reacher-v0', num_envs=5, num_threads=threads)
        obs, _ = envs.reset(seed=3)
        rng = np.random.default_rng(1)
        for _ in range(30):
            obs, reward, *_ = envs.step(rng.uniform(-1, 1, size=(5, 2)))
        outs.append((obs, reward))
        envs.close()
    assert np.array_equal(outs[0][0], outs[1][0]) and np.array_equal(outs[0][1], outs[1][1])


def test_seeds_may_be_given_one_per_env():
    envs = gym.make_vec('sim/PushBox-v0', num_envs=2)
    single = gym.make('sim/PushBox-v0')
    try:
        obs, _ = envs.reset(seed=[42, 7])
        assert np.array_equal(obs[1], single.reset(seed=7)[0])
        with pytest.raises(ValueError, match='give 2 seeds'):
            envs.reset(seed=[1, 2, 3])
    finally:
        envs.close()
        single.close()


@pytest.mark.parametrize('bad, match', [
    (np.zeros((3, 2)), 'shape'),
    (np.full((2, 2), np.nan), 'finite'),
    (np.full((2, 2), 1e12), 'finite'),
])
def test_bad_actions_are_refused_and_no_world_moves(bad, match):
    envs = gym.make_vec('sim/PushBox-v0', num_envs=2)
    try:
        obs, _ = envs.reset(seed=0)
        before = [e.world.get_state() for e in envs.unwrapped.envs]
        with pytest.raises(ValueError, match=match):
            envs.step(bad)
        after = [e.world.get_state() for e in envs.unwrapped.envs]
        assert all(np.array_equal(a.values, b.values) for a, b in zip(before, after))
    finally:
        envs.close()


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match='num_envs must be >= 1'):
        SimVectorEnv(gym_env.PushBoxTask, 0)
    with pytest.raises(ValueError, match='NEXT_STEP or SAME_STEP'):
        SimVectorEnv(gym_env.PushBoxTask, 2, autoreset_mode=AutoresetMode.DISABLED)
    with pytest.raises(ValueError, match='max_episode_steps'):
        SimVectorEnv(gym_env.PushBoxTask, 2, max_episode_steps=0)


def test_a_vector_env_renders_one_frame_per_world():
    envs = gym.make_vec('sim/Reach-v0', num_envs=2, render_mode='rgb_array', width=64,
                        height=48)
    try:
        envs.reset(seed=[0, 1])
        frames = envs.render()
        assert len(frames) == 2 and all(f.shape == (48, 64, 3) for f in frames)
    finally:
        envs.close()


@pytest.mark.slow
def test_the_ray_example_rolls_out_on_two_workers():
    """examples/ray_rollouts.py on a local Ray cluster: two actors, each a vector env."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parent.parent / 'examples' / 'ray_rollouts.py'
    spec = importlib.util.spec_from_file_location('ray_rollouts', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    summary = module.main(['--workers', '2', '--envs', '3', '--steps', '120', '--rounds', '2'])
    assert summary['workers'] == 2  # two processes did the work
    assert summary['env_steps'] == 2 * 2 * 3 * 120
    # Pusher-v0 episodes are 100 steps: each of the 6 worlds ended at least two.
    assert summary['episodes'] >= 12 and np.isfinite(summary['mean_return'])


def test_the_worlds_are_stepped_on_as_many_threads_as_asked():
    import threading
    envs = gym.make_vec('sim/Reacher-v0', num_envs=4, num_threads=2)
    seen = set()
    try:
        envs.reset(seed=0)
        for env in envs.unwrapped.envs:
            world_step = env.world.step

            def step(*args, _step=world_step, **kwargs):
                seen.add(threading.get_ident())
                return _step(*args, **kwargs)
            env.world.step = step
        envs.step(np.zeros((4, 2)))
        assert len(seen) == 2 and threading.get_ident() in seen
    finally:
        envs.close()


def test_a_world_that_diverges_is_named_and_the_others_step_on():
    from sim_node.core.errors import DivergenceError
    envs = gym.make_vec('sim/Reacher-v0', num_envs=3, num_threads=2)
    try:
        envs.reset(seed=0)
        worlds = [e.world for e in envs.unwrapped.envs]
        times = [w.clock().time for w in worlds]
        with worlds[2].locked() as (m, d):
            d.qvel[:] = 1e12  # beyond what MuJoCo calls a sane state
        with pytest.raises(DivergenceError) as caught:
            envs.step(np.zeros((3, 2)))
        assert caught.value.env_index == 2
        assert 'in world 2 of the vector env' in ''.join(caught.value.__notes__)
        assert [w.clock().time > t for w, t in zip(worlds, times)] == [True, True, False]
        obs, _ = envs.reset(seed=0)
        assert np.isfinite(envs.step(np.zeros((3, 2)))[0]).all()
    finally:
        envs.close()
