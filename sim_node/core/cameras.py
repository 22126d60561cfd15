"""
Camera images of a running world: colour and depth from every selected camera, off the loop.

:class:`CameraRig` copies the world's data under the world lock (one MuJoCo call: 0.1 ms with
400 boxes), then fills one :class:`mujoco.MjvScene` per camera from the copy and draws them
with the lock released, so the stepping loop never waits for the scenes nor for OpenGL. The
renderer starts on the first capture that has a camera to draw: a world without cameras costs
nothing. Use a rig from one thread only.

Intrinsics are read off the frustum MuJoCo itself renders with (:func:`frustum_intrinsics`),
so cameras given by ``sensorsize``/``focal``/``principal`` come out as right as those given by
``fovy``. For ``fovy`` that is a symmetric frustum over the whole image with square pixels:
``fx = fy = (h / 2) / tan(fovy / 2)`` and the principal point is the image centre,
``((w - 1) / 2, (h - 1) / 2)`` in pixel-centre coordinates. The optical frame (REP 103: z
forward, x right, y down) is MuJoCo's camera frame (looking down -z, y up) turned half a turn
about x.
"""

from dataclasses import dataclass
import fnmatch
import logging
from typing import Optional, Sequence

import mujoco
import numpy as np

from .base import quat
from .base.records import CameraSpec
from .devices import catalog
from .devices.rendering import Renderer
from .world import World

log = logging.getLogger(__name__)

#: MuJoCo camera frame -> optical frame: half a turn about x (w, x, y, z).
OPTICAL_FROM_MUJOCO_WXYZ = (0.0, 1.0, 0.0, 0.0)


#: Room in a scene for MuJoCo's own decorations beyond the model's geoms.
DECOR_GEOMS = 1000

#: Tries at copying the world's data for one capture when new models keep coming meanwhile.
COPY_TRIES = 3


def _view_option() -> mujoco.MjvOption:
    """Return the render options of every view: sites are markers for people, not seen."""
    option = mujoco.MjvOption()
    option.sitegroup[:] = 0
    return option


def _new_scene(m: mujoco.MjModel) -> mujoco.MjvScene:
    return mujoco.MjvScene(m, maxgeom=m.ngeom + DECOR_GEOMS)


def frustum_intrinsics(glcam: mujoco.MjvGLCamera, width: int, height: int) -> tuple:
    """
    Return (fx, fy, cx, cy) in pixels of the frustum MuJoCo renders a camera with.

    ``mjr_render`` draws ``glFrustum(center - w, center + w, bottom, top, near, far)`` where
    ``w`` is the camera's ``frustum_width`` or, when that is 0 (fovy cameras), half the
    height times the viewport's aspect ratio. Pixel (u, v) has its centre at (u + 0.5,
    v + 0.5) from the top left corner of the image.
    """
    near, top, bottom = glcam.frustum_near, glcam.frustum_top, glcam.frustum_bottom
    half = glcam.frustum_width or 0.5 * (width / height) * (top - bottom)
    left = glcam.frustum_center - half
    fx = width * near / (2.0 * half)
    fy = height * near / (top - bottom)
    return fx, fy, -left * width / (2.0 * half) - 0.5, top * height / (top - bottom) - 0.5


def optical_pose(pos: Sequence[float], quat_wxyz: Sequence[float]) -> tuple:
    """Turn a MuJoCo camera pose (in any frame) into the pose of its optical frame."""
    return (np.array(pos, dtype=float),
            quat.mul(np.asarray(quat_wxyz, dtype=float), np.asarray(OPTICAL_FROM_MUJOCO_WXYZ)))


def select(cameras: Sequence[CameraSpec], patterns: Sequence[str]) -> tuple:
    """Return the perspective cameras whose names match one of `patterns` (``*``: all)."""
    return tuple(c for c in cameras if not c.orthographic
                 and any(fnmatch.fnmatchcase(c.name, p) for p in patterns if p))


@dataclass(frozen=True)
class CameraFrame:
    """
    One camera's image at one instant.

    :param rgb: (height, width, 3) uint8, top row first.
    :param depth: (height, width) float32 metres along the optical axis, +inf where nothing
        was hit; None when depth is off.
    :param pos: (3,) the camera's world position; `quat_wxyz` (4,) its optical frame's world
        orientation.
    :param intrinsics: (fx, fy, cx, cy) in pixels (:func:`frustum_intrinsics`).
    """

    camera: CameraSpec
    time: float
    generation: int
    rgb: np.ndarray
    depth: Optional[np.ndarray]
    pos: np.ndarray
    quat_wxyz: np.ndarray
    intrinsics: tuple = ()
    resets: int = 0  # the world's resets of state before it: stale once another comes


class CameraRig:
    """
    Renders the selected cameras of a world.

    :param patterns: camera names to render, shell-style (default all).
    :param depth: also read depth images.
    :param shadow_size: shadow map side in texels (1024 renders three times as fast as
        MuJoCo's default 4096 on a CPU); 0: no shadows.
    """

    def __init__(self, world: World, width: int = 320, height: int = 240,
                 patterns: Sequence[str] = ('*',), depth: bool = True,
                 shadow_size: int = 1024):
        self.world = world
        self.width, self.height = int(width), int(height)
        self.patterns = tuple(patterns)
        self.depth = bool(depth)
        self.shadow_size = int(shadow_size)
        self._renderer: Optional[Renderer] = None
        self._generation: Optional[int] = None
        self._cameras: tuple = ()
        self._scenes: list = []
        self._data: Optional[mujoco.MjData] = None  # the world's data copied, for the scenes
        self._model: Optional[mujoco.MjModel] = None
        self._last_model: Optional[mujoco.MjModel] = None  # to upload again to a new renderer
        self._sizes: dict = {}
        self._option = _view_option()

    @property
    def renderer_started(self) -> bool:
        return self._renderer is not None

    @property
    def contexts_made(self) -> int:
        """GL contexts made for this rig: a new model whose meshes or textures changed."""
        return 0 if self._renderer is None else self._renderer.contexts_made

    def cameras(self) -> tuple:
        """Return the selected cameras of the world's current model."""
        return select(self.world.model_info.cameras, self.patterns)

    def capture(self, only: Optional[Sequence[str]] = None,
                sizes: Optional[dict] = None, depth_for: Sequence[str] = ()) -> list:
        """
        Render every selected camera of the current state; returns [:class:`CameraFrame`].

        Empty (and no renderer started) when the world has no selected camera.

        :param only: the names of the cameras to render now (None: all selected).
        :param sizes: camera name -> (width, height) of its own (a robot file declares it);
            the rig's size for the others.
        :param depth_for: cameras that read depth even when the rig does not (declared depth
            cameras).
        """
        self._sizes = dict(sizes or {})
        frames = self._fill_scenes()
        picked = [(f, s) for f, s in zip(frames, self._scenes)
                  if only is None or f[0].name in only]
        if not picked:
            return []
        need = (max([self.width] + [w for w, _ in self._sizes.values()]),
                max([self.height] + [h for _, h in self._sizes.values()]))
        if self._renderer is not None and (self._renderer.width < need[0]
                                           or self._renderer.height < need[1]):
            self._renderer.close()  # a larger camera came: a buffer that holds it
            self._renderer, self._model = None, self._last_model
        if self._renderer is None:
            self._renderer = Renderer(*need)
        if self._model is not None:
            self._renderer.use_model(self._model, self.shadow_size)
            self._model = None
        out = []
        for (cam, sim_time, generation, pos, q, k, resets), scene in picked:
            size = self._sizes.get(cam.name, (self.width, self.height))
            rgb, depth = self._renderer.render(scene, self.depth or cam.name in depth_for,
                                               size)
            out.append(CameraFrame(camera=cam, time=sim_time, generation=generation, rgb=rgb,
                                   depth=depth, pos=pos, quat_wxyz=q, intrinsics=k,
                                   resets=resets))
        return out

    def _fill_scenes(self) -> list:
        """
        Copy what each camera sees into its scene: one MuJoCo call under the world lock.

        Under a storm of requests every MuJoCo call gives the GIL away and waits for it back,
        so filling the scenes under the lock (poses brought up to date, then a scene update
        per camera) held the loop off for up to 157 ms (docs/benchmarks.md). The world's data
        is copied instead, and the poses and scenes are worked out on the copy, holding no
        lock; a new model's scenes and copy are made before the lock is taken.
        """
        for _ in range(COPY_TRIES):
            m, generation = self.world.live_model()
            if generation != self._generation:
                self._new_model(m, generation)
            if not self._cameras:
                return []
            copied = self.world.copy_data(m, self._data)
            if copied is not None:
                break
        else:  # models came faster than a copy could be made: no frame this time
            return []
        generation, resets = copied
        d = self._data
        mujoco.mj_kinematics(m, d)  # the copy's poses were a step behind its state
        mujoco.mj_comPos(m, d)  # cameras that track a centre of mass need it
        if m.nflex:
            mujoco.mj_flex(m, d)
        mujoco.mj_camlight(m, d)
        out = []
        for cam, scene in zip(self._cameras, self._scenes):
            view = mujoco.MjvCamera()
            view.type = mujoco.mjtCamera.mjCAMERA_FIXED
            view.fixedcamid = cam.cam_id
            mujoco.mjv_updateScene(m, d, self._option, None, view,
                                   mujoco.mjtCatBit.mjCAT_ALL, scene)
            pos, q = optical_pose(d.cam_xpos[cam.cam_id],
                                  quat.from_matrix(d.cam_xmat[cam.cam_id]))
            k = frustum_intrinsics(scene.camera[0],
                                   *self._sizes.get(cam.name, (self.width, self.height)))
            out.append((cam, float(d.time), generation, pos, q, k, resets))
        return out

    def _new_model(self, m: mujoco.MjModel, generation: int) -> None:
        """Index a new model's cameras; make their scenes and the data to copy into."""
        self._generation = generation
        # Index the live model: the published model info may lag a recompile.
        self._cameras = select(catalog.cameras(m), self.patterns)
        if not self._cameras:
            self._scenes, self._data = [], None
            return
        # The renderer uploads it on its next frame; models are replaced, never changed in
        # place, by edits (a copy held the lock 33 ms with a humanoid spawned).
        self._model = self._last_model = m
        self._data = mujoco.MjData(m)
        self._scenes = [_new_scene(m) for _ in self._cameras]
        for scene in self._scenes:
            # The skybox is drawn as a surface some 50 m away: depth would read it as one.
            # Without it, nothing there reads +inf (and the sky is black).
            scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = 0
            if self.shadow_size <= 0:
                scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0

    def close(self) -> None:
        """Free the renderer (call from the thread that captured)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


#: The free camera of :func:`picture`: a three-quarter view from above (degrees), at this many
#: model extents (MuJoCo's ``stat.extent``) from the model's centre.
FREE_AZIMUTH_DEG = 150.0
FREE_ELEVATION_DEG = -25.0
FREE_DISTANCE_EXTENTS = 1.1
ERR_NO_CAMERA = 'no camera named {name!r}; cameras: {names}'


class View:
    """
    Pictures of one world from one camera, again and again (a Gym env's ``render``).

    The renderer starts here, so a missing OpenGL backend is reported when the view is made,
    not at the first frame; the model is uploaded again after each recompile. Use a view from
    the thread that made it.

    :param camera: a camera of the model, or '' for a free camera that looks at the whole
        model from the front left, above.
    :raises NotFoundError: no camera of that name.
    :raises RenderingUnavailableError: no OpenGL backend (the message says what to install).
    """

    def __init__(self, world: World, camera: str = '', width: int = 640, height: int = 480):
        self.world, self.camera = world, camera
        self._option = _view_option()
        self._generation: Optional[int] = None
        self._scene: Optional[mujoco.MjvScene] = None
        self._view = mujoco.MjvCamera()
        self._model: Optional[mujoco.MjModel] = None
        world.observe(self._fill)  # an unknown camera is refused before the renderer starts
        self._renderer = Renderer(width, height)

    def _fill(self, m: mujoco.MjModel, d: mujoco.MjData, generation: int) -> None:
        from .base.errors import NotFoundError
        if generation != self._generation:
            view = mujoco.MjvCamera()
            if self.camera:
                cid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, self.camera)
                if cid < 0:
                    raise NotFoundError(ERR_NO_CAMERA.format(
                        name=self.camera, names=[c.name for c in catalog.cameras(m)]))
                view.type, view.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, cid
            else:
                mujoco.mjv_defaultFreeCamera(m, view)
                view.azimuth, view.elevation = FREE_AZIMUTH_DEG, FREE_ELEVATION_DEG
                view.distance = FREE_DISTANCE_EXTENTS * m.stat.extent
            self._generation, self._view = generation, view
            self._scene, self._model = _new_scene(m), m
        mujoco.mjv_updateScene(m, d, self._option, None, self._view,
                               mujoco.mjtCatBit.mjCAT_ALL, self._scene)

    def render(self, depth: bool = False) -> np.ndarray:
        """
        Return the current state seen from the camera.

        (height, width, 3) uint8 colour, or with `depth` (height, width) float32 metres along
        the optical axis (+inf where nothing was hit).
        """
        self.world.observe(self._fill)
        if self._model is not None:
            self._renderer.use_model(self._model)
            self._model = None
        rgb, metres = self._renderer.render(self._scene, depth)
        return metres if depth else rgb

    def close(self) -> None:
        """Free the renderer (from the thread that made the view)."""
        self._renderer.close()


def picture(world: World, camera: str = '', width: int = 640, height: int = 480) -> np.ndarray:
    """
    Render one picture of the world's current state; returns (height, width, 3) uint8.

    :param camera: a camera of the model, or '' for a free camera that looks at the whole
        model from the front left, above.
    :raises NotFoundError: no camera of that name.
    """
    view = View(world, camera, width, height)
    try:
        return view.render()
    finally:
        view.close()
