"""
The controller types a robot's controllers YAML may name here, with ros2_controllers' rules.

For each type, :func:`configure` checks the parameters its configure step needs (as the real
controller's ``on_configure`` refuses a missing or empty one) and returns what it claims (the
command interfaces ``<joint>/<interface>`` it writes) and the joints it reads. Parameters are
ROS 2's dotted names (``constraints.goal_time``), as a YAML's nesting gives them. ROS-free.
"""

from typing import NamedTuple

JSB = 'joint_state_broadcaster/JointStateBroadcaster'
FORWARD = 'forward_command_controller/ForwardCommandController'
GROUPS = {'position_controllers/JointGroupPositionController': 'position',
          'velocity_controllers/JointGroupVelocityController': 'velocity',
          'effort_controllers/JointGroupEffortController': 'effort'}
JTC = 'joint_trajectory_controller/JointTrajectoryController'
DIFF_DRIVE = 'diff_drive_controller/DiffDriveController'
ACKERMANN = 'ackermann_steering_controller/AckermannSteeringController'
BICYCLE = 'bicycle_steering_controller/BicycleSteeringController'
TRICYCLE = 'tricycle_controller/TricycleController'
IMU = 'imu_sensor_broadcaster/IMUSensorBroadcaster'
FORCE_TORQUE = 'force_torque_sensor_broadcaster/ForceTorqueSensorBroadcaster'
PARALLEL_GRIPPER = 'parallel_gripper_action_controller/GripperActionController'
#: Gripper action controllers -> the interface they command.
GRIPPERS = {'position_controllers/GripperActionController': 'position',
            'effort_controllers/GripperActionController': 'effort',
            PARALLEL_GRIPPER: 'position'}
#: type -> the base class ros2_control lists it with (list_controller_types).
TYPES = {JSB: 'controller_interface::ControllerInterface',
         FORWARD: 'controller_interface::ControllerInterface',
         **dict.fromkeys(GROUPS, 'controller_interface::ControllerInterface'),
         JTC: 'controller_interface::ControllerInterface',
         DIFF_DRIVE: 'controller_interface::ChainableControllerInterface',
         **dict.fromkeys(GRIPPERS, 'controller_interface::ControllerInterface'),
         ACKERMANN: 'controller_interface::ChainableControllerInterface',
         BICYCLE: 'controller_interface::ChainableControllerInterface',
         TRICYCLE: 'controller_interface::ControllerInterface',
         IMU: 'controller_interface::ControllerInterface',
         FORCE_TORQUE: 'controller_interface::ControllerInterface'}
JOINT_INTERFACES = ('position', 'velocity', 'effort', 'acceleration')


class Spec(NamedTuple):
    """What a configured controller claims (``<joint>/<interface>``) and the joints it reads."""

    claims: tuple
    joints: tuple


def configure(kind: str, params: dict, manager) -> Spec:
    """
    Check a controller's parameters and return its :class:`Spec`.

    :param manager: its :class:`~.manager.Manager` (the robot's declared interfaces).
    :raises ValueError: naming the parameter (or joint) that is missing or wrong.
    """
    known = {i.split('/', 1)[0] for i in manager.command_interfaces} | \
        {i.split('/', 1)[0] for i in manager.state_interfaces}
    if kind == JSB:
        joints = _names(params, 'joints', required=False) or tuple(sorted(known))
        _known(joints, known)
        return Spec((), joints)
    if kind == FORWARD or kind in GROUPS:
        joints = _names(params, 'joints')
        _known(joints, known)
        interface = GROUPS.get(kind) or params.get('interface_name')
        if not interface or not isinstance(interface, str):
            raise ValueError("'interface_name' is not set")
        return Spec(tuple(f'{j}/{interface}' for j in joints), joints)
    if kind == JTC:
        joints = _names(params, 'joints')
        _known(joints, known)
        command = _names(params, 'command_interfaces')
        state = _names(params, 'state_interfaces')
        for name, given in (('command_interfaces', command), ('state_interfaces', state)):
            odd = [i for i in given if i not in JOINT_INTERFACES]
            if odd:
                raise ValueError(f"'{name}' has {odd}: not one of {list(JOINT_INTERFACES)}")
        if 'position' not in state:
            raise ValueError("'state_interfaces' must hold 'position'")
        method = params.get('interpolation_method', 'splines')
        if method != 'splines':
            raise ValueError(f"'interpolation_method' {method!r} is not provided here: "
                             "'splines' (positions, velocities and accelerations as given)")
        return Spec(tuple(f'{j}/{i}' for j in joints for i in command), joints)
    if kind in (IMU, FORCE_TORQUE):
        sensor = params.get('sensor_name')
        sensors = {i.split('/', 1)[0] for i in manager.state_interfaces}
        if not isinstance(sensor, str) or sensor not in sensors:
            raise ValueError(f"'sensor_name' is {sensor!r}: not a sensor of the robot's "
                             '<ros2_control> block')
        if not params.get('frame_id'):
            raise ValueError("'frame_id' is not set")
        return Spec((), ())
    if kind in (ACKERMANN, BICYCLE, TRICYCLE):
        traction, steering = steering_joints(kind, params)
        _known(traction + steering, known)
        numbers = {ACKERMANN: ('wheelbase', 'front_wheel_track', 'rear_wheels_radius'),
                   BICYCLE: ('wheelbase', 'rear_wheel_radius'),
                   TRICYCLE: ('wheelbase', 'wheel_radius')}[kind]
        for key in numbers:
            value = params.get(key)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or value <= 0:
                raise ValueError(f"'{key}' is {value!r}: it must be a positive number")
        return Spec(tuple(f'{j}/velocity' for j in traction)
                    + tuple(f'{j}/position' for j in steering), traction + steering)
    if kind in GRIPPERS:
        joint = params.get('joint')
        if not isinstance(joint, str) or not joint:
            raise ValueError(f"'joint' is {joint!r}: it must name the gripper's joint")
        _known((joint,), known)
        return Spec((f'{joint}/{GRIPPERS[kind]}',), (joint,))
    if kind == DIFF_DRIVE:
        left, right = _names(params, 'left_wheel_names'), _names(params, 'right_wheel_names')
        _known(left + right, known)
        for key in ('wheel_separation', 'wheel_radius'):
            value = params.get(key)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or value <= 0:
                raise ValueError(f"'{key}' is {value!r}: it must be a positive number")
        return Spec(tuple(f'{j}/velocity' for j in left + right), left + right)
    raise ValueError(f"type '{kind}' is not provided")


def steering_joints(kind: str, params: dict) -> tuple:
    """Return a car-like base's (traction joints, steering joints) from its parameters."""
    if kind == TRICYCLE:
        return (_names({'j': [params.get('traction_joint_name')]}, 'j'),
                _names({'j': [params.get('steering_joint_name')]}, 'j'))
    front = params.get('front_steering', True) is not False
    wheels = ('rear_wheels_names', 'front_wheels_names')
    if 'traction_joints_names' in params:  # the names of later releases
        return _names(params, 'traction_joints_names'), _names(params, 'steering_joints_names')
    rear, ahead = _names(params, wheels[0]), _names(params, wheels[1])
    return (rear, ahead) if front else (ahead, rear)


def _names(params: dict, key: str, required: bool = True) -> tuple:
    value = params.get(key)
    if value in (None, [], ()) and not required:
        return ()
    if not isinstance(value, (list, tuple)) or not value or \
            not all(isinstance(v, str) and v for v in value):
        raise ValueError(f"'{key}' is {value!r}: it must be a non-empty list of names")
    return tuple(value)


def _known(joints: tuple, known: set) -> None:
    missing = [j for j in joints if j not in known]
    if missing:
        raise ValueError(f"joints {missing} are not in the robot's <ros2_control> block")
