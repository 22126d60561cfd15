"""
MuJoCo's own viewer window on a live world, kept in step from a thread of its own. No ROS.

A :class:`Window` shows a :class:`~sim_node.session.Session` (it follows loads, spawns, deletes
and resets: the session tells it of each new model, which its thread copies and hands to the
open window); a script shows the world it steps itself through a session that holds it
(``session.hold(world)``; ``Simulation.view()`` does that). The window has its own copy of
the model and data: at :data:`FPS` its thread takes the world's lock only for ``mj_copyData``
(tens of microseconds on the default scene), so the physics never waits for drawing, and the
window's render thread never touches the world.

What the window does acts on the simulation through the world's own API, under its lock, like
a joint command: a body dragged with Ctrl and the right (force) or left (torque) mouse button
is pushed with the viewer's spring force (:meth:`World.push`), released when the mouse is;
the space bar pauses and plays the session (the overlay shows the pause that an API
call or a service made; the side panel's Pause/Run belongs to MuJoCo's passive viewer and does
not reach the simulation); the right arrow steps a paused one by one step.
An overlay (bottom left) shows the simulated time, the measured real-time factor, the state and
the number of entities. Closing the window leaves the simulation running.
"""

import atexit
import copy
import logging
import os
import threading
import time
from typing import Callable, Optional
import weakref

import mujoco

from .source import framing, RateMeter, Source
from ..core.base.errors import SimError

log = logging.getLogger(__name__)

#: How often the window is brought up to date from the world.
FPS = 30.0
#: GLFW's key codes of the keys the window acts on (its passive mode leaves them to us).
KEY_SPACE, KEY_RIGHT = 32, 262

ERR_NO_DISPLAY = ('the viewer needs a display, and {why}. Run it under a virtual one '
                  '(Debian package xvfb: xvfb-run -a make run ARGS="--ros-args -p '
                  'viewer:=true"), or watch in a browser instead (-p web_view:=8080)')


class ViewerUnavailableError(SimError):
    """No window can be opened here (no display); the message says what to do."""


def check_display() -> None:
    """
    Raise :class:`ViewerUnavailableError` unless a window can be opened on this machine.

    Checked before the viewer's own thread starts: MuJoCo's viewer waits forever for a window
    that GLFW failed to open.
    """
    if not os.environ.get('DISPLAY') and not os.environ.get('WAYLAND_DISPLAY'):
        raise ViewerUnavailableError(ERR_NO_DISPLAY.format(why='DISPLAY is not set'))
    import glfw
    if not glfw.init():
        raise ViewerUnavailableError(ERR_NO_DISPLAY.format(
            why=f'the display {os.environ.get("DISPLAY", "")!r} cannot be opened'))


_open: 'weakref.WeakSet[Window]' = weakref.WeakSet()


def close_all() -> None:
    """Close every window this process opened (before its display goes away)."""
    for window in list(_open):
        window.close()


class Window:
    """
    MuJoCo's viewer on a session (see the module docstring).

    :param session: the :class:`~sim_node.session.Session` to show.
    :param on_closed: called once, from the window's thread, when the user closes the window.
    :param show_ui: MuJoCo's side panels (off: the scene fills the window).
    :param camera: look through this camera of the model ('' or missing: the free camera).
    :raises ViewerUnavailableError: no display.
    """

    def __init__(self, session, on_closed: Optional[Callable[[], None]] = None,
                 fps: float = FPS, show_ui: bool = True, camera: str = ''):
        check_display()
        # Mesa's software renderer (no GPU) draws on every core by default, taking the
        # physics' core on a small machine: one thread is enough for a window (set it to
        # override; a GPU ignores it).
        os.environ.setdefault('LP_NUM_THREADS', '1')
        self._camera = camera
        self._source = Source(session)
        self._on_closed = on_closed
        self._period = 1.0 / float(fps)
        self._show_ui = bool(show_ui)
        self._stop = threading.Event()
        self._handle = None
        self._ui_threads: set = set()
        self._shown: tuple = (None, -1)  # (world, generation) in the window
        self._model: Optional[mujoco.MjModel] = None
        self._data: Optional[mujoco.MjData] = None
        self._toggles_asked = 0  # space bar presses not yet acted on
        self._steps_asked = 0
        self._pushed: Optional[tuple] = None  # (world, body) the mouse is pushing
        self._rate = RateMeter()
        #: Seconds each reload of a new model took (copy and hand-over), latest last.
        self.reload_seconds: list = []
        self.frames = 0
        self._thread = threading.Thread(target=self._run, name='sim-viewer', daemon=True)
        _open.add(self)
        self._thread.start()

    @property
    def handle(self):
        """
        Return MuJoCo's passive viewer handle once the window is open (None before).

        Its ``cam`` and ``perturb`` are what the mouse sets; scripts may set them too.
        """
        return self._handle

    @property
    def is_open(self) -> bool:
        """Whether the window is open (False once the user closed it or :meth:`close` ran)."""
        return self._thread.is_alive() and (self._handle is None or self._handle.is_running())

    def close(self) -> None:
        self._stop.set()
        self._source.close()
        if threading.current_thread() is not self._thread:  # on_closed may call it
            self._thread.join(5.0)
        if self._handle is not None:
            self._handle.close()
            for thread in self._ui_threads:
                thread.join(5.0)
        _open.discard(self)
        atexit.unregister(self.close)

    def __enter__(self) -> 'Window':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- the window's thread

    def _run(self) -> None:
        next_frame = time.monotonic()
        while not self._stop.is_set():
            try:
                if not self._frame():
                    break
            except Exception:  # noqa: B902 (a failed frame must not end the window)
                log.exception('the viewer failed to draw a frame; it goes on')
                self._stop.wait(0.5)
            next_frame += self._period
            self._stop.wait(max(0.0, next_frame - time.monotonic()))
            next_frame = max(next_frame, time.monotonic() - self._period)

    def _frame(self) -> bool:
        """Bring the window up to date; return False once it was closed by the user."""
        if self._handle is not None and not self._handle.is_running():
            self._release()
            if self._on_closed is not None:
                self._on_closed()
            return False
        world, loop = self._source.current()
        if world is None:
            return True
        if not self._copy(world):
            self._reload(world)
            if not self._copy(world):
                return True  # replaced again meanwhile: next frame
        self._act(world, loop)
        self._handle.sync()
        return True

    def _reload(self, world) -> None:
        """Copy the world's current model into the window (open it the first time)."""
        started = time.perf_counter()
        self._release()
        model, generation = world.observe(lambda m, d, gen: (_copy_model(m), gen))
        data = mujoco.MjData(model)
        opened = self._handle is None
        if opened:
            from mujoco import viewer  # here: it loads GLFW, which a node without one skips
            before = set(threading.enumerate())
            self._handle = viewer.launch_passive(
                model, data, key_callback=self._on_key, show_left_ui=self._show_ui,
                show_right_ui=self._show_ui)
            # MuJoCo's render thread: close() waits for it, so that nothing tears GLFW
            # down (a display that goes, the interpreter's exit) while it still draws.
            self._ui_threads = {t for t in set(threading.enumerate()) - before
                                if '_launch_internal' in t.name}
            # At exit, before MuJoCo's own handlers (registered at its launch, so run after
            # this one) terminate GLFW: a script that never closed its window ends cleanly.
            atexit.register(self.close)
        else:
            sim = self._handle._get_sim()  # the passive viewer's own reload (no public API)
            if sim is None:
                return
            sim.load(model, data, '')
        self._model, self._data = model, data
        self._shown = (world, generation)
        cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, self._camera) \
            if self._camera else -1
        if cam >= 0:
            self._handle.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            self._handle.cam.fixedcamid = cam
        elif opened:  # the first model: frame it (later ones keep the user's camera)
            free = self._handle.cam
            lookat, free.distance, free.azimuth, free.elevation = world.read(framing)
            free.lookat[:] = lookat
        self.reload_seconds.append(time.perf_counter() - started)

    def _copy(self, world) -> bool:
        """Copy the world's state into the window's data; False when its model changed."""
        if self._handle is None or self._shown[0] is not world:
            return False
        dest, shown = self._data, self._shown[1]

        def copy(m, d, generation):
            if generation != shown:
                return False
            mujoco.mj_copyData(dest, m, d)
            return True
        with self._handle.lock():  # not while the render thread reads it
            return world.observe(copy)

    def _act(self, world, loop) -> None:
        """Apply what the user did in the window; show the state and the overlay."""
        if loop is not None:
            while self._toggles_asked > 0:  # the space bar: pause or play
                self._toggles_asked -= 1
                self._source.set_paused(self._source.playing())
            while self._steps_asked > 0:
                self._steps_asked -= 1
                if not self._source.playing():
                    self._source.step()
        self._push(world)
        snap_time = float(self._data.time)
        rtf = self._rate.update(snap_time)
        entities = len(world.entities())
        self._handle.set_texts((
            mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_BOTTOMLEFT,
            'time\nreal-time factor\nstate\nentities',
            f'{snap_time:.3f} s\n{rtf}\n{self._source.state(loop)}\n{entities}'))
        self.frames += 1

    def _push(self, world) -> None:
        """Forward the viewer's mouse perturbation to the world as a force on the body."""
        pert = self._handle.perturb
        body = int(pert.select)
        if pert.active and body > 0 and _moves(self._model, body):
            data = self._data
            data.xfrc_applied[body] = 0.0
            mujoco.mjv_applyPerturbForce(self._model, data, pert)
            wrench = data.xfrc_applied[body].copy()
            name = self._model.body(body).name or body
            world.push(name, wrench[:3], wrench[3:])
            self._pushed = (world, name)
        else:
            self._release()

    def _release(self) -> None:
        if self._pushed is None:
            return
        world, name = self._pushed
        self._pushed = None
        try:
            world.push(name, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        except SimError:  # the body went with its entity, or the world was unloaded
            pass

    def _on_key(self, key: int) -> None:
        """Note a key pressed in the window (on MuJoCo's render thread: note it, no more)."""
        if key == KEY_RIGHT:
            self._steps_asked += 1
        elif key == KEY_SPACE:
            self._toggles_asked += 1


def _copy_model(m: mujoco.MjModel) -> mujoco.MjModel:
    return copy.copy(m)


def _moves(m: mujoco.MjModel, body: int) -> bool:
    """Whether a force on the body can move it (a joint on its chain to the world)."""
    while body > 0:
        if m.body_dofnum[body] > 0:
            return True
        body = int(m.body_parentid[body])
    return False
