"""
The `sim` rclpy node: a thin layer over the world core.

Callbacks convert the request, call the core, convert the answer (``msg_adapters``). The node
makes no ``mj_*`` call and never touches MjData. Its threads besides the world's stepping loop:
the executor's (services, reentrant; the housekeeping timer), ``sim-publisher`` (``/tf`` and
joint states from the newest snapshot, paced to absolute deadlines), ``sim-clock`` (``/clock``
alone, so time flows however long /tf takes to build), ``sim-model`` (per model generation:
``/tf_static``, markers, sensor publishers and robot descriptions, which take up to hundreds of
milliseconds for a mesh-heavy robot and would otherwise hold /tf back), the command drain's
and the perception thread (cameras and scanners). FollowJointTrajectory
goals (:mod:`.trajectories`) wait on executor threads of their own callback group.
Publishers that come and go with entities carry no QoS event handlers, so they are never in an
executor's wait set and may be destroyed from any thread; the action servers that come and go
take no part in a wait set once destroyed (see :mod:`.trajectories`).
"""

import collections
import logging
import os
from pathlib import Path
import signal
import socket
import sys
import threading
import time
from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray
from msg_adapters import convert, diagnostics, markers
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from . import params, resources
from .command_drain import CommandDrain
from .core.config import WorldConfig
from .core.errors import IncorrectStateError, InvalidArgumentError, SimError
from .core.loop import SimLoop
from .core.memory import release_free_memory
from .core.records import EFFORT, POSITION, VELOCITY
from .core.world import World
from .descriptions import default_mesh_dir, RobotDescriptions
from .perception import Perception
from .qos import LATCHED_QOS
from .services import ERR_NO_WORLD, Sim, SimServices
from .trajectories import TrajectoryServers

NODE_NAME = 'sim'


DUPLICATE_WINDOW_SEC = 15.0
ERR_SECOND_SIMULATOR = ('another simulator already runs in namespace {ns!r}: start '
                        'this one in a namespace of its own with a frame prefix (--ros-args -r '
                        '__ns:=/sim2 -p frame_prefix:=sim2/ -p publish_clock:=false, see the '
                        'README), or set allow_second_simulator:=true')


def _next_deadline(deadline: float, period: float, now: float) -> float:
    """Return the next absolute deadline; one period from now if more than a period behind."""
    deadline += period
    return deadline if deadline > now else now + period


class _LogForwarder(logging.Handler):
    """
    Core log records go to a queue the node drains on its own thread.

    The loop thread never calls rclpy.
    """

    def __init__(self):
        super().__init__(logging.INFO)
        self.records = collections.deque(maxlen=200)

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


#: How long a refused joint command stays in /diagnostics (wall seconds).
REFUSAL_SHOWN_SEC = 10.0
#: How often freed heap goes back to the system (glibc's malloc_trim): a reset, a delete or a
#: big request leaves free memory that glibc would otherwise keep. A trim stalls every thread
#: that allocates (up to 66 ms under a storm of edits): while the model keeps changing, only
#: once BUSY_TRIM_BYTES are free; once it has stood still a period, whatever is free.
TRIM_PERIOD_SEC = 2.0
BUSY_TRIM_BYTES = 64 << 20
#: The model has stood still this long: the node is not busy with edits (see TRIM_PERIOD_SEC).
QUIET_SEC = 0.5


class SimNode(SimServices, Node):
    """
    Publishes /clock, /tf, /tf_static, markers and joint_states; serves simulation_interfaces.

    Call :meth:`start` after adding it to an executor.
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self._scenes_dir = resources.installed_scenes_dir()
        params.declare(self, str(self._scenes_dir))
        p = self._param
        self._world_frame = p('world_frame')
        self._frame_prefix = p('frame_prefix')
        self._out_world_frame = self._frame_prefix + self._world_frame  # as published
        self._frames: tuple = ()  # TF frame of each body of the published generation
        # resource_paths adds to the installed scenes and objects (builtin_resources: false
        # leaves only resource_paths).
        own = [str(self._scenes_dir)] if p('builtin_resources') else []
        self._resource_paths = [str(Path(r).resolve()) for r in own + params.string_list(
            self, 'resource_paths') if r]
        self._sim: Optional[Sim] = None
        self._syncing_thread: Optional[int] = None  # set while we mirror `paused` ourselves
        self._sim_lock = threading.RLock()
        self._stopped = False  # STATE_STOPPED until play or pause
        self._loading = 0  # load_world requests being read and compiled (STATE_LOADING_WORLD)
        self._loading_lock = threading.Lock()
        self._published_generation = None
        self._published_seq = -1
        self._tf_time: Optional[float] = None  # the stamp of the last /tf
        self._tf_layout = ((), None)  # (frame names, moving bodies) that /tf went with
        self._tf_added: set = set()  # frames sent since at the same stamp (new entities)
        self._moving = None
        self._forwarder = _LogForwarder()
        logging.getLogger('sim_node').addHandler(self._forwarder)
        logging.getLogger('sim_node').setLevel(logging.INFO)

        self._pub_group = MutuallyExclusiveCallbackGroup()
        self._srv_group = ReentrantCallbackGroup()
        self._clock_pub = (self.create_publisher(Clock, '/clock', 10)
                           if p('publish_clock') else None)
        self._tf_pub = self.create_publisher(TFMessage, '/tf', 100)
        self._tf_static_pub = self.create_publisher(TFMessage, '/tf_static', LATCHED_QOS)
        self._marker_pub = self.create_publisher(MarkerArray, 'markers', LATCHED_QOS)
        self._joint_pub = self.create_publisher(JointState, 'joint_states', 10)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._diagnostics_name = f'{self.get_fully_qualified_name()}: physics'
        self._diagnosed = (None, 0.0)  # (divergence report, wall time) last published
        self.exit_code = 0  # main's exit status; 2 when another simulator had this name
        self._refused_command: Optional[tuple] = None  # (why, names, wall time) the latest
        # Taken in batches on a thread, not by the executor (see command_drain).
        self._commands = CommandDrain(self, 'joint_commands', self._on_joint_command)
        # Publishing runs on a thread of its own, paced to absolute deadlines: rclpy timers
        # woke the executor 150 times a second (each wake rebuilds its wait set while holding
        # the GIL), which cost the physics several percent, and drift below their rate.
        self._tf_period = 1.0 / p('tf_rate_hz')
        self._js_period = 1.0 / p('joint_states_rate_hz')
        self._publishing = threading.Event()
        self._publisher_thread: Optional[threading.Thread] = None
        self._clock_thread: Optional[threading.Thread] = None
        # A new model generation's slow publications, handed from the publisher thread.
        self._model_cv = threading.Condition()
        self._model_due: Optional[tuple] = None
        self._model_thread: Optional[threading.Thread] = None
        self._trimmed = time.monotonic()
        self._trim_generation: Optional[int] = None  # the model generation last seen, and
        self._changed = self._trimmed  # when it changed (see _trim_memory)
        self._trim_owed = False
        self._housekeeping_timer = self.create_timer(0.2, self._housekeeping,
                                                     callback_group=self._pub_group)
        self.perception = Perception(self, params.perception_config(self), self._world_frame,
                                     self._frame_prefix, lambda: self._sim)
        self.trajectories = TrajectoryServers(
            self, ReentrantCallbackGroup(), lambda: self._sim,
            lambda: tuple(p(n) for n in ('trajectory_path_tolerance',
                                         'trajectory_goal_tolerance',
                                         'trajectory_goal_time_tolerance',
                                         'trajectory_feedback_hz')))
        self.descriptions = RobotDescriptions(
            self, lambda: self._sim,
            Path(p('robot_description_mesh_dir') or default_mesh_dir()).expanduser())
        self._make_services()
        self.add_on_set_parameters_callback(self._on_set_parameters)

    # ------------------------------------------------------------------ parameters

    def _param(self, name: str):
        return self.get_parameter(name).value

    def world_config(self) -> WorldConfig:
        return params.world_config(self)

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
        """Load the `scene` parameter's world; start its stepping loop and the publisher."""
        path = resources.resolve_scene(self._param('scene'), self._scenes_dir)
        world = World.from_file(str(path), self.world_config())
        self._install(world, path.stem, path.resolve().as_uri())
        self._publishing.set()
        self._publisher_thread = threading.Thread(target=self._publish_loop,
                                                  name='sim-publisher', daemon=True)
        self._publisher_thread.start()
        if self._clock_pub is not None:
            self._clock_thread = threading.Thread(target=self._clock_loop, name='sim-clock',
                                                  daemon=True)
            self._clock_thread.start()
        self._model_thread = threading.Thread(target=self._model_loop, name='sim-model',
                                              daemon=True)
        self._model_thread.start()
        self._commands.start()
        self.perception.start()
        self._announce_instance()

    def _announce_instance(self, window_sec: float = DUPLICATE_WINDOW_SEC) -> None:
        """
        One simulator per name: a newer node beside an older one says why and exits 2.

        Two would answer one service name at random (seen: 3 of 4 fresh clients talked to one,
        the other to the other) and publish two /clock. Each node publishes its start (wall
        time, pid, host) on the hidden, latched ``_sim_instances`` topic of its namespace; for
        `window_sec` after its start a node listens there, and leaves if it hears of an older
        one (the older never yields, so exactly one stays). DDS discovery takes about 3 s here:
        a check before starting would delay every start by as much.
        """
        self._instance = f'{time.time():.6f} {os.getpid()} {socket.gethostname()}'
        self._instance_pub = self.create_publisher(String, '_sim_instances', LATCHED_QOS)
        self._instance_pub.publish(String(data=self._instance))
        if self._param('allow_second_simulator'):
            return
        deadline = time.monotonic() + window_sec

        def heard(msg: String) -> None:
            if time.monotonic() > deadline or msg.data == self._instance:
                return
            try:
                older = (float(msg.data.split()[0]), msg.data) < \
                    (float(self._instance.split()[0]), self._instance)
            except (ValueError, IndexError):
                return  # not ours
            if older and self.exit_code == 0:
                self.exit_code = 2
                threading.Thread(target=self._leave, name='sim-leave', daemon=True).start()
        self.create_subscription(String, '_sim_instances', heard, LATCHED_QOS,
                                 callback_group=self._pub_group)

    def _leave(self) -> None:
        why = ERR_SECOND_SIMULATOR.format(ns=self.get_namespace())
        print(f'[sim] cannot start: {why}', file=sys.stderr, flush=True)
        self.end_process()

    def end_process(self, delay_sec: float = 0.0) -> None:
        """After `delay_sec`, stop the node's threads and end as on Ctrl-C (main exits)."""
        time.sleep(delay_sec)
        self.shutdown()
        os.kill(os.getpid(), signal.SIGINT)

    def _install(self, world: World, name: str, uri: str, paused: bool = False) -> None:
        loop = SimLoop(world)
        if paused:
            loop.pause()
        with self._sim_lock:
            old, self._sim = self._sim, Sim(world, loop, name, uri)
            self._published_generation = None
        if old is not None:
            old.loop.stop()
        loop.start()
        self.get_logger().info(f'world {name!r} loaded from {uri}: '
                               f'{len(world.entities())} entities, dt={world.timestep} s, '
                               f'{"paused" if loop.paused else "playing"}')

    def shutdown(self) -> None:
        """Stop the stepping loop and the publisher first (before the executor and the node)."""
        with self._sim_lock:
            if self._sim is not None:
                # Short: a spawn still compiling holds the world lock and the loop waits for it;
                # the process exits anyway (see main), so SIGTERM ends it within 2 s.
                self._sim.loop.stop(timeout=0.5)
        self._publishing.clear()
        self.perception.stop()
        self._commands.stop()
        with self._model_cv:
            self._model_cv.notify_all()
        for thread in (self._publisher_thread, self._clock_thread, self._model_thread):
            if thread is not None:
                thread.join(2.0)

    def _require(self) -> Sim:
        sim = self._sim
        if sim is None:
            raise IncorrectStateError(ERR_NO_WORLD)
        return sim

    # ------------------------------------------------------------------ publishing

    def _publish_loop(self) -> None:
        """
        /tf every tf period, joint_states every joint-states period (/clock: _clock_loop).

        From the newest snapshot; re-syncs after a stall instead of bursting.
        """
        self._paced('publishing', [(self._tf_period, self._publish_state),
                                   (self._js_period, self._publish_joint_states)])

    def _clock_loop(self) -> None:
        """
        /clock every tf period from the newest snapshot, on a thread of its own.

        Time flows for every ``use_sim_time`` node however long /tf takes to build: under 8
        clients spawning and deleting, a publisher cycle with /tf of 400 bodies and a new model
        took up to 146 ms, and /clock, sent in the same cycle, stood still as long.
        """
        self._paced('publishing /clock', [(self._tf_period, self._publish_clock)])

    def _paced(self, what: str, jobs: list) -> None:
        """
        Run each job ``(period, fn)`` every period, to absolute deadlines, while publishing.

        Re-syncs after a stall instead of bursting. A failure is logged (:meth:`report_failure`)
        and every job goes on one period later.
        """
        deadlines = [time.perf_counter()] * len(jobs)
        while self._publishing.is_set():
            now = time.perf_counter()
            due = min(deadlines)
            if due > now:
                time.sleep(due - now)
                continue
            try:
                for k, (period, job) in enumerate(jobs):
                    if now >= deadlines[k]:
                        job()
                        deadlines[k] = _next_deadline(deadlines[k], period, now)
            except Exception as exc:  # never die silently: say why, keep publishing
                self.report_failure(what, exc)
                deadlines = [now + period for period, _ in jobs]

    def _publish_clock(self) -> None:
        sim = self._sim
        if sim is not None:
            # /clock goes on while paused (the same time), as Gazebo's does: nodes started with
            # use_sim_time then still start their timers, and RViz shows the time.
            self._clock_pub.publish(convert.clock(sim.loop.latest_snapshot().time))

    def report_failure(self, what: str, exc: Exception) -> None:
        """
        Log that a publishing thread's work failed (at most every 5 s); it goes on.

        Once ROS is shutting down (Ctrl-C, SIGTERM: rclpy's signal handler ends the context
        before the node's threads stop) every publication fails: that is the end, not an
        error, so the threads stop quietly instead (a log line would fail too).
        """
        if not self.context.ok():
            self._publishing.clear()
            return
        self.get_logger().error(f'{what} failed: {exc!r}', throttle_duration_sec=5.0)

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
        if len(self._moving):
            self._publish_tf(info, snap)

    def _publish_tf(self, info, snap) -> None:
        """
        /tf of a snapshot, never a frame twice with one stamp.

        Every tf2 listener (RViz too) drops a transform whose stamp it already has and logs
        TF_REPEATED_DATA. So when time has not moved since the last /tf (paused, stalled, a
        service's snapshot), only frames not yet sent at this stamp go out: those of an entity
        spawned meanwhile. A pose set while paused shows on /tf with the next step. A reset
        (time going back) sends everything again: listeners handle that by the time jump.
        """
        if snap.time != self._tf_time:
            self._tf_pub.publish(convert.moving_tf(self._tf_template, info, snap,
                                                   self._moving))
            self._tf_time = snap.time
            self._tf_layout, self._tf_added = (self._frames, self._moving), set()
            return
        frames, moving = self._tf_layout
        if moving is self._moving:  # the layout it went with: every frame went already
            return
        sent = {frames[b] for b in moving} | self._tf_added  # built only when time stands
        new = np.array([b for b in self._moving if self._frames[b] not in sent], dtype=int)
        if len(new):
            template = convert.moving_tf_template(info, new, self._frames, self._frame_prefix)
            self._tf_pub.publish(convert.moving_tf(template, info, snap, new))
            self._tf_added |= {self._frames[b] for b in new}

    def _publish_model(self, info, sim_time: float) -> None:
        """
        On a new model generation: what /tf needs, here; the rest on the model thread.

        /tf_static, every marker anew and the sensor publishers cost up to hundreds of
        milliseconds for a mesh-heavy robot (163 meshes as triangle lists, 92 touch sensors):
        done here, they held /clock and /tf back for as long.
        """
        self._published_generation = info.generation
        self._moving = convert.moving_body_ids(info)
        self._frames = convert.frame_names(info, self._world_frame, self._frame_prefix)
        self._tf_template = convert.moving_tf_template(info, self._moving, self._frames,
                                                       self._frame_prefix)
        with self._model_cv:
            self._model_due = (info, sim_time, self._frames)
            self._model_cv.notify()

    def _model_loop(self) -> None:
        """Publish /tf_static and markers, and sync sensor publishers, per model generation."""
        while self._publishing.is_set():
            with self._model_cv:
                self._model_cv.wait_for(lambda: self._model_due is not None
                                        or not self._publishing.is_set(), timeout=0.5)
                due, self._model_due = self._model_due, None
            if due is None:
                continue
            info, sim_time, frames = due
            try:
                static = convert.static_transforms(info, sim_time, frames, self._frame_prefix)
                static.transforms += self.perception.static_transforms(info, sim_time, frames)
                self._tf_static_pub.publish(static)  # one latched message: every static frame
                self._marker_pub.publish(markers.markers(info, sim_time, frames))
                self.perception.sync_sensors(info)
                self.trajectories.sync(info)
                self.descriptions.sync(info)
            except Exception as exc:  # never die silently: say why, keep publishing
                self.report_failure('publishing the model', exc)

    def _publish_joint_states(self) -> None:
        sim = self._sim
        if sim is None:
            return
        snap = sim.loop.latest_snapshot()
        if snap.info.joint_names:
            self._joint_pub.publish(convert.joint_state(snap.info, snap))
        if snap.info.sensors:
            self.perception.publish_sensors(snap)

    def _sync_paused_parameter(self) -> None:
        """
        Mirror the loop's paused state in the `paused` parameter, so `ros2 param get` is true.

        The state changes through services, limits and divergence too, not only the parameter.
        """
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
        self._publish_diagnostics()
        self._trim_memory(time.monotonic())

    def _trim_memory(self, now: float) -> None:
        """Give freed heap back every TRIM_PERIOD_SEC; while the model changes, only if a lot."""
        sim = self._sim
        generation = None if sim is None else sim.loop.latest_snapshot().info.generation
        if generation != self._trim_generation:
            self._trim_generation, self._changed = generation, now
        quiet = now - self._changed >= QUIET_SEC
        if now - self._trimmed >= TRIM_PERIOD_SEC or (quiet and self._trim_owed):
            self._trimmed = now
            # Skipped while busy: owed, and made as soon as the model stands still.
            self._trim_owed = not release_free_memory(at_least=0 if quiet else BUSY_TRIM_BYTES)

    def _publish_diagnostics(self, force: bool = False) -> None:
        """
        /diagnostics once a second, and at once when the physics diverges.

        Also at once (at most ten times a second) when a joint command is refused: a status
        ``<node>: joint_commands`` says why (the joint, and for an unknown name the closest
        valid ones) and stays in the messages for REFUSAL_SHOWN_SEC.
        """
        sim = self._sim
        if sim is None:
            return
        status = sim.loop.status()
        now = time.monotonic()
        last_report, last_time = self._diagnosed
        if force and now - last_time < 0.1:
            return
        if not force and status.divergence is last_report and now - last_time < 1.0:
            return
        self._diagnosed = (status.divergence, now)
        msg = diagnostics.diagnostics(status, self._diagnostics_name)
        refused = self._refused_command
        if refused is not None and now - refused[2] < REFUSAL_SHOWN_SEC:
            msg.status.append(diagnostics.refused_command(
                refused[0], refused[1], f'{self.get_fully_qualified_name()}: joint_commands'))
        self._diagnostics_pub.publish(msg)

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

    def _after_change(self, sim: Sim) -> None:
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
            self._refused_command = (str(exc), list(msg.name), time.monotonic())
            self._publish_diagnostics(force=True)
