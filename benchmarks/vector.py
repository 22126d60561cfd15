"""
Many worlds at once: env steps per second of our vector env against the other ways to get them.

``make bench-vec`` (about 4 minutes; the first run also installs EnvPool, below). For N = 1, 2,
4, 8 and 16 worlds of one task, side by side in one run (interleaved rounds, median):

- ``SimVectorEnv``: ``gymnasium.make_vec('sim/Pusher-v0', num_envs=N)``, ours (threads);
- Gymnasium's ``SyncVectorEnv`` and ``AsyncVectorEnv`` (subprocesses) of the same sim/Pusher-v0;
- Gymnasium's own ``Pusher-v5``, vectorised both ways;
- EnvPool's ``Pusher-v5`` (a C++ thread pool). EnvPool is not a dependency of this project: the
  benchmark installs it once into ``.build/bench-envpool`` (its own venv, from the package index)
  and talks to it through a child process, so it never shares our interpreter or NumPy.

The task is the same everywhere: Gymnasium's ``pusher_v5.xml`` (EnvPool ships an identical copy
with a licence header): the same options, printed from each model file, and frame skip 5.
Differences: Gymnasium's and EnvPool's Pusher-v5 also run
``mj_rnePostConstraint`` after each step (for contact forces no Pusher observation uses); ours do
not. EnvPool runs its own build of MuJoCo (C++), ours the ``mujoco`` package's.
Every env gets the same stream of uniform random actions within the control range.
"""

import json
import os
from pathlib import Path
import statistics
import subprocess
import sys
import time

import gymnasium as gym
import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
import sim_node.gym.env  # noqa: E402, F401  (registers the sim/ ids)
sys.path.insert(0, str(Path(__file__).resolve().parent))
from verdict import summary, verdict  # noqa: E402, I100

ENVPOOL_VERSION = '1.2.5'
ENVPOOL_VENV = ROOT / '.build' / 'bench-envpool'
SIZES = (1, 2, 4, 8, 16)
ROUNDS = 3
SECONDS = 0.6  # per measurement
PUSHER_XML = Path(gym.__file__).parent / 'envs' / 'mujoco' / 'assets' / 'pusher_v5.xml'

# The child process that runs EnvPool: 'make N' builds a pool, 'run S' steps it for S seconds
# and answers env steps per second, 'xml' answers its model file.
ENVPOOL_CHILD = """
import sys, time, numpy as np, envpool, envpool_assets, os
env, actions = None, None
for line in sys.stdin:
    cmd, *args = line.split()
    if cmd == 'xml':
        print(os.path.join(os.path.dirname(envpool_assets.__file__), 'mujoco', 'assets_gym',
                           'pusher_v5_envpool.xml'), flush=True)
    elif cmd == 'make':
        n = int(args[0])
        if env is not None:
            env.close()
        env = envpool.make_gymnasium('Pusher-v5', num_envs=n, batch_size=n, seed=0)
        env.reset()
        actions = np.random.default_rng(0).uniform(-2, 2, size=(64, n, 7)).astype(np.float32)
        for a in actions:
            env.step(a)
        print('ok', flush=True)
    elif cmd == 'run':
        k, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < float(args[0]):
            env.step(actions[k % 64])
            k += 1
        print(k * actions.shape[1] / (time.perf_counter() - t0), flush=True)
"""


def ensure_envpool() -> str:
    """Return the python of the EnvPool venv, installing it the first time ('' if that fails)."""
    python = ENVPOOL_VENV / 'bin' / 'python'
    stamp = ENVPOOL_VENV / f'.envpool-{ENVPOOL_VERSION}'
    if stamp.exists():
        return str(python)
    print(f'[bench-vec] installing EnvPool {ENVPOOL_VERSION} into {ENVPOOL_VENV.relative_to(ROOT)}'
          ' (once; about a minute: 53 MB wheel and its assets) ...', flush=True)
    try:
        subprocess.run([sys.executable, '-m', 'venv', str(ENVPOOL_VENV)], check=True)
        subprocess.run([str(python), '-m', 'pip', 'install', '-q', '--disable-pip-version-check',
                        f'envpool=={ENVPOOL_VERSION}'], check=True, timeout=900)
    except (subprocess.SubprocessError, OSError) as exc:
        print(f'[bench-vec] EnvPool could not be installed ({exc}); its column stays empty. '
              f'Delete {ENVPOOL_VENV} and run again to retry.', flush=True)
        return ''
    stamp.touch()
    return str(python)


class EnvPoolChild:
    """EnvPool in its own venv, driven over a pipe."""

    def __init__(self, python: str):
        self.proc = subprocess.Popen([python, '-c', ENVPOOL_CHILD], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True)

    def ask(self, line: str) -> str:
        self.proc.stdin.write(line + '\n')
        self.proc.stdin.flush()
        answer = self.proc.stdout.readline().strip()
        if not answer:
            raise RuntimeError(f'the EnvPool child stopped answering ({line!r})')
        return answer

    def close(self):
        self.proc.stdin.close()
        self.proc.wait(10)


def measure(envs, actions: np.ndarray, seconds: float) -> float:
    """Step `envs` for `seconds`; return env steps per second."""
    k, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        envs.step(actions[k % len(actions)])
        k += 1
    return k * actions.shape[1] / (time.perf_counter() - t0)


def options(path) -> str:
    m = mujoco.MjModel.from_xml_path(str(path))
    o = m.opt
    return (f'timestep {o.timestep:g} s, {mujoco.mjtIntegrator(o.integrator).name[6:]}, '
            f'{mujoco.mjtSolver(o.solver).name[6:]} {o.iterations} iterations, '
            f'{m.nbody} bodies, {m.nv} dofs')


def main() -> None:
    python = ensure_envpool()
    pool = EnvPoolChild(python) if python else None
    print(f'[bench-vec] env steps per second, N worlds of one task, median of {ROUNDS} '
          f'interleaved rounds of {SECONDS} s; {os.cpu_count()} cores')
    print(f'  sim/Pusher-v0 and Gymnasium Pusher-v5: {PUSHER_XML.name}: {options(PUSHER_XML)}, '
          'frame skip 5')
    if pool is not None:
        xml = pool.ask('xml')
        print(f'  EnvPool Pusher-v5: {Path(xml).name}: {options(xml)}, frame skip 5')
    makers = {
        'SimVectorEnv': lambda n: gym.make_vec('sim/Pusher-v0', num_envs=n),
        'Sync(sim)': lambda n: gym.make_vec('sim/Pusher-v0', num_envs=n,
                                            vectorization_mode='sync'),
        'Async(sim)': lambda n: gym.make_vec('sim/Pusher-v0', num_envs=n,
                                             vectorization_mode='async'),
        'Sync(v5)': lambda n: gym.make_vec('Pusher-v5', num_envs=n, vectorization_mode='sync'),
        'Async(v5)': lambda n: gym.make_vec('Pusher-v5', num_envs=n,
                                            vectorization_mode='async'),
    }
    names = list(makers) + (['EnvPool'] if pool else [])
    print('  ' + f'{"N":>3}' + ''.join(f'{name:>14}' for name in names)
          + f'{"ours/EnvPool":>14}{"ours/Async":>12}')
    ratios = {}
    for n in SIZES:
        envs = {name: make(n) for name, make in makers.items()}
        actions = np.random.default_rng(0).uniform(-2, 2, size=(64, n, 7)).astype(np.float32)
        for e in envs.values():
            e.reset(seed=0)
            for a in actions[:8]:
                e.step(a)
        if pool is not None:
            pool.ask(f'make {n}')
        rates: dict = {name: [] for name in names}
        for _ in range(ROUNDS):
            for name, e in envs.items():
                rates[name].append(measure(e, actions, SECONDS))
            if pool is not None:
                rates['EnvPool'].append(float(pool.ask(f'run {SECONDS}')))
        for e in envs.values():
            e.close()
        med = {name: statistics.median(r) for name, r in rates.items()}
        ours = med['SimVectorEnv']
        vs_pool = ours / med['EnvPool'] if pool else float('nan')
        vs_async = ours / med['Async(sim)']
        ratios[n] = (vs_pool, vs_async)
        print('  ' + f'{n:>3}' + ''.join(f'{med[name]:>14.0f}' for name in names)
              + f'{vs_pool:>14.2f}{vs_async:>12.2f}', flush=True)
    if pool is not None:
        pool.close()
    big = [n for n in SIZES if n >= 4]
    worst_pool = min(ratios[n][0] for n in big)
    worst_async = min(ratios[n][1] for n in big)
    if pool is not None:
        verdict(worst_pool >= 1.0, f'SimVectorEnv / EnvPool Pusher-v5 env steps per second at '
                f'N >= 4, worst {worst_pool:.2f} (target >= 1.0)')
    verdict(worst_async >= 1.5, f'SimVectorEnv / AsyncVectorEnv of sim/Pusher-v0 at N >= 4, '
            f'worst {worst_async:.2f} (target >= 1.5)')
    summary()
    print(json.dumps({'ratios': {str(n): r for n, r in ratios.items()}}))


if __name__ == '__main__':
    os.environ.setdefault('MUJOCO_GL', 'disable')
    main()
