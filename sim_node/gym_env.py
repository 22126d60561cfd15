"""
Gymnasium environments over the same core world (composed, not Gymnasium's MujocoEnv).

    import gymnasium, sim_node.gym_env   # the import registers sim/PushBox-v0, sim/Reach-v0
    env = gymnasium.make('sim/PushBox-v0')

(``gymnasium.make('sim_node.gym_env:sim/PushBox-v0')`` works without the import.)

A :class:`SimEnv` is a scene plus a :class:`Task` (observation, reward, termination, and an
optional hook that randomizes the initial state from the seed). ``reset(seed)`` restores a
snapshot of the initial state instead of rebuilding; actions are actuator controls within the
actuators' control ranges.
"""

from typing import Optional

import gymnasium as gym
from gymnasium import spaces
import mujoco
import numpy as np

from . import resources
from .core.checks import MAX_ABS_VALUE as MAX_CONTROL
from .core.world import World


def _scene(name: str) -> str:
    """Return a scene file: from the source tree, else from the installed share folder."""
    path = resources.source_scenes_dir() / name
    return str(path if path.is_file() else resources.installed_scenes_dir() / name)


class Task:
    """
    What a task defines; subclass and override.

    Methods get ``(model, data)`` read-only, except :meth:`randomize`, which may write the initial
    state.
    """

    scene = 'default.xml'
    frame_skip = 5

    def setup(self, model: mujoco.MjModel) -> None:
        """Look up ids once per model."""

    def randomize(self, model: mujoco.MjModel, data: mujoco.MjData,
                  rng: np.random.Generator) -> None:
        """Change the initial state from the seeded generator (called by reset)."""

    def observation(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        raise NotImplementedError

    def reward(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        raise NotImplementedError

    def terminated(self, model: mujoco.MjModel, data: mujoco.MjData) -> bool:
        return False


class SimEnv(gym.Env):
    """A Gymnasium environment: a :class:`World` built from the task's scene."""

    metadata = {'render_modes': []}

    def __init__(self, task: Task, render_mode: Optional[str] = None):
        if render_mode is not None:
            raise ValueError('sim environments do not render; watch them in RViz instead')
        self.task = task
        self.world = World.from_file(_scene(task.scene))
        with self.world.locked() as (m, d):  # no MuJoCo object is kept past the block
            task.setup(m)
            lo, hi = m.actuator_ctrlrange[:, 0].copy(), m.actuator_ctrlrange[:, 1].copy()
            limited = m.actuator_ctrllimited.astype(bool)
            lo[~limited], hi[~limited] = -np.inf, np.inf
            obs = task.observation(m, d)
        self.action_space = spaces.Box(lo.astype(np.float32), hi.astype(np.float32),
                                       dtype=np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=obs.shape, dtype=np.float64)
        self._action_shape = self.action_space.shape
        self._initial = self.world.get_state()

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        self.world.set_state(self._initial)
        with self.world.locked() as (m, d):
            self.task.randomize(m, d, self.np_random)
            mujoco.mj_forward(m, d)
            obs = self.task.observation(m, d)
        return obs, {}

    def step(self, action):
        # MuJoCo clamps ctrl to the control ranges itself (ctrllimited actuators), but zeroes
        # every actuator while any control is NaN or beyond 1e10: refuse those here.
        action = np.asarray(action, dtype=np.float64)
        if action.shape != self._action_shape:
            raise ValueError(f'action must have shape {self._action_shape}, '
                             f'got {action.shape}')
        # Exact and cheap for a short vector: NaN or inf make the sum fail the test; a large
        # sum gets the element-wise check.
        if not sum(map(abs, action.tolist())) <= MAX_CONTROL and not (
                np.abs(action) <= MAX_CONTROL).all():
            raise ValueError(f'action must be finite and within +-{MAX_CONTROL:g}, got {action}')
        self.world.step(self.task.frame_skip, ctrl=action)
        # The world's current model and data, under its lock: a recompile (a spawn into
        # env.world, say) replaces both, so none is kept from one call to the next.
        return self.world.read(self._outcome)

    def _outcome(self, m: mujoco.MjModel, d: mujoco.MjData) -> tuple:
        task = self.task
        return (task.observation(m, d), float(task.reward(m, d)), bool(task.terminated(m, d)),
                False, {})


class PushBoxTask(Task):
    """
    A finger on two slide joints pushes a box to a goal on the table.

    Dense reward on the box-goal distance (plus a small term for reaching the box). Success within
    3 cm.
    """

    scene = 'push_box.xml'
    frame_skip = 10

    def setup(self, model):
        self.box = model.body('box').id
        self.pusher = model.body('pusher').id
        self.goal = model.site('goal').id
        self.box_q = model.jnt_qposadr[model.joint('box_free').id]
        self.goal_xy = np.array([0.2, 0.2])

    def randomize(self, model, data, rng):
        self.goal_xy = rng.uniform(-0.25, 0.25, size=2)
        box_xy = rng.uniform(-0.15, 0.15, size=2)
        data.qpos[self.box_q:self.box_q + 2] = box_xy
        data.qpos[0:2] = box_xy + rng.uniform(-0.12, -0.08, size=2)
        model.site_pos[self.goal][:2] = self.goal_xy

    def observation(self, model, data):
        return np.concatenate([data.qpos[0:2], data.qvel[0:2], data.xpos[self.box][:2],
                               data.qvel[2:4], self.goal_xy])

    def reward(self, model, data):
        box = data.xpos[self.box][:2]
        tip = data.xpos[self.pusher][:2]
        return -np.linalg.norm(box - self.goal_xy) - 0.1 * np.linalg.norm(tip - box)

    def terminated(self, model, data):
        return bool(np.linalg.norm(data.xpos[self.box][:2] - self.goal_xy) < 0.03)


class ReachTask(Task):
    """The default scene's left arm brings its tip to a random reachable target."""

    scene = 'default.xml'
    frame_skip = 5
    SHOULDER = np.array([0.19, 0.2, 0.55])

    def setup(self, model):
        self.tip = model.site('left_tip').id
        self.target = self.SHOULDER + np.array([0.45, 0.0, 0.0])

    def randomize(self, model, data, rng):
        a1 = rng.uniform(-1.0, 0.2)
        a2 = rng.uniform(0.0, 1.0)
        # Rotation about +y by a maps the x axis to (cos a, 0, -sin a).
        self.target = self.SHOULDER + 0.3 * np.array([np.cos(a1), 0, -np.sin(a1)]) + \
            0.25 * np.array([np.cos(a1 + a2), 0, -np.sin(a1 + a2)])

    def observation(self, model, data):
        return np.concatenate([data.qpos[:4], data.qvel[:4], data.site_xpos[self.tip],
                               self.target])

    def reward(self, model, data):
        return -float(np.linalg.norm(data.site_xpos[self.tip] - self.target))

    def terminated(self, model, data):
        return False


def make_push_box(**kwargs) -> SimEnv:
    return SimEnv(PushBoxTask(), **kwargs)


def make_reach(**kwargs) -> SimEnv:
    return SimEnv(ReachTask(), **kwargs)


def register_envs() -> None:
    """Register sim/PushBox-v0 and sim/Reach-v0 (idempotent)."""
    for env_id, entry, steps in (('sim/PushBox-v0', 'sim_node.gym_env:make_push_box', 200),
                                 ('sim/Reach-v0', 'sim_node.gym_env:make_reach', 200)):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry, max_episode_steps=steps)


register_envs()
