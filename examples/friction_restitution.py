"""Ten blocks of rising friction on a tilted table, ten balls of rising restitution."""

from pathlib import Path
import sys

import numpy as np
from sim_node.simulation import Simulation

VIEW = '--view' in sys.argv  # MuJoCo's viewer on the world, in real time (a display)

SCENE = Path(__file__).resolve().parent.parent / 'scenes' / 'friction_restitution.xml'


def main() -> dict:
    sim = Simulation.from_file(str(SCENE))
    if VIEW:
        sim.view()
    start = sim.get_state()['bodies']
    peaks, landed = np.zeros(10), np.zeros(10, bool)
    for step in range(1000):  # 2 s
        sim.step()
        if step == 399:  # 0.8 s: the slowest sliders are still on the table
            slid_at = sim.get_state()['bodies']
        st = sim.get_state()
        for i in range(10):
            z = st['bodies'][f'ball_{i}'][0][2]
            landed[i] |= z < 0.04
            if landed[i] and st['body_velocities'][f'ball_{i}'][0][2] > 0:
                peaks[i] = max(peaks[i], z)
    slides = [float(np.linalg.norm(slid_at[f'block_{i}'][0] - start[f'block_{i}'][0]))
              for i in range(10)]
    for i in range(10):
        print(f'block {i} (friction {0.1 + 0.1 * i:.1f}) slid {slides[i]:.3f} m;   '
              f'ball {i} (restitution {0.05 + 0.08 * i:.2f}) bounced to {peaks[i]:.3f} m')
    return {'slides': slides, 'bounces': peaks.tolist()}


if __name__ == '__main__':
    main()
