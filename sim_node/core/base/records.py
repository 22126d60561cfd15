"""Immutable values the world hands out: entity records, model info, snapshots, states."""

from dataclasses import dataclass, field
from typing import NamedTuple, Optional

import numpy as np

ROBOT = 'robot'
DYNAMIC = 'dynamic'
STATIC = 'static'

# Joint command modes.
POSITION = 'position'
VELOCITY = 'velocity'
EFFORT = 'effort'
MODES = (POSITION, VELOCITY, EFFORT)

# Reset scopes (bit flags, as in simulation_interfaces/ResetSimulation).
RESET_TIME = 1
RESET_STATE = 2
RESET_SPAWNED = 4
RESET_ALL = 255


class Clock(NamedTuple):
    """Where a world is in time, read at once (:meth:`~.world.World.clock`)."""

    time: float  # simulated seconds
    step_count: int  # steps since the last time reset
    timestep: float  # seconds per step
    resets: int = 0  # resets of state since the world was built (samples carry theirs)


@dataclass(frozen=True)
class EntityRecord:
    """
    An entity: one body attached directly to the world body, with its subtree.

    Ids index the model of the generation the record came from.
    """

    name: str
    category: str
    root_body: int
    body_ids: tuple
    geom_ids: tuple
    spawned: bool
    description: str = ''
    has_free_joint: bool = False
    #: The ROS namespace it was spawned with ('' for none): its interfaces (robot_description,
    #: follow_joint_trajectory, controller_state) go there instead of under its name.
    namespace: str = ''


@dataclass(frozen=True)
class GeomVisual:
    """What a marker needs to draw one geom, in its body's frame."""

    name: str
    body: int
    type: str  # noqa: A003  'box', 'sphere', 'cylinder', 'capsule', 'ellipsoid', 'plane', 'mesh'
    size: tuple  # MuJoCo geom_size (3,)
    pos: tuple  # (3,) in the body frame
    quat_wxyz: tuple  # (4,) in the body frame
    rgba: tuple
    mesh_vertices: Optional[np.ndarray] = None  # (nvert, 3)
    mesh_faces: Optional[np.ndarray] = None  # (nface, 3)


@dataclass(frozen=True)
class CameraSpec:
    """
    A camera of the model (MuJoCo's convention: looks down its -z axis, y up).

    :param name: its MuJoCo name (a spawned entity's carry ``<entity>/``); unnamed cameras are
        called ``camera<id>``.
    :param pos: (3,) in its body's frame; likewise `quat_wxyz` (4,).
    :param fixed: it keeps that pose in its body (MuJoCo's ``mode="fixed"``); tracking cameras
        move relative to their body.
    """

    name: str
    cam_id: int
    body: int
    pos: tuple
    quat_wxyz: tuple
    fovy_deg: float
    fixed: bool
    orthographic: bool = False


@dataclass(frozen=True)
class SiteSpec:
    """A site that carries a sensor or a laser scanner: a frame fixed in its body."""

    name: str
    site_id: int
    body: int
    pos: tuple  # (3,) in the body frame
    quat_wxyz: tuple  # (4,)


@dataclass(frozen=True)
class SensorSpec:
    """
    One group of MuJoCo sensors published as one message.

    :param kind: 'imu' (framequat, gyro, accelerometer on one site), 'wrench' (force and
        torque on one site), 'range' (a rangefinder), or 'generic' (any other sensor).
    :param adr: name -> (start, size) in ``sensordata``; for 'imu' the names are 'quat',
        'gyro', 'accelerometer' (any may be missing), for 'wrench' 'force' and 'torque', for
        'range' and 'generic' 'value'.
    :param site: the site the values are measured in (None for generic sensors).
    :param cutoff: a rangefinder's largest distance (0: none).
    :param type_name: MuJoCo's sensor type, e.g. 'touch'.
    """

    kind: str
    name: str
    adr: dict
    site: Optional[SiteSpec] = None
    cutoff: float = 0.0
    type_name: str = ''


@dataclass(frozen=True)
class DeclaredLaser:
    """
    A laser scanner as a robot file declares it (a Gazebo ray or lidar sensor), on its site.

    Every value is the tag's, checked (:mod:`.models.sensor_tags`); None where the tag gives
    none: the node's own setting applies.

    :param site: the site it scans from, ``<entity>/<sensor>_lidar``.
    :param rate_hz: scans per simulated second.
    :param samples, angle_min, angle_max: the horizontal sweep (rad, about the site's z).
    :param vertical: (samples, min angle, max angle) of the vertical sweep; samples > 1 makes it
        a 3D lidar, published as PointCloud2.
    :param range_min, range_max: metres.
    :param noise: (mean, standard deviation) of Gaussian noise on each range, metres.
    :param always_on: False: it scans only while someone subscribes (Gazebo's).
    :param frame: the frame id its messages carry (``<entity>/<link or frame name>``).
    :param topic: its topic as declared, already under the entity's namespace ('' : none).
    :param points: publish PointCloud2 (``output_type`` says so, or a vertical sweep).
    :param own_frame: `frame` is its own, at its site (an SDF sensor's scoped name, see
        :attr:`ModelInfo.sensor_frames`), not a link's.
    """

    site: str
    rate_hz: Optional[float] = None
    samples: Optional[int] = None
    angle_min: Optional[float] = None
    angle_max: Optional[float] = None
    vertical: Optional[tuple] = None
    range_min: Optional[float] = None
    range_max: Optional[float] = None
    noise: Optional[tuple] = None
    always_on: bool = True
    frame: str = ''
    topic: str = ''
    points: bool = False
    own_frame: bool = False


#: A declared camera's image or depth topic that says: none (:class:`DeclaredCamera`).
NO_TOPIC = '-'


@dataclass(frozen=True)
class DeclaredCamera:
    """
    A camera as a robot file declares it (a Gazebo camera, depth or RGB-D sensor).

    :param camera: its MuJoCo camera, ``<entity>/<sensor>``.
    :param width, height: pixels; `rate_hz`: images per simulated second (None: the node's).
    :param frame: the frame its images name (an optical frame link of the robot, or '': the
        node's own optical frame); `topic`: the base of its topics ('' : the node's own).
    :param encoding: its images' sensor_msgs encoding, from the tag's ``<format>``.
    :param clip: (near, far) metres: depth outside reads -inf (nearer) or +inf (farther),
        as REP 118 has it; None: the node's.
    :param depth: a depth or RGB-D camera: it publishes depth images and points too.
    :param image_topic, info_topic, depth_topic, points_topic: topics a plugin names one by
        one (the RealSense plugin's, :mod:`~..models.realsense`); '' : ``<topic>/image_raw``,
        ``<topic>/camera_info``, ``<topic>/depth/image_raw``, ``<topic>/points``; an image
        topic of :data:`NO_TOPIC`: no colour or grey image (a depth stream alone); a depth
        topic of :data:`NO_TOPIC`: no depth even when the node's cameras publish depth (an
        image stream alone).
    :param depth_mm: depth images as 16UC1 millimetres, 0 outside `clip` (a RealSense's),
        not 32FC1 metres.
    :param points: None: a depth camera publishes points, another does not; else whether it
        does. `points_clip`: (near, far) metres of the points (NaN outside), None: `clip`'s.
    """

    camera: str
    width: Optional[int] = None
    height: Optional[int] = None
    rate_hz: Optional[float] = None
    always_on: bool = True
    frame: str = ''
    topic: str = ''
    encoding: str = 'rgb8'
    clip: Optional[tuple] = None
    depth: bool = False
    image_topic: str = ''
    info_topic: str = ''
    depth_topic: str = ''
    points_topic: str = ''
    depth_mm: bool = False
    points: Optional[bool] = None
    points_clip: Optional[tuple] = None


@dataclass(frozen=True)
class DeclaredImu:
    """
    An IMU as a robot file declares it, on its site ``<entity>/<sensor>_imu``.

    Sampled in the stepping loop at `rate_hz` of simulated time (:mod:`.stepping.sampling`),
    with Gaussian noise on its gyro and accelerometer: (mean (3,), standard deviation (3,)) per
    axis as the tag gives them, or None. `own_frame`: as a laser's (:class:`DeclaredLaser`).
    """

    site: str
    rate_hz: float = 100.0
    gyro_noise: Optional[tuple] = None
    accel_noise: Optional[tuple] = None
    always_on: bool = True
    frame: str = ''
    topic: str = ''
    own_frame: bool = False


#: The kinds of :class:`DeclaredGeo`.
GEO_KINDS = ('magnetometer', 'navsat')


@dataclass(frozen=True)
class DeclaredGeo:
    """
    A magnetometer or a NavSat receiver a robot file declares, on its site.

    Sampled in the stepping loop at `rate_hz` of simulated time (:mod:`.stepping.geo`).

    :param site: ``<entity>/<sensor>_<kind>``; `kind`: one of :data:`GEO_KINDS`.
    :param frame: the frame id of its messages; `own_frame`: as a laser's
        (:class:`DeclaredLaser`); `topic`: as declared ('' : the node's own).
    """

    site: str
    kind: str
    rate_hz: float = 100.0
    always_on: bool = True
    frame: str = ''
    topic: str = ''
    own_frame: bool = False


@dataclass(frozen=True)
class DeclaredWrench:
    """
    A force-torque sensor a robot file declares on a joint (SDF's ``force_torque``), on its site.

    MuJoCo's force and torque sensors on a site of the joint's child give the wrench the parent
    applies to the child, in the site's frame, about the site: ``sign`` -1 turns that into
    SDF's default ``child_to_parent``; ``frame`` 'child' and 'sensor' are the site's frame
    ('sensor' at the tag's ``<pose>``), 'parent' is turned into the parent link's frame.

    :param site: ``<entity>/<sensor>_ft``; `parent`: the parent link's body name.
    :param frame_id: the frame its messages name; `topic`: as declared ('' : none).
    """

    site: str
    sign: float = -1.0
    frame: str = 'child'
    parent: str = ''
    frame_id: str = ''
    topic: str = ''


@dataclass(frozen=True)
class DeclaredOdometer:
    """
    A link's true pose and twist as Gazebo's P3D plugin publishes them (:mod:`.models.p3d`).

    Sampled in the stepping loop (:mod:`.stepping.odometers`) on its site at the link's
    origin.

    :param site: ``<entity>/<name>_p3d``; `body`: the link's body.
    :param rate_hz: samples per simulated second (0: every step).
    :param frame: the frame id of its messages: ``world``, ``map`` (the pose in the world) or
        the `reference` link's frame (``<entity>/<link>``), its pose and twist then relative
        to that link's body `reference` ('' : the world).
    :param offset_pos, offset_quat: added to the position, turned before the orientation.
    :param noise: the standard deviation of the noise on each twist component.
    :param topic: as declared (relative names kept relative).
    """

    site: str
    body: str
    rate_hz: float = 0.0
    frame: str = 'world'
    reference: str = ''
    offset_pos: tuple = (0.0, 0.0, 0.0)
    offset_quat: tuple = (1.0, 0.0, 0.0, 0.0)
    noise: float = 0.0
    topic: str = 'odom'


@dataclass(frozen=True)
class DeclaredContact:
    """
    A contact sensor: the contacts of some collision geometry, reported at a rate.

    From a robot file's Gazebo ``<sensor type="contact">`` (on collisions of its link), a
    MuJoCo ``contact`` or ``touch`` sensor, or an entity whose contacts were asked for
    (:meth:`~sim_node.core.world.World.report_contacts`).

    :param name: the key its messages go by (``<entity>/<sensor>``, a MuJoCo sensor's name, or
        the entity's name).
    :param geoms: the geom names whose contacts it reports (reported as collision 1).
    :param others: geoms the other side must be one of (a MuJoCo ``contact`` sensor's
        ``geom2``/``body2``); () : any.
    :param rate_hz: reports per simulated second (None: the node's ``contact_rate_hz``).
    :param frame: the frame id its messages name; `topic`: as declared ('' : the node's own).
    """

    name: str
    geoms: tuple = ()
    others: tuple = ()
    rate_hz: Optional[float] = None
    always_on: bool = True
    frame: str = ''
    topic: str = ''


@dataclass(frozen=True)
class ModelInfo:
    """Names and structure of one compiled model; replaced on every recompile (generation)."""

    generation: int
    timestep: float
    body_names: tuple  # (nbody,) body 0 is the world
    body_parent: np.ndarray  # (nbody,)
    body_root: np.ndarray  # (nbody,) the entity (top-level) body each body belongs to; 0: world
    body_has_joint: np.ndarray  # (nbody,) bool: moves relative to its parent
    body_local_pos: np.ndarray  # (nbody, 3) pose in the parent frame for welded bodies
    body_local_quat_wxyz: np.ndarray  # (nbody, 4)
    #: (nbody,) for the root body of a spawned URDF, ``<entity>/<root link>``: a frame at the
    #: root (the entity's own frame) that the root's child links hang from, so every link's
    #: frame is named as robot_state_publisher names it with ``frame_prefix:=<entity>/``.
    body_alias: tuple
    #: (nbody,) for the root body of an entity with joints whose root has joints of its own
    #: (other than a free joint) or that has several top-level bodies: ``<entity>/world``, a
    #: frame at the world's origin, the root link of the entity's robot description, which
    #: the top-level bodies hang from.
    body_mount: tuple
    joint_names: tuple  # hinge and slide joints only, in model order
    geoms: tuple  # GeomVisual for every visible geom
    entities: tuple  # EntityRecord
    cameras: tuple = ()  # CameraSpec
    sensors: tuple = ()  # SensorSpec
    sites: tuple = ()  # SiteSpec of every named site
    joint_entity: tuple = ()  # for joint_names: the entity each joint belongs to
    #: The intermediate links of the robot descriptions made from the model
    #: (:class:`~.models.description.ChainFrame`, their steps' joints as indices into
    #: joint_names): frames on /tf and /tf_static as every other link.
    chains: tuple = ()
    #: Other links of descriptions that no body stands for, fixed to one that does:
    #: (parent frame, frame, position (3,), quaternion wxyz (4,)) for /tf_static (a URDF's
    #: ``world`` link, which its root is fixed to).
    link_frames: tuple = ()
    #: Site name -> :class:`DeclaredLaser` for the lasers spawned robots declare.
    lasers: dict = field(default_factory=dict)
    #: Site name -> :class:`DeclaredWrench` for their force-torque sensors.
    wrenches: dict = field(default_factory=dict)
    #: Site name -> :class:`DeclaredImu` for their IMUs.
    imus: dict = field(default_factory=dict)
    #: Camera name -> :class:`DeclaredCamera` for their cameras.
    cameras_declared: dict = field(default_factory=dict)
    #: Site name -> :class:`DeclaredOdometer` for their P3D plugins.
    odometers: dict = field(default_factory=dict)
    #: Name -> :class:`DeclaredContact` for their contact sensors and the model's MuJoCo
    #: ``contact``/``touch`` sensors.
    contacts: dict = field(default_factory=dict)
    #: (ngeom,) each geom as Gazebo scopes a collision: ``model::link::collision``.
    geom_scoped: tuple = ()
    #: (ngeom,) the body each geom is on.
    geom_body: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    #: Entity -> its URDF's ros2_control declaration (``.models.ros2_control.Ros2Control``,
    #: under its namespace) where it names simulated or topic-based hardware: the robots whose
    #: joints their own controllers publish and drive (a real robot's hardware: not here).
    ros2_control: dict = field(default_factory=dict)
    #: Entity -> (its namespace, the gz-sim systems its SDF declares:
    #: :class:`~.control.gz_systems.GzSystem`), for the entities that declare any.
    gz_systems: dict = field(default_factory=dict)
    #: Site name -> :class:`DeclaredGeo` for their magnetometers and NavSat receivers.
    geo: dict = field(default_factory=dict)
    #: (site name, frame) of declared sensors whose frame is their own (an SDF sensor's scoped
    #: name ``<entity>/<link>/<sensor>``, as ros_gz_bridge names it): each on /tf_static at its
    #: site, so its messages' frame is where it is.
    sensor_frames: tuple = ()
    #: Where the world's origin is on the Earth (latitude deg, longitude deg, elevation m,
    #: heading deg: an SDF world's ``<spherical_coordinates>``), or None: not said.
    spherical: Optional[tuple] = None


#: The custom numeric a model keeps its world's :attr:`ModelInfo.spherical` in (it goes with
#: the model through every edit).
ORIGIN_NUMERIC = 'sim:spherical_coordinates'


@dataclass(frozen=True)
class Snapshot:
    """
    A copy of the world made by the loop between steps: safe to read from any thread.

    :param joint_position: (njoint,) for ModelInfo.joint_names; likewise velocity and effort.
    :param body_xpos: (nbody, 3) world positions.
    :param body_xquat_wxyz: (nbody, 4) world orientations.
    :param seq: rises with every snapshot the world makes, so a consumer can drop one older
        than what it already has (several threads take snapshots).
    """

    generation: int
    step: int
    time: float
    joint_position: np.ndarray
    joint_velocity: np.ndarray
    joint_effort: np.ndarray
    body_xpos: np.ndarray
    body_xquat_wxyz: np.ndarray
    seq: int = 0
    info: Optional['ModelInfo'] = None  # names and structure of `generation`
    sensordata: Optional[np.ndarray] = None  # (nsensordata,) MuJoCo's sensor values


@dataclass(frozen=True)
class EntityState:
    """
    Pose, twist and acceleration of an entity's root body, in the world or a reference frame.

    Twist: linear velocity of the body origin and angular velocity, both in the world frame.
    Acceleration: the same point's linear acceleration (coordinate acceleration: -9.81 m/s^2
    in free fall, 0 at rest) and the angular acceleration.
    """

    position: np.ndarray  # (3,)
    quat_wxyz: np.ndarray  # (4,)
    linear_velocity: np.ndarray  # (3,)
    angular_velocity: np.ndarray  # (3,)
    time: float = 0.0
    linear_acceleration: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_acceleration: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass(frozen=True)
class PhysicsState:
    """
    The full integration state of one model generation, as ``mj_getState`` gives it.

    (time, qpos, qvel, act, ctrl, mocap, warm start, applied forces: mjSTATE_INTEGRATION.)
    """

    generation: int
    step: int
    values: np.ndarray


@dataclass(frozen=True)
class LoopStatus:
    """
    How the stepping loop is stepping: where it is, how fast, whether it is told to hold.

    The loop keeps no lifecycle of its own: whether the simulation is playing, paused, stopped
    or failed, and why, is the :class:`~sim_node.session.Session`'s (its ``StateEvent``).
    """

    step: int
    time: float
    real_time_factor: float
    #: The loop is holding (told to, or by itself after what it reported): no step is due.
    held: bool = False
    #: Simulated seconds per wall second over the last measuring window while stepping.
    achieved_real_time_factor: float = 0.0
    #: Set while stepping slower than the requested factor: by how much, and why.
    lag: str = ''


class Report(NamedTuple):
    """
    What a stepping loop did by itself, for its owner to decide on (``SimLoop.take_reports``).

    ``kind`` is ``'limit'`` (a termination constraint made it hold), ``'diverged'`` (the
    physics diverged and it holds), ``'diverged_on'`` (the physics diverged, its policy removed
    the culprit or reset the state, and it steps on) or ``'failed'`` (an internal error made it
    hold); ``reason`` says why in a sentence; ``divergence`` is the divergence's report (the
    step, time, entity, body, warnings and the policy's ``action``) or None.
    """

    kind: str
    reason: str
    divergence: Optional[dict] = None
