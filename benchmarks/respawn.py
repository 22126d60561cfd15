"""
A robot spawned again after its delete: its first spawn, its second, and MuJoCo's compile.

``make bench-respawn`` (about half a minute). In this process, on the default scene, robots of
the ROS corpus (``ros_env/corpus.py``: URDFs of example-robot-data with their meshes, the
heaviest first) are each spawned, deleted and spawned again, as a user does who restarts a
robot. Printed per robot, side by side in one run: the first spawn's wall time, the second's,
and bare MuJoCo's compile of the world the second spawn made (``spec.compile()`` of the same
world with the mesh cache as it is then), with the mesh cache's size and what the delete kept
in it (``mesh_cache_keep_sec``, ``mesh_cache_keep_mb``).

Verdict (issue 52): each second spawn within 0.25 s or within 1.25 times MuJoCo's compile of
the world it makes, whichever is larger. A second run with ``mesh_cache_keep_mb`` 0 (a delete
evicts at once, as at d48b79a), made first, shows what the kept meshes save.
"""

import os
from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'ros_env'))
sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

import corpus  # noqa: E402, I100
from sim_node.core.config import WorldConfig  # noqa: E402
from sim_node.core.models import asset_store, sources  # noqa: E402
from sim_node.core.world import World  # noqa: E402
from verdict import summary, verdict  # noqa: E402, I100

#: Robots of example-robot-data with many or large meshes (a humanoid, an arm, a quadruped,
#: a mobile manipulator, a hand).
ROBOTS = ('g1_description/urdf/g1_29dof_rev_1_0.urdf', 'talos_data/robots/talos_full_v2.urdf',
          'panda_description/urdf/panda.urdf', 'go1_description/urdf/go1.urdf',
          'tiago_description/robots/tiago.urdf',
          'allegro_hand_description/urdf/allegro_right_hand.urdf')
TARGET_SEC, TARGET_RATIO = 0.25, 1.25


def timed(fn) -> tuple:
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def run(keep_mb: int, share: Path) -> list:
    world = World.from_file(str(ROOT / 'scenes' / 'default.xml'),
                            WorldConfig(real_time_factor=0.0, mesh_cache_keep_mb=keep_mb))
    rows = []
    for rel in ROBOTS:
        path = share / 'example-robot-data' / 'robots' / rel
        if not path.is_file():
            print(f'  {rel}: not in the corpus, left out')
            continue
        name = rel.split('/')[0].replace('_description', '').replace('_data', '')
        spawn = lambda: world.spawn(name, sources.from_file(  # noqa: E731
            str(path), allowed_roots=[str(share)]), position=(0.0, 3.0, 1.5))
        _, first = timed(spawn)
        world.delete(name)
        kept = world.kept_mesh_bytes() / 2 ** 20
        _, second = timed(spawn)
        # bare MuJoCo on the world's own spec (the World keeps it; no public copy of it)
        _, compile_sec = timed(lambda: world._live.design.spec.copy().compile())
        cache = asset_store.mesh_cache_bytes() / 2 ** 20
        world.delete(name)
        rows.append((name, first, second, compile_sec, cache, kept))
        print(f'  {name:10s} first {first:5.2f} s, second {second:5.2f} s, MuJoCo compile '
              f'{compile_sec:5.2f} s (second/compile {second / compile_sec:4.2f}); cache '
              f'{cache:6.1f} MiB, kept after the delete {kept:6.1f} MiB', flush=True)
    return rows


def main() -> None:
    share = corpus.CORPUS / 'example_robot_data' / 'cmeel.prefix' / 'share'
    if not share.is_dir():
        corpus.fetch()
    # The cache is the process's: the run that evicts goes first, so that it starts and ends
    # with nothing kept, and the run that keeps starts from a cache without these robots.
    print('evicted at the delete (mesh_cache_keep_mb 0, as at d48b79a):')
    run(0, share)
    print("deleted robots' meshes kept (mesh_cache_keep_mb 512, the default):")
    kept = run(512, share)
    for name, _, second, compile_sec, _, _ in kept:
        verdict(second <= max(TARGET_SEC, TARGET_RATIO * compile_sec),
                f'{name} spawned again in {second:.2f} s (target: <= {TARGET_SEC} s or '
                f"<= {TARGET_RATIO} x MuJoCo's compile, {compile_sec:.2f} s)")
    summary()


if __name__ == '__main__':
    main()
