"""
SDF worlds: what reading one costs over MuJoCo's own compile, and what stepping it costs.

``make bench-sdf``. Measured side by side in one run (issue 54's targets):

1. A world of 3,000 shapes (1,500 boxes free on the ground plane and 1,500 static posts, each
   a model of one link with a collision and a visual), as an SDF file: loaded
   (``World.from_file``: read, checked, made MJCF, compiled, its state set; best of three)
   over bare MuJoCo's load of the same world written as MJCF by hand here
   (``MjModel.from_xml_path`` in a fresh process, best of three, as ``make bench-urdf``
   measures it; its load in this process is printed beside). Target: at most 2x.
2. That world stepped by the node (installed executable, real_time_factor 0, cameras off,
   /tf and joint_states as by default) over bare ``mj_step`` on the MJCF in this process,
   interleaved rounds, from /clock. Target: at least 0.95x.
3. A world of 20 model folders included by ``model://`` (each a ``model.config``, a
   ``model.sdf`` and a mesh of its own, 5,120 faces), loaded a first time into a cold mesh
   cache and a second time (its conversions cached) over bare MuJoCo's load of the same
   world as MJCF (its meshes as the STL files) in a fresh process. Target: the second load at
   most 1.5x. MuJoCo's load in this process, with its own mesh cache warm from the loads
   before, is printed beside: the fixed cost of reading 21 SDF files shows there.

It ends with one verdict line per target.
"""

import math
import os
from pathlib import Path
import random
import statistics
import sys
import tempfile
import time

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'benchmarks'))
sys.path.insert(0, str(ROOT / 'ros_env'))
from clocked_node import ClockedNode  # noqa: E402, I100
import corpus  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402, I100

TARGET_LOAD = 2.0
TARGET_STEPS = 0.95
TARGET_CACHED = 1.5
FREE, POSTS = 1500, 1500
STEP = 0.002
MODELS = 20
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(120, 200)))


def _grid(k: int, per_row: int, spacing: float) -> tuple:
    return (k % per_row) * spacing - per_row * spacing / 2, (k // per_row) * spacing


def shapes_world() -> tuple:
    """Return (the 3,000-shape world as SDF, the same world as MJCF)."""
    sdf, mjcf = [], []
    box = '<box><size>0.1 0.1 0.1</size></box>'
    inertia = 0.2 * 0.1 ** 2 / 6
    for k in range(FREE):
        x, y = _grid(k, 50, 0.3)
        sdf.append(f'<model name="box{k}"><pose>{x:.3f} {y:.3f} 0.0505 0 0 0</pose>'
                   f'<link name="l"><inertial><mass>0.2</mass><inertia><ixx>{inertia}</ixx>'
                   f'<iyy>{inertia}</iyy><izz>{inertia}</izz></inertia></inertial>'
                   f'<collision name="c"><geometry>{box}</geometry></collision>'
                   f'<visual name="v"><geometry>{box}</geometry></visual></link></model>')
        mjcf.append(f'<body name="box{k}" pos="{x:.3f} {y:.3f} 0.0505"><freejoint/>'
                    f'<inertial pos="0 0 0" mass="0.2" diaginertia="{inertia} {inertia} '
                    f'{inertia}"/><geom type="box" size="0.05 0.05 0.05"/>'
                    '<geom type="box" size="0.05 0.05 0.05" contype="0" conaffinity="0" '
                    'group="1"/></body>')
    post = '<cylinder><radius>0.05</radius><length>1</length></cylinder>'
    for k in range(POSTS):
        x, y = _grid(k, 50, 0.3)
        y = -y - 1.0
        sdf.append(f'<model name="post{k}"><static>true</static><pose>{x:.3f} {y:.3f} 0.5 0 0 '
                   f'0</pose><link name="l"><collision name="c"><geometry>{post}</geometry>'
                   f'</collision><visual name="v"><geometry>{post}</geometry></visual></link>'
                   '</model>')
        mjcf.append(f'<body name="post{k}" pos="{x:.3f} {y:.3f} 0.5"><geom type="cylinder" '
                    'size="0.05 0.5"/><geom type="cylinder" size="0.05 0.5" contype="0" '
                    'conaffinity="0" group="1"/></body>')
    ground = ('<model name="ground"><static>true</static><link name="l"><collision name="c">'
              '<geometry><plane><normal>0 0 1</normal><size>100 100</size></plane></geometry>'
              '</collision></link></model>')
    sdf_text = (f'<?xml version="1.0"?><sdf version="1.9"><world name="shapes"><physics '
                f'name="p" type="ignored"><max_step_size>{STEP}</max_step_size></physics>'
                f'{ground}{"".join(sdf)}</world></sdf>')
    mjcf_text = (f'<mujoco model="shapes"><option timestep="{STEP}" integrator="implicitfast"/>'
                 '<worldbody><geom type="plane" size="50 50 0.1"/>'
                 f'{"".join(mjcf)}</worldbody></mujoco>')
    return sdf_text, mjcf_text


def sphere_stl(path: Path, subdivisions: int = 4) -> None:
    """Write an icosphere of 20 * 4**subdivisions faces, radius 0.1 m, as binary STL."""
    from sim_node.core.models.collada_fast import binary_stl
    t = (1 + math.sqrt(5)) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        cache, faces = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = faces
    path.write_bytes(binary_stl(0.1 * np.array(verts), np.array(f)))


def model_folders(top: Path) -> tuple:
    """Write 20 model folders with a mesh each; return (the world as SDF, as MJCF)."""
    includes, bodies, assets = [], [], []
    for k in range(MODELS):
        folder = top / f'thing{k}'
        (folder / 'meshes').mkdir(parents=True)
        sphere_stl(folder / 'meshes' / 'thing.stl')
        (folder / 'model.config').write_text(
            f'<?xml version="1.0"?><model><name>thing{k}</name><version>1.0</version>'
            '<sdf version="1.9">model.sdf</sdf></model>')
        mesh = '<mesh><uri>meshes/thing.stl</uri></mesh>'
        (folder / 'model.sdf').write_text(
            f'<?xml version="1.0"?><sdf version="1.9"><model name="thing{k}"><link name="l">'
            '<inertial><mass>1</mass><inertia><ixx>0.004</ixx><iyy>0.004</iyy><izz>0.004'
            f'</izz></inertia></inertial><collision name="c"><geometry>{mesh}</geometry>'
            f'</collision><visual name="v"><geometry>{mesh}</geometry></visual></link>'
            '</model></sdf>')
        includes.append(f'<include><uri>model://thing{k}</uri><pose>{k * 0.5} 0 0.2 0 0 0'
                        '</pose></include>')
        assets.append(f'<mesh name="thing{k}" file="{folder / "meshes" / "thing.stl"}"/>')
        bodies.append(f'<body name="thing{k}" pos="{k * 0.5} 0 0.2"><freejoint/><inertial '
                      'pos="0 0 0" mass="1" diaginertia="0.004 0.004 0.004"/><geom type="mesh" '
                      f'mesh="thing{k}"/><geom type="mesh" mesh="thing{k}" contype="0" '
                      'conaffinity="0" group="1"/></body>')
    sdf = (f'<?xml version="1.0"?><sdf version="1.9"><world name="things">'
           f'<include><uri>model://ground_plane</uri></include>{"".join(includes)}</world>'
           '</sdf>')
    mjcf = (f'<mujoco model="things"><option timestep="{STEP}"/><asset>{"".join(assets)}'
            '</asset><worldbody><geom type="plane" size="50 50 0.1"/>'
            f'{"".join(bodies)}</worldbody></mujoco>')
    return sdf, mjcf


def load_seconds(path: Path, models: str = '') -> float:
    """Return the wall time of ``World.from_file`` on an SDF world (its models' folder too)."""
    from sim_node.core.base.config import WorldConfig
    from sim_node.core.models import resources, sdf_files
    from sim_node.core.world import World
    places = sdf_files.Places.of([models] if models else [],
                                 scenes_dir=resources.installed_scenes_dir())
    t0 = time.perf_counter()
    World.from_file(str(path), WorldConfig(max_bodies=10_000), places=places)
    return time.perf_counter() - t0


def compile_seconds(mjcf: str) -> float:
    """Return MuJoCo's parse and compile of MJCF text in this process (its caches warm)."""
    t0 = time.perf_counter()
    mujoco.MjModel.from_xml_string(mjcf)
    return time.perf_counter() - t0


def cold_compile_seconds(mjcf: str, folder: Path) -> float:
    """Return bare MuJoCo's load of the MJCF as a file in a fresh process (as bench-urdf)."""
    path = folder / f'bare_{len(mjcf)}.xml'
    path.write_text(mjcf)
    return min(corpus.bare_load_seconds(path) for _ in range(3))


def bare_steps_per_second(mjcf: str, seconds: float) -> float:
    m = mujoco.MjModel.from_xml_string(mjcf)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, 200)  # settled as the node's is by now
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        mujoco.mj_step(m, d, 20)
        n += 20
    return n / (time.perf_counter() - t0)


def bench_load(top: Path) -> tuple:
    sdf, mjcf = shapes_world()
    path = top / 'shapes.sdf'
    path.write_text(sdf)
    load_seconds(path)  # imports and first-time costs out of the way
    loads, compiles = [], []
    for _ in range(3):
        loads.append(load_seconds(path))
        compiles.append(compile_seconds(mjcf))
    load, warm = min(loads), min(compiles)
    bare = cold_compile_seconds(mjcf, top)
    print(f'[sdf] {FREE + POSTS} shapes: load {load:.2f} s (best of 3; '
          f'{statistics.median(loads):.2f} median); bare MuJoCo loads the same MJCF in '
          f'{bare:.2f} s in a fresh process ({load / bare:.2f}x), {warm:.2f} s in this one '
          f'({load / warm:.2f}x)')
    verdict(load / bare <= TARGET_LOAD, f'3,000-shape SDF world loads in {load / bare:.2f}x '
            f'bare MuJoCo loading the same MJCF (target <= {TARGET_LOAD:g}x; '
            f'{load / warm:.2f}x its load in this process)')
    return path, mjcf


def bench_steps(path: Path, mjcf: str, rounds: int = 4, seconds: float = 4.0) -> None:
    node = ClockedNode(f'scene:={path}', 'real_time_factor:=0.0', 'cameras:=[none]',
                       'max_bodies:=10000')
    try:
        node.start(settle=5.0)
        ours, bare = [], []
        for _ in range(rounds):
            ours.append(node.rate(seconds) / STEP)
            bare.append(bare_steps_per_second(mjcf, seconds))
    finally:
        node.close()
    ratio = statistics.median(o / b for o, b in zip(ours, bare))
    print(f'[sdf] stepping: node {statistics.median(ours):.0f} steps/s, bare mj_step '
          f'{statistics.median(bare):.0f} steps/s (medians of {rounds} interleaved rounds of '
          f'{seconds:g} s): {ratio:.3f}x')
    verdict(ratio >= TARGET_STEPS, f'the 3,000-shape world steps at {ratio:.3f}x bare mj_step '
            f'on its MJCF (target >= {TARGET_STEPS:g}x)')


def bench_models(top: Path) -> None:
    folders = top / 'models'
    sdf, mjcf = model_folders(folders)
    path = top / 'things.sdf'
    path.write_text(sdf)
    os.environ['SIM_MESH_CACHE'] = tempfile.mkdtemp(prefix='bench_sdf_cache_')
    first = load_seconds(path, str(folders))
    again = [load_seconds(path, str(folders)) for _ in range(3)]  # as a node loads it again
    warm = min(compile_seconds(mjcf) for _ in range(3))  # MuJoCo's own mesh cache warm
    bare = cold_compile_seconds(mjcf, top)
    second = min(again)
    print(f'[sdf] {MODELS} model:// folders with a 5,120-face mesh each: first load '
          f'{first:.2f} s (cold cache), again {second:.3f} s (best of 3); bare MuJoCo loads the '
          f'same MJCF in {bare:.3f} s in a fresh process ({second / bare:.2f}x), {warm:.3f} s in '
          f'this one, its mesh cache warm ({second / warm:.2f}x)')
    verdict(second / bare <= TARGET_CACHED, f'a world of {MODELS} included models with meshes '
            f'loads a second time in {second / bare:.2f}x bare MuJoCo loading it (target <= '
            f'{TARGET_CACHED:g}x; {second / warm:.2f}x bare MuJoCo with its own mesh cache warm)')


def main() -> int:
    print(f'[sdf] {os.cpu_count()} cores; MuJoCo {mujoco.__version__}')
    top = Path(tempfile.mkdtemp(prefix='bench_sdf_'))
    path, mjcf = bench_load(top)
    bench_models(top)
    bench_steps(path, mjcf)
    summary()
    return 0


if __name__ == '__main__':
    sys.exit(main())
