"""
The node's simulation_interfaces services and the simulate_steps action.

Each callback converts the request, calls the core, converts the answer (``msg_adapters``). A mixin
of :class:`~sim_node.node.SimNode`, which owns the publishers, timers, parameters and lifecycle.
"""

import threading
import traceback

from msg_adapters import convert, markers
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from simulation_interfaces import srv as si_srv
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import (EntityCategory, EntityInfo, Resource, Result,
                                       SimulationState, SimulatorFeatures, Spawnable,
                                       WorldResource)
from tf2_msgs.msg import TFMessage

from . import entity_query, resources
from .core import sources
from .core.errors import FeatureUnsupportedError, NotFoundError, SimError
from .core.loop import SimLoop
from .core.records import RESET_ALL
from .core.world import World
from .qos import FEEDBACK_QOS, SERVICE_QOS

MAX_RESOURCE_STRING_BYTES = 5_000_000
#: Most steps simulate_steps runs between two looks for a cancel (a few ms of physics).
SIMULATE_CHUNK_STEPS = 200
QUIT_DELAY_SEC = 0.3  # after the QUITTING answer, before the process ends
ERR_NO_WORLD = 'no world is loaded; call load_world first'
ERR_TOO_MANY_STEPS = ('{n} steps is more than one step_simulation request may take '
                      '(max_steps_per_request {limit}): use the simulate_steps action '
                      '(simulation_interfaces/action/SimulateSteps), which reports progress and '
                      'can be cancelled')


class Sim:
    """A loaded world with its loop and where it came from."""

    def __init__(self, world: World, loop: SimLoop, name: str, uri: str):
        self.world, self.loop, self.name, self.uri = world, loop, name, uri


class SimServices:
    """Service and action callbacks of the sim node (see the module docstring)."""

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
        # Interfaces of features we do not list: served, so a client hears why, not a timeout.
        for name, srv_type, feature in UNSUPPORTED:
            table[name] = (srv_type, _unsupported(feature))
        for name, (srv_type, handler) in table.items():
            self.create_service(srv_type, name, self._guard(srv_type, handler),
                                qos_profile=SERVICE_QOS, callback_group=g)
        self._action = ActionServer(
            self, SimulateSteps, 'simulate_steps', execute_callback=self._act_simulate,
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda handle: CancelResponse.ACCEPT, callback_group=g,
            feedback_pub_qos_profile=FEEDBACK_QOS)

    def _guard(self, srv_type, handler):
        """Every core error becomes a Result; nothing escapes to kill spin()."""
        def callback(request, response):
            try:
                response = handler(request, response)
            except Exception as exc:  # a bug must not take the node down: report it
                response.result = self._result_for(exc, srv_type.Response, handler.__name__)
            result = getattr(response, 'result', None)  # get_simulator_features has none
            if result is not None and result.error_message:
                result.error_message = self._redact(result.error_message)
            return response
        return callback

    def _result_for(self, exc: Exception, response_type, where: str) -> Result:
        """Return the Result for an exception: its code, or an internal error (logged)."""
        if isinstance(exc, SimError):
            return convert.result_for(exc, response_type)
        trace = ''.join(traceback.format_exception(exc)).rstrip()
        self.get_logger().error(f'{where} failed: {exc!r}; please report this with the '
                                f'traceback:\n{trace}')
        return Result(result=Result.RESULT_OPERATION_FAILED,
                      error_message=f'internal error: {exc!r}')

    def _redact(self, text: str) -> str:
        return resources.redact(text, self._resource_paths, self._scenes_dir)

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
        if resource_string and not uri:  # the standard: a uri, when given, wins
            # from_model_text refuses text over max_bytes (UNSUPPORTED_ASSETS) before parsing.
            return sources.from_model_text(resource_string, base_dir=None,
                                           allowed_roots=roots,
                                           max_bytes=MAX_RESOURCE_STRING_BYTES)
        path = resources.resolve_uri(uri, roots, self._scenes_dir)
        return sources.from_file(str(path), allowed_roots=roots)

    def _reference_frame(self, frame_id: str) -> str:
        """'' for the world frame, else the entity whose frame the pose is given in."""
        if frame_id in ('', self._world_frame, '/' + self._world_frame, self._out_world_frame):
            return ''
        return frame_id

    def _spawn_one(self, sim: Sim, name: str, allow_renaming: bool, uri: str,
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
        from simulation_interfaces.msg import SpawnResult  # only in releases that have it
        sim = self._require()
        failed = 0
        for req in request.spawn_requests:
            res = SpawnResult()
            try:  # one result per request, whatever happens; earlier spawns stay
                res.entity_name = self._spawn_one(
                    sim, req.name, req.allow_renaming, req.entity_resource.uri,
                    req.entity_resource.resource_string, req.entity_namespace, req.initial_pose)
                res.result = convert.ok()
            except Exception as exc:
                failed += 1
                res.result = self._result_for(exc, SpawnResult, 'spawn_entities')
                res.result.error_message = self._redact(res.result.error_message)
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

    @staticmethod
    def _filtered(sim: Sim, filters) -> list:
        return entity_query.query(sim.world, **convert.entity_filters(filters))

    def _srv_get_entities(self, request, response):
        response.entities = [r.name for r in self._filtered(self._require(), request.filters)]
        response.result = convert.ok()
        return response

    def _srv_get_state(self, request, response):
        state = self._require().world.get_entity_state(request.entity)
        response.state = convert.entity_state_to_msg(state, self._out_world_frame)
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
            response.states.append(convert.entity_state_to_msg(state, self._out_world_frame))
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
            reference=self._reference_frame(st.header.frame_id),
            acceleration=[*convert.vec_from_msg(st.acceleration.linear),
                          *convert.vec_from_msg(st.acceleration.angular)])
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
        # The standard: in the entity's canonical link frame (its root body's frame).
        lo, hi = self._require().world.entity_bounds(request.entity, local=True)
        response.bounds = convert.bounds_box(lo, hi)
        response.result = convert.ok()
        return response

    def _srv_spawnables(self, request, response):
        unrecognised = []  # the standard: named in error_message, and the call succeeds
        for uri, desc in resources.list_spawnables(self._resource_paths, self._scenes_dir,
                                                   list(request.sources), unrecognised):
            response.spawnables.append(Spawnable(uri=uri, description=desc))
        response.result = convert.ok()
        if unrecognised:
            response.result.error_message = ('sources not recognised, left out: '
                                             + '; '.join(unrecognised))
        return response

    # ---- simulation control

    def _srv_reset(self, request, response):
        sim = self._require()
        sim.world.reset(int(request.scope))
        sim.loop.recover()  # a failed loop comes back, paused, after a reset
        self._after_change(sim)
        response.result = convert.ok()
        return response

    def _srv_step(self, request, response):
        sim = self._require()
        limit = self._param('max_steps_per_request')
        if request.steps > limit:
            response.result = Result(result=Result.RESULT_OPERATION_FAILED,
                                     error_message=ERR_TOO_MANY_STEPS.format(n=request.steps,
                                                                             limit=limit))
            return response
        if request.steps > 0:  # 0 steps: nothing to do, answered OK
            sim.loop.step(int(request.steps))
            self._stopped = False  # stepped from STOPPED: paused, no longer at the reset state
        response.result = convert.ok()
        return response

    def _sim_state(self) -> str:
        sim = self._sim
        if self._loading:
            return 'loading_world'
        if sim is None:
            return 'no_world'
        if self._stopped or sim.loop.failure:
            return 'stopped'
        return 'paused' if sim.loop.paused else 'playing'

    def _srv_get_sim_state(self, request, response):
        response.state = convert.simulation_state(self._sim_state())
        response.result = convert.ok()
        sim = self._sim
        if sim is not None:  # OK, with why it stopped or a word when the physics lags
            status = sim.loop.status()
            response.result.error_message = status.stop_reason or status.lag
        return response

    def _srv_set_sim_state(self, request, response):
        target = request.state.state
        s = SimulationState
        resp = si_srv.SetSimulationState.Response
        if target == s.STATE_QUITTING:
            return self._quit(response)
        if target not in (s.STATE_PLAYING, s.STATE_PAUSED, s.STATE_STOPPED):
            response.result = Result(result=resp.INCORRECT_TRANSITION, error_message=(
                f'cannot set state {target}: use PLAYING ({s.STATE_PLAYING}), PAUSED '
                f'({s.STATE_PAUSED}), STOPPED ({s.STATE_STOPPED}) or QUITTING '
                f'({s.STATE_QUITTING})'))
            return response
        if self._loading:  # the standard: not until the world has loaded
            response.result = Result(result=resp.INCORRECT_TRANSITION, error_message=(
                'a world is loading (LOADING_WORLD): ask again when load_world has answered'))
            return response
        sim = self._require()
        sim.loop.cancel_steps()  # any state request ends a step request in progress
        current = convert.simulation_state(self._sim_state()).state
        if current == target and not sim.loop.failure:  # STOPPED after a failure: reset
            response.result = Result(result=resp.ALREADY_IN_TARGET_STATE,
                                     error_message='already in that state')
            return response
        if sim.loop.failure and target != s.STATE_STOPPED:
            response.result = Result(result=resp.STATE_TRANSITION_ERROR,
                                     error_message=sim.loop.failure)
            return response
        if target == s.STATE_PLAYING:
            self._stopped = False
            sim.loop.play()
        elif target == s.STATE_PAUSED:
            self._stopped = False
            sim.loop.pause()
        else:
            self._stop(sim)
        self._sync_paused_parameter()
        response.result = convert.ok()
        return response

    def _stop(self, sim: Sim) -> None:
        """Stop (STOPPED): pause and reset everything; a failed loop comes back."""
        sim.loop.pause()
        sim.world.reset(RESET_ALL)
        sim.loop.recover()
        self._stopped = True
        self._after_change(sim)

    def _quit(self, response):
        """
        QUITTING: stop the simulation (a full reset, as STOPPED), answer, then end the process.

        The answer goes first (the caller hears OK); 0.3 s later the node stops its threads and
        ends as on Ctrl-C, exit status 0, its services gone, well within 2 s.
        """
        sim = self._sim
        if sim is not None:
            sim.loop.cancel_steps()
            self._stop(sim)
        self.get_logger().info('QUITTING requested: the simulation is stopped; exiting')
        threading.Thread(target=self.end_process, args=(QUIT_DELAY_SEC,), name='sim-quit',
                         daemon=True).start()
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
                done += sim.loop.step(min(chunk, total - done))
                self._stopped = False
                for n in range(before + 1, done + 1):
                    if n % every == 0 or n == total:
                        goal_handle.publish_feedback(SimulateSteps.Feedback(
                            completed_steps=n, remaining_steps=total - n))
        except SimError as exc:
            goal_handle.abort()
            result.result = convert.result_for(exc)
            return result
        goal_handle.succeed()
        result.result = convert.ok()
        return result

    # ---- worlds

    def _srv_worlds(self, request, response):
        if len(request.filter.tags):
            raise FeatureUnsupportedError('world tag filters are not supported (WORLD_TAGS is '
                                          'not listed): worlds carry no tags')
        for name, uri in resources.list_worlds(self._scenes_dir):
            response.worlds.append(WorldResource(name=name, description=f'scene {name}',
                                                 world_resource=_resource(uri)))
        failed = []
        for src in request.additional_sources:
            try:
                folder = resources.check_folder(src, self._resource_paths)
            except SimError as exc:
                if not request.continue_on_error:
                    raise
                failed.append(str(exc))  # the standard: go on, and succeed with the rest
                continue
            for f in sorted(folder.glob('*.xml')):
                response.worlds.append(WorldResource(name=f.stem, description=str(f),
                                                     world_resource=_resource(f.as_uri())))
        response.result = convert.ok()
        response.result.error_message = '; '.join(failed)
        return response

    def _srv_load_world(self, request, response):
        """Read, check and compile the world (LOADING_WORLD meanwhile), then swap it in."""
        with self._loading_lock:
            self._loading += 1
        try:
            return self._load_world(request, response)
        finally:
            with self._loading_lock:
                self._loading -= 1

    def _load_world(self, request, response):
        cfg = self.world_config()
        # The same checks as a spawn: safe XML, budgets, and every file read here, from inside
        # the resource paths (MuJoCo opens nothing itself).
        modes = {'fail_on_unsupported_element': request.fail_on_unsupported_element,
                 'ignore_missing_assets': request.ignore_missing_or_unsupported_assets}
        if request.resource_string and not request.uri:  # the standard: a uri, when given, wins
            spec, dropped = sources.world_spec(request.resource_string, None,
                                               self._resource_paths, MAX_RESOURCE_STRING_BYTES,
                                               **modes)
            name, uri = 'resource_string', ''
        else:
            path = resources.resolve_world(request.uri, self._resource_paths, self._scenes_dir)
            spec, dropped = sources.world_spec(sources.read_model_text(path), str(path.parent),
                                               self._resource_paths, **modes)
            name, uri = path.stem, request.uri
        world = World(spec, cfg, source=name)
        # The standard: a loaded world is left STOPPED (at its initial state, not stepping).
        self._stopped = True
        self._install(world, name, uri, paused=True)
        self._sync_paused_parameter()
        response.world = WorldResource(name=name, world_resource=_resource(uri))
        response.result = convert.ok()
        if dropped:
            note = f'left out elements MuJoCo does not know: {sources.element_list(dropped)}'
            self.get_logger().warning(f'load_world {name}: {note}')
            response.result.error_message = note
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
        self._marker_pub.publish(markers.clear_markers(sim.world.time, self._out_world_frame))
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


def _resource(uri: str) -> Resource:
    return Resource(uri=uri, resource_string='')
