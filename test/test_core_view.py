"""
MuJoCo's viewer window on a session (a script's own world held by one), on a virtual display.

Each test opens the window on Xvfb (Debian's xvfb; skipped with the package's name where it is
missing) and reads the screen's pixels: the probe scene's red ball is drawn right of the top
camera's centre, where the scene puts it; what the window does (a drag, its closing) acts on
the simulation as the module :mod:`sim_node.view.window` says.
"""

from pathlib import Path
import time

import mujoco
import numpy as np
import pytest
from sim_node.core.config import WorldConfig
from sim_node.core.models import sources
from sim_node.core.world import World
from sim_node.session import Session
from sim_node.view.window import check_display, ViewerUnavailableError, Window

#: Front-ends that start an X server (Xvfb) and a window: in make test, not make test-fast.
pytestmark = pytest.mark.slow

PROBE = Path(__file__).resolve().parent / 'scenes' / 'view_probe.xml'


def held(world: World, **options) -> Window:
    """Open a window on a world its script steps, as a script does: a session holds the world."""
    session = Session(trim_memory=False)
    session.hold(world)
    return Window(session, **options)


def until(condition, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return False


def drawn(display, channel: int) -> tuple:
    """
    Find a pure colour (0 red, 1 green) in the window: (pixels, mean x in [-1, 1], aspect).

    The aspect is the window's width over its height.
    """
    img = display.grab().astype(int)
    inside = np.nonzero(img.sum(axis=2) > 30)  # the window; the screen around it is black
    if len(inside[0]) == 0:
        return 0, None, 1.0  # no window (yet)
    x0, x1 = inside[1].min(), inside[1].max()
    aspect = (x1 - x0 + 1) / (inside[0].max() - inside[0].min() + 1)
    others = [c for c in range(3) if c != channel]
    mask = (img[..., channel] > 120) & (img[..., others[0]] < 60) & (img[..., others[1]] < 60)
    ys, xs = np.nonzero(mask)
    if len(xs) < 50:
        return 0, None, aspect
    return len(xs), float((xs.mean() - (x0 + x1) / 2) / ((x1 - x0) / 2)), aspect


def test_no_display_is_one_clear_error(monkeypatch):
    monkeypatch.delenv('DISPLAY', raising=False)
    monkeypatch.delenv('WAYLAND_DISPLAY', raising=False)
    with pytest.raises(ViewerUnavailableError, match='xvfb-run'):
        check_display()
    with pytest.raises(ViewerUnavailableError), Session() as session:
        Window(session)


def test_a_world_you_step_shows_the_ball_where_the_scene_puts_it(display):
    world = World.from_file(str(PROBE))
    with held(world, show_ui=False, camera='top') as window:
        assert until(lambda: window.frames > 3)
        world.step(100)
        n, x, aspect = drawn(display, 0)
        # the ball's centre at x = 0.8 m, 2.8 m under a camera with 60 degrees of vertical
        # field of view: 0.8 / (2.8 tan 30 deg * aspect) of the half width, right of the centre
        assert n > 0 and x == pytest.approx(0.8 / (2.8 * np.tan(np.pi / 6) * aspect), abs=0.03)


def test_a_drag_pushes_the_body_and_letting_go_releases_it(display):
    world = World.from_file(str(PROBE))
    ball = world.read(lambda m, d: m.body('ball').id)
    with held(world, show_ui=False, camera='top') as window:
        assert until(lambda: window.frames > 3)
        pert = window.handle.perturb  # what MuJoCo's mouse handling sets on a Ctrl-drag
        pert.select, pert.localmass = ball, 1.0
        pert.refpos[:] = pert.refselpos[:] = (0.8, 1.0, 0.2)
        pert.localpos[:] = 0.0
        pert.active = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
        for _ in range(60):
            world.step(10)
            time.sleep(0.02)
        y = world.read(lambda m, d: float(d.xpos[ball][1]))
        assert 0.5 < y < 1.1  # pulled by the viewer's spring towards y = 1 m, not past it
        pert.active = 0
        assert until(lambda: not world.read(lambda m, d: d.xfrc_applied[ball].any()))
        # a kinematic check: nothing but the ball was told to move
        assert world.read(lambda m, d: d.xfrc_applied.any()) == 0


def test_a_session_shows_spawns_and_its_pause(display):
    with Session() as session:
        session.load_file(str(PROBE), WorldConfig(real_time_factor=1.0))
        with Window(session, show_ui=False, camera='top') as window:
            assert until(lambda: window.frames > 3)
            assert drawn(display, 1)[0] == 0
            box = sources.primitive('box', [0.2, 0.2, 0.2], rgba=[0, 1, 0, 1])
            session.world.spawn('box', box, position=[-0.8, 0.0, 0.2])
            assert until(lambda: len(window.reload_seconds) == 2)
            assert until(lambda: (drawn(display, 1)[1] or 0) < -0.2)
            session.pause()
            time.sleep(1.3)  # the measured real-time factor (over a second) has come to 0
            a, b = display.grab(), (time.sleep(0.5), display.grab())[1]
            assert (a == b).all()  # paused: the overlay's time stands still
            session.play()
            time.sleep(0.3)
            a, b = display.grab(), (time.sleep(0.5), display.grab())[1]
            assert (a != b).any()


def test_closing_the_window_leaves_the_simulation_running(display):
    closed = []
    with Session() as session:
        session.load_file(str(PROBE), WorldConfig(real_time_factor=1.0))
        window = Window(session, on_closed=lambda: closed.append(1))
        assert until(lambda: window.frames > 3)
        window.handle.close()  # what the window's close button does
        assert until(lambda: not window.is_open)
        t = session.world.time
        time.sleep(0.5)
        assert session.world.time > t + 0.3 and session.state == 'playing'
        assert closed == [1]
        window.close()


def test_the_default_scene_in_the_window_as_a_person_sees_it(display):
    """Show the default scene with MuJoCo's simulate panels: the README's picture."""
    default = Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml'
    with Session() as session:
        session.load_file(str(default), WorldConfig(real_time_factor=1.0))
        with Window(session) as window:
            assert until(lambda: window.frames > 10)
            img = display.grab()
            inside = img[:480, :853]
            # a drawn scene and panels: many colours, not a blank or one-colour window
            assert len(np.unique(inside.reshape(-1, 3) // 16, axis=0)) > 50
            save_picture(img[:480, :853], 'viewer_window.png')


def save_picture(img, name: str) -> None:
    """Keep a screenshot where SIM_SCREENSHOT_DIR says (the README's pictures), if it says."""
    import os
    folder = os.environ.get('SIM_SCREENSHOT_DIR')
    if folder:
        from PIL import Image
        Image.fromarray(img).save(Path(folder) / name)


def test_the_stepping_api_shows_its_world_in_real_time_until_the_window_closes(display):
    """The lab's ``C.view()``: a person sees the motion, not a jump, then scripts run free."""
    from sim_node.simulation import Simulation
    sim = Simulation.empty()
    sim.add_object('ball', 'sphere', [0.05], position=[0, 0, 1.0], mass=0.2)
    window = sim.view(show_ui=False)
    assert until(lambda: window.frames > 3)
    assert sim.paced
    t0 = time.monotonic()
    sim.step(dt=0.5)
    # Simulated time no faster than the clock: a lower bound, which a busy host only helps.
    assert time.monotonic() - t0 >= 0.45
    window.handle.close()  # the user closes it
    assert until(lambda: not window.is_open)
    sim.step(dt=2.0)
    # Free again: the step no longer waits for the clock (a behaviour, not a wall-clock bound
    # that a loaded machine could miss).
    assert not sim.paced and sim.time == pytest.approx(2.5, abs=1e-9)
    window.close()


def test_a_tutorial_takes_view(display):
    import subprocess
    import sys
    example = Path(__file__).resolve().parent.parent / 'examples' / 'block_gets_mass.py'
    t0 = time.monotonic()
    out = subprocess.run([sys.executable, str(example), '--view'], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    assert 'after 1 s without mass' in out.stdout
    assert time.monotonic() - t0 >= 2.0  # its 2 simulated seconds, watched in real time


def test_keys_and_mouse_in_the_window_act_on_the_session(display):
    """Space pauses and plays, the right arrow steps, a Ctrl right-drag pushes the ball."""
    import shutil
    import subprocess
    if not shutil.which('xdotool'):
        pytest.skip("needs Debian's xdotool to press keys and drag the mouse (make setup as "
                    'root installs it)')

    def xdo(*args):
        return subprocess.run(['xdotool', *map(str, args)], check=True, capture_output=True,
                              text=True).stdout
    with Session() as session:
        session.load_file(str(PROBE), WorldConfig(real_time_factor=1.0))
        with Window(session, show_ui=False, camera='top') as window:
            assert until(lambda: window.frames > 3)
            wid = xdo('search', '--name', 'MuJoCo').split()[-1]
            xdo('windowfocus', '--sync', wid)
            xdo('key', 'space')
            assert until(lambda: session.state == 'paused')
            steps = session.world.step_count
            xdo('key', 'Right')
            assert until(lambda: session.world.step_count == steps + 1)
            time.sleep(0.3)
            assert session.world.step_count == steps + 1  # one step, and paused still
            xdo('key', 'space')
            assert until(lambda: session.state == 'playing')
            # the ball is drawn right of the centre: double-click selects it, Ctrl and the
            # right button drag it (MuJoCo's simulate's gestures)
            _, x, aspect = drawn(display, 0)
            w, h = 480 * aspect, 480
            bx, by = int(w / 2 * (1 + x)), h // 2
            xdo('mousemove', '--window', wid, bx, by)
            xdo('click', '--repeat', '2', '--delay', '80', '1')
            ball = session.world.read(lambda m, d: m.body('ball').id)
            assert until(lambda: window.handle.perturb.select == ball)
            xdo('keydown', 'ctrl')
            xdo('mousedown', '3')
            try:
                for k in range(15):
                    xdo('mousemove', '--window', wid, bx, by - 6 * k)
                    time.sleep(0.03)
                assert until(lambda: session.world.read(
                    lambda m, d: np.abs(d.xfrc_applied[ball]).max()) > 1.0)
            finally:
                xdo('mouseup', '3')
                xdo('keyup', 'ctrl')
            assert until(lambda: not session.world.read(lambda m, d: d.xfrc_applied.any()))
