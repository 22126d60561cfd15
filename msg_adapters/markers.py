"""
RViz markers for every visible geom, locked to its body's TF frame.

One MarkerArray per model generation, written straight to its wire form (:mod:`.cdr`) from the
model info.
"""

from typing import Sequence

import numpy as np
from sim_node.core.base.records import GeomVisual, ModelInfo

from .cdr import CdrWriter, split_time

NAMESPACE_PREFIX = 'sim/'
# A plane of size 0 is infinite in MuJoCo; draw it this big (m).
INFINITE_PLANE_HALF = 10.0
# visualization_msgs/Marker constants.
CUBE, SPHERE, CYLINDER, TRIANGLE_LIST = 1, 2, 3, 11
ADD, DELETEALL = 0, 3


def marker_ns(info: ModelInfo, geom: GeomVisual) -> str:
    """Markers are grouped by entity: namespace ``sim/<entity>``."""
    root = int(info.body_root[geom.body])
    return NAMESPACE_PREFIX + (info.body_names[root] if root else 'world')


def shape(geom: GeomVisual) -> tuple:
    """(marker type, scale (3,), triangle-list points (k, 3) or None) for a geom."""
    sx, sy, sz = geom.size
    if geom.type == 'box':
        return CUBE, (2 * sx, 2 * sy, 2 * sz), None
    if geom.type == 'sphere':
        return SPHERE, (2 * sx,) * 3, None
    if geom.type == 'ellipsoid':
        return SPHERE, (2 * sx, 2 * sy, 2 * sz), None
    if geom.type == 'cylinder':
        return CYLINDER, (2 * sx, 2 * sx, 2 * sy), None
    if geom.type == 'capsule':
        # RViz has no capsule: a cylinder spanning the full length is close enough.
        return CYLINDER, (2 * sx, 2 * sx, 2 * sy + 2 * sx), None
    if geom.type == 'plane':
        return CUBE, (2 * (sx or INFINITE_PLANE_HALF), 2 * (sy or INFINITE_PLANE_HALF),
                      0.001), None
    vertices, faces = coarser(geom.mesh_vertices, geom.mesh_faces, MAX_MARKER_FACES)
    return TRIANGLE_LIST, (1.0, 1.0, 1.0), vertices[faces.reshape(-1)]


#: A mesh with more faces is drawn coarser in markers: a robot's visual meshes (110,000 faces
#: for TIAGo) made a latched MarkerArray of 8 MB, which RViz redraws and rclpy publishes holding
#: Python's GIL for tens of milliseconds. RobotModel, from robot_description, draws them in full.
MAX_MARKER_FACES = 4000


def coarser(vertices: np.ndarray, faces: np.ndarray, max_faces: int) -> tuple:
    """
    Return (vertices, faces) with at most `max_faces` faces, by vertex clustering.

    Vertices are snapped to a grid over the mesh's bounds, each cell's vertices merged into
    their mean, and faces that collapse dropped; the grid is made coarser until few enough
    faces are left. Cheap (numpy), and a mesh keeps its outline.
    """
    if len(faces) <= max_faces:
        return vertices, faces
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    extent = float((hi - lo).max()) or 1.0
    cells = max(2, int(np.sqrt(max_faces)))
    for _ in range(8):
        grid = np.minimum(np.floor((vertices - lo) / (extent / cells)), cells).astype(np.int64)
        key = (grid[:, 0] * (cells + 1) + grid[:, 1]) * (cells + 1) + grid[:, 2]
        _, cluster, counts = np.unique(key, return_inverse=True, return_counts=True)
        cluster = cluster.reshape(-1)
        merged = np.stack([np.bincount(cluster, vertices[:, k], len(counts)) for k in range(3)],
                          axis=1) / counts[:, None]
        f = cluster[faces]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
        if len(f) <= max_faces:
            return merged, f
        cells = max(2, int(cells * 0.7))
    return merged, f[:max_faces]


def _marker(w: CdrWriter, sec: int, nsec: int, frame: str, ns: str, mid: int, mtype: int,
            action: int, pose: tuple = (0, 0, 0, 0, 0, 0, 1), scale=(0, 0, 0),
            rgba=(0, 0, 0, 0), frame_locked: bool = False, points=None) -> None:
    """One visualization_msgs/Marker."""
    w.stamp(sec, nsec)
    w.string(frame)
    w.string(ns)
    w.i32(mid)
    w.i32(mtype)
    w.i32(action)
    w.f64s(pose)  # position x y z, orientation x y z w
    w.f64s(scale)
    w.f32s(rgba)
    w.stamp(0, 0)  # lifetime: forever
    w.boolean(frame_locked)
    w.u32(0 if points is None else len(points))
    if points is not None and len(points):
        w.f64s(np.asarray(points, dtype=float).reshape(-1))
    w.u32(0)  # colors
    w.string('')  # texture_resource
    w.stamp(0, 0)  # texture: header, format, data
    w.string('')
    w.string('')
    w.u32(0)
    w.u32(0)  # uv_coordinates
    w.string('')  # text
    w.string('')  # mesh_resource
    w.string('')  # mesh_file: filename, data
    w.u32(0)
    w.boolean(False)  # mesh_use_embedded_materials


def clear_markers(sim_time: float, world_frame: str) -> bytes:
    """Return a serialized MarkerArray of one DELETEALL: RViz drops every marker of this topic."""
    w = CdrWriter()
    w.u32(1)
    _marker(w, *split_time(sim_time), world_frame, '', 0, 0, DELETEALL)
    return bytes(w.buf)


def markers(info: ModelInfo, sim_time: float, frames: Sequence[str]) -> bytes:
    """
    Return the serialized MarkerArray of one model generation.

    A DELETEALL first (so nothing of an earlier generation survives, whatever was respawned under
    which name), then one marker per visible geom, in its body's frame.

    :param frames: (nbody,) TF frame of each body (``convert.frame_names``).
    """
    sec, nsec = split_time(sim_time)
    w = CdrWriter()
    w.u32(1 + len(info.geoms))
    _marker(w, sec, nsec, frames[0], '', 0, 0, DELETEALL)
    counters: dict = {}
    for geom in info.geoms:
        ns = marker_ns(info, geom)
        mid = counters.get(ns, 0)
        counters[ns] = mid + 1
        mtype, scale, points = shape(geom)
        q = geom.quat_wxyz
        _marker(w, sec, nsec, frames[geom.body], ns, mid, mtype, ADD,
                (*geom.pos, q[1], q[2], q[3], q[0]), scale, geom.rgba, True, points)
    return bytes(w.buf)
