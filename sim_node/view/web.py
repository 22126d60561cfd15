"""
The live world in a web browser, for machines without a display or without ROS. No ROS.

A :class:`WebView` serves a :class:`~sim_node.session.Session` (a script's own world through
``session.hold(world)``) with ``viser``
(its three.js client comes in its wheel: the page needs no network). Every visible geom of the
model (primitives with their sizes, meshes with their vertices, each in its colour) hangs from a
frame per body; a thread of its own moves those frames from the loop's snapshots at up to
:data:`FPS` (only the bodies that moved), and rebuilds the scene when the model changes (a load,
a spawn, a delete), so the physics never waits for it. A panel shows what the viewer window's
overlay shows: simulated time, the measured real-time factor, the state, the entities.

It listens on 127.0.0.1 unless told otherwise; another address lets other machines watch, which
:func:`serve` warns about.
"""

import contextlib
import io
import logging
import threading
import time
from typing import Optional

import numpy as np

from .source import camera_position, framing, RateMeter, Source
from ..core.base.errors import SimError

log = logging.getLogger(__name__)

#: Most frame updates per second sent to the browsers.
FPS = 30.0
#: Half the side of the square drawn for an infinite plane (MuJoCo's size 0).
PLANE_HALF_SIDE = 10.0
LOOPBACK = ('127.0.0.1', 'localhost', '::1')


class WebView:
    """
    Serve the live world to browsers at ``http://<host>:<port>`` (see the module docstring).

    :param camera: the page opens looking through this camera of the model ('': from above,
        at an angle).
    """

    def __init__(self, session, port: int = 8080, host: str = '127.0.0.1', camera: str = '',
                 fps: float = FPS):
        try:
            import viser
        except ImportError as exc:
            raise SimError('the browser view needs the viser package: pip install viser') \
                from exc
        self._source = Source(session)
        self._camera = camera
        self._period = 1.0 / float(fps)
        if host not in LOOPBACK:
            log.warning('the browser view listens on %s: every machine that reaches this one '
                        'can watch the simulation', host)
        with _quiet():
            self.server = viser.ViserServer(host=host, port=int(port), verbose=False)
        self.port = int(self.server.get_port())
        self.url = f'http://{host if ":" not in host else f"[{host}]"}:{self.port}'
        self._panel = self.server.gui.add_markdown('loading...')
        self._shown: tuple = (None, -1)
        self._frames: dict = {}  # body id -> frame handle
        self._sent: dict = {}  # body id -> (position, wxyz) last sent
        self._rate = RateMeter()
        self.rebuilds = 0
        self.updates = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim-web-view', daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._source.close()
        self._thread.join(5.0)
        with _quiet():
            self.server.stop()

    def __enter__(self) -> 'WebView':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- the view's thread

    def _run(self) -> None:
        while not self._stop.is_set():
            started = time.monotonic()
            try:
                self._frame()
            except Exception:  # noqa: B902 (a failed update must not end the view)
                log.exception('the browser view failed to update; it goes on')
                self._stop.wait(0.5)
            self._stop.wait(max(0.0, self._period - (time.monotonic() - started)))

    def _frame(self) -> None:
        world, loop = self._source.current()
        if world is None:
            if self._shown[0] is not None:
                self._clear()
                self._shown = (None, -1)
            self._panel.content = 'no world is loaded'
            return
        snap = loop.latest_snapshot() if loop is not None else world.snapshot()
        if (world, snap.generation) != self._shown:
            self._build(world, snap)
        self._move(snap)
        rtf = self._rate.update(snap.time)
        self._panel.content = (f'**time** {snap.time:.3f} s  \n**real-time factor** {rtf}  \n'
                               f'**state** {self._source.state(loop)}  \n'
                               f'**entities** {len(snap.info.entities)}')

    def _clear(self) -> None:
        for handle in self._frames.values():
            handle.remove()
        self._frames, self._sent = {}, {}

    def _build(self, world, snap) -> None:
        """Make the scene of a new model: a frame per body with geoms, the geoms under it."""
        scene = self.server.scene
        with self.server.atomic():
            self._clear()
            self.rebuilds += 1
            prefix = f'/sim{self.rebuilds}'  # names never collide with the last model's
            for i, geom in enumerate(snap.info.geoms):
                frame = self._frames.get(geom.body)
                if frame is None:
                    frame = scene.add_frame(f'{prefix}/b{geom.body}', show_axes=False)
                    self._frames[geom.body] = frame
                _add_geom(scene, f'{prefix}/b{geom.body}/g{i}', geom)
        new_world = world is not self._shown[0]
        self._shown = (world, snap.generation)
        self._look(world, new_world)

    def _look(self, world, new_world: bool) -> None:
        """
        Aim the page's camera, for who connects from now on (and who watches, at a new world).

        Browsers already watching are aimed only when the world itself is new: a spawn or a
        delete leaves a view a person turned alone.
        """
        pose = world.read(lambda m, d: _camera_pose(m, d, self._camera))
        if pose is None:  # as the viewer window frames it, with MuJoCo's free camera's fovy
            lookat, *angles = world.read(framing)
            position, look_at, up, fov = camera_position(lookat, *angles), lookat, (0, 0, 1), 45.0
        else:
            position, forward, up, fov = pose
            look_at = position + forward
        cam = self.server.initial_camera
        cam.position, cam.look_at, cam.up, cam.fov = position, look_at, up, np.radians(fov)
        for client in self.server.get_clients().values() if new_world else ():
            client.camera.position, client.camera.look_at = position, look_at
            client.camera.up_direction = up
            client.camera.fov = np.radians(fov)

    def _move(self, snap) -> None:
        moved = []
        for body, frame in self._frames.items():
            pos, quat = snap.body_xpos[body], snap.body_xquat_wxyz[body]
            last = self._sent.get(body)
            if last is not None and np.allclose(last[0], pos, atol=1e-5) \
                    and np.allclose(last[1], quat, atol=1e-6):
                continue
            moved.append((body, frame, pos.copy(), quat.copy()))
        if not moved:
            return
        with self.server.atomic():
            for body, frame, pos, quat in moved:
                frame.position, frame.wxyz = pos, quat
                self._sent[body] = (pos, quat)
        self.updates += 1


def _add_geom(scene, name: str, geom) -> None:
    """Add one geom (:class:`~sim_node.core.records.GeomVisual`) in its body's frame."""
    rgb = tuple(int(round(255 * min(max(c, 0.0), 1.0))) for c in geom.rgba[:3])
    alpha = float(geom.rgba[3])
    common = {'position': tuple(geom.pos), 'wxyz': tuple(geom.quat_wxyz),
              'opacity': alpha if alpha < 1.0 else None}
    sx, sy, sz = (float(v) for v in geom.size)
    kind = geom.type
    if kind == 'box':
        scene.add_box(name, color=rgb, dimensions=(2 * sx, 2 * sy, 2 * sz), **common)
    elif kind == 'sphere':
        scene.add_icosphere(name, radius=sx, color=rgb, **common)
    elif kind == 'ellipsoid':
        scene.add_icosphere(name, radius=1.0, color=rgb, scale=(sx, sy, sz), **common)
    elif kind == 'cylinder':
        scene.add_cylinder(name, radius=sx, height=2 * sy, color=rgb, **common)
    elif kind == 'capsule':
        import trimesh
        mesh = trimesh.creation.capsule(height=2 * sy, radius=sx, count=(16, 16))
        scene.add_mesh_simple(name, mesh.vertices, mesh.faces, color=rgb, **common)
    elif kind == 'plane':
        half_x, half_y = sx or PLANE_HALF_SIDE, sy or PLANE_HALF_SIDE
        scene.add_box(name, color=rgb, dimensions=(2 * half_x, 2 * half_y, 0.002), **common)
    elif kind == 'mesh' and geom.mesh_vertices is not None:
        scene.add_mesh_simple(name, np.asarray(geom.mesh_vertices, dtype=np.float32),
                              np.asarray(geom.mesh_faces, dtype=np.uint32), color=rgb,
                              flat_shading=True, **common)


def _camera_pose(m, d, name: str) -> Optional[tuple]:
    """Return (position, forward, up, fovy in degrees) of a named camera of the model."""
    import mujoco
    cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, name) if name else -1
    if cam < 0:
        return None
    rot = d.cam_xmat[cam].reshape(3, 3)  # columns: the camera's x, y (up), z (backwards)
    return d.cam_xpos[cam].copy(), -rot[:, 2].copy(), rot[:, 1].copy(), float(m.cam_fovy[cam])


def _quiet():
    """
    Keep viser's banners (a boxed table at start, a line at stop) off standard output.

    They are printed whatever ``verbose`` says (viser 1.1), in the middle of a node's log; the
    view logs its own address instead (:func:`serve`).
    """
    return contextlib.redirect_stdout(io.StringIO())


def serve(session, port: int, host: str = '127.0.0.1', camera: str = '') -> WebView:
    """Start a :class:`WebView`; log where to open it."""
    view = WebView(session, port=port, host=host, camera=camera)
    if view.port != int(port):
        log.warning('port %d was taken: the browser view is on %d instead', port, view.port)
    log.info('the browser view is at %s', view.url)
    return view
