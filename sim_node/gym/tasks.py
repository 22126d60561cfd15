"""
What a Gymnasium environment of ``sim`` learns: a :class:`Task` and the tasks it ships.

A task names its scene and says, from the model and data, the observation, the reward, the
termination, the ``info`` a training loop logs, and optionally how the initial state is
randomized from the seed; :meth:`Task.batch_outcome` says the same for N worlds at once from a
:class:`Batch` (the vector env). The tasks: PushBox and Reach on this project's scenes, Pusher
and Reacher on Gymnasium's own Pusher-v5 and Reacher-v5 model files, with their observations
and rewards. The environments over them are :mod:`.env` and :mod:`.vector`.
"""

import math
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np

from ..core.models import resources

#: Gymnasium's own MuJoCo model files (Pusher-v5, Reacher-v5), shipped in its package.
GYM_ASSETS = Path(gym.__file__).parent / 'envs' / 'mujoco' / 'assets'


def dist(a: np.ndarray, b: np.ndarray) -> float:
    """
    Return the distance between two points, summing the squares in order.

    Bit for bit what :func:`dists` gives for a row (NumPy's dot product may fuse and reorder
    its sums), so one env and a vector env of it report the same numbers.
    """
    total = 0.0
    for x in (a - b).tolist():
        total += x * x
    return math.sqrt(total)


def scene_path(name: str) -> str:
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

    def info(self, model: mujoco.MjModel, data: mujoco.MjData) -> dict:
        """Return what a training loop logs: ``is_success`` and the distances the reward uses."""
        return {}

    def outcome(self, model: mujoco.MjModel, data: mujoco.MjData) -> tuple:
        """
        Return (observation, reward, terminated, info) after a step.

        What the four methods give; a task may compute what they share once.
        """
        return (self.observation(model, data), float(self.reward(model, data)),
                bool(self.terminated(model, data)), self.info(model, data))

    #: Whether :meth:`batch_outcome` is written (the vector env then computes N envs at once).
    batched = False

    def batch_outcome(self, tasks: list, batch: 'Batch') -> tuple:
        """
        Compute the outcome of N envs at once (optional; for the vector env).

        The same numbers as :meth:`observation`, :meth:`reward`, :meth:`terminated` and
        :meth:`info` give env by env, computed over arrays whose first axis is the env.
        `tasks` are the N envs' tasks (for per-episode state such as a goal); `batch` holds their
        data. Set ``batched = True`` when writing it.

        :returns: (observations (N, ...), rewards (N,), terminated (N,) bool, info: a dict of
            (N,) arrays, with the keys :meth:`info` gives).
        """
        raise NotImplementedError


class Batch:
    """
    The data of N worlds of one model, stacked: the fields tasks read, first axis the env.

    ``qpos`` (N, nq), ``qvel`` (N, nv), ``ctrl`` (N, nu), ``xpos`` (N, nbody, 3) and
    ``site_xpos`` (N, nsite, 3), as MjData holds them after a step.
    """

    FIELDS = ('qpos', 'qvel', 'ctrl', 'xpos', 'site_xpos')

    def __init__(self, model: mujoco.MjModel, n: int):
        self.qpos = np.zeros((n, model.nq))
        self.qvel = np.zeros((n, model.nv))
        self.ctrl = np.zeros((n, model.nu))
        self.xpos = np.zeros((n, model.nbody, 3))
        self.site_xpos = np.zeros((n, model.nsite, 3))

    def gather(self, i: int, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Copy one world's fields into row `i` (``partial(batch.gather, i)`` for World.read)."""
        self.qpos[i] = data.qpos
        self.qvel[i] = data.qvel
        self.ctrl[i] = data.ctrl
        self.xpos[i] = data.xpos
        self.site_xpos[i] = data.site_xpos


def dists(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """
    Return the row-wise distances of two (N, k) arrays of points (see :func:`dist`).

    NumPy sums a row of fewer than 8 numbers in order, as :func:`dist` does.
    """
    d = a - b
    return np.sqrt((d * d).sum(axis=1))


class PushBoxTask(Task):
    """
    A finger on two slide joints pushes a box to a goal on the table.

    Dense reward on the box-goal distance (plus a small term for reaching the box). Success within
    3 cm.
    """

    scene = 'push_box.xml'
    frame_skip = 10
    SUCCESS = 0.03  # metres, box to goal

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

    @staticmethod
    def _reward(to_goal, tip_to_box):
        """Return the reward of one env or of N (arrays) from its two distances."""
        return -to_goal - 0.1 * tip_to_box

    def reward(self, model, data):
        box = data.xpos[self.box][:2]
        tip = data.xpos[self.pusher][:2]
        return self._reward(dist(box, self.goal_xy), dist(tip, box))

    def terminated(self, model, data):
        return dist(data.xpos[self.box][:2], self.goal_xy) < self.SUCCESS

    def info(self, model, data):
        box = data.xpos[self.box][:2]
        to_goal = dist(box, self.goal_xy)
        return {'is_success': to_goal < self.SUCCESS, 'box_to_goal': to_goal,
                'tip_to_box': dist(data.xpos[self.pusher][:2], box)}

    batched = True

    def batch_outcome(self, tasks, batch):
        goals = np.array([t.goal_xy for t in tasks])
        box, tip = batch.xpos[:, self.box, :2], batch.xpos[:, self.pusher, :2]
        obs = np.concatenate([batch.qpos[:, 0:2], batch.qvel[:, 0:2], box, batch.qvel[:, 2:4],
                              goals], axis=1)
        to_goal, to_box = dists(box, goals), dists(tip, box)
        success = to_goal < self.SUCCESS
        return obs, self._reward(to_goal, to_box), success, {
            'is_success': success, 'box_to_goal': to_goal, 'tip_to_box': to_box}


class ReachTask(Task):
    """The default scene's left arm brings its tip to a random reachable target."""

    scene = 'default.xml'
    frame_skip = 5
    SUCCESS = 0.02  # metres, tip to target
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
        return -dist(data.site_xpos[self.tip], self.target)

    def info(self, model, data):
        to_target = dist(data.site_xpos[self.tip], self.target)
        return {'is_success': to_target < self.SUCCESS, 'tip_to_target': to_target}

    batched = True

    def batch_outcome(self, tasks, batch):
        targets = np.array([t.target for t in tasks])
        tip = batch.site_xpos[:, self.tip]
        obs = np.concatenate([batch.qpos[:, :4], batch.qvel[:, :4], tip, targets], axis=1)
        to_target = dists(tip, targets)
        return obs, -to_target, np.zeros(len(tasks), dtype=bool), {
            'is_success': to_target < self.SUCCESS, 'tip_to_target': to_target}


class PusherTask(Task):
    """
    Gymnasium's Pusher-v5 as a Task: its model file, frame skip, observation and reward.

    A 7-joint arm pushes a cylinder to a goal. Success: the cylinder within 5 cm of the goal in
    the plane (Pusher-v5 itself never ends an episode; nor does this). ``object_to_goal`` and
    ``tips_to_object`` are the 3-D distances its reward is made of.
    """

    scene = str(GYM_ASSETS / 'pusher_v5.xml')
    frame_skip = 5
    SUCCESS = 0.05  # metres, object to goal

    def setup(self, model):
        self.tips, self.obj, self.goal = (model.body(n).id for n in ('tips_arm', 'object', 'goal'))

    def randomize(self, model, data, rng):
        while True:
            cylinder = np.concatenate([rng.uniform(-0.3, 0, 1), rng.uniform(-0.2, 0.2, 1)])
            if np.linalg.norm(cylinder) > 0.17:
                break
        data.qpos[-4:-2], data.qpos[-2:] = cylinder, 0
        data.qvel[:] = rng.uniform(-0.005, 0.005, size=model.nv)
        data.qvel[-4:] = 0

    def observation(self, model, data):
        x = data.xpos
        return np.concatenate([data.qpos[:7], data.qvel[:7], x[self.tips], x[self.obj],
                               x[self.goal]])

    @staticmethod
    def _reward(object_to_goal, tips_to_object, ctrl):
        """Return Pusher-v5's reward of one env or of N (arrays, one row of `ctrl` each)."""
        return -object_to_goal - np.square(ctrl).sum(axis=-1) * 0.1 + -tips_to_object * 0.5

    def reward(self, model, data):
        x = data.xpos
        return self._reward(dist(x[self.obj], x[self.goal]), dist(x[self.obj], x[self.tips]),
                            data.ctrl)

    def info(self, model, data):
        x = data.xpos
        to_goal = dist(x[self.obj], x[self.goal])
        return {'is_success': dist(x[self.obj][:2], x[self.goal][:2]) < self.SUCCESS,
                'object_to_goal': to_goal,
                'tips_to_object': dist(x[self.obj], x[self.tips])}

    def outcome(self, model, data):
        info = self.info(model, data)
        reward = self._reward(info['object_to_goal'], info['tips_to_object'], data.ctrl)
        return self.observation(model, data), float(reward), False, info

    batched = True

    def batch_outcome(self, tasks, batch):
        x = batch.xpos
        tips, obj, goal = x[:, self.tips], x[:, self.obj], x[:, self.goal]
        obs = np.concatenate([batch.qpos[:, :7], batch.qvel[:, :7], tips, obj, goal], axis=1)
        near, far = dists(obj, tips), dists(obj, goal)
        return obs, self._reward(far, near, batch.ctrl), np.zeros(len(tasks), dtype=bool), {
            'is_success': dists(obj[:, :2], goal[:, :2]) < self.SUCCESS, 'object_to_goal': far,
            'tips_to_object': near}


class ReacherTask(Task):
    """
    Gymnasium's Reacher-v5 as a Task: its model file, frame skip, observation and reward.

    A two-joint arm brings its fingertip to a target. Success: within 1 cm.
    """

    scene = str(GYM_ASSETS / 'reacher.xml')
    frame_skip = 2
    SUCCESS = 0.01  # metres, fingertip to target

    def setup(self, model):
        self.tip, self.target = model.body('fingertip').id, model.body('target').id

    def randomize(self, model, data, rng):
        data.qpos[:] += rng.uniform(-0.1, 0.1, size=model.nq)
        while True:
            goal = rng.uniform(-0.2, 0.2, size=2)
            if np.linalg.norm(goal) < 0.2:
                break
        data.qpos[-2:] = goal
        data.qvel[:] = rng.uniform(-0.005, 0.005, size=model.nv)
        data.qvel[-2:] = 0

    def observation(self, model, data):
        theta = data.qpos[:2]
        return np.concatenate([np.cos(theta), np.sin(theta), data.qpos[2:], data.qvel[:2],
                               (data.xpos[self.tip] - data.xpos[self.target])[:2]])

    @staticmethod
    def _reward(tip_to_target, ctrl):
        """Return Reacher-v5's reward of one env or of N (arrays, one row of `ctrl` each)."""
        return -tip_to_target - np.square(ctrl).sum(axis=-1)

    def reward(self, model, data):
        return self._reward(dist(data.xpos[self.tip], data.xpos[self.target]), data.ctrl)

    def info(self, model, data):
        to_target = dist(data.xpos[self.tip], data.xpos[self.target])
        return {'is_success': to_target < self.SUCCESS, 'tip_to_target': to_target}

    def outcome(self, model, data):
        info = self.info(model, data)
        reward = self._reward(info['tip_to_target'], data.ctrl)
        return self.observation(model, data), float(reward), False, info

    batched = True

    def batch_outcome(self, tasks, batch):
        theta = batch.qpos[:, :2]
        tip, target = batch.xpos[:, self.tip], batch.xpos[:, self.target]
        offset = tip - target
        obs = np.concatenate([np.cos(theta), np.sin(theta), batch.qpos[:, 2:],
                              batch.qvel[:, :2], offset[:, :2]], axis=1)
        to_target = dists(tip, target)
        return obs, self._reward(to_target, batch.ctrl), np.zeros(len(tasks), dtype=bool), {
            'is_success': to_target < self.SUCCESS, 'tip_to_target': to_target}


#: id -> Task class, the envs this module registers (names and lengths: :mod:`.autoload`).
