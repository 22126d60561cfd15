"""
Reading what users bring: model files and text (MJCF, URDF, xacro, SDF), meshes and assets.

:mod:`.sources` (what can be spawned), :mod:`.world_sources` (what can be loaded as a world),
:mod:`.prepare` (model text made ready for MuJoCo: URDF
meshes converted, skins inlined, loose world geometry gathered), :mod:`.assets` (untrusted
model text: safe XML, includes, every file resolved and checked once), :mod:`.asset_store` (the
checked copies MuJoCo reads, one per file identity), :mod:`.paths` (where a path really leads),
:mod:`.resources` (which URIs and folders may be read), :mod:`.urdf` (URDF made ready for
MuJoCo's importer) with :mod:`.inertias` (its inertias repaired as Gazebo loads them),
:mod:`.urdf_declared` (Gazebo sensors and ros2_control interfaces a URDF declares) with
:mod:`.sensor_tags` (what a sensor's tag declares, read and checked), :mod:`.realsense` (the
streams a RealSense Gazebo plugin names), :mod:`.openni` (those an OpenNI Kinect plugin names),
:mod:`.p3d` (the ground truth a P3D plugin asks for) and :mod:`.ros2_control` (a
``<ros2_control>`` block and its Gazebo plugin), :mod:`.controller_yaml`
(a controllers YAML as a controller manager reads it),
:mod:`.xacro_files` and :mod:`.xacro_worker` (xacro expanded in an isolated child process),
:mod:`.meshes`, :mod:`.mesh_worker` and :mod:`.collada_fast` (meshes MuJoCo cannot read,
converted in child processes), :mod:`.decompose` and :mod:`.decompose_worker` (concave
collision meshes split into convex parts in a child process), :mod:`.description` (a URDF of
a compiled model, for robot_description). SDF worlds and models, as Gazebo reads them:
:mod:`.sdf_files` (where ``model://``, Fuel and relative URIs lead; a model folder's file),
:mod:`.sdf_read` (the text read safely, its includes expanded, bounded), :mod:`.sdf_frames`
(poses and frames: ``relative_to``, placement frames, nested models), :mod:`.sdf_shapes`
(geometry and materials as geoms and assets), :mod:`.sdf_parts` (a link's inertial,
collisions, visuals, lights), :mod:`.sdf_joints` (joints, their couplings, loops closed),
:mod:`.sdf_model` (a model's links as a tree of bodies), :mod:`.sdf_world` (a world as one
document, its models with records attached as spawns), :mod:`.sdf_systems` (the gz-sim systems
named, run or not) and :mod:`.sdf_elements` (every element: read, approximated or ignored).
"""
