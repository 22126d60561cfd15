"""
Does the node give its memory back? Its resident memory over a soak, against where it began.

``make bench-soak`` (about 2 minutes). The installed node runs the default scene in real time;
after a warm-up (each path below once), its resident memory (VmRSS) is the baseline. Then,
three times over: 8 client processes each spawn 50 boxes and delete them (issue 21's storm),
one client spawns and deletes an installed mesh object 10 times, and the world is loaded anew
(``load_world``: the mobile scene, then the default one again). Then resets (issue 52): 200
resets of the world's state, then 20 rounds of spawn, delete, reset, spawn (the second box stays
until the next reset); and a storm of mixed calls (8 client processes, each 40 reads, spawns
and deletes). After each part the node has SETTLE_SEC to give freed memory back (it trims on
its own schedule). Printed: RSS after each part, and the peak; the verdicts: the resets leave
RSS within 20 MiB of where they began, and the whole soak within 50 MiB of the baseline (issues
45 and 52).
"""

import os
from pathlib import Path
import random
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'benchmarks'))
from leave import leave  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402, I100

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(120, 200)))
CLIENTS, BOXES, ROUNDS = 8, 50, 3
RESETS, RESET_ROUNDS, MIXED_CALLS = 200, 20, 40
SETTLE_SEC = 4.0
TARGET_MIB = 50.0
RESETS_TARGET_MIB = 20.0


def rss_mib(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS'):
            return int(line.split()[1]) / 1024
    raise RuntimeError('no VmRSS')


def storm_client(k: int) -> None:
    """One client of a storm: spawn BOXES boxes, then delete them."""
    import rclpy
    from sim_node.ros.client import SimClient
    rclpy.init()
    c = SimClient(timeout_sec=60)
    names = [c.spawn(f'soak_{k}_{j}', uri='box', position=(4 + 0.3 * k, -4 + 0.2 * j, 0.3))
             for j in range(BOXES)]
    for name in names:
        c.delete(name)
    leave()  # eight clients leave at once: see leave.py


def mixed_client(k: int) -> None:
    """One client of the mixed storm: reads, spawns and deletes in turn (MIXED_CALLS calls)."""
    import rclpy
    from sim_node.ros.client import SimClient
    rclpy.init()
    c = SimClient(timeout_sec=60)
    scene = [name for name in c.entities() if not name.startswith('mixed_')]
    for j in range(MIXED_CALLS // 4):
        c.entity_state(scene[j % len(scene)])
        c.spawn(f'mixed_{k}_{j}', uri='box', position=(-4 + 0.3 * k, 4 - 0.2 * j, 0.3))
        c.entities()
        c.delete(f'mixed_{k}_{j}')
    leave()


def storm(mode: str = '--client') -> None:
    procs = [subprocess.Popen([sys.executable, __file__, mode, str(k)])
             for k in range(CLIENTS)]
    for p in procs:
        assert p.wait(300) == 0, 'a storm client failed'


def main() -> None:
    import rclpy
    from sim_node.ros.client import SimClient
    node = subprocess.Popen([os.path.join(os.environ['SIM_PREFIX'], 'lib', 'sim', 'node')],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rclpy.init()
    c = SimClient(timeout_sec=60)
    mesh = 'package://sim/scenes/objects/pyramid_mesh.xml'
    try:
        c.entities()
        for k in range(2):  # warm-up: every path once
            c.spawn('warm', uri='box', position=(1, 1, 1))
            c.delete('warm')
            c.spawn('warm', uri=mesh, position=(1, 1, 1))
            c.delete('warm')
            c.load_world(uri='package://sim/scenes/default.xml')
        time.sleep(SETTLE_SEC)
        base = peak = rss_mib(node.pid)
        print(f'[soak] the node on the default scene; baseline RSS {base:.1f} MiB', flush=True)
        for r in range(ROUNDS):
            storm()
            peak = max(peak, rss_mib(node.pid))
            for k in range(10):
                c.spawn(f'mesh_{k}', uri=mesh, position=(2, 2, 1))
                c.delete(f'mesh_{k}')
            c.load_world(uri='package://sim/scenes/mobile.xml')
            peak = max(peak, rss_mib(node.pid))
            c.load_world(uri='package://sim/scenes/default.xml')
            time.sleep(SETTLE_SEC)
            now = rss_mib(node.pid)
            print(f'  round {r + 1}: {CLIENTS} clients x {BOXES} boxes spawned and deleted, 10 '
                  f'meshes, two world loads: RSS {now:.1f} MiB ({now - base:+.1f})',
                  flush=True)
        before_resets = rss_mib(node.pid)
        for _ in range(RESETS):
            c.reset()
        for k in range(RESET_ROUNDS):
            c.spawn(f'cycle_{k}', uri='box', position=(1, 1, 1))
            c.delete(f'cycle_{k}')
            c.reset()
            c.spawn(f'kept_{k}', uri='box', position=(-2 + 0.3 * k, -2, 0.3))  # until a reset
        c.reset()
        time.sleep(SETTLE_SEC)
        after_resets = rss_mib(node.pid)
        print(f'  {RESETS} resets, then {RESET_ROUNDS} rounds of spawn, delete, reset, spawn: '
              f'RSS {after_resets:.1f} MiB ({after_resets - before_resets:+.1f} over where '
              f'they began; {after_resets - base:+.1f} over the baseline)', flush=True)
        storm('--mixed')
        peak = max(peak, rss_mib(node.pid))
        time.sleep(SETTLE_SEC)
        end = rss_mib(node.pid)
        print(f'  a mixed storm ({CLIENTS} clients x {MIXED_CALLS} calls): RSS {end:.1f} MiB '
              f'({end - base:+.1f})', flush=True)
    finally:
        c.close()
        rclpy.shutdown()
        node.terminate()
        node.wait(20)
    print(f'[soak] peak {peak:.1f} MiB; end {end:.1f} MiB, {end - base:+.1f} over the baseline')
    verdict(after_resets - before_resets <= RESETS_TARGET_MIB,
            f'RSS after {RESETS} resets and {RESET_ROUNDS} mixed rounds: '
            f'{after_resets - before_resets:+.1f} MiB over where they began (target <= '
            f'{RESETS_TARGET_MIB:g} MiB)')
    verdict(end - base <= TARGET_MIB, f'RSS after {ROUNDS} rounds of storms, spawns, deletes '
            f'and world loads, the resets and a mixed storm: {end - base:+.1f} MiB over the '
            f'baseline (target <= {TARGET_MIB:g} MiB)')
    summary()


if __name__ == '__main__':
    if sys.argv[1:2] == ['--client']:
        storm_client(int(sys.argv[2]))
    elif sys.argv[1:2] == ['--mixed']:
        mixed_client(int(sys.argv[2]))
    else:
        main()
