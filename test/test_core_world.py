"""
The ROS-free world.

Spawn/delete keep everything else's state, failures change nothing, control, reset, determinism,
physics parameters. Real MuJoCo throughout.
"""

import threading

from conftest import DEFAULT_SCENE, SCENES
import mujoco
import numpy as np
import pytest
from sim_node.core.errors import (DivergenceError, IncorrectStateError, InvalidArgumentError,
                                  InvalidPoseError, MissingAssetsError, NameNotUniqueError,
                                  NotFoundError, ResourceParseError, UnsupportedAssetsError,
                                  UnsupportedFormatError)
from sim_node.core.models import sources
from sim_node.core.records import RESET_SPAWNED, RESET_STATE, RESET_TIME
from sim_node.core.world import World

ARM_MJCF = """<mujoco><worldbody>
  <body name="base"><geom type="box" size=".05 .05 .05"/>
    <body name="link"><joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom name="link_geom" type="capsule" fromto="0 0 0 .2 0 0" size=".02"/></body>
  </body></worldbody>
  <actuator><motor name="motor" joint="hinge"/></actuator>
  <sensor><jointpos name="angle" joint="hinge"/></sensor>
  <contact><exclude body1="base" body2="link"/></contact>
</mujoco>"""


@pytest.fixture
def world():
    w = World.from_file(str(DEFAULT_SCENE))
    w.step(50)
    return w


def box(size=0.05, mass=0.5):
    return sources.primitive('box', [size] * 3, mass=mass)


def named_state(w: World) -> dict:
    """Every joint's qpos and qvel by name, plus time: comparable across recompiles."""
    out = {'time': w.time}
    with w.locked() as (m, d):
        for j in range(m.njnt):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            q0, v0 = m.jnt_qposadr[j], m.jnt_dofadr[j]
            nq = {0: 7, 1: 4, 2: 1, 3: 1}[int(m.jnt_type[j])]
            nv = {0: 6, 1: 3, 2: 1, 3: 1}[int(m.jnt_type[j])]
            out[name] = (d.qpos[q0:q0 + nq].copy(), d.qvel[v0:v0 + nv].copy())
        out['ctrl'] = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a): d.ctrl[a]
                       for a in range(m.nu)}
        out['warmstart'] = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j):
                            d.qacc_warmstart[m.jnt_dofadr[j]] for j in range(m.njnt)}
    return out


def assert_same_state(before: dict, after: dict, keys=None):
    keys = keys or [k for k in before if k in after]
    for k in keys:
        a, b = before[k], after[k]
        if isinstance(a, tuple):
            assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]), k
        elif isinstance(a, dict):
            assert {n: b[n] for n in a if n in b} == {n: a[n] for n in a if n in b}, k
            assert len([n for n in a if n not in b]) <= 1, k  # at most the deleted entity
        else:
            assert a == b, k


def test_scene_entities_and_categories(world):
    cats = {e.name: e.category for e in world.entities()}
    assert cats == {'robot': 'robot', 'table': 'static', 'box_a': 'dynamic', 'box_b': 'dynamic'}
    assert world.joint_names() == ['left_shoulder', 'left_elbow', 'right_shoulder',
                                   'right_elbow']


def test_spawn_and_delete_keep_every_other_state_bit_for_bit(world):
    before = named_state(world)
    world.spawn('crate', box(), position=[0.2, 1.0, 0.5])
    assert_same_state(before, named_state(world))
    world.spawn('arm', sources.from_model_text(ARM_MJCF), position=[-1, 0, 0.5])
    world.step(20)
    before = named_state(world)
    world.delete('crate')  # in the middle of the tree
    after = named_state(world)
    assert 'crate/free' not in after
    assert_same_state(before, after, [k for k in before if k != 'crate/free'])


def test_compacting_the_spec_keeps_the_state_bit_for_bit(world):
    """Every 32nd removal rewrites the spec (an extra generation); the state stays as it was."""
    from sim_node.core.stepping.design import COMPACT_AFTER_REMOVALS
    world.spawn('arm', sources.from_model_text(ARM_MJCF), position=[-1, 0, 0.5])
    names = [f'b{i}' for i in range(COMPACT_AFTER_REMOVALS)]
    for i, name in enumerate(names):
        world.spawn(name, box(), position=[2 + 0.2 * (i % 8), 0.2 * (i // 8), 0.5])
    world.step(50)  # moving, in contact, warm-started
    for name in names[:-1]:
        world.delete(name)
    before, gen = named_state(world), world.generation
    world.delete(names[-1])
    assert world.generation == gen + 2  # the delete, then the compaction
    after = named_state(world)
    assert_same_state(before, after, [k for k in before if k != f'{names[-1]}/free'])
    world.step(10)  # and it steps on


def geom_friction(w: World, geom: str) -> float:
    with w.locked() as (m, _):
        return float(m.geom_friction[m.geom(geom).id][0])


def test_contact_settings_stay_with_their_entity_through_deletes_and_compaction(world):
    """
    An entity's own friction lasts as long as it does.

    A new entity of a deleted one's name starts with the world's; a scene entity keeps its own
    through 32 removals (a compaction) and later changes of the world's default.
    """
    from sim_node.core.stepping.design import COMPACT_AFTER_REMOVALS
    world.set_default_contact(friction=[0.6, 0.005, 0.0001])
    world.set_friction('box_a', 0.2)
    world.spawn('crate', box(), position=[2, 0, 0.5])
    world.set_friction('crate', 1.5)
    assert geom_friction(world, 'crate/geom') == pytest.approx(1.5)
    world.delete('crate')
    world.spawn('crate', box(), position=[2, 0, 0.5])
    assert geom_friction(world, 'crate/geom') == pytest.approx(0.6)
    for i in range(COMPACT_AFTER_REMOVALS):
        world.spawn(f'b{i}', box(), position=[3, 0.2 * i, 0.5])
        world.delete(f'b{i}')
    world.set_default_contact(friction=[0.9, 0.005, 0.0001])
    assert geom_friction(world, 'crate/geom') == pytest.approx(0.9)  # nothing of its own
    assert geom_friction(world, 'box_a_geom') == pytest.approx(0.2)  # its own, kept
    assert geom_friction(world, 'box_b_geom') == pytest.approx(0.9)


@pytest.mark.parametrize('edit', ['set_default_contact', 'set_friction', 'spawn', 'delete'])
def test_an_edit_that_fails_at_its_commit_leaves_every_table_as_it_was(
        world, edit, monkeypatch):
    """
    A fault after the compile (in the switch to the new model) keeps what the world knows.

    Entities, spawned ones (deletable), their contact settings, the world's defaults.
    """
    world.set_default_contact(friction=[0.6, 0.005, 0.0001])
    world.spawn('crate', box(), position=[2, 0, 0.5])
    world.set_friction('crate', 1.5)
    before = (world.entities(), world.spawned_names(), world.generation)
    guard, calls = world.stepping.live.guard, []  # bound to the new data in the switch
    real = guard.bind

    def faulty(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1:  # the switch fails; the way back to the old model does not
            raise RuntimeError('injected fault')
        return real(*args, **kwargs)
    monkeypatch.setattr(guard, 'bind', faulty)
    with pytest.raises(RuntimeError, match='injected'):
        {'set_default_contact': lambda: world.set_default_contact(friction=[0.1, 0, 0]),
         'set_friction': lambda: world.set_friction('crate', 0.1),
         'spawn': lambda: world.spawn('other', box(), position=[3, 0, 0.5]),
         'delete': lambda: world.delete('crate')}[edit]()
    monkeypatch.undo()
    assert (world.entities(), world.spawned_names(), world.generation) == before
    world.set_default_contact(restitution=0.5)  # re-applies every table: none may have moved
    assert geom_friction(world, 'crate/geom') == pytest.approx(1.5)
    assert geom_friction(world, 'box_b_geom') == pytest.approx(0.6)
    world.delete('crate')  # still known as spawned
    assert 'crate' not in world.spawned_names()


def test_spawned_model_brings_its_actuators_sensors_and_excludes_and_delete_removes_them(world):
    world.spawn('arm', sources.from_model_text(ARM_MJCF), position=[-1, 0, 0.5])
    with world.locked() as (m, _):
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, 'arm/motor') >= 0
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, 'arm/angle') >= 0
        assert m.nexclude == 1
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(m.nbody)]
    assert 'arm' in names and 'arm/link' in names
    assert world.entity('arm').category == 'robot'
    world.delete('arm')
    with world.locked() as (m, _):
        assert m.nu == 4 and m.nsensor == 3 and m.nexclude == 0  # the base's IMU


@pytest.mark.parametrize('make_source, error', [
    (lambda: sources.from_model_text('<mujoco><worldbody><body>'), ResourceParseError),
    (lambda: sources.from_model_text('<notmjcf/>'), UnsupportedFormatError),
    (lambda: sources.from_model_text(
        '<mujoco><asset><mesh name="m" file="/nonexistent/m.stl"/></asset>'
        '<worldbody><body><geom type="mesh" mesh="m"/></body></worldbody></mujoco>'),
     MissingAssetsError),
])
def test_bad_resources_are_refused_before_touching_the_world(world, make_source, error):
    before = named_state(world)
    gen = world.generation
    with pytest.raises(error):
        world.spawn('bad', make_source(), position=[0, 1, 1])
    assert world.generation == gen
    assert_same_state(before, named_state(world))


@pytest.mark.parametrize('kwargs, error', [
    ({'name': 'box_a'}, NameNotUniqueError),
    ({'position': [0, 1, float('nan')]}, InvalidPoseError),
    ({'quat_wxyz': [1, 1, 0, 0]}, InvalidPoseError),
    ({'position': [0.75, 0, 0.41]}, InvalidPoseError),  # inside the table top
    ({'reference': 'nobody'}, InvalidPoseError),  # a pose in an unknown frame
])
def test_failed_spawn_leaves_the_world_unchanged(world, kwargs, error):
    before = named_state(world)
    names = [e.name for e in world.entities()]
    args = {'name': 'crate', 'position': [0, 1, 1], **kwargs}
    with pytest.raises(error):
        world.spawn(args.pop('name'), box(), **args)
    assert [e.name for e in world.entities()] == names
    assert_same_state(before, named_state(world))
    world.spawn('crate', box(), position=[0, 1, 1])  # and the world still works
    world.step(10)


def test_spawn_relative_to_an_entity_and_renaming(world):
    world.spawn('on_table', box(0.03), position=[0, 0.3, 0.5], reference='table')
    st = world.get_entity_state('on_table')
    assert np.allclose(st.position, [0.75, 0.3, 0.5])
    renamed = world.spawn('on_table', box(0.03), position=[0, -0.3, 0.5], reference='table',
                          allow_renaming=True)
    assert renamed == 'on_table_1'


def test_delete_then_spawn_same_name_and_reset_spawned(world):
    world.spawn('crate', box(), position=[0, 1, 0.5])
    world.delete('crate')
    world.spawn('crate', box(), position=[0, 1, 0.5])
    world.step(10)
    world.reset(RESET_SPAWNED)
    assert 'crate' not in [e.name for e in world.entities()]
    with pytest.raises(IncorrectStateError):
        world.delete('table')  # scene entities stay


def test_reset_scopes(world):
    world.command(['left_shoulder'], [1.0], 'position')
    world.step(200)
    t = world.time
    q_moved = world.get_joint_states()['left_shoulder'][0]
    world.reset(RESET_TIME)
    assert world.time == 0.0 and world.get_joint_states()['left_shoulder'][0] == q_moved
    world.step(10)
    world.reset(RESET_STATE)
    assert world.time == pytest.approx(10 * world.timestep)
    assert world.get_joint_states()['left_shoulder'][0] == pytest.approx(-0.2)  # home key
    world.step(10)
    assert t > 0
    world.reset()  # all
    assert world.time == 0.0


def test_same_state_and_commands_give_the_same_trajectory():
    def run():
        w = World.from_file(str(DEFAULT_SCENE))
        traj = []
        for i in range(100):
            w.command(['left_elbow', 'right_shoulder'], [0.5 * np.sin(i / 10), -0.3], 'position')
            w.step(5)
            traj.append(w.get_state().values.copy())
        return np.array(traj)
    assert np.array_equal(run(), run())


def test_get_and_set_full_state_round_trip(world):
    snap = world.get_state()
    world.step(100)
    world.set_state(snap)
    assert np.array_equal(world.get_state().values, snap.values)
    world.spawn('crate', box(), position=[0, 1, 0.5])
    with pytest.raises(IncorrectStateError):
        world.set_state(snap)  # from another model generation


def test_entity_state_set_and_get_and_static_twist_refused(world):
    world.set_entity_state('box_a', position=[0.1, 1.0, 1.0], quat_wxyz=[0, 0, 0, 1],
                           linear_velocity=[0.5, 0, 0], angular_velocity=[0, 0, 2])
    st = world.get_entity_state('box_a')
    assert np.allclose(st.position, [0.1, 1.0, 1.0])
    assert np.allclose(st.linear_velocity, [0.5, 0, 0], atol=1e-9)
    assert np.allclose(st.angular_velocity, [0, 0, 2], atol=1e-9)
    with pytest.raises(IncorrectStateError):
        world.set_entity_state('table', linear_velocity=[1, 0, 0])
    world.set_entity_state('table', position=[0.8, 0, 0])  # moving a static entity is fine
    assert np.allclose(world.get_entity_state('table').position, [0.8, 0, 0])


def test_commands_are_validated_and_position_command_reaches_target(world):
    with pytest.raises(InvalidArgumentError):
        world.command(['left_elbow'], [float('nan')], 'position')
    with pytest.raises(NotFoundError):
        world.command(['no_joint'], [0.0], 'position')
    with pytest.raises(InvalidArgumentError):
        world.command(['left_elbow', 'right_elbow'], [0.0], 'position')
    world.command(['left_elbow'], [-0.5], 'position')
    world.step(1500)
    assert world.get_joint_states()['left_elbow'][0] == pytest.approx(-0.5, abs=0.03)


def test_pd_control_without_actuators():
    w = World.from_file(str(SCENES / 'push_stack.xml'))
    w.spawn('arm', sources.from_model_text(ARM_MJCF), position=[-1, 0, 0.5])
    w.command(['arm/hinge'], [0.5], 'position')  # 'arm/motor' is a motor: PD through torque
    w.step(2000)
    assert w.get_joint_states()['arm/hinge'][0] == pytest.approx(0.5, abs=0.05)
    w.command(['arm/hinge'], [2.0], 'velocity')
    w.step(500)
    assert w.get_joint_states()['arm/hinge'][1] == pytest.approx(2.0, abs=0.1)


@pytest.mark.slow  # about 7 s of eight threads hammering
def test_eight_threads_commanding_while_stepping_lose_nothing(world):
    errors = []
    last = {}

    def sender(k):
        try:
            for i in range(200):
                joint = world.joint_names()[k % 4]
                world.command([joint], [0.001 * i + k * 0.01], 'position')
                last[k] = 0.001 * i + k * 0.01
        except Exception as exc:  # noqa: B902 - any error is the failure we look for
            errors.append(exc)

    stop = threading.Event()

    def stepper():
        while not stop.is_set():
            world.step(5)
    t = threading.Thread(target=stepper)
    t.start()
    threads = [threading.Thread(target=sender, args=(k,)) for k in range(8)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    stop.set()
    t.join()
    world.step(1)
    assert not errors
    with world.locked() as (m, d):
        ctrl = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a): d.ctrl[a]
                for a in range(m.nu)}
    # The last command to each joint is what the actuator holds.
    for k in range(4):
        joint = world.joint_names()[k]
        assert ctrl[joint + '_pos'] in (pytest.approx(last[k]), pytest.approx(last[k + 4]))


def test_injected_divergence_restores_the_last_good_state_and_reports_the_step(world):
    world.step(10)
    good = world.get_state()
    with world.locked() as (m, d):
        d.qvel[-1] = 1e12  # a value MuJoCo flags as divergent
    with pytest.raises(DivergenceError) as info:
        world.step(5)
    assert info.value.step == good.step + 1
    assert 'BADQVEL' in ''.join(info.value.report['warnings']) or info.value.report[
        'nonfinite_qvel']
    assert np.all(np.isfinite(world.get_state().values))
    assert world.step_count == good.step


UNSTABLE_MJCF = """<mujoco><option integrator="Euler" timestep="0.01" gravity="0 0 0"/>
  <worldbody>
    <body name="slider"><joint name="j" type="slide" axis="1 0 0"/>
      <geom type="sphere" size=".1" mass="1"/></body>
    <body name="box" pos="0 1 0"><freejoint/><geom type="box" size=".1 .1 .1" mass="1"/></body>
  </worldbody>
  <actuator><position name="servo" joint="j" kp="50000"/></actuator></mujoco>"""


def test_divergence_mid_batch_names_the_exact_step_and_restores_the_state_before_it():
    """
    Name the step a servo too stiff for its time step blows up, mid-batch.

    The batch was given new controls: the report names that step and the world is left exactly
    where a plain MuJoCo run stands one step before it, still holding the new control.
    """
    world = World.from_string(UNSTABLE_MJCF)
    world.step(3, ctrl=np.array([0.0]))  # at rest: the next batch starts from a cached state
    with pytest.raises(DivergenceError) as info:
        world.step(40, ctrl=np.array([1.0]))
    # The same run in bare MuJoCo, one step at a time.
    m = mujoco.MjModel.from_xml_string(UNSTABLE_MJCF)
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, 3)
    d.ctrl[:] = 1.0
    warnings = d.warning.number.copy()
    states = []
    for _ in range(40):
        states.append((d.qpos.copy(), d.qvel.copy()))
        mujoco.mj_step(m, d)
        if (d.warning.number != warnings).any() or not np.isfinite(d.qvel).all():
            break
    bad_step = 3 + len(states)
    assert 3 + 1 < bad_step < 3 + 40  # mid-batch, or the test proves nothing
    assert info.value.step == bad_step
    assert world.step_count == bad_step - 1
    with world.locked() as (_, wd):
        np.testing.assert_array_equal(wd.qpos, states[-1][0])
        np.testing.assert_array_equal(wd.qvel, states[-1][1])
        assert wd.ctrl[0] == 1.0


def test_restitution_and_friction_rank_as_expected():
    w = World.from_file(str(SCENES / 'friction_restitution.xml'))
    start = {e.name: w.get_entity_state(e.name).position.copy() for e in w.entities()}
    peaks = np.zeros(10)
    landed = np.zeros(10, bool)
    for _ in range(1000):
        w.step(2)
        for i in range(10):
            st = w.get_entity_state(f'ball_{i}')
            landed[i] |= st.position[2] < 0.04
            if landed[i] and st.linear_velocity[2] > 0:
                peaks[i] = max(peaks[i], st.position[2])
    assert np.all(np.diff(peaks) > 0), peaks  # higher restitution bounces higher
    slid = [np.linalg.norm(w.get_entity_state(f'block_{i}').position - start[f'block_{i}'])
            for i in range(10)]
    assert slid[0] > slid[1] > slid[5] and slid[2] > slid[5]  # lower friction slides further
    assert slid[9] < 0.02


def test_set_restitution_mass_friction_gravity_timestep_validate(world):
    with pytest.raises(InvalidArgumentError):
        world.set_restitution('box_a', 1.5)
    with pytest.raises(InvalidArgumentError):
        world.set_mass('box_a', float('nan'))
    world.set_mass('box_a', 2.0)
    with world.locked() as (m, _):
        assert m.body_mass[m.body('box_a').id] == pytest.approx(2.0)
    world.set_friction('box_a', 0.3)
    world.set_gravity([0, 0, -1.62])
    world.set_timestep(0.001)
    assert world.timestep == 0.001
    with pytest.raises(InvalidArgumentError):
        world.set_timestep(0)


def test_fifo_and_dotdot_paths_are_refused(tmp_path):
    import os
    fifo = tmp_path / 'pipe.xml'
    os.mkfifo(fifo)
    with pytest.raises(UnsupportedAssetsError) as info:
        sources.from_file(str(fifo))
    assert 'regular file' in str(info.value)
    with pytest.raises(MissingAssetsError):
        sources.from_file(str(tmp_path / '..' / 'x.xml'))
    with pytest.raises(MissingAssetsError):
        sources.from_file(str(DEFAULT_SCENE), allowed_roots=[str(tmp_path)])


def test_mesh_spawn(world, tmp_path):
    src = sources.from_file(str(SCENES / 'objects' / 'pyramid.obj'))
    world.spawn('pyr', src, position=[0, 1, 0.3])
    world.step(100)
    assert world.entity('pyr').category == 'dynamic'
    world.delete('pyr')
    bad = tmp_path / 'bad.stl'
    bad.write_text('this is not a mesh')
    with pytest.raises(UnsupportedAssetsError):
        sources.from_file(str(bad))


def test_radian_looking_ranges_in_a_degree_model_are_warned_about(caplog):
    """MJCF reads angles in degrees unless told otherwise: range="-1.57 1.57" is +-1.57 deg."""
    arm = ('<body name="b"><joint name="elbow" type="hinge" range="-1.57 1.57"/>'
           '<geom size=".05"/></body>')
    with caplog.at_level('WARNING'):
        World.from_string(f'<mujoco><worldbody>{arm}</worldbody></mujoco>')
    assert 'elbow [-1.57, 1.57]' in caplog.text and 'angle="radian"' in caplog.text
    caplog.clear()
    with caplog.at_level('WARNING'):
        World.from_string(f'<mujoco><compiler angle="radian"/><worldbody>{arm}</worldbody>'
                          '</mujoco>')
        World.from_string('<mujoco><worldbody><body><joint type="hinge" range="-90 90"/>'
                          '<geom size=".05"/></body></worldbody></mujoco>')
    assert 'look like radians' not in caplog.text
    with caplog.at_level('WARNING'):
        sources.from_model_text(f'<mujoco><worldbody>{arm}</worldbody></mujoco>')
    assert 'elbow [-1.57, 1.57]' in caplog.text


def test_mujoco_warnings_go_to_logging_not_to_a_file(tmp_path, monkeypatch, caplog):
    monkeypatch.chdir(tmp_path)
    world = World.from_string(UNSTABLE_MJCF)
    with caplog.at_level('WARNING'), pytest.raises(DivergenceError):
        world.step(40, ctrl=np.array([1.0]))
    assert 'MuJoCo: Nan, Inf or huge value' in caplog.text
    assert not (tmp_path / 'MUJOCO_LOG.TXT').exists()


def test_entity_state_and_snapshot_describe_the_state_at_their_time_stamp():
    """
    After mj_step MuJoCo's body poses still describe the state before the step.

    What we report must match qpos and the time stamp (a falling box: 4 mm per step apart).
    """
    world = World.from_file(str(DEFAULT_SCENE))
    world.set_entity_state('box_b', position=[2, 2, 3])
    world.step(100)
    st = world.get_entity_state('box_b')
    snap = world.snapshot()
    with world.locked() as (m, d):
        body = m.body('box_b').id
        adr = m.jnt_qposadr[m.body_jntadr[body]]
        qpos_z, qvel_z = d.qpos[adr + 2], d.qvel[m.jnt_dofadr[m.body_jntadr[body]] + 2]
    assert st.position[2] == pytest.approx(qpos_z, abs=1e-12)
    assert st.linear_velocity[2] == pytest.approx(qvel_z, abs=1e-12)
    assert snap.body_xpos[body][2] == pytest.approx(qpos_z, abs=1e-12)
    assert st.time == snap.time == pytest.approx(100 * world.timestep)


def test_entity_acceleration_is_the_coordinate_acceleration():
    """
    Free fall reads -g, resting reads 0.

    And a tumbling brick (spun off its principal axes, so its angular velocity wanders) matches the
    finite difference of its twist.
    """
    world = World.from_string("""<mujoco><worldbody>
      <geom type="plane" size="5 5 .1"/>
      <body name="brick" pos="0 0 20"><freejoint/><geom type="box" size=".05 .1 .2"/></body>
      <body name="crate" pos="1 0 .1"><freejoint/><geom type="box" size=".1 .1 .1"/></body>
      </worldbody></mujoco>""")
    world.set_entity_state('brick', angular_velocity=[3, 1, 2])
    world.step(500)  # the crate settles on the floor meanwhile
    brick = world.get_entity_state('brick')
    assert brick.linear_acceleration == pytest.approx([0, 0, -9.81], abs=1e-6)
    world.step(1)
    later = world.get_entity_state('brick')
    fd = (later.angular_velocity - brick.angular_velocity) / world.timestep
    assert np.abs(fd).max() > 1.0  # tumbling for real
    assert brick.angular_acceleration == pytest.approx(fd, abs=0.02 * np.abs(fd).max())
    resting = world.get_entity_state('crate')
    assert np.abs(resting.linear_acceleration).max() < 0.05


_EVERY_STATE_PART = """
<mujoco>
  <size nuserdata="3"/>
  <worldbody>
    <body name="target" mocap="true" pos="0 0 1">
      <geom type="sphere" size=".05" contype="0" conaffinity="0"/>
    </body>
    <body name="arm" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping=".1"/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/>
    </body>
    <body name="crate" pos="1 0 .5"><freejoint/><geom type="box" size=".05 .05 .05"/></body>
    <geom type="plane" size="3 3 .1"/>
  </worldbody>
  <equality><weld body1="target" body2="crate" active="false"/></equality>
  <actuator><general joint="hinge" dyntype="filter" dynprm=".05" gainprm="2"/></actuator>
</mujoco>"""


def test_the_loops_numpy_state_copy_is_mj_getState_bit_for_bit():
    """Every part of the integration state, each set to something, in MuJoCo's order."""
    from sim_node.core.compiled.index import STATE_SPEC
    from sim_node.core.compiled.state import state_copier
    m = mujoco.MjModel.from_xml_string(_EVERY_STATE_PART)
    d = mujoco.MjData(m)
    d.ctrl[:] = 0.7
    d.qfrc_applied[:] = np.arange(m.nv) * 0.01
    d.xfrc_applied[3] = [0.1, 0.2, 0.3, 0.01, 0.02, 0.03]
    d.userdata[:] = [1.5, -2.5, 3.5]
    d.mocap_pos[0] = [0.2, 0.1, 1.1]
    d.mocap_quat[0] = [0.9, 0.1, 0.1, 0.0]
    mujoco.mj_step(m, d, 30)
    d.eq_active[0] = 1
    mujoco.mj_step(m, d, 30)
    assert d.act[0] != 0 and d.time > 0 and np.any(d.qacc_warmstart != 0)
    expected = np.empty(mujoco.mj_stateSize(m, STATE_SPEC))
    mujoco.mj_getState(m, d, expected, STATE_SPEC)
    copy = state_copier(m, d, STATE_SPEC)
    got = np.full_like(expected, np.nan)
    copy(got)
    assert got.tobytes() == expected.tobytes()
    mujoco.mj_step(m, d, 5)  # the copier reads the live arrays, not the ones it was made with
    mujoco.mj_getState(m, d, expected, STATE_SPEC)
    copy(got)
    assert got.tobytes() == expected.tobytes()


def test_a_state_part_the_data_has_no_array_for_leaves_the_copy_to_mujoco():
    """An actuator's delay keeps a history in the state: no numpy copy, and none wrong."""
    from sim_node.core.compiled.index import STATE_SPEC
    from sim_node.core.compiled.state import state_copier
    delayed = ('<mujoco><worldbody><body><joint name="j"/><geom size=".1"/></body>'
               '</worldbody><actuator><motor joint="j" nsample="3" delay="0.01"/></actuator>'
               '</mujoco>')
    m = mujoco.MjModel.from_xml_string(delayed)
    assert mujoco.mj_stateSize(m, int(mujoco.mjtState.mjSTATE_HISTORY)) > 0
    assert state_copier(m, mujoco.MjData(m), STATE_SPEC) is None
    w = World.from_string(delayed)
    w.step(10)  # with mj_getState
    assert w.get_state().step == 10


_COASTING = """<mujoco><option gravity="0 0 0"/><worldbody><body name="slider">
  <joint name="j" type="slide" axis="1 0 0"/>
  <geom type="sphere" size=".1" mass="1" contype="0" conaffinity="0"/></body></worldbody>
  </mujoco>"""


@pytest.mark.parametrize('how', ['step', 'step_batch'])
def test_a_value_gone_bad_in_a_batchs_last_integration_is_caught_in_that_batch(how):
    """
    Catch a bad qpos at the end of the batch; MuJoCo checks at the start of the next step.

    A slider at 9.99e9 m coasting at 9e9 m/s: both fine for MuJoCo (up to 1e10), until the one
    step's integration carries it past. Both ways of stepping (the loop's, quiet about the
    GIL, and everyone else's) say so in that step.
    """
    world = World.from_string(_COASTING)
    with world.locked() as (m, d):
        d.qpos[0], d.qvel[0] = 9.99e9, 9e9
    with pytest.raises(DivergenceError) as info:
        world.step(1) if how == 'step' else world.stepping.batch(1, snapshot=False)
    assert info.value.step == 1 and 'BADQPOS' in ''.join(info.value.report['warnings'])
    assert world.step_count == 0 and world.get_state().values[1] == 9.99e9


CHECKERED = """<mujoco><asset><texture name="grid" type="2d" builtin="checker" width="64"
  height="64" rgb1="1 1 1" rgb2="0 0 0"/><material name="g" texture="grid"/></asset>
  <worldbody><body name="tile"><geom type="box" size=".1 .1 .1" material="g"/></body>
  </worldbody></mujoco>"""


def test_generated_textures_keep_their_pixels_through_spawns_deletes_and_compaction(world):
    """
    Builtin textures (the sky) are generated once; every later compile reuses the pixels.

    What a camera sees must not change: the pixels are those MuJoCo makes from the files.
    """
    from sim_node.core.stepping.design import COMPACT_AFTER_REMOVALS
    sky = mujoco.MjModel.from_xml_path(str(DEFAULT_SCENE))
    grid = mujoco.MjModel.from_xml_string(CHECKERED)

    def pixels(m, name):
        t = m.texture(name).id
        n = m.tex_width[t] * m.tex_height[t] * m.tex_nchannel[t]
        return m.tex_data[m.tex_adr[t]:m.tex_adr[t] + n].copy()
    world.spawn('tiles', sources.from_model_text(CHECKERED), position=[2, 2, 0.5])
    for i in range(COMPACT_AFTER_REMOVALS):  # a compaction writes the spec out as XML
        world.spawn(f'b{i}', box(), position=[-2, 0.3 * i, 0.5])
        with world.locked() as (m, _):  # recompiled from the pixels held
            assert np.array_equal(pixels(m, 'sky'), pixels(sky, 'sky'))
            assert np.array_equal(pixels(m, 'tiles/grid'), pixels(grid, 'grid'))
        world.delete(f'b{i}')
    with world.locked() as (m, _):  # and after the compaction
        assert np.array_equal(pixels(m, 'sky'), pixels(sky, 'sky'))
        assert np.array_equal(pixels(m, 'tiles/grid'), pixels(grid, 'grid'))


def test_the_model_and_its_info_are_read_while_another_thread_holds_the_world(world):
    """What the perception thread asks with every scan waits for nobody, and is one pair."""
    held, done = threading.Event(), threading.Event()

    def hold():
        with world.locked():
            held.set()
            done.wait(10)
    holder = threading.Thread(target=hold)
    holder.start()
    try:
        assert held.wait(10)
        answers = []
        reader = threading.Thread(target=lambda: answers.append(
            (world.model_info, world.live_model())))
        reader.start()
        reader.join(2.0)
        assert answers, 'model_info and live_model waited for the world lock'
        info, (model, generation) = answers[0]
        assert info.generation == generation and model.ngeom == len(info.geom_scoped)
    finally:
        done.set()
        holder.join()
    world.spawn('crate', box(), position=[0.2, 1.0, 0.5])
    model, generation = world.live_model()
    assert generation == world.model_info.generation == info.generation + 1
    assert model.ngeom == len(world.model_info.geom_scoped) == len(info.geom_scoped) + 1
    with pytest.raises(NameNotUniqueError):
        world.spawn('crate', box(), position=[0.2, 2.0, 0.5])
    assert world.live_model() == (model, generation)  # a refused spawn leaves the pair
