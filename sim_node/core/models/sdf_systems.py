"""
The gz-sim systems an SDF file names: by what they are here, and what they declare.

A ``<plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">`` (or
``libgz-sim-...-system.so``, ``ignition-gazebo-...``, ``ignition::gazebo::systems::...``) is
known by its system name (:func:`system_name`: ``DiffDrive``). World systems that only make
Gazebo do what this simulator always does (its physics, its scene broadcast to the GUI, its
user commands, its sensors and the systems that feed them) are accepted silently
(:data:`SILENT`); the model systems this simulator runs are :data:`RUN` (their laws:
:mod:`sim_node.core.control`); any other is named once in a warning and on /diagnostics
(:func:`world_systems`, :func:`model_systems`).

:func:`read` takes a system this simulator runs into a :class:`GzSystem`: the joints it
commands or publishes, its parameters (gz-sim's defaults where the plugin gives none), its
topics (its ``<topic>``-like elements, else gz-sim's defaults: the names a ros_gz_bridge user
bridges) and its rate; their laws are :mod:`sim_node.core.control.gz_systems`.
"""

from dataclasses import dataclass, field
import math
import re
from typing import Iterable, Optional, Sequence
import xml.etree.ElementTree as ET

#: Systems whose work this simulator does anyway.
SILENT = frozenset({
    'Physics', 'MujocoPhysics', 'SceneBroadcaster', 'UserCommands', 'Sensors', 'Imu',
    'Contact', 'ForceTorque', 'Altimeter', 'Magnetometer', 'NavSat', 'AirPressure',
    'LogicalCamera'})
#: Model systems this simulator runs: their laws and publishers, and gz_ros2_control's
#: controller manager (:mod:`.ros2_control`).
RUN = frozenset({
    'DiffDrive', 'AckermannSteering', 'JointPositionController', 'JointController',
    'JointStatePublisher', 'JointTrajectoryController', 'PosePublisher',
    'GazeboSimROS2ControlPlugin', 'IgnitionROS2ControlPlugin', 'gz_ros2_control'})
_PREFIXES = ('libgz-sim-', 'gz-sim-', 'libignition-gazebo-', 'ignition-gazebo-')


def system_name(plugin: ET.Element) -> str:
    """Return the system a ``<plugin>`` names (``DiffDrive``), from its name or file."""
    name = (plugin.get('name') or '').strip()
    if '::' in name:
        return name.rsplit('::', 1)[-1]
    filename = (plugin.get('filename') or '').strip()
    base = filename.rsplit('/', 1)[-1]
    base = re.sub(r'\.so(\.\d+)*$', '', base)
    if 'ros2_control' in base:
        return 'gz_ros2_control'
    for prefix in _PREFIXES:
        if base.startswith(prefix):
            base = re.sub(r'^\d+-', '', base[len(prefix):])
            break
    base = re.sub(r'-system$', '', base)
    return ''.join(p.capitalize() for p in re.split(r'[-_]', base) if p) or name or filename


def _unknown(plugins: Iterable[ET.Element], known: frozenset) -> list:
    out = []
    for p in plugins:
        name = system_name(p)
        if name not in known and name not in out:
            out.append(name)
    return out


def world_systems(world: ET.Element) -> list:
    """Return the world plugins this simulator neither runs nor needs: named in a warning."""
    return _unknown(world.findall('plugin'), SILENT | RUN)


def model_systems(model: ET.Element) -> list:
    """Return a model's plugins that this simulator does not run (not its sensors')."""
    inside = {id(p) for s in model.iter('sensor') for p in s.iter('plugin')}
    return _unknown((p for p in model.iter('plugin') if id(p) not in inside), SILENT | RUN)


#: Systems with a law, and those whose publishers read the world.
LAWS = ('DiffDrive', 'AckermannSteering', 'JointPositionController', 'JointController',
        'JointTrajectoryController')
PUBLISHERS = ('JointStatePublisher', 'PosePublisher')
#: Simulated Hz the base systems update at (their wheels' velocity actuators hold between).
BASE_RATE_HZ = 100.0
#: gz-sim's PID defaults: JointPositionController's; JointController's force PID.
POSITION_PID = {'p_gain': 1.0, 'i_gain': 0.1, 'd_gain': 0.01, 'i_max': 1.0, 'i_min': -1.0,
                'cmd_max': 1000.0, 'cmd_min': -1000.0, 'cmd_offset': 0.0}
VELOCITY_PID = {'p_gain': 1.0, 'i_gain': 0.0, 'd_gain': 0.0, 'i_max': 1.0, 'i_min': -1.0,
                'cmd_max': 1000.0, 'cmd_min': -1000.0, 'cmd_offset': 0.0}
_LIMIT_NAMES = {  # gz-sim's element -> diff_drive_controller's parameter
    'max_linear_velocity': 'linear.x.max_velocity', 'min_linear_velocity': 'linear.x.min_velocity',
    'max_velocity': 'linear.x.max_velocity', 'min_velocity': 'linear.x.min_velocity',
    'max_linear_acceleration': 'linear.x.max_acceleration',
    'min_linear_acceleration': 'linear.x.min_acceleration',
    'max_acceleration': 'linear.x.max_acceleration',
    'min_acceleration': 'linear.x.min_acceleration',
    'max_linear_jerk': 'linear.x.max_jerk', 'min_linear_jerk': 'linear.x.min_jerk',
    'max_jerk': 'linear.x.max_jerk', 'min_jerk': 'linear.x.min_jerk',
    'max_angular_velocity': 'angular.z.max_velocity',
    'min_angular_velocity': 'angular.z.min_velocity',
    'max_angular_acceleration': 'angular.z.max_acceleration',
    'min_angular_acceleration': 'angular.z.min_acceleration',
    'max_angular_jerk': 'angular.z.max_jerk', 'min_angular_jerk': 'angular.z.min_jerk'}

ERR_JOINT = '{system} of {model!r}: {what} {joint!r} is not a joint of the model'
ERR_NUMBER = '{system} of {model!r}: <{tag}>{text}</{tag}> is not a finite number'
ERR_NO_JOINT = '{system} of {model!r} names no <{tag}>'


def ros_topic(name: str) -> str:
    """
    Return a gz-sim topic as ROS can name it: the same, where ROS takes it.

    gz-transport takes names ROS refuses: a token that is a number (JointPositionController's
    default ``/model/<m>/joint/<j>/0/cmd_pos`` holds the axis index) is left out, another
    character than a letter, a digit or ``_`` (a nested joint's ``::``) becomes ``_``, and a
    token starting with a digit gets a ``_`` before it.
    """
    out = []
    for token in name.split('/'):
        if not token or token.isdigit():
            continue
        token = re.sub(r'[^A-Za-z0-9_]', '_', token)
        out.append(f'_{token}' if token[0].isdigit() else token)
    return '/' + '/'.join(out)


@dataclass(frozen=True)
class GzSystem:
    """
    One system of one model (see the module docstring), in the model's own joint names.

    :param topics: role -> topic (``cmd_vel``, ``odometry``, ``tf``, ``cmd_pos/<joint>``,
        ``cmd_vel/<joint>``, ``joint_state``, ``pose``, ``trajectory``, ``progress``).
    :param frames: the odometry's ``frame_id`` and ``child_frame_id`` (base systems).
    :param rate_hz: simulated Hz it updates or publishes at (0: every step).
    """

    kind: str
    joints: tuple = ()
    params: dict = field(default_factory=dict)
    topics: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)
    rate_hz: float = 0.0


def _texts(plugin: ET.Element, tag: str) -> list:
    return [(e.text or '').strip() for e in plugin.findall(tag) if (e.text or '').strip()]


def _number(plugin: ET.Element, tag: str, default: float, system: str, model: str) -> float:
    text = plugin.findtext(tag)
    if text is None or not text.strip():
        return default
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ValueError(ERR_NUMBER.format(system=system, model=model, tag=tag,
                                           text=text.strip()[:40]))
    return value


def _flag(plugin: ET.Element, tag: str) -> bool:
    return (plugin.findtext(tag) or '').strip().lower() in ('true', '1')


def read(kind: str, plugin: ET.Element, model: str, joints: Sequence[str], canonical: str,
         world: str) -> Optional[GzSystem]:
    """
    Return the system `kind` a plugin of `model` declares (None: not one of these).

    :param joints: the model's joint names (SDF's, ``nested::joint`` for a nested model's).
    :param canonical: its canonical link (the odometry's default child frame).
    :param world: the world's name (gz-sim's default topics hold it).
    :raises ValueError: a joint it names that the model lacks, or a number that is not one.
    """
    known = set(joints)

    def joint_list(tag: str, required: bool = True) -> tuple:
        names = tuple(_texts(plugin, tag))
        if required and not names:
            raise ValueError(ERR_NO_JOINT.format(system=kind, model=model, tag=tag))
        for j in names:
            if j not in known:
                raise ValueError(ERR_JOINT.format(system=kind, model=model, what=f'<{tag}>',
                                                  joint=j))
        return names

    def topic(tag: str, default: str) -> str:
        given = (plugin.findtext(tag) or '').strip()
        return ros_topic(given if given.startswith('/') else f'/{given}' if given else default)

    base = f'/model/{model}'
    num = lambda tag, default: _number(plugin, tag, default, kind, model)  # noqa: E731
    if kind in ('DiffDrive', 'AckermannSteering'):
        left, right = joint_list('left_joint'), joint_list('right_joint')
        topics = {'cmd_vel': topic('topic', f'{base}/cmd_vel'),
                  'odometry': topic('odom_topic', f'{base}/odometry'),
                  'tf': topic('tf_topic', f'{base}/tf')}
        frames = {'frame_id': (plugin.findtext('frame_id') or f'{model}/odom').strip(),
                  'child_frame_id': (plugin.findtext('child_frame_id')
                                     or f'{model}/{canonical}').strip()}
        limits = {name: num(tag, 0.0) for tag, name in _LIMIT_NAMES.items()
                  if plugin.find(tag) is not None}
        params = {'wheel_separation': num('wheel_separation', 1.0),
                  'wheel_radius': num('wheel_radius', 0.2),
                  'odom_publish_frequency': num('odom_publish_frequency', 50.0), **limits}
        if kind == 'DiffDrive':
            params.update(left_wheel_names=list(left), right_wheel_names=list(right),
                          cmd_vel_timeout=0.0)
            return GzSystem(kind, left + right, params, topics, frames, BASE_RATE_HZ)
        steer = (joint_list('right_steering_joint'), joint_list('left_steering_joint'))
        params.update(traction_joints_names=[right[0], left[0]], front_steering=True,
                      steering_joints_names=[steer[0][0], steer[1][0]], rear_wheels_names=[],
                      front_wheels_names=[], wheelbase=num('wheel_base', 1.0),
                      rear_wheel_track=params['wheel_separation'],
                      front_wheel_track=num('kingpin_width', params['wheel_separation']),
                      rear_wheels_radius=params['wheel_radius'], reference_timeout=0.0,
                      steering_limit=num('steering_limit', 0.5),
                      steer_p_gain=num('steer_p_gain', 1.0))
        return GzSystem(kind, left + right + steer[0] + steer[1], params, topics, frames,
                        BASE_RATE_HZ)
    if kind in ('JointPositionController', 'JointController'):
        names = joint_list('joint_name')
        position = kind == 'JointPositionController'
        defaults = POSITION_PID if position else VELOCITY_PID
        params = {k: num(k, v) for k, v in defaults.items()}
        params['direct'] = (_flag(plugin, 'use_velocity_commands') if position
                            else not _flag(plugin, 'use_force_commands'))
        params['initial'] = num('initial_position' if position else 'initial_velocity', 0.0)
        index = int(num('joint_index', 0.0)) if position else 0
        role = 'cmd_pos' if position else 'cmd_vel'
        default = (f'{base}/joint/{names[0]}/{index}/cmd_pos' if position
                   else f'{base}/joint/{names[0]}/cmd_vel')
        return GzSystem(kind, names, params, {role: topic('topic', topic('sub_topic', default))},
                        rate_hz=0.0)
    if kind == 'JointTrajectoryController':
        names = joint_list('joint_name', required=False) or tuple(joints)
        gains = {g: [float(v) for v in _texts(plugin, f'position_{g}')]
                 for g in ('p_gain', 'i_gain', 'd_gain', 'i_max', 'i_min', 'cmd_max',
                           'cmd_min')}
        return GzSystem(kind, names, {'gains': gains,
                                      'initial': [float(v) for v in
                                                  _texts(plugin, 'initial_position')]},
                        {'trajectory': topic('topic', f'{base}/joint_trajectory'),
                         'progress': topic('progress_topic',
                                           f'{base}/joint_trajectory_progress')})
    if kind == 'JointStatePublisher':
        names = joint_list('joint_name', required=False) or tuple(joints)
        return GzSystem(kind, names, {}, {'joint_state': topic(
            'topic', f'/world/{world}/model/{model}/joint_state')},
            rate_hz=num('update_rate', 50.0))
    if kind == 'PosePublisher':
        rate = num('update_frequency', -1.0)
        flags = {f: _flag(plugin, f) if plugin.find(f) is not None else f == 'publish_link_pose'
                 for f in ('publish_link_pose', 'publish_model_pose',
                           'publish_nested_model_pose')}
        return GzSystem(kind, (), flags, {'pose': f'{base}/pose'},
                        rate_hz=rate if rate > 0 else 50.0)
    return None
