"""
The Session: one owner of the loaded simulation, its lifecycle and its listeners, with no ROS.

The lifecycle's transitions and the refusals simulation_interfaces names are checked here at
core speed; the node's tests keep what needs the wire (the codes on it).
"""

import subprocess
import sys
import time

from conftest import DEFAULT_SCENE, ROOT, wait_for
import pytest
from sim_node import session as lifecycle
from sim_node.core.config import WorldConfig
from sim_node.core.errors import (AlreadyInStateError, IncorrectStateError,
                                  IncorrectTransitionError, NoWorldError, OperationFailedError,
                                  StateTransitionError)
from sim_node.core.models import sources
from sim_node.core.world import World
from sim_node.session import Session

FAST = WorldConfig(real_time_factor=0)


def box():
    return sources.primitive('box', [0.05] * 3, mass=0.5)


@pytest.fixture
def session():
    s = Session(trim_memory=False)
    yield s
    s.close()


def test_with_no_world_every_request_says_so(session):
    assert session.state == lifecycle.NO_WORLD
    for request in (session.play, session.pause, session.stop, lambda: session.step(1),
                    lambda: session.set_state(lifecycle.PLAYING), session.unload,
                    lambda: session.reset(255)):
        with pytest.raises(NoWorldError, match='no world is loaded'):
            request()
    assert session.state == lifecycle.NO_WORLD


def test_a_world_loaded_stopped_plays_pauses_steps_and_stops_as_the_standard_says(session):
    session.load_file(str(DEFAULT_SCENE), FAST, stopped=True)
    assert session.state == lifecycle.STOPPED and session.world.time == 0
    with pytest.raises(AlreadyInStateError):
        session.set_state(lifecycle.STOPPED)
    session.set_state(lifecycle.PLAYING)
    assert session.state == lifecycle.PLAYING
    with pytest.raises(AlreadyInStateError):
        session.set_state(lifecycle.PLAYING)
    with pytest.raises(OperationFailedError):  # the standard: stepping while playing is 4
        session.step(1)
    session.set_state(lifecycle.PAUSED)
    assert session.state == lifecycle.PAUSED
    t0, dt = session.world.time, session.world.timestep
    assert session.step(25) == 25
    assert session.world.time == pytest.approx(t0 + 25 * dt)
    session.world.spawn('crate', box(), position=[2, 0, 0.5])
    session.set_state(lifecycle.STOPPED)  # pause plus a full reset
    assert session.state == lifecycle.STOPPED
    assert session.world.time == 0 and session.world.spawned_names() == []


def test_stepping_from_stopped_leaves_it_paused(session):
    session.load_file(str(DEFAULT_SCENE), FAST, stopped=True)
    session.step(3)
    assert session.state == lifecycle.PAUSED and session.world.step_count == 3


@pytest.mark.parametrize('target', ['quitting', 'no_world', 'loading_world', 'dancing'])
def test_a_state_nobody_may_ask_for_is_an_incorrect_transition(session, target):
    session.load_file(str(DEFAULT_SCENE), FAST)
    with pytest.raises(IncorrectTransitionError):
        session.set_state(target)


def test_while_a_world_loads_no_state_may_be_set(session):
    session.load_file(str(DEFAULT_SCENE), FAST)
    with session.loading():
        assert session.state == lifecycle.LOADING_WORLD
        with pytest.raises(IncorrectTransitionError, match='loading'):
            session.set_state(lifecycle.PAUSED)
    assert session.state == lifecycle.PLAYING


def test_a_failed_loop_shows_stopped_until_a_stop_brings_it_back(session):
    loaded = session.load_file(str(DEFAULT_SCENE), FAST)
    real = loaded.world.stepping.batch

    def broken(*args, **kwargs):
        loaded.world.stepping.batch = real
        raise RuntimeError('injected fault')
    loaded.world.stepping.batch = broken
    wait_for(lambda: session.state_event().failed, timeout=5)
    assert session.state == lifecycle.STOPPED
    assert 'injected fault' in session.status_message()
    with pytest.raises(StateTransitionError, match='injected fault'):
        session.set_state(lifecycle.PLAYING)
    with pytest.raises(IncorrectStateError, match='injected fault'):
        session.step(10)  # nothing reports success while time stands still
    session.set_state(lifecycle.STOPPED)  # allowed although STOPPED: it recovers
    assert session.state == lifecycle.STOPPED and not session.state_event().failed
    session.set_state(lifecycle.PLAYING)
    t0 = session.world.time
    wait_for(lambda: session.world.time > t0 + 0.1, timeout=5)


def test_a_reset_keeps_playing_or_paused(session):
    session.load_file(str(DEFAULT_SCENE), FAST)
    session.pause()
    session.reset(255)
    assert session.state == lifecycle.PAUSED
    session.play()
    session.reset(1)
    assert session.state == lifecycle.PLAYING


def test_loading_another_world_stops_the_old_loop_and_unloading_leaves_no_world(session):
    first = session.load_file(str(DEFAULT_SCENE), FAST)
    second = session.load(World.from_file(str(DEFAULT_SCENE), FAST), 'again', '', stopped=True)
    assert not first.loop.running and second.loop.running
    assert session.loaded is second and session.state == lifecycle.STOPPED
    assert session.unload() is second
    assert not second.loop.running and session.state == lifecycle.NO_WORLD


def test_a_listener_sees_every_new_model_once(session):
    seen = []
    session.add_listener(lambda loaded, snap: seen.append(
        None if snap is None else (loaded.name, snap.info.generation,
                                   [e.name for e in snap.info.entities if e.spawned])))
    assert session.sync()
    session.load_file(str(DEFAULT_SCENE), FAST)
    assert session.sync()
    session.world.spawn('crate', box(), position=[2, 0, 0.5])
    assert session.sync()
    session.world.spawn('ball', box(), position=[-2, 0, 0.5])
    assert session.sync()
    session.world.delete('crate')
    assert session.sync()
    session.reset(4)  # the spawned entities go: a new model
    assert session.sync()
    session.reset(2)  # the state only: the same model
    session.load(World.from_file(str(DEFAULT_SCENE), FAST), 'second', '')
    assert session.sync()
    session.unload()
    assert session.sync()
    time.sleep(0.2)  # nothing more comes while nothing changes
    assert seen == [None, ('default', 0, []), ('default', 1, ['crate']),
                    ('default', 2, ['crate', 'ball']), ('default', 3, ['ball']),
                    ('default', 4, []), ('second', 0, []), None]


def test_a_late_listener_hears_the_current_model_and_the_others_nothing_twice(session):
    first, late = [], []
    session.add_listener(lambda loaded, snap: first.append(snap.info.generation))
    session.load_file(str(DEFAULT_SCENE), FAST)
    assert session.sync()
    session.add_listener(lambda loaded, snap: late.append(snap.info.generation))
    assert session.sync()
    assert first == [0] and late == [0]


def test_a_listener_that_fails_does_not_stop_the_others(session):
    calls = []

    def failing(loaded, snap):
        raise RuntimeError('listener bug')
    session.add_listener(failing)
    session.add_listener(lambda loaded, snap: calls.append(snap and snap.info.generation))
    session.load_file(str(DEFAULT_SCENE), FAST)
    assert session.sync()
    session.world.spawn('crate', box(), position=[2, 0, 0.5])
    assert session.sync()
    assert calls[-2:] == [0, 1]


def test_a_session_runs_and_notifies_with_no_rclpy_in_the_process():
    code = '\n'.join([
        'import sys',
        'from sim_node.session import Session',
        'from sim_node.core.config import WorldConfig',
        'from sim_node.core.models import sources',
        'seen = []',
        'with Session() as s:',
        '    s.add_listener(lambda loaded, snap: seen.append(snap and snap.info.generation))',
        f'    s.load_file({str(DEFAULT_SCENE)!r}, WorldConfig(real_time_factor=0))',
        "    s.world.spawn('crate', sources.primitive('box', [.05] * 3, mass=.5),",
        '                  position=[2, 0, .5])',
        '    assert s.sync()',
        '    s.pause(); s.step(10)',
        "    assert s.state == 'paused'",
        'print(seen, sorted(m for m in sys.modules if m.split(".")[0] == "rclpy"))',
    ])
    out = subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == '[None, 0, 1] []'


def test_step_inside_the_world_lock_is_refused_not_a_deadlock(session):
    session.load_file(str(DEFAULT_SCENE), FAST)
    session.pause()
    with session.world.locked():
        with pytest.raises(IncorrectStateError):
            session.step(1)


def test_a_held_world_is_stepped_by_its_owner_alone_and_its_listeners_follow_it(session):
    """What a window on a script's world sees: the script steps it, the session only shows it."""
    seen = []
    session.add_listener(lambda loaded, snap: seen.append(
        snap and (loaded.loop, [e.name for e in snap.info.entities if e.spawned])))
    world = World.from_file(str(DEFAULT_SCENE), FAST)
    assert session.hold(world, 'script').loop is None
    assert session.state == lifecycle.PLAYING and session.world is world
    for request in (session.pause, session.play, session.stop, lambda: session.step(1),
                    lambda: session.set_state(lifecycle.PAUSED)):
        with pytest.raises(IncorrectStateError, match='stepped by its owner'):
            request()
    world.step(10)
    time.sleep(0.2)  # nothing but its owner steps it
    assert world.step_count == 10
    world.spawn('crate', box(), position=[2, 0, 0.5])
    assert session.sync()
    assert seen[-1] == (None, ['crate'])
    session.load(World.from_file(str(DEFAULT_SCENE), FAST), 'looped')
    assert session.sync() and seen[-1][0] is session.loop and session.loop.running


def test_the_loop_reports_what_it_did_by_itself_and_the_session_decides():
    """A limit holds the loop at once; the session's state follows from the loop's report."""
    from sim_node.core.loop import LIMIT, SimLoop
    loop = SimLoop(World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=0,
                                                                   max_steps=50)))
    loop.start()
    try:
        wait_for(lambda: loop.held, timeout=10)
        assert loop.take_reports() == [(LIMIT, 'max_steps reached (50 steps)', None)]
        assert loop.take_reports() == []  # each report is decided on once
    finally:
        loop.stop()
    with Session(trim_memory=False) as session:
        events = []
        session.add_listener(on_state=events.append)
        session.load_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=0, max_steps=50))
        # Told, not asked: the listener hears of the limit with nobody asking for the state.
        wait_for(lambda: events and events[-1].cause == 'limit', timeout=10)
        assert events[-1].state == lifecycle.PAUSED and 'max_steps' in events[-1].reason
        assert session.loop.take_reports() == []  # the session took it when the loop told it
        session.loop.set_limits(max_steps=0)
        session.play()  # a play supersedes the pause reported before it
        time.sleep(0.2)
        assert session.state == lifecycle.PLAYING and not session.loop.held
        assert events[-1] == session.state_event() and events[-1].reason == ''


def test_the_lifecycle_is_one_table_that_every_change_of_state_goes_through():
    """Every state the session takes after a load comes from TRANSITIONS, in one method."""
    import ast
    import inspect
    tree = ast.parse(inspect.getsource(lifecycle))
    writers = {f.name for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)
               for n in ast.walk(f) if isinstance(n, ast.Attribute)
               and isinstance(n.ctx, ast.Store) and n.attr == '_state'}
    assert writers == {'__init__', '_go'}  # load, hold, unload and loading go through _go
    events = {event for _, event in lifecycle.TRANSITIONS}
    assert events >= {'load_stopped', 'load_paused', 'load_playing', 'hold', 'loading',
                      'load_failed', 'unload', 'play', 'pause', 'stop', 'step', 'reset',
                      'limit', 'diverged', 'failed'}
    targets = set(lifecycle.TRANSITIONS.values())
    assert targets == {lifecycle.PLAYING, lifecycle.PAUSED, lifecycle.STOPPED, lifecycle.FAILED,
                       lifecycle.NO_WORLD, lifecycle.LOADING_WORLD, lifecycle.BEFORE_LOADING}


def test_the_loop_keeps_no_lifecycle_of_its_own():
    """No state constants, no paused, failure or stop-reason flags: it holds, steps, reports."""
    import ast
    import inspect
    from sim_node.core import loop as loop_module
    for name in ('PLAYING', 'PAUSED', 'STOPPED'):
        assert not hasattr(loop_module, name), name
    tree = ast.parse(inspect.getsource(loop_module.SimLoop))
    stored = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)
              and isinstance(n.ctx, ast.Store)}
    assert not stored & {'_paused', '_failure', '_stop_reason', '_divergence', '_state'}
    assert 'state' not in set(loop_module.LoopStatus.__dataclass_fields__)


def test_after_a_stop_every_listener_hears_stopped(session):
    """The old bug: after Session.stop() the loop's own state said paused (/diagnostics)."""
    events = []
    session.add_listener(on_state=events.append)
    session.load_file(str(DEFAULT_SCENE), FAST)
    session.stop()
    wait_for(lambda: events and events[-1].cause == 'stop', timeout=5)
    assert [e.state for e in events] == [lifecycle.NO_WORLD, lifecycle.PLAYING,
                                         lifecycle.STOPPED]
    assert session.loop.status().held


def test_a_load_that_fails_goes_back_through_the_table(session):
    events = []
    session.load_file(str(DEFAULT_SCENE), FAST)
    session.pause()
    session.add_listener(on_state=events.append)
    with pytest.raises(RuntimeError):
        with session.loading():
            assert session.state == lifecycle.LOADING_WORLD
            raise RuntimeError('the file did not parse')
    assert session.state == lifecycle.PAUSED
    wait_for(lambda: len(events) == 3, timeout=5)
    assert [(e.state, e.cause) for e in events] == [
        (lifecycle.PAUSED, 'pause'), (lifecycle.LOADING_WORLD, 'loading'),
        (lifecycle.PAUSED, 'load_failed')]


def test_a_listener_that_blocks_holds_back_nobody_but_itself(session):
    """Each listener has a thread: one stuck in its hook delays neither the session nor others."""
    import threading
    stuck, models, states = threading.Event(), [], []
    session.add_listener(lambda loaded, snap: stuck.wait(30), lambda event: stuck.wait(30))
    session.add_listener(lambda loaded, snap: models.append(snap.info.generation),
                         states.append)
    try:
        session.load_file(str(DEFAULT_SCENE), FAST)
        session.world.spawn('crate', box(), position=[2, 0, 0.5])
        t0 = time.monotonic()
        session.pause()
        session.play()
        assert time.monotonic() - t0 < 1.0  # the session never waits for a listener
        wait_for(lambda: models and models[-1] == session.world.generation, timeout=5)
        wait_for(lambda: states and states[-1].cause == 'play', timeout=5)
    finally:
        stuck.set()


def test_the_front_ends_follow_on_state_and_never_ask_for_the_state_in_a_loop():
    """The window, the browser view and the node's status read no Session.state."""
    import ast
    for path in ('sim_node/view/source.py', 'sim_node/view/window.py', 'sim_node/view/web.py',
                 'sim_node/ros/node/status.py'):
        tree = ast.parse((ROOT / path).read_text())
        reads = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Attribute)
                 and n.attr == 'state' and isinstance(n.value, ast.Attribute)
                 and n.value.attr in ('session', '_session')]
        assert reads == [], (path, reads)


def test_a_view_takes_a_session_and_nothing_else(session):
    """The views' one kind of target: a world or a loop is shown through a session holding it."""
    from sim_node.view.source import OWNER_STEPPED, Source
    world = World.from_file(str(DEFAULT_SCENE), FAST)
    with pytest.raises(TypeError, match=r'Session\.hold\(world\)'):
        Source(world)
    session.hold(world)
    source = Source(session)
    try:
        assert source.current() == (world, None)
        assert source.state(None) == OWNER_STEPPED
    finally:
        source.close()
