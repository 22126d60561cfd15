"""
The viewer window: what MuJoCo's viewer on the live world costs the physics.

A session on the default scene at real_time_factor 0 (as fast as it goes), ROS-free: simulated
steps per wall second without a window, then with MuJoCo's viewer open on it (synced at 30 Hz,
drawn by Mesa's software renderer on a virtual display), each over bare ``mj_step`` of the same
scene measured beside it in this process. Then what reloading the window's model costs when a
spawn changes it, and the same ratio with the browser view served (nobody watching, then a
headless Chromium on this machine watching).

    make bench-viewer
"""

from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'benchmarks'))
sys.path.insert(0, str(ROOT / 'test'))  # headless_browser: the tests' Chromium driver
from verdict import summary, verdict  # noqa: E402, I100

TARGET = 0.9  # steps per second with the viewer over without
SECONDS = 5.0
SCENE = ROOT / 'scenes' / 'default.xml'


def bare_steps_per_second() -> float:
    import mujoco
    m = mujoco.MjModel.from_xml_path(str(SCENE))
    d = mujoco.MjData(m)
    t0, n = time.perf_counter(), 0
    while time.perf_counter() - t0 < 2.0:
        mujoco.mj_step(m, d, 500)
        n += 500
    return n / (time.perf_counter() - t0)


def web_steps_per_second(browser: bool) -> float:
    """Measure steps per second with the browser view served (and a browser watching)."""
    from sim_node.core.config import WorldConfig
    from sim_node.session import Session
    from sim_node.view.web import WebView
    with Session() as session:
        session.load_file(str(SCENE), WorldConfig(real_time_factor=0.0))
        with WebView(session, port=8765) as view:
            page = None
            if browser:
                from headless_browser import Browser
                page = Browser()
                page.load(view.url)
            try:
                time.sleep(2.0)
                world = session.world
                s0, t0 = world.step_count, time.perf_counter()
                time.sleep(SECONDS)
                return (world.step_count - s0) / (time.perf_counter() - t0)
            finally:
                if page is not None:
                    page.close()


def loop_steps_per_second(viewer: bool) -> tuple:
    from sim_node.core.config import WorldConfig
    from sim_node.core.models import sources
    from sim_node.session import Session
    from sim_node.view.window import Window
    with Session() as session:
        session.load_file(str(SCENE), WorldConfig(real_time_factor=0.0))
        window = Window(session) if viewer else None
        try:
            time.sleep(2.0 if viewer else 0.5)  # the window opens, the loop warms up
            world = session.world
            s0, t0 = world.step_count, time.perf_counter()
            time.sleep(SECONDS)
            rate = (world.step_count - s0) / (time.perf_counter() - t0)
            reloads = []
            if window is not None:
                for i in range(3):
                    world.spawn(f'box{i}', sources.primitive('box', [0.1, 0.1, 0.1]),
                                position=[0.5 * i, 2.0, 0.5])
                    deadline = time.monotonic() + 10
                    while len(window.reload_seconds) < 2 + i and time.monotonic() < deadline:
                        time.sleep(0.01)
                reloads = window.reload_seconds[1:]
                print(f'  window frames drawn: {window.frames / (SECONDS + 2.0):.0f} per second')
        finally:
            if window is not None:
                window.close()
    return rate, reloads


def main() -> int:
    import os
    from sim_node.view.xvfb import VirtualDisplay
    display = None
    if not os.environ.get('DISPLAY'):
        if not VirtualDisplay.available():
            print('bench-viewer: no display and no Xvfb (sudo apt-get install xvfb)')
            return 1
        display = VirtualDisplay().start()
    try:
        rows = []
        for viewer in (False, True):
            bare = bare_steps_per_second()
            rate, reloads = loop_steps_per_second(viewer)
            rows.append((viewer, rate, bare, reloads))
            print(f'viewer {"on " if viewer else "off"}: {rate:9.0f} steps/s, bare mj_step '
                  f'{bare:9.0f}/s, ratio {rate / bare:.3f}')
        off, on = rows[0][1] / rows[0][2], rows[1][1] / rows[1][2]
        ratio = on / off
        reloads = rows[1][3]
        if reloads:
            print(f'reload of the window after a spawn: '
                  f'{", ".join(f"{r * 1000:.0f} ms" for r in reloads)}')
        verdict(ratio >= TARGET, f'viewer on over off, steps/s (each over bare mj_step): '
                f'{ratio:.2f}x (target >= {TARGET}x)')
        bare = bare_steps_per_second()
        served = web_steps_per_second(browser=False) / bare
        print(f'browser view served, nobody watching: ratio {served:.3f}')
        verdict(served / off >= TARGET, f'browser view served over off: {served / off:.2f}x '
                f'(target >= {TARGET}x)')
        import headless_browser
        if headless_browser.executable():
            bare = bare_steps_per_second()
            watched = web_steps_per_second(browser=True) / bare
            print(f'browser view, headless Chromium watching: ratio {watched:.3f}')
            verdict(watched / off >= TARGET, f'browser view watched by a browser on this '
                    f'machine over off: {watched / off:.2f}x (target >= {TARGET}x; the '
                    "browser's software WebGL shares this machine's cores)")
        summary()
    finally:
        if display is not None:
            display.stop()
    return 0


if __name__ == '__main__':
    sys.exit(main())
