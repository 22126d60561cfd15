"""
The node gives memory back: its RSS after reset cycles, a spawn/delete storm, refused requests.

And the process settings that make it so (:mod:`sim_node.ros.node.middleware`) yield to the
user's own.
"""

import os
from pathlib import Path
import sys
import threading
import time

from conftest import DEFAULT_SCENE
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'benchmarks'))

#: How long after the last request the node has had to give freed memory back (the node
#: trims every TRIM_PERIOD_SEC).
SETTLE_SEC = 3.0


def rss_mib(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS'):
            return int(line.split()[1]) / 1024
    raise RuntimeError('no VmRSS')


@pytest.fixture
def warm(start_node, rclpy_context, tmp_path):
    """
    Return (node, client, RSS in MiB) once every path below has run once; tmp_path readable.

    A deleted robot's meshes are kept a second here (``mesh_cache_keep_sec``; 120 s by
    default): after that the robot is gone for good and its memory must come back.
    """
    from sim_node.ros.client import SimClient
    node = start_node(f'resource_paths:=["{tmp_path}"]', 'mesh_cache_keep_sec:=1.0')
    client = SimClient(timeout_sec=60)
    try:
        client.entities()
        for _ in range(3):
            client.spawn('warm', uri='box', position=(1, 1, 1))
            client.delete('warm')
            client.reset()
        time.sleep(SETTLE_SEC)
        yield node, client, rss_mib(node.proc.pid)
    finally:
        client.close()


def grown(node, before: float) -> float:
    time.sleep(SETTLE_SEC)
    return rss_mib(node.proc.pid) - before


def test_reset_cycles_leave_at_most_20_mib(warm):
    node, client, before = warm
    for _ in range(200):
        client.reset()
    for k in range(20):
        client.spawn(f'cycle{k}', uri='box', position=(1, 1, 1))
        client.delete(f'cycle{k}')
        client.reset()
    assert grown(node, before) <= 20.0


def test_refused_large_requests_leave_at_most_20_mib(warm):
    """A 50 MB resource string and six 10 MB names, each refused: their memory comes back."""
    from sim_node.ros.client import SimServiceError
    node, client, before = warm
    with pytest.raises(SimServiceError):
        client.spawn('big', resource_string='<mujoco>' + 'x' * 50_000_000 + '</mujoco>')
    for k in range(6):
        with pytest.raises(SimServiceError):
            client.spawn('n' * 10_000_000 + str(k), uri='box', position=(0, 0, 3))
    assert client.entities()  # and the node still answers
    assert grown(node, before) <= 20.0


def test_xacro_bombs_are_refused_at_their_limits_and_leave_at_most_50_mib(warm):
    """A macro bomb (time) and a property bomb (memory) over the wire: each named limit."""
    from simulation_interfaces.srv import SpawnEntity
    from sim_node.core.models import xacro_files
    from sim_node.ros.client import SimServiceError
    from test_core_urdf import MACRO_BOMB, PROPERTY_BOMB
    from sim_node.ros.client import SimClient
    node, client, before = warm
    # A client that waits three times the limit hears the refusal (before: no answer in 15 s)
    patient = SimClient(timeout_sec=3 * xacro_files.TIMEOUT_SEC)
    head = '<robot name="bomb" xmlns:xacro="http://www.ros.org/wiki/xacro">'
    # Which limit a bomb meets first depends on the CPU it gets: on a loaded machine the macro
    # bomb was killed at its CPU-time limit before the wall clock's, and the property bomb met
    # the wall clock before its memory limit (CI runs, twice). Each is refused by a named limit.
    limits = (f'took longer than {xacro_files.TIMEOUT_SEC:g} s',
              f'({xacro_files.MEMORY_BYTES >> 20} MiB', 'of CPU time')
    for body in (MACRO_BOMB, PROPERTY_BOMB):
        with pytest.raises(SimServiceError) as err:
            patient.spawn('bomb', resource_string=head + body + '</robot>')
        assert err.value.code == SpawnEntity.Response.RESOURCE_PARSE_ERROR, err.value.message
        assert any(says in err.value.message for says in limits), err.value.message
    patient.close()
    assert client.entities()  # and the node still answers
    assert grown(node, before) <= 50.0


def test_a_run_of_large_and_malformed_meshes_leaves_at_most_20_mib(warm, tmp_path):
    """
    Spawn and delete large meshes and spawn malformed ones: the memory comes back.

    ``make bench-meshes``' files over the wire: a 250k-face STL and a 259k-face Collada dome
    spawned (decimated) and deleted, seven malformed meshes refused. Before: +214 MiB; then,
    with a heap per thread, +30 to +55 MiB (a CI run failed at 50); with one heap for all
    (:func:`sim_node.core.base.memory.share_one_heap`), -4 to +11 MiB.
    """
    import mesh_limits as bench
    from sim_node.ros.client import SimServiceError
    node, client, before = warm
    for name, path in bench.large_files(tmp_path).items():
        client.spawn(name, uri=path.as_uri(), position=(4, 4, 2))
        client.delete(name)
    for name, path in bench.malformed_files(tmp_path).items():
        with pytest.raises(SimServiceError):
            client.spawn(name, uri=path.as_uri(), position=(4, 4, 2))
    assert client.entities()  # and the node still answers
    assert grown(node, before) <= 20.0


def test_diagnostics_show_the_mesh_cache_and_what_a_deleted_robot_keeps_in_it(start_node,
                                                                              rclpy_context,
                                                                              tmp_path):
    """
    The cache's size and a deleted robot's kept meshes are on /diagnostics, then gone.

    Its own node keeps a deleted robot's meshes 5 s: /diagnostics goes out once a second, so a
    keep as short as the `warm` node's (1 s) can fall between two reports (it did, in CI).
    """
    import mesh_limits as bench
    from conftest import wait_for
    from sim_node.ros.client import SimClient
    from test_node_conventions import DiagnosticsWatcher
    start_node(f'resource_paths:=["{tmp_path}"]', 'mesh_cache_keep_sec:=5.0')
    client = SimClient(timeout_sec=60)
    watch = DiagnosticsWatcher()
    try:
        path = next(iter(bench.large_files(tmp_path).values()))
        client.spawn('kept', uri=path.as_uri(), position=(4, 4, 2))
        wait_for(lambda: watch.latest and float(watch.latest[2]['mesh_cache_mib']) > 1.0,
                 timeout=10)
        client.delete('kept')
        wait_for(lambda: float(watch.latest[2]['mesh_cache_kept_mib']) > 1.0, timeout=10)
        # five seconds later (this node's mesh_cache_keep_sec) it is gone for good
        wait_for(lambda: float(watch.latest[2]['mesh_cache_kept_mib']) == 0.0, timeout=15)
    finally:
        watch.close()
        client.close()


@pytest.mark.parametrize('given', [{}, {'FASTRTPS_DEFAULT_PROFILES_FILE': '/theirs.xml'},
                                   {'RMW_FASTRTPS_USE_QOS_FROM_XML': '0'},
                                   {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}])
def test_the_node_loads_its_fast_dds_profiles_only_where_the_user_set_none(given, monkeypatch):
    from sim_node.ros.node import middleware
    for key in ('FASTRTPS_DEFAULT_PROFILES_FILE', 'RMW_FASTRTPS_USE_QOS_FROM_XML',
                'RMW_IMPLEMENTATION'):
        monkeypatch.delenv(key, raising=False)
    for key, value in given.items():
        monkeypatch.setenv(key, value)
    middleware.configure()
    if given:
        assert all(os.environ[k] == v for k, v in given.items())
        assert os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE') != str(middleware.PROFILES)
    else:
        assert os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(middleware.PROFILES)
        assert os.environ['RMW_FASTRTPS_USE_QOS_FROM_XML'] == '1'
        assert middleware.PROFILES.is_file()


_HEAPS = """
import ctypes, os, sys, tempfile, threading
from sim_node.ros.node import entry
heavy = sorted({'numpy', 'mujoco', 'rclpy'} & set(sys.modules))
chose = entry.memory.share_one_heap()
import numpy
def work():
    for _ in range(300):
        [numpy.zeros(1000) for _ in range(50)]
threads = [threading.Thread(target=work) for _ in range(4)]
[t.start() for t in threads]
[t.join() for t in threads]
libc = ctypes.CDLL('libc.so.6')
libc.fopen.restype = ctypes.c_void_p
path = os.path.join(tempfile.mkdtemp(), 'heaps.xml')
out = libc.fopen(path.encode(), b'w')
libc.malloc_info(0, ctypes.c_void_p(out))
libc.fclose(ctypes.c_void_p(out))
print(heavy, chose, open(path).read().count('<heap nr='))
"""


@pytest.mark.parametrize('user', ['', 'MALLOC_ARENA_MAX=4',
                                  'GLIBC_TUNABLES=glibc.malloc.arena_max=4'])
def test_the_node_entry_shares_one_heap_among_threads_unless_the_user_chose(user):
    # Each thread's heap kept what it freed: a large mesh's spawn and delete left the node
    # 30-55 MiB larger. glibc fixes the number of heaps when a second thread first allocates,
    # and importing numpy, MuJoCo or rclpy starts such threads: the entry imports none.
    import subprocess
    import sys
    env = {k: v for k, v in os.environ.items()
           if k not in ('MALLOC_ARENA_MAX', 'GLIBC_TUNABLES')}
    if user:
        key, value = user.split('=', 1)
        env[key] = value
    out = subprocess.run([sys.executable, '-c', _HEAPS], check=True, capture_output=True,
                         text=True, timeout=120, env=env).stdout.split()
    heavy, chose, heaps = out[0], out[1], int(out[2])
    assert heavy == '[]', f'the entry imported {heavy}: threads may have made heaps already'
    if user:
        assert (chose, heaps > 1) == ('False', True)  # theirs: four
    else:
        assert (chose, heaps) == ('True', 1)


_FAULTS_PER_COPY = """
import resource, sys
import mujoco
from sim_node.core.base import memory
if sys.argv[1] == 'node':
    memory.keep_large_blocks_mapped()
spec = mujoco.MjSpec.from_file(sys.argv[2])
model = spec.copy().compile()
sky = spec.textures[0]  # baked to its pixels, as a world holds it (1.2 MB)
w, h, n = (int(model.tex_width[0]), int(model.tex_height[0]), int(model.tex_nchannel[0]))
sky.builtin = mujoco.mjtBuiltin.mjBUILTIN_NONE
sky.width, sky.height, sky.nchannel = w, h, n
sky.data = model.tex_data[:w * h * n].tobytes()
for _ in range(5):
    spec.copy()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(50):
    spec.copy()  # every edit copies the world's spec, and frees the copy
print((resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 50)
"""


@pytest.mark.parametrize('settings', ['glibc', 'node'])
def test_copying_the_default_worlds_spec_faults_no_page_in_with_the_nodes_heap_settings(
        settings):
    # The node fixes glibc's thresholds (large blocks mapped apart, so that freed ones go
    # back). Fixed too low, each copy of the sky texture (every edit makes two) was a fresh
    # mapping, 289 pages faulted in one by one: 0.9 ms a copy instead of 0.06.
    import subprocess
    import sys
    out = subprocess.run([sys.executable, '-c', _FAULTS_PER_COPY, settings, str(DEFAULT_SCENE)],
                         check=True, capture_output=True, text=True, timeout=120)
    assert float(out.stdout.split()[-1]) < 10, f'page faults per copy: {out.stdout}'


_TRACKED = """
import gc, sys
from sim_node.ros.node import node  # noqa: F401 (everything the node imports)
from sim_node.core.base import memory
from sim_node.core.world import World
world = World.from_file(sys.argv[1])
before = len(gc.get_objects())
memory.freeze_long_lived()
print(before, len(gc.get_objects()))
"""


def test_after_start_up_a_full_garbage_collection_walks_only_what_came_later():
    # A full collection walks every object Python tracks, with the GIL held: one of the
    # node's 72,000 objects took 42 ms during a spawn, and /clock stood still for 47 ms.
    import subprocess
    import sys
    out = subprocess.run([sys.executable, '-c', _TRACKED, str(DEFAULT_SCENE)], check=True,
                         capture_output=True, text=True, timeout=120)
    before, after = (int(n) for n in out.stdout.split()[-2:])
    assert before > 20_000 and after < 2_000, out.stdout


def test_a_storm_of_eight_spawning_and_deleting_clients_leaves_at_most_50_mib(warm):
    from sim_node.ros.client import SimClient
    node, client, before = warm
    failures = []

    def storm(k: int) -> None:
        c = SimClient(timeout_sec=60)
        try:
            for j in range(50):
                c.spawn(f's{k}_{j}', uri='box', position=(4 + 0.3 * k, -4 + 0.2 * j, 0.3))
            for j in range(50):
                c.delete(f's{k}_{j}')
        except Exception as exc:  # noqa: B902 (reported below)
            failures.append(repr(exc))
        finally:
            c.close()
    threads = [threading.Thread(target=storm, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(180)
    assert not failures, failures[:3]
    client.reset()
    assert not [n for n in client.entities() if n[0] == 's' and n[1].isdigit()]
    assert grown(node, before) <= 50.0
