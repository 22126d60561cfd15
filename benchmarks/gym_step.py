"""
Env.step throughput of our Gymnasium environments over Gymnasium's own MuJoCo environments.

Two comparisons, each measured side by side in one run (interleaved rounds, median):

1. Gymnasium's own environments, Pusher-v5 (frame skip 5) and Reacher-v5 (frame skip 2),
   against a SimEnv on the same model file with the same frame skip and a Task that computes
   the same observation and reward. Before timing, both are put in the same state and driven
   with the same actions; the largest observation and reward differences are printed, so the
   two are shown to be the same environment.
2. Framework overhead alone: sim/Reach-v0 against a minimal MujocoEnv subclass that runs the
   very same Task code on scenes/default.xml. Only the stepping machinery differs: ours adds the
   world lock, the divergence check and the state kept for replaying a divergence; Gymnasium's
   adds mj_rnePostConstraint and its action-shape check.

All environments are unwrapped (no TimeLimit or checker wrappers) and get the same actions.
"""

import os
from pathlib import Path
import statistics
import sys
import time

import gymnasium as gym
from gymnasium.envs.mujoco import MujocoEnv
from gymnasium.spaces import Box
import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from sim_node.gym.env import PusherTask, ReacherTask, ReachTask, SimEnv  # noqa: E402
sys.path.insert(0, str(Path(__file__).resolve().parent))
from verdict import verdict  # noqa: E402, I100

SCENE = str(Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml')


class GymnasiumReach(MujocoEnv):
    """Sim/Reach-v0's Task run by Gymnasium's MujocoEnv: the same work per step as SimEnv."""

    metadata = {'render_modes': ['human', 'rgb_array', 'depth_array', 'rgbd_tuple'],
                'render_fps': 100}

    def __init__(self):
        super().__init__(SCENE, ReachTask.frame_skip,
                         observation_space=Box(-np.inf, np.inf, (14,), dtype=np.float64))
        self.task = ReachTask()
        self.task.setup(self.model)

    def step(self, action):
        self.do_simulation(action, self.frame_skip)
        m, d = self.model, self.data
        obs = self.task.observation(m, d)
        return obs, float(self.task.reward(m, d)), bool(self.task.terminated(m, d)), False, {}

    def reset_model(self):
        self.set_state(self.init_qpos, self.init_qvel)
        return self.task.observation(self.model, self.data)


def same_environment(ours: SimEnv, theirs, actions) -> tuple:
    """Put both in Gymnasium's reset state, step both; the largest obs and reward gaps."""
    theirs.reset(seed=0)
    ours.reset(seed=0)
    d = theirs.unwrapped.data
    with ours.world.locked() as (m, od):
        od.qpos[:], od.qvel[:] = d.qpos, d.qvel
        mujoco.mj_forward(m, od)
    obs_gap = rew_gap = 0.0
    for a in actions[:200]:
        o1, r1, *_ = ours.step(a)
        o2, r2, *_ = theirs.step(a)
        obs_gap = max(obs_gap, float(np.abs(o1 - o2).max()))
        rew_gap = max(rew_gap, abs(r1 - r2))
    return obs_gap, rew_gap


def steps_per_sec(env, actions) -> float:
    env.reset(seed=0)
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    return len(actions) / (time.perf_counter() - t0)


def compare(ours, theirs, n: int, rounds: int) -> tuple:
    shape = ours.action_space.shape
    actions = np.random.default_rng(0).uniform(-1, 1, size=(n,) + shape)
    a, b = [], []
    for _ in range(rounds):
        a.append(steps_per_sec(ours, actions))
        b.append(steps_per_sec(theirs, actions))
    return statistics.median(a), statistics.median(b), actions


def main(n: int = 20000, rounds: int = 5) -> None:
    print(f'[gym env.step] steps/s, median of {rounds} interleaved rounds of {n} steps; '
          'all unwrapped, same random actions')
    for name, task in (('Pusher-v5', PusherTask()), ('Reacher-v5', ReacherTask())):
        ours, theirs = SimEnv(task), gym.make(name).unwrapped
        ra, rb, actions = compare(ours, theirs, n, rounds)
        obs_gap, rew_gap = same_environment(ours, theirs, actions)
        print(f'  Gymnasium {name:10s} (own env, frame skip {task.frame_skip}): {rb:8.0f}   '
              f'SimEnv, same model file and task: {ra:8.0f}   ratio {ra / rb:5.2f}'
              f'   (target >= 1.0; same run: max |obs diff| {obs_gap:.1e}, '
              f'|reward diff| {rew_gap:.1e})')
        verdict(ra / rb >= 1.0, f'SimEnv / Gymnasium {name} steps per second, {ra / rb:.2f} '
                '(target >= 1.0)')
    ra, rb, _ = compare(SimEnv(ReachTask()), GymnasiumReach(), n, rounds)
    print(f'  framework only, sim/Reach-v0 Task on default.xml, frame skip '
          f'{ReachTask.frame_skip}: MujocoEnv subclass {rb:8.0f}   SimEnv {ra:8.0f}   '
          f'ratio {ra / rb:5.2f}')


if __name__ == '__main__':
    os.environ.setdefault('MUJOCO_GL', 'disable')
    main()
