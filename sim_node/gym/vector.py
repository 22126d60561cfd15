"""
Many worlds stepped at once, from one process: Gymnasium's ``make_vec`` for the sim/ ids.

    import gymnasium, sim_node.gym.env
    envs = gymnasium.make_vec('sim/Pusher-v0', num_envs=8)      # a SimVectorEnv
    obs, info = envs.reset(seed=0)                              # env i is seeded with 0 + i
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())

A :class:`SimVectorEnv` holds N :class:`~sim_node.gym.env.SimEnv` (each its own world) and steps
them on a few threads (one per core by default). MuJoCo's ``mj_step`` releases the GIL, so the
physics of different worlds runs on all cores at once while Python computes observations. Each
sub-env does exactly what a SimEnv does, so N of them give the same observations, rewards and
infos as N separate envs seeded ``seed + i`` (``test_gym_vector.py`` checks this against
Gymnasium's SyncVectorEnv).

Autoreset follows Gymnasium's modes: NEXT_STEP (its default: the step after an episode ends
resets that env and returns its first observation with reward 0) or SAME_STEP (the env resets
in the step that ended it; ``info['final_obs']`` and ``info['final_info']`` hold what ended).
Episodes are cut at ``max_episode_steps`` (``truncated``), as ``gymnasium.make`` does with its
TimeLimit wrapper. If a world's physics diverges, ``step`` raises the
:class:`~sim_node.core.errors.DivergenceError` once every world has stepped (``env_index`` names
the world, left at the state before its bad step, as a single env leaves it); ``reset()`` to go
on.
"""

from functools import partial
import os
import threading
from typing import Callable, Optional, Sequence, Union

import gymnasium as gym
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space
import numpy as np

from . import env as gym_env, tasks
from .env import SimEnv
from .tasks import Batch, Task
from ..core.base.checks import MAX_ABS_VALUE as MAX_CONTROL
from ..core.base.errors import DivergenceError

ERR_AUTORESET = 'autoreset_mode must be NEXT_STEP or SAME_STEP, got {mode!r}'


class _Workers:
    """
    A fixed set of threads that run one job over all of them and wait for each other.

    The calling thread is worker 0, so N threads cost N - 1 extra ones. Each other worker waits
    on a lock of its own (the cheapest wake-up Python has: a Barrier costs several times more
    per step). Errors raised by a job are raised again by :meth:`run` (the first one, after
    every worker has finished).
    """

    def __init__(self, count: int):
        self.count = count
        self._go = [threading.Lock() for _ in range(count)]
        self._done = [threading.Lock() for _ in range(count)]
        for lock in self._go + self._done:
            lock.acquire()
        self._job: Optional[Callable[[int], None]] = None
        self._errors: list = []
        self._closing = False
        self._threads = [threading.Thread(target=self._serve, args=(k,), daemon=True,
                                          name=f'sim-vector-{k}') for k in range(1, count)]
        for t in self._threads:
            t.start()

    def _do(self, k: int) -> None:
        try:
            self._job(k)
        except BaseException as exc:  # handed to the caller of run()
            self._errors.append(exc)

    def _serve(self, k: int) -> None:
        while True:
            self._go[k].acquire()
            if self._closing:
                return
            self._do(k)
            self._done[k].release()

    def run(self, job: Callable[[int], None]) -> None:
        """Call ``job(k)`` for k = 0 .. count - 1, each on its own thread; wait for all."""
        if self.count == 1:
            job(0)
            return
        self._job, self._errors = job, []
        for k in range(1, self.count):
            self._go[k].release()
        self._do(0)
        for k in range(1, self.count):
            self._done[k].acquire()
        self._job = None
        if self._errors:
            raise self._errors[0]

    def close(self) -> None:
        self._closing = True
        for k in range(1, self.count):
            self._go[k].release()
        for t in self._threads:
            t.join(1.0)


class SimVectorEnv(gym.vector.VectorEnv):
    """
    N sub-envs of one task, stepped together on `num_threads` threads.

    :param task_factory: makes one :class:`~sim_node.gym.env.Task` per sub-env (tasks keep
        per-episode state such as a goal, so each env has its own).
    :param max_episode_steps: episode length (``truncated``); None: no limit.
    :param num_threads: threads that step the worlds (default: the cores, at most N).
    :param env_kwargs: passed to every :class:`~sim_node.gym.env.SimEnv` (``render_mode``,
        ``width``, ``height``, ``camera_name``, ``camera_id``).
    """

    metadata = {'autoreset_mode': AutoresetMode.NEXT_STEP,
                'render_modes': list(gym_env.RENDER_MODES)}

    def __init__(self, task_factory: Callable[[], Task], num_envs: int,
                 max_episode_steps: Optional[int] = None,
                 autoreset_mode: Union[AutoresetMode, str] = AutoresetMode.NEXT_STEP,
                 num_threads: Optional[int] = None, **env_kwargs):
        if int(num_envs) < 1:
            raise ValueError(f'num_envs must be >= 1, got {num_envs}')
        mode = AutoresetMode(autoreset_mode) if isinstance(autoreset_mode, str) \
            else autoreset_mode
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(ERR_AUTORESET.format(mode=autoreset_mode))
        if max_episode_steps is not None and int(max_episode_steps) < 1:
            raise ValueError(f'max_episode_steps must be >= 1, got {max_episode_steps}')
        self.num_envs = int(num_envs)
        self.envs = [SimEnv(task_factory(), **env_kwargs) for _ in range(self.num_envs)]
        first = self.envs[0]
        self.render_mode = first.render_mode
        self.metadata = dict(self.metadata, autoreset_mode=mode,
                             render_fps=first.metadata['render_fps'])
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(first.observation_space, self.num_envs)
        self.action_space = batch_space(first.action_space, self.num_envs)
        self._max_steps = None if max_episode_steps is None else int(max_episode_steps)
        self._frame_skip = first.task.frame_skip
        self._mode = mode
        n = self.num_envs
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._needs_reset = np.zeros(n, dtype=bool)
        self._actions = np.zeros((n,) + first.action_space.shape)
        self._results: list = [None] * n
        threads = num_threads or os.cpu_count() or 1
        if int(threads) < 1:
            raise ValueError(f'num_threads must be >= 1, got {num_threads}')
        self._workers = _Workers(min(int(threads), n))
        # Worker k steps the contiguous slice of envs k (the same slice every time).
        bounds = np.linspace(0, n, self._workers.count + 1).astype(int)
        self._slices = [range(bounds[k], bounds[k + 1]) for k in range(self._workers.count)]
        self._reset_args: list = [None] * n
        self._first: list = [None] * n  # (obs, info) of envs reset in this step
        self._tasks = [env.task for env in self.envs]
        self._task = first.task
        self._batch: Optional[Batch] = None
        if self._task.batched:
            with first.world.locked() as (m, _):
                self._batch = Batch(m, n)

    # ---------------------------------------------------------------- the Gymnasium API

    def reset(self, *, seed: Union[int, Sequence[Optional[int]], None] = None,
              options: Optional[dict] = None):
        """
        Reset every env; `seed` an int (env i gets seed + i), a list of N seeds, or None.

        Returns (observations (N, ...), infos in Gymnasium's vector form).
        """
        n = self.num_envs
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f'give {n} seeds, one per env; got {len(seeds)}')
        self._reset_args = [(s, options) for s in seeds]
        self._workers.run(self._reset_slice)
        self._elapsed[:] = 0
        self._needs_reset[:] = False
        obs = np.stack([r[0] for r in self._results])
        return obs, self._vector_info([r[1] for r in self._results])

    def step(self, actions):
        """Step every env with its row of `actions` (N, ...); see the module for autoreset."""
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != self._actions.shape:
            raise ValueError(f'actions must have shape {self._actions.shape}, '
                             f'got {actions.shape}')
        if not (np.abs(actions) <= MAX_CONTROL).all():
            raise ValueError(f'actions must be finite and within +-{MAX_CONTROL:g}')
        self._actions = actions
        # Rows whose step is a reset (NEXT_STEP, after an episode ended): their action is unused.
        resets = self._needs_reset.copy()
        self._workers.run(self._step_slice)
        if self._batch is not None:
            obs, rewards, terminated, infos = self._task.batch_outcome(self._tasks, self._batch)
            rewards = np.array(rewards, dtype=np.float64)
            terminated = np.array(terminated, dtype=bool)
            infos = _masked(infos, self.num_envs)
        else:
            res = self._results
            obs = np.stack([r[0] for r in res])
            rewards = np.array([r[1] for r in res], dtype=np.float64)
            terminated = np.array([r[2] for r in res], dtype=bool)
            infos = self._vector_info([r[3] for r in res])
        self._elapsed[~resets] += 1
        truncated = np.zeros(self.num_envs, dtype=bool) if self._max_steps is None \
            else self._elapsed >= self._max_steps
        for i in np.flatnonzero(resets):  # their first observation, as reset gave it
            obs[i], rewards[i], terminated[i], truncated[i] = self._first[i][0], 0.0, False, False
            self._elapsed[i] = 0
            infos = self._add_info(infos, self._first[i][1], int(i))
        ended = terminated | truncated
        if self._mode == AutoresetMode.SAME_STEP:
            keys = [k for k in infos if not k.startswith('_')]
            for i in np.flatnonzero(ended):  # reset now; what ended goes in final_obs/final_info
                i = int(i)
                final_info = {k: infos[k][i].item() if isinstance(infos[k][i], np.generic)
                              else infos[k][i] for k in keys}
                infos = self._add_info(infos, {'final_obs': obs[i].copy(),
                                               'final_info': final_info}, i)
                obs[i], first_info = self.envs[i].reset()
                infos = self._add_info(infos, first_info, i)
                self._elapsed[i] = 0
        else:
            self._needs_reset = ended
        return obs, rewards, terminated, truncated, infos

    def render(self):
        """Return one frame per env (a tuple), as Gymnasium's SyncVectorEnv does."""
        if self.render_mode is None:
            return None
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs):
        self._workers.close()
        for env in self.envs:
            env.close()

    # ---------------------------------------------------------------- per worker

    def _reset_slice(self, k: int) -> None:
        for i in self._slices[k]:
            seed, options = self._reset_args[i]
            self._results[i] = self.envs[i].reset(seed=seed, options=options)

    def _step_slice(self, k: int) -> None:
        envs, actions, skip, batch = self.envs, self._actions, self._frame_skip, self._batch
        for i in self._slices[k]:
            env = envs[i]
            if self._needs_reset[i]:  # NEXT_STEP: this step resets the env
                self._first[i] = first, info = env.reset()
                if batch is not None:
                    env.world.read(partial(batch.gather, i))
                else:
                    self._results[i] = (first, 0.0, False, info)
                continue
            try:
                if batch is not None:  # the task computes all envs at once afterwards
                    env.world.step(skip, ctrl=actions[i], then=partial(batch.gather, i))
                else:
                    env.world.step(skip, ctrl=actions[i])
                    self._results[i] = env.world.read(env.outcome_row)
            except DivergenceError as exc:
                exc.env_index = i
                exc.add_note(f'in world {i} of the vector env; reset() to go on')
                raise

    def _vector_info(self, infos: list) -> dict:
        """Gymnasium's vector form: each key an array over the envs, ``_key`` its mask."""
        keys = infos[0].keys() if infos else ()
        if all(info.keys() == keys for info in infos):  # the usual case: one array per key
            return _masked({key: [info[key] for info in infos] for key in keys}, len(infos))
        out: dict = {}
        for i, info in enumerate(infos):
            out = self._add_info(out, info, i)
        return out


def _masked(infos: dict, n: int) -> dict:
    """Give a dict of N values per key (arrays or lists) the masks of the vector form."""
    out = {}
    for key, value in infos.items():
        out[key] = np.array(value)  # a copy: a task may hand out one array twice
        out['_' + key] = np.ones(n, dtype=bool)
    return out


def _maker(task: type) -> Callable[..., SimVectorEnv]:
    def make(num_envs: int = 1, **kwargs) -> SimVectorEnv:
        return SimVectorEnv(task, num_envs, **kwargs)
    make.__doc__ = f'Return a SimVectorEnv of {task.__name__} (gymnasium.make_vec calls it).'
    return make


make_push_box = _maker(tasks.PushBoxTask)
make_reach = _maker(tasks.ReachTask)
make_pusher = _maker(tasks.PusherTask)
make_reacher = _maker(tasks.ReacherTask)
