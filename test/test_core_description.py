"""
Robot descriptions: forward kinematics of the URDF we write gives the poses MuJoCo computes.

The check is independent of the writer: a small URDF forward-kinematics (origin, then the joint's
motion, per joint, from the root link) in this file, against MuJoCo's own ``mj_kinematics`` at
random joint positions, for the default scene's robot, every Gymnasium MuJoCo model, every
gymnasium-robotics model of the corpus, and a spawned URDF robot (whose own text is used).
Links are matched to bodies by the frame names ``/tf`` uses (``frame_prefix: <entity>/``).
"""

from dataclasses import replace
from pathlib import Path
import sys

from conftest import DEFAULT_SCENE
import defusedxml.ElementTree as SafeET
import gymnasium
from msg_adapters import convert
import mujoco
import numpy as np
import pytest
from sim_node.core.errors import InvalidArgumentError
from sim_node.core.models import description, sources
from sim_node.core.world import World
from urdf_fk import urdf_fk

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
import corpus  # noqa: E402, I100

GYM_ASSETS = Path(gymnasium.__file__).parent / 'envs' / 'mujoco' / 'assets'
GYM_MODELS = sorted(GYM_ASSETS.glob('*.xml'))
ROBOTICS = [m for m in corpus.MODELS if m.package == 'gymnasium-robotics']
ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))

# A fixed base, joints with turned origins, an off-axis prismatic joint, a fixed flange.
ARM_URDF = """<robot name="arm">
  <link name="base_link"><inertial><mass value="2"/><inertia ixx=".02" iyy=".02" izz=".02"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="upper"><inertial><mass value="1"/><inertia ixx=".01" iyy=".01" izz=".01"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="fore"><inertial><mass value=".5"/><inertia ixx=".01" iyy=".01" izz=".01"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="slider"><inertial><mass value=".2"/><inertia ixx=".001" iyy=".001" izz=".001"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tool0"/>
  <joint name="shoulder" type="revolute"><parent link="base_link"/><child link="upper"/>
    <origin xyz="0 0 .3" rpy="0.3 0 0.5"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz=".1 .2 .3" rpy="1.2 -0.4 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="1"/></joint>
  <joint name="extend" type="prismatic"><parent link="fore"/><child link="slider"/>
    <origin xyz=".25 0 0" rpy="0 0.7 0"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-.1" upper=".2" effort="10" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="slider"/><child link="tool0"/>
    <origin xyz=".05 0 0" rpy="0 0 1.5708"/></joint>
</robot>"""


# ------------------------------------------------------------------ the comparison

def _random_joints(world: World, entity: str, rng) -> dict:
    """Put the entity's hinge and slide joints at random positions (in range); return them."""
    out = {}
    with world.locked() as (m, d):
        for j in range(m.njnt):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if int(m.jnt_type[j]) not in ONE_DOF or \
                    world.model_info.joint_entity[world.joint_names().index(name)] != entity:
                continue
            lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-1.5, 1.5)
            d.qpos[m.jnt_qposadr[j]] = out[name] = float(rng.uniform(lo, hi))
        mujoco.mj_kinematics(m, d)
    return out


def check_description_matches_mujoco(world: World, entity: str, rng, mesh_dir=None) -> int:
    """Compare every link's pose; return how many body frames were compared."""
    values = _random_joints(world, entity, rng)
    text = world.robot_description(entity, mesh_dir)
    root_link, fk = urdf_fk(text, values)
    info = world.model_info
    frames = convert.frame_names(info, 'world', f'{entity}/')
    rec = world.entity(entity)
    alias, mount = info.body_alias[rec.root_body], info.body_mount[rec.root_body]
    assert f'{entity}/{root_link}' == (mount or alias), \
        "the root link is the root body's own frame, or its mount if it has joints"
    movable = {j.get('name') for j in SafeET.fromstring(text).findall('joint')
               if j.get('type') in ('revolute', 'continuous', 'prismatic')}
    assert movable == {n for n, e in zip(info.joint_names, info.joint_entity) if e == entity}
    with world.locked() as (m, d):
        if mount:  # at the world's origin
            r0, p0 = np.eye(3), np.zeros(3)
        else:
            r0, p0 = d.xmat[rec.root_body].reshape(3, 3).copy(), d.xpos[rec.root_body].copy()
        compared = 0
        for b in rec.body_ids:
            frame = alias if b == rec.root_body else frames[b][len(entity) + 1:]
            link = description.link_name(entity, frame)
            assert link in fk, f'body {info.body_names[b]} has no link {link!r}'
            want_p = r0.T @ (d.xpos[b] - p0)
            want_r = r0.T @ d.xmat[b].reshape(3, 3)
            got_p, got_r = fk[link]
            assert np.linalg.norm(got_p - want_p) < 1e-6, (entity, link, got_p, want_p)
            assert np.abs(got_r - want_r).max() < 1e-6, (entity, link)
            compared += 1
    return compared


@pytest.mark.parametrize('path', [DEFAULT_SCENE] + GYM_MODELS,
                         ids=['default'] + [p.stem for p in GYM_MODELS])
def test_urdf_of_a_scene_robot_gives_mujocos_poses(path, tmp_path):
    world = World.from_file(str(path))
    robots = sorted(set(world.model_info.joint_entity))
    assert robots, 'every model here has a robot'
    rng = np.random.default_rng(7)
    for entity in robots:
        for _ in range(3):
            assert check_description_matches_mujoco(world, entity, rng, tmp_path) >= 1


@pytest.fixture(scope='module')
def corpus_folder():
    return corpus.fetch()


@pytest.mark.parametrize('model', ROBOTICS, ids=[m.name for m in ROBOTICS])
def test_urdf_of_a_spawned_gymnasium_robotics_model_gives_mujocos_poses(corpus_folder, model,
                                                                        tmp_path):
    world = World.from_file(str(DEFAULT_SCENE))
    name = world.spawn('thing', sources.from_file(str(model.file)), position=(4, 4, 1))
    rng = np.random.default_rng(3)
    assert check_description_matches_mujoco(world, name, rng, tmp_path) >= 1
    # Meshes are written where RViz can read them, by file:// URI, once per content.
    text = world.robot_description(name, tmp_path)
    for mesh in SafeET.fromstring(text).iter('mesh'):
        uri = mesh.get('filename')
        assert uri.startswith('file://') and Path(uri[len('file://'):]).stat().st_size > 84


def test_a_spawned_urdf_is_published_as_given_with_its_joints_renamed():
    world = World.from_file(str(DEFAULT_SCENE))
    world.spawn('arm', sources.from_model_text(ARM_URDF), position=(2, 0, 0),
                quat_wxyz=(0.8, 0, 0, 0.6))
    text = world.robot_description('arm')
    given = SafeET.fromstring(ARM_URDF)
    got = SafeET.fromstring(text)
    assert [j.get('name') for j in got.findall('joint')] == \
        ['arm/' + j.get('name') for j in given.findall('joint')]
    assert [link.get('name') for link in got.findall('link')] == \
        [link.get('name') for link in given.findall('link')]
    assert check_description_matches_mujoco(world, 'arm', np.random.default_rng(1)) == 5


def test_the_urdf_generated_for_a_spawned_urdf_robot_also_matches():
    """The generator too, on a model with turned origins and an off-axis prismatic joint."""
    world = World.from_file(str(DEFAULT_SCENE))
    world.spawn('arm', sources.from_model_text(ARM_URDF.replace('robot name', 'robot x')),
                position=(2, 0, 0))
    live = world.stepping.live
    design = live.design  # forget its URDF text: describe it from the compiled model
    live.design = replace(design, spawned={'arm': replace(design.spawned['arm'], urdf='')})
    assert check_description_matches_mujoco(world, 'arm', np.random.default_rng(2)) == 5


OFF_CENTRE = """<mujoco><worldbody><body name="base" pos="0 0 1">
  <body name="a" pos=".1 .2 .3" quat=".9 .1 .3 .2">
    <joint name="j1" type="hinge" pos=".05 -.02 .1" axis="1 1 0" ref=".4" range="-1 2"/>
    <joint name="j2" type="slide" axis="0 0 1" ref=".1"/>
    <joint name="j3" type="hinge" pos="0 .1 0" axis="0 1 0"/>
    <geom type="ellipsoid" size=".1 .05 .02" mass="1"/>
    <body name="b" pos=".3 0 0"><joint name="ball" type="ball" pos=".01 0 0"/>
      <geom type="capsule" size=".02 .1" mass=".1"/></body>
  </body></body></worldbody></mujoco>"""


def test_several_joints_off_centre_with_refs_and_a_ball_are_described_exactly(tmp_path):
    world = World.from_string(OFF_CENTRE)
    for seed in range(5):
        assert check_description_matches_mujoco(world, 'base', np.random.default_rng(seed),
                                                tmp_path) == 3
    types = {j.get('name'): j.get('type') for j in
             SafeET.fromstring(world.robot_description('base')).findall('joint')}
    assert types['j1'] == 'revolute' and types['j2'] == 'prismatic' and \
        types['j3'] == 'continuous' and types['ball'] == 'floating'


def test_an_entity_without_joints_has_no_description():
    world = World.from_file(str(DEFAULT_SCENE))
    with pytest.raises(InvalidArgumentError, match='no hinge or slide joints'):
        world.robot_description('table')
