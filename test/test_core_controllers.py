"""
A robot's ros2_control declaration and its controller manager's rules, without ROS (issue 42).

What a URDF's ``<ros2_control>`` block and Gazebo plugin say, a controllers YAML as ROS reads
it, and the manager's lifecycle and switch rules as controller_manager applies them.
"""

import math
from xml.etree import ElementTree as ET

import controllers_corpus as corpus
import pytest
from sim_node.core.control import diff_drive, manager as core
from sim_node.core.models import controller_yaml, ros2_control, urdf


def _manager(yaml_text: str, tmp_path, joints=('slider_to_cart',), interfaces=('position',)):
    doc = controller_yaml.load(corpus.write(tmp_path, 'c.yaml', yaml_text))
    params = controller_yaml.node_parameters([doc], 'controller_manager')
    commands = {f'{j}/{i}': (None, None) for j in joints for i in interfaces}
    states = tuple(f'{j}/{i}' for j in joints for i in ('position', 'velocity'))
    return core.Manager(commands, states, params,
                        lambda name: controller_yaml.node_parameters([doc], name))


def test_a_urdfs_ros2_control_block_and_gazebo_plugin_are_read_with_its_names():
    root = ET.fromstring(corpus.cart('velocity', '/pkg/config/cart.yaml', namespace='/lab'))
    control = urdf.prepare(root).ros2_control
    assert control.simulated and control.parameters == ('/pkg/config/cart.yaml',)
    assert (control.namespace, control.manager) == ('lab', 'controller_manager')
    (joint,) = control.joints().values()
    assert (joint.name, joint.command, joint.state) == (
        'slider_to_cart', {'velocity': (-10.0, 10.0)}, ('position', 'velocity', 'effort'))
    assert ros2_control.read([]) is None
    # <parameters> as a list, in order, and <controller_manager_name>
    text = corpus.cart('velocity', '/pkg/a.yaml').replace(
        '</plugin>', '<parameters>/pkg/b.yaml</parameters>'
        '<controller_manager_name>/my_manager</controller_manager_name></plugin>')
    control = urdf.prepare(ET.fromstring(text)).ros2_control
    assert (control.parameters, control.manager) == (('/pkg/a.yaml', '/pkg/b.yaml'), 'my_manager')


def test_the_plugins_remapping_rules_are_read_and_a_rule_ros_would_refuse_is_said(caplog):
    # <ros><remapping>, and <hardware_init_timeout>, which needs nothing here
    rules = ('diff_drive_base_controller/cmd_vel:=/cmd_vel', ' ~/odom := /odom ', '/tf:=tf',
             'nonsense', '__node:=other', 'a:=b:=c', 'bad name:=/x')
    root = ET.fromstring(corpus.diff_drive('/pkg/rover.yaml', remappings=rules))
    # gz_ros2_control's wait for its hardware: nothing to wait for here, read without a word
    ET.SubElement(root.find('gazebo/plugin'), 'hardware_init_timeout').text = '20'
    with caplog.at_level('WARNING'):
        control = urdf.prepare(root).ros2_control
    assert control.remappings == ('diff_drive_base_controller/cmd_vel:=/cmd_vel',
                                  '~/odom:=/odom', '/tf:=tf')
    refused = [r.getMessage() for r in caplog.records if '<remapping>' in r.getMessage()]
    assert len(refused) == 4 and all('left out' in m for m in refused)
    assert 'hardware_init_timeout' not in caplog.text
    assert "'nonsense'" in refused[0] and "'__node:=other'" in refused[1]
    assert urdf.prepare(ET.fromstring(corpus.diff_drive('/r.yaml'))).ros2_control.remappings == ()


def test_a_controllers_yaml_is_read_as_ros_reads_it(tmp_path):
    doc = controller_yaml.load(corpus.write(tmp_path, 'a.yaml', """/**:
  ros__parameters:
    use_sim_time: true
/lab/arm_controller:
  ros__parameters:
    joints: [a, b]
    constraints:
      goal_time: 0.5
arm_controller:
  ros__parameters:
    joints: [c]
"""))
    got = controller_yaml.node_parameters([doc], 'arm_controller', 'lab')
    assert got == {'use_sim_time': True, 'joints': ['a', 'b'], 'constraints.goal_time': 0.5}
    assert controller_yaml.node_parameters([doc], 'arm_controller')['joints'] == ['c']
    for text, why in (('a: [b', 'not YAML'), ('- 1\n- 2', 'not a mapping')):
        with pytest.raises(ValueError, match=why):
            controller_yaml.load(corpus.write(tmp_path, 'bad.yaml', text))
    with pytest.raises(ValueError, match='outside the folders'):
        controller_yaml.load(str(tmp_path / 'a.yaml'), lambda p: False)


def test_the_lifecycle_goes_as_the_real_managers_does(tmp_path):
    m = _manager(corpus.cart_yaml('position'), tmp_path)
    assert m.update_rate == 100
    assert m.load('forward_position_controller')[0]
    ok, why = m.load('forward_position_controller')
    assert not ok and 'already loaded' in why
    ok, why = m.load('nameless')
    assert not ok and "'type'" in why
    ok, why = m.switch(['forward_position_controller'], [], core.STRICT)[:2]
    assert not ok and 'configure it first' in why
    assert m.configure('forward_position_controller')[0]
    assert m.switch(['forward_position_controller'], [], core.STRICT)[0]
    assert not m.configure('forward_position_controller')[0]  # active
    assert not m.unload('forward_position_controller')[0]
    assert not m.cleanup('forward_position_controller')[0]
    assert m.switch([], ['forward_position_controller'], core.STRICT)[0]
    assert m.cleanup('forward_position_controller')[0]
    assert m.controllers['forward_position_controller'].state == core.UNCONFIGURED
    assert m.unload('forward_position_controller')[0]
    assert not m.unload('forward_position_controller')[0]


def test_a_controllers_schema_fills_defaults_and_refuses_wrong_types_naming_them(tmp_path):
    """
    Parameters are read once, by the type's schema: defaults filled, wrong types refused.

    At d48b79a a covariance of five values or a tolerance given as a string fell back to a
    default without a word, and each runtime wrote its own defaults again.
    """
    yaml = corpus.DIFF_DRIVE_YAML
    wheels = ('left_wheel_joint', 'right_wheel_joint')
    m = _manager(yaml, tmp_path, joints=wheels, interfaces=('velocity',))
    assert m.load('diff_drive_base_controller')[0]
    assert m.configure('diff_drive_base_controller')[0]
    params = m.controllers['diff_drive_base_controller'].params
    assert params['cmd_vel_timeout'] == 0.5 and params['publish_rate'] == 50.0  # the YAML's
    assert params['use_stamped_vel'] is True and params['wheel_separation_multiplier'] == 1.0
    assert params['twist_covariance_diagonal'] == (0.0,) * 6  # defaults, filled in
    assert params['linear.x.max_velocity'] == 1.0  # a family the limits read, kept
    for old, new, why in (
            ('cmd_vel_timeout: 0.5', "cmd_vel_timeout: 'soon'",
             "'cmd_vel_timeout' is 'soon': it must be a double"),
            ('pose_covariance_diagonal: [0.001, 0.001, 1000000.0, 1000000.0, 1000000.0, 0.01]',
             'pose_covariance_diagonal: [1, 2, 3, 4, 5]',
             "'pose_covariance_diagonal' is [1, 2, 3, 4, 5]: it must be a double_array of 6"),
            ('enable_odom_tf: true', 'enable_odom_tf: 1', "'enable_odom_tf' is 1: it must be"),
            ('wheel_radius: 0.1', 'wheel_radius: -0.1', "'wheel_radius' is -0.1: it must be a "
             'positive number'),
            ('left_wheel_names: [left_wheel_joint]', 'left_wheel_names: []',
             "'left_wheel_names' is []: it must not be empty")):
        assert old in yaml
        folder = tmp_path / str(len(why))
        folder.mkdir(exist_ok=True)
        bad = _manager(yaml.replace(old, new), folder, joints=wheels, interfaces=('velocity',))
        assert bad.load('diff_drive_base_controller')[0]
        ok, message = bad.configure('diff_drive_base_controller')
        assert not ok and why in message, message
    (tmp_path / 'r').mkdir()
    gone = _manager(yaml.replace('    wheel_radius: 0.1\n', ''), tmp_path / 'r',
                    joints=wheels, interfaces=('velocity',))
    assert gone.load('diff_drive_base_controller')[0]
    ok, message = gone.configure('diff_drive_base_controller')
    assert not ok and "'wheel_radius' is not set" in message


def test_a_switch_is_all_or_nothing_unless_best_effort(tmp_path):
    m = _manager(corpus.cart_yaml('position'), tmp_path)
    for name in ('forward_position_controller', 'group_position_controller'):
        assert m.load(name)[0] and m.configure(name)[0]
    both = ['forward_position_controller', 'group_position_controller']
    ok, why, on, off = m.switch(both, [], core.STRICT)
    assert (ok, on) == (False, []) and 'slider_to_cart/position' in why
    assert {c.state for c in m.controllers.values()} == {core.INACTIVE}
    ok, why, on, off = m.switch(both + ['ghost'], [], core.BEST_EFFORT)
    assert ok and on == ['forward_position_controller'] and 'ghost' in why
    ok, _, on, off = m.switch(['group_position_controller'], [], core.FORCE_AUTO)
    assert ok and (on, off) == (['group_position_controller'], ['forward_position_controller'])
    assert m.claimed() == {'slider_to_cart/position': 'group_position_controller'}
    assert not m.switch(['group_position_controller'], [], core.STRICT)[0]  # already active
    assert not m.switch([], ['forward_position_controller'], core.STRICT)[0]  # not active
    assert not m.switch(['x'], [], 7)[0]


def test_what_a_controller_claims_must_be_declared_and_its_joints_known(tmp_path):
    m = _manager(corpus.cart_yaml('velocity'), tmp_path, interfaces=('velocity',))
    text = corpus.cart_yaml('position')  # position controllers on a velocity-only cart
    m2 = _manager(text, tmp_path, interfaces=('velocity',))
    assert m2.load('forward_position_controller')[0]
    assert m2.configure('forward_position_controller')[0]
    ok, why = m2.switch(['forward_position_controller'], [], core.STRICT)[:2]
    assert not ok and 'slider_to_cart/position' in why and 'does not declare' in why
    bad = corpus.cart_yaml('velocity').replace('joints: [slider_to_cart]\n    command',
                                               'joints: [elbow]\n    command')
    m3 = _manager(bad, tmp_path, interfaces=('velocity',))
    assert m3.load('joint_trajectory_controller')[0]
    ok, why = m3.configure('joint_trajectory_controller')
    assert not ok and "['elbow']" in why
    assert m.load('group_velocity_controller')[0] and m.configure('group_velocity_controller')[0]


def test_diff_drive_kinematics_and_odometry_agree_with_the_geometry():
    g = diff_drive.Geometry.of({'wheel_separation': 0.4, 'wheel_radius': 0.1})
    assert diff_drive.wheel_speeds(g, 0.3, 0.0) == pytest.approx((3.0, 3.0))
    assert diff_drive.wheel_speeds(g, 0.0, 1.0) == pytest.approx((-2.0, 2.0))
    odo = diff_drive.odometry(g)
    # a quarter circle of radius 1 m at 0.5 rad/s: left and right wheels on radii 0.8 and 1.2
    for k in range(0, 3142):
        t = k * 0.001
        odo.update(t, 0.8 * 0.5 * t / 0.1, 1.2 * 0.5 * t / 0.1)
    turned = 0.5 * 3.141
    assert (odo.x, odo.y, odo.yaw) == pytest.approx((math.sin(turned), 1 - math.cos(turned),
                                                     turned), abs=1e-9)  # exact arcs
    assert (odo.vx, odo.wz) == pytest.approx((0.5, 0.5))


def test_one_planar_odometry_integrates_arcs_exactly_for_every_kind_of_base():
    """
    The diff drive's, the steering controllers' and the node bases' odometry are one integrator.

    At d48b79a there were three, two of them by Runge-Kutta only: half a circle of 1 m driven
    in five updates ended 3.3 cm off (now exact, as ros2_controllers' odometries integrate arcs).
    """
    from sim_node.core.control.odometry import (BaseOdometry, PlanarOdometry,
                                                SteeringOdometry)
    diff = diff_drive.odometry(diff_drive.Geometry.of({'wheel_separation': 0.4,
                                                       'wheel_radius': 0.1}))
    # half a circle of radius 1 m in five updates of 0.2 pi rad: left on 0.8 m, right on 1.2 m
    car = SteeringOdometry(length=1.0, radius=0.1, steered_traction=False)
    steer = math.atan(1.0 / 1.0)  # a bicycle of 1 m wheelbase on a circle of 1 m
    for k in range(6):
        turned = k * 0.2 * math.pi
        diff.update(k * 0.1, 0.8 * turned / 0.1, 1.2 * turned / 0.1)
        car.update(k * 0.1, turned / 0.1, steer)
    for odo in (diff, car):
        assert (odo.x, odo.y, abs(odo.yaw)) == pytest.approx((0.0, 2.0, math.pi), abs=1e-9)
        assert (odo.vx, odo.wz) == pytest.approx((2 * math.pi, 2 * math.pi))
        assert isinstance(odo, PlanarOdometry)
    assert issubclass(BaseOdometry, PlanarOdometry)
    straight = PlanarOdometry()
    straight.advance(0.0, 0.0, 0.0)
    straight.advance(1.0, 1.0, 1e-9)  # hardly turning: Runge-Kutta, no division by ~0
    assert (straight.x, straight.y) == pytest.approx((1.0, 5e-10), abs=1e-12)


def test_only_simulated_or_topic_based_hardware_takes_a_robots_joints_over(tmp_path):
    """A URDF for a real robot's hardware spawns as any robot: its joints stay the node's."""
    from sim_node.core.models import sources
    from sim_node.core.world import World
    path = corpus.write(tmp_path, 'c.yaml', corpus.cart_yaml('position'))
    world = World.from_file(str(corpus.Path(__file__).resolve().parent.parent / 'scenes'
                                / 'empty.xml'))
    world.spawn('sim_cart', sources.from_model_text(corpus.cart('position', path)))
    real = corpus.cart('position', path).replace('gz_ros2_control/GazeboSimSystem',
                                                 'uf_robot_hardware/UFRobotSystemHardware')
    world.spawn('real_cart', sources.from_model_text(real), position=[0, 3, 0])
    world.spawn('topic_cart', sources.from_model_text(corpus.topic_based()),
                position=[0, -3, 0])
    assert sorted(world.model_info.ros2_control) == ['sim_cart', 'topic_cart']


def test_a_trajectory_controller_names_the_interpolation_it_cannot_run(tmp_path):
    text = corpus.cart_yaml('position').replace(
        'state_interfaces: [position, velocity]',
        'state_interfaces: [position, velocity]\n    interpolation_method: none')
    m = _manager(text, tmp_path)
    assert m.load('joint_trajectory_controller')[0]
    ok, why = m.configure('joint_trajectory_controller')
    assert not ok and "'none'" in why and 'splines' in why


def test_base_limits_ramp_clamp_and_keep_signs_as_the_controllers_limiters():
    """Per 10 ms update: velocity, acceleration and jerk as diff_drive's; sizes as tricycle's."""
    from sim_node.core.control import limits
    dt = 0.01
    lin = limits.signed({'linear.x.max_velocity': 1.0, 'linear.x.max_acceleration': 0.5},
                        'linear.x')
    v, v0 = 0.0, 0.0
    for _ in range(100):  # asked 3 m/s for 1 s: 0.5 m/s^2 gives 0.5 m/s
        v0, v = v, lin.limit(3.0, v, v0, dt)
    assert v == pytest.approx(0.5)
    for _ in range(300):  # then held at 1 m/s, and back the other way at most 0.5 m/s^2
        v0, v = v, lin.limit(3.0, v, v0, dt)
    assert v == pytest.approx(1.0)
    assert lin.limit(-3.0, 1.0, 1.0, dt) == pytest.approx(1.0 - 0.5 * dt)
    jerk = limits.signed({'angular.z.max_jerk': 2.0}, 'angular.z')  # no velocity limit
    # from rest, the second difference grows at most 2 * 2 dt^2 per update
    assert jerk.limit(5.0, 0.0, 0.0, dt) == pytest.approx(2.0 * 2 * dt * dt)
    assert not limits.signed({}, 'linear.x').limits
    traction = limits.traction({'traction.max_velocity': 4.0, 'traction.min_velocity': 1.0})
    assert traction.limit(-9.0, 0.0, 0.0, dt) == -4.0  # sizes: the sign is kept
    assert traction.limit(0.2, 0.0, 0.0, dt) == 1.0  # at least its minimum
    steer = limits.steering({'steering.max_position': 0.15, 'steering.max_velocity': 1.0})
    assert steer.limit(-0.5, -0.149, 0.0, dt) == pytest.approx(-0.15)
    assert steer.limit(0.5, 0.0, 0.0, dt) == pytest.approx(1.0 * dt)  # 1 rad/s from 0
    with pytest.raises(ValueError, match='cannot be negative'):
        limits.traction({'traction.max_velocity': -1.0})
    with pytest.raises(ValueError, match='above'):
        limits.signed({'linear.x.max_velocity': 1.0, 'linear.x.min_velocity': 2.0}, 'linear.x')


def test_a_limit_flag_set_false_turns_its_limit_off_as_jazzys_controllers_do():
    """
    The widely used YAML style: ``has_jerk_limits: false`` beside ``max_jerk: 0.0``.

    At d48b79a the jerk of 0 was taken as a limit: the wheels never turned.
    """
    from sim_node.core.control import limits
    dt = 0.01
    style = {'linear.x.has_velocity_limits': True, 'linear.x.max_velocity': 1.0,
             'linear.x.has_acceleration_limits': True, 'linear.x.max_acceleration': 1.0,
             'linear.x.has_jerk_limits': False, 'linear.x.max_jerk': 0.0}
    lin = limits.signed(style, 'linear.x')
    assert lin.limit(0.5, 0.0, 0.0, dt) == pytest.approx(1.0 * dt)  # the acceleration limit
    assert limits.signed({**style, 'linear.x.has_jerk_limits': True}, 'linear.x').limit(
        0.5, 0.0, 0.0, dt) == 0.0  # a jerk limit of 0, asked for, is one
    off = {'angular.z.has_velocity_limits': False, 'angular.z.max_velocity': 0.1,
           'angular.z.has_acceleration_limits': False, 'angular.z.max_acceleration': 0.0}
    assert not limits.signed(off, 'angular.z').limits
    assert limits.signed({'angular.z.max_velocity': 0.1}, 'angular.z').limit(
        5.0, 0.0, 0.0, dt) == pytest.approx(0.1)  # no flag: the limit given applies
    traction = limits.traction({'traction.has_acceleration_limits': False,
                                'traction.max_acceleration': 0.0,
                                'traction.max_deceleration': 0.0})
    assert traction.limit(3.0, 0.0, 0.0, dt) == 3.0 and traction.limit(0.0, 3.0, 3.0, dt) == 0.0
    steer = limits.steering({'steering.has_position_limits': False, 'steering.max_position': 0.0})
    assert steer.limit(0.4, 0.0, 0.0, dt) == 0.4
    with pytest.raises(ValueError, match="linear.x.has_jerk_limits is 'no': it must be true"):
        limits.signed({'linear.x.has_jerk_limits': 'no'}, 'linear.x')


def test_a_reset_of_state_is_counted_and_the_joint_samples_after_it_carry_the_count(tmp_path):
    """A controller tells a sample taken before a reset of state from one taken after."""
    from sim_node.core.models import sources
    from sim_node.core.records import RESET_STATE, RESET_TIME
    from sim_node.core.world import World
    path = corpus.write(tmp_path, 'c.yaml', corpus.cart_yaml('position'))
    world = World.from_file(str(corpus.Path(__file__).resolve().parent.parent / 'scenes'
                                / 'empty.xml'))
    world.spawn('cart', sources.from_model_text(corpus.cart('position', path)))
    world.sample_joints('cart', ['cart/slider_to_cart'], 100.0)
    world.step(50)
    count = world.clock().resets
    before = [s for s in world.take_sensor_samples() if s.key == 'cart']
    assert before and {s.resets for s in before} == {count}
    world.reset(RESET_STATE)
    world.reset(RESET_TIME)  # time alone is not state: not counted
    assert world.clock().resets == count + 1
    world.step(50)
    after = [s for s in world.take_sensor_samples() if s.key == 'cart']
    assert after and {s.resets for s in after} == {count + 1}
