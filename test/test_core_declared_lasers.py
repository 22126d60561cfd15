"""
Lasers and IMUs as a robot file declares them (issue 43): sweep, range, rate, noise, frame, topic.

RANGER declares, as ROS description packages do, a 270-degree laser of 541 rays between 0.2
and 12 m at 15 Hz with noise (Gazebo classic's ray sensor and its ROS 2 plugin), a 16-ring 3D
lidar (current Gazebo's gpu_lidar with its own topic and frame id), an IMU at 250 Hz with
noise, and a laser whose every value is absurd. The sweeps are checked against the scene's
geometry, as the camera tests do; the IMU against gravity, at rest.
"""

from dataclasses import replace
import logging
import math

from conftest import DEFAULT_SCENE
import numpy as np
import pytest
from sim_node.core.errors import InvalidArgumentError, NamespaceInvalidError
from sim_node.core.lidar import LaserConfig, LaserScanner, sweep_of
from sim_node.core.models import sensor_tags, sources
from sim_node.core.world import World

_INERTIA = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
#: The 3D lidar's height above the floor when RANGER is spawned at z = 0.1 (base) + 0.4.
LIDAR3D_Z = 0.5
RANGER = f"""<robot name="ranger">
  <link name="world"/>
  <link name="base_link"><inertial><mass value="5"/>{_INERTIA}</inertial></link>
  <link name="base_front_laser_link"><inertial><mass value="0.1"/>{_INERTIA}</inertial></link>
  <link name="lidar3d_link"><inertial><mass value="0.1"/>{_INERTIA}</inertial></link>
  <joint name="anchor" type="fixed"><parent link="world"/><child link="base_link"/></joint>
  <joint name="front_laser" type="fixed"><parent link="base_link"/>
    <child link="base_front_laser_link"/><origin xyz="0.2 0 0.1"/></joint>
  <joint name="lidar3d" type="fixed"><parent link="base_link"/>
    <child link="lidar3d_link"/><origin xyz="0 0 0.4"/></joint>
  <link name="head_cam_optical_frame"/>
  <joint name="head_cam_optical" type="fixed"><parent link="base_link"/>
    <child link="head_cam_optical_frame"/><origin rpy="-1.5708 0 -1.5708"/></joint>
  <gazebo reference="base_link">
    <sensor type="camera" name="head_cam">
      <update_rate>7</update_rate>
      <camera><horizontal_fov>1.2</horizontal_fov>
        <image><width>400</width><height>300</height></image></camera>
      <plugin name="head_cam" filename="libgazebo_ros_camera.so">
        <ros><namespace>/ranger</namespace></ros>
        <camera_name>head_front_camera</camera_name>
        <frame_name>head_cam_optical_frame</frame_name>
      </plugin>
    </sensor>
  </gazebo>
  <gazebo reference="base_front_laser_link">
    <sensor type="ray" name="front_laser">
      <update_rate>15</update_rate>
      <ray>
        <scan><horizontal><samples>541</samples><resolution>1</resolution>
          <min_angle>-2.356194</min_angle><max_angle>2.356194</max_angle></horizontal></scan>
        <range><min>0.2</min><max>12.0</max><resolution>0.01</resolution></range>
        <noise><type>gaussian</type><mean>0.0</mean><stddev>0.01</stddev></noise>
      </ray>
      <plugin name="front_laser" filename="libgazebo_ros_ray_sensor.so">
        <ros><namespace>/ranger</namespace><remapping>~/out:=scan</remapping></ros>
        <output_type>sensor_msgs/LaserScan</output_type>
        <frame_name>base_front_laser_link</frame_name>
      </plugin>
    </sensor>
  </gazebo>
  <gazebo reference="lidar3d_link">
    <sensor type="gpu_lidar" name="lidar3d">
      <topic>points3d</topic><gz_frame_id>lidar3d_link</gz_frame_id>
      <update_rate>10</update_rate>
      <lidar>
        <scan>
          <horizontal><samples>360</samples><min_angle>-3.14159</min_angle>
            <max_angle>3.14159</max_angle></horizontal>
          <vertical><samples>16</samples><min_angle>-0.2618</min_angle>
            <max_angle>0.2618</max_angle></vertical>
        </scan>
        <range><min>0.1</min><max>30</max></range>
      </lidar>
    </sensor>
  </gazebo>
  <gazebo reference="base_link">
    <sensor type="imu" name="base_imu">
      <update_rate>250</update_rate>
      <imu>
        <angular_velocity>
          <x><noise type="gaussian"><mean>0</mean><stddev>0.01</stddev></noise></x>
          <y><noise type="gaussian"><mean>0</mean><stddev>0.01</stddev></noise></y>
          <z><noise type="gaussian"><mean>0</mean><stddev>0.01</stddev></noise></z>
        </angular_velocity>
        <linear_acceleration>
          <z><noise type="gaussian"><mean>0</mean><stddev>0.1</stddev></noise></z>
        </linear_acceleration>
      </imu>
      <plugin name="base_imu" filename="libgazebo_ros_imu_sensor.so">
        <ros><namespace>/ranger</namespace><remapping>~/out:=imu</remapping></ros>
      </plugin>
    </sensor>
    <sensor type="ray" name="junk">
      <update_rate>1000000</update_rate>
      <ray>
        <scan><horizontal><samples>1000000000</samples><min_angle>-1</min_angle>
          <max_angle>1</max_angle></horizontal></scan>
        <range><min>-1</min><max>-2</max></range>
        <noise><type>gaussian</type><mean>0</mean><stddev>nan</stddev></noise>
      </ray>
      <plugin name="junk" filename="libgazebo_ros_ray_sensor.so">
        <ros><remapping>~/out:=bad topic!</remapping></ros>
        <frame_name>not_a_link</frame_name>
      </plugin>
    </sensor>
  </gazebo>
</robot>"""
BOX = ('<mujoco><worldbody><body name="crate"><geom type="box" size="0.25 0.25 0.25"/>'
       '</body></worldbody></mujoco>')


@pytest.fixture
def world():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('ranger', sources.from_model_text(RANGER), position=[2.0, -2.0, 0.1])
    return w


def declared(w: World) -> dict:
    return w.model_info.lasers


def test_each_declared_value_is_read_with_the_robots_names_under_the_entity(world):
    front = declared(world)['ranger/front_laser_lidar']
    assert (front.samples, front.angle_min, front.angle_max) == (541, -2.356194, 2.356194)
    assert (front.range_min, front.range_max, front.rate_hz) == (0.2, 12.0, 15.0)
    assert front.noise == (0.0, 0.01) and front.always_on and not front.points
    assert (front.frame, front.topic) == ('ranger/base_front_laser_link', '/ranger/scan')
    lidar = declared(world)['ranger/lidar3d_lidar']
    assert lidar.vertical == (16, -0.2618, 0.2618) and lidar.points
    assert (lidar.frame, lidar.topic, lidar.rate_hz) == ('ranger/lidar3d_link', 'points3d',
                                                         10.0)


def test_absurd_values_are_left_out_with_a_warning_naming_the_sensor_and_value(caplog):
    with caplog.at_level(logging.WARNING):
        src = sources.from_model_text(RANGER)
    junk = next(d for d in src.urdf_notes.sensors if getattr(d, 'site', '') == 'junk_lidar')
    assert (junk.rate_hz, junk.samples, junk.range_min, junk.range_max, junk.noise) == \
        (None, None, None, None, None)
    assert (junk.frame, junk.topic) == ('base_link', '')  # its link; the node's own topic
    said = [r.getMessage() for r in caplog.records if "'junk'" in r.getMessage()]
    for value in ("'1000000'", '1000000000', "('-1', '-2')", "'nan'", "'not_a_link'",
                  "'bad topic!'"):
        assert any(value in s for s in said), (value, said)
    # and the robot spawns with them
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('ranger', src, position=[2.0, -2.0, 0.1])
    assert 'ranger/junk_lidar' in declared(w)


def test_the_declared_sweep_sees_the_scene_as_declared_with_seeded_noise(world):
    world.spawn('crate', sources.from_model_text(BOX), position=[3.0, -2.0, 0.25])
    world.step(1)
    site = 'ranger/front_laser_lidar'
    sweep = sweep_of(declared(world)[site], LaserConfig())
    (first,) = LaserScanner(world).scan([site], {site: sweep})
    (again,) = LaserScanner(world).scan([site], {site: sweep})
    assert first.ranges.shape == (541,)
    ahead = round((0.0 - sweep.config.angle_min) / sweep.config.angle_increment)
    # the laser 0.2 m ahead of the base at x = 2.0, the crate's face at x = 2.75
    assert first.ranges[ahead] == pytest.approx(0.55, abs=0.05)
    hits = np.isfinite(first.ranges)
    (clean,) = LaserScanner(world).scan([site], {site: replace(sweep, noise=None)})
    noise = first.ranges[hits] - clean.ranges[hits]
    assert 0.005 < np.std(noise) < 0.02  # its 0.01 m
    np.testing.assert_array_equal(first.ranges, again.ranges)  # seeded: a run repeats


def test_a_3d_lidar_sweeps_its_rings_and_its_lowest_ring_meets_the_floor(world):
    site = 'ranger/lidar3d_lidar'
    sweep = sweep_of(declared(world)[site], LaserConfig())
    world.step(1)
    (reading,) = LaserScanner(world).scan([site], {site: sweep})
    assert reading.ranges.shape == (16, 360)
    lowest = reading.ranges[0]
    expect = LIDAR3D_Z / math.sin(0.2618)  # down 15 degrees to the floor
    assert np.median(lowest[np.isfinite(lowest)]) == pytest.approx(expect, rel=0.02)
    assert not np.isfinite(reading.ranges[-1]).any()  # the highest looks up: the sky


def test_a_second_robot_on_the_same_declared_topic_is_refused_unless_namespaced(world):
    with pytest.raises(NamespaceInvalidError, match="on topic '/ranger/.*'ranger'.*namespace"):
        world.spawn('twin', sources.from_model_text(RANGER), position=[-2.0, -2.0, 0.1])
    world.spawn('twin', sources.from_model_text(RANGER), position=[-2.0, -2.0, 0.1],
                namespace='twin')
    assert declared(world)['twin/front_laser_lidar'].topic == '/twin/ranger/scan'
    assert declared(world)['twin/lidar3d_lidar'].topic == '/twin/points3d'


@pytest.mark.parametrize('name, ok', [('scan', True), ('/a/b_2', True), ('bad topic!', False),
                                      ('2scan', False), ('a//b', False), ('', False)])
def test_topic_names_are_judged_as_ros_judges_them(name, ok):
    assert sensor_tags.valid_topic(name) is ok


def test_a_declared_imu_samples_at_its_rate_in_simulated_time_with_its_seeded_noise(world):
    world.take_sensor_samples()  # what the settling left
    t0 = world.time
    world.step(500)  # one second of simulated time, in one batch
    got = [x for x in world.take_sensor_samples() if x[0] == 'ranger/base_imu_imu']
    times = np.array([x[1] for x in got])
    assert len(got) == pytest.approx(250, abs=1)
    # the first when the model came, then every 4 ms on multiples of it
    assert np.diff(times[1:]) == pytest.approx(np.full(len(times) - 2, 1 / 250), abs=1e-9)
    assert t0 <= times[0] < t0 + 1 / 250 + 1e-9
    gyro = np.array([x[3] for x in got])
    acc = np.array([x[4] for x in got])
    assert np.std(gyro, axis=0) == pytest.approx([0.01] * 3, rel=0.2)  # at rest: noise only
    assert np.mean(acc[:, 2]) == pytest.approx(9.81, abs=0.03)  # gravity, held up
    assert np.std(acc[:, 2]) == pytest.approx(0.1, rel=0.2) and np.std(acc[:, 0]) < 1e-6
    imu = world.model_info.imus['ranger/base_imu_imu']
    assert (imu.frame, imu.topic, imu.rate_hz) == ('ranger/base_link', '/ranger/imu', 250.0)
    other = World.from_file(str(DEFAULT_SCENE))  # seeded: the same run, the same noise
    other.spawn('ranger', sources.from_model_text(RANGER), position=[2.0, -2.0, 0.1])
    other.take_sensor_samples()
    other.step(500)
    again = [x for x in other.take_sensor_samples() if x[0] == 'ranger/base_imu_imu']
    np.testing.assert_array_equal(np.array([x[3] for x in again]), gyro)


def test_a_declared_camera_keeps_its_size_rate_frame_and_topic(world):
    cam = world.model_info.cameras_declared['ranger/head_cam']
    assert (cam.width, cam.height, cam.rate_hz) == (400, 300, 7.0)
    assert (cam.frame, cam.topic) == ('ranger/head_cam_optical_frame',
                                      '/ranger/head_front_camera')


#: A depth camera 0.5 m up looking along x at what is 1.2 m ahead, seeing from 0.3 to 2 m,
#: its images grey (Gazebo's L8).
EYES = f"""<robot name="eyes">
  <link name="world"/>
  <link name="base_link"><inertial><mass value="1"/>{_INERTIA}</inertial></link>
  <joint name="anchor" type="fixed"><parent link="world"/><child link="base_link"/>
    <origin xyz="0 0 0.5"/></joint>
  <gazebo reference="base_link">
    <sensor type="depth" name="depth_cam">
      <update_rate>10</update_rate>
      <camera><horizontal_fov>1.0</horizontal_fov>
        <image><width>160</width><height>120</height><format>L8</format></image>
        <clip><near>0.3</near><far>2.0</far></clip></camera>
      <plugin name="depth_cam" filename="libgazebo_ros_camera.so">
        <ros><namespace>/eyes</namespace></ros></plugin>
    </sensor>
  </gazebo>
</robot>"""


def test_a_declared_depth_camera_keeps_its_format_clip_and_depth():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('eyes', sources.from_model_text(EYES), position=[0.0, -3.0, 0.0])
    cam = w.model_info.cameras_declared['eyes/depth_cam']
    assert (cam.encoding, cam.clip, cam.depth, cam.topic) == (
        'mono8', (0.3, 2.0), True, '/eyes/depth_cam')


ODD = """<robot name="odd">
  <link name="base_link"><inertial><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <gazebo reference="base_link">
    <sensor type="camera" name="huge"><update_rate>1e6</update_rate>
      <camera><image><width>100000</width><height>100000</height></image></camera>
      <plugin name="huge" filename="libgazebo_ros_camera.so">
        <camera_name>bad name!</camera_name><frame_name>no_such_frame</frame_name></plugin>
    </sensor>
    <sensor type="depth" name="murky">
      <camera><image><format>YUV_9000</format></image><clip><near>3</near><far>-1</far></clip>
      </camera></sensor>
    <sensor type="imu" name="shaky"><update_rate>-5</update_rate>
      <imu><angular_velocity><x><noise type="gaussian"><mean>0</mean><stddev>nan</stddev>
      </noise></x></angular_velocity></imu></sensor>
  </gazebo>
</robot>"""


def test_absurd_camera_and_imu_values_are_left_out_each_named_and_the_robot_spawns(caplog):
    with caplog.at_level(logging.WARNING):
        w = World.from_file(str(DEFAULT_SCENE))
        w.spawn('odd', sources.from_model_text(ODD), position=[0.0, 3.0, 0.5])
    cam = w.model_info.cameras_declared['odd/huge']
    assert (cam.width, cam.height, cam.rate_hz, cam.frame, cam.topic) == (
        None, None, None, '', '')  # the node's own size, rate, optical frame and topics
    murky = w.model_info.cameras_declared['odd/murky']
    assert (murky.encoding, murky.clip, murky.depth) == ('rgb8', None, True)
    imu = w.model_info.imus['odd/shaky_imu']
    assert imu.rate_hz == sensor_tags.DEFAULT_IMU_RATE_HZ and imu.gyro_noise is None
    said = caplog.text
    for value in ("'huge'", "('100000', '100000')", "'1e6'", "'no_such_frame'", "'bad name!'",
                  "'shaky'", "'-5'", "('0', 'nan')", "'murky'", "'YUV_9000'", "('3', '-1')"):
        assert value in said, value


def test_always_on_false_is_read_for_each_kind():
    """Gazebo's always_on: false: the node sends such a sensor's messages only to listeners."""
    shy = f"""<robot name="shy"><link name="base_link"><inertial><mass value="1"/>{_INERTIA}
      </inertial></link>
      <gazebo reference="base_link">
        <sensor type="ray" name="eye"><always_on>false</always_on></sensor>
        <sensor type="imu" name="ear"><always_on>0</always_on></sensor>
        <sensor type="camera" name="cam"><always_on>false</always_on></sensor>
        <sensor type="contact" name="skin"><always_on>false</always_on></sensor>
      </gazebo></robot>"""
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('shy', sources.from_model_text(shy), position=[0.0, -3.0, 0.5])
    info = w.model_info
    assert not info.lasers['shy/eye_lidar'].always_on
    assert not info.imus['shy/ear_imu'].always_on
    assert not info.cameras_declared['shy/cam'].always_on
    assert not info.contacts['shy/skin'].always_on


#: A laser among things it must see as they are at each scan's time: a box going round it (at
#: 2 rad/s, no gravity), a mesh, a height field and a capsule, all in its plane.
SWEPT = """<mujoco><option gravity="0 0 0" timestep="0.002"/>
  <asset>
    <mesh name="wedge" vertex="0 0 0  0.4 0 0  0 0.4 0  0 0 0.8  0.4 0.4 0.8"/>
    <hfield name="bumps" nrow="3" ncol="3" elevation="0 1 0 1 0 1 0 1 0" size="1 1 0.5 0.1"/>
  </asset>
  <worldbody>
    <body name="scanner" pos="0 0 0.3"><site name="lidar"/></body>
    <body name="rotor" pos="0 0 0.3"><joint name="spin" type="hinge" axis="0 0 1"/>
      <geom type="box" size="0.1 0.1 0.1" pos="1 0 0" mass="1"/></body>
    <geom type="mesh" mesh="wedge" pos="-1.5 0.5 0"/>
    <geom type="hfield" hfield="bumps" pos="0 -2.5 0"/>
    <geom type="capsule" size="0.1 0.3" pos="0 1.6 0.3"/>
  </worldbody>
  <keyframe><key name="home" qvel="2"/></keyframe>
</mujoco>"""


@pytest.mark.parametrize('stepping', ['batch', 'every step'])
@pytest.mark.parametrize('integrator', ['Euler', 'implicitfast', 'RK4'])
def test_laser_poses_come_at_their_rate_and_cast_as_a_scan_of_that_instant(
        integrator, stepping):
    """
    The stepping side takes poses; cast later, off the lock, they read as a scan then.

    A batch of steps is stepped by MuJoCo's rollout, which gives the state at each due time.
    With a command applied before every step (a velocity held by a PD torque), the poses are
    those the step from the due time computed (Euler, implicit), or computed anew after
    Runge-Kutta's steps, whose passes leave those of its last stage.
    """
    swept = SWEPT.replace('timestep="0.002"', f'timestep="0.002" integrator="{integrator}"')

    def world() -> World:
        made = World.from_string(swept)
        if stepping == 'every step':
            made.command(['spin'], [2.0], 'velocity')
        return made
    w = world()
    w.scan_lasers({'lidar': 50.0})
    w.step(251)  # 0.502 s: the poses of 0, 0.02, ..., 0.5
    poses = w.take_laser_poses()
    times = [p.time for p in poses]
    # the first when the schedule starts: at 0 s, or at the first step's end (RK4 stepped
    # one step at a time: its poses are of the data's time)
    start = 0.002 if (integrator, stepping) == ('RK4', 'every step') else 0.0
    np.testing.assert_allclose(times, [start] + list(np.arange(1, 26) * 0.02), atol=1e-9)
    assert w.take_laser_poses() == []  # taken once
    config = LaserConfig(samples=720, range_max=5.0)
    late = LaserScanner(w, config).cast(poses)  # the world is past 0.5 s: each as at its time
    twin = world()
    twin.step(250)  # the same world stopped at 0.5 s, scanned there
    (now,) = LaserScanner(twin, config).scan(['lidar'])
    np.testing.assert_allclose(late[-1].ranges, now.ranges, rtol=0, atol=1e-9)
    twin = world()
    if start:
        twin.step(1)
    (first,) = LaserScanner(twin, config).scan(['lidar'])
    np.testing.assert_allclose(late[0].ranges, first.ranges, rtol=0, atol=1e-9)
    assert np.isfinite(now.ranges).sum() > 60  # the box, the mesh, the bumps, the capsule
    # the box went round: where a ray met it at 0.1 s it meets nothing at 0.5 s
    angle = LaserConfig(samples=720).angles()
    at = np.argmin(np.abs(angle - 0.2))  # the box's bearing at 0.1 s (2 rad/s)
    assert late[5].time == pytest.approx(0.1)
    assert late[5].ranges[at] == pytest.approx(0.9, abs=0.02)  # its near face, 1 - 0.1 m
    assert not np.isfinite(now.ranges[at])


def test_laser_poses_of_a_past_timeline_or_model_are_not_cast_and_bad_rates_are_refused():
    w = World.from_string(SWEPT)
    w.scan_lasers({'lidar': 100.0})
    w.step(10)
    before = w.take_laser_poses()
    assert before
    scanner = LaserScanner(w)
    w.reset()  # a new timeline: those poses are of a past it left
    assert scanner.cast(before, resets=w.clock().resets) == []
    assert len(scanner.cast(before)) == len(before)  # (unless the caller asks to check)
    w.step(10)
    fresh = w.take_laser_poses()
    w.spawn('crate', sources.from_model_text(BOX), position=[0.0, 3.0, 0.3])
    assert scanner.cast(fresh) == []  # another model: its geoms are others
    for rate in (0.0, -5.0, float('nan'), 1e6, True, '15'):
        with pytest.raises(InvalidArgumentError, match='lidar.*rate'):
            w.scan_lasers({'lidar': rate})
    w.scan_lasers({'nope': 10.0})  # a site the model lacks waits for one that has it
    w.step(10)
    assert w.take_laser_poses() == []


@pytest.mark.parametrize('integrator', ['Euler', 'implicitfast', 'RK4'])
def test_a_scanned_world_steps_exactly_as_an_unscanned_one(integrator):
    """Stepping by rollout to take lasers' states changes no bit of the physics."""
    import mujoco
    from conftest import SCENES

    def world(scanned: bool) -> World:
        made = World.from_file(str(SCENES / 'mobile.xml'))
        with made.locked() as (m, _):
            m.opt.integrator = getattr(mujoco.mjtIntegrator, f'mjINT_{integrator.upper()}')
        made.drive('rover', 0.3, 0.0, 0.6, timeout=0.0)
        made.drive('omni', 0.0, 0.1, 0.5, timeout=0.0)
        if scanned:
            made.scan_lasers({'rover_lidar': 30.0})  # between steps: 1 / 30 s is 16.7 steps
        return made
    plain, scanned = world(False), world(True)
    for n in (1, 17, 250, 1000):
        plain.step(n)
        scanned.step(n)
    assert scanned.take_laser_poses()
    a, b = plain.get_state(), scanned.get_state()
    assert a.step == b.step == 1268
    np.testing.assert_array_equal(a.values, b.values)  # time, positions, warm start, ...
