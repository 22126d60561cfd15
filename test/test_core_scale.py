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
from sim_node.core.loop import SimLoop
from sim_node.core.records import RESET_SPAWNED
from sim_node.core.stepping.rate import RATE_WINDOW_SEC
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
    from sim_node.core.models import sources
    w.spawn('more', sources.primitive('box', [0.05] * 3), position=[0, 0, 5])
    assert arena_mb(w) == pytest.approx(expected + c.arena_bytes_per_body / 2 ** 20)


def test_a_scene_that_sizes_its_arena_keeps_its_size():
    xml = box_scene(10).replace('<option', '<size memory="3M"/><option')
    assert arena_mb(World.from_string(xml)) == pytest.approx(3.0)


@pytest.mark.slow  # about 5 s of real time
def test_the_loop_says_once_when_the_physics_cannot_keep_the_factor(caplog):
    w = World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=1000.0))
    loop = SimLoop(w)
    with caplog.at_level(logging.WARNING, logger='sim_node.core.stepping'):
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


@pytest.mark.slow  # about 3 s of real time
def test_lag_is_reported_exactly_when_the_factor_is_not_kept():
    """
    The lag message follows the measured factor; the factor is never over what was asked.

    Whether this machine keeps a factor of 1 is make bench-pacing's verdict: a test that
    asserted "no lag" failed for want of CPU, not for a fault.
    """
    from sim_node.core.stepping.rate import LAG_FRACTION
    w = World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=1.0))
    loop = SimLoop(w)
    loop.start()
    try:
        time.sleep(RATE_WINDOW_SEC + 1.0)
        st = loop.status()
    finally:
        loop.stop()
    assert 0 < st.achieved_real_time_factor <= 1.02
    assert bool(st.lag) == (st.achieved_real_time_factor < LAG_FRACTION * 1.0)


@pytest.fixture
def slow_source(tmp_path):
    """
    Return a model whose four 150k-face meshes take about a second or more to compile.

    One took about a second while MuJoCo built its hull on every vertex; with hulls bounded
    (``decompose.bound_hulls``) it takes 0.3 s here, too short to tell a stall from a step.
    """
    from conftest import write_mesh_model
    from sim_node.core.models import sources
    model = write_mesh_model(tmp_path, 150_000, meshes=4)
    return sources.from_file(str(model), allowed_roots=[str(tmp_path)])


class StallWatch:
    """How often a running loop's simulated time moved while an edit ran, watched meanwhile."""

    def __init__(self, loop: SimLoop):
        import threading
        self.loop, self.moves, self.longest = loop, 0, 0.0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._watch)

    def _watch(self) -> None:
        last_t, since = self.loop.world.time, time.monotonic()
        while not self._done.is_set():
            t, now = self.loop.world.time, time.monotonic()
            if t != last_t:
                last_t, since, self.moves = t, now, self.moves + 1
            self.longest = max(self.longest, now - since)  # for the messages only
            time.sleep(0.005)

    def __enter__(self) -> 'StallWatch':
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._done.set()
        self._thread.join()


def moved_during(loop: SimLoop, edit, what: str) -> float:
    """
    Run `edit` on a loop running at real-time factor 1; assert simulated time kept moving.

    A compile under the world lock holds the loop for its whole length: simulated time would
    not move at all while it runs. So the loop must have advanced by at least a quarter of the
    edit's wall time (less 20 ms, for edits too short to tell). How long the longest stall is,
    is a benchmark's verdict (make bench-edits, make bench-storm), not a wall-clock bound here
    that a loaded machine could miss. Returns the edit's wall time.
    """
    t0_sim = loop.world.time
    with StallWatch(loop) as watch:
        t0 = time.monotonic()
        edit()
        took = time.monotonic() - t0
    moved = loop.world.time - t0_sim
    assert moved >= 0.25 * took - 0.02, (
        f'simulated time moved {moved:.3f} s ({watch.moves} times; its longest stand '
        f'{watch.longest:.2f} s) during a {took:.2f} s {what}')
    return took


def assert_the_loop_keeps_stepping(loop: SimLoop, edit, what: str) -> None:
    """Run `edit` (a slow compile) on a running loop: simulated time keeps moving meanwhile."""
    time.sleep(0.3)
    assert moved_during(loop, edit, what) > 0.5  # slow enough to mean something


def test_a_slow_spawn_compiles_outside_the_world_lock_so_the_loop_keeps_stepping(slow_source):
    """A 150k-face mesh takes seconds to compile; the loop must not stall for it."""
    loop = SimLoop(World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=1.0)))
    loop.start()
    try:
        assert_the_loop_keeps_stepping(
            loop, lambda: loop.world.spawn('big', slow_source, position=[0, 2, 1]), 'spawn')
    finally:
        loop.stop()


@pytest.mark.slow  # about 2 s each: slow compiles
@pytest.mark.parametrize('edit', ['add_body', 'set_default_contact', 'delete'])
def test_other_edits_compile_outside_the_world_lock_too(slow_source, edit):
    """With MuJoCo's mesh cache off, every compile of this world takes seconds: no stall."""
    from sim_node.core.models import asset_store, sources
    loop = SimLoop(World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=1.0)))
    w = loop.world
    w.spawn('big', slow_source, position=[0, 2, 1])
    w.spawn('crate', sources.primitive('box', [0.05] * 3), position=[1.5, 1.5, 1])
    asset_store.set_mesh_cache(0)  # every compile processes the big mesh again
    edits = {'add_body': lambda: w.add_body('lid', 'crate', 'box', [0.05, 0.05, 0.01],
                                            position=(0, 0, 0.06)),
             'set_default_contact': lambda: w.set_default_contact(friction=[0.8, 0.01, 0.001]),
             'delete': lambda: w.delete('crate')}
    loop.start()
    try:
        assert_the_loop_keeps_stepping(loop, edits[edit], edit)
    finally:
        loop.stop()
        asset_store.set_mesh_cache(WorldConfig().mesh_cache_mb)


def test_an_edit_during_a_slow_spawn_is_kept_and_the_spawn_lands_on_the_new_world(slow_source):
    """A delete while the spawn compiles: the spawn starts over; nothing deleted comes back."""
    import threading

    from sim_node.core.models import sources
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('victim', sources.primitive('box', [0.05] * 3), position=[1.5, 1.5, 1])
    w.command(['left_elbow'], [0.5], 'position')
    spawner = threading.Thread(target=lambda: w.spawn('big', slow_source, position=[0, 2, 1]))
    spawner.start()
    time.sleep(0.3)  # compiling now
    w.delete('victim')
    w.step(200)  # and the world moves on meanwhile
    spawner.join()
    names = [e.name for e in w.entities()]
    assert 'big' in names and 'victim' not in names
    w.step(300)  # the command held through both edits
    assert w.get_joint_states()['left_elbow'][0] == pytest.approx(0.5, abs=0.02)


@pytest.mark.slow  # about 2 s
def test_mesh_heavy_arms_spawn_without_stalling_the_loop():
    """
    Three 58-mesh arms, one after another: the loop keeps stepping while each compiles.

    Before the checked-file store and the uncompiled world spec, MuJoCo compiled meshes given
    as an asset dict holding the GIL (160-330 ms at a stretch) and the world's compiled spec
    was copied under the lock: the loop stood still 0.33-1.1 s per spawn (issue 19).
    """
    from sim_node.core.models import sources
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
    import corpus
    folder = corpus.fetch()
    panda = next(m for m in corpus.MODELS if 'panda' in m.path)
    loop = SimLoop(World.from_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=1.0)))
    loop.start()
    try:
        time.sleep(0.3)
        w = loop.world
        for i in range(3):
            src = sources.from_file(str(panda.file), allowed_roots=[str(folder)])
            moved_during(loop, lambda: w.spawn(f'arm{i}', src, position=[2.0 + i, 3.0, 0.0]),
                         f'spawn of arm{i}')
        # Every other edit of a world holding the arms compiles it all again (MuJoCo's mesh
        # cache makes that cheap): outside the lock too.
        edits = {'delete': lambda: w.delete('arm0'),
                 'friction': lambda: w.set_friction('arm1', 0.5),
                 'restitution': lambda: w.set_restitution('arm1', 0.3),
                 'mass': lambda: w.set_mass('arm1', 20.0),
                 'gravity': lambda: w.set_gravity([0, 0, -9.0]),
                 'reset of the spawned': lambda: w.reset(RESET_SPAWNED)}
        for label, edit in edits.items():
            moved_during(loop, edit, label)
    finally:
        loop.stop()


@pytest.mark.slow  # about 7 s
def test_a_model_of_5000_bodies_spawns_when_max_bodies_allows_it():
    """The arena (MuJoCo's) is sized for the world after the spawn, not before (it failed)."""
    from sim_node.core.models import sources
    bodies = ''.join(f'<body pos="{i % 70 * 0.3} {i // 70 * 0.3} 0.2"><freejoint/>'
                     '<geom type="box" size=".1 .1 .1"/></body>' for i in range(5000))
    source = sources.from_model_text(f'<mujoco model="many"><worldbody>{bodies}</worldbody>'
                                     '</mujoco>')
    w = World.from_file(str(DEFAULT_SCENE), WorldConfig(max_bodies=6000))
    assert w.spawn('many', source, (20.0, 20.0, 0.0)) == 'many'
    w.step(200)  # 0.4 s: every box has landed on the floor, 20,000 contacts
    assert w.model_info.body_names.count('many') == 1
    assert abs(w.get_entity_state('many').position[2] - 0.1) < 0.01


def _queue_behind_a_slow_spawn(world: World, slow_source, edits: dict) -> dict:
    """Run `edits` (name -> callable) on threads of their own while a slow spawn compiles."""
    import threading

    from sim_node.core.models import asset_store
    answers: dict = {}

    def run(name, edit):
        try:
            answers[name] = edit()
        except Exception as exc:  # noqa: B902 (the answer this caller got)
            answers[name] = exc
    slow = threading.Thread(target=lambda: world.spawn('big', slow_source, position=[0, 2, 1]))
    asset_store.set_mesh_cache(0)  # compiled before by another test: slow all the same
    try:
        slow.start()
        time.sleep(0.3)  # compiling: the edits below queue behind it
        threads = [threading.Thread(target=run, args=item) for item in edits.items()]
        for t in threads:
            t.start()
        slow.join()
        for t in threads:
            t.join()
    finally:
        asset_store.set_mesh_cache(WorldConfig().mesh_cache_mb)
    return answers


@pytest.mark.slow  # about 1.5 s
def test_edits_queued_behind_a_slow_one_are_made_together_each_with_its_own_answer(slow_source):
    """Six spawns and a delete queue while a spawn compiles: one more compile for all seven."""
    from sim_node.core.models import sources
    w = World.from_file(str(DEFAULT_SCENE))
    box = sources.primitive('box', [0.05] * 3)
    w.spawn('old', box, position=[1.5, 1.5, 1])
    before = w.get_state().generation
    edits = {f'b{i}': (lambda i=i: w.spawn(f'b{i}', box, position=[-2 + 0.3 * i, -2, 0.5]))
             for i in range(6)}
    edits['delete'] = lambda: w.delete('old')
    answers = _queue_behind_a_slow_spawn(w, slow_source, edits)
    assert answers == dict({f'b{i}': f'b{i}' for i in range(6)}, delete=None)
    names = {e.name for e in w.entities()}
    assert {'big', *(f'b{i}' for i in range(6))} <= names and 'old' not in names
    assert w.get_state().generation == before + 2  # the slow spawn, then the seven at once
    w.step(500)
    assert w.get_entity_state('b5').position[2] == pytest.approx(0.05, abs=0.01)  # landed


@pytest.mark.slow  # about 4 s
def test_edits_that_clash_in_a_group_are_made_one_by_one_and_refused_alone(slow_source):
    """Two spawns of one name, two at one place: one of each pair lands, the other is refused."""
    from sim_node.core.models import sources
    from sim_node.core.errors import InvalidPoseError, NameNotUniqueError
    w = World.from_file(str(DEFAULT_SCENE))
    box = sources.primitive('box', [0.05] * 3)
    edits = {'twin_a': lambda: w.spawn('twin', box, position=[-2, -2, 0.5]),
             'twin_b': lambda: w.spawn('twin', box, position=[-1, -2, 0.5]),
             'here_a': lambda: w.spawn('here_a', box, position=[-2, 2, 0.5]),
             'here_b': lambda: w.spawn('here_b', box, position=[-2, 2, 0.5]),
             'free': lambda: w.spawn('free', box, position=[2, -2, 0.5])}
    answers = _queue_behind_a_slow_spawn(w, slow_source, edits)
    twins = sorted(type(answers[k]).__name__ for k in ('twin_a', 'twin_b'))
    assert twins == sorted([NameNotUniqueError.__name__, 'str'])
    here = [answers[k] for k in ('here_a', 'here_b')]
    assert sum(isinstance(a, InvalidPoseError) for a in here) == 1
    assert answers['free'] == 'free'
    names = [e.name for e in w.entities()]
    assert names.count('twin') == 1 and ('here_a' in names) != ('here_b' in names)


@pytest.mark.slow  # about 2 s
def test_a_spawn_whose_world_changed_while_it_compiled_is_planned_again(slow_source):
    """A delete made inside locked() while the spawn compiles: the deleted box stays deleted."""
    import threading

    from sim_node.core.models import asset_store, sources
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('victim', sources.primitive('box', [0.05] * 3), position=[1.5, 1.5, 1])
    asset_store.set_mesh_cache(0)  # compiled before by another test: slow all the same
    try:
        spawner = threading.Thread(target=lambda: w.spawn('big', slow_source,
                                                          position=[0, 2, 1]))
        spawner.start()
        time.sleep(0.3)  # compiling, from a design that still holds the victim
        with w.locked():
            w.delete('victim')  # made at once, under the lock: a new generation
        spawner.join()
    finally:
        asset_store.set_mesh_cache(WorldConfig().mesh_cache_mb)
    names = [e.name for e in w.entities()]
    assert 'big' in names and 'victim' not in names


@pytest.mark.slow  # fetches the ROS corpus once (as the node's corpus tests do)
def test_deleting_a_robot_lets_every_other_thread_run():
    """
    A delete holds no other thread up while MuJoCo takes the robot out of the world's spec.

    MuJoCo's bindings hold the GIL in ``MjSpec.delete``: TIAGo's frame took 26 ms, and a
    thread ticking every millisecond was held 28 ms (the stepping loop with it: issue 52,
    item 1). Through ctypes (``core/base/native.py``) the GIL goes meanwhile.
    """
    from conftest import Ticker
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
    import corpus
    from sim_node.core.models import sources
    tiago = next(m for m in corpus.ros_models() if m.path.name == 'tiago.urdf')
    world = World.from_file(str(DEFAULT_SCENE))
    held = []
    for _ in range(3):
        world.spawn('tiago', sources.from_file(str(tiago.path), [str(tiago.root)]),
                    position=(0.0, 3.0, 0.1))
        with Ticker() as ticker:
            world.delete('tiago')
        held.append(ticker.held)
    assert 'tiago' not in world.entities()
    assert min(held) < 0.015, [f'{h * 1000:.0f} ms' for h in held]
