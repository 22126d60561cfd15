"""
Finding a mobile base: which entities are differential-drive or holonomic planar robots.

An entity has a base when (first match wins):

* its URDF carries a Gazebo drive plugin: diff drive (``libgazebo_ros_diff_drive.so``, ROS 1's
  ``<leftJoint>`` spelling too, or ``gz-sim-diff-drive-system`` with one or more joints a side)
  or planar move (``libgazebo_ros_planar_move.so``, for a floating root);
* it has hinge joints named as wheels, ``left`` and ``right`` (``left_wheel_joint``,
  ``wheel_right``...): differential drive;
* two slide joints with horizontal axes and a hinge with a vertical one (robosuite's mobile
  bases): holonomic planar.

Wheel radius and separation are measured from the model (a plugin's values win where it gives
them): the radius from the wheel's colliding geoms across its axis, the separation between the
left and right anchors along it, the sign of each wheel from which way its axis turns it
forward. What it finds is a :class:`BaseSpec`.

Driving a base found here is :mod:`.drives` (a velocity command held by its wheels or joints);
:class:`.odometry.BaseOdometry` integrates a base's pose from its wheel angles (it drifts with
slip, as a real robot's does) or takes the simulation's ground truth; ROS-free, used by the
node's ``<entity>/odom``. What a spawn adds to a wheeled model (wheel actuators, rolling
casters) is :mod:`.wheels`.
"""

from dataclasses import dataclass
import math
from typing import Optional, Sequence

import mujoco
import numpy as np

from .odometry import BaseOdometry as Odometry  # noqa: F401 (the name older code imports)
from ..base import quat

DIFF_DRIVE, PLANAR_JOINTS, PLANAR_FREE = 'diff_drive', 'planar_joints', 'planar_free'
ERR_NO_BASE = ('entity {entity!r} has no mobile base: no wheel joints named left and right, no '
               'planar joints and no Gazebo drive plugin in its URDF')
_HINGE, _SLIDE, _FREE = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE),
                         int(mujoco.mjtJoint.mjJNT_FREE))
_DIFF_PLUGINS = ('diff_drive', 'diff-drive', 'diffdrive')
_PLANAR_PLUGINS = ('planar_move',)


@dataclass(frozen=True)
class BaseSpec:
    """
    What drives an entity's base, as found in its model (see the module docstring).

    Joint names are as on joint_states (``<entity>/<joint>``). ``signs``: per wheel, +1 when
    turning it positively drives the base forward. Limits are +-inf when not given.
    """

    entity: str
    kind: str
    found_by: str  # 'gazebo plugin', 'wheel names', 'planar joints'
    left: tuple = ()
    right: tuple = ()
    signs: tuple = ()  # for left + right, in that order
    radius: float = 0.0
    separation: float = 0.0
    planar: tuple = ()  # (slide, slide, hinge) joint names of a holonomic planar base
    max_wheel_speed: float = math.inf  # rad/s
    max_wheel_acceleration: float = math.inf  # rad/s^2
    max_wheel_torque: float = math.inf  # N m
    odom_frame: str = 'odom'
    base_frame: str = ''  # the plugin's robot base frame ('' : the description's root link)

    @property
    def wheels(self) -> tuple:
        return self.left + self.right


def drive_plugin(extensions: Sequence) -> Optional[dict]:
    """
    Read a Gazebo drive plugin out of a URDF's extension elements.

    The elements are those :class:`sim_node.core.models.urdf.Prepared` kept.

    :returns: {'kind', 'left', 'right', 'separation', 'radius', 'max_acceleration',
        'max_torque', 'odom_frame', 'base_frame'} (values absent: missing), or None.
    """
    for ext in extensions:
        for plugin in ext.iter('plugin'):
            name = (plugin.get('filename', '') + ' ' + plugin.get('name', '')).lower()

            def text(*tags):
                for tag in tags:
                    found = [e.text.strip() for e in plugin.iter(tag) if e.text and e.text.strip()]
                    if found:
                        return found
                return []

            def number(*tags):
                values = text(*tags)
                try:
                    return float(values[0]) if values else None
                except ValueError:
                    return None
            frames = {'odom_frame': (text('odometry_frame', 'odometryFrame', 'frame_id') or
                                     ['odom'])[0],
                      'base_frame': (text('robot_base_frame', 'robotBaseFrame', 'child_frame_id')
                                     or [''])[0]}
            if any(k in name for k in _DIFF_PLUGINS):
                diameter = number('wheel_diameter', 'wheelDiameter')
                return {'kind': DIFF_DRIVE, 'left': text('left_joint', 'leftJoint'),
                        'right': text('right_joint', 'rightJoint'),
                        'separation': number('wheel_separation', 'wheelSeparation'),
                        'radius': (number('wheel_radius') if diameter is None
                                   else diameter / 2),
                        'max_acceleration': number('max_wheel_acceleration',
                                                   'wheelAcceleration'),
                        # Gazebo's plugin limits the wheels to 20 N m unless told
                        'max_torque': number('max_wheel_torque', 'wheelTorque') or 20.0,
                        **frames}
            if any(k in name for k in _PLANAR_PLUGINS):
                return {'kind': PLANAR_FREE, **frames}
    return None


def find_all(model, data, entities, spawned: dict) -> dict:
    """Return entity name -> :class:`BaseSpec` for every entity with a mobile base."""
    found = {}
    # Without a plugin's word, a base turns on hinges (wheels, or a planar base's yaw): an
    # entity with none is passed over at once. Looking at each of 400 boxes held the world
    # lock 23-38 ms per model under a spawn storm (``make bench-storm``, timed in the node).
    hinged = set(model.jnt_bodyid[model.jnt_type == _HINGE].tolist())
    for rec in entities:
        plugin = getattr(spawned.get(rec.name), 'drive', None)
        if plugin is None and hinged.isdisjoint(rec.body_ids):
            continue
        spec = find(model, data, rec.name, rec.body_ids, plugin)
        if spec is not None:
            found[rec.name] = spec
    return found


def find(m: mujoco.MjModel, d: mujoco.MjData, entity: str, bodies: Sequence[int],
         plugin: Optional[dict] = None) -> Optional[BaseSpec]:
    """
    Return the base of one entity (its bodies, root first), or None.

    `d` must have its kinematics computed (anchors and axes are measured from it).
    """
    prefix = entity + '/'
    joints = [j for b in bodies for j in range(m.body_jntadr[b], m.body_jntadr[b]
                                               + m.body_jntnum[b])]

    def jname(j: int) -> str:  # as on joint_states
        return mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f'joint_{j}'

    def own(j: int) -> str:  # as in the entity's own file
        name = jname(j)
        return name[len(prefix):] if name.startswith(prefix) else name

    frames = {k: plugin[k] for k in ('odom_frame', 'base_frame')} if plugin else {}
    if plugin and plugin['kind'] == PLANAR_FREE:
        root = bodies[0]
        if m.body_jntnum[root] and int(m.jnt_type[m.body_jntadr[root]]) == _FREE:
            return BaseSpec(entity, PLANAR_FREE, 'gazebo plugin', **frames)
    by_name = {own(j): j for j in joints if int(m.jnt_type[j]) == _HINGE}
    if plugin and plugin['kind'] == DIFF_DRIVE:
        left = [by_name[n] for n in plugin['left'] if n in by_name]
        right = [by_name[n] for n in plugin['right'] if n in by_name]
        if left and right:
            return _diff(m, d, entity, left, right, 'gazebo plugin', plugin, jname, frames)
    wheels = [j for n, j in by_name.items() if 'wheel' in n.lower()]
    left = [j for j in wheels if 'left' in own(j).lower()]
    right = [j for j in wheels if 'right' in own(j).lower()]
    if left and right:
        return _diff(m, d, entity, left, right, 'wheel names', {}, jname, frames)
    planar = _planar_joints(m, joints)
    if planar is not None:
        return BaseSpec(entity, PLANAR_JOINTS, 'planar joints',
                        planar=tuple(jname(j) for j in planar), **frames)
    return None


def _diff(m, d, entity: str, left: list, right: list, found_by: str, plugin: dict, jname,
          frames: dict) -> Optional[BaseSpec]:
    root = int(m.body_rootid[m.jnt_bodyid[left[0]]])
    base = int(m.body_parentid[m.jnt_bodyid[left[0]]])
    forward = d.xmat[base].reshape(3, 3)[:, 0]
    up = np.array([0.0, 0.0, 1.0])
    signs, radii = [], []
    for j in left + right:
        axis = d.xaxis[j]
        signs.append(1.0 if float(np.dot(np.cross(axis, up), forward)) >= 0 else -1.0)
        radii.append(_wheel_radius(m, int(m.jnt_bodyid[j]), m.jnt_axis[j]))
    axis = d.xaxis[left[0]]
    lc = np.mean([d.xanchor[j] for j in left], axis=0)
    rc = np.mean([d.xanchor[j] for j in right], axis=0)
    # Measured in the pose the base is in: to a nanometre, so that the same base measured in
    # another pose (another model generation) is the same spec (1.2 m read 1.2000000000000002).
    separation = plugin.get('separation') or round(abs(float(np.dot(lc - rc, axis))), 9)
    radius = plugin.get('radius') or round(float(np.median(radii)), 9)
    if not (separation > 0 and radius > 0) or root == 0:
        return None
    return BaseSpec(
        entity, DIFF_DRIVE, found_by, tuple(jname(j) for j in left),
        tuple(jname(j) for j in right), tuple(signs), float(radius), float(separation),
        max_wheel_acceleration=plugin.get('max_acceleration') or math.inf,
        max_wheel_torque=plugin.get('max_torque') or math.inf, **frames)


def _wheel_radius(m: mujoco.MjModel, body: int, axis: np.ndarray) -> float:
    """Return a wheel's radius across its axis, from its colliding geoms (else any), or 0."""
    geoms = range(m.body_geomadr[body], m.body_geomadr[body] + m.body_geomnum[body])
    solid = [g for g in geoms if m.geom_contype[g] or m.geom_conaffinity[g]] or list(geoms)
    best = 0.0
    for g in solid:
        local = quat.rotate(quat.conj(m.geom_quat[g]), axis)  # the axis in the geom's frame
        half = m.geom_aabb[g, 3:]
        across = [half[k] for k in range(3) if abs(local[k]) < 0.5]
        if across:
            best = max(best, float(max(across)))
    return best


def _planar_joints(m: mujoco.MjModel, joints: list) -> Optional[tuple]:
    """Two slides with horizontal axes and a vertical hinge: (slide, slide, hinge)."""
    slides = [j for j in joints if int(m.jnt_type[j]) == _SLIDE and abs(m.jnt_axis[j][2]) < 0.1]
    hinges = [j for j in joints if int(m.jnt_type[j]) == _HINGE and abs(m.jnt_axis[j][2]) > 0.9]
    if len(slides) < 2 or not hinges:
        return None
    a, b = m.jnt_axis[slides[0]][:2], m.jnt_axis[slides[1]][:2]
    if abs(a[0] * b[1] - a[1] * b[0]) < 0.5:  # parallel: not a plane
        return None
    return slides[0], slides[1], hinges[0]
