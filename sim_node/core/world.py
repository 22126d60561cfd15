"""
The MuJoCo world while it runs: the facade every user of the core talks to.

Its public methods lock, validate and delegate: they are the one surface scripts, the Session,
the Gym envs and the node use, so a method whose work lives in a part still stands here, with
its contract in its docstring. What is current (the lock, the model, data, index, design and
generation) is one :class:`~.stepping.live.Live`; the steps and the stepping loop's protocol are
:mod:`.stepping.steps` (``world.stepping``); structural edits are planned in
:mod:`.editing.edits` and made by the one commit path, :mod:`.editing.transaction`; state
writes are :mod:`.editing.writes`; trajectories, bases, pushes and gains are
:mod:`.control.motion`; addresses come from :mod:`.compiled.index`, reads from
:mod:`.compiled.state`. The threading contract is in the package docstring (``sim_node.core``).
"""

import contextlib
import logging
import math
from pathlib import Path
import time
from typing import Callable, Iterator, Mapping, Optional, Sequence, TypeVar

import mujoco
import numpy as np

from .base.config import WorldConfig
from .base.errors import FeatureUnsupportedError, InvalidArgumentError, ResourceParseError
from .base.records import (Clock, EntityRecord, EntityState, ModelInfo, PhysicsState, RESET_ALL,
                           RESET_SPAWNED, RESET_STATE, RESET_TIME, Snapshot)
from .compiled import state
from .compiled.index import STATE_SPEC
from .control.drives import COMMAND_TIMEOUT
from .control.motion import Motion
from .control.trajectory import TrajectoryHandle
from .editing import editor
from .editing.edits import Edits
from .editing.transaction import Transaction
from .editing.writes import Writes
from .models import (asset_store, decompose, description, resources, sdf_files, sources,
                     world_sources)
from .stepping import guard, sampling
from .stepping.design import Design
from .stepping.live import Live
from .stepping.steps import Stepping

log = logging.getLogger(__name__)

T = TypeVar('T')

ERR_SCOPE = ('reset scope {scope} has bits no simulator defines: use 0 (all), 255 (all) or a '
             'combination of 1 (time), 2 (state) and 4 (spawned)')
ERR_NO_DESCRIPTION = ('entity {name!r} has no hinge or slide joints: only robots have a robot '
                      'description')

_SCOPE_BITS = RESET_TIME | RESET_STATE | RESET_SPAWNED
_NO_AUTORESET = int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)


class World:
    """
    A MuJoCo world that can change while it runs.

    Thread-safe; see ``sim_node.core``. Build with :meth:`from_file` or :meth:`from_string`.
    """

    def __init__(self, spec: mujoco.MjSpec, config: WorldConfig = WorldConfig(),
                 source: str = '', entities: Sequence[tuple] = (), name: str = '',
                 named: bool = False):
        """
        Make the world of `spec`; `source` says where it came from.

        :param entities: ``(name, source, position, quat wxyz)`` of the world's own models made
            on their own (an SDF world's, :attr:`.models.world_sources.WorldSource.entities`):
            attached as the world is made, kept by deletes and resets of the spawned.
        :param name: the name the world gives itself ('' : none).
        :param named: the spec's writer named every element that needs a name (an SDF
            world's): they are not looked over again (50 ms for 3,000 models).
        """
        self.config = config
        self.source = source
        self.name = name
        #: The pace the world's file asks for (an SDF world's ``<real_time_factor>``; None: it
        #: asks none): a loop made without a configuration of its own takes it.
        self.real_time_factor: Optional[float] = None
        #: The gz-sim systems the world's file names that are not run here (an SDF world's
        #: world plugins; its models' are their entities', :meth:`systems_not_run`).
        self.world_systems_not_run: tuple = ()
        # Disable MuJoCo's whole-world auto-reset on NaN: divergence is ours to report.
        spec.option.disableflags |= _NO_AUTORESET
        if config.timestep > 0:
            spec.option.timestep = float(config.timestep)
        guard.route_mujoco_warnings()
        asset_store.set_mesh_cache(config.mesh_cache_mb)
        decompose.configure(config.mesh_decomposition, config.mesh_decomposition_threshold)
        sources.split_marked_meshes(spec)  # a scene file's, load_world's
        decompose.bound_hulls(spec)
        sources.warn_radian_like_ranges(spec, f'the scene {source}'.strip())
        if not named:
            editor.name_unnamed(spec)
        arena = ((config.arena_base_bytes, config.arena_bytes_per_body)
                 if spec.memory == -1 else None)  # the scene left it to MuJoCo's default
        # The edit phase's state, replaced whole by each structural edit (.design).
        design, model = Design.start(spec, arena)
        self._live = live = Live(config, design, model)
        self._descriptions = description.Descriptions()
        #: The stepping loop's way in (:class:`~.stepping.Stepping`).
        self.stepping = Stepping(live)
        self._transaction = Transaction(live)
        self._edits = Edits(live, self._transaction)
        self._writes = Writes(live, self._transaction)
        self._motion = Motion(live)
        if entities:
            self._edits.spawn_world(entities)

    @classmethod
    def from_file(cls, path: str, config: WorldConfig = WorldConfig(),
                  places: Optional[sdf_files.Places] = None) -> 'World':
        """
        Load an MJCF, URDF or SDF scene file.

        :param places: where an SDF world's ``model://`` URIs lead (None: the environment's
            model paths and the models this package ships).
        """
        real = sources.check_path(path, None)
        if real.suffix.lower() in sdf_files.SUFFIXES:
            places = places or sdf_files.Places.of(scenes_dir=resources.installed_scenes_dir())
            plan = world_sources.world_source(sources.read_model_text(real),
                                              str(Path(path).parent), places=places,
                                              name=Path(path).name)
            return cls.from_plan(plan, config, str(path))
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except ValueError as exc:
            raise ResourceParseError(f'cannot load the scene: {exc}') from None
        return cls(spec, config, source=str(path))

    @classmethod
    def from_plan(cls, plan: world_sources.WorldSource, config: WorldConfig = WorldConfig(),
                  source: str = '') -> 'World':
        """
        Make the world a :func:`.models.world_sources.world_source` read (an SDF world's).

        Its entities are attached as it is made; its pace and the systems it names that are
        not run here are kept; the files it copied go if it cannot be made.
        """
        try:
            made = cls(plan.spec, config, source, plan.entities, plan.name, named=True)
        except BaseException:
            plan.settle(False)
            raise
        plan.settle(True)
        made.real_time_factor = plan.real_time_factor
        made.world_systems_not_run = tuple(plan.systems)
        if plan.systems:
            log.warning('the world names gz-sim systems that are not run here: %s (what is: '
                        'docs/sdf.md)', ', '.join(plan.systems))
        return made

    @classmethod
    def from_string(cls, xml: str, config: WorldConfig = WorldConfig()) -> 'World':
        """Load an MJCF (or URDF) scene from text."""
        try:
            spec = mujoco.MjSpec.from_string(xml)
        except ValueError as exc:
            raise ResourceParseError(f'cannot parse scene: {exc}') from None
        return cls(spec, config, source='<string>')

    # ---------------------------------------------------------------- locking

    def holds_lock(self) -> bool:
        """Whether the calling thread holds the world lock (is inside :meth:`locked`)."""
        return self._live.holds_lock()

    @contextlib.contextmanager
    def locked(self) -> Iterator[tuple]:
        """
        Direct access to ``(model, data)`` under the world lock, for advanced use.

        Anything changed here is the caller's responsibility; the loop is held off meanwhile.
        """
        live = self._live
        with live.lock:
            live.cached = None  # the caller may change anything
            try:
                yield live.model, live.data
            finally:  # even when the caller's block raised, after changing something
                live.changed_locked()

    def read(self, read: Callable[[mujoco.MjModel, mujoco.MjData], T]) -> T:
        """
        Return what `read` returns, called with (model, data) under the world lock.

        The current model and data as they are (after a step, body poses are a step behind:
        see :meth:`Live.kinematics_locked <.live.Live.kinematics_locked>`); `read` must change
        nothing and keep neither.
        """
        live = self._live
        with live.lock:
            return read(live.model, live.data)

    def observe(self, read: Callable[[mujoco.MjModel, mujoco.MjData, int], T]) -> T:
        """
        Call ``read(model, data, generation)`` under the world lock with poses up to date.

        For sensors that look at the world (cameras, ray casts): body, geom, site and camera
        poses describe the current state. `read` must change nothing and be quick: the loop
        waits meanwhile.
        """
        live = self._live
        with live.lock:
            live.kinematics_locked()
            mujoco.mj_camlight(live.model, live.data)
            return read(live.model, live.data, live.index.generation)

    def copy_data(self, model: mujoco.MjModel, into: mujoco.MjData) -> Optional[tuple]:
        """
        Copy the world's data into `into`, made for `model`; return (generation, resets).

        None, copying nothing, when `model` is no longer the world's (a spawn or a delete came
        since :meth:`live_model`). The lock is held for one MuJoCo call (0.1 ms with 400 boxes
        resting on the floor), so a reader that works on the copy (a camera updating its
        scenes, which takes several calls, each giving the GIL away and waiting for it back
        under a storm of requests) never holds the loop off longer than that. The copy's
        poses are those the data had: a step behind its state after a step (see
        :meth:`Live.kinematics_locked <.stepping.live.Live.kinematics_locked>`), so a reader
        works them out again on the copy.
        """
        live = self._live
        with live.lock:
            if live.model is not model:
                return None
            mujoco.mj_copyData(into, model, live.data)
            return live.index.generation, live.resets

    def wait_new_model(self, after: int, timeout: float) -> int:
        """Block until the model generation is no longer `after` (or `timeout` s); return it."""
        return self._live.wait_new_model(after, timeout)

    def add_model_watcher(self, watcher: Callable[[], None]) -> None:
        """
        Call ``watcher()`` after each new model (a spawn, a delete, a reset of the spawned).

        It is called under the world lock, from the thread that made the model: it must not
        block or touch the world (an owner sets an event and does its work on its own thread).
        """
        self._live.model_watchers.append(watcher)

    def remove_model_watcher(self, watcher: Callable[[], None]) -> None:
        """Stop calling `watcher` (compared by equality); nothing if it was not watching."""
        self._live.model_watchers[:] = [w for w in self._live.model_watchers if w != watcher]

    # ---------------------------------------------------------------- introspection

    @property
    def generation(self) -> int:
        with self._live.lock:
            return self._live.index.generation

    @property
    def resets(self) -> int:
        """
        Count the resets of state so far (as :attr:`Clock.resets`), read without the world lock.

        A reading of the world stamped before a reset is of a timeline the world left; a
        thread holding a lock of its own (one never held while taking the world lock) can
        still compare against this.
        """
        return self._live.resets

    @property
    def model_info(self) -> ModelInfo:
        """
        Return the current model's :class:`ModelInfo`, read without the world lock.

        The perception thread asks for it with every scan it publishes: under the lock, each
        ask made the stepping loop step aside for it
        (:meth:`.stepping.lock.WorldLock.wait_for_callers`), 18% of the loop's time with the
        mobile scene's laser at real_time_factor 0 (``make bench-bases``). A read racing a
        spawn is one from just before it.
        """
        return self._live.current[1].info

    def take_sensor_samples(self) -> list:
        """Take the IMU samples and contact reports so far (:func:`.stepping.sampling.drain`)."""
        return sampling.drain(self._live.samples)

    def report_contacts(self, entities: Sequence[str], rate_hz: float = 50.0) -> None:
        """Report these entities' contacts from now on: :func:`.stepping.sampling.request`."""
        request = sampling.request(entities, rate_hz)
        with self._live.lock:
            self._live.contact_request = request

    def sample_joints(self, key: str, joints: Sequence[str], rate_hz: float = 0.0,
                      sensors: bool = False, tick: Optional[Callable] = None) -> None:
        """
        Sample joints `rate_hz` times per simulated second (0: stop): JointSample.

        `tick`, if given, takes every sample due on the stepping thread and returns joint
        commands the world applies before the next step (a robot's controllers' laws,
        :class:`~.control.laws.Laws`; see :func:`.stepping.sampling.joint_requests`).
        Takes no world lock (only a leaf lock of the requests): a caller holding a lock of
        its own (a controller manager's, as robots come and go) waits for no step.
        """
        live = self._live
        with live.requests_lock:
            live.joint_requests = sampling.joint_requests(live.joint_requests, key, joints,
                                                          rate_hz, sensors, tick)

    def scan_lasers(self, rates: Mapping[str, float]) -> None:
        """
        Take the poses of these lasers at their rates (site name -> scans per simulated second).

        Replaces the last request ({}: none). Each due time, the stepping side keeps where the
        laser and every geom are, or the state they follow from
        (:class:`~.stepping.sampling.LaserPose`), taken with
        :meth:`take_laser_poses` and cast by :meth:`~.lidar.LaserScanner.cast` off the
        stepping thread. Takes no world lock, as :meth:`sample_joints`.

        :raises InvalidArgumentError: a rate not in (0, 1000] Hz.
        """
        request = sampling.laser_requests(rates)
        live = self._live
        with live.requests_lock:
            if request != live.laser_requests:
                live.laser_requests = request

    def take_laser_poses(self) -> list:
        """Take the lasers' poses so far, oldest first (see :meth:`scan_lasers`)."""
        return sampling.drain(self._live.laser_poses)

    def live_model(self) -> tuple:
        """
        Return (model, generation) of the world now: the model to cast rays in or draw.

        The model is the world's own, not a copy: read it, never write it. A new model (a
        spawn, a delete) is a new object; this one stays as it is while a caller holds it,
        but for edits of its values in place (a colour, a friction), which the world makes
        under its lock.
        """
        model, index = self._live.current  # one pair, without the world lock (model_info)
        return model, index.generation

    @property
    def timestep(self) -> float:
        with self._live.lock:
            return float(self._live.model.opt.timestep)

    @property
    def time(self) -> float:
        with self._live.lock:
            return float(self._live.data.time)

    def clock(self) -> Clock:
        """Return the time, step count and timestep, read together."""
        with self._live.lock:
            return self._live.clock_locked()

    @property
    def step_count(self) -> int:
        """Step since the last time reset."""
        with self._live.lock:
            return self._live.step_count

    def entities(self) -> list:
        """Every entity (:class:`EntityRecord`), in model order."""
        with self._live.lock:
            return list(self._live.index.entities)

    def entity(self, name: str) -> EntityRecord:
        with self._live.lock:
            return self._live.index.entity(name)

    def systems_not_run(self) -> dict:
        """
        Return the gz-sim systems named that are not run here: ``{'world' or entity: names}``.

        The world file's own plugins and those of its entities (an SDF model's, spawned or
        the world's); a deleted entity's go with it.
        """
        with self._live.lock:
            spawned = dict(self._live.design.spawned)
        out = {'world': self.world_systems_not_run} if self.world_systems_not_run else {}
        out.update((name, rec.systems_not_run) for name, rec in spawned.items()
                   if rec.systems_not_run)
        return out

    def spawned_names(self) -> list:
        """Return the entities spawned since load (the ones that can be deleted)."""
        with self._live.lock:
            return self._live.design.deletable()

    def joint_names(self) -> list:
        """Hinge and slide joints, the ones joint commands and joint_states cover."""
        with self._live.lock:
            return list(self._live.index.joint_names)

    def robot_description(self, name: str, mesh_dir: Optional[str] = None) -> str:
        """
        Return the URDF of an entity with joints or spawned from URDF (:mod:`.models.description`).

        Built outside the world lock from the current model (models are replaced, never changed
        in place, by edits). :param mesh_dir: where mesh geometry is written as STL (None: meshes
        are left out).
        """
        live = self._live
        with live.lock:
            rec = live.index.entity(name)
            spawned = live.design.spawned.get(name)
            model, info = live.model, live.index.info
        if spawned is not None and spawned.urdf:
            return description.renamed_urdf(spawned.urdf, name)
        if not info.body_alias[rec.root_body]:
            raise InvalidArgumentError(ERR_NO_DESCRIPTION.format(name=name))
        return self._descriptions.of(name, model, info, rec, mesh_dir)

    def entity_bounds(self, name: str, local: bool = False) -> tuple:
        """
        Axis-aligned bounds of an entity's geoms: (min (3,), max (3,)).

        In the world frame, or with `local` in the entity's own (root body) frame.
        """
        live = self._live
        with live.lock:
            rec = live.index.entity(name)
            live.kinematics_locked()
            return state.bounds(live.model, live.data, rec, local)

    # ---------------------------------------------------------------- snapshots and state

    def snapshot(self) -> Snapshot:
        """Return an immutable copy for publishers, with the model info of its generation."""
        with self._live.lock:
            return self._live.snapshot_locked()

    def get_state(self) -> PhysicsState:
        """Return the full integration state, like the older systems' ``getState``."""
        live = self._live
        with live.lock:
            values = np.empty(live.index.state_size)
            mujoco.mj_getState(live.model, live.data, values, STATE_SPEC)
            return PhysicsState(generation=live.index.generation, step=live.step_count,
                                values=values)

    def set_state(self, physics_state: PhysicsState) -> None:
        """Overwrite the full state with one from :meth:`get_state` of the same generation."""
        self._writes.set_state(physics_state)

    def get_entity_state(self, name: str, reference: str = '') -> EntityState:
        """
        Pose, twist and acceleration of the entity's root body origin.

        In the world or `reference`'s frame (see :func:`.compiled.state.entity_state`).
        """
        live = self._live
        with live.lock:
            rec = live.index.entity(name)
            live.dynamics_locked()
            frame = live.frame_locked(reference) if reference else None
            return state.entity_state(live.model, live.data, rec, frame)

    def get_joint_states(self) -> dict:
        """Name -> (position, velocity, effort) for every hinge and slide joint."""
        snap = self.snapshot()
        return {n: (float(p), float(v), float(e)) for n, p, v, e in zip(
            snap.info.joint_names, snap.joint_position, snap.joint_velocity,
            snap.joint_effort)}

    def set_entity_state(self, name: str, position: Optional[Sequence[float]] = None,
                         quat_wxyz: Optional[Sequence[float]] = None,
                         linear_velocity: Optional[Sequence[float]] = None,
                         angular_velocity: Optional[Sequence[float]] = None,
                         reference: str = '',
                         acceleration: Optional[Sequence[float]] = None) -> None:
        """Set the pose and/or twist of an entity's root body (see :mod:`.editing.writes`)."""
        self._writes.set_entity_state(name, position, quat_wxyz, linear_velocity,
                                      angular_velocity, reference, acceleration)

    def overwrite(self, poses: Optional[dict] = None, twists: Optional[dict] = None,
                  joint_positions: Optional[dict] = None,
                  joint_velocities: Optional[dict] = None) -> None:
        """Overwrite any parts of the state at once, world frame (see :mod:`.editing.writes`)."""
        self._writes.overwrite(poses, twists, joint_positions, joint_velocities)

    # ---------------------------------------------------------------- control

    def command(self, names: Sequence[str], values: Sequence[float], mode: str) -> None:
        """
        Stage joint commands.

        The next step applies them, and they hold until replaced or until their joint is deleted
        (see :class:`~sim_node.core.control.commands.Control`).

        :raises NotFoundError: an unknown joint; nothing is staged.
        :raises InvalidArgumentError: a non-finite value, a length mismatch or a bad mode.
        """
        with self._live.lock:
            index = self._live.index
        self._live.control.stage(index, names, values, mode)

    def follow_trajectory(self, entity: str, joint_names: Sequence[str],
                          times: Sequence[float], positions: Sequence[Sequence[float]],
                          velocities: Sequence[Sequence[float]] = (),
                          accelerations: Sequence[Sequence[float]] = (),
                          start_time: float = 0.0, path_tolerance: Optional[dict] = None,
                          goal_tolerance: Optional[dict] = None,
                          goal_time_tolerance: float = 0.0, allow_end_velocity: bool = False,
                          open_loop: bool = False) -> 'TrajectoryHandle':
        """
        Drive an entity's joints along a trajectory in simulated time (a new one preempts).

        :param times: (k,) seconds after the start of each point, increasing.
        :param positions: (k, n); `velocities` and `accelerations` empty or (k, n): the
            fields given choose linear, cubic or quintic interpolation.
        :param start_time: simulated time of the start (0: now); a trajectory that would end
            before now is refused.
        :param path_tolerance: joint -> (position, velocity, acceleration) limits on the
            error along the way; goal_tolerance likewise at the end; 0 or absent: not checked.
        :param goal_time_tolerance: how long after the end the goal tolerance may take to be
            met (0: no limit).
        :param allow_end_velocity: accept a last point with a velocity (refused otherwise,
            as joint_trajectory_controller does by default).
        :param open_loop: start from what was last commanded to the joints, not from where
            they are (joint_trajectory_controller's ``open_loop_control``).
        :raises TrajectoryError: with FollowJointTrajectory's error code; a point outside a
            joint's range is refused too.
        """
        run = self._motion.follow(entity, joint_names, times, positions, velocities,
                                  accelerations, start_time, path_tolerance, goal_tolerance,
                                  goal_time_tolerance, allow_end_velocity, open_loop)
        return TrajectoryHandle(self, entity, run)

    def check_trajectory(self, entity: str, joint_names: Sequence[str],
                         times: Sequence[float], positions: Sequence[Sequence[float]],
                         velocities: Sequence[Sequence[float]] = (),
                         accelerations: Sequence[Sequence[float]] = (),
                         start_time: float = 0.0, allow_end_velocity: bool = False) -> None:
        """
        Raise what :meth:`follow_trajectory` would refuse the goal for; start nothing.

        :raises TrajectoryError: with FollowJointTrajectory's error code.
        """
        self._motion.check(entity, joint_names, times, positions, velocities, accelerations,
                           start_time, allow_end_velocity)

    def cancel_trajectory(self, handle: 'TrajectoryHandle') -> None:
        """End a trajectory now; the joints hold where they are (see TrajectoryHandle)."""
        self._motion.cancel(handle.entity, handle.run)

    def bases(self) -> dict:
        """
        Return the entities that have a mobile base: name -> :class:`~.bases.BaseSpec`.

        Found from each entity's model (wheel joints, planar joints) or its URDF's Gazebo drive
        plugin; measured once per model generation.
        """
        return self._motion.bases()

    def drive(self, entity: str, vx: float, vy: float = 0.0, wz: float = 0.0,
              timeout: float = COMMAND_TIMEOUT) -> list:
        """
        Drive an entity's base at `vx`, `vy` (m/s) and `wz` (rad/s), in its own frame.

        From the next step on, until another command, a reset, or `timeout` simulated seconds
        without one (then it stops; 0: never, as Gazebo's DiffDrive system). The base's own
        motion tracks the command (see :mod:`.control.bases`). A differential drive ignores
        `vy`.

        :returns: what the base could not take, in words (empty: all of it): `vy` on a
            differential drive; the command before this one needing more than the model's
            actuators give (:data:`.control.drives.NOTE_BEYOND`).

        :raises NotFoundError: no such entity.
        :raises InvalidArgumentError: it has no base; a value not finite or beyond
            :data:`.control.drives.MAX_SPEED` / :data:`.control.drives.MAX_TURN`.
        """
        return self._motion.drive(entity, vx, vy, wz, timeout)

    def push(self, body: str, force: Sequence[float], torque: Sequence[float] = (0, 0, 0)
             ) -> None:
        """
        Push a body with a force (N, at its centre of mass) and a torque (N m), world axes.

        The push holds from the next step until replaced (zeros release it) or a reset (a spawn
        or delete keeps it): what a viewer's mouse drag applies (MuJoCo's ``xfrc_applied``).

        :raises NotFoundError: no such body; :raises InvalidArgumentError: not 3 finite values.
        """
        self._motion.push(body, force, torque)

    def set_gains(self, kp: float, kd: float) -> None:
        """PD gains for joints commanded without a matching actuator."""
        self._motion.set_gains(kp, kd)

    # ---------------------------------------------------------------- stepping

    def step(self, n: int = 1, ctrl: Optional[np.ndarray] = None,
             then: Optional[Callable[[mujoco.MjModel, mujoco.MjData], None]] = None) -> int:
        """
        Advance `n` steps (applying staged commands first); returns the step count.

        :param ctrl: (nu,) actuator controls to set first, for callers that own the world
            (the Gym environment); the caller checks them (finite, within +-1e10).
        :param then: called as ``then(model, data)`` after the steps, under the same hold of
            the world lock (a vector env copies what its task reads); it must change nothing.
        :raises DivergenceError: the physics diverged; the world is back at the state before
            the bad step and ``error.step`` names it.
        """
        return self.stepping.step(n, ctrl, then)

    def step_kinematic(self, positions: dict, n: int = 1) -> int:
        """
        Advance `n` steps with no physics (see :func:`state.kinematic_step`).

        The named hinge/slide joints take `positions` exactly at every step; returns the step
        count.
        """
        return self.stepping.kinematic(positions, n)

    # ---------------------------------------------------------------- reset

    def reset(self, scope: int = RESET_ALL) -> None:
        """
        Reset by scope bits.

        RESET_TIME (time and step count to 0), RESET_STATE (the `home` keyframe or the initial
        state; held commands are dropped), RESET_SPAWNED (delete everything spawned since load). 0
        and RESET_ALL do all three.
        """
        if scope != RESET_ALL and not 0 <= scope <= _SCOPE_BITS:
            raise FeatureUnsupportedError(ERR_SCOPE.format(scope=scope))
        scope = _SCOPE_BITS if scope in (0, RESET_ALL) else scope
        if scope & RESET_SPAWNED:  # built outside the lock like every removal; the state below
            self._edits.remove_spawned()
        live = self._live
        with live.lock:
            if scope & RESET_STATE:
                live.reset_state_locked(keep_time=not scope & RESET_TIME)
            elif scope & RESET_TIME:
                live.data.time = 0.0
                live.step_count = 0
                live.cached = None

    # ---------------------------------------------------------------- edits (see .edits)

    def spawn(self, name: str, source: sources.SpawnSource,
              position: Sequence[float] = (0.0, 0.0, 0.0),
              quat_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0), reference: str = '',
              allow_renaming: bool = False, namespace: str = '',
              allow_interpenetration: Optional[bool] = None) -> str:
        """
        Add an entity at a pose (world frame, or `reference` entity's frame) while running.

        All or nothing; returns its name (see :meth:`Edits.spawn <.edits.Edits.spawn>`).
        """
        return self._edits.spawn(name, source, position, quat_wxyz, reference, allow_renaming,
                                 namespace, allow_interpenetration)

    def add_body(self, name: str, parent: str, shape: str, size: Sequence[float],
                 position: Sequence[float] = (0.0, 0.0, 0.0),
                 quat_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0), mass: float = 0.0,
                 joint: Optional[str] = None, axis: Sequence[float] = (0.0, 0.0, 1.0),
                 rgba: Sequence[float] = (0.7, 0.7, 0.7, 1.0)) -> str:
        """Add a body under a spawned entity's body (see :meth:`.editing.edits.Edits.add_body`)."""
        return self._edits.add_body(name, parent, shape, size, position, quat_wxyz, mass,
                                    joint, axis, rgba)

    def delete(self, name: str) -> None:
        """
        Remove a spawned entity and everything that came with it; all else keeps its state.

        Its processed meshes stay in MuJoCo's cache a while (``mesh_cache_keep_sec``, at most
        ``mesh_cache_keep_mb``): spawned again meanwhile, it is quick. :meth:`release_meshes`
        gives them back when that is over.
        """
        self._edits.delete(name)

    def release_meshes(self, every: bool = False) -> bool:
        """
        Evict the kept meshes of deleted entities whose time is over (a periodic call).

        Skipped, returning False, while an edit is being made (it does this when it ends).
        :param every: all of them, whatever their time (the world is being dropped: nobody
            would evict them later, and MuJoCo's cache is the process's).
        """
        return self._transaction.release_meshes(math.inf if every else time.monotonic())

    def kept_mesh_bytes(self) -> int:
        """Return the bytes of deleted entities' meshes kept in MuJoCo's cache now."""
        return self._transaction.kept_mesh_bytes()

    def set_gravity(self, gravity: Sequence[float]) -> None:
        self._edits.set_gravity(gravity)

    def set_timestep(self, timestep: float) -> None:
        self._edits.set_timestep(timestep)

    def set_friction(self, name: str, sliding: float, torsional: Optional[float] = None,
                     rolling: Optional[float] = None) -> None:
        """Friction of every geom of an entity (see :meth:`.editing.edits.Edits.set_friction`)."""
        self._edits.set_friction(name, sliding, torsional, rolling)

    def set_restitution(self, name: str, restitution: float) -> None:
        """Bounciness in [0, 0.8] of an entity's geoms (:mod:`.editing.edits`)."""
        self._edits.set_restitution(name, restitution)

    def set_default_contact(self, friction: Optional[Sequence[float]] = None,
                            restitution: Optional[float] = None) -> None:
        """Global friction (3 values) and/or restitution for every geom without its own."""
        self._edits.set_default_contact(friction, restitution)

    def set_mass(self, name: str, mass: float) -> None:
        """Total mass of an entity (kg); 0 welds a free one where it is (:mod:`.editing.edits`)."""
        self._edits.set_mass(name, mass)
