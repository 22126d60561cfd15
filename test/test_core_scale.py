"""
Large worlds.

MuJoCo's arena sized by body count, and a loop that says when the physics cannot keep the requested
real-time factor.
"""

import logging
from pathlib import Path
import sys
import time

from conftest import DEFAULT_SCENE
import pytest
from sim_node.core.config import WorldConfig
from sim_node.core.loop import RATE_WINDOW_SEC, SimLoop
from sim_node.core.world import World

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'benchmarks'))
from box_scene import box_scene  # noqa: E402, I100


def arena_mb(w: World) -> float:
    with w.locked() as (m, d):
        return m.narena / 2 ** 20


def test_the_arena_grows_with_the_bodies_not_with_their_square(caplog):
    c = WorldConfig()
    w = World.from_string(box_scene(1000))
    expected = (c.arena_base_bytes + c.arena_bytes_per_body * 1001) / 2 ** 20  # + world
    assert arena_mb(w) == pytest.approx(expected)  # MuJoCo's own default: 1.7 GB
    with caplog.at_level(logging.WARNING):
        w.step(100)  # 4,000 contacts fit
    assert not [r for r in caplog.records if 'arena' in r.getMessage().lower()]
    from sim_node.core import sources
    w.spawn('more', sources.primitive('box', [0.05] * 3), position=[0, 0, 5])
    assert arena_mb(w) == pytest.approx(expected + c.arena_bytes_per_body / 2 ** 20)


def test_a_scene_that_sizes_its_arena_keeps_its_size():
    xml = box_scene(10).replace('<option', '<size memory="3M"/><option')
    assert arena_mb(World.from_string(xml)) == pytest.approx(3.0)


def test_the_loop_says_once_when_the_physics_cannot_keep_the_factor(caplog):
    w = World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=1000.0))
    loop = SimLoop(w)
    with caplog.at_level(logging.WARNING, logger='sim_node.core.loop'):
        loop.start()
        try:
            time.sleep(2.5 * RATE_WINDOW_SEC + 0.5)
            st = loop.status()
        finally:
            loop.stop()
    assert 0 < st.achieved_real_time_factor < 950
    assert 'cannot keep real_time_factor 1000' in st.lag
    lag_logs = [r for r in caplog.records if 'cannot keep' in r.getMessage()]
    assert len(lag_logs) == 1


def test_no_lag_is_reported_when_the_factor_is_kept():
    w = World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=1.0))
    loop = SimLoop(w)
    loop.start()
    try:
        time.sleep(RATE_WINDOW_SEC + 1.0)
        st = loop.status()
    finally:
        loop.stop()
    assert st.achieved_real_time_factor == pytest.approx(1.0, abs=0.02) and st.lag == ''
