"""
Concave collision meshes collide as the meshes they are, as Gazebo collides them.

A tray, a table and a ring, each one STL (test/concave_meshes.py), spawned by URI and as a URDF
model's collision: a box dropped into the tray rests on its floor, not on an invisible lid at
its rim; a box fits under the table's top; a peg goes through the ring. Decomposed once and
cached (in this process, on disk for the next); bounded; off when asked; bad meshes answered.
Real MuJoCo, real CoACD in its child process.
"""

import logging
import os
from pathlib import Path
import subprocess
import sys

import concave_meshes as cm
from conftest import SCENES
import mujoco
import numpy as np
import pytest
from sim_node.core.base.config import WorldConfig
from sim_node.core.base.errors import InvalidArgumentError, ResourceParseError
from sim_node.core.models import decompose, sources, world_sources
from sim_node.core.world import World

BOX = 0.06  # side of the box dropped into the tray (m)


@pytest.fixture(scope='module')
def meshes(tmp_path_factory):
    folder = tmp_path_factory.mktemp('concave')
    return {name: str(getattr(cm, name)(folder / f'{name}.stl'))
            for name in ('tray', 'table', 'ring')}


@pytest.fixture
def world():
    decompose.configure()
    w = World.from_file(str(SCENES / 'empty.xml'))
    yield w
    decompose.configure()


def urdf(mesh: str, name: str = 'thing') -> str:
    return f"""<robot name="{name}"><link name="{name}">
      <inertial><mass value="2"/><inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0"
        iyz="0"/></inertial>
      <visual><geometry><mesh filename="{mesh}"/></geometry></visual>
      <collision><geometry><mesh filename="{mesh}"/></geometry></collision></link>
      <gazebo><static>true</static></gazebo></robot>"""


def box_source(side: float = BOX, mass: float = 0.2):
    return sources.primitive('box', [side / 2] * 3, mass=mass)


def rest_height(w: World, name: str, seconds: float = 1.5) -> float:
    w.step(int(seconds / w.timestep))
    return float(w.get_entity_state(name).position[2])


def colliding_parts(w: World, entity: str) -> list:
    with w.locked() as (m, _):
        return [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m.ngeom)
                if (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or '').startswith(
                    f'{entity}/') and (m.geom_contype[g] or m.geom_conaffinity[g])]


@pytest.mark.parametrize('how', ['uri', 'urdf'])
def test_a_box_dropped_into_a_tray_rests_on_its_floor(world, meshes, how):
    tray = (sources.from_mesh(meshes['tray'], static=True) if how == 'uri'
            else sources.from_model_text(urdf(meshes['tray'], 'tray')))
    world.spawn('tray', tray)
    world.spawn('box', box_source(), position=(0.0, 0.0, 0.2))
    z = rest_height(world, 'box')
    floor = cm.TRAY_FLOOR + BOX / 2  # 0.05 m; on a lid at the rim it would be 0.13 m
    assert z == pytest.approx(floor, abs=0.005), (z, floor)
    assert len(colliding_parts(world, 'tray')) >= 5  # a floor and four walls at least


def test_a_box_fits_under_a_table_and_rests_on_its_top(world, meshes):
    world.spawn('table', sources.from_mesh(meshes['table'], static=True))
    # Under the top, between the legs: as a hull, this overlapped the table by 0.1 m and more.
    world.spawn('under', box_source(0.2), position=(0.0, 0.0, 0.3))
    world.spawn('on', box_source(), position=(0.2, 0.1, 0.9))
    top = cm.TABLE_UNDER + cm.TABLE_THICK
    assert rest_height(world, 'on') == pytest.approx(top + BOX / 2, abs=0.005)
    assert world.get_entity_state('under').position[2] == pytest.approx(0.1, abs=0.005)
    assert len(colliding_parts(world, 'table')) == 5  # its top and legs, each its own hull


def test_a_peg_falls_through_a_ring(world, meshes):
    world.spawn('ring', sources.from_mesh(meshes['ring'], static=True))
    peg = sources.primitive('cylinder', [0.04, 0.1], mass=0.1)
    world.spawn('peg', peg, position=(0.0, 0.0, 0.3))
    assert rest_height(world, 'peg') < 0.11  # through the hole, on the floor (0.1 m)


def test_the_mass_and_inertia_stay_those_of_the_mesh(meshes):
    def inertia(mode):
        decompose.configure(mode)
        m = sources.from_mesh(meshes['tray'], mass=2.0).spec.compile()
        return m.body_mass[1], m.body_inertia[1].copy(), m.body_ipos[1].copy(), m.ngeom
    try:
        hull, split = inertia('none'), inertia('objects')
    finally:
        decompose.configure()
    assert split[3] > hull[3] == 1
    assert split[0] == hull[0] == 2.0
    np.testing.assert_allclose(split[1], hull[1], rtol=1e-9)
    np.testing.assert_allclose(split[2], hull[2], atol=1e-12)


def test_a_mesh_is_decomposed_once_then_read_from_the_cache(world, meshes):
    sources.from_mesh(meshes['tray'], static=True)
    before = decompose.runs()
    sources.from_mesh(meshes['tray'], static=True)
    sources.from_model_text(urdf(meshes['tray']))
    assert decompose.runs() == before  # this process kept it
    code = ('from sim_node.core.models import decompose, sources; '
            f'sources.from_mesh({meshes["tray"]!r}, static=True); print(decompose.runs())')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         env=os.environ, timeout=120)
    assert out.stdout.strip() == '0', out.stderr[-2000:]  # the next process read the disk


@pytest.mark.parametrize('noise', [0.0, 1e-4])
def test_a_patch_of_a_convex_surface_stays_whole_at_once(world, tmp_path, caplog, noise):
    # A ragged 40% of a sphere fills 0.6 of its hull, measured from its opening: a 250,000-face
    # one went to CoACD and spent its 30 s budget, then collided as its hull all the same. Its
    # every vertex is on its hull: its hull stands for it, as for a dome. Exact, every shared
    # edge folds outwards; moved by noise (as a decimation's rounding moves them) some fold in.
    path = cm.patch(tmp_path / 'patch.stl', subdivisions=6, share=0.4, noise=noise)  # 32,768
    with caplog.at_level(logging.INFO, logger=decompose.__name__):
        world.spawn('patch', sources.from_mesh(str(path), static=True))
    assert colliding_parts(world, 'patch') and \
        not any('_part' in g for g in colliding_parts(world, 'patch'))
    assert 'collides as' not in caplog.text and 'could not be decomposed' not in caplog.text


def test_a_dented_patch_is_not_taken_for_a_convex_one(tmp_path, monkeypatch, caplog):
    # Its dent is below its neighbours' reach: it goes on to CoACD (which takes an open surface
    # past any short budget: 30 s for this one here; the budget is 5 s, and the warning says it
    # was tried). A machine fast enough to finish within it gives parts: tried all the same.
    path = cm.patch(tmp_path / 'dented.stl', subdivisions=4, share=0.4, dent=0.2)
    decompose.forget()
    monkeypatch.setattr(decompose, 'SECONDS', 5.0)
    with caplog.at_level(logging.WARNING, logger='sim_node'):
        model = sources.from_mesh(str(path), static=True).spec.compile()
    parts = [model.geom(g).name for g in range(model.ngeom) if '_part' in model.geom(g).name]
    assert parts or 'dented.stl could not be decomposed' in caplog.text, caplog.text


def test_off_keeps_the_hull_and_the_threshold_reaches_coacd(meshes):
    try:
        decompose.configure('none')
        assert sources.from_mesh(meshes['tray']).spec.compile().ngeom == 1
        counts = []
        for threshold in (0.2, 0.02):
            decompose.configure('objects', threshold)
            counts.append(sources.from_mesh(meshes['tray']).spec.compile().ngeom - 1)
    finally:
        decompose.configure()
    assert 1 < counts[0] < counts[1], counts
    with pytest.raises(InvalidArgumentError, match='mesh_decomposition'):
        decompose.configure('sometimes')
    with pytest.raises(InvalidArgumentError, match='threshold'):
        decompose.configure('objects', 0.0)


def test_a_robot_keeps_its_links_as_hulls_unless_all(meshes):
    robot = f"""<robot name="arm"><link name="base"/><link name="cup">
      <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0"
        iyz="0"/></inertial>
      <collision><geometry><mesh filename="{meshes['tray']}"/></geometry></collision></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="cup"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      </robot>"""
    try:
        decompose.configure('objects')
        as_robot = sources.from_model_text(robot).spec.compile().ngeom
        decompose.configure('all')
        everything = sources.from_model_text(robot).spec.compile().ngeom
    finally:
        decompose.configure()
    assert as_robot == 1 and everything > 5, (as_robot, everything)


def test_parts_report_the_collision_name_gazebo_gives(world, meshes):
    source = sources.from_model_text(urdf(meshes['tray'], 'tray'))
    names = source.urdf_notes.collisions
    parts = [g for g in names if '_part' in g]
    assert parts and {names[g] for g in parts} == {'tray_collision'}


@pytest.mark.parametrize('budget, value, cells', [('SECONDS', 0.2, 3),
                                                  ('MEMORY_BYTES', 64 << 20, 4)])
def test_a_mesh_past_its_budget_collides_as_its_hull_with_a_warning(budget, value, cells,
                                                                    tmp_path, monkeypatch,
                                                                    caplog):
    # Wall and CPU time, or memory (less than the child's libraries hold). Each a tray of its
    # own: a failure is kept by this process (not on disk, where the next node would see it).
    tray = str(cm.tray(tmp_path / f'{budget}_tray.stl', cells=cells))
    decompose.forget()
    monkeypatch.setattr(decompose, budget, value)
    with caplog.at_level(logging.WARNING, logger='sim_node'):
        m = sources.from_mesh(tray).spec.compile()
    assert m.ngeom == 1 and m.geom_contype[0] == 1
    assert any(f'{budget}_tray.stl' in r.getMessage() and 'hull' in r.getMessage()
               for r in caplog.records), [r.getMessage() for r in caplog.records]
    monkeypatch.undo()  # its budget back, in a new process (forget: as one): decomposed now
    decompose.forget()
    assert sources.from_mesh(tray).spec.compile().ngeom > 5


def test_bad_meshes_are_answered_and_the_world_keeps_stepping(world, tmp_path, caplog):
    rng = np.random.default_rng(0)
    soup = cm.write_stl(tmp_path / 'soup.stl', rng.uniform(-0.2, 0.2, (300, 3, 3)))
    plate = cm.write_stl(tmp_path / 'plate.stl', cm.box((0.3, 0.3, 0.0), (0, 0, 0)))
    # Two boxes crossing each other in one shell's worth of faces: self-intersecting.
    crossing = cm.write_stl(tmp_path / 'crossing.stl', np.concatenate([
        cm.box((0.4, 0.05, 0.05), (0, 0, 0.1)), cm.box((0.05, 0.4, 0.05), (0, 0, 0.1))]))
    # A fan of triangles on one edge: non-manifold (an edge of four faces), no inside.
    fan = cm.write_stl(tmp_path / 'fan.stl', np.array(
        [[(0, 0, 0), (0, 0, 0.2), (0.2 * np.cos(a), 0.2 * np.sin(a), 0.1)]
         for a in np.linspace(0, 3, 4)]))
    with caplog.at_level(logging.WARNING, logger='sim_node'):
        for i, path in enumerate((soup, crossing, fan)):
            world.spawn(f'bad{i}', sources.from_mesh(str(path), static=True),
                        position=(2.0 * i, 3.0, 0.5))
        with pytest.raises(ResourceParseError, match='coplanar'):  # MuJoCo's own answer
            sources.from_mesh(str(plate), static=True)
    warned = ' '.join(r.getMessage() for r in caplog.records)
    assert 'soup.stl' in warned and 'separate shells' in warned  # 300 triangles: its hull
    assert 'plate.stl' not in warned  # flat: nothing to decompose
    assert len(colliding_parts(world, 'bad1')) == 2  # the crossing bars, each its hull
    t = world.time
    world.step(100)
    assert world.time > t and np.isfinite(world.get_entity_state('bad0').position).all()


def test_mjcf_meshes_a_model_marks_are_decomposed(meshes):
    text = f"""<mujoco><asset><mesh name="tray" file="{meshes['tray']}"/>
      <mesh name="other" file="{meshes['ring']}"/></asset>
      <custom><text name="decompose_meshes" data="tray"/></custom>
      <worldbody><body name="t"><geom type="mesh" mesh="tray"/></body>
      <body name="r" pos="1 0 0"><geom type="mesh" mesh="other"/></body></worldbody></mujoco>"""
    m = sources.from_model_text(text).spec.compile()
    assert m.ngeom > 6  # the tray's parts (and itself), the ring as it is
    bad = text.replace('data="tray"', 'data="tray shelf"')
    with pytest.raises(ResourceParseError, match='shelf'):
        sources.from_model_text(bad)


def test_a_world_loaded_with_marked_meshes_gets_their_parts(meshes, tmp_path):
    text = f"""<mujoco><asset><mesh name="tray" file="{meshes['tray']}"/></asset>
      <custom><text name="decompose_meshes" data="tray"/></custom>
      <worldbody><geom type="plane" size="5 5 0.1"/>
        <body name="t"><geom type="mesh" mesh="tray"/></body></worldbody></mujoco>"""
    spec, _ = world_sources.world_spec(text)  # what load_world reads, then makes a World of
    loaded = World(spec)
    with loaded.locked() as (m, _):
        assert m.ngeom > 6
    # And the scene parameter (World.from_file): its mesh found through meshdir, turned.
    (tmp_path / 'meshes').mkdir()
    (tmp_path / 'meshes' / 'tray.stl').write_bytes(Path(meshes['tray']).read_bytes())
    scene = tmp_path / 'scene.xml'
    scene.write_text(text.replace(meshes['tray'], 'tray.stl').replace(
        '<asset>', '<compiler meshdir="meshes"/><asset>').replace(
        '<body name="t">', '<body name="t" pos="0 0 0.5">').replace(
        'mesh="tray"/>', 'mesh="tray" euler="0 0 90"/>'))
    w = World.from_file(str(scene))
    # Turned a quarter (its inside 0.36 m along y now), on a 0.5 m stand: a box beside the
    # middle along y rests on its floor (unturned, the tray's wall would be under it).
    w.spawn('box', box_source(), position=(0.0, 0.14, 0.8))
    assert rest_height(w, 'box') == pytest.approx(0.5 + cm.TRAY_FLOOR + BOX / 2, abs=0.005)


def hull_vertices(w: World, entity: str) -> list:
    """Return the vertex count of each of an entity's mesh hulls, as MuJoCo compiled them."""
    with w.locked() as (m, _):
        return [int(m.mesh_graph[m.mesh_graphadr[i]]) for i in range(m.nmesh)
                if (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_MESH, i) or '').startswith(
                    f'{entity}/') and m.mesh_graphadr[i] >= 0]


def test_a_finely_cut_sphere_collides_on_a_bounded_hull_and_rests_on_its_radius(
        world, tmp_path):
    # Every vertex of a sphere is on its hull: MuJoCo built all 40,962 into it (the compile
    # time of a 200k-face sphere: 1.8 s, 0.6 s bounded). Bounded, it still rests on its radius.
    decompose.configure('none')
    path = cm.sphere(tmp_path / 'ball.stl', radius=0.1, subdivisions=6)
    world.spawn('ball', sources.from_mesh(str(path), mass=1.0), position=(0, 0, 0.3))
    hulls = hull_vertices(world, 'ball')
    assert hulls and max(hulls) <= decompose.HULL_VERTICES, hulls
    assert rest_height(world, 'ball', 1.0) == pytest.approx(0.1, abs=5e-4)


def test_a_hull_bound_the_file_sets_is_its_own(world, tmp_path):
    cm.sphere(tmp_path / 'ball.stl', radius=0.1, subdivisions=4)
    text = f"""<mujoco><asset><mesh name="ball" file="{tmp_path / 'ball.stl'}" maxhullvert="32"/>
      </asset><worldbody><body name="ball"><freejoint/><geom type="mesh" mesh="ball"/></body>
      </worldbody></mujoco>"""
    world.spawn('ball', sources.from_model_text(text, str(tmp_path)), position=(0, 0, 0.3))
    assert 4 <= max(hull_vertices(world, 'ball')) <= 32


def test_the_parameter_reaches_the_world():
    World.from_file(str(SCENES / 'empty.xml'), WorldConfig(mesh_decomposition='none'))
    try:
        assert decompose.mode() == 'none'
    finally:
        decompose.configure()


def test_the_disk_cache_keeps_its_bound_the_least_recently_used_out(meshes, tmp_path,
                                                                    monkeypatch):
    monkeypatch.setenv('SIM_MESH_CACHE', str(tmp_path / 'cache'))
    decompose.forget()
    ring = str(cm.ring(tmp_path / 'small_ring.stl', segments=24))
    sources.from_mesh(meshes['tray'])
    sources.from_mesh(ring)
    root = tmp_path / 'cache' / 'decomposed'
    entries = sorted(root.iterdir(), key=lambda d: d.stat().st_mtime)
    assert len(entries) == 2
    newest = sum(f.stat().st_size for f in entries[-1].iterdir())
    decompose.prune(root, limit=newest)
    assert [d.name for d in root.iterdir()] == [entries[-1].name]
    # The pruned mesh spawns again in this process: its parts made anew, not the files gone
    # (MuJoCo could not open them: the spawn failed).
    model = sources.from_mesh(meshes['tray']).spec.compile()
    assert sum('_part' in model.geom(g).name for g in range(model.ngeom)) >= 5


def test_a_million_face_tray_is_decimated_then_decomposed_and_named(world, tmp_path, caplog):
    tray = cm.tray(tmp_path / 'scanned_tray.stl', cells=500)  # 1,004,004 faces, 50 MB
    with caplog.at_level(logging.INFO, logger='sim_node'):
        world.spawn('scanned', sources.from_mesh(str(tray), static=True))
    said = ' '.join(r.getMessage() for r in caplog.records)
    assert 'scanned_tray.stl' in said and 'decimated' in said and 'convex parts' in said
    world.spawn('box', box_source(), position=(0.0, 0.0, 0.2))
    assert rest_height(world, 'box') == pytest.approx(cm.TRAY_FLOOR + BOX / 2, abs=0.005)
