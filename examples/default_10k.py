"""
The default scene on its stepping thread, as fast as possible.

With a max-steps constraint of 10,000 steps: the loop stops by itself and says why.
"""

from pathlib import Path
import sys
import time

from sim_node.core.config import WorldConfig
from sim_node.core.world import World
from sim_node.session import Session

VIEW = '--view' in sys.argv  # MuJoCo's viewer on the world, in real time (a display)

SCENE = Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml'


def main() -> dict:
    world = World.from_file(str(SCENE), WorldConfig(real_time_factor=0, max_steps=10_000))
    session = Session()
    window = None
    if VIEW:
        from sim_node.view.window import Window
        window = Window(session)
    t0 = time.perf_counter()
    loop = session.load(world, 'default').loop
    while not loop.paused:
        time.sleep(0.01)
    wall = time.perf_counter() - t0
    status = loop.status()
    if window is not None:
        window.close()
    session.close()
    print(f'stopped after {world.step_count} steps (t = {world.time:.2f} s) in {wall:.2f} s '
          f'wall: {status.stop_reason}')
    return {'steps': world.step_count, 'time': world.time, 'reason': status.stop_reason}


if __name__ == '__main__':
    main()
