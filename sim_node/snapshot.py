"""
Write a PNG picture of a scene: ``python -m sim_node.snapshot SCENE -o out.png``.

SCENE is an MJCF/URDF file or an installed scene name (``default``). Without ``--camera`` the
picture comes from a free camera that shows the whole scene; ``--settle`` simulates that many
seconds first (objects come to rest). Needs no ROS and no display (see
:mod:`sim_node.core.devices.rendering`).
"""

import argparse
import sys

from .core.base.errors import SimError
from .core.cameras import picture
from .core.models.resources import installed_scenes_dir, resolve_scene
from .core.world import World


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='python -m sim_node.snapshot',
                                     description='Write a PNG picture of a scene.')
    parser.add_argument('scene', nargs='?', default='default',
                        help='an MJCF/URDF file or an installed scene name (default: default)')
    parser.add_argument('-o', '--output', default='snapshot.png', help='PNG file to write')
    parser.add_argument('--camera', default='', help='a camera of the scene (default: free)')
    parser.add_argument('--width', type=int, default=640)
    parser.add_argument('--height', type=int, default=480)
    parser.add_argument('--settle', type=float, default=0.0,
                        help='simulated seconds to step before the picture')
    args = parser.parse_args(argv)
    try:
        from PIL import Image
        world = World.from_file(str(resolve_scene(args.scene, installed_scenes_dir())))
        if args.settle > 0:
            world.step(max(1, round(args.settle / world.timestep)))
        rgb = picture(world, args.camera, args.width, args.height)
        Image.fromarray(rgb).save(args.output, format='PNG')
    except (SimError, OSError, ValueError) as exc:
        print(f'snapshot: {exc}', file=sys.stderr)
        return 1
    print(f'wrote {args.output} ({args.width}x{args.height}, '
          f'{"camera " + args.camera if args.camera else "free camera"})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
