"""
A world built in code while it runs.

A fixed robot base, then a revolute arm on it, then a free box; the arm's joint is commanded in a
loop.
"""

import math
import sys
import time

from sim_node.core.config import WorldConfig
from sim_node.session import Session
from sim_node.simulation import Simulation

VIEW = '--view' in sys.argv  # MuJoCo's viewer on the world, in real time (a display)


def main() -> dict:
    sim = Simulation.empty(real_time_factor=4.0)
    session = Session()
    session.load(sim.world, config=WorldConfig(real_time_factor=4.0))  # running from here on
    window = None
    if VIEW:
        from sim_node.view.window import Window
        window = Window(session)
    try:
        sim.add_object('base', 'box', [0.1, 0.1, 0.1], position=[0, 0, 0.1], mass=0)
        time.sleep(0.1)
        arm = sim.add_body('arm', 'base', 'capsule', [0.02, 0.15], position=[0, 0, 0.3],
                           mass=0.5, joint='hinge', axis=[0, 1, 0])
        time.sleep(0.1)
        sim.add_object('crate', 'box', [0.05, 0.05, 0.05], position=[0.5, 0, 0.5], mass=0.3)
        joint = f'{arm}/joint'
        errors = []
        t_end = sim.time + 3.0
        while sim.time < t_end:
            target = 0.6 * math.sin(2 * math.pi * 0.5 * sim.time)
            sim.world.command([joint], [target], 'position')
            time.sleep(0.01)
            q = sim.world.get_joint_states()[joint][0]
            errors.append(abs(q - target))
        crate_z = sim.world.get_entity_state('crate').position[2]
    finally:
        if window is not None:
            window.close()
        session.close()
    entities = {e.name: e.category for e in sim.world.entities()}
    tail = errors[len(errors) // 2:]
    print(f'entities {entities}; crate rests at z = {crate_z:.3f} m; '
          f'arm tracking error (second half) mean {sum(tail) / len(tail):.3f} rad')
    return {'entities': entities, 'crate_z': crate_z,
            'mean_tracking_error': sum(tail) / len(tail), 'max_angle_seen': None}


if __name__ == '__main__':
    main()
