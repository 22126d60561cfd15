"""
SDF files nobody here wrote (issue 54), from the package index.

The corpus of ros_env/corpus.py: pybullet's, drake's and gym-ignition's (licences in
test/sdf/README.md).

Each world loads and each model spawns, with as many bodies as the file has links and as many
degrees of freedom as its joints give, and steps with a finite state; the two files no
simulator can load as they are are refused with the right error; what the files say of their
joints (types, limits) is what the world has.
"""

from pathlib import Path
import sys
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
from sim_node.core import errors
from sim_node.core.base.config import WorldConfig
from sim_node.core.models import sdf_files, sources
from sim_node.core.world import World

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
import corpus  # noqa: E402, I100

EMPTY = Path(__file__).resolve().parent.parent / 'scenes' / 'empty.xml'
#: Degrees of freedom of each SDF joint type (MuJoCo's joints for it).
DOFS = {'revolute': 1, 'continuous': 1, 'prismatic': 1, 'ball': 3, 'universal': 2,
        'revolute2': 2, 'screw': 2, 'gearbox': 1, 'fixed': 0}
FILES = corpus.sdf_models()


def places() -> sdf_files.Places:
    return sdf_files.Places.of(environ={'GZ_SIM_RESOURCE_PATH': str(corpus.gym_models())})


def expected(path: Path) -> tuple:
    """Return (links, degrees of freedom) of the file's models, by reading it as XML."""
    root = ET.parse(path).getroot()
    links = [e for e in root.iter('link') if e.get('name') != 'world'
             or e.find('collision') is not None or e.find('visual') is not None]
    dofs = 0
    for model in root.iter('model'):
        static = (model.findtext('static') or '').strip() in ('1', 'true')
        own = model.findall('joint')
        children = {(j.findtext('child') or '').strip() for j in own}
        dofs += 0 if static else sum(DOFS[j.get('type')] for j in own)
        names = [e.get('name') for e in model.findall('link')]
        roots = [n for n in names if n not in children and n != 'world']
        held = {(j.findtext('child') or '').strip() for j in own
                if (j.findtext('parent') or '').strip() == 'world'}
        dofs += 0 if static else 6 * len([r for r in roots if r not in held])
    return len(links), dofs


def made(f) -> World:
    if f.kind == 'world':
        return World.from_file(str(f.path), WorldConfig(), places())
    world = World.from_file(str(EMPTY), WorldConfig(allow_interpenetration=True))
    world.spawn('', sources.from_file(str(f.path), places=places()), (0, 0, 2))
    return world


@pytest.mark.parametrize('f', FILES, ids=[f.name for f in FILES])
def test_each_file_loads_with_its_links_and_joints_or_is_refused_as_it_must(f):
    if f.refused:
        with pytest.raises(getattr(errors, f.refused)):
            made(f)
        return
    world = made(f)
    links, dofs = expected(f.path)
    nbody, nv = world.read(lambda m, d: (m.nbody - 1, m.nv))
    assert nbody == links
    assert nv == dofs
    world.step(500)
    assert world.read(lambda m, d: bool(np.all(np.isfinite(d.qpos))
                                        and np.all(np.isfinite(d.qvel))))


def test_the_kuka_arms_joint_limits_are_the_files():
    f = next(f for f in FILES if f.path.name == 'kuka_with_gripper2.sdf')
    world = made(f)
    root = ET.parse(f.path).getroot()
    for joint in root.iter('joint'):
        if joint.get('type') != 'revolute':
            continue
        lo, hi = (float(joint.findtext(f'axis/limit/{k}')) for k in ('lower', 'upper'))
        name = f'lbr_iiwa_with_wsg50/{joint.get("name")}'
        got = world.read(lambda m, d, n=name: m.jnt_range[m.joint(n).id].copy())
        assert np.allclose(got, [lo, hi])


def test_a_world_of_gazebo_model_folders_with_an_sdf_ground_and_urdf_robots():
    """gym-ignition's folders: model.config names an SDF ground plane and URDF robots."""
    text = ('<sdf version="1.7"><world name="w"><include><uri>model://ground_plane</uri>'
            '</include><include><uri>model://pendulum</uri><pose>0 0 0.5 0 0 0</pose>'
            '</include><include><uri>model://cartpole</uri><name>cart</name>'
            '<pose>2 0 0.5 0 0 0</pose></include></world></sdf>')
    from sim_node.core.models import world_sources
    plan = world_sources.world_source(text, places=places())
    world = World.from_plan(plan, WorldConfig(), 'gym')
    kinds = {e.name: e.category for e in world.entities()}
    assert kinds['ground_plane'] == 'static'
    assert kinds['pendulum'] == 'robot' and kinds['cart'] == 'robot'
    assert any(n.startswith('cart/') for n in world.joint_names())
    world.step(500)


def test_drakes_cart_pole_has_its_slider_to_the_world_and_its_pin():
    f = next(f for f in FILES if f.path.name == 'cart_pole.sdf')
    world = made(f)
    kinds = world.read(lambda m, d: sorted(int(m.jnt_type[j]) for j in range(m.njnt)))
    assert kinds == sorted([int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE)])
    assert world.entities()[-1].category == 'robot' and not world.entities()[-1].has_free_joint


def test_the_stadiums_meshes_span_the_stadium():
    f = next(f for f in FILES if f.path.name == 'stadium.sdf')
    world = made(f)
    lo, hi = np.min([world.entity_bounds(e.name)[0] for e in world.entities()], axis=0), \
        np.max([world.entity_bounds(e.name)[1] for e in world.entities()], axis=0)
    assert np.all(hi[:2] - lo[:2] > 20)  # metres across
