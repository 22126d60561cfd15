"""
The `sim` rclpy node: a ROS front-end over a :class:`~sim_node.session.Session`.

The session owns the loaded world, its stepping loop and the lifecycle; the node declares the
parameters, makes the publishers, services and actions, and attaches to the session as its
listeners (/tf_static and markers, sensor publishers, trajectory servers, robot descriptions,
each called with every new model on the session's ``sim-model`` thread). It makes no ``mj_*``
call and never touches MjData.

Its threads besides the session's (``sim-loop``, ``sim-model``): the executor's (services,
reentrant; the housekeeping timer), ``sim-publisher`` and ``sim-clock``
(:mod:`.publishing`), the command drain's (:mod:`.command_drain`) and the perception thread
(cameras and scanners, :mod:`.perception`). FollowJointTrajectory goals (:mod:`.trajectories`)
wait on executor threads of their own callback group. Publishers that come and go with entities
carry no QoS event handlers, so they are never in an executor's wait set and may be destroyed
from any thread. ``docs/threading.md`` has the whole picture.
"""

from dataclasses import replace
import os
from pathlib import Path
import signal
import sys
import threading
import time
from typing import Optional

from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from sensor_msgs.msg import JointState

from . import instances
from .status import Status
from ..commands.bases import BaseControllers
from ..commands.command_drain import CommandDrain
from ..commands.trajectories import TrajectoryServers
from ..control.controller_manager import ControllerManagers
from ..control.gz_systems import GzSystems
from ..services.services import Services
from ..settings import params, replies
from ..topics.descriptions import default_mesh_dir, RobotDescriptions
from ..topics.perception import Perception
from ..topics.publishing import ModelTopics, StatePublisher
from ..topics.recording import Recording
from ...core.base.config import WorldConfig
from ...core.base.errors import InvalidArgumentError, SimError
from ...core.base.records import EFFORT, POSITION, VELOCITY
from ...core.models import resources
from ...record.bag import Limits
from ...session import Session
from ...view import web
from ...view.window import check_display, Window

NODE_NAME = 'sim'
#: How often the housekeeping timer runs: the `paused` parameter, log lines, /diagnostics.
HOUSEKEEPING_SEC = 0.2


#: How long a node taken out of the executor is left before it is destroyed (s).
DROP_SEC = 0.3


class SimNode(Node):
    """
    Publishes /clock, /tf, /tf_static, markers and joint_states; serves simulation_interfaces.

    Call :meth:`start` after adding it to an executor, :meth:`shutdown` before destroying it.
    """

    def __init__(self, **kwargs):
        self._recording: Optional[Recording] = None  # before Node makes its publishers
        super().__init__(NODE_NAME, **kwargs)
        scenes_dir = resources.installed_scenes_dir()
        params.declare(self, str(scenes_dir))
        p = self.param
        if p('record'):
            self._recording = Recording(
                p('record'), params.string_list(self, 'record_topics'), p('record_cameras'),
                Limits(int(p('record_split_mb') * 2 ** 20), p('record_split_s'),
                       int(p('record_max_mb') * 2 ** 20)), self._sim_time,
                lambda text: self.get_logger().error(text))
        self.frames = params.frames(self)
        self._factor_given = p('real_time_factor') != 1.0  # else an SDF world's own paces it
        # resource_paths adds to the installed scenes and objects (builtin_resources: false
        # leaves only resource_paths).
        self.readable = resources.Readable.of(params.string_list(self, 'resource_paths'),
                                              scenes_dir, p('builtin_resources'))
        if p('viewer'):
            check_display()  # no display: one line and exit status 2, before anything starts
        self.window: Optional[Window] = None
        self.web_view: Optional[web.WebView] = None
        self.session = Session()
        self.exit_code = 0  # main's exit status; 2 when another simulator had this name
        # One shutdown: QUITTING's, then main's. The first caller claims it (a leaf lock,
        # held only to claim); a later one waits until it is done.
        self._shutdown_claim = threading.Lock()
        self._shutdown_claimed = False
        self._shut_down = threading.Event()
        self._events = MutuallyExclusiveCallbackGroup()
        self.status = Status(self, self.session)
        self.perception = Perception(
            self, params.perception_config(self), self.frames.world, self.frames.prefix,
            lambda: tuple(params.string_list(self, 'contact_entities')))
        self.publisher = StatePublisher(
            self, self.frames, 1.0 / p('tf_rate_hz'),
            1.0 / p('joint_states_rate_hz'), p('publish_clock'), self.perception.publish_sensors,
            self.report_failure)
        self.model_topics = ModelTopics(self, self.frames, self.perception.static_transforms)
        self.trajectories = TrajectoryServers(
            self, ReentrantCallbackGroup(), self.session,
            lambda: tuple(p(n) for n in ('trajectory_path_tolerance',
                                         'trajectory_goal_tolerance',
                                         'trajectory_goal_time_tolerance',
                                         'trajectory_feedback_hz',
                                         'trajectory_allow_nonzero_velocity_at_end')),
            self.status.refused)
        self.bases = BaseControllers(self, ReentrantCallbackGroup(), self.session, self.frames,
                                     self.param, self.publisher.set_tf_elsewhere,
                                     self.status.refused)
        self.controllers = ControllerManagers(self, self.session, self.readable.roots,
                                              self._add_node, self._drop_node,
                                              self.status.refused)
        self.gz_systems = GzSystems(self, self.session)
        self.perception.joint_samples = lambda samples: (self.controllers.on_samples(samples),
                                                         self.gz_systems.on_samples(samples))
        self.descriptions = RobotDescriptions(
            self, self.session,
            Path(p('robot_description_mesh_dir') or default_mesh_dir()).expanduser())
        # Taken in batches on a thread, not by the executor (see command_drain).
        self._commands = CommandDrain(self, 'joint_commands', self._on_joint_command)
        self.sim_services = Services(self, self.session, self.frames, self.readable, p,
                                     self.world_config, self.status.sync_paused_parameter,
                                     self.end_process)
        self.sim_services.after_edit = self._after_edit
        self.sim_services.after_reset = self._after_reset
        self.create_timer(HOUSEKEEPING_SEC, self.status.housekeeping,
                          callback_group=self._events)
        self.add_on_set_parameters_callback(self._on_set_parameters)

    def _after_reset(self) -> None:
        """After a reset, before its reply: controllers start again, stale readings are out."""
        self.controllers.after_reset()
        self.perception.settle()

    def create_publisher(self, msg_type, topic, qos_profile, **kwargs):
        """Make a publisher; with ``record``, one that also writes into the bag."""
        pub = super().create_publisher(msg_type, topic, qos_profile, **kwargs)
        recording = getattr(self, '_recording', None)
        wrapped = recording.wrap(pub, msg_type, qos_profile) if recording else None
        return wrapped or pub

    def destroy_publisher(self, publisher) -> bool:
        return super().destroy_publisher(getattr(publisher, 'publisher', publisher))

    def _sim_time(self) -> float:
        loaded = self.session.loaded if hasattr(self, 'session') else None
        return loaded.loop.latest_snapshot().time if loaded is not None else 0.0

    def param(self, name: str):
        """Return a parameter's value."""
        return self.get_parameter(name).value

    def world_config(self, file_factor: Optional[float] = None) -> WorldConfig:
        """
        Return the configuration a world is made with, from the node's parameters.

        `file_factor`: the real-time factor the world's file asks (an SDF world's
        ``<real_time_factor>``); it paces the world unless the node was started with a factor
        other than 1 or was given one since.
        """
        config = params.world_config(self)
        if file_factor is not None and not self._factor_given:
            config = replace(config, real_time_factor=float(file_factor))
        return config

    def _on_set_parameters(self, changed) -> SetParametersResult:
        if self.status.syncing_thread == threading.get_ident():
            return SetParametersResult(successful=True)  # our own mirror of the loop state
        loaded = self.session.loaded
        try:
            for prm in changed if loaded is not None else ():
                if prm.name == 'real_time_factor':
                    self._factor_given = True
                    loaded.loop.set_real_time_factor(float(prm.value))
                elif prm.name == 'paused':
                    self.session.pause() if prm.value else self.session.play()
                elif prm.name == 'timestep' and prm.value > 0:
                    loaded.world.set_timestep(float(prm.value))
                elif prm.name in ('max_steps', 'max_sim_time'):
                    limits = {'max_steps': self.param('max_steps'),
                              'max_sim_time': self.param('max_sim_time'), prm.name: prm.value}
                    loaded.loop.set_limits(int(limits['max_steps']),
                                           float(limits['max_sim_time']))
                elif prm.name in ('contact_entities', 'contact_rate_hz'):
                    wanted = {'contact_entities': params.string_list(self, 'contact_entities'),
                              'contact_rate_hz': self.param('contact_rate_hz'),
                              prm.name: prm.value}
                    loaded.world.report_contacts(list(wanted['contact_entities'] or ()),
                                                 float(wanted['contact_rate_hz']))
                elif prm.name in ('kp', 'kd'):
                    gains = {'kp': self.param('kp'), 'kd': self.param('kd'),
                             prm.name: prm.value}
                    loaded.world.set_gains(float(gains['kp']), float(gains['kd']))
        except SimError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        """Load the `scene` parameter's world; start its loop, the publishers and listeners."""
        path = resources.resolve_scene(self.param('scene'), self.readable.scenes_dir)
        for listener in (self.publisher.on_model, self.model_topics, self.perception.on_model,
                         self.trajectories.on_model, self.descriptions.on_model,
                         self.bases.on_model, self.controllers.on_model,
                         self.gz_systems.on_model):
            self.session.add_listener(listener)
        self.session.load_file(str(path), self.world_config(), places=self.readable.places,
                               paced_by_file=not self._factor_given)
        if self.param('viewer'):
            self.window = Window(self.session, on_closed=lambda: self.get_logger().info(
                'the viewer window was closed; the simulation goes on'),
                show_ui=self.param('viewer_ui'), camera=self.param('view_camera'))
        if self.param('web_view'):
            self.web_view = web.serve(self.session, self.param('web_view'),
                                      self.param('web_view_host'), self.param('view_camera'))
        self.publisher.start()
        self._commands.start()
        self.perception.start()
        instances.announce(self, self._events, self._leave,
                           listen=not self.param('allow_second_simulator'))

    def _leave(self, why: str) -> None:
        if self.exit_code == 0:
            self.exit_code = 2
            print(f'[sim] cannot start: {why}', file=sys.stderr, flush=True)
            self.end_process()

    def end_process(self, delay_sec: float = 0.0) -> None:
        """After `delay_sec`, stop the node's threads and end as on Ctrl-C (main exits)."""
        time.sleep(delay_sec)
        self.shutdown()
        os.kill(os.getpid(), signal.SIGINT)

    def _after_edit(self) -> None:
        """Before an edit's answer: controller managers and held arms as the world is now."""
        self.controllers.sync_now()
        loaded = self.session.loaded
        self.trajectories.sync(loaded.world.model_info if loaded is not None else None)

    def _add_node(self, node) -> None:
        """Spin another node of this process (a robot's controller manager, a controller)."""
        self.executor.add_node(node)

    def _drop_node(self, *nodes) -> None:
        """
        Stop spinning nodes, then destroy them, before anything of the same name comes.

        Left for later, a robot's manager outlived the next robot's for a moment: a client that
        found the old one's service sent its request there, and no answer ever came. Taken
        out of the executor first, its entities are in no later wait set (DROP_SEC lets a
        wait and a callback of it that had begun end).
        """
        executor = self.executor
        if executor is not None:
            for node in nodes:
                executor.remove_node(node)
            time.sleep(DROP_SEC)
        for node in nodes:
            node.destroy_node()

    def shutdown(self) -> None:
        """
        Stop the loop, the session's thread and the publishers (before the executor).

        Once: QUITTING (and a second simulator's exit) stop the node from a thread of their
        own, then main calls it again; that call waits for the first and does nothing more.
        """
        with self._shutdown_claim:
            first, self._shutdown_claimed = not self._shutdown_claimed, True
        if not first:
            self._shut_down.wait()
            return
        try:
            self._shutdown_once()
        finally:
            self._shut_down.set()

    def _shutdown_once(self) -> None:
        for view in (self.window, self.web_view):
            if view is not None:
                view.close()
        self.controllers.close()
        self.gz_systems.close()
        self.session.close()
        self.publisher.stop()
        self.perception.stop()
        self._commands.stop()
        self.status.close()
        replies.resender().clear()  # replies still kept go with their services
        if self._recording is not None:  # after the publishers: what they sent is written
            self._recording.close()

    def report_failure(self, what: str, exc: Exception) -> None:
        """
        Log that a publishing thread's work failed (at most every 5 s); it goes on.

        Once ROS is shutting down (Ctrl-C, SIGTERM: rclpy's signal handler ends the context
        before the node's threads stop) every publication fails: that is the end, not an
        error, so the threads stop quietly instead (a log line would fail too).
        """
        if not self.context.ok():
            self.publisher.running.clear()
            return
        self.get_logger().error(f'{what} failed: {exc!r}', throttle_duration_sec=5.0)

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
            self.session.require().world.command(list(msg.name), list(vals), mode)
        except SimError as exc:
            self.status.refused_command(str(exc), list(msg.name))
