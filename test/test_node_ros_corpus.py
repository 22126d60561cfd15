"""
ROS robots as ROS users have them, over the wire (issue 32).

Every file of the ROS corpus (``ros_env/corpus.py``: the 69 URDFs of example-robot-data, the
xacro descriptions of rtb-data, robots of pybullet's data folder, and files written there) is
spawned by ``file://`` URI into the running default scene with the corpus folders in
resource_paths. Each shows its movable joints on joint_states and finite frames on /tf, stands
where it was spawned when its URDF joins its root to ``world`` (or it is static) and falls
otherwise, as Gazebo places it, and goes cleanly. Files no simulator can spawn get their code.
What is expected is read from the files themselves (xacro run in this process), not from the
node.
"""

import math
from pathlib import Path
import sys
import time
import xml.etree.ElementTree as ET

from conftest import serve_node, wait_for, Watcher
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
import corpus  # noqa: E402, I100

MODELS = corpus.ros_models()
MOVABLE = ('revolute', 'continuous', 'prismatic')
SPAWN_Z = 1.5


def expected(model: corpus.RosModel) -> tuple:
    """Return (movable joint names, whether the root stays where spawned) as the URDF says."""
    if model.path.suffix == '.xacro':
        import xacro  # trusted corpus files: plain xacro, here in the test
        from ament_index_python import packages

        def find(pkg):
            return str(model.root / pkg)
        old = packages.get_package_share_directory
        packages.get_package_share_directory = find
        try:
            root = ET.fromstring(xacro.process_file(str(model.path)).toxml())
        finally:
            packages.get_package_share_directory = old
    else:
        root = ET.parse(model.path).getroot()
    joints = [j.get('name') for j in root.findall('joint') if j.get('type') in MOVABLE]
    # Joined to `world` (fixed, or by a joint that turns or slides): anchored where spawned.
    to_world = any(j.get('type') != 'floating' and j.find('parent').get('link') == 'world'
                   for j in root.findall('joint'))
    static = any((g.findtext('static') or '').strip() == 'true' for g in root.findall('gazebo'))
    return joints, to_world or static


@pytest.fixture(scope='module')
def node():
    roots = ','.join(f'"{r}"' for r in corpus.ros_roots())
    yield from serve_node(f'resource_paths:=[{roots}]', 'real_time_factor:=0.0',
                          'cameras:=[none]')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


def sim_seconds_later(watch, seconds: float) -> None:
    t0 = wait_for(watch.latest_clock, timeout=10)
    wait_for(lambda: (watch.latest_clock() or 0) > t0 + seconds, timeout=60)


@pytest.mark.parametrize('model', MODELS, ids=[f'{m.package}:{m.name}' for m in MODELS])
def test_every_ros_corpus_file_spawns_stands_or_falls_and_goes(node, watch, sim, model):
    from sim_node.ros.client import SimServiceError
    if model.refused:
        with pytest.raises(SimServiceError) as err:
            sim.spawn('refused', uri=model.uri, position=(4.0, 4.0, 1.5))
        assert err.value.code == model.refused, err.value.message
        return
    joints, stays = expected(model)
    name = sim.spawn('robot_' + model.name.replace('-', '_'), uri=model.uri,
                     position=(4.0, 4.0, SPAWN_Z))
    try:
        z0 = sim.entity_state(name)['position'][2]

        def joints_listed():
            js = watch.joint_states
            return js is not None and {f'{name}/{j}' for j in joints} <= set(js.name)
        try:
            wait_for(joints_listed, timeout=15)
        except AssertionError:
            raise AssertionError(f'{name} joints not on joint_states: {watch.report()}') \
                from None

        def own_frames():
            with watch.lock:
                return {f: e for f, e in {**watch.tf, **watch.tf_static}.items()
                        if f == name or f.startswith(name + '/')}
        wait_for(lambda: name in own_frames(), timeout=15)
        sim_seconds_later(watch, 1.5)
        for frame, (_, _, xyz, q) in own_frames().items():
            assert all(math.isfinite(v) for v in xyz + q), frame
        # Every link of its robot_description has a frame (RViz's RobotModel needs them all).
        assert watch.links_without_frames(name) == []
        z1 = sim.entity_state(name)['position'][2]
        if stays:
            assert z1 == pytest.approx(z0, abs=1e-6), 'its URDF fixes it where it is spawned'
        else:  # (at real_time_factor 0 it may have landed before z0 was read)
            assert z1 < SPAWN_Z - 0.3, 'it floats: it falls, as in Gazebo'
    finally:
        sim.delete(name)
    assert name not in sim.entities()


def test_the_corpus_covers_what_the_issue_names():
    """Collada visuals, Gazebo tags, transmissions, mimic joints, package:// and xacro."""
    text = '\n'.join(m.path.read_text(errors='replace') for m in MODELS)
    for what in ('.dae"', '<gazebo', '<transmission', '<mimic', 'package://', 'xacro:arg'):
        assert what in text, what
    assert time  # (used by helpers in other corpus tests)


def test_the_fast_collada_reader_reads_every_corpus_mesh_as_trimesh_does():
    """Every Collada file of the corpus: the same triangles, or handed on to trimesh."""
    import io
    import numpy as np
    import trimesh
    from sim_node.core.models import meshes
    sys.path.insert(0, str(Path(meshes.__file__).parent))
    import collada_fast  # noqa: I100 (the worker's own module, imported as the worker does)
    files = sorted({p for m in MODELS for p in m.root.rglob('*') if p.suffix.lower() == '.dae'})
    assert len(files) > 250
    read_here = 0
    for path in files:
        data = path.read_bytes()
        try:
            vertices, faces, _ = collada_fast.read(data)
        except collada_fast.Unsupported:
            continue
        read_here += 1
        theirs = trimesh.load(io.BytesIO(data), file_type='dae', force='scene', process=False)
        if not theirs.geometry:
            continue  # pycollada drops a node with a broken material; the worker then strips
        mesh = theirs.to_mesh()  # the materials and reads it again
        ours = np.sort(vertices[faces].reshape(-1, 3).round(6), axis=0)
        assert np.allclose(ours, np.sort(mesh.vertices[mesh.faces].reshape(-1, 3).round(6),
                                         axis=0), atol=1e-5), path.name
    assert read_here >= 0.9 * len(files)
