"""
The node as users meet it: the installed executable in its own process, a real client here.

One node process serves the whole module (start-up costs seconds); tests that need a clean
world reset it first.
"""

import collections
import math
import threading
import time

from conftest import serve_node, wait_for, Watcher
import pytest
from sim_node.ros.client import SimClient, SimServiceError
from simulation_interfaces.msg import EntityCategory, Result, SimulationState
from simulation_interfaces.srv import SetEntityState, SetSimulationState, SpawnEntity

BOX = ('<mujoco><worldbody><body name="b"><freejoint/>'
       '<geom type="box" size=".05 .05 .05" mass=".3"/></body></worldbody></mujoco>')


@pytest.fixture(scope='module')
def node():
    yield from serve_node('real_time_factor:=1.0')


@pytest.fixture
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


def world_state(sim):
    return {n: sim.entity_state(n) for n in sim.entities()}


def test_features_list_what_works(sim):
    f = sim.features()
    from simulation_interfaces.msg import SimulatorFeatures as F
    for feature in (F.SPAWNING, F.DELETING, F.STEP_SIMULATION_MULTIPLE, F.SIMULATION_RESET,
                    F.ENTITY_STATE_SETTING):
        assert feature in f.features
    assert F.NAMED_POSES not in f.features
    assert 'mjcf' in f.spawn_formats and 'urdf' in f.spawn_formats


def test_box_falls_onto_the_table_in_tf_then_delete_removes_tf_and_markers(sim, watch):
    name = sim.spawn('crate', uri='box', position=(0.75, 0.3, 1.0))
    assert name == 'crate'
    first = wait_for(lambda: watch.tf.get('crate'), timeout=10)
    assert first[1] == 'world'

    def resting():
        e = watch.tf.get('crate')
        st = sim.entity_state('crate')
        return e and abs(e[2][2] - 0.47) < 0.01 and math.dist(st['linear'], (0, 0, 0)) < 1e-2
    wait_for(resting, timeout=15)
    x, y, z = watch.tf['crate'][2]
    assert (x, y) == pytest.approx((0.75, 0.3), abs=0.02)  # on the table top (z 0.42 + 0.05)
    wait_for(lambda: any(ns == 'sim/crate' for ns, _ in watch.markers), timeout=5)
    sim.delete('crate')
    wait_for(lambda: not any(ns == 'sim/crate' for ns, _ in watch.markers), timeout=5)
    assert 'crate' not in sim.entities()
    n = len(watch.tf_stamps)
    wait_for(lambda: len(watch.tf_stamps) > n + 3, timeout=5)
    watch.tf.pop('crate', None)
    time.sleep(0.3)
    assert 'crate' not in watch.tf


def test_tf_stamps_are_simulation_time_one_stamp_per_message(sim, watch):
    # /tf_static is latched and may come after the first /tf messages on busy cores: wait.
    wait_for(lambda: len(watch.tf_stamps) > 5 and watch.clock and 'table' in watch.tf_static,
             timeout=20)
    with watch.lock:
        stamps = list(watch.tf_stamps[-5:])
        clock = watch.clock[-1]
    assert all(len(s) == 1 for s in stamps)
    assert abs(max(next(iter(s)) for s in stamps) - clock) < 1.0  # sim time, not wall time
    assert clock < 1e6
    assert 'table' in watch.tf_static and watch.tf_static['table'][1] == 'world'


def test_tf_never_sends_a_frame_twice_with_one_stamp(sim, watch):
    """tf2 listeners drop repeats and log TF_REPEATED_DATA: paused, nothing goes again."""
    sim.pause()
    time.sleep(0.3)
    with watch.lock:
        before = collections.Counter(watch.tf_sends)
    for _ in range(20):  # each answer takes a snapshot
        sim.entity_state('box_a')
    sim.spawn('crate', uri='box', position=(0.3, 2.0, 1.0))
    wait_for(lambda: 'crate' in watch.tf, timeout=5)  # spawned while paused: on /tf at once
    for z in (1.3, 1.4, 1.5):  # changes while paused, each published apart: no frame again
        sim.set_entity_state('box_b', (0.9, 0.0, z))
        time.sleep(0.2)
    for _ in range(10):
        sim.entities_states()
    sim.step(1)  # a new stamp: everything once more, box_b where it was set
    wait_for(lambda: abs(watch.tf['box_b'][2][2] - 1.5) < 1e-3, timeout=5)
    time.sleep(0.5)
    with watch.lock:
        sent = collections.Counter(watch.tf_sends)
    sent.subtract(before)
    repeated = {k: n for k, n in sent.items() if n > 1}
    assert not repeated, sorted(repeated)[:5]


def test_step_simulation_advances_clock_by_exactly_n_steps(sim, watch):
    sim.pause()
    sim.pause()  # already paused: fine for the client, which only wants that state
    with pytest.raises(SimServiceError) as info:
        sim.set_state(SimulationState.STATE_PAUSED)  # the service says so
    assert info.value.code == SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    time.sleep(0.3)
    before = wait_for(watch.latest_clock)
    sim.step(250)  # /clock may show the steps in progress; it ends exactly 250 steps on
    wait_for(lambda: abs(watch.latest_clock() - before - 250 * 0.002) < 1e-6, timeout=5)
    time.sleep(0.3)
    assert watch.latest_clock() == pytest.approx(before + 250 * 0.002, abs=1e-6)
    sim.play()
    t0 = sim.entity_state('box_a')['stamp']
    with pytest.raises(SimServiceError) as info:
        sim.step(1)
    # StepSimulation.srv: not paused -> OPERATION_FAILED (not Result.msg's INCORRECT_STATE)
    assert info.value.code == Result.RESULT_OPERATION_FAILED
    assert 'pause' in info.value.message
    assert sim.state() == SimulationState.STATE_PLAYING
    with pytest.raises(SimServiceError) as info:
        sim.simulate_steps(10)
    assert info.value.code == Result.RESULT_OPERATION_FAILED
    assert sim.entity_state('box_a')['stamp'] > t0  # still playing


def test_simulate_steps_action_reports_feedback(sim):
    sim.pause()
    seen = []
    t0 = sim.entity_state('box_a')['stamp']
    sim.simulate_steps(300, feedback=lambda done, left: seen.append((done, left)))
    assert sim.entity_state('box_a')['stamp'] == pytest.approx(t0 + 300 * 0.002, abs=1e-9)
    # Feedback travels on a topic: some may arrive after the result, but each adds up.
    assert seen and all(done + left == 300 for done, left in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_reset_scopes_over_services(sim):
    sim.spawn('crate', uri='box', position=(0.75, 0.3, 1.0))
    time.sleep(0.3)
    sim.reset(4)  # spawned
    assert 'crate' not in sim.entities()
    sim.pause()
    sim.step(500)
    sim.reset(1)  # time only: the boxes stay where they fell
    assert sim.entity_state('box_a')['stamp'] == pytest.approx(0.0, abs=1e-9)
    assert sim.entity_state('box_a')['position'][2] < 0.5
    sim.reset(2)  # state: back to the home keyframe
    assert sim.entity_state('box_a')['position'][2] == pytest.approx(0.6, abs=1e-6)


def test_position_command_reaches_target_in_joint_states(sim, watch):
    from sensor_msgs.msg import JointState
    pub = watch.node.create_publisher(JointState, 'joint_commands', 10)
    target = -0.5

    def reached():
        pub.publish(JointState(name=['left_elbow'], position=[target]))
        js = watch.joint_states
        return js and abs(js.position[list(js.name).index('left_elbow')] - target) < 0.03
    wait_for(reached, timeout=15, interval=0.2)
    js = watch.joint_states
    assert set(js.name) == {'left_shoulder', 'left_elbow', 'right_shoulder', 'right_elbow'}


def test_a_command_flood_is_coalesced_and_the_latest_command_per_joint_wins(sim, watch):
    """5,000 commands as fast as they go, two joints interleaved: each ends at its last one."""
    from sensor_msgs.msg import JointState
    pub = watch.node.create_publisher(JointState, 'joint_commands', 1000)
    wait_for(lambda: pub.get_subscription_count() > 0, timeout=10)
    t0 = sim.entity_state('box_a')['stamp']
    for i in range(5000):
        pub.publish(JointState(name=['left_elbow'], position=[0.4 if i % 2 else -0.4]))
        pub.publish(JointState(name=['right_elbow'], position=[-0.3 if i % 2 else 0.3]))
    pub.publish(JointState(name=['left_elbow'], position=[-0.7]))  # the last word

    def settled():
        js = watch.joint_states
        pos = dict(zip(js.name, js.position)) if js else {}
        return (abs(pos.get('left_elbow', 9) + 0.7) < 0.03
                and abs(pos.get('right_elbow', 9) + 0.3) < 0.03)
    wait_for(settled, timeout=15, interval=0.1)
    assert sim.entity_state('box_a')['stamp'] > t0  # the simulation kept running


def test_set_get_entity_state_round_trip(sim):
    sim.pause()
    sim.set_entity_state('box_b', position=(0.2, 1.0, 0.8),
                         orientation_xyzw=(0, 0, math.sin(0.25), math.cos(0.25)),
                         linear=(0.1, 0, 0))
    st = sim.entity_state('box_b')
    assert st['position'] == pytest.approx((0.2, 1.0, 0.8), abs=1e-9)
    assert st['orientation_xyzw'] == pytest.approx((0, 0, math.sin(0.25), math.cos(0.25)),
                                                   abs=1e-9)
    assert st['linear'] == pytest.approx((0.1, 0, 0), abs=1e-9)
    assert st['linear_acceleration'] == pytest.approx((0, 0, -9.81), abs=1e-6)  # in the air
    info = sim.entity_info('robot')
    assert info.category.category == EntityCategory.CATEGORY_ROBOT


BAD_SPAWNS = [
    ({'name': 'box_a', 'uri': 'box'}, SpawnEntity.Response.NAME_NOT_UNIQUE),
    ({'name': 'bad name!', 'uri': 'box'}, SpawnEntity.Response.NAME_INVALID),
    ({'name': 'x', 'uri': 'box', 'namespace': 'not a ns'},
     SpawnEntity.Response.NAMESPACE_INVALID),
    ({'name': 'x'}, SpawnEntity.Response.NO_RESOURCE),
    ({'name': 'x', 'resource_string': '<mujoco><worldbody><body>'},
     SpawnEntity.Response.RESOURCE_PARSE_ERROR),
    ({'name': 'x', 'resource_string': '<sdf version="1.9"/>'},
     SpawnEntity.Response.UNSUPPORTED_FORMAT),
    ({'name': 'x', 'resource_string': '{"mujoco": {"worldbody": {}}}'},  # JSON: not a format
     SpawnEntity.Response.UNSUPPORTED_FORMAT),                          # we read, not a typo
    ({'name': 'x', 'resource_string': '#usda 1.0\ndef Xform "box" {}'},
     SpawnEntity.Response.UNSUPPORTED_FORMAT),
    ({'name': 'x', 'resource_string': '<mujoco><asset><mesh name="m" file="/etc/passwd.stl"/>'
      '</asset><worldbody><body><geom type="mesh" mesh="m"/></body></worldbody></mujoco>'},
     SpawnEntity.Response.MISSING_ASSETS),
    ({'name': 'x', 'uri': 'file:///etc/passwd'}, SpawnEntity.Response.MISSING_ASSETS),
    ({'name': 'x', 'uri': 'package://sim/scenes/../../../../etc/passwd'},
     SpawnEntity.Response.MISSING_ASSETS),
    ({'name': 'x', 'uri': 'no_such_object'}, Result.RESULT_NOT_FOUND),
    ({'name': 'x', 'uri': 'box', 'orientation_xyzw': (0, 0, 0.5, 0.5)},
     SpawnEntity.Response.INVALID_POSE),
    ({'name': 'x', 'uri': 'box', 'position': (float('nan'), 0, 1)},
     SpawnEntity.Response.INVALID_POSE),
    ({'name': 'x', 'uri': 'box', 'orientation_xyzw': (0, 0, 0, 0)},
     SpawnEntity.Response.INVALID_POSE),
    ({'name': 'x', 'resource_string': 'x' * 6_000_000}, SpawnEntity.Response.UNSUPPORTED_ASSETS),
]


@pytest.mark.parametrize('kwargs, code', BAD_SPAWNS)
def test_bad_spawn_gets_its_code_and_changes_nothing(sim, kwargs, code):
    sim.pause()
    before = world_state(sim)
    kw = dict(kwargs)
    with pytest.raises(SimServiceError) as info:
        sim.spawn(kw.pop('name'), position=kw.pop('position', (0, 1, 1)), **kw)
    assert info.value.code == code, info.value.message
    assert info.value.message
    assert world_state(sim) == before


@pytest.mark.parametrize('call, code', [
    (lambda s: s.delete('nobody'), Result.RESULT_NOT_FOUND),
    (lambda s: s.entity_state('nobody'), Result.RESULT_NOT_FOUND),
    (lambda s: s.set_entity_state('table', (0.75, 0, 0), linear=(1, 0, 0)),
     Result.RESULT_OPERATION_FAILED),  # a twist for a static entity: SetEntityState.srv says 4
    (lambda s: s.set_entity_state('box_a', (0, 0, 1), orientation_xyzw=(0, 0, 0, 2)),
     SetEntityState.Response.INVALID_POSE),
    (lambda s: s.set_entity_state('box_a', (0, 0, 1), orientation_xyzw=(0, 0, 0, 0)),
     SetEntityState.Response.INVALID_POSE),  # a zero quaternion is no rotation, not identity
])
def test_bad_requests_get_their_code_and_change_nothing(sim, call, code):
    sim.pause()
    before = world_state(sim)
    with pytest.raises(SimServiceError) as info:
        call(sim)
    assert info.value.code == code, info.value.message
    assert world_state(sim) == before


def test_flood_of_requests_does_not_stall_clock(sim, watch):
    stop = threading.Event()

    def flood():
        c = SimClient(timeout_sec=5)
        try:
            while not stop.is_set():
                try:
                    c.entities()
                    c.spawn('x', resource_string='<mujoco><worldbody><body>')
                except (SimServiceError, TimeoutError):
                    pass
        finally:
            c.close()
    threads = [threading.Thread(target=flood) for _ in range(2)]
    for t in threads:
        t.start()
    try:
        time.sleep(0.5)
        n0, c0 = len(watch.clock), watch.latest_clock()
        time.sleep(1.5)
        n1, c1 = len(watch.clock), watch.latest_clock()
    finally:
        stop.set()
        for t in threads:
            t.join(30)
    assert not any(t.is_alive() for t in threads)
    assert n1 - n0 > 30, 'clock messages stalled'
    assert c1 - c0 > 1.0


def test_two_clients_at_once(sim):
    errors = []

    def work(k):
        c = SimClient()
        try:
            for i in range(3):
                name = c.spawn(f'c{k}_{i}', uri='sphere', position=(-1 - k, i * 0.3, 0.5))
                assert name in c.entities()
                c.delete(name)
        except Exception as exc:  # noqa: B902
            errors.append(exc)
        finally:
            c.close()
    threads = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors, errors


def test_spawn_urdf_and_mesh_and_relative_pose(sim):
    urdf = ('<robot name="r"><link name="base"><visual><geometry><box size=".1 .1 .1"/>'
            '</geometry></visual><collision><geometry><box size=".1 .1 .1"/></geometry>'
            '</collision><inertial><mass value="1"/><inertia ixx=".01" iyy=".01" izz=".01" '
            'ixy="0" ixz="0" iyz="0"/></inertial></link></robot>')
    sim.spawn('urdf_thing', resource_string=urdf, position=(-1, -1, 0.5))
    sim.pause()  # the pyramid has mass: running, it would fall before we look
    try:
        sim.spawn('pyr', uri='pyramid', position=(0, 0.35, 0.6), frame_id='table')
        st = sim.entity_state('pyr')
    finally:
        sim.play()
    assert st['position'] == pytest.approx((0.75, 0.35, 0.6), abs=1e-6)
    assert any(u.endswith('box.xml') for u in sim.spawnables())


def test_worlds_load_unload(sim):
    sim.load_world(uri='package://sim/scenes/push_stack.xml')
    assert sim.current_world() == 'push_stack'
    # The standard: a loaded world is left STOPPED, at its initial state.
    assert sim.state() == SimulationState.STATE_STOPPED
    t0 = sim.entity_state('finger_base')['stamp']
    time.sleep(0.3)
    assert sim.entity_state('finger_base')['stamp'] == t0
    assert 'finger_base' in sim.entities()
    sim.unload_world()
    with pytest.raises(SimServiceError):
        sim.entities()
    assert sim.state() == SimulationState.STATE_NO_WORLD
    sim.load_world(uri='package://sim/scenes/default.xml')
    assert 'robot' in sim.entities()


def test_paused_parameter_follows_the_simulation_state_service(sim):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    params = AsyncParameterClient(sim.node, 'sim')
    assert params.wait_for_services(timeout_sec=10)

    def paused_param():
        future = params.get_parameters(['paused'])
        sim.spin_until_future_complete(future, 10)
        return future.result().values[0].bool_value
    try:
        sim.pause()
        assert paused_param() is True
        sim.play()
        assert paused_param() is False
        # The loop pausing itself at a limit shows up too.
        future = params.set_parameters([Parameter(
            'max_sim_time', value=sim.entity_state('box_a')['stamp'] + 0.2)])
        sim.spin_until_future_complete(future, 10)
        wait_for(lambda: sim.state() == SimulationState.STATE_PAUSED, timeout=10)
        wait_for(paused_param, timeout=5)
    finally:
        future = params.set_parameters([Parameter('max_sim_time', value=0.0)])
        sim.spin_until_future_complete(future, 10)
        if sim.state() != SimulationState.STATE_PLAYING:
            sim.play()


def test_paused_and_real_time_factor_parameters_change_at_run_time(sim, watch):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    params = AsyncParameterClient(sim.node, 'sim')
    assert params.wait_for_services(timeout_sec=10)

    def set_param(name, value):
        future = params.set_parameters([Parameter(name, value=value)])
        sim.spin_until_future_complete(future, 10)
        assert all(r.successful for r in future.result().results), future.result()
    try:
        set_param('paused', True)
        time.sleep(0.3)
        c0 = watch.latest_clock()
        time.sleep(0.5)
        assert watch.latest_clock() == c0
        set_param('real_time_factor', 3.0)
        set_param('paused', False)
        time.sleep(0.3)
        c1, w1 = watch.latest_clock(), time.monotonic()
        time.sleep(1.0)
        rate = (watch.latest_clock() - c1) / (time.monotonic() - w1)
        # Ahead of the clock, never past 3x (make bench-pacing measures how close to 3).
        assert 1.2 < rate <= 3.3
    finally:
        set_param('real_time_factor', 1.0)
        set_param('paused', False)


def test_an_endless_step_request_ends_on_a_state_request_and_zero_steps_is_a_no_op(sim):
    from simulation_interfaces.srv import StepSimulation
    sim.pause()
    other = SimClient(timeout_sec=30)
    answers = []

    def endless():  # the most one request may take: some seconds to step
        answers.append(other.call('step_simulation', StepSimulation,
                                  StepSimulation.Request(steps=1_000_000), check=False))
    t = threading.Thread(target=endless)
    t.start()
    try:
        time.sleep(1.0)
        assert not answers  # still stepping
        with pytest.raises(SimServiceError):  # already paused, but it ends the request
            sim.set_state(SimulationState.STATE_PAUSED)
        t.join(10)
        assert answers and answers[0].result.result == Result.RESULT_INCORRECT_STATE
        assert 'ended by a state request' in answers[0].result.error_message
        sim.step(10)  # no "another step request is still running"
        zero = sim.call('step_simulation', StepSimulation, StepSimulation.Request(steps=0))
        assert zero.result.result == Result.RESULT_OK
        # More than max_steps_per_request: refused at once, pointing to the action
        t0 = sim.entity_state('box_a')['stamp']
        huge = sim.call('step_simulation', StepSimulation,
                        StepSimulation.Request(steps=2 ** 63 - 1), check=False)
        assert huge.result.result == Result.RESULT_OPERATION_FAILED
        assert 'simulate_steps' in huge.result.error_message
        assert sim.entity_state('box_a')['stamp'] == t0
    finally:
        t.join(10)
        other.close()


def _code_and_message(call):
    with pytest.raises(SimServiceError) as info:
        call()
    return info.value.code, info.value.message


def test_bad_resources_get_their_own_codes_and_never_the_servers_paths(sim):
    from conftest import ROOT, installed_prefix
    from simulation_interfaces.srv import LoadWorld
    before = sorted(sim.entities())
    scenes = installed_prefix() / 'share' / 'sim' / 'scenes'
    spawn_cases = [
        ({'uri': 'package://sim/scenes/objects/nope.xml'}, Result.RESULT_NOT_FOUND, 'no file'),
        ({'uri': 'package://sim/objects/nope.xml'}, Result.RESULT_NOT_FOUND, 'no file'),
        ({'uri': 'package://no_such_package/x.xml'}, Result.RESULT_NOT_FOUND, 'not installed'),
        ({'uri': 'crate_that_is_not_there'}, Result.RESULT_NOT_FOUND, 'box'),  # lists names
        ({'uri': 'file:///etc/passwd'}, SpawnEntity.Response.MISSING_ASSETS, 'resource_paths'),
        ({'uri': 'x' * 100_000}, Result.RESULT_NOT_FOUND, 'spawnable names'),
        ({}, SpawnEntity.Response.NO_RESOURCE, 'empty'),
        # A client that knows where the server's files are is still not told it.
        ({'resource_string': f'<mujoco><asset><mesh name="m" file="{scenes}/objects/gone.stl"/>'
                             '</asset><worldbody><body><geom type="mesh" mesh="m"/></body>'
                             '</worldbody></mujoco>'},
         SpawnEntity.Response.MISSING_ASSETS, 'resource_paths[0]>/objects/gone.stl'),
    ]
    for kwargs, code, hint in spawn_cases:
        got, message = _code_and_message(lambda: sim.spawn('thing', **kwargs))
        assert (got, hint in message) == (code, True), (kwargs, got, message)
        assert len(message) < 3000
        for secret in (str(ROOT), str(installed_prefix()), '/share/sim'):
            assert secret not in message, (kwargs, message)
    world_cases = [
        ({'uri': 'no_such_world'}, Result.RESULT_NOT_FOUND, 'default'),
        ({}, LoadWorld.Response.NO_RESOURCE, 'empty'),
        ({'resource_string': '<robot2/>'}, LoadWorld.Response.UNSUPPORTED_FORMAT, '<robot2>'),
        ({'resource_string': '<mujoco><worldbody><geom type="nope"/></worldbody></mujoco>'},
         LoadWorld.Response.RESOURCE_PARSE_ERROR, 'nope'),
        ({'uri': 'file:///etc/hostname'}, LoadWorld.Response.MISSING_ASSETS, 'resource_paths'),
    ]
    for kwargs, code, hint in world_cases:
        got, message = _code_and_message(lambda: sim.load_world(**kwargs))
        assert (got, hint in message) == (code, True), (kwargs, got, message)
        assert str(installed_prefix()) not in message
    # Nothing of that changed the world.
    assert sorted(sim.entities()) == before
    assert sim.current_world() == 'default'


def test_set_entity_state_honours_the_header_frame(sim):
    sim.pause()
    try:
        sim.spawn('anchor', uri='box', position=(1.0, -1.0, 0.5))
        sim.spawn('mover', uri='box', position=(-1.0, 1.0, 0.5))
        # 90 degrees about z: the anchor's x axis is the world's y axis.
        q = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))
        sim.set_entity_state('anchor', (1.0, -1.0, 0.5), q)
        sim.set_entity_state('mover', (0.3, 0.0, 0.2), linear=(1.0, 0.0, 0.0),
                             frame_id='anchor')
        st = sim.entity_state('mover')
        assert st['position'] == pytest.approx((1.0, -0.7, 0.7), abs=1e-6)
        assert st['linear'] == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)
        assert st['orientation_xyzw'] == pytest.approx(q, abs=1e-6)
        code, message = _code_and_message(
            lambda: sim.set_entity_state('mover', (0, 0, 1), frame_id='no_such_frame'))
        assert code == SetEntityState.Response.INVALID_POSE and 'no_such_frame' in message
    finally:
        sim.play()


def test_launch_file_and_rviz_config_match_what_the_node_offers(sim):
    """The shipped launch file sets real parameters; the RViz config shows real topics."""
    import ast
    from conftest import installed_prefix
    from rcl_interfaces.srv import ListParameters
    import yaml
    share = installed_prefix() / 'share' / 'sim'
    launch_text = (share / 'launch' / 'sim.launch.py').read_text()
    tree = ast.parse(launch_text)
    args = next(n.value for n in tree.body if isinstance(n, ast.Assign)
                and n.targets[0].id == 'ARGUMENTS')
    launch_only = next(n.value for n in tree.body if isinstance(n, ast.Assign)
                       and n.targets[0].id == 'LAUNCH_ONLY')
    launch_params = {k.value for k in args.keys} - {e.value for e in launch_only.elts}
    listed = sim.call('sim/list_parameters', ListParameters, ListParameters.Request(),
                      check=False)
    assert launch_params <= set(listed.result.names)
    assert "'sim.rviz'" in launch_text and (share / 'rviz' / 'sim.rviz').is_file()
    assert 'with_robot_model' in launch_text and "'entity'" in launch_text
    rviz = yaml.safe_load((share / 'rviz' / 'sim.rviz').read_text())
    manager = rviz['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'world'
    displays = {d['Class']: d for d in manager['Displays']}
    assert 'rviz_default_plugins/TF' in displays
    topic = displays['rviz_default_plugins/MarkerArray']['Topic']
    assert topic['Durability Policy'] == 'Transient Local'  # the node latches its markers
    topics = dict(sim.node.get_topic_names_and_types())
    assert topics[topic['Value']] == ['visualization_msgs/msg/MarkerArray']
    # The default scene's camera and scanner, subscribed best effort: the node publishes them
    # with sensor-data QoS, which a reliable subscription would never receive.
    for plugin, msg_type in (('Image', 'sensor_msgs/msg/Image'),
                             ('LaserScan', 'sensor_msgs/msg/LaserScan')):
        topic = displays[f'rviz_default_plugins/{plugin}']['Topic']
        assert topic['Reliability Policy'] == 'Best Effort'
        assert topics[topic['Value']] == [msg_type]
