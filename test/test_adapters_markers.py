"""
Markers follow the model generation.

What RViz shows after each message is exactly the geoms of the model that message came from,
whatever was deleted or respawned under which name in between. The messages are written as bytes:
read back by rclpy's own deserializer.
"""

from conftest import DEFAULT_SCENE
from msg_adapters import convert, markers
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from sim_node.core.models import sources
from sim_node.core.world import World
from visualization_msgs.msg import Marker, MarkerArray

THREE_GEOMS = """<mujoco><worldbody><body name="b"><freejoint/>
  <geom type="box" size=".05 .05 .05"/><geom type="sphere" size=".04" pos="0 0 .1"/>
  <geom type="capsule" size=".02" fromto="0 0 .15 0 0 .3"/></body></worldbody></mujoco>"""


def marker_bytes(w: World, t: float = 0.0) -> bytes:
    info = w.model_info
    return markers.markers(info, t, convert.frame_names(info, 'world'))


def apply(shown: dict, data: bytes) -> dict:
    """Return what an RViz MarkerArray display holds after receiving `data`."""
    for m in deserialize_message(data, MarkerArray).markers:
        if m.action == Marker.DELETEALL:
            shown.clear()
        elif m.action == Marker.DELETE:
            shown.pop((m.ns, m.id), None)
        else:
            shown[(m.ns, m.id)] = m
    return shown


def test_a_respawn_with_fewer_geoms_leaves_no_stale_markers():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('thing', sources.from_model_text(THREE_GEOMS), position=[2, 0, 0.5])
    shown = apply({}, marker_bytes(w))
    assert len([k for k in shown if k[0] == 'sim/thing']) == 3
    # Within one publishing tick: deleted, and respawned under the same name with one geom.
    w.delete('thing')
    w.spawn('thing', sources.primitive('sphere', [0.05]), position=[2, 0, 0.5])
    info = w.model_info
    shown = apply(shown, marker_bytes(w))
    assert len([k for k in shown if k[0] == 'sim/thing']) == 1
    assert len(shown) == len(info.geoms)


def test_cleared_markers_leave_nothing():
    w = World.from_file(str(DEFAULT_SCENE))
    shown = apply({}, marker_bytes(w))
    assert shown
    assert apply(shown, markers.clear_markers(w.time, 'world')) == {}


def test_every_geom_has_a_marker_with_its_shape_pose_colour_and_frame():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('pyr', sources.from_file(str(DEFAULT_SCENE.parent / 'objects' / 'pyramid.obj')),
            position=[2, 0, 0.5])
    info = w.model_info
    msg = deserialize_message(marker_bytes(w, 12.5), MarkerArray)
    assert msg.markers[0].action == Marker.DELETEALL
    got = msg.markers[1:]
    assert len(got) == len(info.geoms)
    by_name = {g.name: g for g in info.geoms}
    box = got[[i for i, g in enumerate(info.geoms) if g.name == 'table_top'][0]]
    g = by_name['table_top']
    assert (box.type, box.ns, box.header.frame_id) == (Marker.CUBE, 'sim/table', 'table')
    assert (box.header.stamp.sec, box.header.stamp.nanosec) == (12, 500_000_000)
    assert [box.scale.x, box.scale.y, box.scale.z] == pytest.approx([2 * s for s in g.size])
    assert [box.pose.position.x, box.pose.position.y, box.pose.position.z] == \
        pytest.approx(g.pos)
    q = box.pose.orientation
    assert [q.w, q.x, q.y, q.z] == pytest.approx(g.quat_wxyz)  # ROS order on the wire
    assert [box.color.r, box.color.g, box.color.b, box.color.a] == pytest.approx(g.rgba)
    assert box.frame_locked
    mesh = [m for m in got if m.ns == 'sim/pyr'][0]
    pg = [g for g in info.geoms if g.name == 'pyr/geom'][0]
    assert mesh.type == Marker.TRIANGLE_LIST and len(mesh.points) == 3 * len(pg.mesh_faces)
    np.testing.assert_allclose([mesh.points[0].x, mesh.points[0].y, mesh.points[0].z],
                               pg.mesh_vertices[pg.mesh_faces[0, 0]])


def test_a_dense_mesh_is_drawn_coarser_within_the_marker_budget():
    import trimesh
    from msg_adapters.markers import coarser, MAX_MARKER_FACES
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=0.2)  # 81,920 faces
    vertices, faces = coarser(np.asarray(sphere.vertices), np.asarray(sphere.faces),
                              MAX_MARKER_FACES)
    assert 0 < len(faces) <= MAX_MARKER_FACES
    drawn = vertices[faces].reshape(-1, 3)
    assert np.allclose(drawn.min(axis=0), -0.2, atol=0.02)  # it keeps its outline
    assert np.allclose(drawn.max(axis=0), 0.2, atol=0.02)
    small = trimesh.creation.box()
    assert coarser(small.vertices, small.faces, MAX_MARKER_FACES)[1] is small.faces
