"""
SDF over the wire (issue 54): a Gazebo user's world, its systems, its models, its refusals.

The world loaded by the node, its systems on the topics a ros_gz_bridge user gives them, its
models spawned by model:// and by the spawn tool, and every refusal answered with the
standard's codes while the running world goes on.

The world is written here (one vehicle of each kind and an arm with gz-sim's joint systems);
Gazebo's own defaults give the topics (gz-sim ``src/systems/*``).
"""

import math
import os
from pathlib import Path
import subprocess
import time

from builtin_interfaces.msg import Duration
from conftest import installed_prefix, NodeProcess, wait_for, Watcher
from geometry_msgs.msg import Twist, Vector3
from nav_msgs.msg import Odometry
import pytest
from sensor_msgs.msg import JointState
from simulation_interfaces.msg import SimulationState
from std_msgs.msg import Float32, Float64
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

ROOT = Path(__file__).resolve().parent.parent


def inertial(mass: float, i: float) -> str:
    return (f'<inertial><mass>{mass}</mass><inertia><ixx>{i}</ixx><iyy>{i}</iyy><izz>{i}</izz>'
            '</inertia></inertial>')


def box(size: str) -> str:
    return f'<geometry><box><size>{size}</size></box></geometry>'


def wheel_link(name: str, pose: str, radius: float = 0.15) -> str:
    g = (f'<geometry><cylinder><radius>{radius}</radius><length>0.08</length></cylinder>'
         '</geometry>')
    return (f'<link name="{name}"><pose relative_to="chassis">{pose} -1.5707963 0 0</pose>'
            f'{inertial(1.0, 0.006)}<collision name="c">{g}</collision><visual name="v">{g}'
            '</visual></link>')


def hinge(name: str, parent: str, child: str, xyz: str = '0 1 0', extra: str = '') -> str:
    return (f'<joint name="{name}" type="revolute"><parent>{parent}</parent><child>{child}'
            f'</child><axis><xyz expressed_in="__model__">{xyz}</xyz>{extra}</axis></joint>')


CAR = f"""<model name="car"><pose>0 6 0.2 0 0 0</pose>
  <link name="chassis">{inertial(40, 2)}<collision name="c">{box("1.6 0.9 0.2")}</collision>
    <visual name="v">{box("1.6 0.9 0.2")}</visual></link>
  {wheel_link("rear_left", "-0.6 0.55 -0.05")}{wheel_link("rear_right", "-0.6 -0.55 -0.05")}
  <link name="steer_left"><pose relative_to="chassis">0.6 0.55 -0.05 0 0 0</pose>
    {inertial(0.5, 0.002)}</link>
  <link name="steer_right"><pose relative_to="chassis">0.6 -0.55 -0.05 0 0 0</pose>
    {inertial(0.5, 0.002)}</link>
  {wheel_link("front_left", "0.6 0.55 -0.05")}{wheel_link("front_right", "0.6 -0.55 -0.05")}
  {hinge("rear_left_joint", "chassis", "rear_left")}
  {hinge("rear_right_joint", "chassis", "rear_right")}
  {hinge("steer_left_joint", "chassis", "steer_left", "0 0 1",
         "<limit><lower>-0.6</lower><upper>0.6</upper></limit>")}
  {hinge("steer_right_joint", "chassis", "steer_right", "0 0 1",
         "<limit><lower>-0.6</lower><upper>0.6</upper></limit>")}
  {hinge("front_left_joint", "steer_left", "front_left")}
  {hinge("front_right_joint", "steer_right", "front_right")}
  <plugin filename="gz-sim-ackermann-steering-system"
          name="gz::sim::systems::AckermannSteering">
    <left_joint>rear_left_joint</left_joint><right_joint>rear_right_joint</right_joint>
    <left_steering_joint>steer_left_joint</left_steering_joint>
    <right_steering_joint>steer_right_joint</right_steering_joint>
    <wheel_base>1.2</wheel_base><wheel_separation>1.1</wheel_separation>
    <kingpin_width>1.1</kingpin_width><wheel_radius>0.15</wheel_radius>
    <steer_p_gain>5</steer_p_gain>
    <topic>/car/cmd_vel</topic><odom_topic>/car/odometry</odom_topic>
  </plugin></model>"""

ARM = f"""<model name="arm"><pose>-3 0 0 0 0 0</pose>
  <link name="base"><pose>0 0 1 0 0 0</pose>{inertial(5, 0.1)}</link>
  <link name="upper"><pose>0 0 1 0 0 0</pose>{inertial(1, 0.01)}
    <visual name="v">{box("0.05 0.05 0.4")}</visual></link>
  <link name="lower"><pose>0.3 0 1 0 0 0</pose>{inertial(1, 0.01)}</link>
  <joint name="anchor" type="fixed"><parent>world</parent><child>base</child></joint>
  <joint name="j1" type="revolute"><parent>base</parent><child>upper</child>
    <axis><xyz>0 0 1</xyz><dynamics><damping>0.1</damping></dynamics></axis></joint>
  <joint name="j2" type="revolute"><parent>base</parent><child>lower</child>
    <axis><xyz>0 0 1</xyz><dynamics><damping>0.1</damping></dynamics></axis></joint>
  <plugin filename="gz-sim-joint-position-controller-system"
          name="gz::sim::systems::JointPositionController">
    <joint_name>j1</joint_name><p_gain>20</p_gain><i_gain>1</i_gain><d_gain>2</d_gain>
  </plugin>
  <plugin filename="gz-sim-joint-controller-system" name="gz::sim::systems::JointController">
    <joint_name>j2</joint_name>
  </plugin>
  <plugin filename="gz-sim-joint-state-publisher-system"
          name="gz::sim::systems::JointStatePublisher"/>
  <plugin filename="gz-sim-pose-publisher-system" name="gz::sim::systems::PosePublisher">
    <publish_link_pose>true</publish_link_pose><update_frequency>20</update_frequency>
  </plugin></model>"""

PICKER = f"""<model name="picker"><pose>-6 0 0 0 0 0</pose>
  <link name="base"><pose>0 0 1 0 0 0</pose>{inertial(5, 0.1)}</link>
  <link name="a"><pose>0 0 1 0 0 0</pose>{inertial(1, 0.01)}</link>
  <link name="b"><pose>0 0 1 0 0 0</pose>{inertial(1, 0.01)}</link>
  <joint name="anchor" type="fixed"><parent>world</parent><child>base</child></joint>
  <joint name="ja" type="revolute"><parent>base</parent><child>a</child>
    <axis><xyz>0 0 1</xyz></axis></joint>
  <joint name="jb" type="revolute"><parent>base</parent><child>b</child>
    <axis><xyz>0 0 1</xyz></axis></joint>
  <plugin filename="gz-sim-joint-trajectory-controller-system"
          name="gz::sim::systems::JointTrajectoryController">
    <joint_name>ja</joint_name><joint_name>jb</joint_name>
  </plugin></model>"""

WORLD = f"""<?xml version="1.0"?><sdf version="1.9"><world name="systems">
  <physics name="p" type="ignored"><max_step_size>0.002</max_step_size>
    <real_time_factor>1.0</real_time_factor></physics>
  <plugin filename="gz-sim-physics-system" name="gz::sim::systems::Physics"/>
  <plugin filename="gz-sim-wind-effects-system" name="gz::sim::systems::WindEffects"/>
  <include><uri>model://sun</uri></include>
  <include><uri>model://ground_plane</uri></include>
  <include><uri>{ROOT / "scenes" / "diff_drive.sdf"}</uri></include>
  {CAR}{ARM}{PICKER}</world></sdf>"""


@pytest.fixture(scope='module')
def folders(tmp_path_factory):
    top = tmp_path_factory.mktemp('sdf_node')
    models = top / 'models' / 'crate'
    models.mkdir(parents=True)
    (models / 'model.config').write_text('<model><name>crate</name><sdf version="1.9">'
                                         'model.sdf</sdf></model>')
    (models / 'model.sdf').write_text(
        f'<sdf version="1.9"><model name="crate"><link name="l">{inertial(1, 0.02)}'
        f'<collision name="c">{box("0.3 0.3 0.3")}</collision><visual name="v">'
        f'{box("0.3 0.3 0.3")}</visual></link></model></sdf>')
    (top / 'systems.sdf').write_text(WORLD.replace(
        f'<include><uri>{ROOT / "scenes" / "diff_drive.sdf"}</uri></include>', ''))
    return top


@pytest.fixture(scope='module')
def node(folders):
    os.environ['GZ_SIM_RESOURCE_PATH'] = str(folders / 'models')
    try:
        proc = NodeProcess(f'scene:={folders / "systems.sdf"}',
                           f"resource_paths:=['{folders}']")
    finally:
        del os.environ['GZ_SIM_RESOURCE_PATH']
    yield proc
    code, _ = proc.interrupt()
    assert code == 0, proc.output()


@pytest.fixture(scope='module')
def client(node, rclpy_context):
    from sim_node.ros.client import SimClient
    c = SimClient(timeout_sec=30)
    yield c
    c.close()


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    w.got = {}

    def keep(key):
        return lambda m: w.got.setdefault(key, []).append(m)
    w.node.create_subscription(Odometry, '/car/odometry', keep('car'), 50)
    w.node.create_subscription(JointState, '/world/systems/model/arm/joint_state',
                               keep('arm_js'), 50)
    w.node.create_subscription(TFMessage, '/model/arm/pose', keep('arm_pose'), 50)
    w.node.create_subscription(Float32, '/model/picker/joint_trajectory_progress',
                               keep('progress'), 50)
    yield w
    w.close()


def stream(watch, topic: str, msg, seconds: float) -> None:
    """Publish `msg` at 20 Hz for `seconds` of simulated time, as /clock says."""
    pub = watch.node.create_publisher(type(msg), topic, 10)
    try:
        wait_for(lambda: pub.get_subscription_count() > 0, timeout=20)
        start = wait_for(watch.latest_clock, timeout=20)
        cap = time.monotonic() + 20 * seconds + 10
        while watch.latest_clock() - start < seconds and time.monotonic() < cap:
            pub.publish(msg)
            time.sleep(0.05)
    finally:
        watch.node.destroy_publisher(pub)


def test_the_sdf_world_is_the_scene_named_by_itself(client):
    assert client.current_world() == 'systems'
    names = set(client.entities())
    assert {'ground_plane', 'car', 'arm', 'picker'} <= names
    assert 'diff_drive' in [w for w, _ in client.worlds()]


def test_a_world_system_not_run_here_is_on_diagnostics(client, watch):
    from diagnostic_msgs.msg import DiagnosticArray
    got = []
    sub = watch.node.create_subscription(DiagnosticArray, '/diagnostics', got.append, 10)
    try:
        wait_for(lambda: any(v.key == 'gz_systems_not_run' for m in got for st in m.status
                             for v in st.values), timeout=10)
    finally:
        watch.node.destroy_subscription(sub)
    said = {v.value for m in got for st in m.status for v in st.values
            if v.key == 'gz_systems_not_run'}
    assert said == {'world: WindEffects'}  # Physics is silent; the models' systems all run


def test_an_ackermann_car_turns_as_the_twist_asks_on_its_own_topic(client, watch):
    stream(watch, '/car/cmd_vel', Twist(linear=Vector3(x=1.0), angular=Vector3(z=0.3)), 4.0)
    odom = watch.got['car'][-1]
    assert odom.header.frame_id == 'car/odom' and odom.child_frame_id == 'car/chassis'
    assert odom.twist.twist.linear.x == pytest.approx(1.0, rel=0.05)
    assert odom.twist.twist.angular.z == pytest.approx(0.3, rel=0.05)


def test_joint_controllers_reach_their_position_and_hold_their_velocity(client, watch):
    # gz-sim's /model/arm/joint/j1/0/cmd_pos: its index is no ROS name (left out)
    stream(watch, '/model/arm/joint/j1/cmd_pos', Float64(data=0.5), 4.0)
    stream(watch, '/model/arm/joint/j2/cmd_vel', Float64(data=2.0), 1.0)
    js = watch.got['arm_js'][-1]
    state = dict(zip(js.name, zip(js.position, js.velocity)))
    assert state['j1'][0] == pytest.approx(0.5, abs=0.02)
    assert state['j2'][1] == pytest.approx(2.0, rel=0.02)


def test_the_pose_publisher_sends_the_arms_links(client, watch):
    wait_for(lambda: watch.got.get('arm_pose'), timeout=20)
    frames = {t.child_frame_id for t in watch.got['arm_pose'][-1].transforms}
    assert {'arm::upper', 'arm::lower'} <= frames
    assert {t.header.frame_id for t in watch.got['arm_pose'][-1].transforms} == {'arm'}


def test_a_trajectory_controller_follows_its_points_and_says_its_progress(client, watch):
    msg = JointTrajectory(joint_names=['ja', 'jb'], points=[
        JointTrajectoryPoint(positions=[0.4, -0.3], time_from_start=Duration(sec=1)),
        JointTrajectoryPoint(positions=[0.8, -0.6], time_from_start=Duration(sec=2))])
    stream(watch, '/model/picker/joint_trajectory', msg, 0.2)
    wait_for(lambda: watch.got.get('progress') and watch.got['progress'][-1].data >= 1.0,
             timeout=60)
    time.sleep(1.0)
    js = dict(zip(watch.joint_states.name, watch.joint_states.position))
    assert js['picker/ja'] == pytest.approx(0.8, abs=0.03)
    assert js['picker/jb'] == pytest.approx(-0.6, abs=0.03)


def test_a_gazebo_model_spawns_by_model_uri_and_is_listed(client):
    listed = client.spawnables()
    assert 'model://crate' in listed
    # the stand-ins for classic worlds' includes are not things to spawn (an endless plane)
    assert not any('ground_plane' in u or u.endswith('/sun') for u in listed), listed
    name = client.spawn('crate', uri='model://crate', position=(1, -4, 1))
    assert wait_for(lambda: client.entity_state(name)['position'][2] < 0.2, timeout=20)
    client.delete(name)


def test_an_sdf_string_spawns_as_ros_gz_sims_create_sends_it(client):
    text = (f'<sdf version="1.6"><model name="brick"><link name="l">{inertial(1, 0.02)}'
            f'<collision name="c">{box("0.2 0.1 0.05")}</collision></link></model></sdf>')
    assert client.spawn('', resource_string=text, position=(2, -4, 0.5)) == 'brick'
    client.delete('brick')


def test_the_spawn_tool_takes_a_model_sdf(folders, client):
    env = {**os.environ}
    out = subprocess.run([str(installed_prefix() / 'lib' / 'sim' / 'spawn'), '-file',
                          str(folders / 'models' / 'crate' / 'model.sdf'), '-name', 'tooled',
                          '-x', '3', '-y', '-4', '-z', '0.5'], capture_output=True, text=True,
                         timeout=120, env=env)
    assert out.returncode == 0, out.stderr
    assert 'tooled' in client.entities()
    client.delete('tooled')


def test_a_world_entity_is_not_deleted_and_a_reset_keeps_it(client):
    from sim_node.ros.client.sim_client import SimServiceError
    with pytest.raises(SimServiceError) as err:
        client.delete('car')
    assert err.value.code == 3
    client.reset(4)
    assert 'car' in client.entities()


@pytest.mark.parametrize('body, code, match', [
    ('<model name="m"><link name="l"><visual name="v"><geometry><mesh><uri>missing.dae</uri>'
     '</mesh></geometry></visual></link></model>', 104, 'missing.dae'),
    ('<model name="m"><link name="l"><pose>0 0 nan 0 0 0</pose></link></model>', 103, 'nan'),
    ('<model name="m"><link name="l"/><gripper name="g"/></model>', 106, 'gripper'),
    ('<include><uri>model://../../etc</uri></include>', 104, 'goes up'),
])
def test_a_world_that_cannot_load_is_answered_and_the_running_world_goes_on(
        client, watch, body, code, match):
    from sim_node.ros.client.sim_client import SimServiceError
    before = sorted(client.entities())
    t0 = wait_for(watch.latest_clock, timeout=20)
    text = f'<sdf version="1.9"><world name="bad"><model name="a"><link name="x"/></model>' \
           f'{body}</world></sdf>'
    with pytest.raises(SimServiceError) as err:
        client.load_world(resource_string=text, fail_on_unsupported_element=True)
    assert err.value.code == code and match in err.value.message
    assert client.current_world() == 'systems' and sorted(client.entities()) == before
    wait_for(lambda: watch.latest_clock() > t0 + 0.2, timeout=20)  # still stepping
    assert client.state() == SimulationState.STATE_PLAYING


def test_a_parse_error_names_the_file_and_the_line(client, folders):
    from sim_node.ros.client.sim_client import SimServiceError
    broken = folders / 'broken.sdf'
    broken.write_text('<sdf version="1.9">\n<world name="w">\n<model name="m">\n</world></sdf>')
    with pytest.raises(SimServiceError) as err:
        client.load_world(uri=broken.as_uri())
    assert err.value.code == 103
    assert 'broken.sdf' in err.value.message and 'line 4' in err.value.message


def test_with_missing_assets_ignored_the_world_loads_without_them_saying_which(client, folders):
    from simulation_interfaces import srv
    text = ('<sdf version="1.9"><world name="patchy"><include><uri>model://nowhere</uri>'
            '</include><model name="b"><link name="l"><visual name="v"><geometry><mesh><uri>'
            f'missing.dae</uri></mesh></geometry></visual>{inertial(1, 0.01)}</link></model>'
            '</world></sdf>')
    try:
        answer = client.call('load_world', srv.LoadWorld, srv.LoadWorld.Request(
            resource_string=text, ignore_missing_or_unsupported_assets=True))
        assert answer.world.name == 'patchy' and client.entities() == ['b']
        said = answer.result.error_message
        assert 'model://nowhere' in said and 'missing.dae' in said, said
    finally:
        assert client.load_world(uri=(folders / 'systems.sdf').as_uri()) == 'systems'
        client.play()


def test_an_sdf_world_loads_by_uri_and_by_string_stopped(client, folders):
    world = client.load_world(uri='package://sim/scenes/diff_drive.sdf')
    assert world == 'diff_drive' and client.state() == SimulationState.STATE_STOPPED
    assert {'rover', 'crate'} <= set(client.entities())
    text = (f'<sdf version="1.6"><world name="tiny"><include><uri>model://ground_plane</uri>'
            f'</include><model name="b"><pose>0 0 1 0 0 0</pose><link name="l">'
            f'{inertial(1, 0.01)}<collision name="c">{box("0.1 0.1 0.1")}</collision></link>'
            f'</model></world></sdf>')
    assert client.load_world(resource_string=text) == 'tiny'
    assert sorted(client.entities()) == ['b', 'ground_plane']
    assert client.load_world(uri=(folders / 'systems.sdf').as_uri()) == 'systems'
    client.play()


def test_the_shipped_diff_drive_world_drives_its_rover_as_gz_sims_diff_drive(
        client, watch, folders):
    from tf2_msgs.msg import TFMessage
    assert client.load_world(uri='package://sim/scenes/diff_drive.sdf') == 'diff_drive'
    client.play()
    odoms, tfs = [], []
    subs = [watch.node.create_subscription(Odometry, '/model/rover/odometry', odoms.append, 50),
            watch.node.create_subscription(TFMessage, '/model/rover/tf', tfs.append, 50)]
    try:
        start = client.entity_state('rover')['position']
        stream(watch, '/model/rover/cmd_vel', Twist(linear=Vector3(x=0.5),
                                                    angular=Vector3(z=0.3)), 3.0)
        wait_for(lambda: odoms and tfs, timeout=20)
    finally:
        for sub in subs:
            watch.node.destroy_subscription(sub)
    twist = odoms[-1].twist.twist
    assert twist.linear.x == pytest.approx(0.5, rel=0.05)
    assert twist.angular.z == pytest.approx(0.3, rel=0.05)
    assert odoms[-1].header.frame_id == 'rover/odom'
    assert odoms[-1].child_frame_id == 'rover/chassis'
    assert tfs[-1].transforms[0].child_frame_id == 'rover/chassis'
    moved = client.entity_state('rover')['position']
    assert math.dist(start[:2], moved[:2]) > 0.5  # it went somewhere
    assert client.load_world(uri=(folders / 'systems.sdf').as_uri()) == 'systems'
    client.play()


def sdf_cart(yaml_path: str) -> str:
    """Return controllers_corpus's position cart as an SDF model with gz_ros2_control."""
    return f"""<sdf version="1.9"><model name="sdf_cart">
  <link name="slider"><pose>0 0 1 0 0 0</pose>{inertial(100, 0.01)}
    <visual name="v">{box("30 0.05 0.05")}</visual></link>
  <joint name="world_to_slider" type="fixed"><parent>world</parent><child>slider</child>
  </joint>
  <link name="cart"><pose>0 0 1 0 0 0</pose>{inertial(1, 0.01)}
    <collision name="c">{box("0.5 0.5 0.2")}</collision></link>
  <joint name="slider_to_cart" type="prismatic"><parent>slider</parent><child>cart</child>
    <axis><xyz>1 0 0</xyz><limit><lower>-15</lower><upper>15</upper><effort>1000</effort>
    <velocity>30</velocity></limit></axis></joint>
  <ros2_control name="GazeboSimSystem" type="system">
    <hardware><plugin>gz_ros2_control/GazeboSimSystem</plugin></hardware>
    <joint name="slider_to_cart"><command_interface name="position"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>
  </ros2_control>
  <plugin filename="gz_ros2_control-system" name="gz_ros2_control::GazeboSimROS2ControlPlugin">
    <parameters>{yaml_path}</parameters></plugin>
</model></sdf>"""


def test_gz_ros2_control_in_an_sdf_model_brings_the_same_controller_manager(
        client, watch, folders):
    import controllers_corpus as corpus
    from std_msgs.msg import Float64MultiArray
    path = corpus.write(folders, 'sdf_cart.yaml', corpus.cart_yaml('position'))
    client.spawn('sdf_cart', resource_string=sdf_cart(path), position=(0.0, -8.0, 0.0))
    try:
        for controller in ('joint_state_broadcaster', 'forward_position_controller'):
            failed, _ = corpus.spawner(client, controller)
            assert failed is None, failed
        states = []
        sub = watch.node.create_subscription(
            JointState, '/joint_states',
            lambda m: states.append(m) if 'slider_to_cart' in m.name else None, 100)
        pub = watch.node.create_publisher(Float64MultiArray,
                                          '/forward_position_controller/commands', 10)
        try:
            def at_two():
                pub.publish(Float64MultiArray(data=[2.0]))
                m = states[-1] if states else None
                return m is not None and abs(
                    m.position[list(m.name).index('slider_to_cart')] - 2.0) < 0.02
            wait_for(at_two, timeout=30)
        finally:
            watch.node.destroy_subscription(sub)
            watch.node.destroy_publisher(pub)
    finally:
        client.delete('sdf_cart')
