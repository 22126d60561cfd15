"""
The default scene on its stepping thread, as fast as possible.

With a max-steps constraint of 10,000 steps: the loop stops by itself and says why.
"""

from pathlib import Path
import sys
import time

from sim_node.core.config import WorldConfig
from sim_node.core.loop import SimLoop
from sim_node.core.world import World

VIEW = '--view' in sys.argv  # MuJoCo's viewer on the world, in real time (a display)

SCENE = Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml'


def main() -> dict:
    world = World.from_file(str(SCENE), WorldConfig(real_time_factor=0, max_steps=10_000))
    loop = SimLoop(world, viewer=VIEW)
    t0 = time.perf_counter()
    loop.start()
    while not loop.paused:
        time.sleep(0.01)
    wall = time.perf_counter() - t0
    status = loop.status()
    loop.stop()
    print(f'stopped after {world.step_count} steps (t = {world.time:.2f} s) in {wall:.2f} s '
          f'wall: {status.stop_reason}')
    return {'steps': world.step_count, 'time': world.time, 'reason': status.stop_reason}


if __name__ == '__main__':
    main()
