"""
The node's viewer window (``viewer:=true``), looked at on a virtual display, from outside.

A node on the probe scene (a red ball right of a top-down camera's centre) with MuJoCo's viewer
looking through that camera, side panels off: the ball is drawn where the scene puts it; a box
spawned over the standard service appears left of the centre; a pause set over the standard
service is what ``get_simulation_state`` says and what the window shows (its overlay stands
still). Without a display the node says so in one line and exits 2. Skipped, with the package
to install, where Debian's xvfb is missing.
"""

import os
from pathlib import Path
import time

from conftest import NodeProcess, serve_node, wait_for
import pytest
from simulation_interfaces.msg import SimulationState
from test_core_view import drawn

SCENES = Path(__file__).resolve().parent / 'scenes'
GREEN_BOX = ('<mujoco><worldbody><body><freejoint/><geom type="box" size="0.2 0.2 0.2" '
             'rgba="0 1 0 1"/></body></worldbody></mujoco>')


@pytest.fixture(scope='module')
def node(display):
    yield from serve_node(f'scene:={SCENES / "view_probe.xml"}',
                          f'resource_paths:=["{SCENES}"]', 'viewer:=true', 'viewer_ui:=false',
                          'view_camera:=top', 'real_time_factor:=1.0')


def test_without_a_display_the_node_says_so_in_one_line_and_exits_2(monkeypatch):
    monkeypatch.delenv('DISPLAY', raising=False)
    proc = NodeProcess('viewer:=true')
    try:
        assert proc.proc.wait(30) == 2
        lines = [ln for ln in proc.output().splitlines() if ln.startswith('[sim]')]
    finally:
        proc.close()
    assert len(lines) == 1 and 'needs a display' in lines[0] and 'xvfb-run' in lines[0]


def test_the_window_shows_the_world_its_spawns_and_its_pause(node, display, sim):
    assert wait_for(lambda: drawn(display, 0)[0] > 0, timeout=20)
    assert drawn(display, 0)[1] > 0.2  # the ball: right of the centre, as the scene has it
    assert drawn(display, 1)[0] == 0
    sim.spawn('box', resource_string=GREEN_BOX, position=(-0.8, 0.0, 0.3))
    assert wait_for(lambda: (drawn(display, 1)[1] or 0) < -0.2, timeout=10)
    sim.pause()
    assert sim.state() == SimulationState.STATE_PAUSED
    time.sleep(1.5)  # the overlay's measured real-time factor (over a second) has come to 0
    a, b = display.grab(), (time.sleep(0.5), display.grab())[1]
    assert (a == b).all()  # the window agrees: its time stands still
    sim.play()
    assert sim.state() == SimulationState.STATE_PLAYING
    a, b = display.grab(), (time.sleep(0.5), display.grab())[1]
    assert (a != b).any()
    assert os.environ['DISPLAY'] == display.name
