"""
ROS robots as ROS users have them: what a URDF spawn costs, step by step, and what it stalls.

``make bench-urdf``. For each file of the ROS corpus (``ros_env/corpus.py``; by default the
Collada-heavy robots and a few others, ``BENCH_URDF=all`` for every file, ``BENCH_URDF=panda,go1``
for those whose path has one of the words), side by side in one run:

* read: parsing and checking the file and every mesh it names (``sources.from_file`` here,
  with the time converting meshes taken out), and convert: the mesh conversions alone, in this
  process's own cold cache;
* compile: bare MuJoCo's cold ``MjModel.from_xml_path`` of the prepared model (its converted
  meshes as files) in a fresh process: what MuJoCo itself needs for this robot;
* the first ``spawn_entity`` round trip from a client into a running node (real_time_factor 1,
  default scene, cameras off) that never converted the file's meshes, and a second spawn after
  a delete; then the first spawn in a new node whose conversion cache holds them;
* the longest stretch of wall time without a new ``/clock`` message during any of those.

It ends with one verdict line per target.
"""

import os
from pathlib import Path
import statistics
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'ros_env'))
import corpus  # noqa: E402, I100
sys.path.insert(0, str(ROOT / 'benchmarks'))
from models import Node  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402, I100

TARGET_FIRST_SEC = 2.5  # first spawn of a Collada-heavy robot
TARGET_RATIO = 1.5  # ... over MuJoCo's own compile of the converted model from files
TARGET_SECOND_SEC = 0.25
TARGET_STALL_SEC = 0.05
#: A robot with at least this many Collada meshes is Collada-heavy.
HEAVY_DAE = 10
DEFAULT = ('panda.urdf', 'talos_reduced.urdf', 'tiago.urdf', 'anymal.urdf', 'baxter.urdf',
           'go1.urdf', 'go2.urdf', 'icub.urdf', 'kinova.urdf', 'ur5_robot.urdf', 'romeo.urdf',
           'b1-z1.urdf', 'solo12.urdf', 'vx300s.urdf.xacro', 'cart.urdf', 'r2d2.urdf')


def prepare(model: corpus.RosModel) -> tuple:
    """Return (read s, convert s, faces converted, the prepared model as MJCF text)."""
    from sim_node.core.models import meshes, sources
    spent = [0.0]
    real = meshes.convert

    def timed(*args, **kwargs):
        t = time.perf_counter()
        try:
            return real(*args, **kwargs)
        finally:
            spent[0] += time.perf_counter() - t
    meshes.convert = timed
    try:
        t0 = time.perf_counter()
        src = sources.from_file(str(model.path), allowed_roots=[str(model.root)])
        total = time.perf_counter() - t0
    finally:
        meshes.convert = real
    return total - spent[0], spent[0], src.spec.to_xml()


def bare_compile_seconds(xml: str) -> float:
    # Written out, numbers lose digits: an inertia repaired to meet the triangle inequality
    # could then break it again; MuJoCo's own balancing puts that right.
    xml = xml.replace('<compiler ', '<compiler balanceinertia="true" ', 1)
    with tempfile.NamedTemporaryFile('w', suffix='.xml', delete=False) as f:
        f.write(xml)
    try:
        return corpus.bare_load_seconds(Path(f.name))
    finally:
        os.unlink(f.name)


def main() -> int:
    sys.setswitchinterval(0.001)  # the clock watcher shares this process's GIL
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(50 + os.getpid() % 50))
    pick = os.environ.get('BENCH_URDF', '')
    models = [m for m in corpus.ros_models() if not m.refused]
    if pick == 'all':
        chosen = models
    elif pick:
        chosen = [m for m in models if any(w in str(m.path) for w in pick.split(','))]
    else:
        chosen = [m for m in models if m.path.name in DEFAULT]
    print(f'[urdf] {len(chosen)} files; a node on the default scene at real_time_factor 1, '
          f'cameras off; {os.cpu_count()} cores')
    node_cache = tempfile.mkdtemp(prefix='bench_urdf_node_cache_')
    # 1. A node that never converted anything: first spawn (cold), second spawn.
    os.environ['SIM_MESH_CACHE'] = node_cache
    cold = {}
    node = Node(corpus.ros_roots(), 'cameras:=[none]')
    try:
        for i, m in enumerate(chosen):
            cold[m.path] = node.spawn(i, m), node.spawn(i, m)
    finally:
        node.close()
    # 2. A new node, the conversions in its cache from the first: its first spawn.
    warm = {}
    node = Node(corpus.ros_roots(), 'cameras:=[none]')
    try:
        for i, m in enumerate(chosen):
            warm[m.path] = node.spawn(i, m)
    finally:
        node.close()
    # 3. Here, with a cache of its own: read and convert apart; MuJoCo's compile alone.
    os.environ['SIM_MESH_CACHE'] = tempfile.mkdtemp(prefix='bench_urdf_cache_')
    print(f'{"file":26s} {"dae":>4s} {"read":>6s} {"conv":>6s} {"mujoco":>7s} {"cold":>6s} '
          f'{"ratio":>6s} {"cached":>7s} {"ratio":>6s} {"again":>6s} {"stall":>6s}')
    rows = []
    for m in chosen:
        dae = m.path.read_text(errors='replace').lower().count('.dae"')
        read, convert, xml = prepare(m)
        bare = bare_compile_seconds(xml)
        (first, stall1, _), (again, stall2, _) = cold[m.path]
        cached, stall3, _ = warm[m.path]
        stall = max(stall1, stall2, stall3)
        rows.append((m, dae, read, convert, bare, first, again, stall, cached))
        print(f'{m.path.name[:26]:26s} {dae:4d} {read:6.3f} {convert:6.3f} {bare:7.3f} '
              f'{first:6.3f} {first / bare:6.2f} {cached:7.3f} {cached / bare:6.2f} '
              f'{again:6.3f} {stall * 1e3:4.0f}ms', flush=True)
    heavy = [r for r in rows if r[1] >= HEAVY_DAE] or rows
    worst = max(heavy, key=lambda r: r[5])
    ratio_cold = statistics.median(r[5] / r[4] for r in heavy)
    ratio = statistics.median(r[8] / r[4] for r in heavy)
    again = statistics.median(r[6] for r in rows)
    worst_again = max(rows, key=lambda r: r[6])
    stall = max(r[7] for r in rows)
    print(f'Collada-heavy (>= {HEAVY_DAE} Collada meshes): {len(heavy)} files; first spawn, '
          f'meshes never converted before: median {statistics.median(r[5] for r in heavy):.2f} '
          f"s, {ratio_cold:.2f}x MuJoCo's own compile; second spawn worst "
          f'{worst_again[6]:.3f} s ({worst_again[0].path.name})')
    verdict(worst[5] <= TARGET_FIRST_SEC,
            f'first spawn of a Collada-heavy robot, meshes never converted before, worst '
            f'{worst[5]:.2f} s ({worst[0].path.name}; target <= {TARGET_FIRST_SEC} s)')
    verdict(ratio <= TARGET_RATIO, f'first spawn of a Collada-heavy robot in a new node (its '
            f"meshes converted by an earlier run) over MuJoCo's own compile of the converted "
            f'model, median {ratio:.2f} (target <= {TARGET_RATIO}; {ratio_cold:.2f} when '
            'nothing was converted before)')
    verdict(again <= TARGET_SECOND_SEC, f'second spawn of the same robot, median {again:.3f} s '
            f'(target <= {TARGET_SECOND_SEC} s)')
    verdict(stall <= TARGET_STALL_SEC, f'longest /clock stall during a spawn {stall * 1e3:.0f} ms '
            f'(target <= {TARGET_STALL_SEC * 1e3:.0f} ms)')
    summary()
    return 0


if __name__ == '__main__':
    sys.exit(main())
