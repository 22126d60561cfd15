"""
How long each kind of edit holds the world lock while the world runs.

The stepping loop waits that long, so time stalls that long. ``make bench-edits`` (about
30 s): a world of 100 free boxes steps in real time on its own loop (as in the node) while one
thread makes each kind of edit 30 times. Every hold of the world lock by the editing thread is
timed (outermost acquisitions; an edit may take the lock more than once, and its longest hold
is what the loop feels). Printed per kind: median, p99 and maximum of that longest hold.
Target (issue 21): p99 <= 5 ms for every kind at 100 bodies.
"""

from pathlib import Path
import statistics
import sys
import threading
import time

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from sim_node.core import sources  # noqa: E402
from sim_node.core.loop import SimLoop  # noqa: E402
from sim_node.core.stepping.lock import WorldLock  # noqa: E402, I100
from sim_node.core.world import World  # noqa: E402
sys.path.insert(0, str(Path(__file__).resolve().parent))
from box_scene import box_scene  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402

REPEATS = 30
TARGET_MS = 5.0


class HoldTimer:
    """Times the outermost holds of WorldLock by one thread (patched in for this run)."""

    def __init__(self):
        self.thread = None
        self.holds: list = []
        self._depth = 0
        self._t0 = 0.0
        enter, exit_ = WorldLock.__enter__, WorldLock.__exit__
        timer = self

        def timed_enter(lock):
            enter(lock)
            if threading.get_ident() == timer.thread:
                if timer._depth == 0:
                    timer._t0 = time.perf_counter()
                timer._depth += 1

        def timed_exit(lock, *exc):
            if threading.get_ident() == timer.thread:
                timer._depth -= 1
                if timer._depth == 0:
                    timer.holds.append(time.perf_counter() - timer._t0)
            return exit_(lock, *exc)
        WorldLock.__enter__, WorldLock.__exit__ = timed_enter, timed_exit

    def longest(self, edit) -> float:
        """Run `edit()`; return its longest hold of the world lock (ms)."""
        self.thread, self.holds, self._depth = threading.get_ident(), [], 0
        edit()
        self.thread = None
        return 1e3 * max(self.holds, default=0.0)


def main() -> None:
    world = World.from_string(box_scene(100))
    loop = SimLoop(world)
    loop.set_real_time_factor(1.0)
    loop.start()
    loop.run()
    timer = HoldTimer()
    box = sources.primitive('box', [0.05, 0.05, 0.05])
    counter = iter(range(10 ** 6))

    def spawned() -> str:
        name = f'extra_{next(counter)}'
        world.spawn(name, box, (3.0, 3.0 + 0.2 * (len(world.spawned_names()) % 20), 0.3))
        return name

    keep = [spawned() for _ in range(5)]  # for reset: spawned entities are removed by it
    kinds = {
        'spawn a box': lambda: spawned(),
        'delete a box': None,  # below: each deletes one spawned just before
        'reset (with spawned boxes)': lambda: world.reset(),
        'set_mass': lambda: world.set_mass('box_7', 0.2),
        'set_mass 0 (weld)': None,  # below: weld, then unweld
        'set_friction': lambda: world.set_friction('box_8', 0.6),
        'set_restitution': lambda: world.set_restitution('box_9', 0.5),
        'set_entity_state': lambda: world.set_entity_state('box_10', position=(0.1, 0.1, 1.0)),
        'set_default_contact': lambda: world.set_default_contact(friction=(0.9, 0.005, 0.0001)),
    }
    results = {}
    for kind, edit in kinds.items():
        longest = []
        for _ in range(REPEATS):
            if kind == 'delete a box':
                name = spawned()
                longest.append(timer.longest(lambda: world.delete(name)))
            elif kind == 'set_mass 0 (weld)':
                longest.append(timer.longest(lambda: world.set_mass('box_11', 0.0)))
                world.set_mass('box_11', 0.1)
            elif kind.startswith('reset'):
                for _ in range(3):
                    spawned()
                longest.append(timer.longest(edit))
            else:
                longest.append(timer.longest(edit))
            time.sleep(0.002)
        results[kind] = longest
    loop.stop()
    del keep
    print(f'[edits] longest hold of the world lock per edit, ms, {REPEATS} of each, a world of '
          '100 free boxes stepping in real time')
    print(f'  {"edit":28s}{"median":>9}{"p99":>9}{"max":>9}')
    worst = 0.0
    for kind, ms in results.items():
        p99 = float(np.percentile(ms, 99))
        worst = max(worst, p99)
        print(f'  {kind:28s}{statistics.median(ms):9.2f}{p99:9.2f}{max(ms):9.2f}')
    verdict(worst <= TARGET_MS, f'every edit kind holds the world lock p99 <= {TARGET_MS:g} ms '
            f'at 100 bodies: worst p99 {worst:.2f} ms')
    summary()


if __name__ == '__main__':
    main()
