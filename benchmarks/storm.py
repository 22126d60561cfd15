"""
Does time stall while clients edit the world? The longest /clock gap under a spawn/delete storm.

``make bench-storm`` (about a minute). The installed node runs the default scene in real time.
A subscriber here records when each /clock message arrives; first for 5 s idle, then while 8
client processes each spawn 50 boxes and delete them (issue 21's storm). Printed: the longest
wall-clock gap between /clock messages, idle and under the storm, and the longest stretch of
wall time in which simulated time did not advance; the storm's 99th-percentile gap and how many
gaps exceed the target; and, for scale, what the physics of the storm's peak world costs alone
(bare mj_step, measured here after the run). Target (issue 21): the longest gap under the
storm <= 50 ms at real_time_factor 1.
"""

import json
import os
from pathlib import Path
import random
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from clocked_node import longest_still  # noqa: E402, I100
from leave import leave  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402, I100

CLIENTS = 8
BOXES = 50
IDLE_SEC = 5.0
TARGET_MS = 50.0


def client(k: int, go: str) -> None:
    """
    Spawn BOXES boxes, then delete them (one client process of the storm).

    It starts, finds the node's services, and waits for the file `go` to exist, so that
    starting eight Python processes is not part of the measured window. Prints each call's
    latency as one line of JSON.
    """
    import rclpy
    from sim_node.ros.client import SimClient, SimServiceError
    from simulation_interfaces import srv
    rclpy.init()
    c = SimClient(timeout_sec=60)
    c.entities()  # the services are there and answer
    for service, srv_type in (('spawn_entity', srv.SpawnEntity),
                              ('delete_entity', srv.DeleteEntity)):
        c.call(service, srv_type, srv_type.Request(), check=False)  # refused: no name
    print('ready', flush=True)
    while not os.path.exists(go):
        time.sleep(0.005)
    names, lat = [], []
    for j in range(BOXES):
        t = time.perf_counter()
        try:
            names.append(c.spawn(f'storm_{k}_{j}', uri='box',
                                 position=(4 + 0.3 * k, -4 + 0.2 * j, 0.3)))
        except SimServiceError:
            pass
        lat.append(time.perf_counter() - t)
    for name in names:
        t = time.perf_counter()
        c.delete(name)
        lat.append(time.perf_counter() - t)
    print(json.dumps(lat), flush=True)
    leave()  # the storm's clients leave at once: see leave.py


class ClockWatch:
    """Record (wall time, sim time) of every /clock message, on a thread of its own."""

    def __init__(self):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock
        rclpy.init()
        self.node = rclpy.create_node('storm_watch')
        self.samples: list = []
        self.node.create_subscription(Clock, '/clock', self._on_clock, 100)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_clock(self, msg) -> None:
        self.samples.append((time.perf_counter(), msg.clock.sec + msg.clock.nanosec * 1e-9))

    def window(self, t0: float, t1: float) -> tuple:
        """
        Return gaps between messages in ms: longest, 99th percentile, how many over TARGET_MS.

        And the longest wall time without sim progress, in ms.
        """
        s = [x for x in self.samples if t0 <= x[0] <= t1]
        gaps = sorted(b[0] - a[0] for a, b in zip(s, s[1:])) or [float('inf')]
        gap = gaps[-1]
        still = longest_still(s)
        over = sum(g > TARGET_MS / 1e3 for g in gaps)
        return 1e3 * gap, 1e3 * still, 1e3 * gaps[int(0.99 * (len(gaps) - 1))], over, len(gaps)

    def close(self) -> None:
        import rclpy
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown()


def peak_physics() -> tuple:
    """Return (seconds per bare mj_step, timestep) of the world at the storm's peak, settled."""
    import mujoco
    from sim_node.core.models import sources
    from sim_node.core.world import World
    scenes = Path(__file__).resolve().parent.parent / 'scenes'
    world = World.from_file(str(scenes / 'default.xml'))
    box = str(scenes / 'objects' / 'box.xml')
    for k in range(CLIENTS):
        for j in range(BOXES):
            world.spawn(f'storm_{k}_{j}', sources.from_file(box, allowed_roots=[str(scenes)]),
                        position=(4 + 0.3 * k, -4 + 0.2 * j, 0.3))
    world.step(1000)  # at rest on the ground
    with world.locked() as (m, d):
        t = time.perf_counter()
        mujoco.mj_step(m, d, 300)
        return (time.perf_counter() - t) / 300, m.opt.timestep


def main() -> None:
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(120, 200)))
    node = subprocess.Popen([os.path.join(os.environ['SIM_PREFIX'], 'lib', 'sim', 'node')],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    watch = None
    try:
        time.sleep(3.0)
        watch = ClockWatch()
        time.sleep(1.0)
        t0 = time.perf_counter()
        time.sleep(IDLE_SEC)
        t_idle = time.perf_counter()
        go = os.path.join(tempfile.mkdtemp(prefix='storm'), 'go')
        clients = [subprocess.Popen([sys.executable, __file__, '--client', str(k), go],
                                    stdout=subprocess.PIPE, text=True)
                   for k in range(CLIENTS)]
        for c in clients:
            assert c.stdout.readline().strip() == 'ready', 'a storm client did not start'
        time.sleep(1.0)
        t1 = time.perf_counter()
        open(go, 'w').close()
        lat = []
        for c in clients:  # the storm ends with the last reply
            lat += json.loads(c.stdout.readline())
        t2 = time.perf_counter()
        for c in clients:
            c.communicate(timeout=60)
        idle, storm = watch.window(t0, t_idle), watch.window(t1, t2)
    finally:
        if watch is not None:
            watch.close()
        node.terminate()
        node.wait(10)
    print(f'[storm] default scene at real_time_factor 1; {CLIENTS} clients each spawn {BOXES} '
          f'boxes and delete them ({t2 - t1:.1f} s)')
    print(f'  longest gap between /clock messages: idle {idle[0]:7.1f} ms   '
          f'storm {storm[0]:7.1f} ms')
    print(f'  longest wall time with sim time still: idle {idle[1]:7.1f} ms   '
          f'storm {storm[1]:7.1f} ms')
    print(f'  /clock gaps under the storm: p99 {storm[2]:.1f} ms; over {TARGET_MS:g} ms: '
          f'{storm[3]} of {storm[4]}')
    step, dt = peak_physics()
    print(f"  the physics alone at the storm's peak (default scene + {CLIENTS * BOXES} boxes at "
          f'rest, bare mj_step): {1e3 * step:.2f} ms per {1e3 * dt:g} ms step = '
          f'{100 * step / dt:.0f}% of a core in real time')
    lat = sorted(lat)
    print(f'  request latency over {len(lat)} spawns and deletes: median '
          f'{1e3 * lat[len(lat) // 2]:.0f} ms, p99 {1e3 * lat[int(0.99 * len(lat))]:.0f} ms, '
          f'max {1e3 * lat[-1]:.0f} ms')
    verdict(storm[0] <= TARGET_MS, f'longest /clock gap under the storm {storm[0]:.1f} ms '
            f'(target <= {TARGET_MS:g} ms; idle {idle[0]:.1f} ms)')
    summary()


if __name__ == '__main__':
    if sys.argv[1:2] == ['--client']:
        client(int(sys.argv[2]), sys.argv[3])
    else:
        main()
