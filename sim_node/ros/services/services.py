"""
The node's simulation_interfaces services and the simulate_steps action.

Each callback converts the request, asks the session or its world, converts the answer
(``msg_adapters``). Core errors become Result codes in one table
(:func:`msg_adapters.convert.result_for`); an unexpected exception is logged with its traceback
and answered as an internal error, never let out to stop the executor.
"""

import threading
import time
import traceback
from typing import Callable

from msg_adapters import convert
from rclpy.action import CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from simulation_interfaces import srv as si_srv
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import (EntityCategory, EntityInfo, Result, SimulationState,
                                       SimulatorFeatures, Spawnable)

from .worlds import MAX_RESOURCE_STRING_BYTES, Worlds
from ..control.controller_manager import with_update_rate
from ..settings import replies
from ..settings.params import Frames
from ..settings.qos import FEEDBACK_QOS, SERVICE_QOS
from ... import session as lifecycle
from ...core import query
from ...core.base.errors import IncorrectTransitionError, NotFoundError, SimError
from ...core.models import resources, sources
from ...core.world import World
from ...session import Loaded, Session

#: Most steps simulate_steps runs between two looks for a cancel (a few ms of physics).
SIMULATE_CHUNK_STEPS = 200
#: Between a goal's last feedback and its result (s). rclpy's ActionClient takes a ready
#: feedback message and a ready result in one pass and drops the goal's feedback once its result
#: is in: without this pause a client whose executor is slow (a loaded host) sees one message
#: of a goal, or none.
SIMULATE_RESULT_SETTLE_SEC = 0.05
QUIT_DELAY_SEC = 0.3  # after the QUITTING answer, before the process ends
ERR_TOO_MANY_STEPS = ('{n} steps is more than one step_simulation request may take '
                      '(max_steps_per_request {limit}): use the simulate_steps action '
                      '(simulation_interfaces/action/SimulateSteps), which reports progress and '
                      'can be cancelled')
#: simulation_interfaces state -> the session's.
_REQUESTED = {SimulationState.STATE_PLAYING: lifecycle.PLAYING,
              SimulationState.STATE_PAUSED: lifecycle.PAUSED,
              SimulationState.STATE_STOPPED: lifecycle.STOPPED}


#: The handlers that change which entities there are.
EDITS = ('_spawn', '_spawn_many', '_delete', '_reset', 'load_world', 'unload_world')


class Services:
    """
    The services and the simulate_steps action of a node over a session.

    :param param: returns a parameter's value by name.
    :param on_state_change: called after a service changed the simulation state.
    :param quit_process: called (on a thread of its own) to end the process after QUITTING.
    """

    def __init__(self, node: Node, session: Session, frames: Frames,
                 readable: resources.Readable, param: Callable, world_config: Callable,
                 on_state_change: Callable[[], None], quit_process: Callable[[float], None]):
        self._node = node
        self._session = session
        self._frames = frames
        self._readable = readable
        self._param = param
        self._world_config = world_config
        self._on_state_change = on_state_change
        self._quit_process = quit_process
        #: Called after a spawn, delete, reset or load answers (before its answer goes out).
        self.after_edit: Callable[[], None] = lambda: None
        #: Called after a reset, after `after_edit` (the robots' controllers start again).
        self.after_reset: Callable[[], None] = lambda: None
        worlds = Worlds(node, session, readable, world_config, on_state_change)
        group = ReentrantCallbackGroup()
        table = {
            'get_simulator_features': (si_srv.GetSimulatorFeatures, self._features),
            'spawn_entity': (si_srv.SpawnEntity, self._spawn),
            'delete_entity': (si_srv.DeleteEntity, self._delete),
            'get_entities': (si_srv.GetEntities, self._get_entities),
            'get_entity_state': (si_srv.GetEntityState, self._get_state),
            'get_entities_states': (si_srv.GetEntitiesStates, self._get_states),
            'set_entity_state': (si_srv.SetEntityState, self._set_state),
            'get_entity_info': (si_srv.GetEntityInfo, self._get_info),
            'get_entity_bounds': (si_srv.GetEntityBounds, self._get_bounds),
            'get_spawnables': (si_srv.GetSpawnables, self._spawnables),
            'reset_simulation': (si_srv.ResetSimulation, self._reset),
            'step_simulation': (si_srv.StepSimulation, self._step),
            'get_simulation_state': (si_srv.GetSimulationState, self._get_sim_state),
            'set_simulation_state': (si_srv.SetSimulationState, self._set_sim_state),
            'get_available_worlds': (si_srv.GetAvailableWorlds, worlds.available_worlds),
            'load_world': (si_srv.LoadWorld, worlds.load_world),
            'unload_world': (si_srv.UnloadWorld, worlds.unload_world),
            'get_current_world': (si_srv.GetCurrentWorld, worlds.current_world),
        }
        if hasattr(si_srv, 'SpawnEntities'):
            table['spawn_entities'] = (si_srv.SpawnEntities, self._spawn_many)
        # Interfaces of features we do not list: served, so a client hears why, not a timeout.
        for name, srv_type, feature in UNSUPPORTED:
            table[name] = (srv_type, _unsupported(feature))
        for name, (srv_type, handler) in table.items():
            # a reply the middleware could not send at once is sent again (replies)
            replies.deliver(node.create_service(srv_type, name, self._guard(srv_type, handler),
                                                qos_profile=SERVICE_QOS, callback_group=group))
        self.action = replies.ResendingActionServer(
            node, SimulateSteps, 'simulate_steps', execute_callback=self._simulate,
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda handle: CancelResponse.ACCEPT, callback_group=group,
            feedback_pub_qos_profile=FEEDBACK_QOS)

    def _guard(self, srv_type, handler):
        """Every core error becomes a Result; nothing escapes to kill spin()."""
        edits = handler.__name__ in EDITS

        def callback(request, response):
            try:
                response = handler(request, response)
                if edits:
                    self.after_edit()
                if handler.__name__ == '_reset':
                    self.after_reset()
            except Exception as exc:  # a bug must not take the node down: report it
                response.result = self._result_for(exc, srv_type.Response, handler.__name__)
            result = getattr(response, 'result', None)  # get_simulator_features has none
            if result is not None and result.error_message:
                result.error_message = self._readable.redact(result.error_message)
            return response
        return callback

    def _result_for(self, exc: Exception, response_type, where: str) -> Result:
        """Return the Result for an exception: its code, or an internal error (logged)."""
        if isinstance(exc, SimError):
            return convert.result_for(exc, response_type)
        trace = ''.join(traceback.format_exception(exc)).rstrip()
        self._node.get_logger().error(f'{where} failed: {exc!r}; please report this with the '
                                      f'traceback:\n{trace}')
        return Result(result=Result.RESULT_OPERATION_FAILED,
                      error_message=f'internal error: {exc!r}')

    def _features(self, request, response):
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
        response.features.spawn_formats = ['mjcf', 'urdf', 'sdf'] + [
            s[1:] for s in sources.MESH_SUFFIXES]
        response.features.custom_info = (
            'MuJoCo simulator. Spawn: uri = spawnable name, package://sim/..., model:// (Gazebo '
            'models on GZ_SIM_RESOURCE_PATH and resource_paths), file:// inside resource_paths '
            '(MJCF, URDF, SDF, STL, OBJ, PLY, GLB, DAE) or resource_string (MJCF, URDF or SDF '
            'text). initial_pose.header.frame_id: empty or the world frame, or an entity. '
            'load_world takes MJCF and SDF worlds.')
        return response

    # ---- spawning

    def _source_for(self, uri: str, resource_string: str,
                    max_bodies: int) -> sources.SpawnSource:
        roots = list(self._readable.roots)
        places = self._readable.places
        loaded = self._session.loaded
        world = loaded.name if loaded is not None else 'default'
        if resource_string and not uri:  # the standard: a uri, when given, wins
            # from_model_text refuses text over max_bytes (UNSUPPORTED_ASSETS) before parsing.
            return sources.from_model_text(resource_string, base_dir=None,
                                           allowed_roots=roots,
                                           max_bytes=MAX_RESOURCE_STRING_BYTES,
                                           max_bodies=max_bodies, places=places,
                                           world=world)
        uri, options = resources.split_options(uri)  # ?static=true, xacro name:=value
        path = resources.resolve_uri(uri, roots, self._readable.scenes_dir, places)
        return sources.from_file(str(path), allowed_roots=roots, fixed=options.fixed,
                                 xacro_args=options.xacro_args, max_bodies=max_bodies,
                                 places=places, world=world)

    def _spawn_one(self, world: World, name: str, allow_renaming: bool, uri: str,
                   resource_string: str, namespace: str, initial_pose) -> str:
        # parsed (meshes converted, xacro expanded) outside the world lock
        src = self._source_for(uri, resource_string, world.config.max_bodies)
        with_update_rate(src, namespace, self._readable.roots)
        pos, quat = convert.pose_from_msg(initial_pose.pose)
        return world.spawn(name, src, pos, quat,
                           reference=self._frames.reference(initial_pose.header.frame_id),
                           allow_renaming=allow_renaming, namespace=namespace)

    def _spawn(self, request, response):
        loaded = self._session.require()
        response.entity_name = self._spawn_one(
            loaded.world, request.name, request.allow_renaming, request.uri,
            request.resource_string, request.entity_namespace, request.initial_pose)
        self._session.changed()
        response.result = convert.ok()
        return response

    def _spawn_many(self, request, response):
        from simulation_interfaces.msg import SpawnResult  # only in releases that have it
        world = self._session.require().world
        failed = 0
        for req in request.spawn_requests:
            res = SpawnResult()
            try:  # one result per request, whatever happens; earlier spawns stay
                res.entity_name = self._spawn_one(
                    world, req.name, req.allow_renaming, req.entity_resource.uri,
                    req.entity_resource.resource_string, req.entity_namespace, req.initial_pose)
                res.result = convert.ok()
            except Exception as exc:
                failed += 1
                res.result = self._result_for(exc, SpawnResult, 'spawn_entities')
                res.result.error_message = self._readable.redact(res.result.error_message)
            response.results.append(res)
        self._session.changed()
        if failed:
            response.result = Result(result=si_srv.SpawnEntities.Response.ENTITIES_SPAWN_FAILED,
                                     error_message=f'{failed} of {len(request.spawn_requests)} '
                                     'spawns failed; see results')
        else:
            response.result = convert.ok()
        return response

    def _delete(self, request, response):
        self._session.require().world.delete(request.entity)
        self._session.changed()
        response.result = convert.ok()
        return response

    # ---- entities

    def _filtered(self, loaded: Loaded, filters) -> list:
        return query.query(loaded.world, **convert.entity_filters(filters))

    def _get_entities(self, request, response):
        loaded = self._session.require()
        response.entities = [r.name for r in self._filtered(loaded, request.filters)]
        response.result = convert.ok()
        return response

    def _get_state(self, request, response):
        state = self._session.require().world.get_entity_state(request.entity)
        response.state = convert.entity_state_to_msg(state, self._frames.out_world)
        response.result = convert.ok()
        return response

    def _get_states(self, request, response):
        loaded = self._session.require()
        for rec in self._filtered(loaded, request.filters):
            try:
                state = loaded.world.get_entity_state(rec.name)
            except NotFoundError:
                continue  # deleted meanwhile
            response.entities.append(rec.name)
            response.states.append(convert.entity_state_to_msg(state, self._frames.out_world))
        response.result = convert.ok()
        return response

    def _set_state(self, request, response):
        world = self._session.require().world
        st = request.state
        pos, quat = convert.pose_from_msg(st.pose)
        world.set_entity_state(
            request.entity, position=pos, quat_wxyz=quat,
            linear_velocity=convert.vec_from_msg(st.twist.linear),
            angular_velocity=convert.vec_from_msg(st.twist.angular),
            reference=self._frames.reference(st.header.frame_id),
            acceleration=[*convert.vec_from_msg(st.acceleration.linear),
                          *convert.vec_from_msg(st.acceleration.angular)])
        self._session.changed()
        response.result = convert.ok()
        return response

    def _get_info(self, request, response):
        rec = self._session.require().world.entity(request.entity)
        response.info = EntityInfo(category=EntityCategory(
            category=convert.CATEGORY_TO_MSG[rec.category]), description=rec.description,
            tags=[])
        response.result = convert.ok()
        return response

    def _get_bounds(self, request, response):
        # The standard: in the entity's canonical link frame (its root body's frame).
        lo, hi = self._session.require().world.entity_bounds(request.entity, local=True)
        response.bounds = convert.bounds_box(lo, hi)
        response.result = convert.ok()
        return response

    def _spawnables(self, request, response):
        unrecognised = []  # the standard: named in error_message, and the call succeeds
        for uri, desc in resources.list_spawnables(list(self._readable.roots),
                                                   self._readable.scenes_dir,
                                                   list(request.sources), unrecognised,
                                                   self._readable.places):
            response.spawnables.append(Spawnable(uri=uri, description=desc))
        response.result = convert.ok()
        if unrecognised:
            response.result.error_message = ('sources not recognised, left out: '
                                             + '; '.join(unrecognised))
        return response

    # ---- simulation control

    def _reset(self, request, response):
        self._session.reset(int(request.scope))
        response.result = convert.ok()
        return response

    def _step(self, request, response):
        self._session.require()
        limit = self._param('max_steps_per_request')
        if request.steps > limit:
            response.result = Result(result=Result.RESULT_OPERATION_FAILED,
                                     error_message=ERR_TOO_MANY_STEPS.format(n=request.steps,
                                                                             limit=limit))
            return response
        if request.steps > 0:  # 0 steps: nothing to do, answered OK
            self._session.step(int(request.steps))
        response.result = convert.ok()
        return response

    def _get_sim_state(self, request, response):
        response.state = convert.simulation_state(self._session.state)
        response.result = convert.ok()
        # OK, with why it stopped or a word when the physics lags
        response.result.error_message = self._session.status_message()
        return response

    def _set_sim_state(self, request, response):
        target = request.state.state
        if target == SimulationState.STATE_QUITTING:
            return self._quit(response)
        if target not in _REQUESTED:
            s = SimulationState
            raise IncorrectTransitionError(
                f'cannot set state {target}: use PLAYING ({s.STATE_PLAYING}), PAUSED '
                f'({s.STATE_PAUSED}), STOPPED ({s.STATE_STOPPED}) or QUITTING '
                f'({s.STATE_QUITTING})')
        self._session.set_state(_REQUESTED[target])
        self._on_state_change()
        response.result = convert.ok()
        return response

    def _quit(self, response):
        """
        QUITTING: stop the simulation (a full reset, as STOPPED), answer, then end the process.

        The answer goes first (the caller hears OK); 0.3 s later the node stops its threads and
        ends as on Ctrl-C, exit status 0, its services gone, well within 2 s.
        """
        if self._session.loaded is not None:
            self._session.stop()
        self._node.get_logger().info('QUITTING requested: the simulation is stopped; exiting')
        threading.Thread(target=self._quit_process, args=(QUIT_DELAY_SEC,), name='sim-quit',
                         daemon=True).start()
        response.result = convert.ok()
        return response

    def _simulate(self, goal_handle):
        total = int(goal_handle.request.steps)
        result = SimulateSteps.Result()
        if self._session.loaded is None or total < 1:
            goal_handle.abort()
            none = self._session.loaded is None
            result.result = Result(result=Result.RESULT_INCORRECT_STATE if none else
                                   Result.RESULT_OPERATION_FAILED,
                                   error_message=lifecycle.ERR_NO_WORLD if none else
                                   'steps must be >= 1')
            return result
        # The standard: feedback after each step. The physics runs in chunks (a hundredth of
        # the goal, at most SIMULATE_CHUNK_STEPS) and a message goes out for every step of each
        # chunk, or every `simulate_steps_feedback_every`-th and the last.
        every = self._param('simulate_steps_feedback_every')
        chunk = min(max(1, total // 100), SIMULATE_CHUNK_STEPS)
        done = 0
        try:
            while done < total:
                if goal_handle.is_cancel_requested:
                    goal_handle.canceled()
                    result.result = Result(result=Result.RESULT_OK,
                                           error_message=f'canceled after {done} steps')
                    return result
                before = done
                done += self._session.step(min(chunk, total - done))
                for n in range(before + 1, done + 1):
                    if n % every == 0 or n == total:
                        goal_handle.publish_feedback(SimulateSteps.Feedback(
                            completed_steps=n, remaining_steps=total - n))
        except SimError as exc:
            goal_handle.abort()
            result.result = convert.result_for(exc)
            return result
        time.sleep(SIMULATE_RESULT_SETTLE_SEC)
        goal_handle.succeed()
        result.result = convert.ok()
        return result


#: Interfaces whose features GetSimulatorFeatures does not list: (service, type, feature).
UNSUPPORTED = (('set_entity_info', si_srv.SetEntityInfo, 'ENTITY_INFO_SETTING'),
               ('get_named_poses', si_srv.GetNamedPoses, 'NAMED_POSES'),
               ('get_named_pose_bounds', si_srv.GetNamedPoseBounds, 'POSE_BOUNDS'))


def _unsupported(feature: str):
    def handler(request, response):
        response.result = Result(result=Result.RESULT_FEATURE_UNSUPPORTED, error_message=(
            f'{feature} is not supported by this simulator (see get_simulator_features)'))
        return response
    handler.__name__ = f'unsupported_{feature.lower()}'
    return handler
