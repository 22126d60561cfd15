"""A block without mass is static; it only falls once it has mass."""

import sys

from sim_node.simulation import Simulation

VIEW = '--view' in sys.argv  # MuJoCo's viewer on the world, in real time (a display)


def main() -> dict:
    sim = Simulation.empty()
    if VIEW:
        sim.view()
    sim.add_object('block', 'box', [0.05, 0.05, 0.05], position=[0, 0, 1.0], mass=0)
    sim.step(dt=1.0)
    z_without_mass = sim.get_state()['bodies']['block'][0][2]
    sim.set_mass('block', 1.0)
    sim.step(dt=1.0)
    z_with_mass = sim.get_state()['bodies']['block'][0][2]
    print(f'after 1 s without mass: z = {z_without_mass:.3f} m; '
          f'1 s after getting mass: z = {z_with_mass:.3f} m')
    return {'z_without_mass': z_without_mass, 'z_with_mass': z_with_mass}


if __name__ == '__main__':
    main()
