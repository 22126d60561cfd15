"""
Contacts (issue 43, item 3): what touches what, where, how deep and how hard, in simulated time.

Checked against statics, not the implementation: a crate resting on the floor is held up by
its weight, m g; a gripper's two fingers closed on a block each touch it and push it from
their own side; apart, nothing touches. Collisions are named as Gazebo scopes them.
"""

import logging

from conftest import DEFAULT_SCENE
import numpy as np
import pytest
from sim_node.core.devices.contacts import ContactReport
from sim_node.core.errors import InvalidArgumentError
from sim_node.core.models import sources
from sim_node.core.world import World

G = 9.81
_I = '<inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/>'
MASS = 3.0
CRATE = f"""<robot name="crate">
  <link name="base"><inertial><mass value="{MASS}"/>{_I}</inertial>
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
    <collision name="lid"><origin xyz="0 0 0.12"/><geometry><sphere radius="0.02"/></geometry>
    </collision>
    <collision><origin xyz="0 0 0.16"/><geometry><sphere radius="0.02"/></geometry></collision>
  </link>
  <gazebo reference="base">
    <sensor name="bottom" type="contact">
      <update_rate>20</update_rate>
      <contact><collision>base_collision</collision><collision>hull_collision</collision>
      </contact>
      <plugin name="bumper" filename="libgazebo_ros_bumper.so">
        <ros><namespace>/crate</namespace><remapping>bumper_states:=bumper</remapping></ros>
        <frame_name>world</frame_name>
      </plugin>
    </sensor>
  </gazebo>
</robot>"""

# A gripper fixed to the world 5 cm up, two fingers sliding along y, a touch sensor on each.
GRIPPER = f"""<robot name="gripper">
  <link name="world"/>
  <link name="palm"><inertial><mass value="1"/>{_I}</inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.04 0.2 0.02"/></geometry></collision>
  </link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="palm"/></joint>
  <link name="left_finger"><inertial><mass value="0.1"/>{_I}</inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.02 0.01 0.08"/></geometry>
    </collision></link>
  <link name="right_finger"><inertial><mass value="0.1"/>{_I}</inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.02 0.01 0.08"/></geometry>
    </collision></link>
  <joint name="left" type="prismatic"><parent link="palm"/><child link="left_finger"/>
    <origin xyz="0 0.06 0"/><axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.06" effort="20" velocity="1"/></joint>
  <joint name="right" type="prismatic"><parent link="palm"/><child link="right_finger"/>
    <origin xyz="0 -0.06 0"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.06" effort="20" velocity="1"/></joint>
  <gazebo reference="left_finger"><sensor name="left_touch" type="contact">
    <update_rate>50</update_rate>
    <contact><collision>left_finger_collision</collision></contact></sensor></gazebo>
  <gazebo reference="right_finger"><sensor name="right_touch" type="contact">
    <update_rate>50</update_rate>
    <contact><collision>right_finger_collision</collision></contact></sensor></gazebo>
</robot>"""
BLOCK = ('<mujoco><worldbody><body name="block"><freejoint/>'
         '<geom name="block" type="box" size="0.02 0.02 0.02" mass="0.05"/>'
         '</body></worldbody></mujoco>')


def reports(world: World, name: str) -> list:
    return [r for r in world.take_sensor_samples()
            if isinstance(r, ContactReport) and r.name == name]


@pytest.fixture
def world():
    return World.from_file(str(DEFAULT_SCENE))


def test_a_crate_on_the_floor_is_held_up_by_its_weight(world):
    world.spawn('crate', sources.from_model_text(CRATE), position=[3.0, 3.0, 0.1])
    world.step(500)  # settled
    world.take_sensor_samples()
    world.step(100)
    got = reports(world, 'crate/bottom')
    assert len(got) == 4  # 20 Hz for 0.2 s
    info = world.model_info
    for report in got:
        (touch,) = report.touches
        assert info.geom_scoped[touch.geom1] == 'crate::base::base_collision'
        assert info.geom_scoped[touch.geom2] == 'world::world::floor'
        # the floor pushes the crate up by its weight; the normal points from crate to floor
        assert touch.forces.sum(axis=0) == pytest.approx([0, 0, MASS * G], rel=0.02, abs=1e-3)
        assert np.allclose(touch.normals, [0, 0, -1], atol=1e-6)
        assert np.all(touch.depths >= 0) and np.all(touch.depths < 1e-3)
        assert np.allclose(touch.positions[:, 2], 0.0, atol=1e-3)  # on the floor


def test_the_sensors_rate_topic_and_collisions_are_read_and_a_wrong_collision_left_out(
        world, caplog):
    with caplog.at_level(logging.WARNING):
        world.spawn('crate', sources.from_model_text(CRATE), position=[3.0, 3.0, 0.1])
    decl = world.model_info.contacts['crate/bottom']
    assert decl.rate_hz == 20.0 and decl.topic == '/crate/bumper'
    assert [world.model_info.geom_scoped[g] for g in decl.geoms] == [
        'crate::base::base_collision']
    said = [r.getMessage() for r in caplog.records if 'hull_collision' in r.getMessage()]
    assert said and "'bottom'" in said[0] and 'base_collision' in said[0]
    # Gazebo's names for a link's collisions: its own or the link's, then _collision, then _i
    scoped = [s for s in world.model_info.geom_scoped if s.startswith('crate::')]
    assert scoped == ['crate::base::base_collision', 'crate::base::lid_collision_1',
                      'crate::base::base_collision_2']


def test_a_grippers_fingers_report_both_contacts_closed_and_none_apart(world):
    world.spawn('gripper', sources.from_model_text(GRIPPER), position=[-3.0, -3.0, 0.0])
    world.spawn('block', sources.from_model_text(BLOCK), position=[-3.0, -3.0, 0.02])
    world.step(200)
    world.take_sensor_samples()
    world.step(50)
    apart = [r for r in world.take_sensor_samples() if isinstance(r, ContactReport)
             and r.name.startswith('gripper/')]
    assert apart and all(r.touches == () for r in apart)
    world.command(['gripper/left', 'gripper/right'], [0.05, 0.05], 'position')
    world.step(1000)
    world.take_sensor_samples()
    world.step(50)
    got = world.take_sensor_samples()
    info = world.model_info
    for side, push in (('left', -1.0), ('right', 1.0)):
        last = [r for r in got if isinstance(r, ContactReport)
                and r.name == f'gripper/{side}_touch'][-1]
        names = {(info.geom_scoped[t.geom1], info.geom_scoped[t.geom2]) for t in last.touches}
        assert names == {(f'gripper::{side}_finger::{side}_finger_collision',
                          'block::block::block')}
        force = sum(t.forces.sum(axis=0) for t in last.touches)
        # the block pushes the finger back out: left finger towards +y, right towards -y
        assert np.sign(force[1]) == -push and abs(force[1]) > 0.1


def test_mujoco_contact_and_touch_sensors_report_and_any_entity_on_request():
    world = World.from_string("""<mujoco><worldbody>
      <geom name="floor" type="plane" size="5 5 0.1"/>
      <body name="puck" pos="0 0 0.05"><freejoint/>
        <geom name="puck" type="cylinder" size="0.1 0.05" mass="2"/>
        <site name="pad" type="box" size="0.11 0.11 0.06"/></body>
      <body name="cube" pos="1 0 0.05"><freejoint/>
        <geom name="cube" type="box" size="0.05 0.05 0.05" mass="0.5"/></body>
    </worldbody><sensor>
      <contact name="puck_floor" geom1="puck" geom2="floor" data="found"/>
      <touch name="pad" site="pad"/>
    </sensor></mujoco>""")
    world.report_contacts(['cube', 'not_yet'], rate_hz=25)
    world.step(500)
    world.take_sensor_samples()
    world.step(100)  # 0.2 s
    got = [r for r in world.take_sensor_samples() if isinstance(r, ContactReport)]
    by_name = {}
    for r in got:
        by_name.setdefault(r.name, []).append(r)
    assert set(by_name) == {'puck_floor', 'pad', 'cube'}
    # 25 Hz: the rate asked for, also that of sensors that declare none
    assert [len(by_name[n]) for n in ('cube', 'puck_floor', 'pad')] == [5, 5, 5]
    info = world.model_info
    for name, mass in (('puck_floor', 2.0), ('pad', 2.0), ('cube', 0.5)):
        (touch,) = by_name[name][-1].touches
        assert info.geom_scoped[touch.geom2] == 'world::world::floor'
        assert touch.forces.sum(axis=0)[2] == pytest.approx(mass * G, rel=0.02)
    with pytest.raises(InvalidArgumentError, match='not in'):
        world.report_contacts(['cube'], rate_hz=float('nan'))
    with pytest.raises(InvalidArgumentError):
        world.report_contacts(['cube'], rate_hz=1e6)
