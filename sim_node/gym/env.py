"""
Gymnasium environments over the same core world (composed, not Gymnasium's MujocoEnv).

    import gymnasium, sim_node.gym.env   # the import registers the sim/ ids below
    env = gymnasium.make('sim/PushBox-v0', render_mode='rgb_array')
    envs = gymnasium.make_vec('sim/PushBox-v0', num_envs=8)   # a SimVectorEnv (gym_vector)

(``gymnasium.make('sim_node.gym.env:sim/PushBox-v0')`` works without the import.) The ids:
sim/PushBox-v0 and sim/Reach-v0 on this project's scenes, sim/Pusher-v0 and sim/Reacher-v0 on
Gymnasium's own Pusher-v5 and Reacher-v5 model files with their observations and rewards.

A :class:`SimEnv` is a scene plus a :class:`Task` (observation, reward, termination, the
``info`` a training loop logs, and an optional hook that randomizes the initial state from the
seed). ``reset(seed)`` restores a snapshot of the initial state instead of rebuilding; actions
are actuator controls within the actuators' control ranges. Rendering is headless, as
Gymnasium's MuJoCo envs do it: ``rgb_array`` and ``depth_array`` (metres), from a camera of the
scene (``camera_name``/``camera_id``) or a free camera that shows the whole scene.
"""

from typing import Optional

import gymnasium as gym
from gymnasium import spaces
import mujoco
import numpy as np

from . import autoload as gym_autoload
from .tasks import (Batch, PushBoxTask, PusherTask, ReacherTask, ReachTask,  # noqa: F401
                    scene_path, Task)  # the tasks, importable from here as before
from ..core.base.checks import MAX_ABS_VALUE as MAX_CONTROL
from ..core.cameras import View
from ..core.world import World

#: The render modes, as Gymnasium's MuJoCo envs name them ('human' needs a window: refused).
RENDER_MODES = ('rgb_array', 'depth_array')
ERR_HUMAN = ("render_mode 'human' opens a window, and sim environments render headless: use "
             "render_mode='rgb_array' (gymnasium.wrappers.RecordVideo writes videos of it) or "
             "'depth_array', or watch the node in RViz")
ERR_RENDER_MODE = 'render_mode must be None, {modes}; got {mode!r}'


class SimEnv(gym.Env):
    """
    A Gymnasium environment: a :class:`World` built from the task's scene.

    :param render_mode: None, 'rgb_array' ((height, width, 3) uint8) or 'depth_array'
        ((height, width) float32 metres along the camera's axis, +inf where nothing is hit).
        The OpenGL backend starts here, so a machine that cannot render says so now.
    :param camera_name: a camera of the scene; `camera_id` its index; neither: a free camera
        that shows the whole scene.
    """

    metadata = {'render_modes': list(RENDER_MODES), 'render_fps': 30}

    def __init__(self, task: Task, render_mode: Optional[str] = None, width: int = 480,
                 height: int = 480, camera_name: Optional[str] = None,
                 camera_id: Optional[int] = None):
        if render_mode == 'human':
            raise ValueError(ERR_HUMAN)
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(ERR_RENDER_MODE.format(modes=', '.join(map(repr, RENDER_MODES)),
                                                    mode=render_mode))
        if camera_name is not None and camera_id is not None:
            raise ValueError('give camera_name or camera_id, not both')
        self.task = task
        self.render_mode = render_mode
        self.world = World.from_file(scene_path(task.scene))
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
        timestep = self.world.timestep
        self.metadata = dict(self.metadata,
                             render_fps=max(1, round(1.0 / (timestep * task.frame_skip))))
        self._view: Optional[View] = None
        if render_mode is not None:
            self._view = View(self.world, _camera(self.world, camera_name, camera_id),
                              width, height)

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        self.world.set_state(self._initial)
        with self.world.locked() as (m, d):
            self.task.randomize(m, d, self.np_random)
            mujoco.mj_forward(m, d)
            obs, info = self.task.observation(m, d), self.task.info(m, d)
        return obs, info

    def render(self):
        """Return the current frame (see `render_mode`); None without a render mode."""
        if self._view is None:
            return None
        return self._view.render(depth=self.render_mode == 'depth_array')

    def close(self):
        if self._view is not None:
            self._view.close()
            self._view = None
        super().close()

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
        obs, reward, terminated, info = self.outcome_row(m, d)
        return obs, reward, terminated, False, info

    def outcome_row(self, m: mujoco.MjModel, d: mujoco.MjData) -> tuple:
        """Return (observation, reward, terminated, info): a step's outcome before time limits."""
        return self.task.outcome(m, d)


def _camera(world: World, name: Optional[str], index: Optional[int]) -> str:
    """Return the camera to render from: a name, the name of camera `index`, or '' (free)."""
    if index is None:
        return name or ''
    with world.locked() as (m, _):
        if not 0 <= index < m.ncam:
            raise ValueError(f'camera_id {index} is not a camera of the scene '
                             f'(it has {m.ncam})')
        found = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_CAMERA, index)
    if not found:
        raise ValueError(f'camera {index} has no name; give the camera a name in the scene')
    return found


TASKS = {'sim/PushBox-v0': PushBoxTask, 'sim/Reach-v0': ReachTask,
         'sim/Pusher-v0': PusherTask, 'sim/Reacher-v0': ReacherTask}


def make_push_box(**kwargs) -> SimEnv:
    return SimEnv(PushBoxTask(), **kwargs)


def make_reach(**kwargs) -> SimEnv:
    return SimEnv(ReachTask(), **kwargs)


def make_pusher(**kwargs) -> SimEnv:
    return SimEnv(PusherTask(), **kwargs)


def make_reacher(**kwargs) -> SimEnv:
    return SimEnv(ReacherTask(), **kwargs)


def register_envs() -> None:
    """Register the sim/ ids (idempotent), each with a vector entry point (:mod:`.vector`)."""
    gym_autoload.register_ids(gym.envs.registration)


register_envs()
