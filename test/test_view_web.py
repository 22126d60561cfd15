"""
The browser view, looked at in headless Chromium: from Python (a session) and from the node.

The probe scene (a red ball right of a top-down camera's centre) served by ``viser`` on a free
local port, the page loaded with no network, a screenshot's pixels read: the ball is drawn
right of the centre, a box spawned while the page is open appears left of it. Skipped, with the
package to install, where Debian's chromium is missing.
"""

from pathlib import Path
import socket
import time

from conftest import wait_for
import headless_browser
from headless_browser import Browser, where
import numpy as np
import pytest
from sim_node.core.config import WorldConfig
from sim_node.core.models import sources
from sim_node.session import Session
from sim_node.view.web import WebView

#: Front-ends that start a browser (headless Chromium): in make test, not make test-fast.
pytestmark = pytest.mark.slow

SCENES = Path(__file__).resolve().parent / 'scenes'
GREEN_BOX = ('<mujoco><worldbody><body><freejoint/><geom type="box" size="0.2 0.2 0.2" '
             'rgba="0 1 0 1"/></body></worldbody></mujoco>')

needs_chromium = pytest.mark.skipif(
    not headless_browser.executable(),
    reason="needs Debian's chromium (sudo apt-get install chromium, or make setup as root)")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def seen(browser, channel: int, side: float) -> bool:
    n, x = where(browser.screenshot(), channel)
    return n > 0 and x * side > 0.1


@needs_chromium
def test_a_session_in_the_browser_shows_the_ball_and_a_spawned_box():
    with Session() as session:
        session.load_file(str(SCENES / 'view_probe.xml'), WorldConfig(real_time_factor=1.0))
        with WebView(session, port=free_port(), camera='top') as view, Browser() as browser:
            assert view.url.startswith('http://127.0.0.1:')
            browser.load(view.url)
            assert wait_for(lambda: seen(browser, 0, +1.0), timeout=30)
            assert where(browser.screenshot(), 1)[0] == 0
            session.world.spawn('box', sources.primitive('box', [0.2, 0.2, 0.2],
                                                         rgba=[0, 1, 0, 1]),
                                position=[-0.8, 0.0, 0.3])
            assert wait_for(lambda: seen(browser, 1, -1.0), timeout=15)
            session.world.delete('box')
            assert wait_for(lambda: where(browser.screenshot(), 1)[0] == 0, timeout=15)
            # the bodies move on the page as in the world: the ball, moved further right
            before = where(browser.screenshot(), 0)[1]
            session.world.set_entity_state('ball', position=[1.4, 0.0, 0.2])
            assert wait_for(lambda: where(browser.screenshot(), 0)[1] > before + 0.1,
                            timeout=15)


def test_the_view_starts_and_stops_without_writing_to_standard_output(capfd):
    with Session() as session:
        session.load_file(str(SCENES / 'view_probe.xml'))
        with WebView(session, port=free_port()) as view:
            assert wait_for(lambda: view.rebuilds >= 1, timeout=10)
    assert capfd.readouterr().out == ''  # a node's log, or a script's own output, stays its own


@needs_chromium
def test_a_view_a_person_turned_stays_turned_when_the_world_changes():
    with Session() as session:
        session.load_file(str(SCENES / 'view_probe.xml'), WorldConfig(real_time_factor=1.0))
        with WebView(session, port=free_port(), camera='top') as view, Browser() as browser:
            browser.load(view.url)
            assert wait_for(lambda: seen(browser, 0, +1.0), timeout=30)
            start = where(browser.screenshot(), 0)[1]
            browser.drag((480, 300), (440, 300))  # orbit: the ball moves across the page
            assert wait_for(lambda: abs(where(browser.screenshot(), 0)[1] - start) > 0.1,
                            timeout=10)
            time.sleep(1.0)  # the camera settles (camera-controls smooths its moves)
            turned = where(browser.screenshot(), 0)[1]
            session.world.spawn('box', sources.primitive('box', [0.1, 0.1, 0.1]),
                                position=[0.0, -1.5, 0.1])
            assert wait_for(lambda: view.rebuilds >= 2, timeout=10)
            time.sleep(1.5)
            assert where(browser.screenshot(), 0)[1] == pytest.approx(turned, abs=0.05)


@needs_chromium
def test_the_default_scene_in_the_browser_as_a_person_sees_it():
    """Show the default scene and the overlay panel in a browser: the README's picture."""
    from test_core_view import save_picture
    default = Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml'
    with Session() as session:
        session.load_file(str(default), WorldConfig(real_time_factor=1.0))
        with WebView(session, port=free_port()) as view, Browser() as browser:
            browser.load(view.url)
            assert wait_for(lambda: view.server.get_clients(), timeout=30)
            time.sleep(3)  # the page draws what it was sent
            img = browser.screenshot()
            assert len(np.unique(img.reshape(-1, 3) // 16, axis=0)) > 50
            save_picture(img, 'web_view.png')


@needs_chromium
def test_the_node_serves_the_live_world_to_a_browser(start_node, client):
    port = free_port()
    node = start_node(f'scene:={SCENES / "view_probe.xml"}', f'resource_paths:=["{SCENES}"]',
                      f'web_view:={port}', 'view_camera:=top')
    sim = client
    wait_for(lambda: sim.state(), timeout=30)  # the node is up, and so is its page
    with Browser() as browser:
        browser.load(f'http://127.0.0.1:{port}')
        assert wait_for(lambda: seen(browser, 0, +1.0), timeout=40), node.output()
        sim.spawn('box', resource_string=GREEN_BOX, position=(-0.8, 0.0, 0.3))
        assert wait_for(lambda: seen(browser, 1, -1.0), timeout=15)
    assert f'the browser view is at http://127.0.0.1:{port}' in node.output()


@needs_chromium
def test_a_recorded_run_replays_into_the_browser(tmp_path):
    """A node's bag (its markers and frames), played back with no ROS: the scene's boxes."""
    import os
    import subprocess
    import sys
    from conftest import NodeProcess
    node = NodeProcess(f'record:={tmp_path / "run"}', 'record_topics:=["/tf*", "/markers"]')
    try:
        wait_for(lambda: list((tmp_path / 'run').glob('*/*.mcap')), timeout=30)
        time.sleep(2.0)
        node.interrupt()
    finally:
        node.close()
    port = free_port()
    replay = subprocess.Popen([sys.executable, '-m', 'sim_node.record.replay', '--web',
                               str(port), '--hold', '60', str(tmp_path / 'run')],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              env=dict(os.environ))
    try:
        assert wait_for(lambda: replay.stdout.readline().startswith('replaying into'),
                        timeout=30)
        with Browser() as browser:
            browser.load(f'http://127.0.0.1:{port}')
            # the default scene's red and green boxes on the table, from the bag alone
            assert wait_for(lambda: where(browser.screenshot(), 0)[0] > 0, timeout=30)
            assert where(browser.screenshot(), 1)[0] > 0
    finally:
        replay.terminate()
        replay.wait(10)
