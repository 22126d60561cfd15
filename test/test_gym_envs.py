"""Gymnasium environments: registered ids, env checker, determinism, vector envs."""

import os
from pathlib import Path
import subprocess
import sys

import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import numpy as np
import pytest
import sim_node.gym.env  # noqa: F401  (registers the ids here; see the next test for without)

IDS = ['sim/PushBox-v0', 'sim/Reach-v0', 'sim/Pusher-v0', 'sim/Reacher-v0']


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
    from sim_node.core.models import sources
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


# --------------------------------------------------------------------------- info


def test_push_box_info_holds_the_distances_its_reward_is_made_of():
    env = gym.make('sim/PushBox-v0')
    obs, info = env.reset(seed=3)
    assert set(info) == {'is_success', 'box_to_goal', 'tip_to_box'}
    for _ in range(5):
        obs, reward, terminated, _, info = env.step(env.action_space.sample())
        box, goal = obs[4:6], obs[8:10]  # the observation's own box and goal positions
        assert info['box_to_goal'] == pytest.approx(np.hypot(*(box - goal)), abs=1e-12)
        assert reward == pytest.approx(-info['box_to_goal'] - 0.1 * info['tip_to_box'])
        assert info['is_success'] is terminated is (info['box_to_goal'] < 0.03)


def test_is_success_turns_true_when_the_object_reaches_the_goal():
    env = gym.make('sim/Pusher-v0').unwrapped
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(7))
    assert info['is_success'] is False and info['object_to_goal'] > 0.05
    with env.world.locked() as (m, d):  # the cylinder's slide joints: put it on the goal
        goal = d.xpos[m.body('goal').id][:2] - m.body('object').pos[:2]
        d.qpos[-4:-2] = goal
        d.qvel[-4:] = 0.0
    _, _, _, _, info = env.step(np.zeros(7))
    # On the goal in the plane; the goal marker sits 4.8 cm lower than the cylinder's centre.
    assert info['is_success'] is True and info['object_to_goal'] < 0.05


@pytest.mark.parametrize('env_id', IDS)
def test_every_task_reports_is_success_and_distances(env_id):
    env = gym.make(env_id)
    _, first = env.reset(seed=0)
    *_, info = env.step(env.action_space.sample())
    assert set(info) == set(first) and isinstance(info['is_success'], bool)
    distances = [k for k in info if k != 'is_success']
    assert distances and all(isinstance(info[k], float) and info[k] >= 0 for k in distances)


# --------------------------------------------------------------------------- rendering


@pytest.mark.parametrize('env_id', IDS)
def test_rgb_array_frames_show_the_scene(env_id):
    env = gym.make(env_id, render_mode='rgb_array', width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.reshape(-1, 3).std(axis=0).min() > 5  # a picture, not a blank
    env.close()


def test_frames_follow_the_world_and_the_chosen_camera():
    env = gym.make('sim/Reach-v0', render_mode='rgb_array', width=96, height=96)
    env.reset(seed=0)
    before = env.render()
    for _ in range(20):
        env.step(env.action_space.high)  # the arm swings
    after = env.render()
    assert np.abs(after.astype(int) - before.astype(int)).sum() > 0
    env.close()
    named = gym.make('sim/Reach-v0', render_mode='rgb_array', width=96, height=96,
                     camera_name='overview')
    by_id = gym.make('sim/Reach-v0', render_mode='rgb_array', width=96, height=96,
                     camera_id=0)
    for e in (named, by_id):
        e.reset(seed=0)
    assert np.array_equal(named.render(), by_id.render())
    assert not np.array_equal(named.render(), before)  # not the free camera
    named.close()
    by_id.close()


def test_depth_array_is_metres_from_the_camera():
    env = gym.make('sim/Reach-v0', render_mode='depth_array', width=64, height=48,
                   camera_name='overview')
    env.reset(seed=0)
    depth = env.render()
    assert depth.shape == (48, 64) and depth.dtype == np.float32
    seen = depth[np.isfinite(depth)]
    # The overview camera stands about 3.2 m from the table it looks at.
    assert seen.size > 0.5 * depth.size and 1.0 < np.median(seen) < 6.0
    env.close()


def test_bad_render_arguments_are_refused_when_the_env_is_made():
    with pytest.raises(ValueError, match="'human' opens a window.*rgb_array"):
        gym.make('sim/PushBox-v0', render_mode='human')
    with pytest.raises(ValueError, match='render_mode must be'):
        gym.make('sim/PushBox-v0', render_mode='rgbd')
    with pytest.raises(ValueError, match='not both'):
        gym.make('sim/Reach-v0', render_mode='rgb_array', camera_name='overview', camera_id=0)
    with pytest.raises(ValueError, match='camera_id 5'):
        gym.make('sim/Reach-v0', render_mode='rgb_array', camera_id=5)
    from sim_node.core.errors import NotFoundError
    with pytest.raises(NotFoundError, match="no camera named 'nope'.*overview"):
        gym.make('sim/Reach-v0', render_mode='rgb_array', camera_name='nope')


def test_a_machine_that_cannot_render_says_so_when_the_env_is_made():
    code = ('import ctypes.util; ctypes.util.find_library = lambda name: None\n'
            'import gymnasium, sim_node.gym.env\n'
            'e = gymnasium.make("sim/PushBox-v0")\n'  # without render_mode: fine
            'try:\n    gymnasium.make("sim/PushBox-v0", render_mode="rgb_array")\n'
            'except Exception as exc:\n    print(type(exc).__name__, exc)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         env=dict(os.environ, MUJOCO_GL=''), timeout=120,
                         cwd=str(Path(__file__).resolve().parent.parent))
    assert 'RenderingUnavailableError' in out.stdout and 'apt-get install' in out.stdout, \
        out.stdout + out.stderr


def test_record_video_writes_one_frame_per_step_and_the_first(tmp_path):
    from gymnasium.wrappers import RecordVideo
    import imageio.v3 as iio
    env = gym.make('sim/PushBox-v0', render_mode='rgb_array', width=128, height=96,
                   max_episode_steps=12)
    env = RecordVideo(env, str(tmp_path), episode_trigger=lambda episode: True,
                      disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    assert len(env.recorded_frames) == 13  # the reset's frame and one per step
    env.close()
    videos = sorted(tmp_path.glob('*.mp4'))
    assert len(videos) == 1
    frames = np.stack(list(iio.imiter(videos[0], plugin='FFMPEG')))
    # MoviePy 2's writer leaves out the last frame of a clip (13 frames at 50 fps make a
    # 0.24 s file); the frames that are there are ours, in size and content.
    assert frames.shape[0] in (12, 13) and frames.shape[1:] == (96, 128, 3)
    assert frames.reshape(-1, 3).std(axis=0).min() > 5
