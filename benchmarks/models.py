"""
Robot files as users bring them: spawn round trips over the wire against bare MuJoCo's load.

``make bench-models``. The corpus (``ros_env/corpus.py``: robot files that robosuite,
gymnasium-robotics and dm_control ship) is fetched once. A real node runs the default scene at
real_time_factor 1 with the corpus in resource_paths. For each file, side by side in one run:

* bare MuJoCo's cold ``MjModel.from_xml_path`` of the file, in a fresh process;
* the first ``spawn_entity`` round trip from a client process, then a delete, then a second
  spawn of the same file (MuJoCo's mesh cache and our checked-file store at work);
* the longest stretch of wall time without a new ``/clock`` message during each spawn, and the
  real-time factor the world held meanwhile (simulated over wall time).

It ends with one verdict line per target. ``BENCH_MODELS=panda,gr1`` runs only the files whose
path contains one of those words; ``BENCH_NODE_PARAMS='cameras:=[none]'`` passes parameters to
the node.
"""

import os
from pathlib import Path
import statistics
import subprocess
import sys
import threading
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'ros_env'))
import corpus  # noqa: E402, I100
sys.path.insert(0, str(ROOT / 'benchmarks'))
from verdict import verdict  # noqa: E402, I100

TARGET_RATIO = 1.25  # first spawn round trip over bare MuJoCo's cold load
TARGET_SECOND_SEC = 0.25
TARGET_SMALL_RATIO = 2.0  # the same ratio, for each file MuJoCo loads in under SMALL_BARE_SEC
SMALL_BARE_SEC = 0.05
TARGET_NO_MESH_SEC = 0.05
TARGET_STALL_SEC = 0.05


class ClockWatch:
    """Records (wall time, sim time) of every /clock message, on a thread of its own."""

    def __init__(self):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock
        self.node = rclpy.create_node('bench_clock_watch')
        self.samples = []
        self.lock = threading.Lock()
        self.node.create_subscription(Clock, '/clock', self._on_clock, 1000)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self._stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self._stop:
            self.executor.spin_once(timeout_sec=0.05)

    def _on_clock(self, msg):
        with self.lock:
            self.samples.append((time.perf_counter(), msg.clock.sec + msg.clock.nanosec * 1e-9))

    def window(self, t0: float, t1: float) -> tuple:
        """(longest wall gap between /clock messages, sim seconds per wall second) in [t0, t1]."""
        with self.lock:
            inside = [s for s in self.samples if t0 - 0.1 <= s[0] <= t1 + 0.1]
        if len(inside) < 2:
            return float('inf'), 0.0
        gaps = [b[0] - a[0] for a, b in zip(inside, inside[1:])]
        rtf = (inside[-1][1] - inside[0][1]) / max(inside[-1][0] - inside[0][0], 1e-9)
        return max(gaps), rtf

    def close(self):
        self._stop = True
        self.thread.join(2)
        self.executor.shutdown()
        self.node.destroy_node()


class Node:
    """A real node on the default scene at real_time_factor 1, the corpus readable."""

    def __init__(self, folder, *params: str):
        import rclpy
        from sim_node.ros.client import SimClient
        exe = Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / 'node'
        folders = folder if isinstance(folder, (list, tuple)) else [folder]
        paths = ','.join(f'"{f}"' for f in folders)
        args = [str(exe), '--ros-args', '-p', f'resource_paths:=[{paths}]',
                '-p', 'real_time_factor:=1.0']
        for p in params:
            args += ['-p', p]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
        rclpy.init()
        self.sim = SimClient(timeout_sec=120)
        self.sim.entities()  # the node is up
        self.watch = ClockWatch()
        time.sleep(1.0)

    def spawn(self, i: int, model) -> tuple:
        """Spawn and delete once: (round trip s, longest /clock gap s, real-time factor)."""
        t0 = time.perf_counter()
        uri = model.uri if hasattr(model, 'uri') else model.file.as_uri()
        name = self.sim.spawn(f'm{i}', uri=uri, position=(4.0, 4.0, 3.0))
        t1 = time.perf_counter()
        time.sleep(0.3)  # /clock of the spawn's last moments
        stall, rtf = self.watch.window(t0, t1)
        self.sim.delete(name)
        time.sleep(0.5)  # what the delete leaves to do (markers, publishers) is not the next
        return t1 - t0, stall, rtf  # spawn's stall

    def close(self) -> None:
        import rclpy
        self.watch.close()
        self.sim.close()
        rclpy.shutdown()
        self.proc.terminate()
        self.proc.wait(10)


def main() -> int:
    # The clock watcher and the client share this process's GIL: hand it over often, so the
    # gaps measured are the node's, not this process's.
    sys.setswitchinterval(0.001)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(50 + os.getpid() % 50))
    folder = corpus.fetch()
    only = [w for w in os.environ.get('BENCH_MODELS', '').split(',') if w]
    models = [(i, m) for i, m in enumerate(corpus.MODELS)
              if not only or any(w in m.path for w in only)]
    extra = os.environ.get('BENCH_NODE_PARAMS', '').split()
    print(f'[models] {len(models)} files; a node on the default scene (its camera on) at '
          f'real_time_factor 1; {os.cpu_count()} cores')
    print(f'{"file":44s} {"bare":>6s} {"spawn":>6s} {"ratio":>6s} {"again":>6s} '
          f'{"stall":>6s} {"rtf":>5s} {"stall, no camera":>16s}')
    rows = []
    node = Node(folder, *extra)
    try:
        for i, m in models:
            bare = corpus.bare_load_seconds(m)
            (first, stall1, rtf1), (again, stall2, rtf2) = node.spawn(i, m), node.spawn(i, m)
            rows.append([m, bare, first, again, max(stall1, stall2), min(rtf1, rtf2)])
    finally:
        node.close()
    # The same spawns with cameras off: the renderer uploads every mesh of a new model to
    # OpenGL in one call that holds Python's GIL (MuJoCo's MjrContext), a stall of its own.
    node = Node(folder, 'cameras:=[none]', *extra)
    try:
        for row, (i, m) in zip(rows, models):
            node.spawn(i, m)  # the first spawn of the file in this process
            row += [node.spawn(i, m)[1]]
    finally:
        node.close()
    for m, bare, first, again, stall, rtf, stall_off in rows:
        print(f'{m.name[:44]:44s} {bare:6.3f} {first:6.3f} {first / bare:6.2f} {again:6.3f} '
              f'{stall * 1e3:4.0f}ms {rtf:5.2f} {stall_off * 1e3:14.0f}ms')
    meshy = [r for r in rows if r[0].meshes] or rows
    plain = [r for r in rows if not r[0].meshes]
    ratio = statistics.median(r[2] / r[1] for r in meshy)
    again = statistics.median(r[3] for r in meshy)
    stall = max(r[4] for r in rows)
    rtf = min(r[5] for r in rows)
    stall_off = max(r[6] for r in rows)
    no_mesh = max(r[2] for r in plain) if plain else float('nan')
    print(f'median over {len(meshy)} mesh files: first spawn '
          f'{statistics.median(r[2] for r in meshy):.3f} s, bare MuJoCo '
          f'{statistics.median(r[1] for r in meshy):.3f} s')

    verdict(ratio <= TARGET_RATIO, f'first spawn / bare cold load, median {ratio:.2f} '
            f'(target <= {TARGET_RATIO})')
    small = [r for r in rows if r[1] < SMALL_BARE_SEC]
    worst = max(small, key=lambda r: r[2] / r[1]) if small else None
    if worst is not None:
        verdict(worst[2] / worst[1] <= TARGET_SMALL_RATIO,
                f'first spawn / bare cold load of each small file (bare < '
                f'{SMALL_BARE_SEC * 1e3:.0f} ms, {len(small)} files), worst '
                f'{worst[2] / worst[1]:.2f} ({worst[0].name}: {worst[2] * 1e3:.0f} ms against '
                f'{worst[1] * 1e3:.0f} ms; target <= {TARGET_SMALL_RATIO})')
    verdict(again <= TARGET_SECOND_SEC, f'second spawn of the same file, median {again:.3f} s '
            f'(target <= {TARGET_SECOND_SEC} s)')
    verdict(no_mesh <= TARGET_NO_MESH_SEC, f'a file without meshes, {no_mesh * 1e3:.0f} ms '
            f'(target <= {TARGET_NO_MESH_SEC * 1e3:.0f} ms)')
    verdict(stall_off <= TARGET_STALL_SEC, f'longest /clock stall during a spawn, cameras off: '
            f'{stall_off * 1e3:.0f} ms (target <= {TARGET_STALL_SEC * 1e3:.0f} ms)')
    verdict(stall <= TARGET_STALL_SEC, f'longest /clock stall during a spawn, default camera on: '
            f'{stall * 1e3:.0f} ms (target <= {TARGET_STALL_SEC * 1e3:.0f} ms); lowest '
            f'real-time factor meanwhile {rtf:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
