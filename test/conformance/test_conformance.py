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
a static entity (category 5). ``[open]`` rules (the text leaves them open) check this node's
documented choice, or with ``SIM_CONFORMANCE_EXTERNAL`` only that the answer is one of the
readings.

Every rule of ``standard_rules.md`` and its test (``rule_NN``: §6, the twenty rules most often
broken; ``sN``: §1-§4; other names: per-service checks)::

    §1  success is 1 on every service; codes always set ........ rule_01
    §1  every name spawn/GetEntities gives works everywhere ..... s1_every_listed_name_...
    §1  empty frame_id is the world; request stamps ignored ..... s1_an_empty_frame_...
    §1  the service names; GetSimulatorFeatures always there .... rule_20, get_simulator_...
    §1  output fields only meaningful on OK ..................... (a rule for callers)
    §2  EntityState: frame named, stamp = simulation time ....... get_entity_state_names_...
    §2  twist in the header frame, world axes (set; read) ....... rule_13, s2_a_twist_reads_...
    §2  acceleration may be ignored when set .................... rule_11 (refused when static)
    §2  categories 0 1 2 4 5, static objects 5 .................. rule_18
    §2  categories filter: any listed category .................. s2_categories_filter_...
    §2  name filter is a POSIX ERE; filter parts AND ............ rule_17
    §2  tags filter needs ENTITY_TAGS (4) ....................... s2_tag_filters_need_...
    §2  bounds filter: overlap; sphere always; box/hull by flag . s2_a_bounds_filter_..., rule_17
    §2  a bounds type no simulator has is 0 ..................... s2_a_bounds_type_...
    §2  bounds take 0, 2 or >= 3 points ......................... s2_bounds_with_the_wrong_...
    §2  entity bounds in the entity's canonical link frame ...... entity_bounds_are_in_...
    §2  every Spawnable uri is a value SpawnEntity accepts ...... s2_every_spawnable_spawns
    §2  Resource: a uri wins over resource_string ............... rule_16, s2_a_resources_uri_...
    §2  SimulatorFeatures lists what works, with spawn_formats .. rule_20, get_simulator_...
    §3  STOPPED = paused + full reset ........................... rule_07
    §3  PLAYING <-> PAUSED, both -> STOPPED, STOPPED -> PLAYING . s3_transitions_...
    §3  QUITTING stops, then exits .............................. rule_09
    §3  NO_WORLD cannot be played, paused or stopped ............ unload_then_load_world_...
    §3  LOADING_WORLD reported; not played or paused meanwhile .. s3_loading_world_...
    §3  101 already there; 103 not allowed; PAUSED needs 26 ..... rule_06, rule_08
    §3  102 a transition tried and failed ....................... (only after an internal
                                                                  failure of this node's loop)
    §3  [open] STOPPED -> PAUSED ................................ rule_08
    §3  [open] 4 or 5 requested by a client ..................... s3_no_and_loading_world_...
    §3  [open] a reset keeps playing or paused .................. s3_a_reset_keeps_...
    §3  after LoadWorld STOPPED, UnloadWorld NO_WORLD, a step
        PAUSED .................................................. s420_load_world_removes_...,
                                                                  unload_then_load_..., rule_03
    §4.1  an empty name takes the resource's own ................ s41_an_empty_name_...
    §4.1  no name at all: 102, or a made-up unique one .......... s41_no_name_anywhere_...
    §4.1  101 a taken name; renaming gives a usable name ........ rule_14
    §4.1  102 a name against the rules .......................... s41_a_name_breaking_...
    §4.1  103 a format not read ................................. s41_a_format_not_read_...
    §4.1  104 no resource ....................................... rule_15
    §4.1  105 a bad namespace ................................... s41_a_bad_namespace_...
    §4.1  the entity's interfaces go under its namespace ........ s41_an_entitys_interfaces_...
    §4.1  106 parse error; 107 missing asset; 108 unsupported
          asset ............................................... s41_a_resource_that_...,
                                                                  s41_a_missing_...,
                                                                  s41_an_asset_...
    §4.1  109 bad quaternion; position outside the world ........ rule_12, s41_a_position_...
    §4.1  resource_string needs SPAWNING_RESOURCE_STRING (9) .... rule_16
    §4.1  a pose in an entity's frame; [open] an unknown frame .. s41_a_pose_may_...,
                                                                  s41_an_unknown_...
    §4.1  a default Pose is valid (w = 1) ....................... s41_a_default_orientation_...
    §4.1  a refused spawn adds nothing .......................... assert_refused, rule_12,
                                                                  rule_14
    §4.2  one result per item, in order; 150; an empty list ..... spawn_entities_reports_...
    §4.2  [open] partial success; a name twice in one batch ..... spawn_entities_reports_...,
                                                                  s42_the_same_name_...
    §4.3  unknown name 2; [open] deleting a scene entity ........ rule_10, s43_deleting_...
    §4.4  default filters list all; unsupported filter 0 ........ rule_17
    §4.5  parallel lists; the filters apply ..................... get_entities_states_lists_...,
                                                                  s45_get_entities_states_...
    §4.6  unknown 2; frame and stamp filled ..................... rule_10, get_entity_state_...
    §4.7-8  info: unknown 2; SetEntityInfo unlisted answers 0 ... rule_10, rule_20
    §4.9  a teleport; zero twist means stop ..................... zero_twist_means_stop_...
    §4.9  stamp ignored; frame of pose and twist ................ s1_an_empty_frame_...,
                                                                  s49_pose_and_twist_...
    §4.9  static: twist or acceleration 4, nothing applied ...... rule_11 (both)
    §4.9  101 bad quaternion or outside the world; unknown 2 .... rule_12, s49_a_position_...,
                                                                  rule_10
    §4.10 a box by default, in the entity's frame; unknown 2 .... entity_bounds_are_a_box_...,
                                                                  entity_bounds_are_in_..., rule_10
    §4.11-12 named poses: unlisted, answer 0 .................... rule_20
    §4.13 unrecognised sources named, still OK .................. get_spawnables_names_...
    §4.14 GetSimulatorFeatures has no Result .................... get_simulator_features_...
    §4.15 GetSimulationState answers OK (field order: the
          released type hash, test_interfaces) .................. rule_01
    §4.16 a default request asks for STOPPED .................... rule_06
    §4.17 scope 0 = 255; each bit its part; unknown bits 0 ...... rule_19, s417_each_scope_bit_...,
                                                                  reset_time_only_...,
                                                                  s417_a_scope_...
    §4.18 only while paused (4), n steps, stays paused; default
          1; > 1 needs 32 ....................................... rule_02, rule_03, rule_04
    §4.18 [open] steps = 0; stepping from STOPPED ............... s418_zero_steps_...,
                                                                  s418_stepping_from_stopped
    §4.19 feedback after each step; 1 when done, 4 not paused ... rule_05
    §4.19 [open] a cancel stops stepping, stays paused .......... s419_a_cancel_...
    §4.20 unloads first, spawned entities gone, STOPPED ......... s420_load_world_removes_...
    §4.20 101-106; [open] a failed load keeps the world ......... s420_codes_and_a_failed_...
    §4.20 102 no resource ....................................... rule_15
    §4.20 unsupported elements left out unless asked to fail .... s420_unsupported_elements_...
    §4.21-22 101 without a world; NO_WORLD after unloading ...... unload_then_load_world_...
    §4.23 tag filter needs 42; failed sources; continue_on_error  s423_world_tags_...
"""

import math
import os
import re
import threading
import time

from conftest import NodeProcess
from geometry_msgs.msg import Vector3
import pytest
from sim_node.ros.client import SimClient, SimServiceError
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
    for n in (20, 250):  # one message per step: completed 1...n, remaining n-1...0
        seen = []
        result = sim.simulate_steps(n, feedback=lambda done, left: seen.append((done, left)))
        assert result.result == OK
        assert seen == [(k, n - k) for k in range(1, n + 1)]
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
        own.set_state(S.STATE_QUITTING)  # answered OK before it goes
        assert proc.proc.wait(5) == 0, proc.output()  # how fast: make bench-pacing
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


@pytest.mark.parametrize('part', ['twist', 'acceleration'])
def test_rule_11_a_twist_for_a_static_entity_answers_4_and_moves_nothing(sim, features, part):
    """And an acceleration (§4.9): nothing is applied, not even the pose."""
    needs(features, F.ENTITY_STATE_SETTING)
    name = static_entity(sim)
    before = sim.entity_state(name)
    state = EntityState()
    p = before['position']
    state.pose.position.x, state.pose.position.y, state.pose.position.z = \
        p[0] + 0.3, p[1], p[2]
    state.pose.orientation.w = 1.0
    getattr(state, part).linear = Vector3(x=1.0)
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
    prefix = f'{NAMESPACE.rstrip("/")}/' if NAMESPACE else '/'

    def served(service: str) -> bool:  # a server, not only clients (ours among them)
        return sim.node.count_services(prefix + service) > 0
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
            assert served(service), f'feature {flag} is listed: {service} must exist'
    if F.ENTITY_STATE_GETTING in features:
        assert served('get_entities_states')
    # An unlisted feature whose interface is served must answer FEATURE_UNSUPPORTED (0).
    unlisted = [(F.ENTITY_INFO_SETTING, 'set_entity_info', srv.SetEntityInfo,
                 {'entity': sim.entities()[0]}),
                (F.NAMED_POSES, 'get_named_poses', srv.GetNamedPoses, {}),
                (F.POSE_BOUNDS, 'get_named_pose_bounds', srv.GetNamedPoseBounds,
                 {'name': 'anything'})]
    for flag, service, srv_type, fields in unlisted:
        if flag not in features and served(service):
            res = raw(sim, service, srv_type, **fields)
            assert res.result.result == UNSUPPORTED and res.result.error_message, service
    if not EXTERNAL:  # this node serves them, to say why
        assert all(served(s) for _, s, _, _ in unlisted)


# ------------------------------------------------------------------ §4: per-service rules

def test_spawn_entities_reports_per_item_and_150_when_one_fails(sim, features):
    needs(features, F.SPAWNING_ENTITIES)
    results = sim.spawn_entities([
        {'name': 'conformance_a', 'uri': spawnable(sim), 'position': (0.5, -2.0, 2.0)},
        {'name': 'conformance_b'},  # no resource
    ])
    assert [r[0] for r in results] == [OK, srv.SpawnEntity.Response.NO_RESOURCE]
    assert 'conformance_a' in sim.entities()  # [open] the good one stays (partial success)
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


# ------------------------------------------------------------------ §1-§4: every other rule

def spawn_raw(sim: SimClient, position=(0.5, -2.0, 2.0), frame_id: str = '', **fields):
    """Call spawn_entity with a pose (identity rotation) and return the response, any code."""
    req = srv.SpawnEntity.Request(**fields)
    req.initial_pose.header.frame_id = frame_id
    p = req.initial_pose.pose.position
    p.x, p.y, p.z = map(float, position)
    return sim.call('spawn_entity', srv.SpawnEntity, req, check=False)


def assert_refused(sim: SimClient, code: int, **fields) -> str:
    """Check that a spawn answers `code` (with a message) and adds nothing; return it."""
    before = set(sim.entities())
    res = spawn_raw(sim, **fields)
    assert res.result.result == code, res.result.error_message
    assert res.result.error_message
    assert set(sim.entities()) == before
    return res.result.error_message


def text_format(features_msg) -> str:
    """'urdf' or 'mjcf', whichever resource_string format the simulator lists (URDF first)."""
    formats = {f.lower() for f in features_msg.spawn_formats}
    for kind in ('urdf', 'mjcf'):
        if kind in formats:
            return kind
    pytest.skip('neither URDF nor MJCF is a listed spawn format')


def model_text(kind: str, name: str = '', mesh: str = '', joint: bool = False) -> str:
    """Return a small model (a box, or with `joint` an arm of two links), URDF or MJCF."""
    if kind == 'urdf':
        inertial = ('<inertial><mass value="1"/><inertia ixx=".01" iyy=".01" izz=".01" '
                    'ixy="0" ixz="0" iyz="0"/></inertial>')
        shape = f'<mesh filename="{mesh}"/>' if mesh else '<box size=".1 .1 .1"/>'
        links = (f'<link name="base">{inertial}<collision><geometry>{shape}</geometry>'
                 '</collision></link>')
        if joint:
            links += (f'<link name="tip">{inertial}<collision><origin xyz="0.1 0 0"/><geometry>'
                      '<box size=".1 .05 .05"/></geometry></collision></link><joint name="j" '
                      'type="revolute"><parent link="base"/><child link="tip"/><origin '
                      'xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" '
                      'effort="1" velocity="1"/></joint>')
        return f'<robot name="{name}">{links}</robot>' if name else f'<robot>{links}</robot>'
    asset = f'<asset><mesh name="m" file="{mesh}"/></asset>' if mesh else ''
    geom = '<geom type="mesh" mesh="m"/>' if mesh else '<geom type="box" size=".05 .05 .05"/>'
    tip = ('<body pos="0 0 .1"><joint name="j" type="hinge" range="-1 1"/>'
           '<geom type="box" size=".1 .025 .025" pos=".1 0 0"/></body>') if joint else ''
    attr = f' model="{name}"' if name else ''
    return (f'<mujoco{attr}>{asset}<worldbody><body><freejoint/>{geom}{tip}</body>'
            '</worldbody></mujoco>')


# §1: every interface

def test_s1_every_listed_name_works_with_every_entity_service(sim, features):
    needs(features, F.ENTITY_STATE_GETTING, F.ENTITY_STATE_SETTING)
    sim.pause()
    names = sim.entities()
    if F.SPAWNING in features:
        names.append(sim.spawn('conformance_item', uri=spawnable(sim), position=(0.5, -2.0, 2.0)))
    for name in names:
        st = raw(sim, 'get_entity_state', srv.GetEntityState, entity=name)
        assert st.result.result == OK, name
        state = st.state
        state.twist = type(state.twist)()  # its own pose, at rest: valid for every entity
        state.acceleration = type(state.acceleration)()
        res = raw(sim, 'set_entity_state', srv.SetEntityState, entity=name, state=state)
        assert res.result.result == OK, (name, res.result.error_message)
        for service, srv_type, flag in (
                ('get_entity_info', srv.GetEntityInfo, F.ENTITY_INFO_GETTING),
                ('get_entity_bounds', srv.GetEntityBounds, F.ENTITY_BOUNDS)):
            if flag in features:
                assert raw(sim, service, srv_type, entity=name).result.result == OK, \
                    (service, name)


def test_s1_an_empty_frame_is_the_world_and_request_stamps_are_ignored(sim, features):
    needs(features, F.SPAWNING, F.ENTITY_STATE_SETTING, F.STEP_SIMULATION_SINGLE)
    sim.pause()
    req = srv.SpawnEntity.Request(name='conformance_item', uri=spawnable(sim))
    req.initial_pose.header.stamp.sec = 123456  # neither past nor present: ignored
    req.initial_pose.pose.position.y, req.initial_pose.pose.position.z = -2.0, 2.0
    assert sim.call('spawn_entity', srv.SpawnEntity, req, check=False).result.result == OK
    got = sim.entity_state('conformance_item')['position']
    assert got == pytest.approx((0, -2.0, 2.0), abs=1e-9)
    state = EntityState()
    state.header.stamp.sec = 654321
    state.pose.position.x, state.pose.position.y, state.pose.position.z = 0.4, -2.5, 1.5
    state.pose.orientation.w = 1.0
    res = raw(sim, 'set_entity_state', srv.SetEntityState, entity='conformance_item',
              state=state)
    assert res.result.result == OK, res.result.error_message
    got = sim.entity_state('conformance_item')
    assert got['position'] == pytest.approx((0.4, -2.5, 1.5), abs=1e-9)
    assert got['stamp'] < 1000  # the simulation's time, not the request's


# §2: messages

def test_s2_a_twist_reads_back_in_world_axes(sim, features):
    """A velocity written reads back the same, in the header (world) frame, whatever the yaw."""
    needs(features, F.SPAWNING, F.ENTITY_STATE_SETTING)
    yaw = 2.0
    q = (0, 0, math.sin(yaw / 2), math.cos(yaw / 2))
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=(0.0, -2.5, 3.0),
                     orientation_xyzw=q)
    sim.pause()
    sim.set_entity_state(name, (0.0, -2.5, 3.0), q, linear=(1.0, 0.5, -0.25),
                         angular=(0.0, 0.3, 0.7))
    st = sim.entity_state(name)
    assert st['linear'] == pytest.approx((1.0, 0.5, -0.25), abs=1e-9)
    assert st['angular'] == pytest.approx((0.0, 0.3, 0.7), abs=1e-9)


def test_s2_categories_filter_keeps_any_listed_category(sim, features):
    needs(features, F.ENTITY_CATEGORIES)
    robot, static = EntityCategory.CATEGORY_ROBOT, EntityCategory.CATEGORY_STATIC_OBJECT
    one, other = sim.entities(categories=[robot]), sim.entities(categories=[static])
    both = sim.entities(categories=[robot, static])
    assert sorted(both) == sorted(one + other) and one and other


def region_filter(sim: SimClient, kind: int, points) -> list:
    req = srv.GetEntities.Request()
    req.filters.bounds = Bounds(type=kind, points=[Vector3(x=float(p[0]), y=float(p[1]),
                                                           z=float(p[2])) for p in points])
    res = sim.call('get_entities', srv.GetEntities, req, check=False)
    assert res.result.result == OK, res.result.error_message
    return list(res.entities)


def test_s2_a_bounds_filter_keeps_entities_that_overlap_it(sim, features):
    """Overlap, not containment of the origin: a sphere grazing the entity's box finds it."""
    needs(features, F.SPAWNING, F.ENTITY_BOUNDS, F.STEP_SIMULATION_SINGLE)
    sim.pause()
    at = (2.5, -3.5, 2.5)  # a free place, in the air (paused: it stays)
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=at)
    _, (lo, hi) = sim.entity_bounds(name)  # its own frame = the world's axes here
    top = max(lo[2], hi[2]) + at[2]
    centre = (at[0], at[1], top + 0.05)  # 5 cm above its top face, off its origin
    assert region_filter(sim, Bounds.TYPE_SPHERE, [centre, (0.0501, 0, 0)]) == [name]
    assert name not in region_filter(sim, Bounds.TYPE_SPHERE, [centre, (0.0499, 0, 0)])
    if F.ENTITY_BOUNDS_BOX in features:  # a box touching its top face only
        box = [(at[0] - 0.01, at[1] - 0.01, top - 0.001), (at[0] + 0.01, at[1] + 0.01, top + 1)]
        assert region_filter(sim, Bounds.TYPE_BOX, box) == [name]
        assert region_filter(sim, Bounds.TYPE_BOX, box[::-1]) == [name]  # either corner first


def test_s2_a_bounds_type_no_simulator_has_is_unsupported(sim, features):
    req = srv.GetEntities.Request()
    req.filters.bounds = Bounds(type=7, points=[Vector3(), Vector3(x=1.0)])
    assert sim.call('get_entities', srv.GetEntities, req, check=False).result.result == \
        UNSUPPORTED


def test_s2_bounds_with_the_wrong_number_of_points_are_refused(sim, features):
    req = srv.GetEntities.Request()
    for kind, n in ((Bounds.TYPE_SPHERE, 1), (Bounds.TYPE_BOX, 1), (Bounds.TYPE_BOX, 3)):
        req.filters.bounds = Bounds(type=kind, points=[Vector3(x=float(i)) for i in range(n)])
        res = sim.call('get_entities', srv.GetEntities, req, check=False)
        assert res.result.result != OK and res.result.error_message, (kind, n)


def test_s2_tag_filters_need_entity_tags(sim, features):
    if F.ENTITY_TAGS in features:
        pytest.skip('ENTITY_TAGS is listed')
    for mode in (0, 1):
        req = srv.GetEntities.Request()
        req.filters.tags.tags, req.filters.tags.filter_mode = ['conformance'], mode
        assert sim.call('get_entities', srv.GetEntities, req,
                        check=False).result.result == UNSUPPORTED
        if F.ENTITY_STATE_GETTING in features:
            req2 = srv.GetEntitiesStates.Request()
            req2.filters = req.filters
            assert sim.call('get_entities_states', srv.GetEntitiesStates, req2,
                            check=False).result.result == UNSUPPORTED


def test_s2_every_spawnable_spawns(sim, features):
    needs(features, F.SPAWNABLES, F.SPAWNING, F.DELETING)
    sim.pause()
    for i, uri in enumerate(sim.spawnables()):
        res = spawn_raw(sim, name=f'conformance_s{i}', uri=uri,
                        position=(-50.0 + 10.0 * i, 50.0, 5.0))
        assert res.result.result == OK, (uri, res.result.error_message)
        sim.delete(res.entity_name)


def test_s2_a_resources_uri_wins_over_its_string_in_spawn_entities(sim, features):
    needs(features, F.SPAWNING_ENTITIES)
    results = sim.spawn_entities([{'name': 'conformance_a', 'uri': spawnable(sim),
                                   'resource_string': 'not a model in any format',
                                   'position': (0.5, -2.0, 2.0)}])
    assert results == [(OK, 'conformance_a')]


# §3: the state machine

def test_s3_transitions_between_playing_paused_and_stopped(sim, features):
    needs(features, F.SIMULATION_STATE_SETTING, F.SIMULATION_STATE_PAUSE)
    ok_moves = [(S.STATE_PLAYING, S.STATE_PAUSED), (S.STATE_PAUSED, S.STATE_PLAYING),
                (S.STATE_PLAYING, S.STATE_STOPPED), (S.STATE_STOPPED, S.STATE_PLAYING),
                (S.STATE_PAUSED, S.STATE_STOPPED)]
    for start, target in ok_moves:
        sim.play() if start == S.STATE_PLAYING else sim.pause()
        if start == S.STATE_STOPPED:
            sim.set_state(S.STATE_STOPPED)
        assert sim.state() == start
        res = raw(sim, 'set_simulation_state', srv.SetSimulationState,
                  state=SimulationState(state=target))
        assert res.result.result == OK, (start, target, res.result.error_message)
        assert sim.state() == target


def test_s3_no_and_loading_world_cannot_be_requested(sim, features):
    """[open] A client asking for NO_WORLD (4) or LOADING_WORLD (5) is refused, state kept."""
    needs(features, F.SIMULATION_STATE_SETTING)
    for target in (S.STATE_NO_WORLD, S.STATE_LOADING_WORLD):
        res = raw(sim, 'set_simulation_state', srv.SetSimulationState,
                  state=SimulationState(state=target))
        assert res.result.result != OK and res.result.error_message
        assert sim.state() == S.STATE_PLAYING


def test_s3_a_reset_keeps_playing_or_paused(sim, features):
    """[open] This node keeps the play/pause state through a reset (as ros_gz does)."""
    needs(features, F.SIMULATION_RESET)
    if EXTERNAL:
        pytest.skip('a choice of this node')
    for state in (S.STATE_PLAYING, S.STATE_PAUSED):
        sim.play() if state == S.STATE_PLAYING else sim.pause()
        sim.reset(0)
        assert sim.state() == state


def test_s3_loading_world_is_reported_while_a_world_loads(sim, features):
    """While LoadWorld runs, GetSimulationState says 5, and play/pause/stop are refused."""
    needs(features, F.WORLD_LOADING, F.WORLD_RESOURCE_STRING)
    bodies = ''.join(f'<body pos="{i % 40} {i // 40} 1"><freejoint/><geom type="box" '
                     f'size=".1 .1 .1"/></body>' for i in range(1200))
    world = f'<mujoco><worldbody>{bodies}</worldbody></mujoco>'
    uri = raw(sim, 'get_current_world', srv.GetCurrentWorld).world.world_resource.uri
    watcher = SimClient(namespace=NAMESPACE, timeout_sec=10)  # its own node, in this thread
    outcome = []
    try:
        watcher.state()  # its clients are connected before the load starts
        loader = threading.Thread(target=lambda: outcome.append(
            sim.call('load_world', srv.LoadWorld, srv.LoadWorld.Request(resource_string=world),
                     check=False)))
        loader.start()
        seen, refused = set(), None
        deadline = time.monotonic() + 60
        while loader.is_alive() and time.monotonic() < deadline:
            state = raw(watcher, 'get_simulation_state', srv.GetSimulationState).state.state
            seen.add(state)
            if state == S.STATE_LOADING_WORLD and refused is None:
                refused = raw(watcher, 'set_simulation_state', srv.SetSimulationState,
                              state=SimulationState(state=S.STATE_PLAYING)).result.result
        loader.join(30)
        assert outcome and outcome[0].result.result == OK, outcome
        assert S.STATE_LOADING_WORLD in seen, seen
        assert refused in (srv.SetSimulationState.Response.INCORRECT_TRANSITION,
                           Result.RESULT_INCORRECT_STATE)
        assert sim.state() == S.STATE_STOPPED
    finally:
        watcher.close()
        sim.load_world(uri=uri)


# §4.1: SpawnEntity

def test_s41_an_empty_name_takes_the_name_inside_the_resource(sim, features):
    needs(features, F.SPAWNING, F.SPAWNING_RESOURCE_STRING)
    kind = text_format(sim.features())
    res = spawn_raw(sim, resource_string=model_text(kind, name='conformance_named'))
    assert res.result.result == OK, res.result.error_message
    assert res.entity_name == 'conformance_named'
    assert 'conformance_named' in sim.entities()


def test_s41_no_name_anywhere_is_102_or_a_made_up_unique_name(sim, features):
    needs(features, F.SPAWNING, F.SPAWNING_RESOURCE_STRING)
    text = model_text(text_format(sim.features()))
    assert_refused(sim, srv.SpawnEntity.Response.NAME_INVALID, resource_string=text)
    names = []
    for y in (-2.0, -3.0):
        res = spawn_raw(sim, resource_string=text, allow_renaming=True, position=(0.5, y, 2.0))
        assert res.result.result == OK and res.entity_name, res.result.error_message
        names.append(res.entity_name)
    assert len(set(names)) == 2 and all(n in sim.entities() for n in names)


def test_s41_a_name_breaking_the_naming_rules_is_102(sim, features):
    needs(features, F.SPAWNING)
    assert_refused(sim, srv.SpawnEntity.Response.NAME_INVALID, name='bad name\n!',
                   uri=spawnable(sim))


def test_s41_a_bad_namespace_is_105(sim, features):
    needs(features, F.SPAWNING)
    assert_refused(sim, srv.SpawnEntity.Response.NAMESPACE_INVALID, name='conformance_item',
                   uri=spawnable(sim), entity_namespace='9 not a namespace')


def test_s41_an_entitys_interfaces_go_under_its_namespace(sim, features):
    """This node's per-entity interfaces (robot_description, ...) move to the namespace."""
    needs(features, F.SPAWNING, F.SPAWNING_RESOURCE_STRING)
    if EXTERNAL:
        pytest.skip("the entity's interfaces are the simulator's own")
    kind = text_format(sim.features())
    res = spawn_raw(sim, name='conformance_arm', entity_namespace='/conformance_ns',
                    resource_string=model_text(kind, joint=True), position=(0.5, -2.5, 1.0))
    assert res.result.result == OK, res.result.error_message
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        topics = {n for n, _ in sim.node.get_topic_names_and_types()}
        if '/conformance_ns/robot_description' in topics:
            break
        time.sleep(0.2)
    assert '/conformance_ns/robot_description' in topics
    assert not any(t.endswith('conformance_arm/robot_description') for t in topics)


def test_s41_a_format_not_read_is_103(sim, features):
    needs(features, F.SPAWNING, F.SPAWNING_RESOURCE_STRING)
    assert_refused(sim, srv.SpawnEntity.Response.UNSUPPORTED_FORMAT, name='conformance_item',
                   resource_string='{"model": "a JSON document"}')


def test_s41_a_resource_that_does_not_parse_is_106(sim, features):
    needs(features, F.SPAWNING, F.SPAWNING_RESOURCE_STRING)
    text = model_text(text_format(sim.features()), name='x')
    assert_refused(sim, srv.SpawnEntity.Response.RESOURCE_PARSE_ERROR, name='conformance_item',
                   resource_string=text[:len(text) // 2])


def test_s41_a_missing_asset_is_107(sim, features):
    needs(features, F.SPAWNING, F.SPAWNING_RESOURCE_STRING)
    text = model_text(text_format(sim.features()), name='x',
                      mesh='/no/such/folder/conformance_mesh.stl')
    assert_refused(sim, srv.SpawnEntity.Response.MISSING_ASSETS, name='conformance_item',
                   resource_string=text)


def test_s41_an_asset_of_an_unsupported_kind_is_108(sim, features):
    """A file that exists but is no mesh (a model file the simulator lists) named as a mesh."""
    needs(features, F.SPAWNING, F.SPAWNING_RESOURCE_STRING, F.SPAWNABLES)
    files = [u[len('file://'):] for u in sim.spawnables() if u.startswith('file:///')]
    if not files:
        pytest.skip('no spawnable is a local file')
    text = model_text(text_format(sim.features()), name='x', mesh=files[0])
    assert_refused(sim, srv.SpawnEntity.Response.UNSUPPORTED_ASSETS, name='conformance_item',
                   resource_string=text)


def test_s41_a_pose_may_be_given_in_an_entitys_frame(sim, features):
    needs(features, F.SPAWNING)
    sim.pause()
    yaw = math.pi / 2
    q = (0, 0, math.sin(yaw / 2), math.cos(yaw / 2))
    base = sim.spawn('conformance_base', uri=spawnable(sim), position=(1.0, -3.0, 2.0),
                     orientation_xyzw=q)
    res = spawn_raw(sim, name='conformance_item', uri=spawnable(sim), position=(0.5, 0.0, 0.0),
                    frame_id=base)
    assert res.result.result == OK, res.result.error_message
    # 0.5 along the base's x, which the quarter turn points along world +y
    got = sim.entity_state('conformance_item')['position']
    assert got == pytest.approx((1.0, -2.5, 2.0), abs=1e-6)


def test_s41_an_unknown_frame_is_refused(sim, features):
    """[open] NOT_FOUND (2) or INVALID_POSE (109); this node answers 109."""
    needs(features, F.SPAWNING)
    before = set(sim.entities())
    res = spawn_raw(sim, name='conformance_item', uri=spawnable(sim),
                    frame_id='no_such_frame_here')
    assert res.result.result in (NOT_FOUND, srv.SpawnEntity.Response.INVALID_POSE)
    assert EXTERNAL or res.result.result == srv.SpawnEntity.Response.INVALID_POSE
    assert set(sim.entities()) == before


def test_s41_a_default_orientation_is_valid(sim, features):
    needs(features, F.SPAWNING)
    req = srv.SpawnEntity.Request(name='conformance_item', uri=spawnable(sim))
    req.initial_pose.pose.position.y, req.initial_pose.pose.position.z = -2.0, 2.0
    assert (req.initial_pose.pose.orientation.w, req.initial_pose.pose.orientation.x) == (1, 0)
    assert sim.call('spawn_entity', srv.SpawnEntity, req, check=False).result.result == OK


def test_s41_a_position_outside_the_world_is_an_invalid_pose(sim, features):
    needs(features, F.SPAWNING)
    if EXTERNAL:
        pytest.skip("the world's bounds are the simulator's own")
    assert_refused(sim, srv.SpawnEntity.Response.INVALID_POSE, name='conformance_item',
                   uri=spawnable(sim), position=(1e9, 0.0, 2.0))


# §4.2 SpawnEntities, §4.3 DeleteEntity, §4.5 GetEntitiesStates

def test_s42_the_same_name_twice_in_one_batch(sim, features):
    """[open] Items are spawned in order: the second of two equal names answers 101."""
    needs(features, F.SPAWNING_ENTITIES)
    results = sim.spawn_entities([
        {'name': 'conformance_a', 'uri': spawnable(sim), 'position': (0.5, -2.0, 2.0)},
        {'name': 'conformance_a', 'uri': spawnable(sim), 'position': (0.5, -3.0, 2.0)}])
    assert results[0] == (OK, 'conformance_a')
    assert results[1][0] == srv.SpawnEntity.Response.NAME_NOT_UNIQUE
    assert sim.entities(pattern='^conformance_a') == ['conformance_a']


def test_s43_deleting_an_entity_of_the_world_is_all_or_nothing(sim, features):
    """[open] This node deletes only what was spawned: a scene entity stays, with a message."""
    needs(features, F.DELETING)
    name = static_entity(sim)
    res = raw(sim, 'delete_entity', srv.DeleteEntity, entity=name)
    if res.result.result == OK:
        assert name not in sim.entities()
    else:
        assert name in sim.entities() and res.result.error_message
    assert EXTERNAL or res.result.result == Result.RESULT_INCORRECT_STATE


def test_s45_get_entities_states_applies_the_filters(sim, features):
    needs(features, F.ENTITY_STATE_GETTING)
    name = sim.entities()[-1]
    assert list(sim.entities_states(pattern=f'^{re.escape(name)}$')) == [name]


# §4.9 SetEntityState

def test_s49_pose_and_twist_may_be_given_in_an_entitys_frame(sim, features):
    needs(features, F.SPAWNING, F.ENTITY_STATE_SETTING)
    sim.pause()
    yaw = math.pi / 2
    q = (0, 0, math.sin(yaw / 2), math.cos(yaw / 2))
    base = sim.spawn('conformance_base', uri=spawnable(sim), position=(1.0, -3.0, 2.0),
                     orientation_xyzw=q)
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=(-1.0, -3.0, 2.0))
    sim.set_entity_state(name, (0.5, 0.0, 0.0), linear=(1.0, 0.0, 0.0), frame_id=base)
    st = sim.entity_state(name)  # read in the world frame
    assert st['position'] == pytest.approx((1.0, -2.5, 2.0), abs=1e-6)
    assert st['linear'] == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)


def test_s49_a_position_outside_the_world_is_101(sim, features):
    needs(features, F.ENTITY_STATE_SETTING)
    if EXTERNAL:
        pytest.skip("the world's bounds are the simulator's own")
    name = sim.entities(categories=[EntityCategory.CATEGORY_DYNAMIC_OBJECT])[0]
    sim.pause()
    before = sim.entity_state(name)['position']
    state = EntityState()
    state.pose.position.x, state.pose.position.z = 1e9, 1.0
    state.pose.orientation.w = 1.0
    res = raw(sim, 'set_entity_state', srv.SetEntityState, entity=name, state=state)
    assert res.result.result == srv.SetEntityState.Response.INVALID_POSE
    assert sim.entity_state(name)['position'] == pytest.approx(before, abs=1e-9)


# §4.17 ResetSimulation

def test_s417_each_scope_bit_resets_only_its_part(sim, features):
    needs(features, F.SIMULATION_RESET_TIME, F.SIMULATION_RESET_STATE,
          F.SIMULATION_RESET_SPAWNED, F.SPAWNING, F.STEP_SIMULATION_MULTIPLE)
    sim.pause()
    sim.reset(255)
    start, picture = sim_time(sim), world_picture(sim)

    def moved_on():
        sim.spawn('conformance_item', uri=spawnable(sim), position=(0.5, -2.0, 2.0))
        sim.step(100)
        return sim_time(sim), {n: v for n, v in world_picture(sim).items() if n in picture}

    t, later = moved_on()
    assert later != picture
    sim.reset(4)  # spawned only: time and the others' state as they were
    assert 'conformance_item' not in sim.entities()
    assert sim_time(sim) == pytest.approx(t, abs=1e-9) and world_picture(sim) == later
    sim.reset(255)
    t, later = moved_on()
    sim.reset(2)  # state only: poses back, time kept, the spawned entity kept
    assert sim_time(sim) == pytest.approx(t, abs=1e-9)
    assert {n: v for n, v in world_picture(sim).items() if n in picture} == picture
    assert 'conformance_item' in sim.entities()
    sim.reset(3)  # time and state: the spawned entity still kept
    assert sim_time(sim) == pytest.approx(start, abs=1e-9)
    assert 'conformance_item' in sim.entities()


def test_s417_a_scope_bit_no_simulator_defines_is_unsupported(sim, features):
    needs(features, F.SIMULATION_RESET)
    for scope in (8, 16 | 1):
        res = raw(sim, 'reset_simulation', srv.ResetSimulation, scope=scope)
        assert res.result.result == UNSUPPORTED and res.result.error_message, scope


# §4.18 StepSimulation, §4.19 SimulateSteps

def test_s418_zero_steps_step_nothing(sim, features):
    """[open] steps = 0: this node answers OK and steps nothing (as O3DE)."""
    needs(features, F.STEP_SIMULATION_SINGLE)
    sim.pause()
    t0 = sim_time(sim)
    res = raw(sim, 'step_simulation', srv.StepSimulation, steps=0)
    assert res.result.result == OK or EXTERNAL
    assert sim_time(sim) == pytest.approx(t0, abs=1e-12)


def test_s418_stepping_from_stopped(sim, features):
    """[open] STOPPED is paused at the start: a step is allowed and leaves it PAUSED."""
    needs(features, F.STEP_SIMULATION_SINGLE, F.SIMULATION_STATE_SETTING)
    sim.set_state(S.STATE_STOPPED)
    t0 = sim_time(sim)
    res = raw(sim, 'step_simulation', srv.StepSimulation, steps=1)
    if EXTERNAL and res.result.result != OK:
        return
    assert res.result.result == OK, res.result.error_message
    assert sim_time(sim) > t0 and sim.state() == S.STATE_PAUSED


def test_s419_a_cancel_stops_stepping_and_stays_paused(sim, features):
    needs(features, F.STEP_SIMULATION_ACTION)
    sim.pause()
    t0 = sim_time(sim)
    seen = []
    result = sim.simulate_steps(10 ** 9, feedback=lambda d, r: seen.append(d),
                                cancel_when=lambda done, left: done >= 50)
    t1 = sim_time(sim)
    assert result.result == OK and seen[-1] < 10 ** 9
    assert 'cancel' in result.error_message
    assert sim.state() == S.STATE_PAUSED
    time.sleep(0.2)
    assert sim_time(sim) == t1 > t0  # it stopped


# §4.20 LoadWorld, §4.23 GetAvailableWorlds

def test_s420_load_world_removes_spawned_entities_and_leaves_stopped(sim, features):
    needs(features, F.WORLD_LOADING, F.WORLD_INFO_GETTING, F.SPAWNING)
    uri = raw(sim, 'get_current_world', srv.GetCurrentWorld).world.world_resource.uri
    name = sim.spawn('conformance_item', uri=spawnable(sim), position=(0.5, -2.0, 2.0))
    res = raw(sim, 'load_world', srv.LoadWorld, uri=uri)
    assert res.result.result == OK, res.result.error_message
    assert name not in sim.entities() and sim.state() == S.STATE_STOPPED


def test_s420_codes_and_a_failed_load_keeps_the_world(sim, features):
    """101-106 as LoadWorld numbers them; a refused load changes nothing [open]."""
    needs(features, F.WORLD_LOADING, F.WORLD_RESOURCE_STRING)
    r = srv.LoadWorld.Response
    missing = ('<mujoco><asset><mesh name="m" file="/no/such/folder/conformance.stl"/></asset>'
               '<worldbody><geom type="mesh" mesh="m"/></worldbody></mujoco>')
    cases = [({'resource_string': '{"world": "JSON"}'}, r.UNSUPPORTED_FORMAT),
             ({}, r.NO_RESOURCE),
             ({'resource_string': '<mujoco><worldbody><body>'}, r.RESOURCE_PARSE_ERROR),
             ({'resource_string': missing}, r.MISSING_ASSETS),
             ({'resource_string': '<mujoco><worldbody><conformance_element/></worldbody>'
               '</mujoco>', 'fail_on_unsupported_element': True}, r.UNSUPPORTED_ELEMENTS)]
    files = [u[len('file://'):] for u in sim.spawnables() if u.startswith('file:///')] \
        if F.SPAWNABLES in features else []
    if files:  # a file that exists but is no mesh, named as a mesh
        cases.append(({'resource_string': missing.replace('/no/such/folder/conformance.stl',
                                                          files[0])}, r.UNSUPPORTED_ASSETS))
    if not EXTERNAL:  # this node cannot load a world without its assets, and says so
        cases.append(({'resource_string': missing,
                       'ignore_missing_or_unsupported_assets': True}, UNSUPPORTED))
    if 'mjcf' not in {f.lower() for f in sim.features().spawn_formats}:
        cases = cases[:2]
    picture, state = world_picture(sim), sim.state()
    for fields, code in cases:
        res = raw(sim, 'load_world', srv.LoadWorld, **fields)
        assert res.result.result == code, (fields, res.result.error_message)
        assert res.result.error_message
        if not EXTERNAL:
            assert sim.state() == state and set(world_picture(sim)) == set(picture)


def test_s420_unsupported_elements_are_left_out_unless_asked_to_fail(sim, features):
    needs(features, F.WORLD_LOADING, F.WORLD_RESOURCE_STRING, F.WORLD_INFO_GETTING)
    if 'mjcf' not in {f.lower() for f in sim.features().spawn_formats}:
        pytest.skip('the world text below is MJCF')
    uri = raw(sim, 'get_current_world', srv.GetCurrentWorld).world.world_resource.uri
    text = ('<mujoco><worldbody><conformance_element/><body name="conformance_box" pos="0 0 1">'
            '<freejoint/><geom type="box" size=".1 .1 .1"/></body></worldbody></mujoco>')
    try:
        res = raw(sim, 'load_world', srv.LoadWorld, resource_string=text)
        assert res.result.result == OK, res.result.error_message
        assert sim.entities() == ['conformance_box']
    finally:
        sim.load_world(uri=uri)


def test_s423_world_tags_need_their_feature_and_failed_sources_are_named(sim, features):
    needs(features, F.AVAILABLE_WORLDS)
    if F.WORLD_TAGS not in features:
        req = srv.GetAvailableWorlds.Request()
        req.filter.tags = ['conformance']
        assert sim.call('get_available_worlds', srv.GetAvailableWorlds, req,
                        check=False).result.result == UNSUPPORTED
    bad = '/no/such/folder/conformance_worlds'
    res = raw(sim, 'get_available_worlds', srv.GetAvailableWorlds, additional_sources=[bad])
    assert res.result.result != OK and res.result.error_message  # [open] which code
    res = raw(sim, 'get_available_worlds', srv.GetAvailableWorlds, additional_sources=[bad],
              continue_on_error=True)
    assert res.result.result == OK and bad in res.result.error_message
    assert len(res.worlds) == len(raw(sim, 'get_available_worlds',
                                      srv.GetAvailableWorlds).worlds)
