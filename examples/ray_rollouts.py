"""
Roll out many sim worlds on a Ray cluster: each Ray actor holds a vector env of N worlds.

    python examples/ray_rollouts.py                       # a local Ray cluster, 2 workers
    python examples/ray_rollouts.py --address auto --workers 16 --envs 8   # an existing one

A worker is a Ray actor that makes ``gymnasium.make_vec(env_id, num_envs)`` (our
SimVectorEnv, stepping its worlds on the cores Ray gives it), plays a policy for a number of
steps and reports episode returns and successes. The driver here sends every worker the same
linear policy and gathers what they report, which is the shape of a training loop's collection
phase (RLlib's env runners do the same with their own policy).

On a cluster: ``ray start --head`` on one machine, ``ray start --address HEAD:6379`` on the
others, each with this package installed (``pip install`` of this checkout, or ``colcon build``
and the workspace sourced), then ``--address auto`` here. Each worker asks Ray for
``--cpus-per-worker`` cores and its vector env uses that many threads.
"""

import argparse
import os
import sys
import time

import numpy as np

# Run from a checkout without installing: the workers import sim_node from here as well.
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def make_worker(ray):
    """Return the Ray actor class (defined once Ray is imported)."""

    @ray.remote
    class RolloutWorker:
        """A vector env of `num_envs` worlds, stepped by one policy at a time."""

        def __init__(self, env_id: str, num_envs: int, threads: int, seed: int):
            sys.path.insert(0, ROOT)
            import gymnasium as gym
            import sim_node.gym.env  # noqa: F401  (registers the sim/ ids)
            self.envs = gym.make_vec(env_id, num_envs=num_envs, num_threads=threads)
            self.obs, _ = self.envs.reset(seed=seed)
            self.returns = np.zeros(num_envs)

        def rollout(self, weights: np.ndarray, steps: int) -> dict:
            """Play ``action = clip(obs @ weights)`` for `steps` steps; report the episodes."""
            space = self.envs.single_action_space
            finished, successes = [], 0
            t0 = time.perf_counter()
            for _ in range(steps):
                actions = np.clip(self.obs @ weights, space.low, space.high)
                self.obs, reward, terminated, truncated, info = self.envs.step(actions)
                self.returns += reward
                for i in np.flatnonzero(terminated | truncated):
                    finished.append(float(self.returns[i]))
                    successes += bool(info['is_success'][i])
                    self.returns[i] = 0.0
            wall = time.perf_counter() - t0
            return {'episodes': finished, 'successes': successes,
                    'env_steps': steps * self.envs.num_envs, 'seconds': wall,
                    'pid': os.getpid()}

        def close(self) -> None:
            self.envs.close()

    return RolloutWorker


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--address', default=None,
                        help="a Ray cluster to join ('auto': the one started on this machine); "
                             'default: start a local one')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--envs', type=int, default=4, help='worlds per worker')
    parser.add_argument('--cpus-per-worker', type=int, default=1)
    parser.add_argument('--steps', type=int, default=250, help='vector steps per rollout')
    parser.add_argument('--rounds', type=int, default=2, help='rollouts per worker')
    parser.add_argument('--env', default='sim/Pusher-v0')
    args = parser.parse_args(argv)

    import ray
    local = args.address is None
    ray.init(address=args.address, include_dashboard=False, log_to_driver=False,
             **({'num_cpus': max(2, args.workers * args.cpus_per_worker)} if local else {}))
    try:
        worker = make_worker(ray).options(num_cpus=args.cpus_per_worker)
        workers = [worker.remote(args.env, args.envs, args.cpus_per_worker, seed=1000 * k)
                   for k in range(args.workers)]
        sizes = _sizes(args.env)
        rng = np.random.default_rng(0)
        results = []
        for _ in range(args.rounds):  # every worker plays the same policy in a round
            weights = ray.put(rng.normal(0.0, 0.1, size=sizes))
            results += ray.get([w.rollout.remote(weights, args.steps) for w in workers])
        ray.get([w.close.remote() for w in workers])
    finally:
        ray.shutdown()
    episodes = [r for res in results for r in res['episodes']]
    summary = {
        'workers': len({res['pid'] for res in results}),
        'episodes': len(episodes),
        'mean_return': float(np.mean(episodes)) if episodes else float('nan'),
        'successes': sum(res['successes'] for res in results),
        'env_steps': sum(res['env_steps'] for res in results),
        'env_steps_per_second': sum(res['env_steps'] / res['seconds'] for res in results)
        / args.rounds,
    }
    print(f"{summary['workers']} workers x {args.envs} worlds ({args.env}): "
          f"{summary['episodes']} episodes, mean return {summary['mean_return']:.2f}, "
          f"{summary['successes']} successes, {summary['env_steps']} env steps, "
          f"{summary['env_steps_per_second']:.0f} env steps/s in all")
    return summary


def _sizes(env_id: str) -> tuple:
    """Return (observation size, action size) of a task: a linear policy's weight shape."""
    sys.path.insert(0, ROOT)
    import gymnasium as gym
    import sim_node.gym.env  # noqa: F401
    env = gym.make(env_id)
    try:
        return env.observation_space.shape[0], env.action_space.shape[0]
    finally:
        env.close()


if __name__ == '__main__':
    main()
