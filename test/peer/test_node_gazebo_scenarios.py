"""
The scenarios of Gazebo's own simulation_interfaces test, run against this node.

Source of the scenarios: ``ros_gz_sim/test/test_gz_simulation_interfaces.launch.py`` in
gazebosim/ros_gz (16 tests with plain rclpy calls against ``gz_server``). This module is
written here, from what that test calls and expects: the same service calls in the same order
of a unittest run, MJCF where it spawns SDF, and its world rebuilt in ``peer_world.xml`` (a
ground, an incline, a differential-drive ``vehicle``, a ``sphere``, a ``box``). Where it checks
a choice of Gazebo's that the standard leaves open or answers otherwise, the test says so and
checks this node's documented answer instead:

* deleting an entity of the loaded world (``box``): Gazebo deletes it; here only spawned
  entities can be deleted (standard_rules 4.3 leaves it open; docs/services.md);
* setting the state the simulation is already in: Gazebo answers OK; the standard's
  SetSimulationState says 101 ALREADY_IN_TARGET_STATE, which this node answers;
* the feature list: Gazebo's is its own; here, each feature Gazebo lists is listed too except
  ENTITY_TAGS (no tags in MuJoCo models), and more;
* the vehicle keeps its last command (Gazebo's DiffDrive has no timeout): the node runs with
  ``cmd_vel_timeout:=0`` and its ``vehicle/cmd_vel`` remapped to ``/cmd_vel``, as the test's
  bridge does.
"""

from pathlib import Path
import time

from conftest import NodeProcess, wait_for
from geometry_msgs.msg import Twist
import pytest
import rclpy
from rclpy.action import ActionClient
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import EntityCategory, Result, SimulationState, SimulatorFeatures
import simulation_interfaces.srv as si

WORLD = Path(__file__).resolve().parent / 'peer_world.xml'
NS = '/gz_peer'
SPHERE = """<mujoco><worldbody><body name="sphere_link"><freejoint/>
  <geom type="sphere" size="1" mass="1"/></body></worldbody></mujoco>"""
EMPTY = '<mujoco><worldbody><body name="link"/></worldbody></mujoco>'


@pytest.fixture(scope='module')
def server(rclpy_context):
    proc = NodeProcess(f'scene:={WORLD}', 'cmd_vel_timeout:=0.0', namespace=NS,
                       remaps=('vehicle/cmd_vel:=/cmd_vel',))
    node = rclpy.create_node('test_interfaces')
    # Up and answering: a request sent the moment a service is discovered can be lost on a
    # loaded host (the server's reader not yet matched), as with any DDS service.
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            call(node, si.GetSimulationState, 'get_simulation_state', timeout=2.0)
            break
        except AssertionError:
            continue
    yield node
    node.destroy_node()
    code, _ = proc.interrupt()
    assert code == 0, proc.output()


def call(node, srv_type, name: str, request=None, timeout: float = 10.0):
    client = node.create_client(srv_type, f'{NS}/{name}')
    try:
        assert client.wait_for_service(timeout_sec=30)
        future = client.call_async(request if request is not None else srv_type.Request())
        rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
        assert future.done()
        return future.result()
    finally:
        node.destroy_client(client)


def ok(response) -> None:
    assert response.result.result == Result.RESULT_OK, response.result.error_message
    assert response.result.error_message == ''


def sim_state(node) -> int:
    response = call(node, si.GetSimulationState, 'get_simulation_state')
    ok(response)
    return response.state.state


def set_state(node, state: int):
    req = si.SetSimulationState.Request()
    req.state.state = state
    return call(node, si.SetSimulationState, 'set_simulation_state', req)


def entity_state(node, name: str):
    response = call(node, si.GetEntityState, 'get_entity_state',
                    si.GetEntityState.Request(entity=name))
    ok(response)
    return response.state


def spawn(node, name: str, text: str, xyz=(0.0, 0.0, 0.0)):
    # (Gazebo's test sets entity_resource.resource_string: a later release's field; the Jazzy
    # release has resource_string on the request itself)
    req = si.SpawnEntity.Request(name=name, resource_string=text)
    req.initial_pose.pose.position.x, req.initial_pose.pose.position.y, \
        req.initial_pose.pose.position.z = xyz
    return call(node, si.SpawnEntity, 'spawn_entity', req)


def delete(node, name: str):
    return call(node, si.DeleteEntity, 'delete_entity', si.DeleteEntity.Request(entity=name))


# In unittest's order (by name), as Gazebo's test runs.

def test_delete_entity(server):
    """Gazebo deletes its world's `box`; here the world's own entities stay (see above)."""
    response = delete(server, 'box')
    assert response.result.result == Result.RESULT_INCORRECT_STATE
    assert 'only spawned entities can be deleted' in response.result.error_message


def test_delete_on_spawned_entity(server):
    ok(spawn(server, 'test_empty', EMPTY))
    time.sleep(2)
    ok(delete(server, 'test_empty'))


def test_get_entities_states(server):
    req = si.GetEntitiesStates.Request()
    req.filters.filter = 'vehicle'
    response = call(server, si.GetEntitiesStates, 'get_entities_states', req)
    ok(response)
    assert list(response.entities) == ['vehicle']


def test_get_entities_with_no_filters(server):
    ok(call(server, si.GetEntities, 'get_entities'))


def test_get_entity_info(server):
    response = call(server, si.GetEntityInfo, 'get_entity_info',
                    si.GetEntityInfo.Request(entity='vehicle'))
    ok(response)
    assert response.info.category.category == EntityCategory.CATEGORY_ROBOT


def test_get_entity_state(server):
    assert abs(entity_state(server, 'vehicle').twist.linear.x) < 1e-4
    pub = server.create_publisher(Twist, '/cmd_vel', 10)
    try:
        wait_for(lambda: pub.get_subscription_count() > 0, timeout=10)
        msg = Twist()
        msg.linear.x = 0.25
        for _ in range(10):  # Gazebo's test publishes until its bridge passes one on
            pub.publish(msg)
            rclpy.spin_once(server, timeout_sec=0.1)
        time.sleep(2)
        assert entity_state(server, 'vehicle').twist.linear.x == pytest.approx(0.25, abs=0.1)
    finally:
        server.destroy_publisher(pub)


def test_get_entity_state_on_spawned_entity(server):
    # spawned above the incline: it lands and rolls down it, toward +x, by itself
    assert spawn(server, 'test_sphere', SPHERE, (4.0, -20.0, 4.0))
    time.sleep(2)
    assert entity_state(server, 'test_sphere').twist.linear.x > 0.1


def test_get_simulator_features(server):
    """Gazebo checks its own list; here every feature of it is listed but ENTITY_TAGS."""
    response = call(server, si.GetSimulatorFeatures, 'get_simulator_features')
    f = SimulatorFeatures
    gazebo_lists = [f.SPAWNING, f.DELETING, f.ENTITY_TAGS, f.ENTITY_CATEGORIES,
                    f.SPAWNING_RESOURCE_STRING, f.ENTITY_STATE_GETTING, f.ENTITY_STATE_SETTING,
                    f.ENTITY_INFO_GETTING, f.SIMULATION_RESET, f.SIMULATION_RESET_TIME,
                    f.SIMULATION_STATE_GETTING, f.SIMULATION_STATE_SETTING,
                    f.SIMULATION_STATE_PAUSE, f.STEP_SIMULATION_SINGLE,
                    f.STEP_SIMULATION_MULTIPLE, f.STEP_SIMULATION_ACTION]
    listed = set(response.features.features)
    assert [x for x in gazebo_lists if x not in listed] == [f.ENTITY_TAGS]


def test_playing_when_already_playing(server):
    """Gazebo answers OK twice; the standard's code for the second is 101, as here."""
    first = set_state(server, SimulationState.STATE_PLAYING)
    assert first.result.result in (Result.RESULT_OK,
                                   si.SetSimulationState.Response.ALREADY_IN_TARGET_STATE)
    second = set_state(server, SimulationState.STATE_PLAYING)
    assert second.result.result == si.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert sim_state(server) == SimulationState.STATE_PLAYING


def test_reset_simulation(server):
    req = si.ResetSimulation.Request(scope=si.ResetSimulation.Request.SCOPE_DEFAULT)
    ok(call(server, si.ResetSimulation, 'reset_simulation', req))


def test_set_entity_state(server):
    ok(call(server, si.ResetSimulation, 'reset_simulation', si.ResetSimulation.Request()))
    if sim_state(server) != SimulationState.STATE_PLAYING:
        ok(set_state(server, SimulationState.STATE_PLAYING))
    req = si.SetEntityState.Request(entity='sphere')
    req.state.pose.position.z = 100.0
    req.state.twist.linear.x = 5.0
    ok(call(server, si.SetEntityState, 'set_entity_state', req))
    assert entity_state(server, 'sphere').twist.linear.x == pytest.approx(5.0, abs=0.1)


def test_set_entity_state_preserves_sim_state(server):
    req = si.SetEntityState.Request(entity='sphere')
    req.state.pose.position.z = 10.0
    for state in (SimulationState.STATE_PLAYING, SimulationState.STATE_PAUSED):
        if sim_state(server) != state:
            ok(set_state(server, state))
        assert sim_state(server) == state
        ok(call(server, si.SetEntityState, 'set_entity_state', req))
        assert sim_state(server) == state


def test_simulate_steps_action(server):
    if sim_state(server) != SimulationState.STATE_PAUSED:
        ok(set_state(server, SimulationState.STATE_PAUSED))
    node = rclpy.create_node('test_action')
    client = ActionClient(node, SimulateSteps, f'{NS}/simulate_steps')
    try:
        assert client.wait_for_server(timeout_sec=30)
        for _ in range(2):  # and again: a second goal is handled as the first
            feedback = []

            def on_feedback(msg):
                assert msg.feedback.completed_steps > 0
                feedback.append(msg)
            sent = client.send_goal_async(SimulateSteps.Goal(steps=200),
                                          feedback_callback=on_feedback)
            rclpy.spin_until_future_complete(node, sent, timeout_sec=30)
            result = sent.result().get_result_async()
            rclpy.spin_until_future_complete(node, result, timeout_sec=30)
            ok(result.result().result)
            assert len(feedback) > 1
    finally:
        client.destroy()
        node.destroy_node()


def test_spawn_entity_duplicate_name(server):
    ok(spawn(server, 'test_duplicate', EMPTY))
    time.sleep(2)
    again = spawn(server, 'test_duplicate', EMPTY)
    assert again.result.result == si.SpawnEntity.Response.NAME_NOT_UNIQUE


def test_step_simulation(server):
    assert sim_state(server) == SimulationState.STATE_PAUSED  # as the tests before left it
    ok(call(server, si.StepSimulation, 'step_simulation', si.StepSimulation.Request(steps=5)))


def test_toggle_simulation_state(server):
    initial = sim_state(server)
    target = (SimulationState.STATE_PLAYING if initial == SimulationState.STATE_PAUSED
              else SimulationState.STATE_PAUSED)
    ok(set_state(server, target))
    assert sim_state(server) == target
    ok(set_state(server, initial))
    assert sim_state(server) == initial
