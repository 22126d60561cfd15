"""
A controller manager on the wire for every robot that declares ros2_control, as Gazebo's.

A spawned URDF whose ``<ros2_control>`` block names Gazebo's (or mock) hardware gets a node
``controller_manager`` (the Gazebo plugin's ``<controller_manager_name>``) in its namespace
(the spawn's, else the plugin's ``<ros><namespace>``) serving controller_manager_msgs as the
Jazzy one does: ``~/list_controllers``, ``~/list_controller_types``, ``~/load_controller``,
``~/configure_controller``, ``~/switch_controller``, ``~/unload_controller``,
``~/cleanup_controller``, ``~/list_hardware_interfaces``, ``~/list_hardware_components``. Its
parameters are the controllers YAML the plugin's ``<parameters>`` names (``update_rate``,
``<controller>.type``) and what controller_manager's ``spawner`` sets (``<controller>.type``,
``<controller>.params_file``), so the spawner and ``ros2 control`` work unchanged. The
bookkeeping is :mod:`sim_node.core.control.manager`; the controllers :mod:`.controllers`.

Joints go by the URDF's names here (the world's are ``<entity>/<joint>``); the loop samples
them at the manager's ``update_rate`` of simulated time and each active controller runs at
its own: its law (:mod:`sim_node.core.control.laws`) on the stepping side at every sample due,
its publishers on the node's side with the samples it is sent. Parameter files are read from
the node's resource folders and installed packages' share folders only.
"""

from dataclasses import replace
import os
import threading
from typing import Callable, Optional

from controller_manager_msgs.msg import (ControllerState, HardwareComponentState,
                                         HardwareInterface)
from controller_manager_msgs.srv import (CleanupController, ConfigureController, ListControllers,
                                         ListControllerTypes, ListHardwareComponents,
                                         ListHardwareInterfaces, LoadController, SwitchController,
                                         UnloadController)
from lifecycle_msgs.msg import State
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter

from . import broadcasters, controllers
from .gripper import GripperAction
from .jtc import TrajectoryController
from .steering import Steering
from .topic_hardware import TopicHardware
from ..settings import replies
from ...core.base.errors import SimError
from ...core.base.records import ModelInfo, Snapshot
from ...core.control import controller_types as types, laws, manager as core
from ...core.models import controller_yaml
from ...core.models.paths import inside_roots
from ...session import Loaded, Session

#: The most joint samples of one robot its controllers take per publishing tick.
MAX_BURST = 20
#: The name the hold of unclaimed joints goes by among a robot's laws (no controller's can).
HOLD = '(hold_joints)'


class _Parameters:
    """The manager node's parameters, read as a dict (`get`)."""

    def __init__(self, node: Node):
        self._node = node

    def get(self, key: str, default=None):
        if not self._node.has_parameter(key):
            return default
        value = self._node.get_parameter(key).value
        return default if value is None else value


class RobotControl:
    """One robot's controller manager node, its controllers and their runtimes."""

    def __init__(self, host, entity: str, control):
        self.host, self.entity, self.control = host, entity, control
        self.namespace = f'/{control.namespace}' if control.namespace else ''
        self.hardware = control.joints()
        self.index = {j: i for i, j in enumerate(self.hardware)}  # joint -> its place in samples
        self.yaml_error = ''
        self.docs = []
        for path in control.parameters:
            try:
                self.docs.append(controller_yaml.load(path, host.readable))
            except ValueError as exc:
                self.yaml_error = str(exc)
        params = controller_yaml.node_parameters(self.docs, control.manager, self.namespace)
        # The plugin's <ros><remapping> rules: gz_ros2_control gives them to the process its
        # manager and controllers run in; here each of their nodes takes them.
        self.remaps = ['--ros-args'] + [a for rule in control.remappings
                                        for a in ('-r', rule)] if control.remappings else None
        self.node = Node(control.manager, namespace=self.namespace or '/',
                         allow_undeclared_parameters=True, cli_args=self.remaps)
        for key, value in params.items():
            try:
                self.node.declare_parameter(key, value)
            except Exception:  # noqa: B902 (a YAML value no parameter type takes: left out)
                pass
        commands = {f'{j.name}/{i}': lim for j in self.hardware.values()
                    for i, lim in j.command.items()}
        states = tuple(f'{j.name}/{i}' for j in self.hardware.values() for i in j.state) + \
            tuple(f'{s}/{i}' for c in control.components for s, ifs in c.sensors.items()
                  for i in ifs)
        self.manager = core.Manager(commands, states, _Parameters(self.node), self._params)
        self.runtimes: dict = {}
        self.latest = None  # the last joint sample
        self.resets = 0  # the world's resets of state: samples from before the last are stale
        self.info = None  # the model info of now (told by ControllerManagers.sync)
        self.sensors = any(c.sensors for c in control.components)
        self.key = f'{entity}:{self.namespace}/{control.manager}'
        group = MutuallyExclusiveCallbackGroup()
        for srv, name, call in (
                (ListControllers, 'list_controllers', self._list),
                (ListControllerTypes, 'list_controller_types', self._types),
                (LoadController, 'load_controller', self._load),
                (ConfigureController, 'configure_controller', self._configure),
                (SwitchController, 'switch_controller', self._switch),
                (UnloadController, 'unload_controller', self._unload),
                (CleanupController, 'cleanup_controller', self._cleanup),
                (ListHardwareInterfaces, 'list_hardware_interfaces', self._interfaces),
                (ListHardwareComponents, 'list_hardware_components', self._components)):
            replies.deliver(self.node.create_service(srv, f'~/{name}', call,
                                                     callback_group=group))
        host.add_node(self.node)
        self.laws = laws.Laws(list(self.hardware),
                              lambda j, interface, v: self.hardware[j].within(interface, v),
                              self.internal)
        self.failure_said = None  # the laws' latest failure logged
        # gz_ros2_control's hold_joints: joints no active controller claims are held still
        self.holder = laws.HoldLaw(laws.held_interfaces(
            {j.name: j.command for j in self.hardware.values()}), self.manager.update_rate) \
            if control.hold_joints and control.simulated else None
        if self.holder is not None:
            self.holder.activate()
            self.laws.put(HOLD, self.holder)
        host.sample(self.key, [self.internal(j) for j in self.hardware],
                    self.manager.update_rate, self.sensors, self.laws.tick)

    def internal(self, joint: str) -> str:
        return f'{self.entity}/{joint}'

    def close(self) -> None:
        self.host.sample(self.key, [], 0.0)
        nodes = [rt.node for rt in self.runtimes.values() if rt.node is not None]
        for rt in self.runtimes.values():
            rt.release()
        self.runtimes.clear()
        self.host.drop_node(self.node, *nodes)

    # ------------------------------------------------------------------ parameters

    def _params(self, name: str) -> dict:
        """Return a controller's parameters: the plugin's YAML, then the spawner's files."""
        if self.yaml_error:
            raise ValueError(self.yaml_error)
        files = self.manager.parameters.get(f'{name}.params_file') or []
        files = [files] if isinstance(files, str) else list(files)
        docs = list(self.docs) + [controller_yaml.load(f, self.host.readable) for f in files]
        return controller_yaml.node_parameters(docs, name, self.namespace)

    # ------------------------------------------------------------------ services

    def _list(self, request, response):
        with self.manager.lock:
            for c in self.manager.controllers.values():
                response.controller.append(ControllerState(
                    name=c.name, state=c.state, type=c.kind, is_async=False,
                    update_rate=int(c.update_rate),
                    claimed_interfaces=list(c.claims) if c.state == core.ACTIVE else [],
                    required_command_interfaces=list(c.claims),
                    required_state_interfaces=[f'{j}/position' for j in c.joints]))
        return response

    def _types(self, request, response):
        response.types = list(types.TYPES)
        response.base_classes = list(types.TYPES.values())
        return response

    def _answer(self, response, ok: bool, message: str, what: str):
        response.ok = ok
        if ok:  # rclpy's logger takes one severity per line of code
            self.node.get_logger().info(f'{what}: {message}')
        else:
            self.node.get_logger().error(f'{what}: {message}')
        return response

    def _load(self, request, response):
        ok, message = self.manager.load(request.name)
        if ok:
            self.runtimes[request.name] = runtime_for(self, self.manager.controllers[request.name])
        return self._answer(response, ok, message, 'load_controller')

    def _configure(self, request, response):
        ok, message = self.manager.configure(request.name)
        if ok:
            try:
                self.runtimes[request.name].configure()
            except (SimError, ValueError, KeyError, TypeError) as exc:
                self.runtimes[request.name].destroy()  # its node and topics go with it
                self.manager.controllers[request.name].state = core.UNCONFIGURED
                ok, message = False, f"controller '{request.name}' cannot be configured: {exc}"
        return self._answer(response, ok, message, 'configure_controller')

    def _switch(self, request, response):
        ok, message, on, off = self.manager.switch(
            list(request.activate_controllers), list(request.deactivate_controllers),
            request.strictness)
        for name in off:
            self.runtimes[name].deactivate()
        for name in on:
            self.runtimes[name].activate(self.latest)
        if self.holder is not None:
            self.holder.claimed({i.rsplit('/', 1)[0] for i in self.manager.claimed()})
        response.message = message
        return self._answer(response, ok, message, 'switch_controller')

    def _unload(self, request, response):
        ok, message = self.manager.unload(request.name)
        if ok:
            self.runtimes.pop(request.name).destroy()
        return self._answer(response, ok, message, 'unload_controller')

    def _cleanup(self, request, response):
        ok, message = self.manager.cleanup(request.name)
        if ok:
            self.runtimes[request.name].destroy()
        return self._answer(response, ok, message, 'cleanup_controller')

    def _interfaces(self, request, response):
        claimed = self.manager.claimed()
        response.command_interfaces = [
            HardwareInterface(name=i, data_type='double', is_available=True,
                              is_claimed=i in claimed)
            for i in sorted(self.manager.command_interfaces)]
        response.state_interfaces = [
            HardwareInterface(name=i, data_type='double', is_available=True, is_claimed=False)
            for i in self.manager.state_interfaces]
        return response

    def _components(self, request, response):
        claimed = self.manager.claimed()
        for c in self.control.components:
            state = State(id=State.PRIMARY_STATE_ACTIVE, label='active')
            response.component.append(HardwareComponentState(
                name=c.name, type=c.kind, is_async=False, rw_rate=self.manager.update_rate,
                class_type=c.plugin, plugin_name=c.plugin, state=state,
                command_interfaces=[HardwareInterface(
                    name=f'{j.name}/{i}', data_type='double', is_available=True,
                    is_claimed=f'{j.name}/{i}' in claimed) for j in c.joints for i in j.command],
                state_interfaces=[HardwareInterface(
                    name=f'{j.name}/{i}', data_type='double', is_available=True,
                    is_claimed=False) for j in c.joints for i in j.state]))
        return response

    def after_reset(self) -> None:
        """
        After a reset of the world's state, each active controller starts again from it.

        As if activated anew: trajectory and gripper controllers hold the joints where the
        reset put them, forward controllers hold them (velocity, effort: at zero), bases
        stop and their odometry starts again from zero.
        """
        self.resets = self.world().clock().resets
        for rt in list(self.runtimes.values()):
            if rt.active:
                rt.after_reset(self.latest)

    # ------------------------------------------------------------------ for the runtimes

    def on_sample(self, sample) -> None:
        """
        Publish for the active controllers due at a joint sample's simulated time.

        Their laws ran on the stepping side already (:attr:`laws`); a law's failure is logged
        here.
        """
        failures = self.laws.failures
        if failures and failures[-1] is not self.failure_said:
            self.failure_said = failures[-1]
            self.node.get_logger().error(f'{failures[-1][0]} update failed: {failures[-1][1]}',
                                         throttle_duration_sec=5.0)
        if sample.resets < self.resets:
            return  # taken before a reset of state the controllers have started again from
        self.latest = sample
        index = self.index
        for rt in list(self.runtimes.values()):
            if rt.active and sample.time >= rt.next_update:
                rt.next_update = sample.time + 1.0 / rt.controller.update_rate - 1e-9
                try:
                    rt.update(sample, index)
                except Exception as exc:  # noqa: B902 (one controller's failure stops no other)
                    self.node.get_logger().error(f'{rt.name} update failed: {exc!r}',
                                                 throttle_duration_sec=5.0)

    def make_node(self, name: str, params: dict) -> Node:
        overrides = []
        for key, value in params.items():
            try:
                overrides.append(Parameter(key, value=value))
            except Exception:  # noqa: B902 (a value no parameter type takes: left out)
                pass
        node = Node(name, namespace=self.namespace or '/', parameter_overrides=overrides,
                    automatically_declare_parameters_from_overrides=True, cli_args=self.remaps)
        self.host.add_node(node)
        return node

    def drop_node(self, node: Node) -> None:
        self.host.drop_node(node)

    def topic(self, name: str) -> str:
        return f'{self.namespace}/{name}'

    def refused(self, topic: str, what: str, why: str, names: list) -> None:
        self.host.refused(topic, what, why, names)

    def world(self):
        return self.host.session.require().world

    def sim_time(self) -> float:
        return self.latest.time if self.latest is not None else 0.0

    def command(self, joints, values, interface: str) -> None:
        """Command URDF-named joints through an interface, within its min and max."""
        out = [self.hardware[j].within(interface, v) for j, v in zip(joints, values)]
        try:
            self.world().command([self.internal(j) for j in joints], out, interface)
        except SimError as exc:
            self.refused(self.topic(self.control.manager), 'command', str(exc), list(joints))

    def write(self, writes) -> None:
        """Command what a law returned (:class:`~sim_node.core.control.laws.Write` each)."""
        for w in writes:
            self.command(w.joints, w.values, w.interface)

    def put_law(self, name: str, law) -> None:
        """Run a controller's law on the stepping side from now on (None: no longer)."""
        self.laws.put(name, law)

    def hold(self, joints, interface: str) -> None:
        """Hold joints: where they are (position), or at zero (velocity, effort)."""
        if interface == 'position':
            states = self.world().get_joint_states()
            values = [states[self.internal(j)][0] for j in joints]
        else:
            values = [0.0] * len(joints)
        self.command(joints, values, interface)


#: Each controller type's runtime: its ROS side (topics, services, actions) over its class.
RUNTIMES = {
    types.JointStateBroadcaster: controllers.JointStateBroadcaster,
    types.ForwardCommand: controllers.ForwardCommand,
    types.JointTrajectory: TrajectoryController,
    types.DiffDrive: controllers.DiffDrive,
    types.Gripper: GripperAction,
    types.Ackermann: Steering, types.Bicycle: Steering, types.Tricycle: Steering,
    types.ImuBroadcaster: broadcasters.ImuBroadcaster,
    types.ForceTorqueBroadcaster: broadcasters.ForceTorqueBroadcaster,
}


def runtime_for(host, controller) -> controllers.Runtime:
    """Return the runtime of a loaded controller's type."""
    runtime = RUNTIMES.get(types.REGISTRY.get(controller.kind))
    if runtime is None:
        raise SimError(f'no runtime for {controller.kind}')
    return runtime(host, controller)


def parameter_roots(roots) -> tuple:
    """Return the folders parameter files are read from: `roots` and installed packages' shares."""
    shares = [os.path.join(p, 'share') for p in
              os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    return tuple(roots) + tuple(shares)


def with_update_rate(source, namespace: str, roots) -> None:
    """
    Give a spawn's gz_ros2_control robot its manager's update rate, as its YAML says it.

    Its position interfaces are held from its spawn by gz_ros2_control's law, whose rate is
    the manager's (:mod:`sim_node.core.control.interfaces`); the YAML is read from the folders
    its manager reads it from (:func:`parameter_roots` of the node's `roots`).
    """
    control = getattr(source.urdf_notes, 'ros2_control', None)
    if control is None or not control.simulated:
        return
    folders = parameter_roots(roots)
    rate = controller_yaml.manager_rate(
        control.parameters, control.manager, namespace.strip('/') or control.namespace,
        lambda p: inside_roots(p, folders))
    source.urdf_notes.ros2_control = replace(control, update_rate=rate)


class ControllerManagers:
    """
    The controller managers of a node's robots, made and removed with them.

    :param add_node, drop_node: put a node into the node's executor, take one out (and
        destroy it once no callback of it can run).
    """

    def __init__(self, node: Node, session: Session, roots: tuple, add_node: Callable,
                 drop_node: Callable, refused: Callable):
        self.node, self.session, self.refused = node, session, refused
        self.add_node, self.drop_node = add_node, drop_node
        self._roots = parameter_roots(roots)
        self.robots: dict = {}  # entity -> RobotControl
        self.topic_robots: dict = {}  # entity -> TopicHardware
        self._lock = threading.Lock()  # the robots: held briefly, never while closing one
        self._sync_lock = threading.Lock()  # syncs take turns (see sync)

    def readable(self, path) -> bool:
        return inside_roots(path, self._roots)

    def sample(self, key: str, joints: list, rate: float, sensors: bool = False,
               tick=None) -> None:
        loaded = self.session.loaded
        if loaded is not None:
            loaded.world.sample_joints(key, joints, rate, sensors, tick)

    def on_model(self, loaded: Optional[Loaded], snap: Optional[Snapshot]) -> None:
        self.sync(None if snap is None else snap.info)

    def sync(self, info: Optional[ModelInfo]) -> None:
        """
        Make and remove the robots' managers as the model `info` declares them.

        The managers of robots that went are taken out under the lock and closed with it let
        go (closing one takes its nodes out of the executor and waits a moment before it
        destroys them, :meth:`SimNode._drop_node`: nobody waits on the lock meanwhile), and
        before the new ones are made: a manager of the same name must never outlive its
        successor (a client that found the old one's service waited for an answer for ever).
        Syncs take turns on their own lock, so one never makes a manager while another still
        closes its predecessor.
        """
        declared = {} if info is None else info.ros2_control
        wanted = {e: c for e, c in declared.items() if c.simulated}
        topics = {e: c for e, c in declared.items() if c.topic_based and not c.simulated}
        with self._sync_lock:
            with self._lock:
                gone = [self.robots.pop(e) for e, r in list(self.robots.items())
                        if wanted.get(e) != r.control]
                gone += [self.topic_robots.pop(e) for e, r in list(self.topic_robots.items())
                         if topics.get(e) != r.control]
            for robot in gone:
                robot.close()
            self._make(info, wanted, topics)

    def _make(self, info: Optional[ModelInfo], wanted: dict, topics: dict) -> None:
        """Make the managers of robots that came (the sync lock held)."""
        with self._lock:
            for entity, control in wanted.items():
                if entity not in self.robots:
                    self.robots[entity] = RobotControl(self, entity, control)
                self.robots[entity].info = info
            for entity, control in topics.items():
                if entity not in self.topic_robots:
                    self.topic_robots[entity] = TopicHardware(self, self.node, entity, control)

    def sync_now(self) -> None:
        """
        Bring the managers up to the world as it is now (after an edit, before its answer).

        A robot deleted or spawned again must not be answered for by the manager of before:
        the session's listeners see a new model only some time after the edit's answer.
        """
        loaded = self.session.loaded
        info = loaded.world.model_info if loaded is not None else None
        if self.robots or self.topic_robots or (info is not None and info.ros2_control):
            self.sync(info)

    def on_samples(self, samples: list) -> None:
        """
        Run each robot's controllers on the joint samples the loop took since the last time.

        At most :data:`MAX_BURST` of one robot's newest: faster than real time, the loop takes
        more than controllers can publish, and the oldest are left (update rates are kept in
        simulated time up to MAX_BURST times the publisher's rate per wall second).
        """
        if not samples:
            return
        with self._lock:
            robots = {r.key: r for r in list(self.robots.values())
                      + list(self.topic_robots.values())}
        by_key: dict = {}
        for sample in samples:
            by_key.setdefault(sample.key, []).append(sample)
        for key, taken in by_key.items():
            robot = robots.get(key)
            if robot is not None:
                for sample in taken[-MAX_BURST:]:
                    robot.on_sample(sample)

    def after_reset(self) -> None:
        """After a reset of state, before its answer: each robot's controllers start again."""
        with self._lock:
            robots = list(self.robots.values())
        for robot in robots:
            robot.after_reset()

    def close(self) -> None:
        self.sync(None)
