"""
The scale benchmark's scene: n free boxes on a floor, one body each, nothing else.

python benchmarks/box_scene.py 1000 > /tmp/boxes_1000.xml
"""

import math
import sys


def box_scene(n: int, spacing: float = 0.25, half: float = 0.05) -> str:
    """MJCF text of `n` free boxes resting in a square grid on a floor."""
    side = max(1, math.ceil(math.sqrt(n)))
    bodies = []
    for i in range(n):
        x = (i % side - side / 2) * spacing
        y = (i // side - side / 2) * spacing
        bodies.append(f'<body name="box_{i}" pos="{x:.3f} {y:.3f} {half:.3f}"><freejoint/>'
                      f'<geom type="box" size="{half} {half} {half}" mass="0.1"/></body>')
    return ('<mujoco model="boxes_%d"><option timestep="0.002"/><worldbody>'
            '<light pos="0 0 10" dir="0 0 -1" directional="true"/>'
            '<geom name="floor" type="plane" size="0 0 0.1"/>\n%s\n</worldbody></mujoco>'
            % (n, '\n'.join(bodies)))


if __name__ == '__main__':
    sys.stdout.write(box_scene(int(sys.argv[1]) if len(sys.argv) > 1 else 1000))
