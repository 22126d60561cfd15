"""
simulation_interfaces 1.5.1 (Jazzy) conformance: one test per rule, over the wire.

Each test is named after its rule in the rules reference (``standard_rules.md``, §6: the rules
simulators most often get wrong; §3-§4: the state machine and the services), and uses only the
standard's services and action under the names simulators that implement it use
(``spawn_entity``, ``get_entity_state``, ..., ``simulate_steps``), relative to a namespace. By
default it starts this package's node; to run it against another simulator, start that one and::

    SIM_CONFORMANCE_EXTERNAL=1 SIM_CONFORMANCE_NAMESPACE=/my_sim pytest test/conformance

GetSimulatorFeatures drives it: a rule whose feature is not listed is skipped, and the
interface of an unlisted feature is checked to answer FEATURE_UNSUPPORTED (0). It needs the
first spawnable GetSpawnables lists to be a body that falls under gravity, and the world to hold
a static entity (category 5).
"""

import math
import os
import re
import time

from conftest import NodeProcess
from geometry_msgs.msg import Vector3
import pytest
from sim_node.client import SimClient, SimServiceError
from simulation_interfaces import srv
from simulation_interfaces.msg import (Bounds, EntityCategory, EntityState, Result,
                                       SimulationState, SimulatorFeatures as F)

NAMESPACE = os.environ.get('SIM_CONFORMANCE_NAMESPACE', '')
EXTERNAL = os.environ.get('SIM_CONFORMANCE_EXTERNAL') == '1'
OK, UNSUPPORTED, NOT_FOUND, OPERATION_FAILED = (Result.RESULT_OK,
                                                Result.RESULT_FEATURE_UNSUPPORTED,
                                                Result.RESULT_NOT_FOUND,
                                                Result.RESULT_OPERATION_FAILED)
S = SimulationState


# ------------------------------------------------------------------ the simulator under test

@pytest.fixture(scope='module')
def simulator():
    """Start this package's node (unless an external one is named); it must exit cleanly."""
    if EXTERNAL:
        yield None
        return
    proc = NodeProcess(namespace=NAMESPACE)
    yield proc
    code, _ = proc.interrupt()
    assert code == 0, proc.output()


@pytest.fixture(scope='module')
def client(simulator, rclpy_context):
    c = SimClient(namespace=NAMESPACE, timeout_sec=30)
    yield c
    c.close()


@pytest.fixture(scope='module')
def features(client) -> set:
    return set(client.features().features)


@pytest.fixture
def sim(client):
    """Return the client, with the simulation reset (scope 0: everything) and playing."""
    client.reset(0)
    client.play()
    return client


def needs(features: set, *flags: int) -> None:
    missing = [f for f in flags if f not in features]
    if missing:
        pytest.skip(f'features {missing} are not listed by GetSimulatorFeatures')


def raw(sim: SimClient, service: str, srv_type, **fields):
    """Call a service and return its response, whatever its Result."""
    return sim.call(service, srv_type, srv_type.Request(**fields), check=False)


def sim_time(sim: SimClient) -> float:
    """Return the simulation time: the stamp of an entity's state."""
    return sim.entity_state(sim.entities()[0])['stamp']


def spawnable(sim: SimClient) -> str:
    uris = sim.spawnables()
    if not uris:
        pytest.skip('no spawnable')
    return uris[0]


def static_entity(sim: SimClient) -> str:
    found = sim.entities(categories=[EntityCategory.CATEGORY_STATIC_OBJECT])
    if not found:
        pytest.skip('the world has no static entity')
    return found[0]


def world_picture(sim: SimClient) -> dict:
    """Every entity's pose: what 'changes nothing' compares."""
    return {n: (s['position'], s['orientation_xyzw']) for n, s in sim.entities_states().items()}


# ------------------------------------------------------------------ §6: the rules

def test_rule_01_success_is_result_1_on_every_service(sim, features):
    calls = [('get_entities', srv.GetEntities, {}),
             ('get_simulation_state', srv.GetSimulationState, {})]
    name = sim.entities()[0]
    if F.ENTITY_STATE_GETTING in features:
        calls += [('get_entity_state', srv.GetEntityState, {'entity': name}),
                  ('get_entities_states', srv.GetEntitiesStates, {})]
    if F.ENTITY_INFO_GETTING in features:
        calls.append(('get_entity_info', srv.GetEntityInfo, {'entity': name}))
    if F.ENTITY_BOUNDS in features:
        calls.append(('get_entity_bounds', srv.GetEntityBounds, {'entity': name}))
    if F.SPAWNABLES in features:
        calls.append(('get_spawnables', srv.GetSpawnables, {}))
    if F.WORLD_INFO_GETTING in features:
        calls.append(('get_current_world', srv.GetCurrentWorld, {}))
    if F.AVAILABLE_WORLDS in features:
        calls.append(('get_available_worlds', srv.GetAvailableWorlds, {}))
    for service, srv_type, fields in calls:
        assert raw(sim, service, srv_type, **fields).result.result == OK, service


def test_rule_02_step_while_playing_answers_4_and_steps_nothing(sim, features):
    needs(features, F.STEP_SIMULATION_SINGLE)
    res = raw(sim, 'step_simulation', srv.StepSimulation, steps=1)
    assert res.result.result == OPERATION_FAILED and res.result.error_message
    assert sim.state() == S.STATE_PLAYING


def paused_step_length(sim: SimClient) -> float:
    """Pause, take one step, and return how long a step is in simulated time."""
    sim.pause()
    t0 = sim_time(sim)
    sim.step(1)
    dt = sim_time(sim) - t0
    assert dt > 0
    return dt


def test_rule_03_step_n_from_paused_advances_exactly_n_steps_and_stays_paused(sim, features):
    needs(features, F.STEP_SIMULATION_SINGLE, F.STEP_SIMULATION_MULTIPLE)
    dt = paused_step_length(sim)
    t1 = sim_time(sim)
    sim.step(37)
    assert sim_time(sim) - t1 == pytest.approx(37 * dt, abs=1e-9)
    assert sim.state() == S.STATE_PAUSED


def test_rule_04_default_steps_is_one_step(sim, features):
    needs(features, F.STEP_SIMULATION_SINGLE, F.STEP_SIMULATION_MULTIPLE)
    dt = paused_step_length(sim)
    t1 = sim_time(sim)
    assert srv.StepSimulation.Request().steps == 1
    assert sim.call('step_simulation', srv.StepSimulation,
                    srv.StepSimulation.Request()).result.result == OK
    assert sim_time(sim) - t1 == pytest.approx(dt, abs=1e-9)


def test_rule_04_steps_above_one_need_their_feature(sim, features):
    if F.STEP_SIMULATION_MULTIPLE in features:
        pytest.skip('STEP_SIMULATION_MULTIPLE is listed (checked by rule 3)')
    sim.pause()
    assert raw(sim, 'step_simulation', srv.StepSimulation, steps=2).result.result == UNSUPPORTED


def test_rule_05_simulate_steps_counts_feedback_to_n_and_fails_while_playing(sim, features):
    needs(features, F.STEP_SIMULATION_ACTION)
    with pytest.raises(SimServiceError) as info:
        sim.simulate_steps(5)  # playing
    assert info.value.code == OPERATION_FAILED
    sim.pause()
    seen = []
    result = sim.simulate_steps(20, feedback=lambda done, left: seen.append((done, left)))
    assert result.result == OK
    assert seen and all(d + r == 20 for d, r in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)
    assert sim.state() == S.STATE_PAUSED


def test_rule_06_setting_the_current_state_answers_101_and_changes_nothing(sim, features):
    needs(features, F.SIMULATION_STATE_SETTING)
    res = raw(sim, 'set_simulation_state', srv.SetSimulationState,
              state=SimulationState(state=S.STATE_PLAYING))
    assert res.result.result == srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert sim.state() == S.STATE_PLAYING
    sim.set_state(S.STATE_STOPPED)
    picture = world_picture(sim)
    res = raw(sim, 'set_simulation_state', srv.SetSimulationState)  # default: STOPPED
    assert res.result.result == srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert world_picture(sim) == picture and sim.state() == S.STATE_STOPPED


def test_rule_07_stopped_resets_everything_and_removes_spawned_entities(sim, features):
    needs(features, F.SIMULATION_STATE_SETTING, F.SPAWNING)
    sim.set_state(S.STATE_STOPPED)  # the reference: the world as it starts
    start, picture = sim_time(sim), world_picture(sim)
    sim.play()
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=(0.5, -2.0, 2.0))
    time.sleep(0.5)
    assert sim_time(sim) > start
    sim.set_state(S.STATE_STOPPED)
    assert sim.state() == S.STATE_STOPPED
    assert name not in sim.entities()
    assert sim_time(sim) == pytest.approx(start, abs=1e-9)
    assert world_picture(sim) == picture
    time.sleep(0.3)
    assert sim_time(sim) == pytest.approx(start, abs=1e-9)  # and it does not step


def test_rule_08_paused_needs_its_feature_and_stopped_to_paused_is_documented(sim, features):
    if F.SIMULATION_STATE_PAUSE not in features:
        res = raw(sim, 'set_simulation_state', srv.SetSimulationState,
                  state=SimulationState(state=S.STATE_PAUSED))
        assert res.result.result == UNSUPPORTED
        return
    sim.set_state(S.STATE_STOPPED)
    # [open] in the text; this node allows it (its README): paused, still at the reset state
    res = raw(sim, 'set_simulation_state', srv.SetSimulationState,
              state=SimulationState(state=S.STATE_PAUSED))
    assert res.result.result in (OK, srv.SetSimulationState.Response.INCORRECT_TRANSITION)
    if not EXTERNAL:
        assert res.result.result == OK and sim.state() == S.STATE_PAUSED


@pytest.mark.skipif(EXTERNAL, reason='ends the simulator: run only against a node started here')
def test_rule_09_quitting_stops_first_then_exits(rclpy_context):
    proc = NodeProcess(namespace='/conformance_quit')
    own = SimClient(namespace='/conformance_quit', timeout_sec=30)
    try:
        name = own.spawn('conformance_item', uri=spawnable(own), position=(0.5, -2.0, 2.0))
        own.entity_state(name)
        t0 = time.monotonic()
        own.set_state(S.STATE_QUITTING)  # answered OK before it goes
        assert proc.proc.wait(5) == 0 and time.monotonic() - t0 < 2.0, proc.output()
        assert 'stopped' in proc.output()
    finally:
        own.close()
        proc.close()


@pytest.mark.parametrize('service, srv_type, fields', [
    ('get_entity_state', srv.GetEntityState, {}),
    ('set_entity_state', srv.SetEntityState, {}),
    ('get_entity_info', srv.GetEntityInfo, {}),
    ('get_entity_bounds', srv.GetEntityBounds, {}),
    ('delete_entity', srv.DeleteEntity, {}),
], ids=lambda v: v if isinstance(v, str) else '')
def test_rule_10_unknown_entity_is_not_found(sim, features, service, srv_type, fields):
    flag = {'get_entity_state': F.ENTITY_STATE_GETTING, 'set_entity_state': F.ENTITY_STATE_SETTING,
            'get_entity_info': F.ENTITY_INFO_GETTING, 'get_entity_bounds': F.ENTITY_BOUNDS,
            'delete_entity': F.DELETING}[service]
    needs(features, flag)
    res = raw(sim, service, srv_type, entity='no_such_entity_here', **fields)
    assert res.result.result == NOT_FOUND, res.result.error_message


def test_rule_11_a_twist_for_a_static_entity_answers_4_and_moves_nothing(sim, features):
    needs(features, F.ENTITY_STATE_SETTING)
    name = static_entity(sim)
    before = sim.entity_state(name)
    state = EntityState()
    p = before['position']
    state.pose.position.x, state.pose.position.y, state.pose.position.z = \
        p[0] + 0.3, p[1], p[2]
    state.pose.orientation.w = 1.0
    state.twist.linear = Vector3(x=1.0)
    res = raw(sim, 'set_entity_state', srv.SetEntityState, entity=name, state=state)
    assert res.result.result == OPERATION_FAILED, res.result.error_message
    assert sim.entity_state(name)['position'] == pytest.approx(p, abs=1e-9)


@pytest.mark.parametrize('quat', [(0, 0, 0, 0), (math.nan, 0, 0, 1)], ids=['zero', 'nan'])
def test_rule_12_bad_quaternions_are_invalid_poses_and_spawn_nothing(sim, features, quat):
    needs(features, F.ENTITY_STATE_SETTING, F.SPAWNING)
    name = sim.entities(categories=[EntityCategory.CATEGORY_DYNAMIC_OBJECT])[0]
    state = EntityState()
    state.pose.position.z = 1.0
    state.pose.orientation.x, state.pose.orientation.y, state.pose.orientation.z, \
        state.pose.orientation.w = map(float, quat)
    res = raw(sim, 'set_entity_state', srv.SetEntityState, entity=name, state=state)
    assert res.result.result == srv.SetEntityState.Response.INVALID_POSE
    before = set(sim.entities())
    req = srv.SpawnEntity.Request(name='conformance_item', uri=spawnable(sim))
    req.initial_pose.pose = state.pose
    res = sim.call('spawn_entity', srv.SpawnEntity, req, check=False)
    assert res.result.result == srv.SpawnEntity.Response.INVALID_POSE
    assert set(sim.entities()) == before


def test_rule_13_twist_is_in_the_header_frame_not_the_body_axes(sim, features):
    needs(features, F.ENTITY_STATE_SETTING, F.SPAWNING, F.STEP_SIMULATION_MULTIPLE)
    yaw = math.pi / 2
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=(0.0, -2.5, 3.0),
                     orientation_xyzw=(0, 0, math.sin(yaw / 2), math.cos(yaw / 2)))
    sim.pause()
    sim.set_entity_state(name, (0.0, -2.5, 3.0), (0, 0, math.sin(yaw / 2), math.cos(yaw / 2)),
                         linear=(1.0, 0.0, 0.0))
    t0 = sim_time(sim)
    sim.step(50)
    moved = sim.entity_state(name)
    elapsed = sim_time(sim) - t0
    assert moved['position'][0] == pytest.approx(elapsed, rel=0.05)  # world +x
    assert moved['position'][1] == pytest.approx(-2.5, abs=1e-3)


def test_rule_14_a_taken_name_is_refused_or_renamed(sim, features):
    needs(features, F.SPAWNING)
    taken = sim.entities()[0]
    before = set(sim.entities())
    req = srv.SpawnEntity.Request(name=taken, uri=spawnable(sim))
    req.initial_pose.pose.position.z, req.initial_pose.pose.position.y = 2.0, -2.0
    req.initial_pose.pose.orientation.w = 1.0
    res = sim.call('spawn_entity', srv.SpawnEntity, req, check=False)
    assert res.result.result == srv.SpawnEntity.Response.NAME_NOT_UNIQUE
    assert set(sim.entities()) == before
    req.allow_renaming = True
    res = sim.call('spawn_entity', srv.SpawnEntity, req, check=False)
    assert res.result.result == OK and res.entity_name and res.entity_name != taken
    assert sim.entity_state(res.entity_name)['stamp'] >= 0
    sim.delete(res.entity_name)
    assert res.entity_name not in sim.entities()


def test_rule_15_no_resource_is_104_for_spawn_and_102_for_load_world(sim, features):
    needs(features, F.SPAWNING)
    res = raw(sim, 'spawn_entity', srv.SpawnEntity, name='conformance_item')
    assert res.result.result == srv.SpawnEntity.Response.NO_RESOURCE
    if F.WORLD_LOADING in features:
        res = raw(sim, 'load_world', srv.LoadWorld)
        assert res.result.result == srv.LoadWorld.Response.NO_RESOURCE


def test_rule_16_uri_wins_over_resource_string(sim, features):
    needs(features, F.SPAWNING)
    req = srv.SpawnEntity.Request(name='conformance_item', uri=spawnable(sim),
                                  resource_string='this is not any format at all')
    req.initial_pose.pose.position.z, req.initial_pose.pose.position.y = 2.0, -2.0
    req.initial_pose.pose.orientation.w = 1.0
    res = sim.call('spawn_entity', srv.SpawnEntity, req, check=False)
    assert res.result.result == OK, res.result.error_message
    if F.SPAWNING_RESOURCE_STRING not in features:
        res = raw(sim, 'spawn_entity', srv.SpawnEntity, name='x2', resource_string='<x/>')
        assert res.result.result == UNSUPPORTED


def test_rule_17_entity_filters_are_posix_ere_and_combine_with_and(sim, features):
    everything = sim.entities()
    assert everything and len(set(everything)) == len(everything)
    name = everything[0]
    assert sim.entities(pattern=f'^{re.escape(name)}$') == [name]
    if F.ENTITY_CATEGORIES in features:
        category = sim.entity_info(name).category.category
        other = next(c for c in (EntityCategory.CATEGORY_ROBOT,
                                 EntityCategory.CATEGORY_STATIC_OBJECT) if c != category)
        assert sim.entities(pattern=f'^{re.escape(name)}$', categories=[other]) == []
    req = srv.GetEntities.Request()
    if F.ENTITY_BOUNDS_CONVEX not in features:
        req.filters.bounds = Bounds(type=Bounds.TYPE_CONVEX_HULL,
                                    points=[Vector3(), Vector3(x=1.0), Vector3(y=1.0),
                                            Vector3(z=1.0)])
        assert sim.call('get_entities', srv.GetEntities, req,
                        check=False).result.result == UNSUPPORTED
    req.filters.bounds = Bounds(type=Bounds.TYPE_SPHERE,
                                points=[Vector3(), Vector3(x=1e6, y=0.0, z=0.0)])
    assert sim.call('get_entities', srv.GetEntities, req, check=False).result.result == OK
    if F.ENTITY_BOUNDS_BOX not in features:
        req.filters.bounds = Bounds(type=Bounds.TYPE_BOX,
                                    points=[Vector3(x=-1e6, y=-1e6, z=-1e6),
                                            Vector3(x=1e6, y=1e6, z=1e6)])
        assert sim.call('get_entities', srv.GetEntities, req,
                        check=False).result.result == UNSUPPORTED


def test_rule_18_categories_are_0_1_2_4_5_and_static_objects_are_5(sim, features):
    needs(features, F.ENTITY_CATEGORIES, F.ENTITY_INFO_GETTING)
    seen = {sim.entity_info(n).category.category for n in sim.entities()}
    assert seen <= {0, 1, 2, 4, 5}
    assert sim.entity_info(static_entity(sim)).category.category == \
        EntityCategory.CATEGORY_STATIC_OBJECT


def test_rule_19_reset_scope_0_is_scope_255(sim, features):
    needs(features, F.SIMULATION_RESET, F.STEP_SIMULATION_MULTIPLE)
    sim.pause()
    sim.reset(255)
    start, picture = sim_time(sim), world_picture(sim)
    for scope in (0, 255):
        sim.pause()
        if F.SPAWNING in features:
            sim.spawn('conformance_item', uri=spawnable(sim), position=(0.5, -2.0, 2.0))
        sim.step(100)
        assert world_picture(sim) != picture
        sim.reset(scope)
        sim.pause()  # [open] whether a reset keeps playing: look at it paused
        assert 'conformance_item' not in sim.entities()
        assert sim_time(sim) == pytest.approx(start, abs=1e-9)
        assert world_picture(sim) == picture, scope
    for flag, bit in ((F.SIMULATION_RESET_TIME, 1), (F.SIMULATION_RESET_STATE, 2),
                      (F.SIMULATION_RESET_SPAWNED, 4)):
        if flag not in features:
            assert raw(sim, 'reset_simulation', srv.ResetSimulation,
                       scope=bit).result.result == UNSUPPORTED


def test_rule_20_every_listed_feature_answers_and_unlisted_ones_are_unsupported(sim, features):
    names = {n for n, _ in sim.node.get_service_names_and_types()}
    prefix = f'{NAMESPACE.rstrip("/")}/' if NAMESPACE else '/'
    interfaces = {F.SPAWNING: 'spawn_entity', F.DELETING: 'delete_entity',
                  F.ENTITY_STATE_GETTING: 'get_entity_state',
                  F.ENTITY_STATE_SETTING: 'set_entity_state',
                  F.ENTITY_INFO_GETTING: 'get_entity_info',
                  F.ENTITY_INFO_SETTING: 'set_entity_info', F.ENTITY_BOUNDS: 'get_entity_bounds',
                  F.NAMED_POSES: 'get_named_poses', F.POSE_BOUNDS: 'get_named_pose_bounds',
                  F.SPAWNABLES: 'get_spawnables', F.SIMULATION_RESET: 'reset_simulation',
                  F.SIMULATION_STATE_GETTING: 'get_simulation_state',
                  F.SIMULATION_STATE_SETTING: 'set_simulation_state',
                  F.STEP_SIMULATION_SINGLE: 'step_simulation',
                  F.STEP_SIMULATION_ACTION: 'simulate_steps/_action/send_goal',
                  F.WORLD_LOADING: 'load_world', F.WORLD_UNLOADING: 'unload_world',
                  F.WORLD_INFO_GETTING: 'get_current_world', F.AVAILABLE_WORLDS:
                  'get_available_worlds', F.SPAWNING_ENTITIES: 'spawn_entities'}
    for flag, service in interfaces.items():
        if flag in features:
            assert prefix + service in names, f'feature {flag} is listed: {service} must exist'
    if F.ENTITY_STATE_GETTING in features:
        assert prefix + 'get_entities_states' in names
    # An unlisted feature whose interface is served must answer FEATURE_UNSUPPORTED (0).
    unlisted = [(F.ENTITY_INFO_SETTING, 'set_entity_info', srv.SetEntityInfo,
                 {'entity': sim.entities()[0]}),
                (F.NAMED_POSES, 'get_named_poses', srv.GetNamedPoses, {}),
                (F.POSE_BOUNDS, 'get_named_pose_bounds', srv.GetNamedPoseBounds,
                 {'name': 'anything'})]
    for flag, service, srv_type, fields in unlisted:
        if flag not in features and prefix + service in names:
            res = raw(sim, service, srv_type, **fields)
            assert res.result.result == UNSUPPORTED and res.result.error_message, service
    if not EXTERNAL:  # this node serves them, to say why
        assert all(prefix + s in names for _, s, _, _ in unlisted)


# ------------------------------------------------------------------ §4: per-service rules

def test_spawn_entities_reports_per_item_and_150_when_one_fails(sim, features):
    needs(features, F.SPAWNING_ENTITIES)
    results = sim.spawn_entities([
        {'name': 'conformance_a', 'uri': spawnable(sim), 'position': (0.5, -2.0, 2.0)},
        {'name': 'conformance_b'},  # no resource
    ])
    assert [r[0] for r in results] == [OK, srv.SpawnEntity.Response.NO_RESOURCE]
    assert sim.spawn_entities([]) == []


def test_get_entities_states_lists_are_parallel(sim, features):
    needs(features, F.ENTITY_STATE_GETTING)
    res = raw(sim, 'get_entities_states', srv.GetEntitiesStates)
    assert res.result.result == OK and len(res.entities) == len(res.states) > 0
    name = res.entities[-1]
    one = sim.entity_state(name)
    assert one['position'] == pytest.approx(
        (res.states[-1].pose.position.x, res.states[-1].pose.position.y,
         res.states[-1].pose.position.z), abs=0.5)


def test_get_simulator_features_has_no_result_and_lists_spawn_formats(sim, features):
    res = raw(sim, 'get_simulator_features', srv.GetSimulatorFeatures)
    assert not hasattr(res, 'result')
    if F.SPAWNING in features:
        assert res.features.spawn_formats


def test_get_spawnables_names_unrecognised_sources_and_still_succeeds(sim, features):
    needs(features, F.SPAWNABLES)
    res = raw(sim, 'get_spawnables', srv.GetSpawnables,
              sources=['/no/such/place/conformance'])
    assert res.result.result == OK
    assert '/no/such/place/conformance' in res.result.error_message
    assert res.spawnables  # the defaults are still listed


def test_get_entity_state_names_its_frame_and_stamps_simulation_time(sim, features):
    needs(features, F.ENTITY_STATE_GETTING, F.STEP_SIMULATION_MULTIPLE)
    sim.pause()
    name = sim.entities()[0]
    t0 = sim.entity_state(name)['stamp']
    sim.step(10)
    st = sim.entity_state(name)
    assert st['frame_id'] and st['stamp'] > t0


def test_zero_twist_means_stop_not_leave_unchanged(sim, features):
    needs(features, F.ENTITY_STATE_SETTING, F.SPAWNING, F.STEP_SIMULATION_MULTIPLE)
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=(0.0, -2.5, 3.0))
    sim.pause()
    sim.step(100)  # falling
    assert abs(sim.entity_state(name)['linear'][2]) > 0.5
    sim.set_entity_state(name, (0.0, -2.5, 3.0))  # twist left at zero
    st = sim.entity_state(name)
    assert st['linear'] == pytest.approx((0, 0, 0), abs=1e-9)
    assert st['position'] == pytest.approx((0.0, -2.5, 3.0), abs=1e-9)


def test_reset_time_only_keeps_the_poses(sim, features):
    needs(features, F.SIMULATION_RESET_TIME, F.STEP_SIMULATION_MULTIPLE)
    sim.pause()
    sim.reset(255)
    start = sim_time(sim)
    sim.step(200)
    picture = world_picture(sim)
    sim.reset(1)
    assert sim_time(sim) == pytest.approx(start, abs=1e-9)
    assert world_picture(sim) == picture


def test_entity_bounds_are_a_box_by_default(sim, features):
    needs(features, F.ENTITY_BOUNDS)
    kind, points = sim.entity_bounds(sim.entities()[0])
    assert kind == Bounds.TYPE_BOX and len(points) == 2


def test_entity_bounds_are_in_the_entitys_own_frame(sim, features):
    """§4.10: in the entity's canonical link frame: moving or turning it changes nothing."""
    needs(features, F.ENTITY_BOUNDS, F.ENTITY_STATE_SETTING, F.SPAWNING)
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=(1.5, -2.5, 1.5))
    sim.pause()
    sim.set_entity_state(name, (1.5, -2.5, 1.5))
    kind, first = sim.entity_bounds(name)
    yaw = 0.7
    sim.set_entity_state(name, (-1.0, -2.0, 2.5), (0, 0, math.sin(yaw / 2), math.cos(yaw / 2)))
    _, moved = sim.entity_bounds(name)
    assert kind == Bounds.TYPE_BOX
    assert [c for p in moved for c in p] == pytest.approx([c for p in first for c in p],
                                                          abs=1e-9)
    lo, hi = first
    assert all(a < b for a, b in zip(lo, hi))


def test_unload_then_load_world_states_and_codes(sim, features):
    needs(features, F.WORLD_LOADING, F.WORLD_UNLOADING, F.WORLD_INFO_GETTING)
    uri = raw(sim, 'get_current_world', srv.GetCurrentWorld).world.world_resource.uri
    try:
        sim.unload_world()
        assert sim.state() == S.STATE_NO_WORLD
        assert raw(sim, 'get_current_world', srv.GetCurrentWorld).result.result == \
            srv.GetCurrentWorld.Response.NO_WORLD_LOADED
        assert raw(sim, 'unload_world', srv.UnloadWorld).result.result == \
            srv.UnloadWorld.Response.NO_WORLD_LOADED
        res = raw(sim, 'set_simulation_state', srv.SetSimulationState,
                  state=SimulationState(state=S.STATE_PLAYING))
        # [open]: 103 (O3DE) or 3; never OK
        assert res.result.result in (srv.SetSimulationState.Response.INCORRECT_TRANSITION,
                                     Result.RESULT_INCORRECT_STATE)
    finally:
        res = raw(sim, 'load_world', srv.LoadWorld, uri=uri)
    assert res.result.result == OK, res.result.error_message
    assert sim.state() == S.STATE_STOPPED  # a loaded world is left STOPPED
