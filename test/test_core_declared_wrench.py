"""
A force-torque sensor a robot file declares on a joint (issue 43, item 4), as SDF defines it.

HANGER holds a 2 kg tool below its base through a fixed joint whose frame is rolled 0.5 rad;
two sensors on that joint: one as SDF's defaults have it (the child's frame, the wrench the
child applies to the parent), one in the parent's frame, parent to child. Their readings are
checked against m g, turned into each frame (the ROS side gives the sign and the turn:
``test_node_urdf_declared``).
"""

from conftest import DEFAULT_SCENE
import pytest
from sim_node.core.models import sources
from sim_node.core.world import World

_INERTIA = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
MASS, ROLL = 2.0, 0.5
HANGER = f"""<robot name="hanger">
  <link name="world"/>
  <link name="base"><inertial><mass value="1"/>{_INERTIA}</inertial></link>
  <link name="tool"><inertial><mass value="{MASS}"/>{_INERTIA}</inertial></link>
  <joint name="anchor" type="fixed"><parent link="world"/><child link="base"/></joint>
  <joint name="wrist" type="fixed"><parent link="base"/><child link="tool"/>
    <origin xyz="0 0 -0.2" rpy="{ROLL} 0 0"/></joint>
  <gazebo reference="wrist">
    <sensor type="force_torque" name="wrist_ft">
      <update_rate>100</update_rate>
      <plugin name="wrist_ft" filename="libgazebo_ros_ft_sensor.so">
        <ros><namespace>/hanger</namespace><remapping>~/out:=wrist_ft</remapping></ros>
      </plugin>
    </sensor>
    <sensor type="force_torque" name="held">
      <force_torque><frame>parent</frame><measure_direction>parent_to_child</measure_direction>
      </force_torque>
    </sensor>
    <sensor type="force_torque" name="odd">
      <force_torque><frame>elsewhere</frame><measure_direction>sideways</measure_direction>
      </force_torque>
    </sensor>
  </gazebo>
</robot>"""


@pytest.fixture
def world():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('hanger', sources.from_model_text(HANGER), position=[2.0, 2.0, 1.0])
    w.step(50)
    return w


def test_each_sensor_is_read_with_its_frame_direction_and_topic(world):
    got = world.model_info.wrenches
    a, b = got['hanger/wrist_ft_ft'], got['hanger/held_ft']
    assert (a.sign, a.frame, a.frame_id, a.topic) == (-1.0, 'child', 'hanger/tool',
                                                      '/hanger/wrist_ft')
    assert (b.sign, b.frame, b.frame_id, b.parent, b.topic) == (1.0, 'parent', 'hanger/base',
                                                                'hanger', '')


def test_absurd_frame_and_direction_fall_back_to_sdfs_defaults_with_a_warning(caplog):
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('hanger', sources.from_model_text(HANGER), position=[2.0, 2.0, 1.0])
    odd = w.model_info.wrenches['hanger/odd_ft']
    assert (odd.sign, odd.frame) == (-1.0, 'child')
    said = caplog.text
    assert "'odd'" in said and "'elsewhere'" in said and "'sideways'" in said


def test_mujoco_reads_the_parent_holding_the_tool_up_in_the_tools_frame(world):
    """The raw reading the messages are made from: +m g up, in the rolled child frame."""
    def read(m, d):
        s = m.site('hanger/wrist_ft_ft').id
        f = d.sensordata[m.sensor('hanger/wrist_ft_force').adr[0]:][:3]
        return d.site_xmat[s].reshape(3, 3) @ f  # into world axes
    world_force = world.read(read)
    assert world_force == pytest.approx([0, 0, MASS * 9.81], abs=0.02 * MASS * 9.81)
