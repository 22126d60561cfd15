"""RViz markers for every visible geom, locked to its body's TF frame."""

from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from sim_node.core.types import GeomVisual, ModelInfo

from .convert import pose_to_msg, stamp

NAMESPACE_PREFIX = 'sim/'
# A plane of size 0 is infinite in MuJoCo; draw it this big (m).
INFINITE_PLANE_HALF = 10.0


def _marker_ns(info: ModelInfo, geom: GeomVisual) -> str:
    """Markers are grouped by entity, so deleting an entity deletes one namespace."""
    root = int(info.body_root[geom.body])
    return NAMESPACE_PREFIX + (info.body_names[root] if root else 'world')


def _shape(marker: Marker, geom: GeomVisual) -> None:
    sx, sy, sz = geom.size
    if geom.type == 'box':
        marker.type = Marker.CUBE
        marker.scale.x, marker.scale.y, marker.scale.z = 2 * sx, 2 * sy, 2 * sz
    elif geom.type == 'sphere':
        marker.type = Marker.SPHERE
        marker.scale.x = marker.scale.y = marker.scale.z = 2 * sx
    elif geom.type == 'ellipsoid':
        marker.type = Marker.SPHERE
        marker.scale.x, marker.scale.y, marker.scale.z = 2 * sx, 2 * sy, 2 * sz
    elif geom.type == 'cylinder':
        marker.type = Marker.CYLINDER
        marker.scale.x = marker.scale.y = 2 * sx
        marker.scale.z = 2 * sy
    elif geom.type == 'capsule':
        # RViz has no capsule: a cylinder spanning the full length is close enough.
        marker.type = Marker.CYLINDER
        marker.scale.x = marker.scale.y = 2 * sx
        marker.scale.z = 2 * sy + 2 * sx
    elif geom.type == 'plane':
        marker.type = Marker.CUBE
        marker.scale.x = 2 * (sx or INFINITE_PLANE_HALF)
        marker.scale.y = 2 * (sy or INFINITE_PLANE_HALF)
        marker.scale.z = 0.001
    elif geom.type == 'mesh':
        marker.type = Marker.TRIANGLE_LIST
        marker.scale.x = marker.scale.y = marker.scale.z = 1.0
        v = geom.mesh_vertices
        marker.points = [Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))
                         for p in v[geom.mesh_faces.reshape(-1)]]


def clear_markers(sim_time: float, world_frame: str) -> MarkerArray:
    """One DELETEALL marker: RViz drops every marker it has from this topic."""
    m = Marker(action=Marker.DELETEALL)
    m.header.stamp = stamp(sim_time)
    m.header.frame_id = world_frame
    return MarkerArray(markers=[m])


def markers(info: ModelInfo, sim_time: float, world_frame: str) -> MarkerArray:
    """The markers of one model generation: a DELETEALL first (so nothing of an earlier
    generation survives, whatever was respawned under which name), then one marker per
    visible geom, in its body's frame."""
    out = clear_markers(sim_time, world_frame)
    t = out.markers[0].header.stamp
    counters: dict = {}
    for geom in info.geoms:
        m = Marker()
        m.header.stamp = t
        m.header.frame_id = world_frame if geom.body == 0 else info.body_names[geom.body]
        m.ns = _marker_ns(info, geom)
        m.id = counters.get(m.ns, 0)
        counters[m.ns] = m.id + 1
        m.action = Marker.ADD
        m.frame_locked = True
        m.pose = pose_to_msg(geom.pos, geom.quat_wxyz)
        m.color = ColorRGBA(r=float(geom.rgba[0]), g=float(geom.rgba[1]),
                            b=float(geom.rgba[2]), a=float(geom.rgba[3]))
        _shape(m, geom)
        out.markers.append(m)
    return out
