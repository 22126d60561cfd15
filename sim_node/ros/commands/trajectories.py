"""
FollowJointTrajectory for every entity with joints: what MoveIt sends to a trajectory controller.

Each entity with hinge or slide joints gets an action server ``<entity>/follow_joint_trajectory``
and a ``<entity>/controller_state`` topic (control_msgs/JointTrajectoryControllerState), made
and removed with the entity. A goal becomes a core trajectory
(:meth:`~sim_node.core.world.World.follow_trajectory`, in simulated time); the execute callback
waits for it, sends feedback at ``trajectory_feedback_hz`` (wall time) and maps the outcome
to the result: SUCCESSFUL and the controller's error codes, ABORTED for a violation or a
preemption, CANCELED for a cancel (the joints then hold where they are). A goal the controller
would reject is rejected, its reason logged and put on /diagnostics. ``controller_state``'s
``output.effort`` is the torque each joint's actuators gave in the last step.
"""

import threading
from typing import Callable, Optional

from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from msg_adapters import convert
from msg_adapters.perception import interface_base
from rclpy._rclpy_pybind11 import RCLError
from rclpy.action import CancelResponse, GoalResponse
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.exceptions import InvalidHandle
from rclpy.waitable import NumberOfEntities
from trajectory_msgs.msg import JointTrajectoryPoint

from ..settings import replies
from ...core.base.errors import SimError
from ...core.base.records import ModelInfo, Snapshot
from ...core.control import trajectory
from ...session import Loaded, Session

ERR_MULTI_DOF = 'multi-DOF trajectories are not supported: send joint trajectories'
ERR_GONE = 'entity {entity!r} is not in the world (any more)'


class LeavableActionServer(replies.ResendingActionServer):
    """
    An action server that may be destroyed while an executor waits on the node.

    Its replies go through the resender (`sim_node.ros.settings.replies`).

    rclpy's executor keeps a waitable whose context it could not enter in its list and still
    adds it to the wait set and asks it whether it is ready: for a destroyed server that raised
    ``InvalidHandle`` or ``RCLError`` ("action server pointer is invalid") out of ``spin()``,
    and the node died (seen once in four runs of the trajectory tests). Here a destroyed
    server takes no part, and it leaves the node before its handle goes.
    """

    def get_num_entities(self):
        try:
            return super().get_num_entities()
        except (InvalidHandle, RCLError):
            return NumberOfEntities()

    def add_to_wait_set(self, wait_set) -> None:
        try:
            super().add_to_wait_set(wait_set)
        except (InvalidHandle, RCLError):
            pass

    def is_ready(self, wait_set) -> bool:
        try:
            return super().is_ready(wait_set)
        except (InvalidHandle, RCLError):
            return False

    def destroy(self) -> None:
        self._node.remove_waitable(self)  # first: no new wait set takes it
        try:
            super().destroy()
        except ValueError:  # rclpy's destroy ends by removing it from the node: done above
            pass


def seconds(d) -> float:
    return d.sec + d.nanosec * 1e-9


def tolerances(names, given, default: float) -> dict:
    """
    Joint -> (position, velocity, acceleration) limits, as the controller reads them.

    `default` (a position limit for every joint; 0: not checked) unless the goal gives a joint
    its own: a positive value replaces it, -1 means not checked, 0 keeps the default.
    """
    out = {n: (default, 0.0, 0.0) for n in names}
    for tol in given:
        if tol.name not in out:
            continue
        cur = list(out[tol.name])
        for k, v in enumerate((tol.position, tol.velocity, tol.acceleration)):
            if v > 0:
                cur[k] = float(v)
            elif v < 0:
                cur[k] = 0.0
        out[tol.name] = tuple(cur)
    return out


def point(q=(), v=(), a=(), e=()) -> JointTrajectoryPoint:
    return JointTrajectoryPoint(positions=[float(x) for x in q], velocities=[float(x) for x in v],
                                accelerations=[float(x) for x in a], effort=[float(x) for x in e])


class TrajectoryServers:
    """
    The action servers and controller-state publishers of a node's entities.

    :param session: the loaded simulation; :meth:`on_model` is its listener.
    :param params: returns (path tolerance, goal tolerance, goal time tolerance, feedback Hz,
        allow a velocity at the end).
    :param refused: called (topic, what, why, joint names) for a rejected goal.
    """

    def __init__(self, node, callback_group, session: Session, params: Callable,
                 refused: Callable):
        self._node = node
        self._group = callback_group
        self._session = session
        self._params = params
        self._refused = refused
        self._servers: dict = {}  # entity -> (action server, controller_state pub, base)
        self._lock = threading.Lock()

    def on_model(self, loaded: Optional[Loaded], snap: Optional[Snapshot]) -> None:
        """Listen to the session's new models: the servers of the model's entities."""
        self.sync(None if snap is None else snap.info)

    def sync(self, info: Optional[ModelInfo]) -> None:
        """Make the servers of a model generation's entities with joints; drop the others."""
        moving = set() if info is None else set(info.joint_entity)
        bases = {e.name: interface_base(e) for e in info.entities
                 if e.name in moving} if info is not None else {}
        with self._lock:
            for entity in [e for e, v in self._servers.items() if bases.get(e) != v[2]]:
                server, pub, _ = self._servers.pop(entity)
                server.destroy()
                self._node.destroy_publisher(pub)
            new = [e for e in bases if e not in self._servers]
            for entity, base in bases.items():
                if entity not in self._servers:
                    self._servers[entity] = (*self._make(entity, base), base)
        self._hold(info, new)

    def _hold(self, info: Optional[ModelInfo], entities: list) -> None:
        """
        Hold a newly spawned arm's joints where they are, as an activated JTC does.

        A client that plans from its joint states finds it there.

        Arms only (spawned, their root fixed: no free joint, not a mobile base on planar
        joints); a robot whose own controllers drive it (``info.ros2_control``) is held by its
        joint_trajectory_controller instead.
        """
        sim = self._session.loaded
        if sim is None or info is None or not entities:
            return
        records = {e.name: e for e in info.entities}
        try:
            bases = sim.world.bases()  # a base on planar joints: its joints are its motion
        except SimError:
            return
        for entity in entities:
            rec = records.get(entity)
            if rec is None or not rec.spawned or rec.has_free_joint \
                    or entity in info.ros2_control or entity in bases:
                continue
            names = [n for n, e in zip(info.joint_names, info.joint_entity) if e == entity]
            try:
                states = sim.world.get_joint_states()
                sim.world.command(names, [states[n][0] for n in names], 'position')
            except (SimError, KeyError):
                continue  # gone meanwhile

    def close(self) -> None:
        with self._lock:
            for server, pub, _ in self._servers.values():
                server.destroy()
                self._node.destroy_publisher(pub)
            self._servers.clear()

    def _make(self, entity: str, base: str) -> tuple:
        server = LeavableActionServer(
            self._node, FollowJointTrajectory, f'{base}/follow_joint_trajectory',
            execute_callback=lambda goal: self._execute(entity, goal),
            goal_callback=lambda goal: self._check(entity, base, goal),
            cancel_callback=lambda goal: CancelResponse.ACCEPT,
            callback_group=self._group)
        pub = self._node.create_publisher(
            JointTrajectoryControllerState, f'{base}/controller_state', 10,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
        return server, pub

    # ------------------------------------------------------------------ one goal

    def _check(self, entity: str, base: str, goal) -> GoalResponse:
        """
        Accept a goal the controller would run; reject the others, as it does.

        joint_trajectory_controller rejects a goal it cannot run (unknown joints, no points,
        times that do not increase, sizes that differ, a velocity at the end, an end in the
        past) at once, in its goal callback; a rejected goal has no result, so the reason goes
        to the log and to /diagnostics (``<node>: <entity>/follow_joint_trajectory``).
        """
        jt = goal.trajectory
        try:
            self._plan(entity, goal, check=True)
        except (trajectory.TrajectoryError, SimError) as exc:
            code = getattr(exc, 'code', trajectory.INVALID_JOINTS)
            self._refused(f'{base}/follow_joint_trajectory', 'FollowJointTrajectory goal',
                          f'{exc} (error code {code})', list(jt.joint_names))
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _plan(self, entity: str, goal, check: bool = False):
        """Start (or with `check`, only check) a goal; return its core handle."""
        jt = goal.trajectory
        sim = self._session.loaded
        path_tol, goal_tol, goal_time, _, allow_end_velocity = self._params()
        if goal.multi_dof_trajectory.joint_names:
            raise trajectory.TrajectoryError(trajectory.INVALID_JOINTS, ERR_MULTI_DOF)
        if sim is None:
            raise trajectory.TrajectoryError(trajectory.INVALID_JOINTS,
                                             ERR_GONE.format(entity=entity))
        names = list(jt.joint_names)
        points = ([seconds(p.time_from_start) for p in jt.points],
                  [list(p.positions) for p in jt.points], [list(p.velocities) for p in jt.points],
                  [list(p.accelerations) for p in jt.points])
        if check:
            return sim.world.check_trajectory(entity, names, *points,
                                              start_time=seconds(jt.header.stamp),
                                              allow_end_velocity=allow_end_velocity)
        gtt = seconds(goal.goal_time_tolerance)
        return sim.world.follow_trajectory(
            entity, names, *points, start_time=seconds(jt.header.stamp),
            path_tolerance=tolerances(names, goal.path_tolerance, path_tol),
            goal_tolerance=tolerances(names, goal.goal_tolerance, goal_tol),
            goal_time_tolerance=gtt if gtt > 0 else goal_time,
            allow_end_velocity=allow_end_velocity)

    def _execute(self, entity: str, goal_handle):
        goal = goal_handle.request
        names = list(goal.trajectory.joint_names)
        result = FollowJointTrajectory.Result()
        feedback_hz = self._params()[3]
        try:  # checked when accepted; the world may have changed since
            handle = self._plan(entity, goal)
        except trajectory.TrajectoryError as exc:
            goal_handle.abort()
            result.error_code, result.error_string = exc.code, str(exc)
            return result
        except SimError as exc:
            goal_handle.abort()
            result.error_code = trajectory.INVALID_JOINTS
            result.error_string = str(exc)
            return result
        period = 1.0 / max(feedback_hz, 1e-3)
        while not handle.wait(period):
            if goal_handle.is_cancel_requested:
                handle.cancel()
                break
            self._report(entity, names, handle, goal_handle)
        self._report(entity, names, handle, None)
        return finish(goal_handle, handle, result)

    def _report(self, entity: str, names: list, handle, goal_handle) -> None:
        """Feedback (while running) and controller state, from the latest judgement."""
        st = handle.status
        if not st.desired:
            return
        (qd, vd, ad), (q, v) = st.desired, st.actual
        stamp = convert.clock(st.time).clock
        desired, actual = point(qd, vd, ad), point(q, v)
        error = point(qd - q, vd - v)
        if goal_handle is not None and goal_handle.is_active:
            fb = FollowJointTrajectory.Feedback(joint_names=names, desired=desired,
                                                actual=actual, error=error)
            fb.header.stamp = stamp
            goal_handle.publish_feedback(fb)
        with self._lock:
            entry = self._servers.get(entity)
        if entry is not None:
            state = JointTrajectoryControllerState(joint_names=names, reference=desired,
                                                   feedback=actual, error=error,
                                                   output=point(e=st.effort),
                                                   speed_scaling_factor=1.0)
            state.header.stamp = stamp
            entry[1].publish(state)


def finish(goal_handle, handle, result):
    """End a goal as its trajectory ended (canceled, succeeded or aborted); return `result`."""
    st = handle.status
    result.error_code, result.error_string = int(st.code or 0), st.message
    if goal_handle.is_cancel_requested:
        goal_handle.canceled()
    elif st.code == trajectory.SUCCESSFUL and not st.canceled:
        goal_handle.succeed()
    else:
        goal_handle.abort()
    return result


def duration(seconds: float) -> Duration:
    """Return a builtin_interfaces Duration of `seconds` (for clients and tests)."""
    sec = int(seconds)
    return Duration(sec=sec, nanosec=int(round((seconds - sec) * 1e9)))
