"""
Mobile bases in the core: found in the model, driven by physics, measured against theory.

The mobile scene's rover (two wheels of 0.06 m, 0.36 m apart, velocity actuators) and omni (a
holonomic base on planar joints), and the corpus's cart URDF (a Gazebo diff-drive plugin).
Distances and turns are checked against v t and w t once the base is up to speed (it
accelerates first), odometry against the simulation's own pose.
"""

import math
from pathlib import Path
import sys

from conftest import SCENES
import numpy as np
import pytest
from sim_node.core.base import quat
from sim_node.core.control import bases, drives
from sim_node.core.control.odometry import BaseOdometry
from sim_node.core.errors import InvalidArgumentError, NotFoundError
from sim_node.core.models import sources
from sim_node.core.world import World

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
import corpus  # noqa: E402, I100

STEP = 0.02  # a command every 20 ms of simulated time, as a 50 Hz nav2 controller sends


@pytest.fixture
def world():
    w = World.from_file(str(SCENES / 'mobile.xml'))
    w.step(250)  # settled on its wheels
    return w


def drive(w: World, entity: str, vx: float, vy: float, wz: float, seconds: float,
          each=None) -> None:
    for _ in range(int(round(seconds / STEP))):
        w.drive(entity, vx, vy, wz)
        w.step(int(round(STEP / w.timestep)))
        if each is not None:
            each()


def planar(w: World, entity: str) -> tuple:
    s = w.get_entity_state(entity)
    return np.array(s.position[:2]), quat.yaw_of(s.quat_wxyz)


def test_the_scenes_bases_are_found_and_measured_from_the_model(world):
    found = world.bases()
    rover, omni = found['rover'], found['omni']
    assert (rover.kind, rover.found_by) == (bases.DIFF_DRIVE, 'wheel names')
    assert rover.left == ('left_wheel_joint',) and rover.right == ('right_wheel_joint',)
    assert rover.radius == pytest.approx(0.06) and rover.separation == pytest.approx(0.36)
    assert rover.signs == (1.0, 1.0)  # +y axes: turning positively rolls forward
    assert omni.kind == bases.PLANAR_JOINTS
    assert omni.planar == ('omni_x', 'omni_y', 'omni_yaw')
    assert set(found) == {'rover', 'omni'}  # walls, crates: no base


def test_a_straight_line_covers_v_t(world):
    drive(world, 'rover', 0.5, 0, 0, 1.0)  # up to speed
    (p0, yaw0), t0 = planar(world, 'rover'), world.time
    drive(world, 'rover', 0.5, 0, 0, 2.0)
    (p1, yaw1), t1 = planar(world, 'rover'), world.time
    assert np.linalg.norm(p1 - p0) == pytest.approx(0.5 * (t1 - t0), rel=0.05)
    assert abs(p1[1] - p0[1]) < 0.02 and abs(yaw1 - yaw0) < 0.02  # straight ahead (+x)


def test_a_turn_in_place_turns_w_t_and_stays_put(world):
    drive(world, 'rover', 0, 0, 1.0, 0.5)
    (p0, yaw0), t0 = planar(world, 'rover'), world.time
    drive(world, 'rover', 0, 0, 1.0, 1.0)
    (p1, yaw1), t1 = planar(world, 'rover'), world.time
    assert quat.yaw_of(np.array([math.cos((yaw1 - yaw0) / 2), 0, 0,
                                 math.sin((yaw1 - yaw0) / 2)])) == pytest.approx(
        1.0 * (t1 - t0), rel=0.05)
    assert np.linalg.norm(p1 - p0) < 0.1  # about the axle's middle, 5 cm ahead of the origin


def test_wheel_odometry_of_a_square_ends_near_the_truth(world):
    spec = world.bases()['rover']
    odo = BaseOdometry(spec)
    start, yaw0 = planar(world, 'rover')
    path = [0.0, start]

    def wheels():
        js = world.get_joint_states()
        odo.from_wheels(world.time, [js[n][0] for n in spec.wheels])
        here = planar(world, 'rover')[0]
        path[0] += float(np.linalg.norm(here - path[1]))
        path[1] = here
    wheels()
    for _ in range(4):
        drive(world, 'rover', 0.5, 0, 0, 2.0, wheels)
        drive(world, 'rover', 0, 0, 1.0, math.pi / 2, wheels)
    end, _ = planar(world, 'rover')
    c, s = math.cos(yaw0), math.sin(yaw0)
    true_end = np.array([[c, s], [-s, c]]) @ (end - start)  # in the odom frame
    assert path[0] > 3.5  # four sides of about a metre
    assert np.linalg.norm(np.array([odo.x, odo.y]) - true_end) < 0.05 * path[0]


def test_ground_truth_odometry_is_the_simulations_pose(world):
    odo = BaseOdometry(world.bases()['rover'])
    (p0, yaw0) = planar(world, 'rover')
    odo.from_pose(world.time, *planar(world, 'rover'))
    twists = []

    def sample():
        odo.from_pose(world.time, *planar(world, 'rover'))
        twists.append((odo.vx, odo.wz))
    drive(world, 'rover', 0.4, 0, 0.5, 2.0, sample)
    p1, yaw1 = planar(world, 'rover')
    c, s = math.cos(yaw0), math.sin(yaw0)
    rel = np.array([[c, s], [-s, c]]) @ (p1 - p0)
    assert (odo.x, odo.y) == pytest.approx(tuple(rel), abs=1e-9)
    assert odo.yaw == pytest.approx(yaw1 - yaw0, abs=1e-9)
    # The twist over the last second, once up to speed: a rover on two rubber points and a
    # caster turns at 0.5 rad/s on average, but its yaw rate over one 20 ms sample swings by a
    # fifth either way (the wheels' contacts slip and grip), so one sample is not the rate.
    vx, wz = np.mean(twists[-50:], axis=0)
    assert vx == pytest.approx(0.4, rel=0.1) and wz == pytest.approx(0.5, rel=0.1)


def test_without_commands_for_half_a_second_the_base_stops(world):
    drive(world, 'rover', 0.5, 0, 0, 1.0)
    world.step(int(drives.COMMAND_TIMEOUT / world.timestep))  # no command since
    world.step(500)
    assert np.linalg.norm(world.get_entity_state('rover').linear_velocity) < 0.01


def test_a_wall_stops_the_base_it_is_physics(world):
    # 4 m ahead is the east wall (its face at x = 4.0); the chassis reaches 0.2 m past the
    # origin: it stops there, wheels turning or not
    drive(world, 'rover', 1.0, 0, 0, 8.0)
    p, _ = planar(world, 'rover')
    assert 3.6 < p[0] < 4.0 - 0.2 + 0.01
    assert world.get_entity_state('rover').position[2] < 0.2  # not climbing it either


def test_a_holonomic_base_moves_in_its_own_frame(world):
    drive(world, 'omni', 0, 0, 1.0, math.pi / 2)  # turn a quarter to face +y
    _, yaw = planar(world, 'omni')
    assert yaw == pytest.approx(math.pi / 2, abs=0.1)
    drive(world, 'omni', 0.3, 0, 0, 0.5)
    p0, _ = planar(world, 'omni')
    drive(world, 'omni', 0.3, 0.2, 0, 1.0)  # forward is +y now, left is -x
    p1, _ = planar(world, 'omni')
    c, s = math.cos(yaw), math.sin(yaw)
    want = np.array([c * 0.3 - s * 0.2, s * 0.3 + c * 0.2])
    assert p1 - p0 == pytest.approx(want, abs=0.03)


@pytest.mark.parametrize('command', [(math.nan, 0, 0), (0, 0, math.inf), (1e9, 0, 0),
                                     (0, -60.0, 0), ('fast', 0, 0)])
def test_a_bad_command_is_refused_and_the_world_stays_as_it_was(world, command):
    drive(world, 'rover', 0.3, 0, 0, 0.5)
    before = world.get_entity_state('rover').position.copy()
    with pytest.raises(InvalidArgumentError, match='must be finite'):
        world.drive('rover', *command)
    world.step(10)
    after = world.get_entity_state('rover')
    assert np.all(np.isfinite(after.position)) and abs(after.position[0] - before[0]) < 0.05


def test_only_entities_with_a_base_are_driven(world):
    with pytest.raises(InvalidArgumentError, match='no mobile base'):
        world.drive('crate', 0.1)
    with pytest.raises(NotFoundError):
        world.drive('nobody', 0.1)


def test_a_reset_stops_every_base(world):
    drive(world, 'rover', 0.5, 0, 0, 0.5)
    world.reset()
    world.step(500)
    assert np.linalg.norm(world.get_entity_state('rover').linear_velocity) < 0.01


def test_a_urdf_with_a_gazebo_diff_drive_plugin_drives_without_settings(world):
    own = corpus.write_own(corpus.CORPUS / 'own')  # written here, no download
    cart = own / 'cart_description' / 'urdf' / 'cart.urdf'
    world.spawn('cart', sources.from_file(str(cart), allowed_roots=[str(own)]),
                position=[-2.0, -0.5, 0.2])  # clear road ahead (+x)
    world.step(500)
    spec = world.bases()['cart']
    assert (spec.kind, spec.found_by) == (bases.DIFF_DRIVE, 'gazebo plugin')
    assert spec.left == ('cart/left_wheel_joint',)
    assert (spec.radius, spec.separation) == (0.1, 0.36)  # the plugin's own values
    drive(world, 'cart', 0.3, 0, 0, 1.0)
    p0, _ = planar(world, 'cart')
    drive(world, 'cart', 0.3, 0, 0, 1.0)
    p1, _ = planar(world, 'cart')
    assert np.linalg.norm(p1 - p0) == pytest.approx(0.3, rel=0.1)


#: A two-wheeled robot whose right wheel's axis points the other way (as many URDFs have it):
#: turned positively, that wheel rolls backward.
MIRRORED = """<mujoco><worldbody><body name="buggy" pos="0 0 0.05"><freejoint/>
  <geom type="box" size="0.1 0.08 0.02" mass="1"/>
  <geom type="sphere" size="0.02" pos="-0.08 0 -0.03" condim="1" mass="0.05"/>
  <body name="wl" pos="0.03 0.1 0"><joint name="wheel_left" axis="0 1 0"/>
    <geom type="sphere" size="0.05" mass="0.1"/></body>
  <body name="wr" pos="0.03 -0.1 0"><joint name="wheel_right" axis="0 -1 0"/>
    <geom type="sphere" size="0.05" mass="0.1"/></body>
  </body></worldbody></mujoco>"""


def test_a_wheel_whose_axis_points_the_other_way_still_drives_forward(world):
    world.spawn('buggy', sources.from_model_text(MIRRORED), position=[-2.0, -1.5, 0.1])
    world.step(250)
    spec = world.bases()['buggy']
    assert spec.signs == (1.0, -1.0) and spec.separation == pytest.approx(0.2)
    drive(world, 'buggy', 0.3, 0, 0, 0.5)
    (p0, yaw0) = planar(world, 'buggy')
    drive(world, 'buggy', 0.3, 0, 0, 1.0)
    (p1, yaw1) = planar(world, 'buggy')
    assert p1[0] - p0[0] == pytest.approx(0.3, rel=0.1)  # straight ahead, not spinning
    assert abs(yaw1 - yaw0) < 0.05


def test_a_base_measured_again_in_another_pose_is_the_same_base():
    """
    A base measured again after it drove and turned and another entity came is the same.

    The vehicle of Gazebo's scenario world: its 1.2 m between wheels read 1.2000000000000002,
    and the node took it for another base and made its cmd_vel subscription anew.
    """
    from sim_node.core.models import sources
    world = World.from_file(str(Path(__file__).resolve().parent / 'peer' / 'peer_world.xml'))
    world.step(200)
    first = world.bases()['vehicle']
    world.drive('vehicle', 0.3, 0.0, 0.4)
    world.step(500)
    world.spawn('passer_by', sources.primitive('box', [0.1] * 3), position=(4.0, -20.0, 4.0))
    assert world.bases()['vehicle'] == first


def test_the_tracking_loops_velocity_is_mujocos_own():
    """A tumbling, drifting body's velocity at its origin, read without a MuJoCo call."""
    import mujoco
    m = mujoco.MjModel.from_xml_string("""<mujoco><option gravity="0 0 0"/><worldbody>
      <body name="a" pos="0.3 -0.2 0.5"><freejoint/><geom type="box" size="0.2 0.1 0.05"/>
        <body name="arm" pos="0.4 0 0"><joint type="hinge" axis="0 1 0"/>
          <geom type="capsule" size="0.05" fromto="0 0 0 0.5 0 0"/></body></body>
    </worldbody></mujoco>""")
    d = mujoco.MjData(m)
    d.qvel[:] = [0.7, -0.4, 0.2, 1.1, -0.6, 2.3, 1.5]
    mujoco.mj_step(m, d, 20)  # the data as a batch of steps leaves it
    for body in (1, 2):
        want = np.empty(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, body, want, 0)
        assert drives.planar_velocity(m, d, body) == pytest.approx(
            (want[3], want[4], want[2]), abs=1e-12)


#: A puck that only a Gazebo planar-move plugin makes a base: no joint of its own but the free
#: one its spawn gives it.
PUCK = """<robot name="puck">
  <link name="base_link">
    <inertial><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><cylinder radius="0.1" length="0.05"/></geometry></collision>
  </link>
  <gazebo><plugin name="move" filename="libgazebo_ros_planar_move.so">
    <odometry_frame>odom</odometry_frame><robot_base_frame>base_link</robot_base_frame>
  </plugin></gazebo>
</robot>"""


def test_among_many_boxes_a_base_without_hinges_is_found_by_its_plugin(world, tmp_path):
    # Entities without hinges are passed over unless a plugin names them a base: a storm of
    # boxes is not looked at one by one, and the plugin's base must not be passed over with
    # them.
    urdf = tmp_path / 'puck.urdf'
    urdf.write_text(PUCK)
    box = SCENES / 'objects' / 'box.xml'
    for k in range(40):
        world.spawn(f'box_{k}', sources.from_file(str(box), allowed_roots=[str(SCENES)]),
                    position=(3 + 0.3 * (k % 8), -2 + 0.3 * (k // 8), 0.2))
    world.spawn('puck', sources.from_file(str(urdf), allowed_roots=[str(tmp_path)]),
                position=[-2.0, 1.5, 0.1])
    world.step(200)
    found = world.bases()
    assert not any(name.startswith('box_') for name in found)
    assert (found['puck'].kind, found['puck'].found_by) == (bases.PLANAR_FREE, 'gazebo plugin')
    x0 = planar(world, 'puck')[0][0]
    drive(world, 'puck', 0.3, 0, 0, 1.0)
    assert planar(world, 'puck')[0][0] - x0 == pytest.approx(0.3, rel=0.2)
