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
#: type -> the base class ros2_control lists it with (list_controller_types).
TYPES = {JSB: 'controller_interface::ControllerInterface',
         FORWARD: 'controller_interface::ControllerInterface',
         **dict.fromkeys(GROUPS, 'controller_interface::ControllerInterface'),
         JTC: 'controller_interface::ControllerInterface',
         DIFF_DRIVE: 'controller_interface::ChainableControllerInterface'}
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
        return Spec(tuple(f'{j}/{i}' for j in joints for i in command), joints)
    if kind == DIFF_DRIVE:
        left, right = _names(params, 'left_wheel_names'), _names(params, 'right_wheel_names')
        _known(left + right, known)
        for key in ('wheel_separation', 'wheel_radius'):
            value = params.get(key)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or value <= 0:
                raise ValueError(f"'{key}' is {value!r}: it must be a positive number")
        return Spec(tuple(f'{j}/velocity' for j in left + right), left + right)
    raise ValueError(f"type '{kind}' is not provided")


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
