"""
A recorded run played back into the browser view, with no ROS: ``replay --web PORT <bag>``.

Reads a bag the node recorded (its ``/tf_static``, ``/tf`` and ``markers``: every geom as an
RViz marker locked to its body's frame) with ``rosbags``, and shows it with ``viser`` as the
live browser view shows a world: each TF frame a node of the page placed at its pose in the
world frame, each marker drawn in its frame, moved at the messages' simulated time (scaled by
``speed``). A new MarkerArray (a spawn or a delete in the run) replaces the drawn geoms.
"""

import time
from typing import Optional

from msg_adapters.markers import CUBE, CYLINDER, DELETEALL, SPHERE, TRIANGLE_LIST
import numpy as np

from ..core.base import quat as quat_maths

#: visualization_msgs/Marker's DELETE action (the node's markers write ADD and DELETEALL).
DELETE = 2
#: Most page updates per second of wall time.
FPS = 30.0


class Frames:
    """The TF tree as messages build it: each frame's pose in the root (world) frame."""

    def __init__(self):
        self._parent: dict = {}  # child -> (parent, position (3,), quaternion wxyz (4,))

    def update(self, tf_message) -> None:
        for t in tf_message.transforms:
            r, p = t.transform.rotation, t.transform.translation
            self._parent[t.child_frame_id] = (t.header.frame_id, np.array([p.x, p.y, p.z]),
                                              np.array([r.w, r.x, r.y, r.z]))

    def names(self) -> set:
        return set(self._parent) | {p for p, _, _ in self._parent.values()}

    def in_world(self, frame: str, depth: int = 0) -> tuple:
        """Return (position, wxyz) of `frame` in the tree's root; unknown frames at the root."""
        link = self._parent.get(frame)
        if link is None or depth > 64:
            return np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
        parent, pos, quat = link
        ppos, pquat = self.in_world(parent, depth + 1)
        return quat_maths.from_frame(ppos, pquat, pos, quat)


def _colour(marker) -> tuple:
    c = marker.color
    return tuple(int(round(255 * min(max(v, 0.0), 1.0))) for v in (c.r, c.g, c.b)), float(c.a)


def add_marker(scene, name: str, marker):
    """Draw one RViz marker (in its frame) as the browser view draws a geom; its handle."""
    rgb, alpha = _colour(marker)
    p, q, s = marker.pose.position, marker.pose.orientation, marker.scale
    common = {'position': (p.x, p.y, p.z), 'wxyz': (q.w, q.x, q.y, q.z),
              'opacity': alpha if alpha < 1.0 else None}
    if marker.type == CUBE:
        return scene.add_box(name, color=rgb, dimensions=(s.x, s.y, s.z), **common)
    if marker.type == SPHERE:
        return scene.add_icosphere(name, radius=0.5, color=rgb, scale=(s.x, s.y, s.z), **common)
    if marker.type == CYLINDER:
        return scene.add_cylinder(name, radius=0.5, height=1.0, color=rgb,
                                  scale=(s.x, s.y, s.z), **common)
    if marker.type == TRIANGLE_LIST and len(marker.points) >= 3:
        points = np.array([(v.x, v.y, v.z) for v in marker.points], dtype=np.float32)
        points = points[:len(points) // 3 * 3] * np.array([s.x, s.y, s.z], dtype=np.float32)
        faces = np.arange(len(points), dtype=np.uint32).reshape(-1, 3)
        return scene.add_mesh_simple(name, points, faces, color=rgb, flat_shading=True,
                                     **common)
    return None


class BagPlayer:
    """
    Play a node's recording into a browser page (see the module docstring).

    :param bags: the bag folders of one recording, in order (its splits).
    """

    def __init__(self, bags: list, port: int = 8080, host: str = '127.0.0.1',
                 speed: float = 1.0):
        import viser
        from rosbags.typesys import get_typestore, Stores
        self._bags, self._speed = list(bags), float(speed)
        self._store = get_typestore(Stores.ROS2_JAZZY)
        self.server = viser.ViserServer(host=host, port=int(port), verbose=False)
        self.url = f'http://{host}:{self.server.get_port()}'
        self._framed = False
        self._panel = self.server.gui.add_markdown('loading...')
        self.frames = Frames()
        self._nodes: dict = {}  # frame -> viser frame handle
        self._drawn: list = []  # marker handles of the current MarkerArray
        self._markers: Optional[object] = None  # the MarkerArray to draw at the next update
        self.shown = 0  # page updates made

    def _messages(self):
        from rosbags.rosbag2 import Reader
        for bag in self._bags:
            with Reader(bag) as reader:
                wanted = [c for c in reader.connections if c.msgtype in (
                    'tf2_msgs/msg/TFMessage', 'visualization_msgs/msg/MarkerArray')]
                for conn, stamp, data in reader.messages(connections=wanted):
                    yield conn.msgtype, stamp, self._store.deserialize_cdr(data, conn.msgtype)

    def play(self) -> float:
        """Play the recording once, in its simulated time; return its length (s)."""
        first, wall0, last_show = None, time.monotonic(), 0.0
        stamp = 0
        for msgtype, stamp, msg in self._messages():
            if first is None:
                first = stamp
            if msgtype == 'tf2_msgs/msg/TFMessage':
                self.frames.update(msg)
            else:
                self._markers = msg
            due = wall0 + (stamp - first) / 1e9 / self._speed
            now = time.monotonic()
            if now < due:
                time.sleep(due - now)
            if time.monotonic() - last_show >= 1.0 / FPS:
                self._show((stamp - first) / 1e9)
                last_show = time.monotonic()
        length = (stamp - first) / 1e9 if first is not None else 0.0
        self._show(length, ended=True)
        return length

    def _show(self, t: float, ended: bool = False) -> None:
        scene = self.server.scene
        with self.server.atomic():
            for name in sorted(self.frames.names() - set(self._nodes)):
                self._nodes[name] = scene.add_frame(f'/tf/f{len(self._nodes)}',
                                                    show_axes=False)
            if self._markers is not None:
                self._draw(self._markers)
                if not self._framed:
                    self._frame_camera(self._markers)
                self._markers = None
            for name, node in self._nodes.items():
                node.position, node.wxyz = self.frames.in_world(name)
        self._panel.content = (f'**replay** {t:.3f} s of simulated time'
                               + ('  \n**ended**' if ended else ''))
        self.shown += 1

    def _draw(self, array) -> None:
        for handle in self._drawn:
            handle.remove()
        self._drawn = []
        scene = self.server.scene
        for k, marker in enumerate(array.markers):
            if marker.action in (DELETE, DELETEALL):
                continue
            frame = marker.header.frame_id
            if frame not in self._nodes:
                self._nodes[frame] = scene.add_frame(f'/tf/f{len(self._nodes)}',
                                                     show_axes=False)
            parent = self._nodes[frame].name
            handle = add_marker(scene, f'{parent}/m{k}', marker)
            if handle is not None:
                self._drawn.append(handle)

    def _frame_camera(self, array) -> None:
        """Point the page's camera at what the markers draw, as the live view does."""
        from ..view.source import camera_position, framing_of
        centres, radii = [], []
        for marker in array.markers:
            s = marker.scale
            if marker.action in (DELETE, DELETEALL) or min(s.x, s.y, s.z) < 0.01:
                continue  # planes (a floor would frame nothing)
            pos, quat = self.frames.in_world(marker.header.frame_id)
            p = marker.pose.position
            centres.append(pos + quat_maths.rotate(quat, np.array([p.x, p.y, p.z])))
            radii.append(0.5 * float(np.linalg.norm([s.x, s.y, s.z])))
        lookat, *angles = framing_of(centres, radii)
        cam = self.server.initial_camera
        cam.position, cam.look_at, cam.up = camera_position(lookat, *angles), lookat, (0, 0, 1)
        cam.fov = np.radians(45.0)
        self._framed = True

    def close(self) -> None:
        self.server.stop()
