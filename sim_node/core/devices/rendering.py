"""
Headless offscreen rendering: an OpenGL context and MuJoCo's renderer, colour and depth at once.

The backend is chosen once per process, on first use: ``MUJOCO_GL`` if it names ``egl`` or
``osmesa``, else EGL if its library is present (Mesa's software driver renders without a
display or GPU), else OSMesa, else :class:`RenderingUnavailableError` naming the Debian package
to install. MuJoCo's own context classes (``mujoco.egl``, ``mujoco.osmesa``, on PyOpenGL) do
the set-up.

A :class:`Renderer` belongs to the thread that made it (an OpenGL context is current on one
thread); nothing here touches the world: callers hand it :class:`mujoco.MjvScene` objects that
they filled under the world lock (see :meth:`~sim_node.core.world.World.observe`).
"""

import ctypes.util
import logging
import os
from typing import Optional

import mujoco
import numpy as np

from ..base import native
from ..base.errors import SimError

log = logging.getLogger(__name__)

#: The Debian packages that carry each backend's library (``apt-get install ...``).
BACKEND_PACKAGES = {'egl': 'libegl1 libgl1-mesa-dri', 'osmesa': 'libosmesa6'}
BACKEND_LIBRARIES = {'egl': 'EGL', 'osmesa': 'OSMesa'}
ERR_NO_BACKEND = ('no headless OpenGL backend: neither libEGL nor libOSMesa is installed; '
                  'install one (Debian/Ubuntu: apt-get install {egl} or {osmesa}) or set '
                  'MUJOCO_GL=egl|osmesa to say which one to use')
ERR_BACKEND_FAILED = ('the {backend} OpenGL backend failed to start ({error}); check that '
                      '{packages} are installed, or set MUJOCO_GL to another backend '
                      '(egl, osmesa)')
ERR_BAD_MUJOCO_GL = "MUJOCO_GL={value!r} cannot render headless here; use 'egl' or 'osmesa'"


class RenderingUnavailableError(SimError):
    """No OpenGL backend could be started; the message says what to install."""


_backend: Optional[str] = None


def choose_backend() -> str:
    """Return 'egl' or 'osmesa' (see the module's docstring); the choice holds per process."""
    global _backend
    if _backend is not None:
        return _backend
    wanted = os.environ.get('MUJOCO_GL', '').strip().lower()
    if wanted in BACKEND_LIBRARIES:
        chosen = wanted
    elif wanted not in ('', 'enable', 'enabled', 'on', 'true', '1'):
        raise RenderingUnavailableError(ERR_BAD_MUJOCO_GL.format(value=wanted))
    else:
        present = [b for b, lib in BACKEND_LIBRARIES.items() if ctypes.util.find_library(lib)]
        if not present:
            raise RenderingUnavailableError(ERR_NO_BACKEND.format(**BACKEND_PACKAGES))
        chosen = present[0]
    # PyOpenGL reads this once, when first imported.
    os.environ.setdefault('PYOPENGL_PLATFORM', chosen)
    _backend = chosen
    return chosen


def gl_context(width: int, height: int):
    """Return a started, current OpenGL context of the chosen backend."""
    backend = choose_backend()
    try:
        if backend == 'egl':
            from mujoco.egl import GLContext
        else:
            from mujoco.osmesa import GLContext
        ctx = GLContext(width, height)
        ctx.make_current()
    except Exception as exc:  # any failure of the driver stack: say what to do instead
        raise RenderingUnavailableError(ERR_BACKEND_FAILED.format(
            backend=backend, error=f'{type(exc).__name__}: {exc}',
            packages=BACKEND_PACKAGES[backend])) from exc
    log.info('rendering with %s', backend)
    return ctx


def depth_from_buffer(buffer: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """
    Turn MuJoCo's reversed-Z depth buffer into metres along the optical axis.

    Nothing hit (the far plane) is +inf, as REP 117 asks of range sensors.

    :param buffer: (h, w) float32 as ``mjr_readPixels`` gives it with ``mjDEPTH_ZEROFAR``.
    :returns: (h, w) float32.
    """
    extent = model.stat.extent
    znear = np.float32(model.vis.map.znear * extent)
    zfar = np.float32(model.vis.map.zfar * extent)
    # The projection of mujoco.Renderer, undone in float64 (as it does).
    c = -(zfar + znear) / (zfar - znear)
    d = -(np.float32(2) * zfar * znear) / (zfar - znear)
    c = np.float32(-0.5) * c - np.float32(0.5)
    d = np.float32(-0.5) * d
    z = buffer.astype(np.float64)
    with np.errstate(divide='ignore'):
        depth = d / (z + c)
    depth[z <= 0.0] = np.inf  # cleared to the far plane: no surface there
    return depth.astype(np.float32)


#: Model arrays an OpenGL context is made from (mjr_makeContext: meshes and their convex
#: hulls, height fields, textures and which material uses which, skins), compared whole.
_GL_ASSET_PREFIXES = ('mesh_', 'hfield_', 'tex_', 'skin_')
_GL_MATERIAL_FIELDS = ('mat_texid', 'mat_texrepeat', 'mat_texuniform')
_GL_QUALITY = ('shadowsize', 'offsamples', 'numslices', 'numstacks', 'numquads')


def same_gl_assets(old: Optional[mujoco.MjModel], new: mujoco.MjModel) -> bool:
    """
    Return True if an OpenGL context made for `old` draws `new` as one made for it would.

    Spawning and deleting bodies made of primitives changes nothing a context holds: its
    meshes, height fields, textures, skins, the grids of plane geoms (one per plane, sized by
    the plane, its material's texture repeat and, for infinite planes, the model's extent),
    built-in shapes and buffers (the visual quality settings, the offscreen size).
    """
    if old is None:
        return False
    q0, q1 = old.vis.quality, new.vis.quality
    g0, g1 = old.vis.global_, new.vis.global_
    if any(getattr(q0, k) != getattr(q1, k) for k in _GL_QUALITY) or (
            (g0.offwidth, g0.offheight) != (g1.offwidth, g1.offheight)):
        return False
    for name in _gl_array_names(new):
        if not np.array_equal(getattr(old, name), getattr(new, name)):
            return False
    planes0 = np.flatnonzero(old.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
    planes1 = np.flatnonzero(new.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
    if not (np.array_equal(planes0, planes1)
            and np.array_equal(old.geom_size[planes0], new.geom_size[planes1])
            and np.array_equal(old.geom_matid[planes0], new.geom_matid[planes1])):
        return False
    infinite = np.any(new.geom_size[planes1, :2] <= 0)
    return not infinite or (old.stat.extent * old.vis.map.zfar
                            == new.stat.extent * new.vis.map.zfar)


def _gl_array_names(model: mujoco.MjModel) -> list:
    names = _GL_ARRAY_NAMES.get(type(model))
    if names is None:
        names = _GL_ARRAY_NAMES[type(model)] = [
            k for k in dir(model) if k.startswith(_GL_ASSET_PREFIXES)
            or k in _GL_MATERIAL_FIELDS] + ['nmat']
    return names


_GL_ARRAY_NAMES: dict = {}


def _copy_visual_settings(model: mujoco.MjModel, con: mujoco.MjrContext) -> None:
    """Set what mjr_makeContext copies from the model's numbers (fog, shadows, lines)."""
    vis, extent = model.vis, model.stat.extent
    con.lineWidth = vis.global_.linewidth
    con.shadowClip = extent * vis.map.shadowclip
    con.shadowScale = vis.map.shadowscale
    con.fogStart = extent * vis.map.fogstart
    con.fogEnd = extent * vis.map.fogend
    con.fogRGBA[:] = vis.rgba.fog


def make_context(model: mujoco.MjModel, shadow_size: int, size: tuple) -> mujoco.MjrContext:
    """
    Make an OpenGL context for `model` (current on this thread) with the GIL released.

    MuJoCo's bindings hold the GIL while ``mjr_makeContext`` uploads a model's meshes and
    textures: 266 ms for the default scene with robosuite's GR1 (Mesa), and with it every
    other thread of the process stood still (the stepping loop: /clock stalled 100 to 290 ms
    after each spawn of a robot with meshes, ``make bench-spawn-clock``). Called through
    ctypes instead (:func:`~..base.native.make_context`), which lets the GIL go, on the struct
    an empty :class:`mujoco.MjrContext` holds (where its address cannot be found, the
    bindings make it).

    The context is made from the world's own model: the shadow map side and the offscreen size
    it needs are set on it for the call and set back (no physics reads them), so no copy of
    the model is taken (33 ms holding the GIL, under the world lock, for that world).

    The process's first context is a probe made by the bindings on an empty model with a
    one-pixel buffer (:func:`_probe_gl`), which raise what MuJoCo finds wrong (a GL that cannot
    make one) and hold the GIL for a few milliseconds; once one was made, GL can, and every
    context for a model (the first camera's included) goes without the GIL. Made through the
    bindings, the first camera's context of the default scene held every other thread 262 ms
    at 640 pixels and 491 ms at 2048 (Mesa); a probe first, 9 and 11 ms.

    :param shadow_size: side of the shadow map (0: the model's own); `size`: the least
        offscreen (width, height).
    """
    quality, frame = model.vis.quality, model.vis.global_
    saved = (quality.shadowsize, frame.offwidth, frame.offheight)
    if shadow_size > 0:
        quality.shadowsize = shadow_size
    frame.offwidth, frame.offheight = max(size[0], saved[1]), max(size[1], saved[2])
    try:
        if not _MADE:
            _probe_gl()
        con = native.make_context(model)
        if con is None:
            con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
        return con
    finally:
        quality.shadowsize, frame.offwidth, frame.offheight = saved


_MADE: list = []  # a context was made by the bindings in this process

#: The probe's model: nothing to upload, a one-pixel offscreen buffer, no shadow map.
_PROBE_XML = ('<mujoco><visual><global offwidth="1" offheight="1"/>'
              '<quality shadowsize="0"/></visual></mujoco>')


def _probe_gl() -> None:
    """Make and free a context through the bindings: they raise what MuJoCo finds wrong."""
    probe = mujoco.MjrContext(mujoco.MjModel.from_xml_string(_PROBE_XML),
                              mujoco.mjtFontScale.mjFONTSCALE_100)
    probe.free()
    _MADE.append(True)


class Renderer:
    """
    Renders prepared scenes of one model into colour and depth images.

    Make it, use it and close it on one thread. :meth:`use_model` uploads a model's meshes and
    textures (after every recompile); :meth:`render` draws one scene.
    """

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self._gl = gl_context(self.width, self.height)
        self._con: Optional[mujoco.MjrContext] = None
        self._model: Optional[mujoco.MjModel] = None
        #: GL contexts made so far: one per model whose meshes or textures changed.
        self.contexts_made = 0
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)

    def use_model(self, model: mujoco.MjModel, shadow_size: int = 0) -> None:
        """
        Upload `model`: the world's own (kept, read, never changed: see :func:`make_context`).

        :param model: the model of the scenes rendered from now on.
        :param shadow_size: side of the shadow map in texels; 0 keeps the model's own
            (``<visual><quality shadowsize>``, 4096 by default: a fifth of the frame rate of
            1024 with Mesa's software renderer).
        """
        self._gl.make_current()
        if self._con is not None and same_gl_assets(self._model, model):
            # Making a context takes 75 ms of this thread (the default scene, Mesa); made by
            # the bindings it held the GIL, and with it every other thread (the stepping loop:
            # a stalled /clock at every spawn); only the process's probe is made so now.
            # What it uploads did not change; only the numbers it copies from the model may.
            _copy_visual_settings(model, self._con)
            self._model = model
            return
        if self._con is not None:
            self._con.free()
        self._con = make_context(model, shadow_size, (self.width, self.height))
        self.contexts_made += 1
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        self._con.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self._model = model

    def render(self, scene: mujoco.MjvScene, depth: bool = True,
               size: Optional[tuple] = None) -> tuple:
        """
        Draw `scene`; return (rgb (h, w, 3) uint8, depth (h, w) float32 metres or None).

        Rows run from the top of the image down, as sensor_msgs/Image stores them.

        :param size: (width, height) of this image, at most the renderer's (a camera's own
            size, drawn in a corner of the offscreen buffer); None: the renderer's.
        """
        self._gl.make_current()
        width, height = size or (self.width, self.height)
        rect = self._rect if size is None else mujoco.MjrRect(0, 0, width, height)
        mujoco.mjr_render(rect, scene, self._con)
        rgb = np.empty((height, width, 3), dtype=np.uint8)
        raw = np.empty((height, width), dtype=np.float32) if depth else None
        mujoco.mjr_readPixels(rgb, raw, rect, self._con)
        rgb = np.ascontiguousarray(rgb[::-1])
        if raw is None:
            return rgb, None
        return rgb, np.ascontiguousarray(depth_from_buffer(raw, self._model)[::-1])

    def close(self) -> None:
        """Free the GL resources (on the thread that made them)."""
        if self._gl is None:
            return
        self._gl.make_current()
        if self._con is not None:
            self._con.free()
            self._con = None
        self._gl.free()
        self._gl = None
