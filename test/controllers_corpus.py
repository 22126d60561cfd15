"""
Robots made for Gazebo and ros2_control, as their description packages ship them (issue 42).

Each is a URDF with a ``<ros2_control>`` block (gz_ros2_control's hardware) and the Gazebo
plugin that names its controllers YAML, and that YAML: a cart per command interface (as
gz_ros2_control_demos' carts), a differential drive, and a 6-joint arm under a
joint_trajectory_controller. :func:`write` puts a robot's YAML where the node may read it and
returns its URDF; :func:`spawner` makes controller_manager's ``spawner`` calls, in its order.
"""

from pathlib import Path

_I = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'


def _plugin(yaml_path: str, namespace: str = '') -> str:
    ns = f'<ros><namespace>{namespace}</namespace></ros>' if namespace else ''
    return (f'<gazebo><plugin filename="gz_ros2_control-system" '
            f'name="gz_ros2_control::GazeboSimROS2ControlPlugin">'
            f'<parameters>{yaml_path}</parameters>{ns}</plugin></gazebo>')


def _gz_system(name: str, joints: str, yaml_path: str, remappings: tuple = ()) -> str:
    """Return a ``<ros2_control>`` block on Gazebo's hardware with `joints`, and its plugin."""
    plugin = _plugin(yaml_path)
    if remappings:
        rules = ''.join(f'<remapping>{r}</remapping>' for r in remappings)
        plugin = plugin.replace('</plugin>', f'<ros>{rules}</ros></plugin>')
    return f"""<ros2_control name="{name}" type="system">
    <hardware><plugin>gz_ros2_control/GazeboSimSystem</plugin></hardware>{joints}
  </ros2_control>
  {plugin}"""


def cart(interface: str, yaml_path: str, namespace: str = '') -> str:
    """Return a cart on a 30 m rail (``slider_to_cart``) commanded through one interface."""
    limits = {'position': (-15, 15), 'velocity': (-10, 10), 'effort': (-100, 100)}[interface]
    return f"""<robot name="cart">
  <link name="world"/>
  <link name="slider"><inertial><mass value="100"/>{_I}</inertial>
    <visual><geometry><box size="30 0.05 0.05"/></geometry></visual></link>
  <joint name="world_to_slider" type="fixed"><parent link="world"/><child link="slider"/>
    <origin xyz="0 0 1"/></joint>
  <link name="cart"><inertial><mass value="1"/>{_I}</inertial>
    <collision><geometry><box size="0.5 0.5 0.2"/></geometry></collision></link>
  <joint name="slider_to_cart" type="prismatic"><parent link="slider"/><child link="cart"/>
    <axis xyz="1 0 0"/><limit lower="-15" upper="15" effort="1000" velocity="30"/>
    <dynamics damping="0.0" friction="0.0"/></joint>
  <ros2_control name="GazeboSimSystem" type="system">
    <hardware><plugin>gz_ros2_control/GazeboSimSystem</plugin></hardware>
    <joint name="slider_to_cart">
      <command_interface name="{interface}">
        <param name="min">{limits[0]}</param><param name="max">{limits[1]}</param>
      </command_interface>
      <state_interface name="position"/><state_interface name="velocity"/>
      <state_interface name="effort"/>
    </joint>
  </ros2_control>
  {_plugin(yaml_path, namespace)}
</robot>"""


#: A buffer stop for the cart's rail: spawned at (1, y, 1) it keeps the cart at x <= 0.65 m.
#: (A link of the cart's own URDF would not do: as in Gazebo, a robot's links do not collide
#: with each other.)
BUFFER = ('<mujoco><worldbody><body name="buffer"><geom type="box" size="0.1 0.25 0.25"/>'
          '</body></worldbody></mujoco>')


def cart_yaml(interface: str) -> str:
    group = {'position': 'position_controllers/JointGroupPositionController',
             'velocity': 'velocity_controllers/JointGroupVelocityController',
             'effort': 'effort_controllers/JointGroupEffortController'}[interface]
    return f"""controller_manager:
  ros__parameters:
    update_rate: 100
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    forward_{interface}_controller:
      type: forward_command_controller/ForwardCommandController
    group_{interface}_controller:
      type: {group}
    joint_trajectory_controller:
      type: joint_trajectory_controller/JointTrajectoryController

forward_{interface}_controller:
  ros__parameters:
    joints: [slider_to_cart]
    interface_name: {interface}

group_{interface}_controller:
  ros__parameters:
    joints: [slider_to_cart]

joint_state_broadcaster:
  ros__parameters:
    extra_joints: [rail_brake]

joint_trajectory_controller:
  ros__parameters:
    joints: [slider_to_cart]
    command_interfaces: [{interface}]
    state_interfaces: [position, velocity]
"""


ARM_JOINTS = tuple(f'joint{i}' for i in range(1, 7))


def arm(yaml_path: str) -> str:
    """
    Return a 6-joint arm fixed to the world, position interfaces, 1 kg links 0.3 m apart.

    On its last link, two 50 g fingers open along y up to 0.04 m each, the right mimicking
    the left (``finger_joint``, position), for a gripper action controller.
    """
    links = ''.join(f"""
  <link name="link{i}"><inertial><origin xyz="0 0 0.15"/><mass value="1"/>{_I}</inertial>
    <collision><origin xyz="0 0 0.15"/><geometry><cylinder radius="0.04" length="0.2"/>
    </geometry></collision></link>
  <joint name="joint{i}" type="revolute"><parent link="link{i - 1}"/><child link="link{i}"/>
    <origin xyz="0 0 {0.1 if i == 1 else 0.3}"/>
    <axis xyz="{'0 0 1' if i in (1, 4, 6) else '0 1 0'}"/>
    <limit lower="-3" upper="3" effort="200" velocity="3"/></joint>""" for i in range(1, 7))
    joints = ''.join(f"""
    <joint name="joint{i}"><command_interface name="position"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>"""
                     for i in range(1, 7))
    joints += """
    <joint name="finger_joint"><command_interface name="position"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>"""
    links += ''.join(f"""
  <link name="{side}_finger"><inertial><origin xyz="0 0 0.03"/><mass value="0.05"/>{_I}
    </inertial><collision><origin xyz="0 0 0.03"/><geometry><box size="0.02 0.01 0.06"/>
    </geometry></collision></link>
  <joint name="{joint}" type="prismatic"><parent link="link6"/><child link="{side}_finger"/>
    <origin xyz="0 {y} 0.3"/><axis xyz="0 {1 if y > 0 else -1} 0"/>
    <limit lower="0" upper="0.04" effort="20" velocity="0.2"/>{mimic}</joint>"""
                     for side, joint, y, mimic in (
                         ('left', 'finger_joint', 0.01, ''),
                         ('right', 'right_finger_joint', -0.01,
                          '<mimic joint="finger_joint" multiplier="1"/>')))
    return f"""<robot name="arm">
  <link name="world"/>
  <link name="link0"><inertial><mass value="5"/>{_I}</inertial></link>
  <joint name="base" type="fixed"><parent link="world"/><child link="link0"/></joint>{links}
  <ros2_control name="ArmSystem" type="system">
    <hardware><plugin>gz_ros2_control/GazeboSimSystem</plugin></hardware>{joints}
    <sensor name="tcp_imu">{''.join(f'<state_interface name="{k}.{a}"/>' for k in (
        'orientation', 'angular_velocity', 'linear_acceleration') for a in 'xyzw'
        if a != 'w' or k == 'orientation')}</sensor>
    <sensor name="tcp_fts">{''.join(f'<state_interface name="{k}.{a}"/>'
                                    for k in ('force', 'torque') for a in 'xyz')}</sensor>
  </ros2_control>
  <gazebo reference="link6"><sensor name="tcp_imu" type="imu"><update_rate>100</update_rate>
  </sensor></gazebo>
  <gazebo reference="joint6"><sensor name="tcp_fts" type="force_torque">
    <update_rate>100</update_rate></sensor></gazebo>
  {_plugin(yaml_path)}
</robot>"""


ARM_YAML = """controller_manager:
  ros__parameters:
    update_rate: 1000
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    imu_sensor_broadcaster:
      type: imu_sensor_broadcaster/IMUSensorBroadcaster
    force_torque_sensor_broadcaster:
      type: force_torque_sensor_broadcaster/ForceTorqueSensorBroadcaster
    gripper_controller:
      type: position_controllers/GripperActionController

gripper_controller:
  ros__parameters:
    joint: finger_joint
    goal_tolerance: 0.002

imu_sensor_broadcaster:
  ros__parameters:
    sensor_name: tcp_imu
    frame_id: link6
    update_rate: 100

force_torque_sensor_broadcaster:
  ros__parameters:
    sensor_name: tcp_fts
    frame_id: link6
    update_rate: 100
"""
#: What the arm's launch file gives the spawner with --param-file (the JTC's own file).
ARM_JTC_YAML = """arm_controller:
  ros__parameters:
    type: joint_trajectory_controller/JointTrajectoryController
    joints: [joint1, joint2, joint3, joint4, joint5, joint6]
    command_interfaces: [position]
    state_interfaces: [position, velocity]
    update_rate: 100
    constraints:
      goal_time: 0.5
      stopped_velocity_tolerance: 0.05
      joint1: {trajectory: 0.3, goal: 0.02}
"""

WHEEL = '<cylinder radius="0.1" length="0.05"/>'


def diff_drive(yaml_path: str, remappings: tuple = ()) -> str:
    """
    Return a 10 kg base on two 0.1 m wheels 0.4 m apart and a caster ball.

    `remappings` go into its gz_ros2_control plugin as ``<ros><remapping>`` rules.
    """
    wheels = ''.join(f"""
  <link name="{side}_wheel"><inertial><mass value="0.5"/>{_I}</inertial>
    <collision><geometry>{WHEEL}</geometry></collision></link>
  <joint name="{side}_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="{side}_wheel"/><origin xyz="0 {y} 0" rpy="-1.5708 0 0"/><axis xyz="0 0 1"/>
    <limit effort="20" velocity="20"/></joint>""" for side, y in (('left', 0.2), ('right', -0.2)))
    joints = ''.join(f"""
    <joint name="{side}_wheel_joint"><command_interface name="velocity">
      <param name="min">-20</param><param name="max">20</param></command_interface>
      <state_interface name="position"/><state_interface name="velocity"/></joint>"""
                     for side in ('left', 'right'))
    return f"""<robot name="rover">
  <link name="base_link"><inertial><origin xyz="-0.1 0 0.05"/><mass value="10"/>
    <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="-0.1 0 0.05"/><geometry><box size="0.4 0.3 0.1"/></geometry>
    </collision></link>{wheels}
  <link name="caster"><inertial><mass value="0.1"/>{_I}</inertial>
    <collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="caster_joint" type="fixed"><parent link="base_link"/><child link="caster"/>
    <origin xyz="-0.3 0 -0.05"/></joint>
  {_gz_system('RoverSystem', joints, yaml_path, remappings)}
</robot>"""


DIFF_DRIVE_YAML = """controller_manager:
  ros__parameters:
    update_rate: 100
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    diff_drive_base_controller:
      type: diff_drive_controller/DiffDriveController

diff_drive_base_controller:
  ros__parameters:
    left_wheel_names: [left_wheel_joint]
    right_wheel_names: [right_wheel_joint]
    wheel_separation: 0.4
    wheel_radius: 0.1
    publish_rate: 50.0
    odom_frame_id: odom
    base_frame_id: base_link
    cmd_vel_timeout: 0.5
    enable_odom_tf: true
    pose_covariance_diagonal: [0.001, 0.001, 1000000.0, 1000000.0, 1000000.0, 0.01]
    # The style of most published configs: the deprecated flags beside every limit, a jerk
    # of 0.0 turned off by its flag (at d48b79a it was taken as a limit: the base never moved)
    linear:
      x:
        has_velocity_limits: true
        max_velocity: 1.0
        has_acceleration_limits: true
        max_acceleration: 0.5
        has_jerk_limits: false
        max_jerk: 0.0
    angular:
      z:
        has_velocity_limits: true
        max_velocity: 1.0
        has_acceleration_limits: false
        max_acceleration: 0.0
        has_jerk_limits: false
        max_jerk: 0.0
"""


def write(folder: Path, name: str, text: str) -> str:
    """Write a YAML into `folder` (one the node reads) and return its absolute path."""
    path = Path(folder) / name
    path.write_text(text)
    return str(path)


def spawner(sim, name: str, param_file: str = '', manager: str = '/controller_manager',
            activate: bool = True) -> tuple:
    """
    Make controller_manager's ``spawner <name> [--param-file F]`` calls, in its order.

    list_controllers; with a param file, set ``<name>.params_file`` (and ``<name>.type`` from
    the file) on the manager; load_controller; configure_controller; switch_controller
    (activate, STRICT). Returns (the first answer that was not ok, or None; the answers).
    A call whose answer never came is made again, as the spawner does (its reply can be lost
    to a manager of the same name that was there a moment before), unless what it asked for
    happened.
    """
    import yaml
    from controller_manager_msgs.srv import (ConfigureController, LoadController,
                                             SwitchController)
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    answers = []

    def state():
        return {c.name: c.state for c in listed(sim, manager)}.get(name)

    def call(service, srv, req, done):
        for _ in range(3):
            try:
                answers.append(sim.call(f'{manager}/{service}', srv, req))
                return answers[-1]
            except TimeoutError:
                if done():
                    answers.append(srv.Response(ok=True))
                    return answers[-1]
        raise TimeoutError(f'{manager}/{service} never answered')

    if state() is None:
        if param_file:
            params = [Parameter(name=f'{name}.params_file', value=ParameterValue(
                type=ParameterType.PARAMETER_STRING_ARRAY, string_array_value=[param_file]))]
            doc = yaml.safe_load(Path(param_file).read_text())
            entry = (doc.get(name) or doc.get(f'/**/{name}')) if isinstance(doc, dict) else None
            kind = (entry or {}).get('ros__parameters', {}).get('type')
            if kind:
                params.append(Parameter(name=f'{name}.type', value=ParameterValue(
                    type=ParameterType.PARAMETER_STRING, string_value=kind)))
            for attempt in range(3):  # setting a parameter twice does no harm
                try:
                    sim.call(f'{manager}/set_parameters', SetParameters,
                             SetParameters.Request(parameters=params))
                    break
                except TimeoutError:
                    if attempt == 2:
                        raise
        if not call('load_controller', LoadController, LoadController.Request(name=name),
                    lambda: state() is not None).ok:
            return answers[-1], answers
    if not call('configure_controller', ConfigureController,
                ConfigureController.Request(name=name),
                lambda: state() == 'inactive').ok or not activate:
        return (None if answers[-1].ok else answers[-1]), answers
    req = SwitchController.Request(activate_controllers=[name],
                                   strictness=SwitchController.Request.STRICT)
    req.timeout.sec = 5
    call('switch_controller', SwitchController, req, lambda: state() == 'active')
    return (None if answers[-1].ok else answers[-1]), answers


def listed(sim, manager: str = '/controller_manager') -> list:
    """Return the controllers a manager lists."""
    from controller_manager_msgs.srv import ListControllers
    return sim.call(f'{manager}/list_controllers', ListControllers,
                    ListControllers.Request()).controller


def gripper(yaml_path: str) -> str:
    """
    Return a two-finger gripper fixed to the world, its right finger mimicking its left.

    The fingers close along y from 0.06 m out; only the left one is in the <ros2_control>
    block (position). Their inner faces meet a 0.04 m block at the centre at 0.035 m closed.
    """
    fingers = ''.join(f"""
  <link name="{side}_finger"><inertial><origin xyz="0 0 -0.08"/><mass value="0.05"/>{_I}
    </inertial><collision><origin xyz="0 0 -0.08"/><geometry><box size="0.03 0.01 0.04"/>
    </geometry></collision></link>
  <joint name="{side}_finger_joint" type="prismatic"><parent link="palm"/>
    <child link="{side}_finger"/><origin xyz="0 {y} 0"/><axis xyz="0 {-1 if y > 0 else 1} 0"/>
    <limit lower="0" upper="0.055" effort="50" velocity="0.5"/>{mimic}</joint>"""
                      for side, y, mimic in (
                          ('left', 0.06, ''),
                          ('right', -0.06, '<mimic joint="left_finger_joint" multiplier="1"/>')))
    return f"""<robot name="gripper">
  <link name="world"/>
  <link name="palm"><inertial><mass value="0.5"/>{_I}</inertial>
    <collision><origin xyz="0 0 0.02"/><geometry><box size="0.04 0.16 0.02"/></geometry>
    </collision></link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="palm"/>
    <origin xyz="0 0 0.1"/></joint>{fingers}
  <ros2_control name="GripperSystem" type="system">
    <hardware><plugin>gz_ros2_control/GazeboSimSystem</plugin></hardware>
    <joint name="left_finger_joint"><command_interface name="position"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>
  </ros2_control>
  {_plugin(yaml_path)}
</robot>"""


GRIPPER_YAML = """controller_manager:
  ros__parameters:
    update_rate: 100
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    gripper_controller:
      type: position_controllers/GripperActionController
    parallel_gripper_controller:
      type: parallel_gripper_action_controller/GripperActionController

gripper_controller:
  ros__parameters:
    joint: left_finger_joint
    goal_tolerance: 0.002
    allow_stalling: true
    stall_velocity_threshold: 0.001
    stall_timeout: 0.3

parallel_gripper_controller:
  ros__parameters:
    joint: left_finger_joint
    goal_tolerance: 0.002
"""
BLOCK = ('<mujoco><worldbody><body name="block"><freejoint/>'
         '<geom type="box" size="0.02 0.02 0.02" mass="0.1"/></body></worldbody></mujoco>')


def topic_based() -> str:
    """
    Return a cart with a spinning wheel whose joints a controller manager elsewhere drives.

    Its hardware is topic_based_ros2_control's: the cart's slider by position, the wheel by
    velocity, over /cart_joint_commands and /cart_joint_states.
    """
    return f"""<robot name="cart">
  <link name="world"/>
  <link name="slider"><inertial><mass value="100"/>{_I}</inertial></link>
  <joint name="world_to_slider" type="fixed"><parent link="world"/><child link="slider"/>
    <origin xyz="0 0 1"/></joint>
  <link name="cart"><inertial><mass value="1"/>{_I}</inertial></link>
  <joint name="slider_to_cart" type="prismatic"><parent link="slider"/><child link="cart"/>
    <axis xyz="1 0 0"/><limit lower="-5" upper="5" effort="1000" velocity="30"/></joint>
  <link name="wheel"><inertial><mass value="0.2"/>{_I}</inertial></link>
  <joint name="spinner" type="continuous"><parent link="cart"/><child link="wheel"/>
    <axis xyz="0 1 0"/><limit effort="10" velocity="20"/></joint>
  <ros2_control name="TopicSystem" type="system">
    <hardware><plugin>topic_based_ros2_control/TopicBasedSystem</plugin>
      <param name="joint_commands_topic">/cart_joint_commands</param>
      <param name="joint_states_topic">/cart_joint_states</param></hardware>
    <joint name="slider_to_cart"><command_interface name="position"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>
    <joint name="spinner"><command_interface name="velocity"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>
  </ros2_control>
</robot>"""


def car(yaml_path: str) -> str:
    """
    Return a car: rear wheels driven (velocity), front wheels steered (position), Ackermann.

    Wheelbase 0.5 m, track 0.4 m, wheels 0.08 m in radius; the front wheels roll freely.
    """
    def wheel(name: str, parent: str, xyz: str, driven: bool) -> str:
        return f"""
  <link name="{name}"><inertial><mass value="0.3"/>{_I}</inertial>
    <collision><geometry><cylinder radius="0.08" length="0.04"/></geometry></collision></link>
  <joint name="{name}_joint" type="continuous"><parent link="{parent}"/><child link="{name}"/>
    <origin xyz="{xyz}" rpy="-1.5708 0 0"/><axis xyz="0 0 1"/>
    <limit effort="{20 if driven else 0}" velocity="50"/></joint>"""
    steers = ''.join(f"""
  <link name="{side}_steer"><inertial><mass value="0.1"/>{_I}</inertial></link>
  <joint name="{side}_steering_joint" type="revolute"><parent link="base_link"/>
    <child link="{side}_steer"/><origin xyz="0.25 {y} 0"/><axis xyz="0 0 1"/>
    <limit lower="-0.6" upper="0.6" effort="50" velocity="5"/></joint>{wheel(
        f'{side}_front_wheel', f'{side}_steer', '0 0 0', False)}"""
                     for side, y in (('left', 0.2), ('right', -0.2)))
    rears = ''.join(wheel(f'{side}_rear_wheel', 'base_link', f'-0.25 {y} 0', True)
                    for side, y in (('left', 0.2), ('right', -0.2)))
    joints = ''.join(f"""
    <joint name="{side}_rear_wheel_joint"><command_interface name="velocity"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>"""
                     for side in ('left', 'right')) + ''.join(f"""
    <joint name="{side}_steering_joint"><command_interface name="position"/>
      <state_interface name="position"/></joint>""" for side in ('left', 'right'))
    return f"""<robot name="car">
  <link name="base_link"><inertial><mass value="10"/>
    <inertia ixx="0.1" iyy="0.3" izz="0.3" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.6 0.3 0.05"/></geometry>
    </collision></link>{rears}{steers}
  {_gz_system('CarSystem', joints, yaml_path)}
</robot>"""


CAR_YAML = """controller_manager:
  ros__parameters:
    update_rate: 100
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    ackermann_steering_controller:
      type: ackermann_steering_controller/AckermannSteeringController
    bicycle_steering_controller:
      type: bicycle_steering_controller/BicycleSteeringController

ackermann_steering_controller:
  ros__parameters:
    reference_timeout: 2.0
    front_steering: true
    # Jazzy's order: the right wheel first
    rear_wheels_names: [right_rear_wheel_joint, left_rear_wheel_joint]
    front_wheels_names: [right_steering_joint, left_steering_joint]
    wheelbase: 0.5
    front_wheel_track: 0.4
    rear_wheel_track: 0.4
    front_wheels_radius: 0.08
    rear_wheels_radius: 0.08
    odom_frame_id: car_odom
    base_frame_id: base_link

bicycle_steering_controller:
  ros__parameters:
    reference_timeout: 2.0
    rear_wheels_names: [left_rear_wheel_joint, right_rear_wheel_joint]
    front_wheels_names: [left_steering_joint, right_steering_joint]
    wheelbase: 0.5
    front_wheel_radius: 0.08
    rear_wheel_radius: 0.08
"""


def trike(yaml_path: str) -> str:
    """
    Return a tricycle: one front wheel that steers and drives, two rear wheels rolling freely.

    Wheelbase 0.5 m, wheels 0.08 m in radius.
    """
    rears = ''.join(f"""
  <link name="{side}_rear_wheel"><inertial><mass value="0.3"/>{_I}</inertial>
    <collision><geometry><cylinder radius="0.08" length="0.04"/></geometry></collision></link>
  <joint name="{side}_rear_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="{side}_rear_wheel"/><origin xyz="-0.25 {y} 0" rpy="-1.5708 0 0"/>
    <axis xyz="0 0 1"/></joint>""" for side, y in (('left', 0.2), ('right', -0.2)))
    return f"""<robot name="trike">
  <link name="base_link"><inertial><mass value="8"/>
    <inertia ixx="0.1" iyy="0.2" izz="0.2" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.6 0.3 0.05"/></geometry>
    </collision></link>{rears}
  <link name="fork"><inertial><mass value="0.1"/>{_I}</inertial></link>
  <joint name="steering_joint" type="revolute"><parent link="base_link"/><child link="fork"/>
    <origin xyz="0.25 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-0.8" upper="0.8" effort="50" velocity="5"/></joint>
  <link name="front_wheel"><inertial><mass value="0.3"/>{_I}</inertial>
    <collision><geometry><cylinder radius="0.08" length="0.04"/></geometry></collision></link>
  <joint name="front_wheel_joint" type="continuous"><parent link="fork"/>
    <child link="front_wheel"/><origin rpy="-1.5708 0 0"/><axis xyz="0 0 1"/>
    <limit effort="20" velocity="50"/></joint>
  <ros2_control name="TrikeSystem" type="system">
    <hardware><plugin>gz_ros2_control/GazeboSimSystem</plugin></hardware>
    <joint name="front_wheel_joint"><command_interface name="velocity"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>
    <joint name="steering_joint"><command_interface name="position"/>
      <state_interface name="position"/></joint>
  </ros2_control>
  {_plugin(yaml_path)}
</robot>"""


TRIKE_YAML = """controller_manager:
  ros__parameters:
    update_rate: 100
    tricycle_controller:
      type: tricycle_controller/TricycleController

tricycle_controller:
  ros__parameters:
    traction_joint_name: front_wheel_joint
    steering_joint_name: steering_joint
    wheel_radius: 0.08
    wheelbase: 0.5
    odom_frame_id: odom
    base_frame_id: base_link
    cmd_vel_timeout: 500
    # The flags as published configs write them: an acceleration of 0.0 turned off by its flag
    traction:
      has_velocity_limits: true
      max_velocity: 4.0
      has_acceleration_limits: false
      max_acceleration: 0.0
      max_deceleration: 0.0
      has_jerk_limits: false
      max_jerk: 0.0
    steering:
      has_position_limits: true
      max_position: 0.15
"""


def boom(yaml_path: str, plugin_extra: str = '') -> str:
    """
    Return a boom: a beam 0.3 m out sideways from a post 1 m up, on a hinge whose axis is level.

    Its ros2_control block commands the hinge by position; `plugin_extra` goes into the
    gz_ros2_control plugin tag (``<hold_joints>false</hold_joints>``). Left free, gravity swings
    the beam down at once.
    """
    return f"""<robot name="boom"><link name="world"/>
  <link name="post"><inertial><mass value="1"/>{_I}</inertial></link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="post"/>
    <origin xyz="0 0 1"/></joint>
  <link name="beam"><inertial><origin xyz="0.3 0 0"/><mass value="1"/>{_I}</inertial></link>
  <joint name="hinge" type="revolute"><parent link="post"/><child link="beam"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="100" velocity="5"/></joint>
  <ros2_control name="BoomSystem" type="system">
    <hardware><plugin>gz_ros2_control/GazeboSimSystem</plugin></hardware>
    <joint name="hinge"><command_interface name="position"/>
      <state_interface name="position"/><state_interface name="velocity"/></joint>
  </ros2_control>
  <gazebo><plugin filename="gz_ros2_control-system"
    name="gz_ros2_control::GazeboSimROS2ControlPlugin"><parameters>{yaml_path}</parameters>
    {plugin_extra}</plugin></gazebo>
</robot>"""


BOOM_YAML = """controller_manager:
  ros__parameters:
    update_rate: 100
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    boom_controller:
      type: forward_command_controller/ForwardCommandController

boom_controller:
  ros__parameters:
    joints: [hinge]
    interface_name: position
"""


def gz_car(yaml_path: str, effort: float = 0.0, speed: float = 0.0) -> str:
    """
    Return a car as gz_ros2_control's Ackermann demo builds it, for its example program.

    A 100 kg chassis (2 x 1 x 0.5 m) over four 11.3 kg wheels 0.3 m in radius; wheelbase
    1.7 m, track 1.0 m; the rear wheels driven by velocity interfaces, the front ones steered
    by position and rolling freely; every joint damped (0.2). (The demo's own URDF puts the
    steering joint named left on the right; this one puts it on the left.) `effort` and
    `speed` (> 0) give the rear wheels a URDF ``<limit>``.
    """
    wheel_inertia = ('<inertial><mass value="11.3"/><inertia ixx="0.26" iyy="0.26" izz="0.51" '
                     'ixy="0" ixz="0" iyz="0"/></inertial>')
    limit = f'<limit effort="{effort}" velocity="{speed}"/>' if effort or speed else ''

    def wheel(name: str, parent: str, xyz: str, rpy: str, extra: str = '') -> str:
        return f"""
  <link name="{name}">{wheel_inertia}
    <collision><geometry><cylinder length="0.08" radius="0.3"/></geometry></collision></link>
  <joint name="{name}_joint" type="continuous"><parent link="{parent}"/><child link="{name}"/>
    <origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/><dynamics damping="0.2"/>{extra}</joint>"""

    steering = ''.join(f"""
  <link name="{side}_wheel_steering"><inertial><mass value="0.1"/>{_I}</inertial></link>
  <joint name="{side}_wheel_steering_joint" type="revolute"><parent link="chassis"/>
    <child link="{side}_wheel_steering"/><origin xyz="0.9 {y} -0.2" rpy="1.57 0 0"/>
    <axis xyz="0 1 0"/><dynamics damping="0.2"/>
    <limit effort="1000" lower="-1.57" upper="1.57" velocity="30"/></joint>{wheel(
        f'front_{side}_wheel', f'{side}_wheel_steering', '0 0 0', '0 0 0')}"""
                       for side, y in (('left', 0.5), ('right', -0.5)))
    rears = ''.join(wheel(f'rear_{side}_wheel', 'chassis', f'-0.8 {y} -0.2', '-1.57 0 0', limit)
                    for side, y in (('left', 0.5), ('right', -0.5)))
    joints = ''.join(f"""
    <joint name="rear_{side}_wheel_joint"><command_interface name="velocity"/>
      <state_interface name="velocity"/><state_interface name="position"/></joint>"""
                     for side in ('left', 'right')) + ''.join(f"""
    <joint name="{side}_wheel_steering_joint"><command_interface name="position"/>
      <state_interface name="position"/></joint>""" for side in ('left', 'right'))
    return f"""<robot name="ackermann_drive"><link name="base_link"/>
  <link name="chassis"><inertial><mass value="100"/>
    <inertia ixx="10.4" iyy="35.4" izz="41.66" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="2 1 0.5"/></geometry></collision></link>
  <joint name="chassis_joint" type="fixed"><parent link="base_link"/><child link="chassis"/>
    <origin xyz="0.8 0 0.5"/></joint>{rears}{steering}
  {_gz_system('GazeboSystem', joints, yaml_path)}
</robot>"""


#: The Ackermann demo's controllers YAML as Jazzy's ros2_controllers read it (update rate 10 Hz,
#: the right wheels first, Twist references as its example program sends them).
GZ_CAR_YAML = """controller_manager:
  ros__parameters:
    update_rate: 10
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    ackermann_steering_controller:
      type: ackermann_steering_controller/AckermannSteeringController

ackermann_steering_controller:
  ros__parameters:
    wheelbase: 1.7
    front_wheel_track: 1.0
    rear_wheel_track: 1.0
    front_wheels_radius: 0.3
    rear_wheels_radius: 0.3
    front_steering: true
    reference_timeout: 2.0
    rear_wheels_names: ['rear_right_wheel_joint', 'rear_left_wheel_joint']
    front_wheels_names: ['right_wheel_steering_joint', 'left_wheel_steering_joint']
    use_stamped_vel: false
    open_loop: false
    velocity_rolling_window_size: 10
    base_frame_id: base_link
    odom_frame_id: odom
    enable_odom_tf: true
    position_feedback: false
"""


def gz_tricycle(yaml_path: str) -> str:
    """
    Return a tricycle as gz_ros2_control's tricycle demo builds it, for its example program.

    A 1 kg chassis (2 x 1 x 0.5 m) on two free rear wheels (2 kg, 0.3 m in radius, 1 m apart,
    damped 0.2) and one 15 kg front wheel 1.7 m ahead that steers (position, on a 5 g link)
    and drives (velocity): most of its weight on the wheel that drives.
    """
    def rear(side: str, y: float) -> str:
        return f"""
  <link name="{side}_wheel"><inertial><mass value="2"/>
      <inertia ixx="0.145833" iyy="0.145833" izz="0.125" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><cylinder length="0.08" radius="0.3"/></geometry></collision></link>
  <joint name="{side}_wheel_joint" type="continuous"><parent link="chassis"/>
    <child link="{side}_wheel"/><origin xyz="-0.8 {y} -0.2" rpy="-1.57 0 0"/>
    <axis xyz="0 0 1"/><dynamics damping="0.2"/></joint>"""

    joints = """
    <joint name="steering_joint"><command_interface name="position"/>
      <state_interface name="position"/></joint>
    <joint name="traction_joint"><command_interface name="velocity"/>
      <state_interface name="velocity"/><state_interface name="position"/></joint>"""
    return f"""<robot name="tricycle_drive"><link name="base_link"/>
  <link name="chassis"><inertial><mass value="1"/>
      <inertia ixx="0.126164" iyy="0.416519" izz="0.481014" ixy="0" ixz="0" iyz="0"/>
    </inertial><collision><geometry><box size="2 1 0.5"/></geometry></collision></link>
  <joint name="chassis_joint" type="fixed"><parent link="base_link"/><child link="chassis"/>
    <origin xyz="0.8 0 0.5"/></joint>{rear('left', 0.5)}{rear('right', -0.5)}
  <link name="steering_link"><inertial><mass value="0.005"/>
      <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="steering_joint" type="continuous"><parent link="chassis"/>
    <child link="steering_link"/><origin xyz="0.9 0 -0.2"/><axis xyz="0 0 1"/></joint>
  <link name="wheel_front_link"><inertial><mass value="15"/>
      <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><cylinder length="0.08" radius="0.3"/></geometry></collision></link>
  <joint name="traction_joint" type="continuous"><parent link="steering_link"/>
    <child link="wheel_front_link"/><origin rpy="-1.57 1.57 0"/><axis xyz="0 0 1"/></joint>
  {_gz_system('GazeboSimSystem', joints, yaml_path)}
</robot>"""


#: The tricycle demo's controllers YAML of the Jazzy line (tricycle_controller at 50 Hz, its
#: traction and steering limits, the rear wheels on joint_states as extra joints).
GZ_TRICYCLE_YAML = """controller_manager:
  ros__parameters:
    update_rate: 50
    tricycle_controller:
      type: tricycle_controller/TricycleController
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster

joint_state_broadcaster:
  ros__parameters:
    extra_joints: ["right_wheel_joint", "left_wheel_joint"]

tricycle_controller:
  ros__parameters:
    traction_joint_name: traction_joint
    steering_joint_name: steering_joint
    wheel_radius: 0.3
    wheelbase: 1.7
    odom_frame_id: odom
    base_frame_id: base_link
    publish_rate: 50.0
    open_loop: false
    enable_odom_tf: true
    odom_only_twist: false
    pose_covariance_diagonal: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    twist_covariance_diagonal: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    velocity_rolling_window_size: 10
    traction:
      max_acceleration: 5.0
      max_deceleration: 8.0
    steering:
      min_position: -1.57
      max_position: 1.57
      max_velocity: 1.0
    cmd_vel_timeout: 500
    use_stamped_vel: false
    publish_ackermann_command: true
"""


def gz_bicycle(yaml_path: str) -> str:
    """
    Return a bicycle-model car built as gz_ros2_control's demos build theirs.

    The Ackermann demo's chassis (100 kg) and wheels (11.3 kg, 0.3 m in radius), wheelbase
    1.7 m, with one rear wheel in the middle driven by a velocity interface and one front
    wheel in the middle steered by a position interface (as bicycle_steering_controller drives
    them), two free rear wheels 1 m apart keeping it upright. No joint name says left or
    right: the driven wheel is known by what it is.
    """
    inertial = ('<inertial><mass value="11.3"/><inertia ixx="0.26" iyy="0.26" izz="0.51" '
                'ixy="0" ixz="0" iyz="0"/></inertial>')

    def wheel(name: str, parent: str, xyz: str, rpy: str = '-1.57 0 0') -> str:
        return f"""
  <link name="{name}">{inertial}
    <collision><geometry><cylinder length="0.08" radius="0.3"/></geometry></collision></link>
  <joint name="{name}_joint" type="continuous"><parent link="{parent}"/><child link="{name}"/>
    <origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/><dynamics damping="0.2"/></joint>"""

    joints = """
    <joint name="rear_wheel_joint"><command_interface name="velocity"/>
      <state_interface name="velocity"/><state_interface name="position"/></joint>
    <joint name="steering_joint"><command_interface name="position"/>
      <state_interface name="position"/></joint>"""
    wheels = ''.join(wheel(n, 'chassis', f'-0.8 {y} -0.2')
                     for n, y in (('rear_wheel', 0.0), ('outer_a', 0.5), ('outer_b', -0.5)))
    return f"""<robot name="bicycle_drive"><link name="base_link"/>
  <link name="chassis"><inertial><mass value="100"/>
    <inertia ixx="10.4" iyy="35.4" izz="41.66" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="2 1 0.5"/></geometry></collision></link>
  <joint name="chassis_joint" type="fixed"><parent link="base_link"/><child link="chassis"/>
    <origin xyz="0.8 0 0.5"/></joint>{wheels}
  <link name="fork"><inertial><mass value="0.1"/>{_I}</inertial></link>
  <joint name="steering_joint" type="revolute"><parent link="chassis"/><child link="fork"/>
    <origin xyz="0.9 0 -0.2" rpy="1.57 0 0"/><axis xyz="0 1 0"/><dynamics damping="0.2"/>
    <limit effort="1000" lower="-1.57" upper="1.57" velocity="30"/></joint>{wheel(
        'front_wheel', 'fork', '0 0 0', '0 0 0')}
  {_gz_system('GazeboSystem', joints, yaml_path)}
</robot>"""


#: bicycle_steering_controller's parameters of the Jazzy line for :func:`gz_bicycle` (10 Hz, as
#: the Ackermann demo's manager; Twist references).
GZ_BICYCLE_YAML = """controller_manager:
  ros__parameters:
    update_rate: 10
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    bicycle_steering_controller:
      type: bicycle_steering_controller/BicycleSteeringController

bicycle_steering_controller:
  ros__parameters:
    wheelbase: 1.7
    front_wheel_radius: 0.3
    rear_wheel_radius: 0.3
    front_steering: true
    reference_timeout: 2.0
    rear_wheels_names: ['rear_wheel_joint']
    front_wheels_names: ['steering_joint']
    use_stamped_vel: false
    open_loop: false
    velocity_rolling_window_size: 10
    base_frame_id: base_link
    odom_frame_id: odom
    enable_odom_tf: true
    position_feedback: false
"""


def gz_diff_drive(yaml_path: str) -> str:
    """
    Return a base as gz_ros2_control's diff-drive demo builds it, for its example program.

    A 1.1 kg chassis (2 x 1 x 0.57 m) on two 2 kg ball wheels 0.3 m in radius, 1.25 m apart,
    and a fixed ball caster behind; velocity interfaces within -1 and 1 rad/s, joints damped.
    """
    def wheel(side: str, y: float) -> str:
        return f"""
  <joint name="{side}_wheel_joint" type="continuous"><parent link="chassis"/>
    <child link="{side}_wheel"/><origin xyz="0.554283 {y} 0.3" rpy="-1.5707 0 0"/>
    <axis xyz="0 0 1"/><dynamics damping="0.2"/></joint>
  <link name="{side}_wheel"><collision><geometry><sphere radius="0.3"/></geometry></collision>
    <inertial><mass value="2"/>
      <inertia ixx="0.145833" iyy="0.145833" izz="0.125" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>"""

    joints = ''.join(f"""
    <joint name="{side}_wheel_joint"><command_interface name="velocity">
        <param name="min">-1</param><param name="max">1</param></command_interface>
      <state_interface name="position"/><state_interface name="velocity"/></joint>"""
                     for side in ('left', 'right'))
    return f"""<robot name="diff_drive">
  <link name="chassis">
    <collision><origin xyz="-0.151427 0 0.5"/><geometry><box size="2.01142 1 0.568726"/>
    </geometry></collision>
    <inertial><origin xyz="-0.151427 0 0.5"/><mass value="1.14395"/>
      <inertia ixx="0.126164" iyy="0.416519" izz="0.481014" ixy="0" ixz="0" iyz="0"/>
    </inertial></link>{wheel('left', 0.625029)}{wheel('right', -0.625029)}
  <joint name="caster_joint" type="fixed"><parent link="chassis"/><child link="caster"/>
    <origin xyz="-0.957138 0 0.2"/></joint>
  <link name="caster"><collision><geometry><sphere radius="0.2"/></geometry></collision>
    <inertial><mass value="0.005"/>{_I}</inertial></link>
  {_gz_system('GazeboSimSystem', joints, yaml_path)}
</robot>"""


#: The diff-drive demo's controllers YAML (its wildcards, its NaN jerks, its limits' flags).
GZ_DIFF_DRIVE_YAML = """/**/controller_manager:
  ros__parameters:
    update_rate: 100
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster

/**/diff_drive_base_controller:
  ros__parameters:
    type: diff_drive_controller/DiffDriveController
    left_wheel_names: ["left_wheel_joint"]
    right_wheel_names: ["right_wheel_joint"]
    wheel_separation: 1.25
    wheel_radius: 0.3
    wheel_separation_multiplier: 1.0
    left_wheel_radius_multiplier: 1.0
    right_wheel_radius_multiplier: 1.0
    publish_rate: 50.0
    odom_frame_id: odom
    base_frame_id: chassis
    open_loop: false
    enable_odom_tf: true
    cmd_vel_timeout: 0.5
    linear.x.has_velocity_limits: true
    linear.x.has_acceleration_limits: true
    linear.x.max_velocity: 1.0
    linear.x.min_velocity: -1.0
    linear.x.max_acceleration: 1.0
    linear.x.max_jerk: .NAN
    linear.x.min_jerk: .NAN
    angular.z.has_velocity_limits: true
    angular.z.has_acceleration_limits: true
    angular.z.max_velocity: 1.0
    angular.z.min_velocity: -1.0
    angular.z.max_acceleration: 1.0
    angular.z.min_acceleration: -1.0
    angular.z.max_jerk: .NAN
    angular.z.min_jerk: .NAN
"""
