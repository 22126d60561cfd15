"""
Every ROS parameter of the node, as one table: the declarations and docs/parameters.md.

:data:`PARAMETERS` lists each parameter once, in the order the node declares them: name,
default (from :class:`~sim_node.core.config.WorldConfig` and
:class:`~sim_node.core.config.PerceptionConfig` where they hold it), description, limits and
whether a change needs a restart. :mod:`.params` declares them from it with descriptors
(``ros2 param describe``); ``python -m sim_node.ros.parameter_table`` prints the reference table
that docs/parameters.md holds between its ``<!-- parameters -->`` markers, and a test checks
that the two agree. No rclpy here: the table is data.
"""

from dataclasses import dataclass
import math
from typing import Optional

from ...core.base.config import PerceptionConfig, WorldConfig

#: The default of a string-array parameter declared without a value (``resource_paths``).
STRING_ARRAY = 'string array'


@dataclass(frozen=True)
class Spec:
    """One parameter: its default's type is the parameter's type."""

    name: str
    default: object
    description: str
    read_only: bool = False
    #: (lowest, highest) accepted: floats for a double, integers for an integer.
    limits: Optional[tuple] = None


_W, _P = WorldConfig(), PerceptionConfig()
RO = {'read_only': True}

PARAMETERS = (
    Spec('scene', 'default', 'MJCF/URDF scene: a file path or an installed scene name '
         '(default, empty, friction_restitution, push_stack, mobile, ...)', **RO),
    Spec('real_time_factor', _W.real_time_factor,
         'simulated seconds per wall second; 0 = as fast as possible', limits=(0.0, 1000.0)),
    Spec('paused', _W.paused, 'pause (true) or play (false); also follows pauses made by the '
         'set_simulation_state service, a step or time limit, or divergence'),
    Spec('timestep', _W.timestep, "physics step in seconds; 0 keeps the scene's own",
         limits=(0.0, 0.1)),
    Spec('max_steps', _W.max_steps, 'pause after this many steps since the last time reset; '
         '0 = unbounded', limits=(0, 2 ** 62)),
    Spec('max_sim_time', _W.max_sim_time, 'pause after the first step at or past this '
         'simulated time (s); 0 = unbounded', limits=(0.0, 1e9)),
    Spec('tf_rate_hz', 100.0, 'rate of /clock and /tf (wall Hz)', limits=(1.0, 1000.0), **RO),
    Spec('joint_states_rate_hz', 50.0, 'rate of joint_states and sensor messages (wall Hz)',
         limits=(1.0, 1000.0), **RO),
    Spec('world_frame', 'world', 'TF frame of the MuJoCo world body', **RO),
    Spec('frame_prefix', '', 'prepended to every frame id the node publishes (/tf, /tf_static, '
         "markers, entity states; e.g. robot2/), like robot_state_publisher's, for several "
         'worlds in one domain', **RO),
    Spec('publish_clock', True, 'publish /clock (one world per domain should)', **RO),
    Spec('resource_paths', STRING_ARRAY, 'directories that spawn and load_world may read files '
         'from, besides the installed scenes and objects (see builtin_resources)', **RO),
    Spec('builtin_resources', True, 'whether the installed scenes and objects ({scenes_dir}) '
         'stay readable besides resource_paths', **RO),
    Spec('kp', _W.kp, 'PD stiffness for position commands on joints without a position '
         'actuator, per unit of joint inertia: torque = M0 (kp error + kd velocity error) + '
         'gravity; kp = w^2, kd = 2 w', limits=(0.0, 1e6)),
    Spec('kd', _W.kd, 'PD damping for position/velocity commands without a matching actuator',
         limits=(0.0, 1e6)),
    Spec('allow_interpenetration', _W.allow_interpenetration,
         'allow spawning into overlapping geometry', **RO),
    Spec('divergence_policy', _W.divergence_policy, 'when the physics diverges while playing '
         '(the state before the bad step is restored first, and the culprit entity named): '
         "'pause', 'remove' the entity it happened in (if spawned, else pause) and play on, or "
         "'reset' the state and play on", **RO),
    Spec('world_extent', _W.world_extent, 'entities may be placed only within this many metres '
         'of the world origin on each axis: a pose outside is invalid (spawn 109, '
         'set_entity_state 101)', limits=(1.0, 1e7), **RO),
    Spec('max_bodies', _W.max_bodies, 'most bodies the world may hold; a spawn past it is '
         'refused (RESULT_OPERATION_FAILED, naming the limit)', limits=(2, 100_000), **RO),
    Spec('trajectory_path_tolerance', 0.25, 'default position tolerance (rad or m) along a '
         "FollowJointTrajectory goal, every joint; 0: not checked; a goal's path_tolerance "
         'overrides it', limits=(0.0, 1e3)),
    Spec('trajectory_goal_tolerance', 0.05, 'default position tolerance at the end of a '
         "FollowJointTrajectory goal; 0: not checked (the goal succeeds at its last point's "
         'time)', limits=(0.0, 1e3)),
    Spec('trajectory_goal_time_tolerance', 1.0, 'default time (s) after the end within which '
         'the goal tolerance must be met; 0: no limit', limits=(0.0, 1e6)),
    Spec('cmd_vel_stamped', False, '<entity>/cmd_vel takes geometry_msgs/TwistStamped '
         "(diff_drive_controller, later nav2) instead of Twist (nav2 Jazzy's default)", **RO),
    Spec('record', '', 'a folder to record the run into: it becomes a rosbag2 bag (MCAP), as '
         'ros2 bag record -o makes it, that ros2 bag play and Foxglove open (one that exists '
         "and is not empty is refused, never overwritten); '' records nothing", **RO),
    Spec('record_topics', ['*'], 'topics to record (shell patterns on the full name, e.g. '
         '/tf*)', **RO),
    Spec('record_cameras', False, 'record camera images too (they are large)', **RO),
    Spec('record_split_mb', 0.0, 'start a new file of the bag after this many MiB; 0: never',
         limits=(0.0, 1e7), **RO),
    Spec('record_split_s', 0.0, 'start a new file of the bag after this many simulated '
         'seconds; 0: never',
         limits=(0.0, 1e9), **RO),
    Spec('record_max_mb', 0.0, 'end the recording after this many MiB in all; 0: no cap',
         limits=(0.0, 1e9), **RO),
    Spec('viewer', False, "open MuJoCo's viewer window on the live world (needs a display: "
         'without one the node exits 2 with one line saying how to get one, xvfb-run -a; '
         'closing it leaves the node running)', **RO),
    Spec('viewer_ui', True, "show the viewer's side panels (off: the scene fills the window)",
         **RO),
    Spec('view_camera', '', 'the viewer window and the browser view look through this camera '
         "of the world ('': MuJoCo's free camera; the browser's from above, at an angle)",
         **RO),
    Spec('web_view', 0, 'serve the live world to a browser on this port '
         "(http://localhost:<port>, viser's bundled page, no network needed); 0: off; a port "
         'already taken moves to the next free one, with a warning', limits=(0, 65535), **RO),
    Spec('web_view_host', '127.0.0.1', 'the address the browser view listens on; anything but '
         'loopback lets other machines see the world (a warning says so)', **RO),
    Spec('cmd_vel_timeout', 0.5, 'simulated seconds without a cmd_vel after which a base '
         "stops, as diff_drive_controller does; 0: never (Gazebo's DiffDrive system)",
         limits=(0.0, 1e6)),
    Spec('casters_roll', _W.casters_roll, "a spawned wheeled base's fixed casters (a body "
         'without a joint, not a wheel, whose collision reaches the floor the wheels stand on, '
         'within a quarter of their radius; whatever its name: a mast never is one) get '
         'frictionless contacts and roll, as Gazebo users set mu 0; false: they drag as the '
         'URDF has them', **RO),
    Spec('contact_entities', STRING_ARRAY, 'entities whose contacts are published on '
         'contacts/<entity> (ros_gz_interfaces/Contacts: what touches what, where, how hard), '
         'from spawn on; an entity not there yet is reported once it spawns'),
    Spec('contact_rate_hz', _W.contact_rate_hz, 'contact reports per simulated second, of '
         'contact_entities and of contact sensors that declare no update_rate',
         limits=(0.001, 1000.0)),
    Spec('odom_rate_hz', 50.0, '<entity>/odom messages (and the odom TF) per wall second',
         limits=(0.1, 1000.0), **RO),
    Spec('odom_source', 'wheels', "where a base's odometry comes from: 'wheels' (integrated "
         "from its wheel joints; drifts with slip, as a real robot's) or 'ground_truth' (the "
         "simulation's)"),
    Spec('odom_tf', True, 'publish world -> <entity>/odom -> <entity> on /tf for every mobile '
         'base (off: for a robot localised by other means)', **RO),
    Spec('odom_pose_covariance', [0.0] * 6, 'the diagonal (x, y, z, roll, pitch, yaw) of '
         "odometry's pose covariance"),
    Spec('odom_twist_covariance', [0.0] * 6, "the diagonal of odometry's twist covariance"),
    Spec('trajectory_allow_nonzero_velocity_at_end', False, 'accept FollowJointTrajectory '
         'goals whose last point has a velocity (refused by default, as '
         "joint_trajectory_controller's allow_nonzero_velocity_at_trajectory_end)"),
    Spec('trajectory_feedback_hz', 20.0, 'FollowJointTrajectory feedback and controller_state '
         'messages per wall second while a goal runs', limits=(0.1, 1000.0)),
    Spec('simulate_steps_feedback_every', 1, 'the simulate_steps action sends feedback after '
         'every this many steps (and the last); 1, as the standard says: after each step',
         limits=(1, 2 ** 62)),
    Spec('mesh_cache_mb', _W.mesh_cache_mb, "MuJoCo's process-wide cache of processed meshes "
         "(MiB; MuJoCo's default is 512): a second spawn of a robot, and edits of a world "
         "holding robots, reuse their meshes from it (GR1's take 158 MiB; a full cache stops "
         "keeping new meshes; memory is taken only as meshes load; a deleted robot's "
         'meshes leave it once mesh_cache_keep_sec is over, unless a robot spawned from the '
         'same description stays); 0 turns it off; its size is on /diagnostics',
         limits=(0, 1_000_000), **RO),
    Spec('mesh_cache_keep_sec', _W.mesh_cache_keep_sec, "how long a deleted robot's processed "
         'meshes stay in that cache (wall seconds): the same robot spawned again meanwhile is '
         'quick (g1: 0.12 s instead of 0.73 s); then they are evicted and the memory given '
         'back; 0: at once', limits=(0.0, 86400.0), **RO),
    Spec('mesh_cache_keep_mb', _W.mesh_cache_keep_mb, "the most deleted robots' meshes kept "
         'in that cache may hold (MiB; the oldest go first); kept MiB are on /diagnostics',
         limits=(0, 1_000_000), **RO),
    Spec('mesh_decomposition', _W.mesh_decomposition, 'which concave collision meshes collide '
         'as convex parts that follow them, as Gazebo collides meshes (MuJoCo collides a mesh as '
         'its hull: a tray would be a solid block): objects (meshes spawned by URI, MJCF meshes '
         'named in <custom><text name="decompose_meshes">, URDF models without joints), all '
         "(robots' links too) or none (every mesh its hull; not 'off', which ROS reads as "
         'false); decomposed once (CoACD, in a child process, at most 30 s a mesh) and cached '
         'beside the converted meshes', **RO),
    Spec('mesh_decomposition_threshold', _W.mesh_decomposition_threshold, "CoACD's concavity "
         "threshold, a fraction of a mesh's size: lower follows a concave mesh closer, with more "
         'parts (a tray: 0.05 gives 9-14, 0.1 gives 5)', limits=(0.001, 1.0), **RO),
    Spec('allow_second_simulator', False, 'start even when another simulator serves the same '
         'services in this namespace (they would answer calls at random; by default the newer '
         'of two exits with status 2, saying why)', **RO),
    Spec('max_steps_per_request', 1_000_000, 'most steps one step_simulation request may ask '
         'for (about 15-50 s of the default scene free-running); larger ones are refused: use '
         'the simulate_steps action', limits=(1, 2 ** 62)),
    Spec('robot_description_mesh_dir', '', 'where robot descriptions write mesh geometry (STL '
         "files named by content, read by RViz through file:// URIs); '' = "
         '$XDG_CACHE_HOME/sim/meshes (~/.cache/sim/meshes)', **RO),
    Spec('cameras', list(_P.cameras), 'cameras to publish (shell-style name patterns, e.g. '
         "['overview', 'arm/*']; one that matches nothing, e.g. 'none', turns cameras off)",
         **RO),
    Spec('camera_width', _P.camera_width, 'camera image width (pixels)', limits=(1, 4096),
         **RO),
    Spec('camera_height', _P.camera_height, 'camera image height (pixels)', limits=(1, 4096),
         **RO),
    Spec('camera_rate_hz', _P.camera_rate_hz, 'camera images per simulated second (fewer if '
         'the renderer cannot keep up: the physics never waits)', limits=(0.01, 1000.0), **RO),
    Spec('camera_depth', _P.camera_depth, 'also publish depth images (32FC1, metres)', **RO),
    Spec('camera_points', _P.camera_points, 'also publish cameras/<camera>/points '
         '(PointCloud2, organized, x y z rgb in the optical frame, NaN where nothing is hit) '
         'from each depth image', **RO),
    Spec('camera_shadow_size', _P.camera_shadow_size, 'shadow map side in texels (0: no '
         'shadows; larger is sharper and slower)', limits=(0, 16384), **RO),
    Spec('lidar_sites', list(_P.lidar_sites), 'sites that carry a planar laser scanner '
         '(shell-style name patterns)', **RO),
    Spec('lidar_rate_hz', _P.lidar_rate_hz, 'laser scans per simulated second',
         limits=(0.01, 1000.0), **RO),
    Spec('lidar_angle_min', _P.lidar_angle_min, 'first ray of a scan, about the site z axis '
         'from its x axis (rad)', limits=(-6.3, 6.3), **RO),
    Spec('lidar_angle_max', _P.lidar_angle_max, 'last ray of a scan (rad)', limits=(-6.3, 6.3),
         **RO),
    Spec('lidar_samples', _P.lidar_samples, 'rays per scan, from angle_min to angle_max '
         'inclusive', limits=(1, 100_000), **RO),
    Spec('lidar_range_min', _P.lidar_range_min, 'closer hits read -inf (m)', limits=(0.0, 1e4),
         **RO),
    Spec('lidar_range_max', _P.lidar_range_max, 'farther read +inf (m)', limits=(1e-3, 1e4),
         **RO),
)

#: Parameters of type double: an integer given for one (``real_time_factor:=0``, ``ros2 param
#: set /sim real_time_factor 1``) is taken as that number, as users type them.
DOUBLES = tuple(p.name for p in PARAMETERS if isinstance(p.default, float))


def _bound(value) -> str:
    if isinstance(value, int) and value >= 2 ** 31:
        return f'2^{value.bit_length() - 1}' if value & (value - 1) == 0 else f'{value:,}'
    return f'{value:g}' if isinstance(value, float) else f'{value:,}'


def _cell(value: object) -> str:
    if value is STRING_ARRAY:
        return '`[]`'
    if isinstance(value, bool):
        return f'`{str(value).lower()}`'
    if isinstance(value, float) and abs(value) == math.pi:
        return '`-π`' if value < 0 else '`π`'
    if isinstance(value, str):
        return f"`'{value}'`"
    return f'`{value}`'


def markdown(scenes_dir: str = '<share>/sim/scenes') -> str:
    """Return the reference table of every parameter (what docs/parameters.md holds)."""
    rows = ['| parameter | default | range | changes | |', '|---|---|---|---|---|']
    for p in PARAMETERS:
        span = '' if p.limits is None else f'{_bound(p.limits[0])} to {_bound(p.limits[1])}'
        when = 'at start-up' if p.read_only else 'at run time'
        text = p.description.format(scenes_dir=scenes_dir).replace('|', '\\|')
        rows.append(f'| `{p.name}` | {_cell(p.default)} | {span} | {when} | {text} |')
    return '\n'.join(rows) + '\n'


if __name__ == '__main__':
    print(markdown(), end='')
