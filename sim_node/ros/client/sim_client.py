"""
A small Python client for the `sim` node's services, for scripts.

Tests and machines without ros2cli. Plain Python arguments in, plain values out; failures raise
:class:`SimServiceError` with the Result code and message.

    import rclpy
    from sim_node.ros.client import SimClient
    rclpy.init()
    sim = SimClient()
    sim.spawn('crate', uri='box', position=(0.75, 0, 1.0))
    sim.pause(); sim.step(100); sim.play()
"""

import time
from typing import Optional, Sequence

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from msg_adapters import convert
import rclpy
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from simulation_interfaces import srv
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import EntityState, Result, SimulationState

from ..settings.qos import FEEDBACK_QOS, SERVICE_QOS


#: The simulation_interfaces services of a `sim` node, by name (as simulators name them).
STANDARD_SERVICES = {name: getattr(srv, kind) for name, kind in (
    ('get_simulator_features', 'GetSimulatorFeatures'), ('spawn_entity', 'SpawnEntity'),
    ('spawn_entities', 'SpawnEntities'), ('delete_entity', 'DeleteEntity'),
    ('get_entities', 'GetEntities'), ('get_entity_state', 'GetEntityState'),
    ('get_entities_states', 'GetEntitiesStates'), ('set_entity_state', 'SetEntityState'),
    ('get_entity_info', 'GetEntityInfo'), ('get_entity_bounds', 'GetEntityBounds'),
    ('get_spawnables', 'GetSpawnables'), ('reset_simulation', 'ResetSimulation'),
    ('step_simulation', 'StepSimulation'), ('get_simulation_state', 'GetSimulationState'),
    ('set_simulation_state', 'SetSimulationState'),
    ('get_available_worlds', 'GetAvailableWorlds'), ('load_world', 'LoadWorld'),
    ('unload_world', 'UnloadWorld'), ('get_current_world', 'GetCurrentWorld'))
    if hasattr(srv, kind)}

#: How old a service client must be before its first request (s). wait_for_service sees the
#: server's request reader; the server may not have matched the client's reply reader yet, and
#: rmw_fastrtps then drops the reply ("failed to send response (timeout)": a first reset in a
#: CI run never came back). The clients of every standard service are made with the SimClient,
#: so only a call right after construction waits, once.
FIRST_CALL_SETTLE_SEC = 0.5

#: Services that only read: a call with no answer after READ_RETRY_SEC is sent again (a write is
#: never repeated: it waits its whole timeout).
READ_ONLY_SERVICES = frozenset((
    'get_entities', 'get_entity_state', 'get_entities_states', 'get_entity_info',
    'get_entity_bounds', 'get_simulation_state', 'get_spawnables', 'get_simulator_features',
    'get_available_worlds', 'get_current_world'))
#: A controller manager's services that only read (by the end of their names).
READ_ONLY_SUFFIXES = ('/list_controllers', '/list_controller_types',
                      '/list_hardware_interfaces', '/list_hardware_components',
                      '/get_parameters', '/list_parameters', '/describe_parameters')
#: Writes whose standard meaning makes a second request do what the first did ("reset to the
#: initial state", "set this pose", "set this description"): asked again like reads. Every
#: other write (spawn, delete, step, load, set a state, an action goal) is never repeated: a
#: second spawn or delete is refused or acts twice, a second step steps twice.
IDEMPOTENT_WRITES = frozenset(('reset_simulation', 'set_entity_state', 'set_entity_info'))
READ_RETRY_SEC = 3.0

#: The longest single wait of the client's executor (s): a deadline is checked at least as often.
SPIN_SLICE_SEC = 0.1

#: After a simulate_steps goal succeeds, how long a client waits for feedback in flight (s).
FEEDBACK_DRAIN_SEC = 2.0


class SimServiceError(RuntimeError):
    """A service answered with a Result other than OK."""

    def __init__(self, service: str, code: int, message: str):
        super().__init__(f'{service} failed (result {code}): {message}')
        self.service, self.code, self.message = service, code, message


class SimClient:
    """
    Wraps the simulation_interfaces services of one `sim` node.

    :param namespace: where the node's services live ('' for a node started without one).
    :param node: an existing node to create clients on (it must not be spun elsewhere);
        by default the client makes its own.
    """

    def __init__(self, namespace: str = '', node: Optional[Node] = None,
                 timeout_sec: float = 30.0):
        self._own = node is None
        self.node = node or rclpy.create_node(f'sim_client_{id(self):x}')
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(self.node)
        self._ns = namespace.rstrip('/')
        self._timeout = timeout_sec
        self._clients: dict = {}  # service -> (rclpy client, when it was made)
        for service, srv_type in STANDARD_SERVICES.items():  # discovered while the caller
            self._client(service, srv_type)  # goes on: see FIRST_CALL_SETTLE_SEC

    def close(self) -> None:
        self._executor.remove_node(self.node)
        self._executor.shutdown()
        if self._own:
            self.node.destroy_node()

    def _client(self, service: str, srv_type) -> tuple:
        """Return (the rclpy client of `service`, when it was made), made on first use."""
        made = self._clients.get(service)
        if made is None:
            # A deep reply history: replies to other clients cannot push ours out (see qos).
            made = self._clients[service] = (self.node.create_client(
                srv_type, self._name(service), qos_profile=SERVICE_QOS), time.monotonic())
        return made

    def _name(self, service: str) -> str:
        return f'{self._ns}/{service}' if self._ns else service

    def call(self, service: str, srv_type, request, check: bool = True):
        """Call a service and wait for the answer; raise on a non-OK Result if `check`."""
        client, born = self._client(service, srv_type)
        deadline = time.monotonic() + self._timeout
        appeared = None
        while not client.wait_for_service(timeout_sec=0.2):
            appeared = time.monotonic()  # the server is new: it shows up during this call
            if appeared > deadline:
                raise TimeoutError(f'service {self._name(service)} is not available; is the '
                                   'sim node running (same ROS_DOMAIN_ID)?')
        # A client this young, or a server that just appeared: let the server match the
        # client's reply reader first (FIRST_CALL_SETTLE_SEC).
        settle = max(born, appeared or 0.0) + FIRST_CALL_SETTLE_SEC - time.monotonic()
        if settle > 0:
            self._spin_until(lambda: False, settle)
        future = client.call_async(request)
        while True:
            left = deadline - time.monotonic()
            reads = service in READ_ONLY_SERVICES or service in IDEMPOTENT_WRITES or \
                service.endswith(READ_ONLY_SUFFIXES)
            wait = min(left, READ_RETRY_SEC) if reads else left
            self._spin_until(future.done, max(0.1, wait))
            if future.done() or time.monotonic() >= deadline:
                break
            # A read changes nothing, and an idempotent write does again what it did, so
            # asking again is safe: its reply may have been dropped (a server that had not
            # matched us yet, or the ghost of a node just stopped).
            future = client.call_async(request)
        if not future.done():
            raise TimeoutError(f'{service} did not answer within {self._timeout} s')
        response = future.result()
        result = getattr(response, 'result', None)
        if check and result is not None and result.result != Result.RESULT_OK:
            raise SimServiceError(service, result.result, result.error_message)
        return response

    # ---------------------------------------------------------------- entities

    def spawn(self, name: str, uri: str = '', resource_string: str = '',
              position: Sequence[float] = (0, 0, 0),
              orientation_xyzw: Sequence[float] = (0, 0, 0, 1), frame_id: str = '',
              allow_renaming: bool = False, namespace: str = '') -> str:
        """Spawn an entity; returns its (possibly renamed) name."""
        req = srv.SpawnEntity.Request(name=name, allow_renaming=allow_renaming, uri=uri,
                                      resource_string=resource_string,
                                      entity_namespace=namespace)
        req.initial_pose = _pose_stamped(position, orientation_xyzw, frame_id)
        return self.call('spawn_entity', srv.SpawnEntity, req).entity_name

    def delete(self, name: str) -> None:
        self.call('delete_entity', srv.DeleteEntity, srv.DeleteEntity.Request(entity=name))

    def entities(self, pattern: str = '', categories: Sequence[int] = ()) -> list:
        from simulation_interfaces.msg import EntityCategory
        req = srv.GetEntities.Request()
        req.filters.filter = pattern
        req.filters.categories = [EntityCategory(category=c) for c in categories]
        return list(self.call('get_entities', srv.GetEntities, req).entities)

    def entity_state(self, name: str) -> dict:
        """
        Return the state of an entity as a dict.

        Keys: 'position', 'orientation_xyzw', 'linear', 'angular', 'linear_acceleration',
        'angular_acceleration', 'stamp', 'frame_id'.
        """
        return _state_dict(self.call('get_entity_state', srv.GetEntityState,
                                     srv.GetEntityState.Request(entity=name)).state)

    def entities_states(self, pattern: str = '') -> dict:
        """Return {entity: state dict, as :meth:`entity_state`} of the entities `pattern` finds."""
        req = srv.GetEntitiesStates.Request()
        req.filters.filter = pattern
        res = self.call('get_entities_states', srv.GetEntitiesStates, req)
        return {name: _state_dict(s) for name, s in zip(res.entities, res.states)}

    def entity_bounds(self, name: str) -> tuple:
        """Return an entity's bounds: (Bounds.TYPE_*, [(x, y, z), ...]) as the node gives them."""
        b = self.call('get_entity_bounds', srv.GetEntityBounds,
                      srv.GetEntityBounds.Request(entity=name)).bounds
        return b.type, [(p.x, p.y, p.z) for p in b.points]

    def spawn_entities(self, requests: Sequence[dict]) -> list:
        """
        Spawn several entities in one call (SpawnEntities); return [(result code, name)].

        Each request is a dict of :meth:`spawn`'s arguments (name, uri, resource_string,
        position, orientation_xyzw, frame_id, allow_renaming, namespace). Per-item failures are
        in the list; the call raises only when the service itself fails otherwise.
        """
        from simulation_interfaces.msg import Resource, SpawnEntity
        items = []
        for r in requests:
            resource = Resource(uri=r.get('uri', ''), resource_string=r.get('resource_string', ''))
            item = SpawnEntity(name=r.get('name', ''), entity_resource=resource,
                               allow_renaming=r.get('allow_renaming', False),
                               entity_namespace=r.get('namespace', ''))
            item.initial_pose = _pose_stamped(r.get('position', (0, 0, 0)),
                                              r.get('orientation_xyzw', (0, 0, 0, 1)),
                                              r.get('frame_id', ''))
            items.append(item)
        res = self.call('spawn_entities', srv.SpawnEntities,
                        srv.SpawnEntities.Request(spawn_requests=items), check=False)
        if res.result.result not in (Result.RESULT_OK,
                                     srv.SpawnEntities.Response.ENTITIES_SPAWN_FAILED):
            raise SimServiceError('spawn_entities', res.result.result, res.result.error_message)
        return [(r.result.result, r.entity_name) for r in res.results]

    def worlds(self) -> list:
        """Return the (name, uri) of every world the node can load (GetAvailableWorlds)."""
        res = self.call('get_available_worlds', srv.GetAvailableWorlds,
                        srv.GetAvailableWorlds.Request())
        return [(w.name, w.world_resource.uri) for w in res.worlds]

    def set_entity_state(self, name: str, position: Sequence[float],
                         orientation_xyzw: Sequence[float] = (0, 0, 0, 1),
                         linear: Sequence[float] = (0, 0, 0),
                         angular: Sequence[float] = (0, 0, 0), frame_id: str = '') -> None:
        st = EntityState()
        st.header.frame_id = frame_id
        st.pose = _pose_stamped(position, orientation_xyzw, frame_id).pose
        st.twist.linear = convert.vec(linear)
        st.twist.angular = convert.vec(angular)
        self.call('set_entity_state', srv.SetEntityState,
                  srv.SetEntityState.Request(entity=name, state=st))

    def entity_info(self, name: str):
        return self.call('get_entity_info', srv.GetEntityInfo,
                         srv.GetEntityInfo.Request(entity=name)).info

    def spawnables(self) -> list:
        return [s.uri for s in self.call('get_spawnables', srv.GetSpawnables,
                                         srv.GetSpawnables.Request()).spawnables]

    def features(self):
        return self.call('get_simulator_features', srv.GetSimulatorFeatures,
                         srv.GetSimulatorFeatures.Request()).features

    # ---------------------------------------------------------------- simulation

    def reset(self, scope: int = 0) -> None:
        self.call('reset_simulation', srv.ResetSimulation,
                  srv.ResetSimulation.Request(scope=scope))

    def step(self, steps: int = 1) -> None:
        """Step while paused; returns when the steps are done."""
        self.call('step_simulation', srv.StepSimulation, srv.StepSimulation.Request(steps=steps))

    def state(self) -> int:
        """SimulationState.STATE_* of the simulation."""
        return self.call('get_simulation_state', srv.GetSimulationState,
                         srv.GetSimulationState.Request()).state.state

    def set_state(self, state: int) -> None:
        self.call('set_simulation_state', srv.SetSimulationState,
                  srv.SetSimulationState.Request(state=SimulationState(state=state)))

    def play(self) -> None:
        """Play; already playing is fine (only the state matters to the caller)."""
        self._ensure_state(SimulationState.STATE_PLAYING)

    def pause(self) -> None:
        """Pause; already paused is fine."""
        self._ensure_state(SimulationState.STATE_PAUSED)

    def _ensure_state(self, state: int) -> None:
        try:
            self.set_state(state)
        except SimServiceError as exc:
            if exc.code != srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE:
                raise

    def simulate_steps(self, steps: int, feedback=None, cancel_when=None):
        """
        Run the simulate_steps action; return its Result (raise unless OK).

        :param feedback: called as ``feedback(completed, remaining)`` on every feedback message.
        :param cancel_when: called likewise; the goal is canceled the first time it returns true
            (the Result then says after how many steps).
        """
        client = ActionClient(self.node, SimulateSteps, self._name('simulate_steps'),
                              feedback_sub_qos_profile=FEEDBACK_QOS)
        canceling, remaining = [], [steps]

        def on_feedback(msg):
            done, left = msg.feedback.completed_steps, msg.feedback.remaining_steps
            remaining[0] = left
            if feedback is not None:
                feedback(done, left)
            if cancel_when is not None and not canceling and cancel_when(done, left):
                canceling.append(goal.result().cancel_goal_async())
        try:
            if not client.wait_for_server(timeout_sec=self._timeout):
                raise TimeoutError('simulate_steps action server not available')
            goal = client.send_goal_async(SimulateSteps.Goal(steps=steps),
                                          feedback_callback=on_feedback)
            self._spin_until(goal.done, self._timeout)
            handle = goal.result()
            if feedback is not None or cancel_when is not None:
                # rclpy drops a goal's feedback once its result is in, and the two travel
                # apart: ask for the result after the last feedback (or the goal's end).
                self._spin_until(lambda: not remaining[0] or handle.status in (
                    GoalStatus.STATUS_ABORTED, GoalStatus.STATUS_CANCELED), self._timeout)
                if remaining[0] and handle.status == GoalStatus.STATUS_SUCCEEDED:
                    self._spin_until(lambda: not remaining[0], FEEDBACK_DRAIN_SEC)
            res = handle.get_result_async()
            self._spin_until(res.done, self._timeout)
            if not res.done():
                raise TimeoutError(f'simulate_steps did not finish within {self._timeout} s')
            result = res.result().result.result
            if result.result != Result.RESULT_OK:
                raise SimServiceError('simulate_steps', result.result, result.error_message)
            return result
        finally:
            client.destroy()

    def spin_until_future_complete(self, future, timeout: float) -> None:
        """Spin this client's node until `future` is done or `timeout` seconds pass."""
        self._spin_until(future.done, timeout)

    def spin_for(self, seconds: float) -> None:
        """Spin this client's node for `seconds` (its subscriptions and clients run)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self._executor.spin_once(timeout_sec=max(0.0, min(end - time.monotonic(),
                                                              SPIN_SLICE_SEC)))

    def _spin_until(self, done, timeout: float) -> None:
        """
        Spin until ``done()`` or `timeout` seconds.

        Not rclpy's ``spin_until_future_complete``: on Jazzy a call's round trip through it took
        5 ms back to back and 22 ms paced at 100 Hz (p50, a bare rclpy server on this machine),
        through plain ``spin_once`` 0.7 and 1.2 ms.
        """
        deadline = time.monotonic() + timeout
        while not done():
            left = deadline - time.monotonic()
            if left <= 0:
                return
            self._executor.spin_once(timeout_sec=min(left, SPIN_SLICE_SEC))

    def load_world(self, uri: str = '', resource_string: str = '',
                   fail_on_unsupported_element: bool = False,
                   ignore_missing_or_unsupported_assets: bool = False) -> str:
        """Load a world (MJCF or SDF; LoadWorld's two modes as its flags); return its name."""
        return self.call('load_world', srv.LoadWorld, srv.LoadWorld.Request(
            uri=uri, resource_string=resource_string,
            fail_on_unsupported_element=fail_on_unsupported_element,
            ignore_missing_or_unsupported_assets=ignore_missing_or_unsupported_assets)
        ).world.name

    def unload_world(self) -> None:
        self.call('unload_world', srv.UnloadWorld, srv.UnloadWorld.Request())

    def current_world(self) -> str:
        return self.call('get_current_world', srv.GetCurrentWorld,
                         srv.GetCurrentWorld.Request()).world.name


def _state_dict(s: EntityState) -> dict:
    p, q = s.pose.position, s.pose.orientation
    return {'position': (p.x, p.y, p.z), 'orientation_xyzw': (q.x, q.y, q.z, q.w),
            'linear': (s.twist.linear.x, s.twist.linear.y, s.twist.linear.z),
            'angular': (s.twist.angular.x, s.twist.angular.y, s.twist.angular.z),
            'linear_acceleration': (s.acceleration.linear.x, s.acceleration.linear.y,
                                    s.acceleration.linear.z),
            'angular_acceleration': (s.acceleration.angular.x, s.acceleration.angular.y,
                                     s.acceleration.angular.z),
            'stamp': convert.stamp_to_sec(s.header.stamp), 'frame_id': s.header.frame_id}


def _pose_stamped(position, orientation_xyzw, frame_id: str) -> PoseStamped:
    ps = PoseStamped()
    ps.header.frame_id = frame_id
    ps.pose.position.x, ps.pose.position.y, ps.pose.position.z = map(float, position)
    o = ps.pose.orientation
    o.x, o.y, o.z, o.w = map(float, orientation_xyzw)
    return ps
