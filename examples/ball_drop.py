"""A ball dropped from 1 m, then again with a higher default restitution: it bounces higher."""

import sys

from sim_node.simulation import Simulation

VIEW = '--view' in sys.argv  # MuJoCo's viewer on the world, in real time (a display)


def bounce_height(default_restitution=None) -> float:
    sim = Simulation.empty()
    if VIEW:
        sim.view()
    if default_restitution is not None:
        sim.set_defaults(restitution=default_restitution)
    sim.add_object('ball', 'sphere', [0.05], position=[0, 0, 1.05], mass=0.2)
    landed, peak = False, 0.0
    for _ in range(1500):  # 3 s
        sim.step()
        st = sim.get_state()
        z, vz = st['bodies']['ball'][0][2], st['body_velocities']['ball'][0][2]
        landed |= z < 0.06
        if landed and vz > 0:
            peak = max(peak, z - 0.05)
    return peak


def main() -> dict:
    result = {'plain': bounce_height(), 'restitution_0.7': bounce_height(0.7)}
    for k, v in result.items():
        print(f'{k:16s} bounce height {v:.3f} m')
    return result


if __name__ == '__main__':
    main()
