"""
SDF's concave collision meshes (issue 54, item 1), on the decomposition URDF meshes have.

SDF 1.11's ``<optimization>`` and the trays, tables and shelves of a Gazebo world go through
the same decomposition as concave URDF meshes.

Gazebo collides a mesh as its triangles unless ``optimization`` says ``convex_hull`` or
``convex_decomposition`` (with at most ``<max_convex_hulls>`` parts, sdformat's default 16);
MuJoCo collides a mesh as its hull. What a user notices is where a box dropped in comes to
rest: on the tray's floor (0.05 m) or on an invisible lid at its rim (0.13 m).
"""

import concave_meshes as cm
import mujoco
import pytest
from sim_node.core.base.config import WorldConfig
from sim_node.core.models import decompose, sdf_files, world_sources
from sim_node.core.world import World

BOX = 0.06  # side of the box dropped into the tray (m)
FLOOR = cm.TRAY_FLOOR + BOX / 2  # where it rests on the floor: 0.05 m
RIM = cm.TRAY_HEIGHT + BOX / 2  # where it rests on a lid at the rim: 0.13 m


@pytest.fixture(scope='module')
def tray(tmp_path_factory):
    return str(cm.tray(tmp_path_factory.mktemp('sdf_concave') / 'tray.stl'))


@pytest.fixture(autouse=True)
def settings():
    decompose.configure()
    yield
    decompose.configure()


def mesh(uri: str, optimization: str = '', hulls: str = '') -> str:
    attr = f' optimization="{optimization}"' if optimization else ''
    most = (f'<convex_decomposition><max_convex_hulls>{hulls}</max_convex_hulls>'
            '</convex_decomposition>') if hulls else ''
    return f'<geometry><mesh{attr}>{most}<uri>{uri}</uri></mesh></geometry>'


def tray_model(uri: str, optimization: str = '', hulls: str = '', moving: bool = False) -> str:
    """Return a tray on the ground: static, or on a turntable joint (a robot's part)."""
    shape = mesh(uri, optimization, hulls)
    inertial = ('<inertial><mass>2</mass><inertia><ixx>0.02</ixx><iyy>0.02</iyy><izz>0.02</izz>'
                '</inertia></inertial>')
    tray_link = (f'<link name="tray">{inertial}<collision name="c">{shape}</collision>'
                 f'<visual name="v">{shape}</visual></link>')
    if not moving:
        return f'<model name="tray"><static>true</static>{tray_link}</model>'
    return (f'<model name="tray"><link name="base">{inertial}</link>{tray_link}'
            '<joint name="fix" type="fixed"><parent>world</parent><child>base</child></joint>'
            '<joint name="turn" type="revolute"><parent>base</parent><child>tray</child>'
            '<axis><xyz>0 0 1</xyz><limit><lower>0</lower><upper>0</upper></limit></axis>'
            '</joint></model>')


def world(models: str) -> World:
    i = 0.2 * BOX ** 2 / 6
    box = (f'<model name="box"><pose>0 0 0.2 0 0 0</pose><link name="l"><inertial><mass>0.2'
           f'</mass><inertia><ixx>{i}</ixx><iyy>{i}</iyy><izz>{i}</izz></inertia></inertial>'
           f'<collision name="c"><geometry><box><size>{BOX} {BOX} {BOX}</size></box></geometry>'
           '</collision></link></model>')
    ground = ('<model name="ground"><static>true</static><link name="l"><collision name="c">'
              '<geometry><plane><normal>0 0 1</normal></plane></geometry></collision></link>'
              '</model>')
    text = (f'<?xml version="1.0"?><sdf version="1.11"><world name="w">{ground}{models}{box}'
            '</world></sdf>')
    plan = world_sources.world_source(text, None, places=sdf_files.Places.of())
    return World.from_plan(plan, WorldConfig(), 'test')


def rest(w: World) -> float:
    w.step(int(1.5 / w.timestep))
    return float(w.read(lambda m, d: d.xpos[m.body('box').id][2]))


def colliding_tray_geoms(w: World) -> list:
    def names(m, _):
        return [m.geom(g).name for g in range(m.ngeom)
                if m.body(m.geom_bodyid[g]).name.startswith('tray')
                and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
                and (m.geom_contype[g] or m.geom_conaffinity[g])]
    return w.read(names)


def test_a_static_tray_in_a_world_holds_a_box_on_its_floor(tray):
    w = world(tray_model(tray))
    assert rest(w) == pytest.approx(FLOOR, abs=0.005)
    assert len(colliding_tray_geoms(w)) >= 5  # a floor and four walls at least


def test_convex_decomposition_on_a_moving_models_mesh_splits_it(tray):
    # A robot's link mesh is its hull unless the file asks (as for URDF robots) ...
    as_robot = world(tray_model(tray, moving=True))
    assert rest(as_robot) == pytest.approx(RIM, abs=0.01)
    assert len(colliding_tray_geoms(as_robot)) == 1
    # ... and SDF 1.11 asks by optimization="convex_decomposition".
    asked = world(tray_model(tray, 'convex_decomposition', moving=True))
    assert rest(asked) == pytest.approx(FLOOR, abs=0.005)
    assert 5 <= len(colliding_tray_geoms(asked)) <= 16  # sdformat's default bound


def test_max_convex_hulls_bounds_the_parts(tray):
    w = world(tray_model(tray, 'convex_decomposition', hulls='3', moving=True))
    assert 2 <= len(colliding_tray_geoms(w)) <= 3


def test_convex_hull_keeps_a_static_mesh_whole(tray):
    w = world(tray_model(tray, 'convex_hull'))
    assert len(colliding_tray_geoms(w)) == 1
    assert rest(w) == pytest.approx(RIM, abs=0.01)
