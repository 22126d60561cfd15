"""
The stepping loop: holding costs nothing, step N while held, limits, divergence, pacing.

The loop keeps no lifecycle: it holds and reports what it did by itself (a limit, a divergence,
a failure); the Session's tests (test_session.py) show what the simulation's state makes of it.
"""

import subprocess
import sys
import textwrap
import threading
import time

from conftest import DEFAULT_SCENE
import pytest
from sim_node.core.config import WorldConfig
from sim_node.core.errors import IncorrectStateError
from sim_node.core.loop import DIVERGED, DIVERGED_ON, FAILED, LIMIT, SimLoop
from sim_node.core.world import World


@pytest.fixture
def make_loop():
    loops = []

    def make(**cfg):
        w = World.from_file(str(DEFAULT_SCENE), WorldConfig(**cfg))
        loop = SimLoop(w)
        loop.start()
        loops.append(loop)
        return loop
    yield make
    for lp in loops:
        lp.stop()


def test_step_n_while_paused_advances_exactly_n_steps(make_loop):
    loop = make_loop(paused=True)
    t0 = loop.world.time
    assert loop.step(250) == 250
    assert loop.world.time == pytest.approx(t0 + 250 * loop.world.timestep, abs=1e-12)
    assert loop.latest_snapshot().time == loop.world.time


def test_step_while_playing_is_refused(make_loop):
    loop = make_loop(real_time_factor=1.0)
    with pytest.raises(IncorrectStateError):
        loop.step(1)


def test_paused_loop_uses_no_cpu(make_loop):
    make_loop(paused=True)
    time.sleep(0.1)
    p0 = time.process_time()
    time.sleep(0.5)
    assert time.process_time() - p0 < 0.05


def test_max_steps_stops_the_loop_and_says_why(make_loop):
    woken = threading.Event()
    loop = make_loop(real_time_factor=0, max_steps=3000)
    loop.on_report = woken.set
    assert woken.wait(20)  # its owner is told at once, not left to ask
    assert loop.status().held and loop.world.step_count == 3000
    [report] = loop.take_reports()
    assert report.kind == LIMIT and 'max_steps' in report.reason
    assert loop.take_reports() == []  # each report is decided on once


def test_after_a_reset_max_steps_counts_again_from_zero(make_loop):
    """The loop reads the world afresh after a pause: not the step count it paused at."""
    loop = make_loop(real_time_factor=0, max_steps=3000)
    assert _wait(lambda: loop.held)
    loop.world.reset()
    time.sleep(0.1)  # the loop waits, held, with the world back at step 0
    loop.run()
    assert _wait(lambda: loop.held and loop.world.step_count > 0)
    assert loop.world.step_count == 3000, loop.take_reports()


def test_max_sim_time_stops_the_loop(make_loop):
    loop = make_loop(real_time_factor=0, max_sim_time=1.5)
    assert _wait(lambda: loop.held, 20)
    assert loop.world.time == pytest.approx(1.5, abs=1e-9)
    assert 'max_sim_time' in loop.take_reports()[-1].reason


def test_real_time_factor_paces_simulated_time(make_loop):
    """
    A factor of 2 never runs past twice the clock; it runs.

    An upper bound only: a busy host can only make the loop slower, so this cannot fail for
    want of CPU. How close it comes to the factor is make bench-pacing's verdict.
    """
    loop = make_loop(real_time_factor=2.0)
    time.sleep(0.2)
    s0, w0 = loop.world.time, time.monotonic()
    time.sleep(1.0)
    simulated, wall = loop.world.time - s0, time.monotonic() - w0
    assert 0 < simulated <= 2.0 * wall + 0.05


def test_divergence_holds_the_loop_with_a_report(make_loop):
    loop = make_loop(real_time_factor=0)
    with loop.world.locked() as (m, d):
        d.qvel[-1] = 1e12
    assert _wait(lambda: loop.held)
    [report] = loop.take_reports()
    assert report.kind == DIVERGED and report.divergence['step'] >= 1
    assert 'diverged' in report.reason
    loop.run()  # the restored state is good: it runs again
    time.sleep(0.1)
    assert not loop.held


# A slide joint far too stiff for the time step: it diverges within a few steps, every time.
STIFF = """<mujoco><worldbody><body name="spring"><joint name="s" type="slide" axis="0 0 1"
  stiffness="1e9"/><geom type="box" size=".05 .05 .05" mass=".01" contype="0" conaffinity="0"/>
  </body></worldbody></mujoco>"""


def _wait(predicate, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.01)
    return predicate()


@pytest.mark.parametrize('policy', ['pause', 'remove', 'reset'])
def test_divergence_names_the_culprit_entity_and_the_policy_acts_on_it(make_loop, policy):
    from sim_node.core.models import sources
    loop = make_loop(real_time_factor=0, divergence_policy=policy)
    loop.world.spawn('stiff', sources.from_model_text(STIFF), position=[2, 2, 1])
    reports = []
    assert _wait(lambda: reports.extend(loop.take_reports()) or reports)
    report = reports[0]
    assert report.divergence['entity'] == 'stiff' and "'stiff'" in report.reason
    assert report.divergence['action'] == policy
    if policy == 'pause':
        assert report.kind == DIVERGED
        assert loop.held and 'stiff' in loop.world.spawned_names()
        return
    assert report.kind == DIVERGED_ON
    assert not loop.held  # it played on (with 'reset' the spring diverges again and again,
    t0 = loop.world.time  # a few steps apart: time still moves)
    assert _wait(lambda: loop.world.time > t0 + 0.05)
    if policy == 'remove':
        assert 'stiff' not in loop.world.spawned_names()


def test_the_remove_policy_pauses_when_the_culprit_belongs_to_the_scene(make_loop):
    loop = make_loop(real_time_factor=0, divergence_policy='remove')
    with loop.world.locked() as (m, d):
        d.qvel[-1] = 1e12  # box_b, part of the scene: it cannot be removed
    assert _wait(lambda: loop.held)
    [report] = loop.take_reports()
    assert report.divergence['entity'] == 'box_b'
    assert report.kind == DIVERGED and report.divergence['action'] == 'pause'


def test_commands_from_many_threads_while_the_loop_runs(make_loop):
    import threading
    loop = make_loop(real_time_factor=0)
    errors = []

    def send(k):
        try:
            for i in range(300):
                loop.world.command(['left_elbow'], [0.1 * (i % 5)], 'position')
                loop.world.get_entity_state('box_a')
        except Exception as exc:  # noqa: B902
            errors.append(exc)
    threads = [threading.Thread(target=send, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert not errors
    assert not loop.held and loop.take_reports() == []


@pytest.mark.slow  # a 1 s stall
def test_pacing_resyncs_after_a_stall_instead_of_bursting(make_loop):
    """The second the loop could not step is not made up: simulated time stays behind."""
    loop = make_loop(real_time_factor=1.0)
    time.sleep(0.2)
    with loop.world.locked():
        t_stall, w_stall = loop.world.time, time.monotonic()
        time.sleep(1.0)  # the loop cannot step for 1 s
    time.sleep(0.3)
    behind = (time.monotonic() - w_stall) - (loop.world.time - t_stall)
    # Catching up would bring simulated time back to the clock; re-syncing leaves it about a
    # second behind (a busy host leaves it further behind, never less). make bench-pacing
    # measures the re-synced rate.
    assert behind > 0.6, f'burst: only {behind:.2f} s behind the clock after a 1 s stall'


def test_a_failed_loop_holds_and_reports_why(make_loop):
    """
    An injected fault in the stepping loop.

    The loop holds (time stands still) and reports the fault; whether play and step are refused
    is its owner's decision (the Session refuses them until a stop or a reset:
    test_session.py), so its owner may run it again.
    """
    loop = make_loop(real_time_factor=0)
    world = loop.world
    real_step = world.stepping.batch

    def broken(*args, **kwargs):
        world.stepping.batch = real_step
        raise RuntimeError('injected fault')
    world.stepping.batch = broken
    reports = []
    assert _wait(lambda: reports.extend(loop.take_reports()) or reports, 5)
    assert reports[0].kind == FAILED and 'injected fault' in reports[0].reason
    assert loop.status().held
    t0 = world.time
    time.sleep(0.2)
    assert world.time == t0
    world.reset()
    assert loop.step(10) == 10 and world.step_count == 10
    loop.run()
    time.sleep(0.2)
    assert world.step_count > 10


def test_an_endless_step_request_is_ended_by_a_state_request(make_loop):
    loop = make_loop(paused=True)
    outcome = []

    def endless():
        try:
            loop.step(2 ** 63 - 1)
        except IncorrectStateError as exc:
            outcome.append(str(exc))
    t = threading.Thread(target=endless)
    t.start()
    time.sleep(0.3)
    assert loop.world.step_count > 0
    loop.hold()  # already held: the request still ends
    t.join(2)
    assert not t.is_alive() and 'ended by a state request' in outcome[0]
    assert loop.step(10) == 10  # no "another step request is still running"


# ---- the lock order (docs/threading.md): world lock before the loop's, never the reverse
#
# A deadlock cannot be undone from inside the process (and the loop's atexit stop would wait
# on it too), so these run in a subprocess that must end within 30 s.

def _ends_in_a_subprocess(body: str) -> None:
    code = textwrap.dedent(f"""
        import threading, time
        from sim_node.core.config import WorldConfig
        from sim_node.core.loop import SimLoop
        from sim_node.core.world import World
        {textwrap.indent(textwrap.dedent(body), ' ' * 8).strip()}
        print('done')
    """)
    try:
        out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                             timeout=30, cwd=str(DEFAULT_SCENE.parent.parent))
    except subprocess.TimeoutExpired:
        pytest.fail('deadlock: the threads never finished')
    assert out.returncode == 0 and out.stdout.strip() == 'done', out.stderr


def test_loop_methods_called_inside_world_locked_do_not_deadlock():
    _ends_in_a_subprocess(f"""
        loop = SimLoop(World.from_file({str(DEFAULT_SCENE)!r}, WorldConfig(real_time_factor=1.0)))
        loop.start()
        w = loop.world
        for _ in range(10):
            with w.locked():
                time.sleep(0.05)  # the loop comes for the lock meanwhile
                loop.hold()
                loop.status()
                loop.set_real_time_factor(2.0)
                loop.run()
        assert w.clock().step_count > 0
        loop.stop()
    """)


def test_step_feedback_runs_with_no_lock_of_the_loop_held():
    """Feedback reading the world while another thread, inside locked(), asks the loop."""
    _ends_in_a_subprocess(f"""
        loop = SimLoop(World.from_file({str(DEFAULT_SCENE)!r}, WorldConfig(paused=True)))
        loop.start()
        w = loop.world
        done = threading.Event()

        def other():
            while not done.is_set():
                with w.locked():
                    time.sleep(0.002)
                    loop.status()
        t = threading.Thread(target=other)
        t.start()
        seen = []
        loop.step(3000, feedback=lambda d, r: seen.append(w.time))
        done.set()
        t.join()
        assert seen and w.clock().step_count == 3000
        loop.stop()
    """)


def test_step_inside_world_locked_is_refused_not_waited_for(make_loop):
    loop = make_loop(paused=True)
    with loop.world.locked():
        with pytest.raises(IncorrectStateError, match='inside World.locked'):
            loop.step(1, timeout=3)  # (a timeout, so that a wait fails this test, not hangs)


def test_locked_marks_poses_stale_even_when_its_block_raises():
    w = World.from_file(str(DEFAULT_SCENE))
    z0 = w.get_entity_state('box_a').position[2]
    with pytest.raises(RuntimeError):
        with w.locked() as (m, d):
            body = m.body('box_a').id
            d.qpos[m.jnt_qposadr[m.body_jntadr[body]] + 2] += 0.5
            raise RuntimeError('a caller error after a change')
    assert w.get_entity_state('box_a').position[2] == pytest.approx(z0 + 0.5, abs=1e-12)


def test_once_pause_returns_no_step_runs_and_a_reset_stays_at_zero(make_loop):
    """
    Pause, then reset: the world shows time 0, not a step the loop had already decided on.

    The loop thread is slowed between deciding on a batch and taking the world lock, as a
    loaded machine preempts it (the conformance suite saw a step land after pause and reset).
    """
    loop = make_loop(real_time_factor=0.0)
    world = loop.world
    decided = world.stepping.wait_for_callers

    def preempted():
        time.sleep(0.005)
        decided()
    world.stepping.wait_for_callers = preempted
    for _ in range(30):
        loop.run()
        time.sleep(0.002)
        loop.hold()
        world.reset()
        time.sleep(0.01)
        assert world.time == 0.0 and world.step_count == 0
