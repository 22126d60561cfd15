"""The `sim` rclpy node: a thin layer over the world core.

Callbacks convert the request, call the core, convert the answer (``msg_adapters``). The node
makes no ``mj_*`` call and never touches MjData. Services run in a reentrant callback group,
publishers and subscriptions in another, so a long step request never starves ``/clock``.
"""

import collections
import logging
import math
import re
import threading
from pathlib import Path
from typing import Optional

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, \
    SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from simulation_interfaces import srv as si_srv
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Bounds, EntityCategory, EntityInfo, Result, \
    SimulationState, SimulatorFeatures, Spawnable, TagsFilter, WorldResource
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from msg_adapters import convert, markers
from .core import sources
from .core.config import WorldConfig
from .core.errors import IncorrectStateError, InvalidArgumentError, NotFoundError, SimError
from .core.loop import SimLoop
from .core.types import EFFORT, POSITION, VELOCITY, RESET_ALL
from .core.world import World
from . import resources

NODE_NAME = 'sim'
MAX_RESOURCE_STRING_BYTES = 5_000_000
ERR_NO_WORLD = 'no world is loaded; call load_world first'


class _Sim:
    """A loaded world with its loop and where it came from."""

    def __init__(self, world: World, loop: SimLoop, name: str, uri: str):
        self.world, self.loop, self.name, self.uri = world, loop, name, uri


class _LogForwarder(logging.Handler):
    """Core log records go to a queue the node drains on its own thread (the loop thread
    never calls rclpy)."""

    def __init__(self):
        super().__init__(logging.INFO)
        self.records = collections.deque(maxlen=200)

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def _descriptor(description: str, read_only: bool = False, fmin=None, fmax=None,
                imin=None, imax=None) -> ParameterDescriptor:
    d = ParameterDescriptor(description=description, read_only=read_only)
    if fmin is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(fmin),
                                                     to_value=float(fmax), step=0.0)]
    if imin is not None:
        d.integer_range = [IntegerRange(from_value=int(imin), to_value=int(imax), step=0)]
    return d


class SimNode(Node):
    """Publishes /clock, /tf, /tf_static, markers and joint_states; serves
    simulation_interfaces. Call :meth:`start` after adding it to an executor."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self._scenes_dir = resources.installed_scenes_dir()
        self._declare_parameters()
        p = self._param
        self._world_frame = p('world_frame')
        self._resource_paths = [str(Path(r).resolve()) for r in p('resource_paths') if r]
        self._sim: Optional[_Sim] = None
        self._syncing_thread: Optional[int] = None  # set while we mirror `paused` ourselves
        self._sim_lock = threading.RLock()
        self._stopped = False  # STATE_STOPPED until play or pause
        self._published_generation = None
        self._published_seq = -1
        self._moving = None
        self._forwarder = _LogForwarder()
        logging.getLogger('sim_node').addHandler(self._forwarder)
        logging.getLogger('sim_node').setLevel(logging.INFO)

        self._pub_group = MutuallyExclusiveCallbackGroup()
        self._srv_group = ReentrantCallbackGroup()
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self._clock_pub = self.create_publisher(Clock, '/clock', 10)
        self._tf_pub = self.create_publisher(TFMessage, '/tf', 100)
        self._tf_static_pub = self.create_publisher(TFMessage, '/tf_static', latched)
        self._marker_pub = self.create_publisher(MarkerArray, 'markers', latched)
        self._joint_pub = self.create_publisher(JointState, 'joint_states', 10)
        self.create_subscription(JointState, 'joint_commands', self._on_joint_command, 10,
                                 callback_group=self._pub_group)
        self._tf_timer = self.create_timer(1.0 / p('tf_rate_hz'), self._publish_state,
                                           callback_group=self._pub_group)
        self._js_timer = self.create_timer(1.0 / p('joint_states_rate_hz'),
                                           self._publish_joint_states,
                                           callback_group=self._pub_group)
        self._housekeeping_timer = self.create_timer(0.2, self._housekeeping,
                                                     callback_group=self._pub_group)
        self._make_services()
        self.add_on_set_parameters_callback(self._on_set_parameters)

    # ------------------------------------------------------------------ parameters

    def _declare_parameters(self) -> None:
        c = WorldConfig()
        d = _descriptor
        self.declare_parameter('scene', 'default', d(
            'MJCF/URDF scene: a file path or an installed scene name', read_only=True))
        self.declare_parameter('real_time_factor', c.real_time_factor, d(
            'simulated seconds per wall second; 0 = as fast as possible', fmin=0, fmax=1000))
        self.declare_parameter('paused', c.paused, d('pause or play the simulation'))
        self.declare_parameter('timestep', c.timestep, d(
            'physics step in seconds; 0 keeps the scene\'s own', fmin=0, fmax=0.1))
        self.declare_parameter('max_steps', c.max_steps, d(
            'pause after this many steps since the last time reset; 0 = unbounded',
            imin=0, imax=2 ** 62))
        self.declare_parameter('max_sim_time', c.max_sim_time, d(
            'pause at this simulated time (s); 0 = unbounded', fmin=0, fmax=1e9))
        self.declare_parameter('tf_rate_hz', 100.0, d(
            'rate of /clock and /tf (wall Hz)', read_only=True, fmin=1, fmax=1000))
        self.declare_parameter('joint_states_rate_hz', 50.0, d(
            'rate of joint_states (wall Hz)', read_only=True, fmin=1, fmax=1000))
        self.declare_parameter('world_frame', 'world', d(
            'TF frame of the MuJoCo world body', read_only=True))
        self.declare_parameter('resource_paths', [str(self._scenes_dir)], d(
            'directories that spawn and load_world may read files from', read_only=True))
        self.declare_parameter('kp', c.kp, d(
            'PD stiffness for position commands on joints without a position actuator',
            fmin=0, fmax=1e6))
        self.declare_parameter('kd', c.kd, d(
            'PD damping for position/velocity commands without a matching actuator',
            fmin=0, fmax=1e6))
        self.declare_parameter('allow_interpenetration', c.allow_interpenetration, d(
            'allow spawning into overlapping geometry', read_only=True))

    def _param(self, name: str):
        return self.get_parameter(name).value

    def world_config(self) -> WorldConfig:
        p = self._param
        return WorldConfig(
            real_time_factor=p('real_time_factor'), paused=p('paused'), timestep=p('timestep'),
            max_steps=p('max_steps'), max_sim_time=p('max_sim_time'),
            snapshot_rate_hz=max(p('tf_rate_hz'), p('joint_states_rate_hz')),
            kp=p('kp'), kd=p('kd'), allow_interpenetration=p('allow_interpenetration'))

    def _on_set_parameters(self, params) -> SetParametersResult:
        sim = self._sim
        if self._syncing_thread == threading.get_ident():
            return SetParametersResult(successful=True)  # our own mirror of the loop state
        try:
            for prm in params:
                if sim is None:
                    continue
                if prm.name == 'real_time_factor':
                    sim.loop.set_real_time_factor(float(prm.value))
                elif prm.name == 'paused':
                    self._stopped = False
                    sim.loop.pause() if prm.value else sim.loop.play()
                elif prm.name == 'timestep' and prm.value > 0:
                    sim.world.set_timestep(float(prm.value))
                elif prm.name in ('max_steps', 'max_sim_time'):
                    limits = {'max_steps': self._param('max_steps'),
                              'max_sim_time': self._param('max_sim_time'), prm.name: prm.value}
                    sim.loop.set_limits(int(limits['max_steps']), float(limits['max_sim_time']))
                elif prm.name in ('kp', 'kd'):
                    gains = {'kp': self._param('kp'), 'kd': self._param('kd'),
                             prm.name: prm.value}
                    sim.world.set_gains(float(gains['kp']), float(gains['kd']))
        except SimError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        """Load the `scene` parameter's world and start its stepping loop."""
        path = resources.resolve_scene(self._param('scene'), self._scenes_dir)
        world = World.from_file(str(path), self.world_config())
        self._install(world, path.stem, path.resolve().as_uri())

    def _install(self, world: World, name: str, uri: str) -> None:
        loop = SimLoop(world)
        with self._sim_lock:
            old, self._sim = self._sim, _Sim(world, loop, name, uri)
            self._published_generation = None
        if old is not None:
            old.loop.stop()
        loop.start()
        self.get_logger().info(f'world {name!r} loaded from {uri}: '
                               f'{len(world.entities())} entities, dt={world.timestep} s, '
                               f'{"paused" if loop.paused else "playing"}')

    def shutdown(self) -> None:
        """Stop the stepping loop first (before the executor and the node)."""
        with self._sim_lock:
            if self._sim is not None:
                self._sim.loop.stop()

    def _require(self) -> _Sim:
        sim = self._sim
        if sim is None:
            raise IncorrectStateError(ERR_NO_WORLD)
        return sim

    # ------------------------------------------------------------------ publishing

    def _publish_state(self) -> None:
        sim = self._sim
        if sim is None:
            return
        seq, snap = sim.loop.wait_snapshot(-1, 0)
        info = snap.info
        if info.generation != self._published_generation:
            self._publish_model(info, snap.time)
        if seq == self._published_seq:
            return
        self._published_seq = seq
        self._clock_pub.publish(convert.clock(snap.time))
        self._tf_pub.publish(convert.moving_transforms(info, snap, self._moving,
                                                       self._world_frame))

    def _publish_model(self, info, sim_time: float) -> None:
        """On a new model generation: /tf_static for welded bodies, and every marker anew."""
        self._published_generation = info.generation
        self._moving = convert.moving_body_ids(info)
        self._tf_static_pub.publish(convert.static_transforms(info, sim_time,
                                                              self._world_frame))
        self._marker_pub.publish(markers.markers(info, sim_time, self._world_frame))

    def _publish_joint_states(self) -> None:
        sim = self._sim
        if sim is None:
            return
        snap = sim.loop.latest_snapshot()
        if snap.info.joint_names:
            self._joint_pub.publish(convert.joint_state(snap.info, snap))

    def _sync_paused_parameter(self) -> None:
        """Mirror the loop's paused state (changed by services, limits or divergence too) in
        the `paused` parameter, so `ros2 param get` tells the truth."""
        sim = self._sim
        if sim is None:
            return
        paused = bool(sim.loop.paused)
        if self._param('paused') != paused:
            self._syncing_thread = threading.get_ident()
            try:
                self.set_parameters([Parameter('paused', Parameter.Type.BOOL, paused)])
            finally:
                self._syncing_thread = None

    def _housekeeping(self) -> None:
        self._sync_paused_parameter()
        self._drain_logs()

    def _drain_logs(self) -> None:
        log = self.get_logger()
        while self._forwarder.records:
            rec = self._forwarder.records.popleft()
            text = rec.getMessage()
            if rec.levelno >= logging.ERROR:
                log.error(text)
            elif rec.levelno >= logging.WARNING:
                log.warning(text, throttle_duration_sec=1.0)
            else:
                log.info(text)

    def _after_change(self, sim: _Sim) -> None:
        sim.loop.refresh_snapshot()

    # ------------------------------------------------------------------ joint commands

    def _on_joint_command(self, msg: JointState) -> None:
        filled = [(mode, vals) for mode, vals in ((POSITION, msg.position),
                                                  (VELOCITY, msg.velocity),
                                                  (EFFORT, msg.effort)) if len(vals)]
        try:
            if len(filled) != 1:
                raise InvalidArgumentError('fill exactly one of position, velocity, effort '
                                           f'(got {len(filled)})')
            mode, vals = filled[0]
            self._require().world.command(list(msg.name), list(vals), mode)
        except SimError as exc:
            self.get_logger().warning(f'joint command refused: {exc}',
                                      throttle_duration_sec=1.0)

    # ------------------------------------------------------------------ services

    def _make_services(self) -> None:
        g = self._srv_group
        table = {
            'get_simulator_features': (si_srv.GetSimulatorFeatures, self._srv_features),
            'spawn_entity': (si_srv.SpawnEntity, self._srv_spawn),
            'delete_entity': (si_srv.DeleteEntity, self._srv_delete),
            'get_entities': (si_srv.GetEntities, self._srv_get_entities),
            'get_entity_state': (si_srv.GetEntityState, self._srv_get_state),
            'get_entities_states': (si_srv.GetEntitiesStates, self._srv_get_states),
            'set_entity_state': (si_srv.SetEntityState, self._srv_set_state),
            'get_entity_info': (si_srv.GetEntityInfo, self._srv_get_info),
            'get_entity_bounds': (si_srv.GetEntityBounds, self._srv_get_bounds),
            'get_spawnables': (si_srv.GetSpawnables, self._srv_spawnables),
            'reset_simulation': (si_srv.ResetSimulation, self._srv_reset),
            'step_simulation': (si_srv.StepSimulation, self._srv_step),
            'get_simulation_state': (si_srv.GetSimulationState, self._srv_get_sim_state),
            'set_simulation_state': (si_srv.SetSimulationState, self._srv_set_sim_state),
            'get_available_worlds': (si_srv.GetAvailableWorlds, self._srv_worlds),
            'load_world': (si_srv.LoadWorld, self._srv_load_world),
            'unload_world': (si_srv.UnloadWorld, self._srv_unload_world),
            'get_current_world': (si_srv.GetCurrentWorld, self._srv_current_world),
        }
        if hasattr(si_srv, 'SpawnEntities'):
            table['spawn_entities'] = (si_srv.SpawnEntities, self._srv_spawn_many)
        for name, (srv_type, handler) in table.items():
            self.create_service(srv_type, name, self._guard(srv_type, handler),
                                callback_group=g)
        self._action = ActionServer(
            self, SimulateSteps, 'simulate_steps', execute_callback=self._act_simulate,
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda handle: CancelResponse.ACCEPT, callback_group=g)

    def _guard(self, srv_type, handler):
        """Every core error becomes a Result; nothing escapes to kill spin()."""
        def callback(request, response):
            try:
                return handler(request, response)
            except SimError as exc:
                response.result = convert.result_for(exc, srv_type.Response)
            except Exception as exc:  # a bug must not take the node down: report it
                self.get_logger().error(f'{handler.__name__} failed: {exc!r}')
                response.result = Result(result=Result.RESULT_OPERATION_FAILED,
                                         error_message=f'internal error: {exc!r}')
            return response
        return callback

    def _srv_features(self, request, response):
        f = SimulatorFeatures
        response.features.features = [
            f.SPAWNING, f.DELETING, f.ENTITY_BOUNDS, f.ENTITY_BOUNDS_BOX, f.ENTITY_CATEGORIES,
            f.SPAWNING_RESOURCE_STRING, f.ENTITY_STATE_GETTING, f.ENTITY_STATE_SETTING,
            f.ENTITY_INFO_GETTING, f.SPAWNABLES, f.SIMULATION_RESET, f.SIMULATION_RESET_TIME,
            f.SIMULATION_RESET_STATE, f.SIMULATION_RESET_SPAWNED, f.SIMULATION_STATE_GETTING,
            f.SIMULATION_STATE_SETTING, f.SIMULATION_STATE_PAUSE, f.STEP_SIMULATION_SINGLE,
            f.STEP_SIMULATION_MULTIPLE, f.STEP_SIMULATION_ACTION, f.WORLD_LOADING,
            f.WORLD_RESOURCE_STRING, f.WORLD_UNLOADING, f.WORLD_INFO_GETTING,
            f.AVAILABLE_WORLDS]
        if hasattr(si_srv, 'SpawnEntities'):
            response.features.features.append(f.SPAWNING_ENTITIES)
        response.features.spawn_formats = ['mjcf', 'urdf'] + [
            s[1:] for s in sources.MESH_SUFFIXES]
        response.features.custom_info = (
            'MuJoCo simulator. Spawn: uri = spawnable name, package://sim/..., file:// inside '
            'resource_paths (MJCF, URDF, STL, OBJ, PLY, GLB, DAE) or resource_string (MJCF or '
            'URDF text). initial_pose.header.frame_id: empty or the world frame, or an entity.')
        return response

    # ---- spawning

    def _source_for(self, uri: str, resource_string: str) -> sources.SpawnSource:
        roots = self._resource_paths
        if resource_string:
            # from_model_text refuses text over max_bytes (UNSUPPORTED_ASSETS) before parsing.
            return sources.from_model_text(resource_string, base_dir=None,
                                           allowed_roots=roots,
                                           max_bytes=MAX_RESOURCE_STRING_BYTES)
        path = resources.resolve_uri(uri, roots, self._scenes_dir)
        return sources.from_file(str(path), allowed_roots=roots)

    def _reference_frame(self, frame_id: str) -> str:
        """'' for the world frame, else the entity whose frame the pose is given in."""
        if frame_id in ('', self._world_frame, '/' + self._world_frame):
            return ''
        return frame_id

    def _spawn_one(self, sim: _Sim, name: str, allow_renaming: bool, uri: str,
                   resource_string: str, namespace: str, initial_pose) -> str:
        src = self._source_for(uri, resource_string)  # parse outside the world lock
        pos, quat = convert.pose_from_msg(initial_pose.pose)
        return sim.world.spawn(name, src, pos, quat,
                               reference=self._reference_frame(initial_pose.header.frame_id),
                               allow_renaming=allow_renaming, namespace=namespace)

    def _srv_spawn(self, request, response):
        sim = self._require()
        response.entity_name = self._spawn_one(
            sim, request.name, request.allow_renaming, request.uri, request.resource_string,
            request.entity_namespace, request.initial_pose)
        self._after_change(sim)
        response.result = convert.ok()
        return response

    def _srv_spawn_many(self, request, response):
        from simulation_interfaces.msg import SpawnResult
        sim = self._require()
        failed = 0
        for req in request.spawn_requests:
            res = SpawnResult()
            try:
                res.entity_name = self._spawn_one(
                    sim, req.name, req.allow_renaming, req.entity_resource.uri,
                    req.entity_resource.resource_string, req.entity_namespace, req.initial_pose)
                res.result = convert.ok()
            except SimError as exc:
                failed += 1
                res.result = convert.result_for(exc, SpawnResult)
            response.results.append(res)
        self._after_change(sim)
        if failed:
            response.result = Result(result=si_srv.SpawnEntities.Response.ENTITIES_SPAWN_FAILED,
                                     error_message=f'{failed} of {len(request.spawn_requests)} '
                                     'spawns failed; see results')
        else:
            response.result = convert.ok()
        return response

    def _srv_delete(self, request, response):
        sim = self._require()
        sim.world.delete(request.entity)
        self._after_change(sim)
        response.result = convert.ok()
        return response

    # ---- entities

    def _filtered(self, sim: _Sim, filters) -> list:
        recs = sim.world.entities()
        if filters.filter:
            try:
                rx = re.compile(filters.filter)
            except re.error as exc:
                raise InvalidArgumentError(f'invalid filter regex {filters.filter!r}: {exc}')
            recs = [r for r in recs if rx.search(r.name)]
        if len(filters.categories):
            wanted = {c.category for c in filters.categories}
            recs = [r for r in recs if convert.CATEGORY_TO_MSG[r.category] in wanted]
        if len(filters.tags.tags):
            # Entities carry no tags: an ANY or ALL filter with tags matches nothing.
            recs = []
        b = filters.bounds
        if b.type == Bounds.TYPE_BOX:
            if len(b.points) != 2:
                raise InvalidArgumentError('box bounds need 2 points: min and max corners')
            lo, hi = convert.vec_from_msg(b.points[0]), convert.vec_from_msg(b.points[1])
            recs = [r for r in recs if self._inside(sim, r.name, lambda p: all(
                lo <= p) and all(p <= hi))]
        elif b.type == Bounds.TYPE_SPHERE:
            if len(b.points) != 2:
                raise InvalidArgumentError('sphere bounds need 2 points: center and (radius, '
                                           '0, 0)')
            c, radius = convert.vec_from_msg(b.points[0]), b.points[1].x
            recs = [r for r in recs if self._inside(
                sim, r.name, lambda p: math.dist(p, c) <= radius)]
        elif b.type == Bounds.TYPE_CONVEX_HULL:
            raise sources.UnsupportedFormatError('convex hull bounds filters are not supported')
        return recs

    @staticmethod
    def _inside(sim: _Sim, name: str, test) -> bool:
        return bool(test(sim.world.get_entity_state(name).position))

    def _srv_get_entities(self, request, response):
        response.entities = [r.name for r in self._filtered(self._require(), request.filters)]
        response.result = convert.ok()
        return response

    def _srv_get_state(self, request, response):
        state = self._require().world.get_entity_state(request.entity)
        response.state = convert.entity_state_to_msg(state, self._world_frame)
        response.result = convert.ok()
        return response

    def _srv_get_states(self, request, response):
        sim = self._require()
        for rec in self._filtered(sim, request.filters):
            try:
                state = sim.world.get_entity_state(rec.name)
            except NotFoundError:
                continue  # deleted meanwhile
            response.entities.append(rec.name)
            response.states.append(convert.entity_state_to_msg(state, self._world_frame))
        response.result = convert.ok()
        return response

    def _srv_set_state(self, request, response):
        sim = self._require()
        st = request.state
        pos, quat = convert.pose_from_msg(st.pose)
        sim.world.set_entity_state(
            request.entity, position=pos, quat_wxyz=quat,
            linear_velocity=convert.vec_from_msg(st.twist.linear),
            angular_velocity=convert.vec_from_msg(st.twist.angular),
            reference=self._reference_frame(st.header.frame_id))
        self._after_change(sim)
        response.result = convert.ok()
        return response

    def _srv_get_info(self, request, response):
        rec = self._require().world.entity(request.entity)
        response.info = EntityInfo(category=EntityCategory(
            category=convert.CATEGORY_TO_MSG[rec.category]), description=rec.description,
            tags=[])
        response.result = convert.ok()
        return response

    def _srv_get_bounds(self, request, response):
        lo, hi = self._require().world.entity_bounds(request.entity)
        response.bounds = convert.bounds_box(lo, hi)
        response.result = convert.ok()
        return response

    def _srv_spawnables(self, request, response):
        for uri, desc in resources.list_spawnables(self._resource_paths, self._scenes_dir,
                                                   list(request.sources)):
            response.spawnables.append(Spawnable(uri=uri, description=desc))
        response.result = convert.ok()
        return response

    # ---- simulation control

    def _srv_reset(self, request, response):
        sim = self._require()
        sim.world.reset(int(request.scope))
        self._after_change(sim)
        response.result = convert.ok()
        return response

    def _srv_step(self, request, response):
        sim = self._require()
        if request.steps < 1:
            raise InvalidArgumentError('steps must be >= 1')
        sim.loop.step(int(request.steps))
        response.result = convert.ok()
        return response

    def _sim_state(self) -> str:
        sim = self._sim
        if sim is None:
            return 'no_world'
        if self._stopped:
            return 'stopped'
        return 'paused' if sim.loop.paused else 'playing'

    def _srv_get_sim_state(self, request, response):
        response.state = convert.simulation_state(self._sim_state())
        response.result = convert.ok()
        return response

    def _srv_set_sim_state(self, request, response):
        target = request.state.state
        s = SimulationState
        resp = si_srv.SetSimulationState.Response
        if target == s.STATE_QUITTING or target not in (s.STATE_PLAYING, s.STATE_PAUSED,
                                                        s.STATE_STOPPED):
            response.result = Result(result=resp.INCORRECT_TRANSITION, error_message=(
                f'cannot set state {target}: use PLAYING ({s.STATE_PLAYING}), PAUSED '
                f'({s.STATE_PAUSED}) or STOPPED ({s.STATE_STOPPED})'))
            return response
        sim = self._require()
        current = convert.simulation_state(self._sim_state()).state
        if current == target:
            response.result = Result(result=resp.ALREADY_IN_TARGET_STATE,
                                     error_message='already in that state')
            return response
        if target == s.STATE_PLAYING:
            self._stopped = False
            sim.loop.play()
        elif target == s.STATE_PAUSED:
            self._stopped = False
            sim.loop.pause()
        else:
            sim.loop.pause()
            sim.world.reset(RESET_ALL)
            self._stopped = True
            self._after_change(sim)
        self._sync_paused_parameter()
        response.result = convert.ok()
        return response

    def _act_simulate(self, goal_handle):
        sim = self._sim
        total = int(goal_handle.request.steps)
        result = SimulateSteps.Result()
        if sim is None or total < 1:
            goal_handle.abort()
            result.result = Result(result=Result.RESULT_INCORRECT_STATE if sim is None else
                                   Result.RESULT_OPERATION_FAILED,
                                   error_message=ERR_NO_WORLD if sim is None else
                                   'steps must be >= 1')
            return result
        chunk = max(1, total // 100)
        done = 0
        try:
            while done < total:
                if goal_handle.is_cancel_requested:
                    goal_handle.canceled()
                    result.result = Result(result=Result.RESULT_OK,
                                           error_message=f'canceled after {done} steps')
                    return result
                done += sim.loop.step(min(chunk, total - done))
                fb = SimulateSteps.Feedback(completed_steps=done, remaining_steps=total - done)
                goal_handle.publish_feedback(fb)
        except SimError as exc:
            goal_handle.abort()
            result.result = convert.result_for(exc)
            return result
        goal_handle.succeed()
        result.result = convert.ok()
        return result

    # ---- worlds

    def _srv_worlds(self, request, response):
        for name, uri in resources.list_worlds(self._scenes_dir):
            response.worlds.append(WorldResource(name=name, description=f'scene {name}',
                                                 world_resource=_resource(uri)))
        for src in request.additional_sources:
            folder = resources.check_folder(src, self._resource_paths)
            for f in sorted(folder.glob('*.xml')):
                response.worlds.append(WorldResource(name=f.stem, description=str(f),
                                                     world_resource=_resource(f.as_uri())))
        if request.filter.tags and request.filter.filter_mode in (TagsFilter.FILTER_MODE_ANY,
                                                                  TagsFilter.FILTER_MODE_ALL):
            response.worlds = []  # worlds carry no tags
        response.result = convert.ok()
        return response

    def _srv_load_world(self, request, response):
        cfg = self.world_config()
        if request.resource_string:
            src = request.resource_string
            # Size, XML, and files only inside the resource paths: the same checks as a spawn.
            sources.check_model_text(src, None, self._resource_paths, MAX_RESOURCE_STRING_BYTES)
            world = World.from_string(src, cfg)
            name, uri = 'resource_string', ''
        else:
            path = resources.resolve_uri(request.uri, self._resource_paths, self._scenes_dir)
            sources.check_model_text(path.read_text(), str(path.parent), self._resource_paths)
            world = World.from_file(str(path), cfg)
            name, uri = path.stem, request.uri
        self._stopped = False
        self._install(world, name, uri)
        response.world = WorldResource(name=name, world_resource=_resource(uri))
        response.result = convert.ok()
        return response

    def _srv_unload_world(self, request, response):
        with self._sim_lock:
            sim, self._sim = self._sim, None
        if sim is None:
            response.result = Result(result=si_srv.UnloadWorld.Response.NO_WORLD_LOADED,
                                     error_message=ERR_NO_WORLD)
            return response
        sim.loop.stop()
        self._published_generation = None
        self._marker_pub.publish(markers.clear_markers(sim.world.time, self._world_frame))
        self._tf_static_pub.publish(TFMessage())
        response.result = convert.ok()
        return response

    def _srv_current_world(self, request, response):
        sim = self._sim
        if sim is None:
            response.result = Result(result=si_srv.GetCurrentWorld.Response.NO_WORLD_LOADED,
                                     error_message=ERR_NO_WORLD)
            return response
        response.world = WorldResource(name=sim.name, world_resource=_resource(sim.uri))
        response.result = convert.ok()
        return response


def _resource(uri: str):
    from simulation_interfaces.msg import Resource
    return Resource(uri=uri, resource_string='')
