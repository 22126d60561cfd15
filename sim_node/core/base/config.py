"""The one source of truth for world and loop configuration."""

from dataclasses import dataclass


@dataclass(frozen=True)
class WorldConfig:
    """
    Configuration of a :class:`~sim_node.core.world.World` and its stepping loop.

    The node declares its ROS parameters from these fields (``sim_node.ros.node.params``).
    """

    #: Wall-clock pacing: 1.0 is real time, 2.0 twice as fast, 0 as fast as possible.
    real_time_factor: float = 1.0
    #: Start paused.
    paused: bool = False
    #: Physics step in seconds; 0 keeps the scene's own.
    timestep: float = 0.0
    #: Stop the loop after this many steps since the last time reset; 0 is unbounded.
    max_steps: int = 0
    #: Stop the loop at this simulated time in seconds; 0 is unbounded.
    max_sim_time: float = 0.0
    #: How often the loop hands an immutable snapshot to consumers (wall-clock Hz).
    snapshot_rate_hz: float = 100.0
    #: PD gains for joints commanded without a matching actuator, per unit of the joint's
    #: inertia (torque = M0 * (kp * error + kd * velocity error) + gravity/Coriolis), so
    #: kp = w^2 and kd = 2 w for a critically damped joint of natural frequency w (rad/s).
    kp: float = 400.0
    kd: float = 40.0
    #: Refuse spawns whose geometry would overlap existing geometry deeper than this (m).
    interpenetration_tolerance: float = 1e-3
    #: Allow spawning into overlapping geometry (off by default: deep overlap explodes).
    allow_interpenetration: bool = False
    #: A spawned wheeled base's fixed casters (ball, omni wheel, swivel fixed in its URDF) roll:
    #: frictionless contacts, as Gazebo users set them (``.control.wheels.roll_casters``).
    casters_roll: bool = True
    #: Entities whose contacts are reported (:func:`.stepping.sampling.request`), and how
    #: often (simulated Hz; also the rate of contact sensors that declare none).
    contact_entities: tuple = ()
    contact_rate_hz: float = 50.0
    #: Largest model file (MJCF or URDF text) or other file a spawn may read, in bytes.
    max_resource_bytes: int = 20_000_000
    #: Largest mesh file, in bytes: the largest mesh of 69 URDFs of ROS description packages is
    #: a 28.8 MB Collada file (Unitree Go1's trunk).
    max_mesh_bytes: int = 64_000_000
    #: Most bytes one model's files may add up to: the most of those 69 URDFs read 64 MB.
    max_model_bytes: int = 256_000_000
    #: Largest mesh, in faces, a spawn may load.
    max_mesh_faces: int = 200_000
    #: MuJoCo's cache of processed meshes, in MiB (process-wide; MuJoCo's default is 512). A
    #: second spawn of a robot, and every edit of a world holding robots, reuses their meshes
    #: from it: GR1's alone take 158 MiB, and a full cache stops keeping new meshes (measured).
    #: Memory is taken only as meshes are loaded. 0 turns the cache off.
    mesh_cache_mb: int = 2048
    #: How long a removed entity's meshes stay in that cache (wall seconds), so that the same
    #: robot spawned again finds them processed (g1: 0.12 s instead of 0.73 s), and the most
    #: they may hold meanwhile (MiB; the oldest go first). Then they are evicted and the
    #: memory is given back. 0 s: evicted at once, as soon as the robot is deleted.
    mesh_cache_keep_sec: float = 120.0
    mesh_cache_keep_mb: int = 512
    #: Which concave collision meshes are split into convex parts (process-wide; see
    #: :mod:`sim_node.core.models.decompose`): ``objects`` (meshes spawned by URI, MJCF meshes
    #: a model marks, URDF models without joints), ``all`` (robots' links too), ``none``.
    mesh_decomposition: str = 'objects'
    #: CoACD's concavity threshold (a fraction of a shell's size): lower follows a concave
    #: mesh closer, with more parts.
    mesh_decomposition_threshold: float = 0.05
    #: Most bodies the world may hold (scene and spawned, world body included): a spawn past it
    #: is refused with a clear error. MuJoCo itself failed at about 5,000 ("Could not allocate
    #: memory"), and every body costs stepping time.
    max_bodies: int = 3000
    #: Half the side of the cube, centred on the world origin, that entities may be placed in
    #: (m): a pose outside it is an invalid pose (spawn 109, set_entity_state 101). A double
    #: still resolves 2 nm at 10 km; far out, contacts and integration lose their precision.
    world_extent: float = 10_000.0
    #: What the loop does when the physics diverges while playing (the state before the bad
    #: step is always restored first): 'pause'; 'remove' the entity it happened in (if it was
    #: spawned, else pause) and play on; or 'reset' the state to the home keyframe and play on.
    divergence_policy: str = 'pause'
    #: Wall seconds behind schedule after which pacing re-syncs instead of bursting.
    resync_after_sec: float = 0.25
    #: MuJoCo's arena (contacts and constraints) for scenes without <size memory>: this much
    #: plus `arena_bytes_per_body` per body, resized on every recompile. MuJoCo's own default
    #: grows with the square of the bodies (1.8 GB at 1,000); a resting box needs about 7 kB.
    arena_base_bytes: int = 16 * 2 ** 20
    arena_bytes_per_body: int = 64 * 2 ** 10


@dataclass(frozen=True)
class PerceptionConfig:
    """
    What the node renders and senses: cameras, laser scanners, sensor messages.

    Rates are in simulated Hz: a camera at 10 Hz gives an image per 0.1 s of simulated time
    (fewer when the renderer cannot keep up; the physics never waits for it).
    """

    #: Camera names to publish, shell-style patterns; a pattern that matches nothing (e.g.
    #: 'none') turns cameras off.
    cameras: tuple = ('*',)
    camera_width: int = 320
    camera_height: int = 240
    camera_rate_hz: float = 10.0
    #: Also publish depth images (32FC1, metres along the optical axis).
    camera_depth: bool = True
    #: Also publish an organized point cloud (PointCloud2 x, y, z, rgb) from each depth image.
    camera_points: bool = False
    #: Shadow map side in texels; 0 turns shadows off. With Mesa's software renderer 1024
    #: draws a 320x240 frame in about 18 ms, MuJoCo's default 4096 in about 60 ms.
    camera_shadow_size: int = 1024
    #: Sites that carry a laser scanner, shell-style patterns on site names.
    lidar_sites: tuple = ('*lidar*',)
    lidar_rate_hz: float = 10.0
    lidar_angle_min: float = -3.141592653589793
    lidar_angle_max: float = 3.141592653589793
    lidar_samples: int = 360
    lidar_range_min: float = 0.05
    lidar_range_max: float = 10.0
