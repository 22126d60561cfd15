"""
Pure conversions between core values and ROS messages.

The one place where quaternion order changes: MuJoCo is (w, x, y, z), ROS is (x, y, z, w).
Stamps always come from simulation time, never from the wall clock.
"""

import math
from typing import Sequence

from builtin_interfaces.msg import Time
from geometry_msgs.msg import (Accel, Point, Pose, Quaternion, Transform, TransformStamped, Twist,
                               Vector3)
import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from sim_node.core.base import errors, quat
from sim_node.core.base.records import DYNAMIC, ModelInfo, ROBOT, Snapshot, STATIC
from sim_node.core.query import Region
from simulation_interfaces.msg import Bounds, EntityCategory, EntityState, Result, SimulationState
from tf2_msgs.msg import TFMessage

from .cdr import TfTemplate

# Core exceptions -> simulation_interfaces Result codes, in one table. Service-specific codes
# (SpawnEntity.Response.NAME_NOT_UNIQUE, ...) are looked up by name on the response type.
RESULT_CODES = (
    (errors.FeatureUnsupportedError, Result.RESULT_FEATURE_UNSUPPORTED, None),
    (errors.NotFoundError, Result.RESULT_NOT_FOUND, None),
    (errors.NameNotUniqueError, Result.RESULT_OPERATION_FAILED, 'NAME_NOT_UNIQUE'),
    (errors.NameInvalidError, Result.RESULT_OPERATION_FAILED, 'NAME_INVALID'),
    (errors.NamespaceInvalidError, Result.RESULT_OPERATION_FAILED, 'NAMESPACE_INVALID'),
    (errors.NoResourceError, Result.RESULT_OPERATION_FAILED, 'NO_RESOURCE'),
    (errors.UnsupportedFormatError, Result.RESULT_OPERATION_FAILED, 'UNSUPPORTED_FORMAT'),
    (errors.ResourceParseError, Result.RESULT_OPERATION_FAILED, 'RESOURCE_PARSE_ERROR'),
    (errors.MissingAssetsError, Result.RESULT_OPERATION_FAILED, 'MISSING_ASSETS'),
    (errors.UnsupportedAssetsError, Result.RESULT_OPERATION_FAILED, 'UNSUPPORTED_ASSETS'),
    (errors.UnsupportedElementsError, Result.RESULT_OPERATION_FAILED, 'UNSUPPORTED_ELEMENTS'),
    (errors.InvalidPoseError, Result.RESULT_OPERATION_FAILED, 'INVALID_POSE'),
    (errors.OperationFailedError, Result.RESULT_OPERATION_FAILED, None),
    (errors.NoWorldError, Result.RESULT_INCORRECT_STATE, 'NO_WORLD_LOADED'),
    (errors.AlreadyInStateError, Result.RESULT_OPERATION_FAILED, 'ALREADY_IN_TARGET_STATE'),
    (errors.StateTransitionError, Result.RESULT_OPERATION_FAILED, 'STATE_TRANSITION_ERROR'),
    (errors.IncorrectTransitionError, Result.RESULT_OPERATION_FAILED, 'INCORRECT_TRANSITION'),
    (errors.IncorrectStateError, Result.RESULT_INCORRECT_STATE, None),
    (errors.CapacityError, Result.RESULT_OPERATION_FAILED, None),
    (errors.InvalidArgumentError, Result.RESULT_OPERATION_FAILED, None),
    (errors.DivergenceError, Result.RESULT_OPERATION_FAILED, None),
    (errors.SimError, Result.RESULT_OPERATION_FAILED, None),
)

CATEGORY_TO_MSG = {ROBOT: EntityCategory.CATEGORY_ROBOT,
                   DYNAMIC: EntityCategory.CATEGORY_DYNAMIC_OBJECT,
                   STATIC: EntityCategory.CATEGORY_STATIC_OBJECT}


def result_for(exc: Exception, response_type: type = None) -> Result:
    """Return the Result for a core exception (a service's own code where it has one)."""
    for kind, code, specific in RESULT_CODES:
        if isinstance(exc, kind):
            if specific and response_type is not None and hasattr(response_type, specific):
                code = getattr(response_type, specific)
            return Result(result=code, error_message=str(exc))
    return Result(result=Result.RESULT_OPERATION_FAILED, error_message=str(exc))


def ok() -> Result:
    return Result(result=Result.RESULT_OK, error_message='')


def stamp(sim_time: float) -> Time:
    sec = int(math.floor(sim_time))
    nanosec = int(round((sim_time - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return Time(sec=sec, nanosec=nanosec)


def stamp_to_sec(t: Time) -> float:
    return t.sec + t.nanosec * 1e-9


def clock(sim_time: float) -> Clock:
    return Clock(clock=stamp(sim_time))


def quat_to_msg(q_wxyz: Sequence[float]) -> Quaternion:
    return Quaternion(x=float(q_wxyz[1]), y=float(q_wxyz[2]), z=float(q_wxyz[3]),
                      w=float(q_wxyz[0]))


def quat_from_msg(q: Quaternion) -> np.ndarray:
    return np.array([q.w, q.x, q.y, q.z], dtype=float)


def vec(v: Sequence[float]) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def vec_from_msg(v) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def pose_to_msg(pos: Sequence[float], q_wxyz: Sequence[float]) -> Pose:
    return Pose(position=Point(x=float(pos[0]), y=float(pos[1]), z=float(pos[2])),
                orientation=quat_to_msg(q_wxyz))


def pose_from_msg(pose: Pose) -> tuple:
    """
    (position (3,), quat_wxyz (4,)) from a Pose, as given.

    An all-zero quaternion is no rotation at all and is refused by the core as an invalid pose (a
    message's default orientation is already the identity, w = 1).
    """
    return vec_from_msg(pose.position), quat_from_msg(pose.orientation)


def entity_state_to_msg(state, frame_id: str) -> EntityState:
    msg = EntityState()
    msg.header.stamp = stamp(state.time)
    msg.header.frame_id = frame_id
    msg.pose = pose_to_msg(state.position, state.quat_wxyz)
    msg.twist = Twist(linear=vec(state.linear_velocity), angular=vec(state.angular_velocity))
    msg.acceleration = Accel(linear=vec(state.linear_acceleration),
                             angular=vec(state.angular_acceleration))
    return msg


def bounds_box(lo: Sequence[float], hi: Sequence[float]) -> Bounds:
    return Bounds(type=Bounds.TYPE_BOX, points=[vec(lo), vec(hi)])


MSG_TO_CATEGORY = {v: k for k, v in CATEGORY_TO_MSG.items()}


def entity_filters(filters) -> dict:
    """Return an EntityFilters message as keyword arguments of ``sim_node.core.query.query``."""
    out = {'pattern': filters.filter, 'tags': tuple(filters.tags.tags), 'region': None,
           'categories': ({MSG_TO_CATEGORY.get(c.category) for c in filters.categories}
                          if len(filters.categories) else None)}
    b = filters.bounds
    if b.type == Bounds.TYPE_BOX:
        if len(b.points) != 2:
            raise errors.InvalidArgumentError('box bounds need 2 points: min and max corners')
        out['region'] = Region('box', vec_from_msg(b.points[0]), vec_from_msg(b.points[1]))
    elif b.type == Bounds.TYPE_SPHERE:
        if len(b.points) != 2:
            raise errors.InvalidArgumentError('sphere bounds need 2 points: center and '
                                              '(radius, 0, 0)')
        out['region'] = Region('sphere', vec_from_msg(b.points[0]), vec_from_msg(b.points[1]))
    elif b.type == Bounds.TYPE_CONVEX_HULL:
        raise errors.FeatureUnsupportedError(
            'convex hull bounds filters are not supported (ENTITY_BOUNDS_CONVEX is not listed): '
            'use a box or a sphere')
    elif b.type != Bounds.TYPE_EMPTY:
        raise errors.FeatureUnsupportedError(
            f'bounds type {b.type} is none of the standard ones (0 empty, 1 box, 2 convex '
            'hull, 3 sphere): use a box or a sphere')
    if len(filters.tags.tags):
        raise errors.FeatureUnsupportedError(
            'tag filters are not supported (ENTITY_TAGS is not listed): entities carry no tags')
    return out


def simulation_state(loop_state: str) -> SimulationState:
    code = {'playing': SimulationState.STATE_PLAYING, 'paused': SimulationState.STATE_PAUSED,
            'stopped': SimulationState.STATE_STOPPED,
            'no_world': SimulationState.STATE_NO_WORLD,
            'loading_world': SimulationState.STATE_LOADING_WORLD}[loop_state]
    return SimulationState(state=code)


def joint_state(info: ModelInfo, snap: Snapshot) -> JointState:
    """
    Return the snapshot's hinge and slide joints as JointState.

    Not those of robots whose own controllers publish them (``info.ros2_control``: their
    joint_state_broadcaster, under the URDF's names).
    """
    msg = JointState()
    msg.header.stamp = stamp(snap.time)
    if getattr(info, 'ros2_control', None):
        keep = [i for i, e in enumerate(info.joint_entity) if e not in info.ros2_control]
        msg.name = [info.joint_names[i] for i in keep]
        msg.position = snap.joint_position[keep].tolist()
        msg.velocity = snap.joint_velocity[keep].tolist()
        msg.effort = snap.joint_effort[keep].tolist()
        return msg
    msg.name = list(info.joint_names)
    msg.position = snap.joint_position.tolist()
    msg.velocity = snap.joint_velocity.tolist()
    msg.effort = snap.joint_effort.tolist()
    return msg


def transform(parent: str, child: str, pos, q_wxyz, t: Time) -> TransformStamped:
    """Return the pose (pos (3,), q_wxyz (4,)) of `child` in `parent` as a TransformStamped."""
    ts = TransformStamped()
    ts.header.stamp = t
    ts.header.frame_id = parent
    ts.child_frame_id = child
    ts.transform = Transform(translation=vec(pos), rotation=quat_to_msg(q_wxyz))
    return ts


def element_frame(info: ModelInfo, body: int, name: str, prefix: str = '') -> str:
    """
    Return the TF frame of something called `name` on `body`, by the one frame rule.

    ``<entity>/<name>`` within an entity (a spawned model's names already carry that prefix
    in MuJoCo), `name` alone on the world body; after `prefix`.
    """
    root = int(info.body_root[body])
    if root != 0 and not name.startswith(info.body_names[root] + '/'):
        name = f'{info.body_names[root]}/{name}'
    return prefix + name


def frame_names(info: ModelInfo, world_frame: str, prefix: str = '') -> tuple:
    """
    Return the TF frame of every body, (nbody,), by one rule for scene and spawned entities.

    The world body is `world_frame`; an entity's root body is the entity's name; every other
    body is ``<entity>/<body>``, its name in its own model (:func:`element_frame`). Each is
    given after `prefix` (like robot_state_publisher's frame_prefix).
    """
    names = info.body_names
    return (prefix + world_frame,) + tuple(
        prefix + names[b] if info.body_root[b] == b else element_frame(info, b, names[b], prefix)
        for b in range(1, len(names)))


def parent_frames(info: ModelInfo, frames: Sequence[str], prefix: str = '') -> tuple:
    """Return the frame each body's transform hangs from: its parent's, or a URDF root link's."""
    return tuple(prefix + info.body_alias[p] if info.body_alias[p] else frames[p]
                 for p in info.body_parent)


def static_transforms(info: ModelInfo, sim_time: float, frames: Sequence[str],
                      prefix: str = '') -> TFMessage:
    """
    Welded bodies: their fixed pose in the parent body's frame, for /tf_static.

    Also the identity from an entity's frame to its root body's own frame (the root link of
    its robot description), and the mount of a root body that has joints.

    :param frames: (nbody,) frame names from :func:`frame_names`.
    """
    t = stamp(sim_time)
    parents = parent_frames(info, frames, prefix)
    out = [transform(parents[b], frames[b], info.body_local_pos[b],
                     info.body_local_quat_wxyz[b], t)
           for b in range(1, len(info.body_names)) if not info.body_has_joint[b]]
    out += [transform(frames[b], prefix + alias, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), t)
            for b, alias in enumerate(info.body_alias) if alias]
    # The intermediate link of a body's last joint: at the joint's anchor, in the body.
    out += [transform(frames[c.body], prefix + c.frame, c.offset, (1.0, 0.0, 0.0, 0.0), t)
            for c in info.chains if c.static]
    out += [transform(prefix + parent, prefix + child, pos, quat_wxyz, t)
            for parent, child, pos, quat_wxyz in info.link_frames]
    # At the world's origin: the root link of the robot description of an entity whose
    # top-level bodies move by joints of their own (see ModelInfo.body_mount).
    out += [transform(frames[0], prefix + mount, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), t)
            for mount in info.body_mount if mount]
    return TFMessage(transforms=out)


def moving_body_ids(info: ModelInfo) -> np.ndarray:
    return np.array([b for b in range(1, len(info.body_names)) if info.body_has_joint[b]],
                    dtype=int)


def relative_poses(snap: Snapshot, bodies: np.ndarray, parents: np.ndarray) -> tuple:
    """Pose of each body in its parent's frame: (pos (n, 3), quat_wxyz (n, 4))."""
    pp, pq = snap.body_xpos[parents], snap.body_xquat_wxyz[parents]
    cp, cq = snap.body_xpos[bodies], snap.body_xquat_wxyz[bodies]
    inv = quat.conj(pq)
    return quat.rotate(inv, cp - pp), quat.mul(inv, cq)


def moving_tf_template(info: ModelInfo, bodies: np.ndarray, frames: Sequence[str],
                       prefix: str = '', chains: Sequence = ()) -> TfTemplate:
    """
    Return the /tf message layout of one model generation.

    Parent body -> body for each of `bodies` (free bodies from the world frame), then parent
    body -> link for each of `chains` (moving intermediate links of descriptions, see
    :attr:`ModelInfo.chains <sim_node.core.records.ModelInfo.chains>`); `frames` from
    :func:`frame_names`.
    """
    parents = parent_frames(info, frames, prefix)
    return TfTemplate([parents[b] for b in bodies] + [parents[c.body] for c in chains],
                      [frames[b] for b in bodies] + [prefix + c.frame for c in chains])


def moving_tf(template: TfTemplate, info: ModelInfo, snap: Snapshot,
              bodies: np.ndarray, chains: Sequence = ()) -> bytes:
    """
    Return the serialized /tf message of a snapshot.

    Every transform stamped with its simulation time, built from numpy arrays in one pass.
    """
    pos, rot = relative_poses(snap, bodies, info.body_parent[bodies])
    if chains:
        cpos, crot = chain_poses(chains, snap.joint_position)
        pos, rot = np.concatenate([pos, cpos]), np.concatenate([rot, crot])
    return template.fill(snap.time, pos, rot[:, [1, 2, 3, 0]])


def chain_poses(chains: Sequence, joint_position: np.ndarray) -> tuple:
    """
    Poses of moving intermediate links in their parent body's frame, at the joints' positions.

    Each is the product of its steps' ``origin * motion(q)``, as robot_state_publisher
    computes them: (positions (n, 3), quaternions wxyz (n, 4)).
    """
    pos, rot = np.zeros((len(chains), 3)), np.zeros((len(chains), 4))
    for i, c in enumerate(chains):
        p, r = np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
        for origin_p, origin_q, j, hinge, axis in c.steps:
            p, r = p + quat.rotate(r, origin_p), quat.mul(r, origin_q)
            q = float(joint_position[j])
            if hinge:
                half = 0.5 * q
                r = quat.mul(r, np.concatenate([[math.cos(half)],
                                                math.sin(half) * np.asarray(axis)]))
            else:
                p = p + quat.rotate(r, np.asarray(axis) * q)
        pos[i], rot[i] = p, r
    return pos, rot
