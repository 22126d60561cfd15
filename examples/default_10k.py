"""
The default scene on its stepping thread, as fast as possible.

With a max-steps constraint of 10,000 steps: the loop stops by itself and says why.
"""

from pathlib import Path
import sys
import threading
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
    paused = threading.Event()  # told by the session, not asked in a loop
    session.add_listener(on_state=lambda event: event.cause == 'limit' and paused.set())
    session.load(world, 'default')
    paused.wait()
    wall = time.perf_counter() - t0
    reason = session.state_event().reason
    if window is not None:
        window.close()
    session.close()
    print(f'stopped after {world.step_count} steps (t = {world.time:.2f} s) in {wall:.2f} s '
          f'wall: {reason}')
    return {'steps': world.step_count, 'time': world.time, 'reason': reason}


if __name__ == '__main__':
    main()
