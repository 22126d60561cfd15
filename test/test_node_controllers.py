"""
A robot's own controllers over the wire (issue 42), brought up as its launch file brings them.

Each robot of ``controllers_corpus`` is spawned from its URDF, then its controllers are
loaded, configured and activated by the calls controller_manager's ``spawner`` makes, in its
order; then driven through the standard controllers' topics and actions, and checked against
what the real ones do.
"""

import math
import time
from typing import Optional

import conftest
from conftest import action_client, serve_node, wait_for, Watcher
import controllers_corpus as corpus
import pytest

FOLDER = {}


@pytest.fixture(scope='module')
def node(tmp_path_factory):
    folder = tmp_path_factory.mktemp('controllers')
    FOLDER['path'] = folder
    yield from serve_node(f'resource_paths:=["{folder}"]')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


def heard(watch, msg_type, topic: str, n: int = 2, timeout: float = 20.0) -> list:
    return conftest.heard(watch, msg_type, topic, n, timeout, reliable=True)


def publish(watch, msg_type, topic: str, msg, times: int = 3) -> None:
    pub = watch.node.create_publisher(msg_type, topic, 10)
    try:
        for _ in range(times):
            pub.publish(msg)
            time.sleep(0.1)
    finally:
        watch.node.destroy_publisher(pub)


def steady(odoms: list, seconds: float = 1.0) -> tuple:
    """
    Return the median (linear x, angular z) of the odometry's last `seconds` (its stamps).

    What a base keeps going at: one message can be a blip (a loaded host's late command, a
    bump), and a sustained error still shows.
    """
    def t(o):
        return o.header.stamp.sec + o.header.stamp.nanosec * 1e-9
    end = t(odoms[-1])
    window = [o for o in odoms if t(o) >= end - seconds]
    assert len(window) >= 10, len(window)
    xs = sorted(o.twist.twist.linear.x for o in window)
    zs = sorted(o.twist.twist.angular.z for o in window)
    return xs[len(xs) // 2], zs[len(zs) // 2]


def _yaw(state: dict) -> float:
    """Return the heading of an entity state (``SimClient.entity_state``)."""
    x, y, z, w = state['orientation_xyzw']
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def listed(sim, manager: str = '/controller_manager') -> dict:
    from controller_manager_msgs.srv import ListControllers
    got = sim.call(f'{manager}/list_controllers', ListControllers, ListControllers.Request())
    return {c.name: c for c in got.controller}


def states(watch, joint: str, topic: str = '/joint_states', n: int = 2) -> list:
    """Return the last `n` JointStates on `topic` that carry `joint` (not the node's own)."""
    from sensor_msgs.msg import JointState
    got = []
    sub = watch.node.create_subscription(
        JointState, topic, lambda m: got.append(m) if joint in m.name else None, 100)
    try:
        wait_for(lambda: len(got) >= n, timeout=20)
    finally:
        watch.node.destroy_subscription(sub)
    return got[-n:]


def position(watch, joint: str, topic: str = '/joint_states') -> float:
    msg = states(watch, joint, topic)[-1]
    return msg.position[list(msg.name).index(joint)]


def spawn_cart(sim, interface: str, name: str = 'cart', namespace: str = '',
               y: float = 3.0) -> None:
    path = corpus.write(FOLDER['path'], f'cart_{interface}.yaml', corpus.cart_yaml(interface))
    sim.spawn(name, resource_string=corpus.cart(interface, path), namespace=namespace,
              position=(0.0, y, 0.0))


def test_a_cart_comes_up_with_its_launch_files_steps_and_goes_where_commanded(sim, watch):
    from std_msgs.msg import Float64MultiArray
    spawn_cart(sim, 'position')
    for controller in ('joint_state_broadcaster', 'forward_position_controller'):
        failed, _ = corpus.spawner(sim, controller)
        assert failed is None, failed
    got = listed(sim)
    assert {n: (c.state, c.type) for n, c in got.items()} == {
        'joint_state_broadcaster': ('active', 'joint_state_broadcaster/JointStateBroadcaster'),
        'forward_position_controller': (
            'active', 'forward_command_controller/ForwardCommandController')}
    assert list(got['forward_position_controller'].claimed_interfaces) == [
        'slider_to_cart/position']
    # /joint_states under the URDF's name, and no second name for it
    assert position(watch, 'slider_to_cart') == pytest.approx(0.0, abs=0.01)
    from sensor_msgs.msg import JointState
    names = {n for m in heard(watch, JointState, '/joint_states', n=10) for n in m.name}
    assert 'cart/slider_to_cart' not in names
    last = states(watch, 'slider_to_cart')[-1]
    assert list(last.name) == ['slider_to_cart', 'rail_brake']  # then its extra_joints
    assert last.position[1] == 0.0
    publish(watch, Float64MultiArray, '/forward_position_controller/commands',
            Float64MultiArray(data=[2.0]))
    wait_for(lambda: abs(position(watch, 'slider_to_cart') - 2.0) < 0.02, timeout=20)
    publish(watch, Float64MultiArray, '/forward_position_controller/commands',
            Float64MultiArray(data=[40.0]))  # beyond the interface's max of 15
    wait_for(lambda: abs(position(watch, 'slider_to_cart') - 15.0) < 0.05, timeout=20)


@pytest.mark.parametrize('interface', ['velocity', 'effort'])
def test_carts_under_velocity_and_effort_controllers_move_as_commanded(sim, watch, interface):
    from std_msgs.msg import Float64MultiArray
    spawn_cart(sim, interface)
    for controller in ('joint_state_broadcaster', f'group_{interface}_controller'):
        failed, _ = corpus.spawner(sim, controller)
        assert failed is None, failed
    publish(watch, Float64MultiArray, f'/group_{interface}_controller/commands',
            Float64MultiArray(data=[0.5 if interface == 'velocity' else 2.0]))
    time.sleep(1.0)
    msgs = states(watch, 'slider_to_cart', n=20)
    (i,) = [k for k, n in enumerate(msgs[-1].name) if n == 'slider_to_cart']
    first, last = msgs[0], msgs[-1]
    dt = (last.header.stamp.sec + last.header.stamp.nanosec * 1e-9
          - first.header.stamp.sec - first.header.stamp.nanosec * 1e-9)
    if interface == 'velocity':
        assert last.velocity[i] == pytest.approx(0.5, abs=0.02)
        assert (last.position[i] - first.position[i]) / dt == pytest.approx(0.5, abs=0.05)
    else:  # 2 N on 1 kg, frictionless: 2 m/s^2
        accel = (last.velocity[i] - first.velocity[i]) / dt
        assert accel == pytest.approx(2.0, rel=0.1)


def test_a_joint_state_broadcaster_publishes_at_its_update_rate_in_simulated_time(sim, watch):
    spawn_cart(sim, 'position')
    failed, _ = corpus.spawner(sim, 'joint_state_broadcaster')
    assert failed is None
    msgs = states(watch, 'slider_to_cart', n=80)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in msgs]
    assert (len(stamps) - 1) / (stamps[-1] - stamps[0]) == pytest.approx(100.0, rel=0.02)


def test_the_managers_answers_for_wrong_orders_and_names_are_the_real_ones(sim, watch):
    from controller_manager_msgs.srv import (CleanupController, ListControllerTypes,
                                             ListHardwareInterfaces, LoadController,
                                             SwitchController, UnloadController)
    spawn_cart(sim, 'position')
    cm = '/controller_manager'
    # a type the YAML does not give, a controller never loaded
    assert not sim.call(f'{cm}/load_controller', LoadController,
                        LoadController.Request(name='no_such_controller')).ok
    req = SwitchController.Request(activate_controllers=['no_such_controller'],
                                   strictness=SwitchController.Request.STRICT)
    assert not sim.call(f'{cm}/switch_controller', SwitchController, req).ok
    # loaded but not configured: cannot be activated
    assert sim.call(f'{cm}/load_controller', LoadController,
                    LoadController.Request(name='forward_position_controller')).ok
    req = SwitchController.Request(activate_controllers=['forward_position_controller'],
                                   strictness=SwitchController.Request.STRICT)
    answer = sim.call(f'{cm}/switch_controller', SwitchController, req)
    assert not answer.ok and 'configure' in answer.message
    assert listed(sim)['forward_position_controller'].state == 'unconfigured'
    # two controllers on one interface: the second is refused, as the real manager does
    for name in ('forward_position_controller', 'group_position_controller'):
        failed, _ = corpus.spawner(sim, name, activate=False)
        assert failed is None
    req = SwitchController.Request(
        activate_controllers=['forward_position_controller', 'group_position_controller'],
        strictness=SwitchController.Request.STRICT)
    answer = sim.call(f'{cm}/switch_controller', SwitchController, req)
    assert not answer.ok and 'slider_to_cart/position' in answer.message
    assert {c.state for c in listed(sim).values()} == {'inactive'}  # nothing half-done
    req.strictness = SwitchController.Request.BEST_EFFORT
    assert sim.call(f'{cm}/switch_controller', SwitchController, req).ok
    states = {n: c.state for n, c in listed(sim).items()}
    assert states == {'forward_position_controller': 'active',
                      'group_position_controller': 'inactive'}
    claimed = sim.call(f'{cm}/list_hardware_interfaces', ListHardwareInterfaces,
                       ListHardwareInterfaces.Request())
    assert [(i.name, i.is_claimed) for i in claimed.command_interfaces] == [
        ('slider_to_cart/position', True)]
    assert {i.name for i in claimed.state_interfaces} == {
        'slider_to_cart/position', 'slider_to_cart/velocity', 'slider_to_cart/effort'}
    # FORCE_AUTO takes the interface over
    req = SwitchController.Request(activate_controllers=['group_position_controller'],
                                   strictness=SwitchController.Request.FORCE_AUTO)
    assert sim.call(f'{cm}/switch_controller', SwitchController, req).ok
    assert listed(sim)['forward_position_controller'].state == 'inactive'
    # an active controller is neither unloaded nor cleaned up
    for srv in (UnloadController, CleanupController):
        service = 'unload_controller' if srv is UnloadController else 'cleanup_controller'
        assert not sim.call(f'{cm}/{service}', srv,
                            srv.Request(name='group_position_controller')).ok
    assert sim.call(f'{cm}/cleanup_controller', CleanupController,
                    CleanupController.Request(name='forward_position_controller')).ok
    assert sim.call(f'{cm}/unload_controller', UnloadController,
                    UnloadController.Request(name='forward_position_controller')).ok
    assert 'forward_position_controller' not in listed(sim)
    types = sim.call(f'{cm}/list_controller_types', ListControllerTypes,
                     ListControllerTypes.Request()).types
    assert 'joint_trajectory_controller/JointTrajectoryController' in types


def test_hardware_components_are_listed_and_auto_switches_as_strict(sim, watch):
    """
    list_hardware_components names the URDF's <ros2_control> system and what is claimed.

    AUTO, with no chained controllers to order, refuses a conflicting switch whole, as STRICT.
    """
    from controller_manager_msgs.srv import ListHardwareComponents, SwitchController
    spawn_cart(sim, 'position')
    cm = '/controller_manager'
    assert corpus.spawner(sim, 'forward_position_controller')[0] is None
    assert corpus.spawner(sim, 'group_position_controller', activate=False)[0] is None
    got = sim.call(f'{cm}/list_hardware_components', ListHardwareComponents,
                   ListHardwareComponents.Request()).component
    assert [(c.name, c.type, c.plugin_name, c.state.label) for c in got] == [
        ('GazeboSimSystem', 'system', 'gz_ros2_control/GazeboSimSystem', 'active')]
    assert [(i.name, i.is_claimed) for i in got[0].command_interfaces] == [
        ('slider_to_cart/position', True)]
    assert [i.name for i in got[0].state_interfaces] == [
        'slider_to_cart/position', 'slider_to_cart/velocity', 'slider_to_cart/effort']
    req = SwitchController.Request(activate_controllers=['group_position_controller'],
                                   strictness=SwitchController.Request.AUTO)
    answer = sim.call(f'{cm}/switch_controller', SwitchController, req)
    assert not answer.ok and 'slider_to_cart/position' in answer.message
    assert {n: c.state for n, c in listed(sim).items()} == {
        'forward_position_controller': 'active', 'group_position_controller': 'inactive'}
    req.deactivate_controllers = ['forward_position_controller']  # with the holder let go
    assert sim.call(f'{cm}/switch_controller', SwitchController, req).ok
    assert listed(sim)['group_position_controller'].state == 'active'


def test_an_arms_trajectory_controller_holds_on_activation_and_follows_goals(sim, watch):
    from control_msgs.action import FollowJointTrajectory
    from trajectory_msgs.msg import JointTrajectoryPoint
    jtc_file = spawn_arm(sim)
    time.sleep(1.0)  # limp: gravity bends it
    failed, _ = corpus.spawner(sim, 'arm_controller', param_file=jtc_file)
    assert failed is None, failed
    assert listed(sim)['arm_controller'].type == \
        'joint_trajectory_controller/JointTrajectoryController'
    held = states(watch, 'joint1')[-1]
    time.sleep(1.0)
    later = states(watch, 'joint1')[-1]
    # every joint of its <ros2_control> block, in the order of their state interfaces' names
    assert list(later.name) == ['finger_joint'] + list(corpus.ARM_JOINTS)
    # held where it was when activated (limp, it sagged)
    assert max(abs(a - b) for a, b in zip(held.position, later.position)) < 0.02
    client = action_client(watch.node, FollowJointTrajectory,
                           '/arm_controller/follow_joint_trajectory')
    assert client.wait_for_server(timeout_sec=10)
    target = [0.3, -0.2, 0.2, 0.1, 0.1, 0.1]
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = list(corpus.ARM_JOINTS)
    goal.trajectory.points = [JointTrajectoryPoint(positions=target)]
    goal.trajectory.points[0].time_from_start.sec = 1
    handle = _send(client, goal)
    assert handle.accepted
    result = _result(handle)
    assert result.error_code == 0, result.error_string
    got = states(watch, 'joint1')[-1]
    at = dict(zip(got.name, got.position))
    assert max(abs(at[j] - q) for j, q in zip(corpus.ARM_JOINTS, target)) < 0.03
    # its sensors' broadcasters: the IMU feels gravity, the wrist holds its 1 kg link
    from geometry_msgs.msg import WrenchStamped
    from sensor_msgs.msg import Imu
    for name in ('imu_sensor_broadcaster', 'force_torque_sensor_broadcaster'):
        assert corpus.spawner(sim, name)[0] is None
    imu = heard(watch, Imu, '/imu_sensor_broadcaster/imu')[-1]
    acc = imu.linear_acceleration
    assert imu.header.frame_id == 'link6'
    assert math.hypot(acc.x, acc.y, acc.z) == pytest.approx(9.81, rel=0.02)
    ft = heard(watch, WrenchStamped, '/force_torque_sensor_broadcaster/wrench')[-1]
    f = ft.wrench.force  # the wrist holds its 1 kg link and two 50 g fingers
    assert math.hypot(f.x, f.y, f.z) == pytest.approx(9.81 * 1.1, rel=0.03)
    # its gripper action opens the fingers to where it is asked
    from control_msgs.action import GripperCommand
    assert corpus.spawner(sim, 'gripper_controller')[0] is None
    gripper = action_client(watch.node, GripperCommand, '/gripper_controller/gripper_cmd')
    assert gripper.wait_for_server(timeout_sec=10)
    opened = GripperCommand.Goal()
    opened.command.position = 0.03
    result = _result(_send(gripper, opened))
    assert result.reached_goal and result.position == pytest.approx(0.03, abs=0.002)
    fingers = states(watch, 'finger_joint')[-1]
    assert fingers.position[list(fingers.name).index('finger_joint')] == pytest.approx(
        0.03, abs=0.002)
    gripper.destroy()
    # a partial goal is refused (allow_partial_joints_goal is false)
    goal.trajectory.joint_names = ['joint1']
    goal.trajectory.points = [JointTrajectoryPoint(positions=[0.0])]
    goal.trajectory.points[0].time_from_start.sec = 1
    assert not _send(client, goal).accepted
    client.destroy()


def spawn_arm(sim) -> str:
    """Spawn the corpus arm with its joint_state_broadcaster up; return its JTC's file."""
    folder = FOLDER['path']
    sim.spawn('arm', resource_string=corpus.arm(corpus.write(folder, 'arm.yaml',
                                                             corpus.ARM_YAML)),
              position=(2.0, 2.0, 0.0))
    jtc_file = corpus.write(folder, 'arm_jtc.yaml', corpus.ARM_JTC_YAML)
    assert corpus.spawner(sim, 'joint_state_broadcaster')[0] is None
    return jtc_file


def _send(client, goal):
    future = client.send_goal_async(goal)
    wait_for(future.done, timeout=20)
    return future.result()


def _result(handle):
    future = handle.get_result_async()
    wait_for(future.done, timeout=30)
    return future.result().result


def spawn_rover(sim, namespace: str = '') -> None:
    """Spawn the corpus diff-drive rover at (2, -2), its broadcaster and controller active."""
    path = corpus.write(FOLDER['path'], 'rover.yaml', corpus.DIFF_DRIVE_YAML)
    sim.spawn('rover', resource_string=corpus.diff_drive(path), position=(2.0, -2.0, 0.15),
              namespace=namespace)
    manager = f'/{namespace}/controller_manager' if namespace else '/controller_manager'
    for controller in ('joint_state_broadcaster', 'diff_drive_base_controller'):
        assert corpus.spawner(sim, controller, manager=manager)[0] is None


def drive(sim, watch, entity: str, msg, topic: str, odom_topic: str, seconds: float,
          first_pose: Optional[float] = None, delete: bool = True) -> tuple:
    """
    Drive `entity` as gz_ros2_control's example programs do; return (odometry, states).

    `msg` goes on `topic` every 50 ms for `seconds` (never a gap a command timeout would
    stop it in); then, unless `delete` is false, `entity` is deleted. Returns the odometry
    heard on `odom_topic` meanwhile and, with `first_pose`, two entity states taken 2 s apart
    from `first_pose` seconds on, while it is driven.
    """
    from nav_msgs.msg import Odometry
    pub = watch.node.create_publisher(type(msg), topic, 10)
    odoms, poses = [], []
    sub = watch.node.create_subscription(Odometry, odom_topic, odoms.append, 100)
    try:
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            pub.publish(msg)
            time.sleep(0.05)
            if first_pose is not None and len(poses) < 2 and \
                    time.monotonic() - t0 > first_pose + 2.0 * len(poses):
                poses.append(sim.entity_state(entity))  # its own motion
    finally:
        watch.node.destroy_subscription(sub)
        watch.node.destroy_publisher(pub)
        if delete:
            sim.delete(entity)
    return odoms, poses


def test_a_diff_drive_base_goes_at_its_commanded_twist_by_its_odometry(sim, watch):
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    spawn_rover(sim)
    cmd = TwistStamped()
    cmd.twist.linear.x = 0.3
    pub = watch.node.create_publisher(TwistStamped, '/diff_drive_base_controller/cmd_vel', 10)
    try:
        odoms = []
        sub = watch.node.create_subscription(Odometry, '/diff_drive_base_controller/odom',
                                             odoms.append, 10)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 4.0:
            pub.publish(cmd)
            time.sleep(0.05)
        watch.node.destroy_subscription(sub)
    finally:
        watch.node.destroy_publisher(pub)
    last = odoms[-1]
    assert (last.header.frame_id, last.child_frame_id) == ('odom', 'base_link')
    assert last.twist.twist.linear.x == pytest.approx(0.3, abs=0.02)
    diagonal = [last.pose.covariance[7 * i] for i in range(6)]
    assert diagonal == [0.001, 0.001, 1e6, 1e6, 1e6, 0.01]  # the YAML's
    assert list(last.twist.covariance) == [0.0] * 36  # none given
    # linear.x.max_acceleration 0.5 m/s^2: from 0.02 to 0.28 m/s takes 0.52 s
    stamp = [o.header.stamp.sec + o.header.stamp.nanosec * 1e-9 for o in odoms]
    speed = [o.twist.twist.linear.x for o in odoms]
    ramp = (next(t for t, v in zip(stamp, speed) if v >= 0.28)
            - next(t for t, v in zip(stamp, speed) if v > 0.02))
    assert ramp == pytest.approx(0.52, abs=0.1)
    late = [o for o in odoms if o.pose.pose.position.x > 0.3]
    a, b = late[0], late[-1]
    dt = (b.header.stamp.sec + b.header.stamp.nanosec * 1e-9
          - a.header.stamp.sec - a.header.stamp.nanosec * 1e-9)
    assert (b.pose.pose.position.x - a.pose.pose.position.x) / dt == pytest.approx(0.3, abs=0.02)
    assert abs(b.pose.pose.position.y) < 0.05
    wait_for(lambda: 'base_link' in watch.tf and watch.tf['base_link'][1] == 'odom')
    # no command for cmd_vel_timeout (0.5 s): it stops
    time.sleep(1.5)
    still = heard(watch, Odometry, '/diff_drive_base_controller/odom')[-1]
    assert abs(still.twist.twist.linear.x) < 0.02
    # the base's true motion agrees with its odometry (both stopped now)
    moved = sim.entity_state('rover')['position']
    assert math.hypot(moved[0] - 2.0, moved[1] + 2.0) == pytest.approx(
        math.hypot(still.pose.pose.position.x, still.pose.pose.position.y), abs=0.1)


def test_the_plugins_remapping_rules_rename_its_controllers_topics(sim, watch):
    # gz_ros2_control's <ros><remapping>: a relative rule (expanded in the robot's namespace),
    # a private one (each controller's own ~), and one ROS would refuse (said, left out).
    from geometry_msgs.msg import TwistStamped
    path = corpus.write(FOLDER['path'], 'rover.yaml', corpus.DIFF_DRIVE_YAML)
    rules = ('diff_drive_base_controller/cmd_vel:=/remapped_cmd', '~/odom:=/remapped_odom',
             'nonsense')
    sim.spawn('remapped', resource_string=corpus.diff_drive(path, remappings=rules),
              position=(-5.0, 5.0, 0.15), namespace='remapped')
    try:
        manager = '/remapped/controller_manager'
        for controller in ('joint_state_broadcaster', 'diff_drive_base_controller'):
            assert corpus.spawner(sim, controller, manager=manager)[0] is None
        topics = dict(watch.node.get_topic_names_and_types())
        assert '/remapped_odom' in topics
        assert '/remapped/diff_drive_base_controller/odom' not in topics
    except BaseException:
        sim.delete('remapped')
        raise
    cmd = TwistStamped()
    cmd.twist.linear.x = 0.3
    odoms, _ = drive(sim, watch, 'remapped', cmd, '/remapped_cmd', '/remapped_odom', 3.0)
    assert odoms and odoms[-1].twist.twist.linear.x == pytest.approx(0.3, abs=0.03)


def test_bad_yaml_types_joints_interfaces_and_files_get_the_managers_answer(
        node, sim, watch, tmp_path):
    from controller_manager_msgs.srv import LoadController
    from std_msgs.msg import Float64MultiArray
    folder = FOLDER['path']
    broken = corpus.write(folder, 'broken.yaml', 'controller_manager: [ros__parameters: {')
    sim.spawn('broken', resource_string=corpus.cart('position', broken), position=(0, 3, 0))
    answer = sim.call('/controller_manager/load_controller', LoadController,
                      LoadController.Request(name='joint_state_broadcaster'))
    assert not answer.ok
    sim.reset()
    odd = corpus.cart_yaml('position').replace(
        'forward_command_controller/ForwardCommandController', 'no_such_pkg/NoSuchController'
    ).replace('joints: [slider_to_cart]\n    command_interfaces',
              'joints: [slider_to_cart, elbow]\n    command_interfaces').replace(
        'interface_name: position', 'interface_name: velocity')
    path = corpus.write(folder, 'odd.yaml', odd)
    sim.spawn('cart', resource_string=corpus.cart('position', path), position=(0, 3, 0))
    failed, _ = corpus.spawner(sim, 'forward_position_controller')  # an unknown type
    assert failed is not None and not failed.ok
    failed, _ = corpus.spawner(sim, 'joint_trajectory_controller')  # a joint it lacks
    assert failed is not None
    odd_group = corpus.write(folder, 'odd_group.yaml', """odd_group:
  ros__parameters:
    type: forward_command_controller/ForwardCommandController
    joints: [slider_to_cart]
    interface_name: velocity
""")
    failed, _ = corpus.spawner(sim, 'odd_group', param_file=odd_group)  # not declared
    assert failed is not None and 'slider_to_cart/velocity' in failed.message
    outside = corpus.write(tmp_path, 'elsewhere.yaml', """group_position_controller:
  ros__parameters:
    type: position_controllers/JointGroupPositionController
    joints: [slider_to_cart]
""")  # a folder the node was not given
    failed, _ = corpus.spawner(sim, 'group_position_controller', param_file=outside)
    assert failed is not None and not failed.ok
    assert 'group_position_controller' not in listed(sim)
    # commands of a wrong length or with NaN are refused; the world steps on
    sim.reset()
    spawn_cart(sim, 'position')
    assert corpus.spawner(sim, 'joint_state_broadcaster')[0] is None
    assert corpus.spawner(sim, 'group_position_controller')[0] is None
    for data in ([1.0, 2.0], [float('nan')]):
        publish(watch, Float64MultiArray, '/group_position_controller/commands',
                Float64MultiArray(data=data))
    before = states(watch, 'slider_to_cart')[-1]
    assert before.position[0] == pytest.approx(0.0, abs=0.02)
    later = states(watch, 'slider_to_cart')[-1]
    assert (later.header.stamp.sec, later.header.stamp.nanosec) > (
        before.header.stamp.sec, before.header.stamp.nanosec)
    # a limit the tricycle cannot take: configure refuses it, the log names it
    sim.reset()
    bad = corpus.TRIKE_YAML.replace('max_velocity: 4.0', 'max_velocity: -4.0')
    sim.spawn('trike', resource_string=corpus.trike(corpus.write(folder, 'bad.yaml', bad)),
              position=(3.0, 3.0, 0.1))
    failed, _ = corpus.spawner(sim, 'tricycle_controller')
    assert failed is not None and not failed.ok
    assert listed(sim)['tricycle_controller'].state == 'unconfigured'
    wait_for(lambda: 'traction.min_velocity and max_velocity (0, -4) cannot be negative'
             in node.output())
    # a limit's flag that is not a bool: configure refuses it, naming it
    sim.reset()
    odd_flag = corpus.DIFF_DRIVE_YAML.replace('has_jerk_limits: false', 'has_jerk_limits: 1', 1)
    sim.spawn('rover', resource_string=corpus.diff_drive(
        corpus.write(folder, 'odd_flag.yaml', odd_flag)), position=(2.0, -2.0, 0.15))
    failed, _ = corpus.spawner(sim, 'diff_drive_base_controller')
    assert failed is not None and not failed.ok
    wait_for(lambda: 'linear.x.has_jerk_limits is 1: it must be true or false' in node.output())


def test_a_second_robot_needs_a_namespace_of_its_own(sim, watch):
    spawn_cart(sim, 'position')
    with pytest.raises(Exception) as err:
        spawn_cart(sim, 'position', name='cart2', y=-3.0)
    assert 'namespace' in str(err.value)
    spawn_cart(sim, 'position', name='cart2', namespace='second', y=-3.0)
    assert corpus.spawner(sim, 'joint_state_broadcaster',
                          manager='/second/controller_manager')[0] is None
    assert position(watch, 'slider_to_cart', '/second/joint_states') == pytest.approx(
        0.0, abs=0.01)


def test_a_mimic_gripper_closes_on_a_block_and_stalls_and_closes_on_nothing(sim, watch):
    from control_msgs.action import GripperCommand, ParallelGripperCommand
    path = corpus.write(FOLDER['path'], 'gripper.yaml', corpus.GRIPPER_YAML)
    sim.spawn('gripper', resource_string=corpus.gripper(path), position=(-2.0, 2.0, 0.0))
    sim.spawn('block', resource_string=corpus.BLOCK, position=(-2.0, 2.0, 0.02))
    for name in ('joint_state_broadcaster', 'gripper_controller'):
        assert corpus.spawner(sim, name)[0] is None
    client = action_client(watch.node, GripperCommand, '/gripper_controller/gripper_cmd')
    assert client.wait_for_server(timeout_sec=10)
    goal = GripperCommand.Goal()
    goal.command.position = 0.05
    result = _result(_send(client, goal))
    # both fingers on the block: the right one, mimicking, holds it from the other side
    assert result.stalled and not result.reached_goal
    assert result.position == pytest.approx(0.035, abs=0.003)
    client.destroy()
    sim.delete('block')
    from controller_manager_msgs.srv import SwitchController
    req = SwitchController.Request(activate_controllers=['parallel_gripper_controller'],
                                   deactivate_controllers=['gripper_controller'],
                                   strictness=SwitchController.Request.STRICT)
    assert corpus.spawner(sim, 'parallel_gripper_controller', activate=False)[0] is None
    assert sim.call('/controller_manager/switch_controller', SwitchController, req).ok
    client = action_client(watch.node, ParallelGripperCommand,
                           '/parallel_gripper_controller/gripper_cmd')
    assert client.wait_for_server(timeout_sec=10)
    goal = ParallelGripperCommand.Goal()
    goal.command.name, goal.command.position = ['left_finger_joint'], [0.05]
    result = _result(_send(client, goal))
    assert result.reached_goal and result.state.position[0] == pytest.approx(0.05, abs=0.003)
    client.destroy()


def test_a_topic_based_robot_takes_the_plugins_commands_and_gives_its_states(sim, watch):
    """As topic_based_ros2_control sends: per interface, the values of the joints that have it."""
    from sensor_msgs.msg import JointState
    sim.spawn('cart', resource_string=corpus.topic_based(), position=(0.0, 3.0, 0.0))
    nan = float('nan')
    for data in ({'position': [1.0, 2.0]}, {'position': [0.5], 'velocity': [1.0, 1.0]}):
        publish(watch, JointState, '/cart_joint_commands',  # refused: arrays that do not fit
                JointState(name=['slider_to_cart', 'spinner'], **data))
    states_before = states(watch, 'spinner', '/cart_joint_states')[-1]
    assert states_before.position[0] == pytest.approx(0.0, abs=0.01)
    publish(watch, JointState, '/cart_joint_commands',
            JointState(name=['slider_to_cart', 'spinner'], position=[1.0], velocity=[2.0]))
    publish(watch, JointState, '/cart_joint_commands',  # NaN: a command not written yet
            JointState(name=['slider_to_cart', 'spinner'], position=[nan], velocity=[2.0]))
    wait_for(lambda: abs(states(watch, 'spinner', '/cart_joint_states')[-1].position[0]
                         - 1.0) < 0.02, timeout=20)
    last = states(watch, 'spinner', '/cart_joint_states')[-1]
    assert list(last.name) == ['slider_to_cart', 'spinner']
    assert last.velocity[1] == pytest.approx(2.0, abs=0.05)
    got = states(watch, 'spinner', '/cart_joint_states', n=30)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in got]
    assert (len(stamps) - 1) / (stamps[-1] - stamps[0]) == pytest.approx(100.0, rel=0.02)


def test_an_ackermann_car_turns_on_the_circle_its_reference_asks_for(sim, watch):
    from geometry_msgs.msg import TwistStamped
    from tf2_msgs.msg import TFMessage
    path = corpus.write(FOLDER['path'], 'car.yaml', corpus.CAR_YAML)
    sim.spawn('car', resource_string=corpus.car(path), position=(-3.0, -3.0, 0.1))
    for controller in ('joint_state_broadcaster', 'ackermann_steering_controller'):
        assert corpus.spawner(sim, controller)[0] is None
    cmd = TwistStamped()
    cmd.twist.linear.x, cmd.twist.angular.z = 0.4, 0.2  # a circle of 2 m radius
    odoms, (start, _) = drive(sim, watch, 'car', cmd, '/ackermann_steering_controller/reference',
                              '/ackermann_steering_controller/odometry', 4.0, first_pose=0.0,
                              delete=False)
    last = odoms[-1]
    assert (last.header.frame_id, last.child_frame_id) == ('car_odom', 'base_link')  # YAML's
    speed, turn = steady(odoms)
    assert speed == pytest.approx(0.4, abs=0.04)
    assert turn == pytest.approx(0.2, abs=0.03)
    tf = heard(watch, TFMessage, '/ackermann_steering_controller/tf_odometry')[-1]
    assert [(t.header.frame_id, t.child_frame_id) for t in tf.transforms] == [
        ('car_odom', 'base_link')]
    moved = sim.entity_state('car')['position']
    assert math.hypot(moved[0] - start['position'][0],
                      moved[1] - start['position'][1]) > 0.5  # it really went


def _car_goes_as_asked(sim, watch, entity: str, text: str, namespace: str,
                       controller: str) -> None:
    """
    Drive a car-like robot as example_ackermann_drive drives the Ackermann demo's car.

    A Twist of 0.5 m/s and 0.3 rad/s on `controller`'s reference_unstamped every 50 ms; its
    speed and turn within 5%, by the controller's odometry and by where the car really goes.
    """
    from geometry_msgs.msg import Twist
    sim.spawn(entity, resource_string=text, namespace=namespace, position=(6.0, -6.0, 0.01))
    manager = f'/{namespace}/controller_manager'
    for name in ('joint_state_broadcaster', controller):
        assert corpus.spawner(sim, name, manager=manager)[0] is None
    cmd = Twist()
    cmd.linear.x, cmd.angular.z = 0.5, 0.3
    odoms, poses = drive(  # at 10 Hz the steering's lag is 1 s
        sim, watch, entity, cmd, f'/{namespace}/{controller}/reference_unstamped',
        f'/{namespace}/{controller}/odometry', seconds=9.0, first_pose=5.0)
    speed, turn = steady(odoms, seconds=2.0)  # 10 Hz odometry
    assert speed == pytest.approx(0.5, rel=0.05)  # the rear wheels' velocity interfaces
    # and the steering's position interfaces, which the front tyres push back: the odometry
    # reads the steering joints' angles
    assert turn == pytest.approx(0.3, rel=0.05)
    (a, b) = poses
    dt = b['stamp'] - a['stamp']
    assert dt > 1.0
    # base_link (on the floor under the rear axle's middle) goes round at 0.5 m/s
    assert math.hypot(*b['linear'][:2]) == pytest.approx(0.5, rel=0.05)
    turned = (_yaw(b) - _yaw(a) + math.pi) % (2 * math.pi) - math.pi
    assert turned / dt == pytest.approx(0.3, rel=0.05)


def test_gz_ros2_controls_ackermann_demo_goes_at_what_its_example_program_asks(sim, watch):
    # Issue 53, item 3: the demo's car (145 kg, its rear wheels on velocity interfaces, its
    # YAML listing the right wheels first as Jazzy reads it) driven as example_ackermann_drive
    # drives it. Gazebo holds the joints' commands under load; so must this.
    path = corpus.write(FOLDER['path'], 'gz_car.yaml', corpus.GZ_CAR_YAML)
    _car_goes_as_asked(sim, watch, 'demo_car', corpus.gz_car(path), 'demo',
                       'ackermann_steering_controller')


def test_a_bicycle_made_for_gz_ros2_control_goes_at_what_its_reference_asks(sim, watch):
    # Issue 53, item 3: a bicycle-model car (corpus.gz_bicycle: one driven rear wheel whose
    # name says no side, carrying the car, and one steered front wheel) driven as the
    # Ackermann demo's program drives its car.
    path = corpus.write(FOLDER['path'], 'gz_bicycle.yaml', corpus.GZ_BICYCLE_YAML)
    _car_goes_as_asked(sim, watch, 'bike', corpus.gz_bicycle(path), 'bike',
                       'bicycle_steering_controller')


def test_gz_ros2_controls_diff_drive_demo_goes_at_what_its_example_program_asks(sim, watch):
    # Issue 53, item 3: the diff-drive demo's base (ball wheels, a fixed ball caster, its YAML
    # with wildcards, NaN jerks and has_*_limits flags) driven as example_diff_drive drives
    # it: a TwistStamped of 0.1 m/s and 0.1 rad/s every 50 ms, its stamp set once.
    from geometry_msgs.msg import TwistStamped
    path = corpus.write(FOLDER['path'], 'gz_diff_drive.yaml', corpus.GZ_DIFF_DRIVE_YAML)
    sim.spawn('demo_base', resource_string=corpus.gz_diff_drive(path), namespace='demo_dd',
              position=(-6.0, -6.0, 0.01))
    manager = '/demo_dd/controller_manager'  # its launch: spawner <controller> --param-file
    assert corpus.spawner(sim, 'joint_state_broadcaster', manager=manager)[0] is None
    assert corpus.spawner(sim, 'diff_drive_base_controller', path, manager=manager)[0] is None
    cmd = TwistStamped()
    cmd.header.stamp = watch.node.get_clock().now().to_msg()
    cmd.twist.linear.x, cmd.twist.angular.z = 0.1, 0.1
    odoms, poses = drive(  # its timeout is 0.5 s
        sim, watch, 'demo_base', cmd, '/demo_dd/diff_drive_base_controller/cmd_vel',
        '/demo_dd/diff_drive_base_controller/odom', seconds=6.0, first_pose=2.5)
    assert (odoms[-1].header.frame_id, odoms[-1].child_frame_id) == ('odom', 'chassis')
    speed, turn = steady(odoms)
    assert speed == pytest.approx(0.1, rel=0.05)
    assert turn == pytest.approx(0.1, rel=0.05)
    (a, b) = poses
    turned = (_yaw(b) - _yaw(a) + math.pi) % (2 * math.pi) - math.pi
    assert turned / (b['stamp'] - a['stamp']) == pytest.approx(0.1, rel=0.05)


def test_gz_ros2_controls_tricycle_demo_goes_at_what_its_example_program_asks(sim, watch):
    # Issue 53, item 3: the tricycle demo (its front wheel steers by a position interface and
    # drives by a velocity interface, carrying most of the weight; the rear wheels roll
    # free), driven as example_tricycle_drive drives it: a TwistStamped of 0.2 m/s and
    # 0.1 rad/s on /tricycle_controller/cmd_vel every 50 ms.
    from geometry_msgs.msg import TwistStamped
    path = corpus.write(FOLDER['path'], 'gz_tricycle.yaml', corpus.GZ_TRICYCLE_YAML)
    sim.spawn('demo_tricycle', resource_string=corpus.gz_tricycle(path), namespace='demo_tc',
              position=(6.0, 6.0, 0.01))
    manager = '/demo_tc/controller_manager'
    for controller in ('joint_state_broadcaster', 'tricycle_controller'):
        assert corpus.spawner(sim, controller, manager=manager)[0] is None
    cmd = TwistStamped()
    cmd.twist.linear.x, cmd.twist.angular.z = 0.2, 0.1
    odoms, poses = drive(  # the steering turns at 1 rad/s at most: 0.7 s to its angle
        sim, watch, 'demo_tricycle', cmd, '/demo_tc/tricycle_controller/cmd_vel',
        '/demo_tc/tricycle_controller/odom', seconds=7.0, first_pose=3.0)
    speed, turn = steady(odoms)
    assert speed == pytest.approx(0.2, rel=0.05)
    assert turn == pytest.approx(0.1, rel=0.05)
    (a, b) = poses
    dt = b['stamp'] - a['stamp']
    assert math.hypot(*b['linear'][:2]) == pytest.approx(0.2, rel=0.05)
    turned = (_yaw(b) - _yaw(a) + math.pi) % (2 * math.pi) - math.pi
    assert turned / dt == pytest.approx(0.1, rel=0.05)


def test_a_spawned_arm_without_controllers_is_held_where_it_spawns(sim, watch):
    """
    Hold a one-link arm whose link hangs out sideways level from its spawn.

    Limp, gravity would swing it down at once; the node's own trajectory server holds it.
    """
    inertia = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
    urdf = f"""<robot name="boom"><link name="world"/>
  <link name="post"><inertial><mass value="1"/>{inertia}</inertial></link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="post"/>
    <origin xyz="0 0 1"/></joint>
  <link name="beam"><inertial><origin xyz="0.3 0 0"/><mass value="1"/>{inertia}</inertial>
  </link>
  <joint name="hinge" type="revolute"><parent link="post"/><child link="beam"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="100" velocity="5"/></joint>
</robot>"""
    sim.spawn('boom', resource_string=urdf, position=(3.0, -3.0, 0.0))
    time.sleep(2.0)
    msg = states(watch, 'boom/hinge')[-1]
    assert msg.position[list(msg.name).index('boom/hinge')] == pytest.approx(0.0, abs=0.05)


def test_joints_no_controller_claims_are_held_as_gz_ros2_control_holds_them(sim, watch):
    """
    A boom made for gz_ros2_control stays where it spawns before any controller is active.

    Unless its plugin says ``<hold_joints>false</hold_joints>``: then gravity swings it down,
    as in Gazebo. A controller that claims the joint and lets it go leaves it held there.
    """
    path = corpus.write(FOLDER['path'], 'boom.yaml', corpus.BOOM_YAML)
    sim.spawn('held', resource_string=corpus.boom(path), position=(3.0, -3.0, 0.0),
              namespace='held')
    sim.spawn('limp', resource_string=corpus.boom(path, '<hold_joints>false</hold_joints>'),
              position=(3.0, -1.0, 0.0), namespace='limp')
    for ns in ('held', 'limp'):  # its joint_states (it claims no joint)
        assert corpus.spawner(sim, 'joint_state_broadcaster',
                              manager=f'/{ns}/controller_manager')[0] is None
    time.sleep(1.0)
    assert position(watch, 'hinge', '/held/joint_states') == pytest.approx(0.0, abs=0.02)
    swing = states(watch, 'hinge', '/limp/joint_states', n=50)  # half a second: it swings
    assert max(abs(m.position[list(m.name).index('hinge')]) for m in swing) > 0.5
    manager = '/held/controller_manager'
    assert corpus.spawner(sim, 'boom_controller', manager=manager)[0] is None
    from std_msgs.msg import Float64MultiArray
    publish(watch, Float64MultiArray, '/held/boom_controller/commands',
            Float64MultiArray(data=[0.4]))
    wait_for(lambda: abs(position(watch, 'hinge', '/held/joint_states') - 0.4) < 0.02)
    from controller_manager_msgs.srv import SwitchController
    request = SwitchController.Request(deactivate_controllers=['boom_controller'],
                                       strictness=SwitchController.Request.STRICT)
    assert sim.call(f'{manager}/switch_controller', SwitchController, request).ok
    time.sleep(1.0)
    assert position(watch, 'hinge', '/held/joint_states') == pytest.approx(0.4, abs=0.03)


def test_a_trajectory_controller_preempts_checks_its_constraints_and_reports_its_state(
        sim, watch):
    """Preemption aborts the running goal; the YAML's path tolerance aborts a goal too fast."""
    from control_msgs.action import FollowJointTrajectory
    from control_msgs.msg import JointTrajectoryControllerState
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    jtc_file = spawn_arm(sim)
    assert corpus.spawner(sim, 'arm_controller', param_file=jtc_file)[0] is None
    # controller_state, at the controller's 100 Hz of simulated time
    got = heard(watch, JointTrajectoryControllerState, '/arm_controller/controller_state', n=30)
    assert list(got[-1].joint_names) == list(corpus.ARM_JOINTS)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in got]
    # Each 10 ms of simulated time. A loaded host's publisher may leave some of a burst out
    # (MAX_BURST of the newest per tick: two of 30 were, in a full run), and the controller's
    # next update is then one period after the sample it took (a gap of 1.8 periods was seen),
    # never sooner: the typical gap is one period and none is shorter.
    periods = [(b - a) / 0.01 for a, b in zip(stamps, stamps[1:])]
    assert sorted(periods)[len(periods) // 2] == pytest.approx(1.0, rel=0.05)
    assert all(k > 0.95 for k in periods), periods
    client = action_client(watch.node, FollowJointTrajectory,
                           '/arm_controller/follow_joint_trajectory')
    assert client.wait_for_server(timeout_sec=10)

    def goal(target, seconds):
        g = FollowJointTrajectory.Goal()
        g.trajectory.joint_names = list(corpus.ARM_JOINTS)
        point = JointTrajectoryPoint(positions=list(target))
        point.time_from_start.sec, point.time_from_start.nanosec = int(seconds), int(
            (seconds % 1) * 1e9)
        g.trajectory.points = [point]
        return g
    first = _send(client, goal([0.5, 0, 0, 0, 0, 0], 4.0))
    time.sleep(0.5)
    second = _send(client, goal([0.2, 0, 0, 0, 0, 0], 1.0))
    assert first.accepted and second.accepted
    assert _result(second).error_code == 0
    first_result = first.get_result_async()
    wait_for(first_result.done, timeout=10)
    assert first_result.result().status == 6  # ABORTED: preempted by the second
    # joint1's path tolerance of 0.3 rad (its YAML's constraints): 2 rad in 50 ms cannot be
    # followed
    fast = _result(_send(client, goal([2.2, 0, 0, 0, 0, 0], 0.05)))
    assert fast.error_code == -4, fast.error_string  # PATH_TOLERANCE_VIOLATED
    client.destroy()
    # a trajectory on the topic, without a goal
    traj = JointTrajectory(joint_names=list(corpus.ARM_JOINTS))
    traj.points = [JointTrajectoryPoint(positions=[-0.3, 0, 0, 0, 0, 0])]
    traj.points[0].time_from_start.sec = 1
    publish(watch, JointTrajectory, '/arm_controller/joint_trajectory', traj, times=1)
    wait_for(lambda: abs(position(watch, 'joint1') + 0.3) < 0.03, timeout=20)


def test_a_bicycle_goes_at_the_twist_asked_and_a_tricycle_within_its_limits(sim, watch):
    """
    Both are asked 0.4 m/s and 0.2 rad/s; the tricycle's YAML limits its wheel and angle.

    Its wheel (radius 0.08 m) may turn at 4 rad/s, 0.32 m/s along its heading, and steer at
    most 0.15 rad: v = 0.32 cos 0.15 and w = 0.32 sin 0.15 / 0.5 (its wheelbase).
    """
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    path = corpus.write(FOLDER['path'], 'car.yaml', corpus.CAR_YAML)
    sim.spawn('car', resource_string=corpus.car(path), position=(-3.0, -3.0, 0.1))
    assert corpus.spawner(sim, 'bicycle_steering_controller')[0] is None
    trike = corpus.write(FOLDER['path'], 'trike.yaml', corpus.TRIKE_YAML)
    sim.spawn('trike', resource_string=corpus.trike(trike), position=(3.0, 3.0, 0.1),
              namespace='trike')
    assert corpus.spawner(sim, 'tricycle_controller',
                          manager='/trike/controller_manager')[0] is None
    cmd = TwistStamped()
    cmd.twist.linear.x, cmd.twist.angular.z = 0.4, 0.2
    pubs = [watch.node.create_publisher(TwistStamped, topic, 10) for topic in (
        '/bicycle_steering_controller/reference', '/trike/tricycle_controller/cmd_vel')]
    odoms = {'car': [], 'trike': []}
    subs = [watch.node.create_subscription(Odometry, topic, odoms[key].append, 100)
            for key, topic in (('car', '/bicycle_steering_controller/odometry'),
                               ('trike', '/trike/tricycle_controller/odom'))]
    try:
        t0 = time.monotonic()
        while time.monotonic() - t0 < 4.0:
            for pub in pubs:
                pub.publish(cmd)
            time.sleep(0.05)
    finally:
        for sub in subs:
            watch.node.destroy_subscription(sub)
        for pub in pubs:
            watch.node.destroy_publisher(pub)
    car = steady(odoms['car'])
    assert car[0] == pytest.approx(0.4, abs=0.05)
    assert car[1] == pytest.approx(0.2, abs=0.04)
    trike = steady(odoms['trike'])
    assert trike[0] == pytest.approx(0.32 * math.cos(0.15), abs=0.02)
    assert trike[1] == pytest.approx(0.32 * math.sin(0.15) / 0.5, abs=0.015)
    # 1.3 s without commands: past the tricycle's cmd_vel_timeout of 500 (ms) and its wheel's
    # coming to rest, within the bicycle's reference_timeout of 2.0 (s)
    time.sleep(1.3)
    trike = heard(watch, Odometry, '/trike/tricycle_controller/odom')[-1]
    car = heard(watch, Odometry, '/bicycle_steering_controller/odometry')[-1]
    assert abs(trike.twist.twist.linear.x) < 0.05
    assert car.twist.twist.linear.x == pytest.approx(0.4, abs=0.05)


def test_open_loop_control_starts_a_new_trajectory_from_the_last_command(sim, watch):
    """
    A cart held against a buffer stop sits short of its command; a goal starts from the command.

    With the YAML's ``open_loop_control: true`` the next trajectory starts from the command
    (1.0 m), as the real controller does, not from where the cart is (0.65 m).
    """
    from control_msgs.msg import JointTrajectoryControllerState
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    text = corpus.cart_yaml('position') + '    open_loop_control: true\n'
    path = corpus.write(FOLDER['path'], 'cart_open_loop.yaml', text)
    sim.spawn('cart', resource_string=corpus.cart('position', path), position=(0.0, 3.0, 0.0))
    sim.spawn('buffer', resource_string=corpus.BUFFER, position=(1.0, 3.0, 1.0))
    for name in ('joint_state_broadcaster', 'joint_trajectory_controller'):
        assert corpus.spawner(sim, name)[0] is None

    def trajectory(x: float, seconds: int) -> JointTrajectory:
        traj = JointTrajectory(joint_names=['slider_to_cart'])
        traj.points = [JointTrajectoryPoint(positions=[x])]
        traj.points[0].time_from_start.sec = seconds
        return traj
    topic = '/joint_trajectory_controller/joint_trajectory'
    publish(watch, JointTrajectory, topic, trajectory(1.0, 1), times=1)
    wait_for(lambda: position(watch, 'slider_to_cart') > 0.6, timeout=20)
    time.sleep(1.0)  # the trajectory has ended: the cart is held at 1.0 against the buffer
    assert position(watch, 'slider_to_cart') < 0.7
    got = []
    sub = watch.node.create_subscription(
        JointTrajectoryControllerState, '/joint_trajectory_controller/controller_state',
        got.append, 100)
    try:
        time.sleep(0.3)
        publish(watch, JointTrajectory, topic, trajectory(-1.0, 4), times=1)
        wait_for(lambda: any(m.reference.velocities[0] < -0.1 for m in list(got)), timeout=20)
    finally:
        watch.node.destroy_subscription(sub)
    first = next(m for m in got if m.reference.velocities[0] < -0.1)
    assert first.reference.positions[0] > 0.85, first.reference.positions


def test_after_a_reset_of_state_a_robots_controllers_start_again_from_it(sim, watch):
    """
    A reset of state puts the robots back where they spawned, their controllers still active.

    As if activated anew: the arm's trajectory controller holds it where the reset put it
    (spawned on its side, limp, gravity would swing it down); the rover's controller drives on
    at the twist still being sent (it writes its wheels at every update, as the real one
    does), its odometry from zero.
    """
    from control_msgs.action import FollowJointTrajectory
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    from simulation_interfaces.srv import ResetSimulation
    from trajectory_msgs.msg import JointTrajectoryPoint
    folder = FOLDER['path']
    sim.spawn('arm', resource_string=corpus.arm(corpus.write(folder, 'arm.yaml',
                                                             corpus.ARM_YAML)),
              position=(-2.0, 2.0, 1.5), orientation_xyzw=(0.0, 0.7071068, 0.0, 0.7071068))
    assert corpus.spawner(sim, 'joint_state_broadcaster')[0] is None
    jtc_file = corpus.write(folder, 'arm_jtc.yaml', corpus.ARM_JTC_YAML)
    assert corpus.spawner(sim, 'arm_controller', param_file=jtc_file)[0] is None
    client = action_client(watch.node, FollowJointTrajectory,
                           '/arm_controller/follow_joint_trajectory')
    assert client.wait_for_server(timeout_sec=10)
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = list(corpus.ARM_JOINTS)
    goal.trajectory.points = [JointTrajectoryPoint(positions=[0.3, -0.2, 0.2, 0.1, 0.1, 0.1])]
    goal.trajectory.points[0].time_from_start.sec = 1
    assert _result(_send(client, goal)).error_code == 0
    spawn_rover(sim, namespace='rover')  # a second robot: a namespace of its own
    cmd = TwistStamped()
    cmd.twist.linear.x = 0.3
    pub = watch.node.create_publisher(TwistStamped, '/rover/diff_drive_base_controller/cmd_vel',
                                      10)

    def drive(seconds: float) -> None:
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            pub.publish(cmd)
            time.sleep(0.05)
    try:
        drive(2.0)
        sim.reset(ResetSimulation.Request.SCOPE_STATE)
        back = sim.entity_state('rover')['position']
        assert math.hypot(back[0] - 2.0, back[1] + 2.0) < 0.05  # where it spawned
        drive(3.0)
        odom = heard(watch, Odometry, '/rover/diff_drive_base_controller/odom')[-1]
    finally:
        watch.node.destroy_publisher(pub)
        client.destroy()
    moved = sim.entity_state('rover')['position']
    run = math.hypot(moved[0] - back[0], moved[1] - back[1])
    assert run > 0.5  # 0.3 m/s for 3 s
    assert odom.pose.pose.position.x == pytest.approx(run, abs=0.1)  # from zero at the reset
    arm = dict(zip(*(lambda m: (m.name, m.position))(states(watch, 'joint1')[-1])))
    assert max(abs(arm[j]) for j in corpus.ARM_JOINTS) < 0.02  # held at the spawn pose
    assert listed(sim)['arm_controller'].state == 'active'
    assert listed(sim, '/rover/controller_manager')['diff_drive_base_controller'].state == \
        'active'
