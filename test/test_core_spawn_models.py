"""
Spawning the standalone model files people already have.

Every Gymnasium MuJoCo asset spawns into the running default scene beside its entities, runs, obeys
commands, honours its own angle units, and deletes cleanly. Real files, real MuJoCo.
"""

import glob
import os
import xml.etree.ElementTree as ET

from conftest import DEFAULT_SCENE
import gymnasium
import mujoco
import numpy as np
import pytest
from sim_node.core.models import sources
from sim_node.core.records import RESET_STATE
from sim_node.core.world import World
from sim_node.simulation import Simulation

GYM_ASSETS = os.path.join(os.path.dirname(gymnasium.__file__), 'envs', 'mujoco', 'assets')
MODELS = sorted(os.path.basename(f)[:-4] for f in glob.glob(os.path.join(GYM_ASSETS, '*.xml')))
SPAWN_AT = [2.5, 2.5, 1.0]  # clear of the scene's robot, table and boxes


def gym_file(name: str) -> str:
    return os.path.join(GYM_ASSETS, f'{name}.xml')


def others(w: World, name: str) -> dict:
    """Qpos and qvel of every joint not in entity `name`, by joint name."""
    out = {}
    with w.locked() as (m, d):
        for j in range(m.njnt):
            jn = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if jn.startswith(f'{name}/'):
                continue
            nq = {0: 7, 1: 4}.get(int(m.jnt_type[j]), 1)
            nv = {0: 6, 1: 3}.get(int(m.jnt_type[j]), 1)
            out[jn] = (d.qpos[m.jnt_qposadr[j]:m.jnt_qposadr[j] + nq].copy(),
                       d.qvel[m.jnt_dofadr[j]:m.jnt_dofadr[j] + nv].copy())
        out['time'] = d.time
    return out


def actuated_joints(w: World, name: str) -> list:
    """Hinge/slide joints of the entity driven by a motor of their own."""
    with w.locked() as (m, d):
        out = []
        for a in range(m.nu):
            if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
                jn = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, m.actuator_trnid[a, 0])
                if jn.startswith(f'{name}/') and jn in w.joint_names():
                    out.append((jn, float(m.actuator_ctrlrange[a, 1]) or 1.0))
    return out


def test_all_fourteen_gymnasium_models_are_here():
    assert len(MODELS) == 14, MODELS


@pytest.mark.parametrize('model', MODELS)
def test_a_gymnasium_model_spawns_runs_obeys_and_deletes_cleanly(model):
    w = World.from_file(str(DEFAULT_SCENE))
    w.step(20)
    scene = [e.name for e in w.entities()]
    w.spawn(model, sources.from_file(gym_file(model)), position=SPAWN_AT)
    assert [e.name for e in w.entities()] == scene + [model]
    rec = w.entity(model)
    info = w.model_info
    # Every body of the file is in the entity, named under its prefix; no infinite plane came.
    assert all(info.body_names[b] == model or info.body_names[b].startswith(f'{model}/')
               for b in rec.body_ids)
    with w.locked() as (m, d):
        assert [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE] \
            == [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, 'floor')]
    w.step(500)  # 1 s, no DivergenceError
    assert np.all(np.isfinite(w.snapshot().body_xpos))
    joints = actuated_joints(w, model)
    assert joints, 'every Gymnasium model has motors'
    # Commands reach its actuators by its prefixed joint names: compared with the same world
    # left alone, the commanded joint moves.
    twin = World.from_file(str(DEFAULT_SCENE))
    twin.step(20)
    twin.spawn(model, sources.from_file(gym_file(model)), position=SPAWN_AT)
    twin.step(500)
    joint, effort = joints[0]
    w.command([joint], [effort], 'effort')
    w.step(100)
    twin.step(100)
    assert abs(w.get_joint_states()[joint][0] - twin.get_joint_states()[joint][0]) > 1e-4
    before = others(w, model)
    w.delete(model)
    assert [e.name for e in w.entities()] == scene
    after = others(w, model)
    assert after.keys() == before.keys()
    for k in before:
        if k != 'time':
            assert np.array_equal(before[k][0], after[k][0]) and np.array_equal(
                before[k][1], after[k][1]), k
    with w.locked() as (m, d):
        names = [mujoco.mj_id2name(m, obj, i) or '' for obj, n in (
            (mujoco.mjtObj.mjOBJ_ACTUATOR, m.nu), (mujoco.mjtObj.mjOBJ_SENSOR, m.nsensor),
            (mujoco.mjtObj.mjOBJ_TENDON, m.ntendon), (mujoco.mjtObj.mjOBJ_TEXTURE, m.ntex),
            (mujoco.mjtObj.mjOBJ_MATERIAL, m.nmat), (mujoco.mjtObj.mjOBJ_MESH, m.nmesh),
            (mujoco.mjtObj.mjOBJ_LIGHT, m.nlight), (mujoco.mjtObj.mjOBJ_CAMERA, m.ncam),
            (mujoco.mjtObj.mjOBJ_GEOM, m.ngeom)) for i in range(n)]
    assert not [n for n in names if n.startswith(f'{model}/')]
    w.spawn(model, sources.from_file(gym_file(model)), position=SPAWN_AT)  # and again


@pytest.mark.parametrize('model', ['ant', 'humanoid', 'half_cheetah'])
def test_a_spawned_model_keeps_its_own_angle_units(model):
    alone = mujoco.MjModel.from_xml_path(gym_file(model))
    w = World.from_file(str(DEFAULT_SCENE))  # the scene reads radians
    w.spawn(model, sources.from_file(gym_file(model)), position=SPAWN_AT)
    with w.locked() as (m, d):
        for j in range(alone.njnt):
            jn = mujoco.mj_id2name(alone, mujoco.mjtObj.mjOBJ_JOINT, j)
            here = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f'{model}/{jn}')
            assert here >= 0, jn
            np.testing.assert_allclose(m.jnt_range[here], alone.jnt_range[j], err_msg=jn)


def test_the_worlds_home_keyframe_still_works_and_holds_the_spawn_state():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('ant', sources.from_file(gym_file('ant')), position=SPAWN_AT)
    start = w.get_entity_state('ant').position.copy()
    home_shoulder = w.get_joint_states()['left_shoulder'][0]
    w.command(['left_shoulder'], [1.0], 'position')
    w.step(500)
    assert not np.allclose(w.get_entity_state('ant').position, start, atol=1e-3)
    w.reset(RESET_STATE)
    np.testing.assert_allclose(w.get_entity_state('ant').position, start, atol=1e-9)
    assert w.get_joint_states()['left_shoulder'][0] == home_shoulder


def test_a_models_own_keyframes_do_not_replace_the_worlds():
    own = ('<mujoco><worldbody><body name="ball" pos="0 0 .5"><freejoint/><geom size=".1"/>'
           '</body></worldbody><keyframe><key name="home" qpos="5 5 5 1 0 0 0"/></keyframe>'
           '</mujoco>')
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('ball', sources.from_model_text(own), position=SPAWN_AT)
    with w.locked() as (m, d):
        assert m.nkey == 1  # the world's home only
    spawned_at = w.get_entity_state('ball').position.copy()
    w.step(300)
    w.reset(RESET_STATE)
    np.testing.assert_allclose(w.get_entity_state('ball').position, spawned_at, atol=1e-9)


def test_worldbody_geometry_follows_the_documented_rule():
    """
    Ground planes are dropped.

    Other static worldbody geoms become a welded part of the entity (reacher's arena walls and
    base); lights come along and go with it.
    """
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('reacher', sources.from_file(gym_file('reacher')), position=SPAWN_AT)
    rec = w.entity('reacher')
    info = w.model_info
    assert f'reacher/{sources.WORLD_GEOMS_BODY}' in [info.body_names[b] for b in rec.body_ids]
    geoms = {g.name for g in info.geoms if info.body_root[g.body] == rec.root_body}
    assert {'reacher/sideS', 'reacher/root'} <= geoms and 'reacher/ground' not in geoms
    lo, hi = w.entity_bounds('reacher')
    assert hi[0] - lo[0] > 0.4  # the arena's walls are part of it
    with w.locked() as (m, d):
        n_light = m.nlight
    w.spawn('ant', sources.from_file(gym_file('ant')), position=[-2.5, 2.5, 1.0])
    with w.locked() as (m, d):
        assert m.nlight == n_light + 1  # ant's light came along
    w.delete('ant')
    with w.locked() as (m, d):
        assert m.nlight == n_light


def test_a_whole_model_moves_as_a_group_and_a_welded_one_by_its_frame():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('reacher', sources.from_file(gym_file('reacher')), position=SPAWN_AT)
    target = np.array([-2.5, 2.5, 0.5])
    q = np.array([np.cos(0.3), 0, 0, np.sin(0.3)])
    w.set_entity_state('reacher', position=target, quat_wxyz=q)
    st = w.get_entity_state('reacher')
    np.testing.assert_allclose(st.position, target, atol=1e-9)
    np.testing.assert_allclose(abs(np.dot(st.quat_wxyz, q)), 1.0, atol=1e-9)
    lo, hi = w.entity_bounds('reacher')
    assert lo[0] < target[0] < hi[0] and lo[1] < target[1] < hi[1]  # the walls came along


def test_a_urdf_with_a_world_link_spawns_as_one_fixed_base_robot(tmp_path):
    urdf = tmp_path / 'arm.urdf'
    inertial = ('<inertial><mass value="{m}"/><inertia ixx=".01" iyy=".01" izz=".01" ixy="0" '
                'ixz="0" iyz="0"/></inertial>')
    urdf.write_text(
        '<robot name="arm"><link name="world"/>'
        '<joint name="fix" type="fixed"><parent link="world"/><child link="base"/>'
        '<origin xyz="0 0 0.1"/></joint>'
        f'<link name="base">{inertial.format(m=1)}<collision><geometry><box size=".1 .1 .1"/>'
        '</geometry></collision></link>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
        '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
        '<limit lower="-1" upper="1" effort="10" velocity="1"/></joint>'
        f'<link name="l1">{inertial.format(m=0.5)}</link></robot>')
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('arm', sources.from_file(str(urdf)), position=[2, 2, 0])
    rec = w.entity('arm')
    assert rec.category == 'robot' and not rec.has_free_joint
    np.testing.assert_allclose(w.get_entity_state('arm').position, [2, 2, 0.1], atol=1e-9)
    w.command(['arm/j1'], [0.5], 'position')
    w.step(1000)
    assert w.get_joint_states()['arm/j1'][0] == pytest.approx(0.5, abs=1e-3)


def test_simulation_add_model_takes_a_whole_model_file_text():
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    with open(gym_file('half_cheetah')) as f:
        text = f.read()
    sim.add_model('cheetah', text, position=SPAWN_AT)
    sim.step(dt=0.5)
    assert 'cheetah/bthigh' in sim.joint_names
    assert ET.fromstring(text).find('worldbody') is not None


@pytest.mark.parametrize('model', MODELS)
def test_a_gymnasium_model_loads_as_a_whole_world_too(model):
    w = World.from_file(gym_file(model))
    w.step(100)
    assert w.entities() and np.all(np.isfinite(w.snapshot().body_xpos))


def test_world_contact_defaults_reach_every_body_of_a_spawned_model():
    sim = Simulation.from_file(str(DEFAULT_SCENE))
    sim.set_defaults(friction=[0.3, 0.005, 0.0001])
    sim.add_model('reacher', open(gym_file('reacher')).read(), position=SPAWN_AT)
    with sim.world.locked() as (m, d):
        for name in ('reacher/target', 'reacher/fingertip', 'reacher/sideS'):
            g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
            assert m.geom_friction[g][0] == pytest.approx(0.3), name


def _write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_includes_with_mujocoinclude_roots_and_dotdot_inside_the_roots_load(tmp_path):
    """What published models do: <mujocoinclude> files, and includes that climb to a sibling."""
    _write(tmp_path / 'shared' / 'parts.xml',
           '<mujocoinclude><body name="arm"><joint name="j" type="hinge"/>'
           '<geom type="capsule" size="0.05 0.2"/></body></mujocoinclude>')
    model = _write(tmp_path / 'robot' / 'robot.xml',
                   '<mujoco><worldbody><body name="base"><freejoint/><geom size="0.1"/>'
                   '<include file="../shared/parts.xml"/></body></worldbody></mujoco>')
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('bot', sources.from_file(str(model), allowed_roots=[str(tmp_path)]), (2, 2, 1))
    assert 'bot/j' in w.joint_names()


def test_dotdot_that_leaves_the_roots_is_refused_like_any_outside_file(tmp_path):
    from sim_node.core.errors import MissingAssetsError
    _write(tmp_path / 'secret' / 'parts.xml', '<mujocoinclude/>')
    model = _write(tmp_path / 'allowed' / 'robot.xml',
                   '<mujoco><worldbody><include file="../secret/parts.xml"/>'
                   '<body><geom size="0.1"/></body></worldbody></mujoco>')
    with pytest.raises(MissingAssetsError, match='not inside the directories'):
        sources.from_file(str(model), allowed_roots=[str(tmp_path / 'allowed')])


def test_a_second_spawn_of_the_same_files_reads_and_checks_nothing_again(tmp_path):
    """The checked copy is kept by path, inode, size and mtime: the file is not read again."""
    from conftest import write_mesh_model
    model = write_mesh_model(tmp_path, 1000)
    first = sources.from_file(str(model), allowed_roots=[str(tmp_path)])
    mesh = tmp_path / 'big.stl'
    st = mesh.stat()
    data = mesh.read_bytes()
    mesh.write_bytes(b'\0' * len(data))  # same size; the mtime put back below
    os.utime(mesh, ns=(st.st_atime_ns, st.st_mtime_ns))
    second = sources.from_file(str(model), allowed_roots=[str(tmp_path)])
    assert [m.file for m in second.spec.meshes] == [m.file for m in first.spec.meshes]
    assert open(second.spec.meshes[0].file, 'rb').read() == data  # the checked copy


def test_a_skinned_model_keeps_its_bones_when_its_root_takes_the_entity_name(tmp_path):
    """dm_control's dog: a skin's bones name bodies; the root's rename must reach them."""
    model = _write(tmp_path / 'skinned.xml', """<mujoco><worldbody>
      <body name="torso" pos="0 0 0.3"><freejoint/><geom size="0.1"/>
        <body name="leg" pos="0 0 -0.1"><joint name="knee"/><geom size="0.05"/></body>
      </body></worldbody>
      <deformable><skin name="fur" vertex="0 0 0.3  0.1 0 0.3  0 0.1 0.3  0 0 0.2"
          face="0 1 2  0 1 3  0 2 3  1 2 3">
        <bone body="torso" bindpos="0 0 0.3" bindquat="1 0 0 0" vertid="0 1 2" vertweight="1 1 1"/>
        <bone body="leg" bindpos="0 0 0.2" bindquat="1 0 0 0" vertid="3" vertweight="1"/>
      </skin></deformable></mujoco>""")
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('dog', sources.from_file(str(model), allowed_roots=[str(tmp_path)]), (2, 2, 1))
    with w.locked() as (m, _):
        bones = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(b))
                 for b in m.skin_bonebodyid]
    assert bones == ['dog', 'dog/leg']


def _png(path, width=8, height=8):
    """Write a small RGB PNG (a gradient) with Pillow."""
    from PIL import Image
    img = Image.new('RGB', (width, height))
    img.putdata([(x * 30 % 256, y * 30 % 256, 90) for y in range(height) for x in range(width)])
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)
    return path


def test_textures_heightfields_frames_replicate_and_nested_includes_work(tmp_path):
    """MJCF features of standalone files: each works when spawned, files read by the reader."""
    _png(tmp_path / 'textures' / 'wood.png')
    _png(tmp_path / 'terrain.png', 16, 16)
    _write(tmp_path / 'parts' / 'inner.xml',
           '<mujocoinclude><geom name="inner" type="sphere" size="0.03" pos="0 0 0.2"/>'
           '</mujocoinclude>')
    _write(tmp_path / 'parts' / 'outer.xml',
           '<mujocoinclude><include file="parts/inner.xml"/></mujocoinclude>')
    model = _write(tmp_path / 'features.xml', """<mujoco>
      <compiler texturedir="textures"/>
      <asset>
        <texture name="wood" type="2d" file="wood.png"/>
        <material name="wood" texture="wood"/>
        <hfield name="terrain" file="../terrain.png" size="0.3 0.3 0.05 0.01"/>
      </asset>
      <worldbody>
        <body name="base" pos="0 0 0.5"><freejoint/>
          <geom type="box" size="0.1 0.1 0.05" material="wood"/>
          <include file="parts/outer.xml"/>
          <frame name="ring" pos="0 0 0.1">
            <replicate count="4" euler="0 0 90">
              <geom name="tooth" type="box" size="0.01 0.01 0.01" pos="0.12 0 0"/>
            </replicate>
          </frame>
        </body>
        <body name="ground_patch" pos="0 0 0.01"><geom type="hfield" hfield="terrain"/></body>
      </worldbody></mujoco>""")
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('features', sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
            (2.5, -2.5, 0.3))
    with w.locked() as (m, _):
        names = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m.ngeom)}
        assert m.nhfield == 1 and m.ntex >= 1
    assert 'features/inner' in names
    assert sum(1 for n in names if n and n.startswith('features/tooth')) == 4
    w.step(50)


def test_a_model_asset_is_refused_naming_the_element(tmp_path):
    from sim_node.core.errors import UnsupportedFormatError
    _write(tmp_path / 'gripper.xml', '<mujoco><worldbody><body name="g"><geom size="0.1"/>'
           '</body></worldbody></mujoco>')
    model = _write(tmp_path / 'arm.xml', '<mujoco><asset><model name="g" file="gripper.xml"/>'
                   '</asset><worldbody><body name="arm"><geom size="0.1"/><attach model="g" '
                   'body="g" prefix="g_"/></body></worldbody></mujoco>')
    with pytest.raises(UnsupportedFormatError, match='<model>'):
        sources.from_file(str(model), allowed_roots=[str(tmp_path)])


def test_a_plugin_shipped_with_mujoco_works_in_a_spawned_model(tmp_path):
    """An <extension> plugin MuJoCo ships (its PID actuator) drives a spawned joint."""
    model = _write(tmp_path / 'pid.xml', """<mujoco>
      <extension><plugin plugin="mujoco.pid"><instance name="pid">
        <config key="kp" value="5"/><config key="kd" value="1"/></instance></plugin>
      </extension>
      <worldbody><body name="base"><geom type="box" size="0.05 0.05 0.05"/>
        <body name="arm" pos="0 0 0.1"><joint name="hinge" axis="0 1 0"/>
          <geom type="capsule" size="0.02" fromto="0 0 0 0.2 0 0" mass="1"/></body>
      </body></worldbody>
      <actuator><plugin name="servo" joint="hinge" plugin="mujoco.pid" instance="pid"/>
      </actuator></mujoco>""")
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('servo', sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
            (-2.5, 2.5, 0.3))
    with w.locked() as (m, d):
        assert m.nplugin >= 1
        d.ctrl[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, 'servo/servo')] = 0.5
    w.step(2000)
    assert w.get_joint_states()['servo/hinge'][0] == pytest.approx(0.5, abs=0.1)


def test_urdf_package_uris_resolve_in_the_readable_folders(tmp_path):
    """package://<pkg>/... in a URDF: <folder>/<pkg>/... for each readable folder."""
    from conftest import write_mesh_model
    pkg = tmp_path / 'my_robot_description' / 'meshes'
    pkg.mkdir(parents=True)
    write_mesh_model(pkg, 200)  # big.stl
    urdf = _write(tmp_path / 'robot.urdf', """<robot name="r">
      <link name="base"><collision><geometry>
        <mesh filename="package://my_robot_description/meshes/big.stl"/>
      </geometry></collision><inertial><mass value="1"/>
        <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
    </robot>""")
    src = sources.from_file(str(urdf), allowed_roots=[str(tmp_path)])
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('r', src, (2.5, 2.5, 1.0))
    with w.locked() as (m, _):
        assert m.nmesh >= 1
