"""
Every conversion of ``msg_adapters.convert`` and ``markers``, both ways where there are two.

Quaternion order (MuJoCo w, x, y, z; ROS x, y, z, w), stamps, codes and marker shapes, against
values worked out by hand and rclpy's own message classes.
"""

import math

from builtin_interfaces.msg import Time
from msg_adapters import convert, markers
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from sim_node.core import errors
from sim_node.core.records import EntityState, GeomVisual
from simulation_interfaces.msg import Bounds, Result, SimulationState
from simulation_interfaces.srv import LoadWorld, SetEntityState, SpawnEntity
from visualization_msgs.msg import Marker, MarkerArray


@pytest.mark.parametrize('t, sec, nsec', [
    (0.0, 0, 0), (1.5, 1, 500_000_000), (12.000000001, 12, 1),
    (0.9999999999, 1, 0),  # rounds up into the next second, never nanosec = 1e9
    (123456.789, 123456, 789_000_000)])
def test_stamps_both_ways(t, sec, nsec):
    msg = convert.stamp(t)
    assert (msg.sec, msg.nanosec) == (sec, nsec)
    assert convert.stamp_to_sec(msg) == pytest.approx(t, abs=1e-9)
    assert convert.clock(t).clock == msg


def test_quaternion_order_both_ways():
    wxyz = np.array([0.5, -0.5, 0.5, 0.5])
    msg = convert.quat_to_msg(wxyz)
    assert (msg.x, msg.y, msg.z, msg.w) == (-0.5, 0.5, 0.5, 0.5)
    np.testing.assert_array_equal(convert.quat_from_msg(msg), wxyz)


def test_vectors_and_poses_both_ways():
    v = convert.vec([1, -2.5, 3e-9])
    assert (v.x, v.y, v.z) == (1.0, -2.5, 3e-9)
    np.testing.assert_array_equal(convert.vec_from_msg(v), [1, -2.5, 3e-9])
    q = (math.cos(0.3), 0.0, 0.0, math.sin(0.3))
    pose = convert.pose_to_msg((0.1, 0.2, 0.3), q)
    assert (pose.orientation.z, pose.orientation.w) == (math.sin(0.3), math.cos(0.3))
    pos, back = convert.pose_from_msg(pose)
    np.testing.assert_array_equal(pos, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(back, q)


def test_an_all_zero_message_quaternion_is_passed_on_as_zero_for_the_core_to_refuse():
    from geometry_msgs.msg import Pose
    pose = Pose()
    pose.orientation.w = 0.0
    np.testing.assert_array_equal(convert.pose_from_msg(pose)[1], [0, 0, 0, 0])


def test_entity_state_message_carries_every_field_with_its_stamp_and_frame():
    st = EntityState(position=np.array([1., 2., 3.]), quat_wxyz=np.array([0., 1., 0., 0.]),
                     linear_velocity=np.array([4., 5., 6.]),
                     angular_velocity=np.array([7., 8., 9.]), time=2.25,
                     linear_acceleration=np.array([0., 0., -9.81]),
                     angular_acceleration=np.array([.1, .2, .3]))
    msg = convert.entity_state_to_msg(st, 'r2/world')
    assert msg.header.frame_id == 'r2/world'
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (2, 250_000_000)
    p, o = msg.pose.position, msg.pose.orientation
    assert (p.x, p.y, p.z, o.x, o.y, o.z, o.w) == (1, 2, 3, 1, 0, 0, 0)
    assert (msg.twist.linear.z, msg.twist.angular.x) == (6, 7)
    assert (msg.acceleration.linear.z, msg.acceleration.angular.z) == (-9.81, .3)


def test_bounds_box_is_min_then_max_corner():
    b = convert.bounds_box((-1, -2, -3), (1, 2, 3))
    assert b.type == Bounds.TYPE_BOX
    assert [(p.x, p.y, p.z) for p in b.points] == [(-1, -2, -3), (1, 2, 3)]


@pytest.mark.parametrize('state, code', [
    ('playing', SimulationState.STATE_PLAYING), ('paused', SimulationState.STATE_PAUSED),
    ('stopped', SimulationState.STATE_STOPPED), ('no_world', SimulationState.STATE_NO_WORLD)])
def test_simulation_states(state, code):
    assert convert.simulation_state(state).state == code


@pytest.mark.parametrize('exc, response, code', [
    (errors.NotFoundError('x'), SpawnEntity.Response, Result.RESULT_NOT_FOUND),
    (errors.NameNotUniqueError('x'), SpawnEntity.Response, SpawnEntity.Response.NAME_NOT_UNIQUE),
    (errors.InvalidPoseError('x'), SpawnEntity.Response, SpawnEntity.Response.INVALID_POSE),
    (errors.InvalidPoseError('x'), SetEntityState.Response, SetEntityState.Response.INVALID_POSE),
    (errors.MissingAssetsError('x'), SpawnEntity.Response, SpawnEntity.Response.MISSING_ASSETS),
    (errors.MissingAssetsError('x'), LoadWorld.Response, LoadWorld.Response.MISSING_ASSETS),
    (errors.ResourceParseError('x'), LoadWorld.Response, LoadWorld.Response.RESOURCE_PARSE_ERROR),
    (errors.NoResourceError('x'), LoadWorld.Response, LoadWorld.Response.NO_RESOURCE),
    # A service without a code of its own for it: the generic one.
    (errors.InvalidPoseError('x'), None, Result.RESULT_OPERATION_FAILED),
    (errors.IncorrectStateError('x'), SpawnEntity.Response, Result.RESULT_INCORRECT_STATE),
    (errors.InvalidArgumentError('x'), SpawnEntity.Response, Result.RESULT_OPERATION_FAILED),
    (ValueError('x'), SpawnEntity.Response, Result.RESULT_OPERATION_FAILED),
])
def test_result_codes(exc, response, code):
    result = convert.result_for(exc, response)
    assert (result.result, result.error_message) == (code, 'x')
    assert convert.ok().result == Result.RESULT_OK


def _geom(kind, size, mesh=None):
    verts, faces = mesh if mesh else (None, None)
    return GeomVisual(name='g', body=1, type=kind, size=size, pos=(0.1, 0.2, 0.3),
                      quat_wxyz=(0.0, 0.0, 0.0, 1.0), rgba=(1.0, 0.5, 0.25, 1.0),
                      mesh_vertices=verts, mesh_faces=faces)


@pytest.mark.parametrize('kind, size, mtype, scale', [
    ('box', (0.1, 0.2, 0.3), Marker.CUBE, (0.2, 0.4, 0.6)),
    ('sphere', (0.1, 0, 0), Marker.SPHERE, (0.2, 0.2, 0.2)),
    ('ellipsoid', (0.1, 0.2, 0.3), Marker.SPHERE, (0.2, 0.4, 0.6)),
    ('cylinder', (0.1, 0.5, 0), Marker.CYLINDER, (0.2, 0.2, 1.0)),
    ('capsule', (0.1, 0.5, 0), Marker.CYLINDER, (0.2, 0.2, 1.2)),  # tip to tip
    ('plane', (0, 0, 0.1), Marker.CUBE, (20.0, 20.0, 0.001)),  # infinite: drawn 20 m wide
    ('plane', (2, 3, 0.1), Marker.CUBE, (4.0, 6.0, 0.001)),
])
def test_marker_shapes_match_mujoco_sizes(kind, size, mtype, scale):
    got_type, got_scale, points = markers.shape(_geom(kind, size))
    assert got_type == mtype and points is None
    assert got_scale == pytest.approx(scale)


def test_a_mesh_is_a_triangle_list_of_its_faces_and_markers_read_back_in_ros_order():
    from types import SimpleNamespace
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = np.array([[0, 1, 2], [0, 1, 3]])
    geom = _geom('mesh', (0, 0, 0), (verts, faces))
    mtype, _, points = markers.shape(geom)
    assert mtype == Marker.TRIANGLE_LIST
    np.testing.assert_array_equal(points, verts[[0, 1, 2, 0, 1, 3]])
    info = SimpleNamespace(body_root=np.array([0, 1]), body_names=('world', 'thing'),
                           geoms=(geom,))
    msg = deserialize_message(markers.markers(info, 3.5, ('w', 'thing')), MarkerArray)
    clear, m = msg.markers
    assert clear.action == Marker.DELETEALL
    assert (m.header.frame_id, m.ns, m.id, m.action) == ('thing', 'sim/thing', 0, Marker.ADD)
    assert (m.header.stamp.sec, m.header.stamp.nanosec) == (3, 500_000_000)
    assert m.frame_locked
    o = m.pose.orientation
    assert (o.x, o.y, o.z, o.w) == (0.0, 0.0, 1.0, 0.0)  # MuJoCo (w, x, y, z) = (0, 0, 0, 1)
    assert (m.color.r, m.color.g, m.color.b, m.color.a) == (1.0, 0.5, 0.25, 1.0)
    assert [(p.x, p.y, p.z) for p in m.points] == [tuple(v) for v in verts[[0, 1, 2, 0, 1, 3]]]


def test_clear_markers_is_one_deleteall_in_the_world_frame():
    msg = deserialize_message(markers.clear_markers(1.25, 'r2/world'), MarkerArray)
    (m,) = msg.markers
    assert (m.action, m.header.frame_id) == (Marker.DELETEALL, 'r2/world')
    assert (m.header.stamp.sec, m.header.stamp.nanosec) == (1, 250_000_000)


def test_joint_state_message():
    from types import SimpleNamespace
    info = SimpleNamespace(joint_names=('a/j1', 'j2'))
    snap = SimpleNamespace(time=0.5, joint_position=np.array([0.1, 0.2]),
                           joint_velocity=np.array([1.0, 2.0]), joint_effort=np.array([3., 4.]))
    msg = convert.joint_state(info, snap)
    assert list(msg.name) == ['a/j1', 'j2']
    assert (list(msg.position), list(msg.velocity), list(msg.effort)) == (
        [0.1, 0.2], [1.0, 2.0], [3.0, 4.0])
    assert msg.header.stamp == Time(sec=0, nanosec=500_000_000)


@pytest.mark.parametrize('encoding, pixel', [('rgb8', [200, 100, 50]), ('bgr8', [50, 100, 200]),
                                             ('mono8', [124]), ('mono16', [31919])])
def test_an_image_goes_out_in_the_encoding_its_camera_declares(encoding, pixel):
    """Grey is BT.601's luma: 0.299 R + 0.587 G + 0.114 B = 124.2 of (200, 100, 50); x 257."""
    from msg_adapters import perception
    rgb = np.tile(np.array([200, 100, 50], np.uint8), (2, 3, 1))
    msg = perception.image(rgb, 1.5, 'cam', encoding)
    dtype = '<u2' if encoding == 'mono16' else np.uint8
    got = np.frombuffer(bytes(msg.data), dtype).reshape(2, 3, -1)
    assert msg.encoding == encoding and msg.step == 3 * len(pixel) * np.dtype(dtype).itemsize
    assert got[1, 2].tolist() == pixel
