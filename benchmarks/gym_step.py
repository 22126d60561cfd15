"""env.step throughput: our sim/Reach-v0 over Gymnasium's own MujocoEnv stepping the same
model (scenes/default.xml) with the same frame skip, observation and reward. Both unwrapped,
same random actions, interleaved runs; prints the ratio."""

import statistics
import sys
import time
from pathlib import Path

import numpy as np
from gymnasium.envs.mujoco import MujocoEnv
from gymnasium.spaces import Box

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from sim_node.gym_env import ReachTask, SimEnv  # noqa: E402

SCENE = str(Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml')


class GymnasiumReach(MujocoEnv):
    """The same task written the usual Gymnasium way."""

    metadata = {'render_modes': ['human', 'rgb_array', 'depth_array', 'rgbd_tuple'],
                'render_fps': 100}

    def __init__(self):
        super().__init__(SCENE, ReachTask.frame_skip,
                         observation_space=Box(-np.inf, np.inf, (14,), dtype=np.float64))
        self.task = ReachTask()
        self.task.setup(self.model)

    def step(self, action):
        self.do_simulation(action, self.frame_skip)
        obs = self.task.observation(self.model, self.data)
        return obs, self.task.reward(self.model, self.data), False, False, {}

    def reset_model(self):
        self.set_state(self.init_qpos, self.init_qvel)
        return self.task.observation(self.model, self.data)


def steps_per_sec(env, actions) -> float:
    env.reset(seed=0)
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    return len(actions) / (time.perf_counter() - t0)


def main(n: int = 20000, rounds: int = 5) -> None:
    ours, theirs = SimEnv(ReachTask()), GymnasiumReach()
    actions = np.random.default_rng(0).uniform(-1, 1, size=(n, 4))
    a, b = [], []
    for _ in range(rounds):
        a.append(steps_per_sec(ours, actions))
        b.append(steps_per_sec(theirs, actions))
    ra, rb = statistics.median(a), statistics.median(b)
    print(f'[gym env.step] Reach on scenes/default.xml, frame skip {ReachTask.frame_skip}, '
          f'{rounds} interleaved rounds of {n} steps (median)')
    print(f'  sim SimEnv (sim/Reach-v0)         : {ra:9.0f} steps/s')
    print(f'  Gymnasium MujocoEnv, same model   : {rb:9.0f} steps/s')
    print(f'  ratio sim/Gymnasium               : {ra / rb:9.2f}   (target >= 1.0)')


if __name__ == '__main__':
    main()
