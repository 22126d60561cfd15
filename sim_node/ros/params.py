"""
The node's ROS parameters.

Declared from :class:`~sim_node.core.config.WorldConfig` with descriptors (description, range,
read-only where a change needs a restart).
"""

import dataclasses
import re
from typing import List

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..core.checks import closest_hint
from ..core.config import PerceptionConfig, WorldConfig


@dataclasses.dataclass(frozen=True)
class Frames:
    """The node's frame names: the world body's (`world_frame`) and the prefix of every frame."""

    world: str = 'world'
    prefix: str = ''

    @property
    def out_world(self) -> str:
        """Return the world frame as published (after the prefix)."""
        return self.prefix + self.world

    def reference(self, frame_id: str) -> str:
        """'' for the world frame, else the entity whose frame a request's pose is given in."""
        if frame_id in ('', self.world, '/' + self.world, self.out_world):
            return ''
        return frame_id


def frames(node: Node) -> Frames:
    return Frames(node.get_parameter('world_frame').value,
                  node.get_parameter('frame_prefix').value)


def _descriptor(description: str, read_only: bool = False, fmin=None, fmax=None,
                imin=None, imax=None) -> ParameterDescriptor:
    d = ParameterDescriptor(description=description, read_only=read_only)
    if fmin is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(fmin),
                                                     to_value=float(fmax), step=0.0)]
    if imin is not None:
        d.integer_range = [IntegerRange(from_value=int(imin), to_value=int(imax), step=0)]
    return d


#: Parameters of type double: an integer given for one (``real_time_factor:=0``, ``ros2 param
#: set /sim real_time_factor 1``) is taken as that number, as users type them.
DOUBLES = ('real_time_factor', 'timestep', 'max_sim_time', 'tf_rate_hz', 'joint_states_rate_hz',
           'kp', 'kd', 'camera_rate_hz', 'lidar_rate_hz', 'lidar_angle_min', 'lidar_angle_max',
           'lidar_range_min', 'lidar_range_max', 'world_extent', 'odom_rate_hz',
           'cmd_vel_timeout', 'record_split_mb', 'record_split_s', 'record_max_mb')


def integers_as_doubles(params: List[Parameter]) -> List[Parameter]:
    """
    Accept an integer value for a double parameter as that double.

    Nothing else changes (a string stays a string, and is refused as the wrong type).
    """
    return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
            if p.name in DOUBLES and p.type_ == Parameter.Type.INTEGER else p for p in params]


def string_list(node: Node, name: str) -> List[str]:
    """Return a string-array parameter declared without a default ([] when it was not given)."""
    try:
        return list(node.get_parameter(name).value or [])
    except ParameterUninitializedException:
        return []


def declare(node: Node, scenes_dir: str) -> None:
    """
    Declare every parameter of the node with its default.

    Integers given on the command line for double parameters are taken as doubles, at start-up and
    at run time.
    """
    overrides = getattr(node, '_parameter_overrides', {})  # rclpy keeps --ros-args -p here
    for p in integers_as_doubles(list(overrides.values())):
        overrides[p.name] = p
    node.add_pre_set_parameters_callback(integers_as_doubles)
    c = WorldConfig()
    d = _descriptor
    node.declare_parameter('scene', 'default', d(
        'MJCF/URDF scene: a file path or an installed scene name', read_only=True))
    node.declare_parameter('real_time_factor', c.real_time_factor, d(
        'simulated seconds per wall second; 0 = as fast as possible', fmin=0, fmax=1000))
    node.declare_parameter('paused', c.paused, d('pause or play the simulation'))
    node.declare_parameter('timestep', c.timestep, d(
        "physics step in seconds; 0 keeps the scene's own", fmin=0, fmax=0.1))
    node.declare_parameter('max_steps', c.max_steps, d(
        'pause after this many steps since the last time reset; 0 = unbounded',
        imin=0, imax=2 ** 62))
    node.declare_parameter('max_sim_time', c.max_sim_time, d(
        'pause after the first step at or past this simulated time (s); 0 = unbounded',
        fmin=0, fmax=1e9))
    node.declare_parameter('tf_rate_hz', 100.0, d(
        'rate of /clock and /tf (wall Hz)', read_only=True, fmin=1, fmax=1000))
    node.declare_parameter('joint_states_rate_hz', 50.0, d(
        'rate of joint_states and sensor messages (wall Hz)', read_only=True, fmin=1, fmax=1000))
    node.declare_parameter('world_frame', 'world', d(
        'TF frame of the MuJoCo world body', read_only=True))
    node.declare_parameter('frame_prefix', '', d(
        'prepended to every frame id the node publishes (e.g. robot2/), for several worlds '
        'in one domain', read_only=True))
    node.declare_parameter('publish_clock', True, d(
        'publish /clock (one world per domain should)', read_only=True))
    node.declare_parameter('resource_paths', Parameter.Type.STRING_ARRAY, d(
        'directories that spawn and load_world may read files from, besides the installed '
        'scenes and objects (see builtin_resources)', read_only=True))
    node.declare_parameter('builtin_resources', True, d(
        f'whether the installed scenes and objects ({scenes_dir}) stay readable besides '
        'resource_paths', read_only=True))
    node.declare_parameter('kp', c.kp, d(
        'PD stiffness for position commands on joints without a position actuator',
        fmin=0, fmax=1e6))
    node.declare_parameter('kd', c.kd, d(
        'PD damping for position/velocity commands without a matching actuator',
        fmin=0, fmax=1e6))
    node.declare_parameter('allow_interpenetration', c.allow_interpenetration, d(
        'allow spawning into overlapping geometry', read_only=True))
    node.declare_parameter('divergence_policy', c.divergence_policy, d(
        "when the physics diverges while playing: 'pause', 'remove' the entity it happened in "
        "(if spawned) and play on, or 'reset' the state and play on", read_only=True))
    node.declare_parameter('world_extent', c.world_extent, d(
        'entities may be placed only within this many metres of the world origin on each axis: '
        'a pose outside is invalid (spawn 109, set_entity_state 101)', read_only=True,
        fmin=1.0, fmax=1e7))
    node.declare_parameter('max_bodies', c.max_bodies, d(
        'most bodies the world may hold; a spawn past it is refused', read_only=True,
        imin=2, imax=100_000))
    node.declare_parameter('trajectory_path_tolerance', 0.25, d(
        'default position tolerance (rad or m) along a FollowJointTrajectory goal, every '
        "joint; 0: not checked; a goal's path_tolerance overrides it", fmin=0, fmax=1e3))
    node.declare_parameter('trajectory_goal_tolerance', 0.05, d(
        'default position tolerance at the end of a FollowJointTrajectory goal; 0: not '
        "checked (the goal succeeds at its last point's time)", fmin=0, fmax=1e3))
    node.declare_parameter('trajectory_goal_time_tolerance', 1.0, d(
        'default time (s) after the end within which the goal tolerance must be met; 0: no '
        'limit', fmin=0, fmax=1e6))
    node.declare_parameter('cmd_vel_stamped', False, d(
        '<entity>/cmd_vel takes geometry_msgs/TwistStamped (diff_drive_controller, later nav2) '
        "instead of Twist (nav2 Jazzy's default)", read_only=True))
    node.declare_parameter('record', '', d(
        'a folder to record the run into, as rosbag2 bags (MCAP) that ros2 bag play and '
        "Foxglove open; '' records nothing", read_only=True))
    node.declare_parameter('record_topics', ['*'], d(
        'topics to record (shell patterns on the full name, e.g. /tf*)', read_only=True))
    node.declare_parameter('record_cameras', False, d(
        'record camera images too (they are large)', read_only=True))
    node.declare_parameter('record_split_mb', 0.0, d(
        'start a new bag after this many MiB; 0: never', fmin=0, fmax=1e7, read_only=True))
    node.declare_parameter('record_split_s', 0.0, d(
        'start a new bag after this many simulated seconds; 0: never', fmin=0, fmax=1e9,
        read_only=True))
    node.declare_parameter('record_max_mb', 0.0, d(
        'end the recording after this many MiB in all; 0: no cap', fmin=0, fmax=1e9,
        read_only=True))
    node.declare_parameter('viewer', False, d(
        "open MuJoCo's viewer window on the live world (needs a display; closing it leaves the "
        'node running)', read_only=True))
    node.declare_parameter('viewer_ui', True, d(
        "show the viewer's side panels (off: the scene fills the window)", read_only=True))
    node.declare_parameter('view_camera', '', d(
        "the viewer window and the browser view look through this camera of the world ('': "
        "MuJoCo's free camera; the browser's from above, at an angle)", read_only=True))
    node.declare_parameter('web_view', 0, d(
        'serve the live world to a browser on this port (http://localhost:<port>); 0: off',
        read_only=True, imin=0, imax=65535))
    node.declare_parameter('web_view_host', '127.0.0.1', d(
        'the address the browser view listens on; anything but loopback lets other machines '
        'see the world (a warning says so)', read_only=True))
    node.declare_parameter('cmd_vel_timeout', 0.5, d(
        'simulated seconds without a cmd_vel after which a base stops, as diff_drive_controller '
        "does; 0: never (Gazebo's DiffDrive system)", fmin=0, fmax=1e6))
    node.declare_parameter('odom_rate_hz', 50.0, d(
        '<entity>/odom messages (and the odom TF) per wall second', fmin=0.1, fmax=1000,
        read_only=True))
    node.declare_parameter('odom_source', 'wheels', d(
        "where a base's odometry comes from: 'wheels' (integrated from its wheel joints; drifts "
        "with slip, as a real robot's) or 'ground_truth' (the simulation's)"))
    node.declare_parameter('odom_tf', True, d(
        'publish world -> <entity>/odom -> <entity> on /tf for every mobile base (off: for a '
        'robot localised by other means)', read_only=True))
    node.declare_parameter('odom_pose_covariance', [0.0] * 6, d(
        "the diagonal (x, y, z, roll, pitch, yaw) of odometry's pose covariance"))
    node.declare_parameter('odom_twist_covariance', [0.0] * 6, d(
        "the diagonal of odometry's twist covariance"))
    node.declare_parameter('trajectory_allow_nonzero_velocity_at_end', False, d(
        'accept FollowJointTrajectory goals whose last point has a velocity (refused by '
        "default, as joint_trajectory_controller's allow_nonzero_velocity_at_trajectory_end)"))
    node.declare_parameter('trajectory_feedback_hz', 20.0, d(
        'FollowJointTrajectory feedback and controller_state messages per wall second while '
        'a goal runs', fmin=0.1, fmax=1000))
    node.declare_parameter('simulate_steps_feedback_every', 1, d(
        'the simulate_steps action sends feedback after every this many steps (and the last); '
        '1, as the standard says: after each step', imin=1, imax=2 ** 62))
    node.declare_parameter('mesh_cache_mb', c.mesh_cache_mb, d(
        "MuJoCo's cache of processed meshes (MiB): a second spawn of a robot, and edits of a "
        'world holding robots, reuse their meshes from it; 0 turns it off', read_only=True,
        imin=0, imax=1_000_000))
    node.declare_parameter('allow_second_simulator', False, d(
        'start even when another simulator serves the same services in this namespace (they '
        'would answer calls at random)', read_only=True))
    node.declare_parameter('max_steps_per_request', 1_000_000, d(
        'most steps one step_simulation request may ask for (about 15-50 s of the default '
        'scene free-running); larger ones are refused: use the simulate_steps action',
        imin=1, imax=2 ** 62))
    node.declare_parameter('robot_description_mesh_dir', '', d(
        'where robot descriptions write mesh geometry (STL files named by content, read by RViz '
        "through file:// URIs); '' = $XDG_CACHE_HOME/sim/meshes (~/.cache/sim/meshes)",
        read_only=True))
    _declare_perception(node)
    unknown = sorted(n for n in overrides if not node.has_parameter(n))
    if unknown:  # rclpy drops them silently: a typo would go unnoticed
        names = list(node.get_parameters_by_prefix(''))  # every declared name
        node.get_logger().warning('; '.join(
            f'unknown parameter {n!r} ignored{closest_hint(n, names)}' for n in unknown))


def _with_article(word: str) -> str:
    return f"{'an' if word[:1] in 'aeiou' else 'a'} {word}"


def parameter_error(exc: Exception) -> str:
    """Say in one line which parameter a start-up value was refused for, and what it takes."""
    text = str(exc)
    m = re.match(r"Trying to set parameter '(?P<name>[^']*)' to '(?P<value>.*)' of type "
                 r"'(?P<got>\w+)', expecting type '(?:Type\.)?(?P<want>\w+)'", text, re.S)
    if m:
        got, want = (_with_article(m[k].lower().replace('_', ' ')) for k in ('got', 'want'))
        return f"parameter {m['name']}: {m['value']!r} is {got}, but it takes {want}"
    m = re.match(r'.*Reason: (?P<reason>.*): (?P<name>[^:]+)$', text, re.S)
    if m:
        r = re.match(r'.*out of range Min: (?P<lo>\S+), Max: (?P<hi>\S+), value: (?P<v>.+)$',
                     m['reason'], re.S)
        if r:
            return (f"parameter {m['name']}: {r['v']} is out of its range, "
                    f"{r['lo']} to {r['hi']}")
        return f"parameter {m['name']}: {' '.join(m['reason'].split())}"
    return ' '.join(text.split())


def _declare_perception(node: Node) -> None:
    c = PerceptionConfig()
    d = _descriptor
    ro = {'read_only': True}
    node.declare_parameter('cameras', list(c.cameras), d(
        "cameras to publish (shell-style name patterns; one that matches nothing, e.g. 'none', "
        'turns cameras off)', **ro))
    node.declare_parameter('camera_width', c.camera_width, d(
        'camera image width (pixels)', imin=1, imax=4096, **ro))
    node.declare_parameter('camera_height', c.camera_height, d(
        'camera image height (pixels)', imin=1, imax=4096, **ro))
    node.declare_parameter('camera_rate_hz', c.camera_rate_hz, d(
        'camera images per simulated second', fmin=0.01, fmax=1000, **ro))
    node.declare_parameter('camera_depth', c.camera_depth, d(
        'also publish depth images (32FC1, metres)', **ro))
    node.declare_parameter('camera_points', c.camera_points, d(
        'also publish points (PointCloud2, x y z rgb) from each depth image', **ro))
    node.declare_parameter('camera_shadow_size', c.camera_shadow_size, d(
        'shadow map side in texels (0: no shadows; larger is sharper and slower)',
        imin=0, imax=16384, **ro))
    node.declare_parameter('lidar_sites', list(c.lidar_sites), d(
        'sites that carry a planar laser scanner (shell-style name patterns)', **ro))
    node.declare_parameter('lidar_rate_hz', c.lidar_rate_hz, d(
        'laser scans per simulated second', fmin=0.01, fmax=1000, **ro))
    node.declare_parameter('lidar_angle_min', c.lidar_angle_min, d(
        'first ray of a scan, about the site z axis from its x axis (rad)',
        fmin=-6.3, fmax=6.3, **ro))
    node.declare_parameter('lidar_angle_max', c.lidar_angle_max, d(
        'last ray of a scan (rad)', fmin=-6.3, fmax=6.3, **ro))
    node.declare_parameter('lidar_samples', c.lidar_samples, d(
        'rays per scan', imin=1, imax=100_000, **ro))
    node.declare_parameter('lidar_range_min', c.lidar_range_min, d(
        'closer hits read -inf (m)', fmin=0, fmax=1e4, **ro))
    node.declare_parameter('lidar_range_max', c.lidar_range_max, d(
        'farther read +inf (m)', fmin=1e-3, fmax=1e4, **ro))


def perception_config(node: Node) -> PerceptionConfig:
    """Return the cameras and sensors configuration of the node's parameters."""
    names = [f.name for f in dataclasses.fields(PerceptionConfig)]
    values = {n: node.get_parameter(n).value for n in names}
    values['cameras'] = tuple(values['cameras'])
    values['lidar_sites'] = tuple(values['lidar_sites'])
    return PerceptionConfig(**values)


def world_config(node: Node) -> WorldConfig:
    """Return the configuration the node's current parameters describe."""
    def p(name: str):
        return node.get_parameter(name).value
    return WorldConfig(
        real_time_factor=p('real_time_factor'), paused=p('paused'), timestep=p('timestep'),
        max_steps=p('max_steps'), max_sim_time=p('max_sim_time'),
        # Twice the fastest publisher, so that every publishing tick finds a new snapshot.
        snapshot_rate_hz=2 * max(p('tf_rate_hz'), p('joint_states_rate_hz')),
        kp=p('kp'), kd=p('kd'), allow_interpenetration=p('allow_interpenetration'),
        max_bodies=p('max_bodies'), world_extent=p('world_extent'),
        divergence_policy=p('divergence_policy'), mesh_cache_mb=p('mesh_cache_mb'))
