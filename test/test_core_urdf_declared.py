"""
What a URDF declares for a simulator becomes the simulation's: Gazebo sensors, ros2_control.

A small robot whose URDF declares, as ROS description packages do, a camera, an IMU and a
laser in ``<gazebo reference>`` tags and a joint with only a velocity command interface.
"""

import math

from conftest import DEFAULT_SCENE
import numpy as np
import pytest
from sim_node.core.control import trajectory
from sim_node.core.models import sources
from sim_node.core.world import World

_INERTIA = '<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/>'
SCOUT = f"""<robot name="scout">
  <link name="world"/>
  <link name="base"><inertial><mass value="2"/>{_INERTIA.format(i=0.02)}</inertial>
    <collision><geometry><box size="0.3 0.2 0.1"/></geometry></collision></link>
  <link name="mount"><inertial><mass value="0.1"/>{_INERTIA.format(i=0.001)}</inertial></link>
  <link name="wheel"><inertial><mass value="0.2"/>{_INERTIA.format(i=0.001)}</inertial></link>
  <joint name="anchor" type="fixed"><parent link="world"/><child link="base"/></joint>
  <joint name="mount_joint" type="fixed"><parent link="base"/><child link="mount"/>
    <origin xyz="0.2 0 0.1"/></joint>
  <joint name="spin" type="continuous"><parent link="base"/><child link="wheel"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit effort="2" velocity="5"/></joint>
  <gazebo reference="mount">
    <sensor type="camera" name="front_cam"><update_rate>30</update_rate>
      <camera><horizontal_fov>1.2</horizontal_fov><image><width>640</width><height>480</height>
      </image></camera></sensor>
    <sensor type="imu" name="imu"/>
    <sensor type="gpu_lidar" name="scan"><pose>0 0 0.05 0 0 0</pose></sensor>
    <sensor type="camera" name="silly"><camera><horizontal_fov>1e9</horizontal_fov>
      <image><width>100000</width><height>100000</height></image></camera></sensor>
    <sensor type="depth" name="front_cam"/>
  </gazebo>
  <gazebo reference="no_such_link"><sensor type="imu" name="lost"/></gazebo>
  <ros2_control name="sys" type="system">
    <joint name="spin"><command_interface name="velocity"/><state_interface name="position"/>
    </joint>
    <joint name="no_such_joint"><command_interface name="velocity"/></joint>
  </ros2_control>
</robot>"""


@pytest.fixture
def world():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('scout', sources.from_model_text(SCOUT), position=[2.0, -2.0, 0.1])
    return w


def test_gazebo_sensors_become_a_camera_an_imu_and_a_laser_on_their_link(world):
    cams, sites, sensors, body_of = world.read(lambda m, d: (
        {m.camera(i).name: (float(m.cam_fovy[i]), int(m.cam_bodyid[i])) for i in range(m.ncam)},
        {m.site(i).name: int(m.site_bodyid[i]) for i in range(m.nsite)},
        {m.sensor(i).name: int(m.sensor_type[i]) for i in range(m.nsensor)},
        lambda name: m.body(name).id))
    # vertical field of view from Gazebo's horizontal one and the tag's 640 x 480
    want = math.degrees(2 * math.atan(math.tan(0.6) * 480 / 640))
    assert cams['scout/front_cam'][0] == pytest.approx(want)
    assert cams['scout/front_cam'][1] == sites['scout/imu_imu'] == sites['scout/scan_lidar']
    assert {'scout/imu_orientation', 'scout/imu_gyro', 'scout/imu_accel'} <= set(sensors)
    # an absurd tag costs nothing: a camera of the node's own size, a sane field of view
    assert cams['scout/silly'][0] == pytest.approx(
        math.degrees(2 * math.atan(math.tan(1.047 / 2) * 480 / 640)))
    assert 'scout/lost_imu' not in sites
    # two sensors of one name (as a depth and an RGB sensor in ROS files): both, told apart
    assert cams['scout/front_cam_2'][1] == cams['scout/front_cam'][1]


def test_the_camera_looks_along_its_links_x_as_gazebos_do(world):
    def look(m, d):
        c = m.camera('scout/front_cam').id
        return d.cam_xmat[c].reshape(3, 3) @ np.array([0, 0, -1.0]), d.xmat[
            m.cam_bodyid[c]].reshape(3, 3)[:, 0]
    world.step(1)
    forward, link_x = world.read(look)
    assert forward == pytest.approx(link_x, abs=1e-9)


def test_a_velocity_interface_is_driven_by_velocity_commands_within_its_limits(world):
    act = world.read(lambda m, d: (list(m.actuator_ctrlrange[m.actuator('scout/spin_velocity')
                                                             .id]),
                                   list(m.actuator_forcerange[m.actuator('scout/spin_velocity')
                                                              .id])))
    assert act == ([-5.0, 5.0], [-2.0, 2.0])  # the URDF's velocity and effort limits
    world.command(['scout/spin'], [3.0], 'velocity')
    world.step(250)
    assert world.get_joint_states()['scout/spin'][1] == pytest.approx(3.0, abs=0.01)
    world.command(['scout/spin'], [50.0], 'velocity')  # beyond its 5 rad/s
    world.step(250)
    assert world.get_joint_states()['scout/spin'][1] == pytest.approx(5.0, abs=0.01)


def test_a_velocity_interface_follows_a_trajectory_through_its_velocity(world):
    start = world.get_joint_states()['scout/spin'][0]
    h = world.follow_trajectory('scout', ['scout/spin'], [1.0, 2.0],
                                [[start + 1.0], [start + 2.5]],
                                goal_tolerance={'scout/spin': (0.01, 0, 0)},
                                goal_time_tolerance=0.5)
    applied = []
    for _ in range(1500):
        world.step(1)
        if h.done:  # (from its last step on, PD holds the point it reached)
            break
        applied.append(world.read(lambda m, d: d.qfrc_applied[m.joint('scout/spin').dofadr[0]]))
    assert h.status.code == trajectory.SUCCESSFUL, h.status.message
    assert max(abs(a) for a in applied) == 0.0  # its velocity actuator, nothing around it
    world.step(500)  # and it holds there
    assert world.get_joint_states()['scout/spin'][0] == pytest.approx(start + 2.5, abs=0.02)
