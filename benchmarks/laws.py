"""
What a controller's law costs the stepping side: a diff-drive rover's, ticking as it steps.

``make bench-laws`` (about ten seconds). The corpus rover (``test/controllers_corpus.py``: 10 kg
on two wheels, velocity interfaces) is spawned into the empty scene, its
diff_drive_controller's law (:mod:`sim_node.core.control.laws`) activated and driven, and the
world stepped 20,000 steps at a time, at its manager's ``update_rate`` of 100 Hz and of 1 kHz
(the timestep is 1 ms: at 1 kHz the law runs before every step). Printed side by side in one
run, best of three each: steps/s with the law ticking; with the joints sampled but no tick
(where the law ran until issue 51 moved it: the node's publisher thread, off the stepping
side); not sampled at all; and bare ``mj_step`` on a copy of the same model and data.

Verdict: at 100 Hz, the world with its law ticking keeps at least 0.5 of the speed it has
with the joints sampled and no law (the law's Python, about 30 microseconds an update, is now
the stepping side's to pay; it was the publisher thread's, which skipped updates faster than
real time).
"""

import copy
import os
from pathlib import Path
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'test'))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

import mujoco  # noqa: E402, I100
import test_core_laws as rover  # noqa: E402

STEPS = 20_000
VERDICT = 0.5


def best_rate(step) -> float:
    best = 0.0
    for _ in range(3):
        t0 = time.perf_counter()
        step()
        best = max(best, STEPS / (time.perf_counter() - t0))
    return best


def main() -> int:
    folder = Path(tempfile.mkdtemp())
    ratios = {}
    for hz in (100, 1000):
        yaml = rover.corpus.DIFF_DRIVE_YAML.replace('update_rate: 100', f'update_rate: {hz}')
        world, laws, law, _ = rover._robot(folder, rover.corpus.diff_drive, yaml,
                                           'diff_drive_base_controller')
        law.activate()
        law.take(0.3, 0.0)
        law.timeout = 0.0  # the twist holds for the whole run
        joints = [f'robot/{j}' for j in laws.index]
        ticking = best_rate(lambda: world.step(STEPS))
        world.sample_joints('robot', joints, float(hz))  # the same samples, no tick
        sampled = best_rate(lambda: world.step(STEPS))
        world.sample_joints('robot', [], 0.0)
        plain = best_rate(lambda: world.step(STEPS))
        model, data = world.read(lambda m, d: (copy.deepcopy(m), copy.deepcopy(d)))
        bare = best_rate(lambda: mujoco.mj_step(model, data, STEPS))
        ratios[hz] = ticking / sampled
        print(f'update_rate {hz:>4} Hz: law ticking {ticking:>9,.0f} steps/s, sampled without '
              f'a law {sampled:>9,.0f}, not sampled {plain:>9,.0f}, bare mj_step {bare:>9,.0f}; '
              f'ticking / sampled {ratios[hz]:.2f}, ticking / bare {ticking / bare:.2f}')
    met = ratios[100] >= VERDICT
    print(f'verdict: {"met" if met else "MISSED"} (at 100 Hz ticking / sampled '
          f'{ratios[100]:.2f} >= {VERDICT})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
