"""
The controller types a robot's controllers YAML may name here, with ros2_controllers' rules.

One class per type (some classes serve several names, as the JointGroup controllers do), each
with its parameter schema (:class:`Param`: name, type, default, description, as
ros2_controllers' ``*_parameters.yaml`` give them) and :meth:`ControllerType.check`, which
takes what the type's configure step needs beyond the schema (the joints the robot declares,
one value against another) and says what the controller claims. :data:`REGISTRY` maps a type's
name to its class: the controller manager (:mod:`.manager`) loads and configures through it,
the ROS layer maps each class to its runtime, and :func:`markdown` writes the parameter tables
of docs/controllers.md from the schemas (``python -m sim_node.core.control.controller_types``).

:func:`configure` applies a schema: a parameter left out takes its default, one required and
left out, or given with a wrong type (a string for a number, a number for a bool), refuses the
configure step naming it, as the real controllers' parameter library does. Parameters are
ROS 2's dotted names (``constraints.goal_time``), as a YAML's nesting gives them; families of
names (``constraints.<joint>.goal``, ``linear.x.max_velocity``) are read where they are used
(:mod:`.limits`) and listed in the tables as patterns. ROS-free.
"""

import math
import sys
from typing import Any, NamedTuple, Optional

JOINT_INTERFACES = ('position', 'velocity', 'effort', 'acceleration')
#: A parameter without a default: the configure step refuses to go on without it.
REQUIRED = object()
_BASE = 'controller_interface::ControllerInterface'
_CHAINABLE = 'controller_interface::ChainableControllerInterface'


class Param(NamedTuple):
    """
    One parameter of a controller type.

    ``kind``: ``bool``, ``int``, ``double`` (an int is taken too), ``string``,
    ``string_array`` or ``double_array``; ``size``: an array's length (0: any, not empty when
    required); ``positive``: a number must be > 0.
    """

    name: str
    kind: str
    default: Any
    description: str
    size: int = 0
    positive: bool = False

    def take(self, params: dict) -> Any:
        """Return this parameter's value in `params`, or its default; raise ValueError."""
        value = params.get(self.name, REQUIRED)
        if value is REQUIRED or value is None:
            if self.default is REQUIRED:
                raise ValueError(f"'{self.name}' is not set: {self.description}")
            return self.default
        if not _of_kind(value, self.kind, self.size):
            size = f' of {self.size}' if self.size else ''
            raise ValueError(f"'{self.name}' is {value!r}: it must be a {self.kind}{size}")
        if self.default is REQUIRED and self.kind.endswith('_array') and not value:
            raise ValueError(f"'{self.name}' is []: it must not be empty ({self.description})")
        if self.positive and not value > 0:
            raise ValueError(f"'{self.name}' is {value!r}: it must be a positive number")
        if self.kind == 'double':
            return float(value)
        return tuple(value) if self.kind.endswith('_array') else value


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and \
        math.isfinite(value)


def _of_kind(value, kind: str, size: int) -> bool:
    if kind == 'bool':
        return isinstance(value, bool)
    if kind == 'int':
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == 'double':
        return _number(value)
    if kind == 'string':
        return isinstance(value, str)
    if not isinstance(value, (list, tuple)) or (size and len(value) != size):
        return False
    if kind == 'string_array':
        return all(isinstance(v, str) and v for v in value)
    return all(_number(v) for v in value)  # double_array


class Spec(NamedTuple):
    """
    A configured controller: what it claims, the joints it reads, its parameters.

    ``claims``: ``<joint>/<interface>``; ``params``: the YAML's with every schema parameter
    given (defaults filled in, doubles as floats, arrays as tuples).
    """

    claims: tuple
    joints: tuple
    params: Optional[dict] = None


class ControllerType:
    """A controller type: its names, base class, parameter schema and configure checks."""

    #: The type names (``<package>/<Class>``) this class serves.
    names: tuple = ()
    #: The base class ros2_control lists it with (list_controller_types).
    base = _BASE
    #: What it is, for docs/controllers.md.
    summary = ''
    parameters: tuple = ()
    #: Families of parameter names read where they are used: (pattern, description).
    patterns: tuple = ()

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        """Check what the schema cannot (`p` resolved) and return what it claims and reads."""
        return Spec((), ())


def known_joints(manager) -> set:
    """Return the joints (and sensors) a robot's ``<ros2_control>`` block declares."""
    return {i.split('/', 1)[0] for i in manager.command_interfaces} | \
        {i.split('/', 1)[0] for i in manager.state_interfaces}


def _known(joints: tuple, manager) -> tuple:
    missing = [j for j in joints if j not in known_joints(manager)]
    if missing:
        raise ValueError(f"joints {missing} are not in the robot's <ros2_control> block")
    return joints


_STAMPED = Param('use_stamped_vel', 'bool', True, 'TwistStamped (false: Twist)')
_ODOM = (
    Param('odom_frame_id', 'string', 'odom', 'the odometry frame'),
    Param('base_frame_id', 'string', 'base_link', "the base's frame"),
    Param('pose_covariance_diagonal', 'double_array', (0.0,) * 6,
          "the odometry pose's covariance diagonal", size=6),
    Param('twist_covariance_diagonal', 'double_array', (0.0,) * 6,
          "the odometry twist's covariance diagonal", size=6),
)


class JointStateBroadcaster(ControllerType):
    names = ('joint_state_broadcaster/JointStateBroadcaster',)
    summary = '`joint_states` at its update rate'
    parameters = (
        Param('joints', 'string_array', (), 'the joints published (none: every ros2_control '
              'joint)'),
        Param('extra_joints', 'string_array', (), 'more names, published with zeros'),
    )

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        return Spec((), _known(p['joints'] or tuple(sorted(known_joints(manager))), manager))


#: The JointGroup controllers -> the interface they command.
GROUPS = {'position_controllers/JointGroupPositionController': 'position',
          'velocity_controllers/JointGroupVelocityController': 'velocity',
          'effort_controllers/JointGroupEffortController': 'effort'}


class ForwardCommand(ControllerType):
    names = ('forward_command_controller/ForwardCommandController', *GROUPS)
    summary = '`~/commands` (Float64MultiArray) to one interface of its joints'
    parameters = (
        Param('joints', 'string_array', REQUIRED, 'the joints commanded, in the order of '
              'the values'),
        Param('interface_name', 'string', '', 'the command interface (ForwardCommandController'
              '; the JointGroup controllers have their own)'),
    )

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        joints = _known(p['joints'], manager)
        interface = GROUPS.get(kind) or p['interface_name']
        if not interface:
            raise ValueError("'interface_name' is not set")
        return Spec(tuple(f'{j}/{interface}' for j in joints), joints)


class JointTrajectory(ControllerType):
    names = ('joint_trajectory_controller/JointTrajectoryController',)
    summary = '`~/follow_joint_trajectory` (action), `~/joint_trajectory`, `~/controller_state`'
    parameters = (
        Param('joints', 'string_array', REQUIRED, 'the joints it moves'),
        Param('command_interfaces', 'string_array', REQUIRED, 'position, velocity, effort, '
              'acceleration'),
        Param('state_interfaces', 'string_array', REQUIRED, 'position (required), velocity, '
              'acceleration'),
        Param('allow_partial_joints_goal', 'bool', False, 'a goal may name some joints only'),
        Param('allow_nonzero_velocity_at_trajectory_end', 'bool', False,
              'a trajectory may end moving'),
        Param('open_loop_control', 'bool', False, 'a new trajectory starts from the last '
              'command, not the state'),
        Param('interpolation_method', 'string', 'splines', 'only splines here'),
        Param('constraints.goal_time', 'double', 0.0, 'seconds a goal may run over (0: any)'),
        Param('constraints.stopped_velocity_tolerance', 'double', 0.01,
              'the speed under which a joint counts as stopped'),
    )
    patterns = (('constraints.<joint>.trajectory', 'the path tolerance (rad or m; 0: none)'),
                ('constraints.<joint>.goal', 'the goal tolerance (0: none)'))

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        joints = _known(p['joints'], manager)
        for name in ('command_interfaces', 'state_interfaces'):
            odd = [i for i in p[name] if i not in JOINT_INTERFACES]
            if odd:
                raise ValueError(f"'{name}' has {odd}: not one of {list(JOINT_INTERFACES)}")
        if 'position' not in p['state_interfaces']:
            raise ValueError("'state_interfaces' must hold 'position'")
        if p['interpolation_method'] != 'splines':
            raise ValueError(f"'interpolation_method' {p['interpolation_method']!r} is not "
                             'provided here: '
                             "'splines' (positions, velocities and accelerations as given)")
        return Spec(tuple(f'{j}/{i}' for j in joints for i in p['command_interfaces']), joints)


class DiffDrive(ControllerType):
    names = ('diff_drive_controller/DiffDriveController',)
    base = _CHAINABLE
    summary = '`~/cmd_vel` in, `~/odom` and the odom TF out'
    parameters = (
        Param('left_wheel_names', 'string_array', REQUIRED, 'the left wheels'),
        Param('right_wheel_names', 'string_array', REQUIRED, 'the right wheels'),
        Param('wheel_separation', 'double', REQUIRED, 'between the wheels (m)', positive=True),
        Param('wheel_radius', 'double', REQUIRED, "the wheels' radius (m)", positive=True),
        Param('wheel_separation_multiplier', 'double', 1.0, 'times the separation'),
        Param('left_wheel_radius_multiplier', 'double', 1.0, 'times the left radius'),
        Param('right_wheel_radius_multiplier', 'double', 1.0, 'times the right radius'),
        Param('cmd_vel_timeout', 'double', 0.5, 'simulated seconds after which a twist is '
              'stale and the base stops'),
        Param('publish_rate', 'double', 50.0, 'odometry messages per simulated second',
              positive=True),
        _STAMPED,
        Param('enable_odom_tf', 'bool', True, 'the odom TF on /tf'),
        *_ODOM,
    )
    patterns = (('linear.x.{has,max,min}_{velocity,acceleration,jerk}[_limits]',
                 'limits on the twist, once per update (`has_<x>_limits: false`: that one off)'),
                ('angular.z.{has,max,min}_{velocity,acceleration,jerk}[_limits]',
                 'the same on the turn rate'))

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        wheels = _known(p['left_wheel_names'] + p['right_wheel_names'], manager)
        return Spec(tuple(f'{j}/velocity' for j in wheels), wheels)


class _Steering(ControllerType):
    """The car-like bases: the traction joints take velocities, the steering ones positions."""

    radius = ''

    @classmethod
    def joints(cls, p: dict) -> tuple:
        """Return (traction joints, steering joints) from resolved parameters."""
        raise NotImplementedError

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        traction, steering = cls.joints(p)
        _known(traction + steering, manager)
        return Spec(tuple(f'{j}/velocity' for j in traction)
                    + tuple(f'{j}/position' for j in steering), traction + steering)


_STEERING_COMMON = (
    Param('front_steering', 'bool', True, 'the front wheels steer (false: the rear ones)'),
    Param('rear_wheels_names', 'string_array', (),
          'the rear wheels (Ackermann: the right one, then the left, as Jazzy orders them)'),
    Param('front_wheels_names', 'string_array', (),
          'the front wheels (Ackermann: the right one, then the left)'),
    Param('traction_joints_names', 'string_array', (),
          'the driving joints (later releases; right, then left)'),
    Param('steering_joints_names', 'string_array', (),
          'the steering joints (later releases; right, then left)'),
    Param('wheelbase', 'double', REQUIRED, 'between the axles (m)', positive=True),
    Param('reference_timeout', 'double', 1.0, 'simulated seconds after which a reference is '
          'stale and the base stops'),
    Param('use_stamped_vel', 'bool', True, '`~/reference` TwistStamped (false: '
          '`~/reference_unstamped` Twist)'),
    Param('enable_odom_tf', 'bool', True, 'the odom TF on `~/tf_odometry`'),
    *_ODOM,
)


class SteeringLibrary(_Steering):
    """What the steering_controllers_library's controllers share: wheels by names' lists."""

    base = _CHAINABLE

    @classmethod
    def joints(cls, p: dict) -> tuple:
        if p['traction_joints_names'] or p['steering_joints_names']:
            pairs = (('traction_joints_names', p['traction_joints_names']),
                     ('steering_joints_names', p['steering_joints_names']))
        else:
            rear, front = (('rear_wheels_names', p['rear_wheels_names']),
                           ('front_wheels_names', p['front_wheels_names']))
            pairs = (rear, front) if p['front_steering'] else (front, rear)
        for name, joints in pairs:
            if not joints:
                raise ValueError(f"'{name}' is not set: it must name the wheels")
        return pairs[0][1], pairs[1][1]


class Ackermann(SteeringLibrary):
    names = ('ackermann_steering_controller/AckermannSteeringController',)
    summary = '`~/reference` in, `~/odometry` and `~/tf_odometry` out'
    radius = 'rear_wheels_radius'
    parameters = (
        *_STEERING_COMMON,
        Param('front_wheel_track', 'double', REQUIRED, 'between the front wheels (m)',
              positive=True),
        Param('rear_wheel_track', 'double', 0.0, 'between the rear wheels (m; 0: the front '
              "track's)"),
        Param('rear_wheels_radius', 'double', REQUIRED, "the rear wheels' radius (m)",
              positive=True),
        Param('front_wheels_radius', 'double', 0.0, "the front wheels' radius (m)"),
    )


class Bicycle(SteeringLibrary):
    names = ('bicycle_steering_controller/BicycleSteeringController',)
    summary = Ackermann.summary
    radius = 'rear_wheel_radius'
    parameters = (
        *_STEERING_COMMON,
        Param('rear_wheel_radius', 'double', REQUIRED, "the rear wheel's radius (m)",
              positive=True),
        Param('front_wheel_radius', 'double', 0.0, "the front wheel's radius (m)"),
    )


class Tricycle(_Steering):
    names = ('tricycle_controller/TricycleController',)
    summary = '`~/cmd_vel` in, `~/odom` and the odom TF out'
    radius = 'wheel_radius'
    parameters = (
        Param('traction_joint_name', 'string', REQUIRED, 'the steered wheel that drives'),
        Param('steering_joint_name', 'string', REQUIRED, 'its steering joint'),
        Param('wheelbase', 'double', REQUIRED, 'from the steered wheel to the rear axle (m)',
              positive=True),
        Param('wheel_radius', 'double', REQUIRED, "the traction wheel's radius (m)",
              positive=True),
        Param('cmd_vel_timeout', 'int', 500, 'milliseconds after which a twist is stale, '
              'as its own'),
        _STAMPED,
        Param('enable_odom_tf', 'bool', False, 'the odom TF on /tf (off, as its own)'),
        *_ODOM,
    )
    patterns = (('traction.{has,max,min}_{velocity,acceleration,deceleration,jerk}[_limits]',
                 "limits on the wheel's speed, on sizes (`has_<x>_limits: false`: that one off)"),
                ('steering.{has,max,min}_{position,velocity,acceleration}[_limits]',
                 'limits on its angle'))

    @classmethod
    def joints(cls, p: dict) -> tuple:
        for name in ('traction_joint_name', 'steering_joint_name'):
            if not p[name]:
                raise ValueError(f"'{name}' is '': it must name a joint")
        return (p['traction_joint_name'],), (p['steering_joint_name'],)


PARALLEL_GRIPPER = 'parallel_gripper_action_controller/GripperActionController'
#: The gripper action controllers -> the interface they command.
GRIPPERS = {'position_controllers/GripperActionController': 'position',
            'effort_controllers/GripperActionController': 'effort',
            PARALLEL_GRIPPER: 'position'}


class Gripper(ControllerType):
    names = tuple(GRIPPERS)
    summary = '`~/gripper_cmd` (GripperCommand; the parallel one ParallelGripperCommand)'
    parameters = (
        Param('joint', 'string', REQUIRED, "the gripper's joint"),
        Param('goal_tolerance', 'double', 0.01, 'how near the goal counts as reached',
              positive=True),
        Param('stall_velocity_threshold', 'double', 0.001, 'the speed under which it stalls',
              positive=True),
        Param('stall_timeout', 'double', 1.0, 'simulated seconds stalled before it ends',
              positive=True),
        Param('allow_stalling', 'bool', False, 'a stall succeeds (false: aborts)'),
        Param('action_monitor_rate', 'double', 20.0, 'checks per simulated second',
              positive=True),
    )

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        if not p['joint']:
            raise ValueError("'joint' is '': it must name the gripper's joint")
        joint = _known((p['joint'],), manager)
        return Spec((f'{joint[0]}/{GRIPPERS[kind]}',), joint)


class _SensorBroadcaster(ControllerType):
    parameters = (
        Param('sensor_name', 'string', REQUIRED, "a <sensor> of the robot's <ros2_control> "
              'block'),
        Param('frame_id', 'string', REQUIRED, "the messages' frame"),
    )

    @classmethod
    def check(cls, kind: str, p: dict, manager) -> Spec:
        sensors = {i.split('/', 1)[0] for i in manager.state_interfaces}
        if p['sensor_name'] not in sensors:
            raise ValueError(f"'sensor_name' is {p['sensor_name']!r}: not a sensor of the "
                             "robot's <ros2_control> block")
        if not p['frame_id']:
            raise ValueError("'frame_id' is not set")
        return Spec((), ())


class ImuBroadcaster(_SensorBroadcaster):
    names = ('imu_sensor_broadcaster/IMUSensorBroadcaster',)
    summary = '`~/imu` (sensor_msgs/Imu)'
    parameters = _SensorBroadcaster.parameters + tuple(
        Param(f'static_covariance_{k}', 'double_array', (0.0,) * 9,
              f'the {k.replace("_", " ")} covariance', size=9)
        for k in ('orientation', 'angular_velocity', 'linear_acceleration'))


class ForceTorqueBroadcaster(_SensorBroadcaster):
    names = ('force_torque_sensor_broadcaster/ForceTorqueSensorBroadcaster',)
    summary = '`~/wrench` (geometry_msgs/WrenchStamped)'


#: Every type name -> its class.
REGISTRY = {name: cls for cls in (
    JointStateBroadcaster, ForwardCommand, JointTrajectory, DiffDrive, Gripper, Ackermann,
    Bicycle, Tricycle, ImuBroadcaster, ForceTorqueBroadcaster) for name in cls.names}
#: type -> the base class ros2_control lists it with (list_controller_types).
TYPES = {name: cls.base for name, cls in REGISTRY.items()}


def configure(kind: str, params: dict, manager) -> Spec:
    """
    Check a controller's parameters by its type's schema and checks; return its :class:`Spec`.

    :param manager: its :class:`~.manager.Manager` (the robot's declared interfaces).
    :raises ValueError: naming the parameter (or joint) that is missing or wrong.
    """
    cls = REGISTRY.get(kind)
    if cls is None:
        raise ValueError(f"type '{kind}' is not provided")
    resolved = dict(params)
    for param in cls.parameters:
        resolved[param.name] = param.take(params)
    claims, joints, _ = cls.check(kind, resolved, manager)
    return Spec(claims, joints, resolved)


def markdown() -> str:
    """Return the parameter tables docs/controllers.md holds: one per controller class."""
    out = []
    for cls in dict.fromkeys(REGISTRY.values()):
        out.append(f"### {', '.join(f'`{n}`' for n in cls.names)}\n\n{cls.summary}\n")
        out.append('| parameter | type | default | what it is |\n|---|---|---|---|')
        for p in cls.parameters:
            out.append(f'| `{p.name}` | {p.kind}{f"[{p.size}]" if p.size else ""} | '
                       f'{_shown(p.default)} | {p.description} |')
        for pattern, description in cls.patterns:
            out.append(f'| `{pattern}` | double, bool | none | {description} |')
        out.append('')
    return '\n'.join(out)


def _shown(default) -> str:
    if default is REQUIRED:
        return '**required**'
    if isinstance(default, bool):
        return f'`{str(default).lower()}`'
    if isinstance(default, tuple):
        return '`[]`' if not default else f'`{list(default)}`'
    return f'`{default!r}`' if isinstance(default, str) else f'`{default}`'


if __name__ == '__main__':
    sys.stdout.write(markdown())
