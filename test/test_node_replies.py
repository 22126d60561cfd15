"""
Every reply and report arrives (issue 52, item 4).

rmw_fastrtps sends a reply only to a client whose reply reader it has matched; failing that
within 100 ms, rclpy warns "failed to send response (timeout)" and drops it, and the client
waits in vain (`sim_node.ros.settings.replies`). The node keeps such a reply and sends it
again until the client can hear it, the client is gone, or the bound passes; what it gave up
is on /diagnostics and in its log.

The first tests make a client the middleware never matches: a reply reader asking for
transient-local durability, which the services' volatile reply writers cannot serve, while
its volatile-compatible request still reaches them. The last is the stress of the issue:
fresh clients asking at once, spawns and deletes, a robot's controller manager coming and
going, arms' trajectory servers coming and going with a goal each (its response and its
result), /diagnostics listened to, over 1,000 calls; none may be lost. Its discovery loses
announcements (`lossy_discovery`), which is what lost replies: without it no stress here made
the middleware fail a single reply (thousands of calls, with both cores kept busy). With it the
node's resender sends some replies again each run, 0.1 to 1.8 s after they failed, and it
found two more losses of the node's own: actions' replies went unsent again (now they are,
`ResendingActionServer`), and a spawn's compile took the services' failure warnings on another
thread (`sim_node.core.base.thread_warnings`).
"""

import os
import threading
import time

from conftest import NodeProcess, TWO_JOINT_ARM, wait_for
import controllers_corpus as corpus
import lossy_discovery
import pytest

pytestmark = pytest.mark.slow

#: How long a call may go unanswered before it counts as lost (s): the node answers these in
#: milliseconds, and re-sent replies go out within a second of the client's match.
LOST_AFTER_SEC = 10.0
#: Calls of the stress that may be asked again. Under lossy discovery a fresh client's first
#: request is now and then lost before it reaches the node: the node matched the client's
#: request writer only after it wrote the request, and Fast DDS's volatile reader takes what
#: its writer wrote before they were matched for history it must not deliver (the gap of
#: Fast-DDS issue 2641; seen here as no reply ever tried, once in about four runs, most often a
#: fresh robot's first list_controllers). Only the client can mend that, by asking again
#: (SimClient does, for reads). The node's own losses are many more: a node without its
#: resender had 6 calls of 1,288 asked again (and lost 23 and 36 in two runs of 150 s), and one
#: whose spawn's compile took the services' warnings (thread_warnings) lost one or two a run.
ASKED_AGAIN_AT_MOST = 2


class Diagnostics:
    """Every /diagnostics physics status heard: (wall time, values)."""

    def __init__(self, node):
        from diagnostic_msgs.msg import DiagnosticArray
        self.heard: list = []
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on, 50)

    def _on(self, msg) -> None:
        for st in msg.status:
            if st.name.endswith(': physics'):
                self.heard.append((time.monotonic(), {kv.key: kv.value for kv in st.values}))

    def latest(self) -> dict:
        return self.heard[-1][1] if self.heard else {}


class Caller:
    """A node of its own, spun by whoever calls: raw rclpy clients, one retry (`ask`)."""

    def __init__(self, name: str):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self.node = rclpy.create_node(name)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.calls = 0
        self.lost: list = []
        self.asked_again: list = []

    def client(self, srv_type, name: str, qos=None):
        from sim_node.ros.settings.qos import SERVICE_QOS
        client = self.node.create_client(srv_type, name, qos_profile=qos or SERVICE_QOS)
        deadline = time.monotonic() + 20
        while not client.wait_for_service(timeout_sec=0.1):
            assert time.monotonic() < deadline, f'{name} never appeared'
        return client

    def spin_until(self, done, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def call(self, client, request):
        """Ask at once; see `ask`."""
        return self.ask(lambda: client.call_async(request), client.srv_name,
                        client.remove_pending_request)

    def ask(self, send, what: str, forget=lambda future: None):
        """
        Send (`send()` returns a future) and count one call; return its result, or None if lost.

        A call not answered after LOST_AFTER_SEC is asked once more, and lost only if that is
        not answered either: a first request of a fresh client can be lost before it reaches
        the node (ASKED_AGAIN_AT_MOST says why), which the node cannot see nor answer. What was
        asked again is kept in `asked_again`.
        """
        self.calls += 1
        for attempt in range(2):
            future = send()
            self.spin_until(future.done, LOST_AFTER_SEC)
            if future.done():
                return future.result()
            forget(future)
            (self.asked_again if attempt == 0 else self.lost).append(what)
        return None

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def test_a_reply_no_client_can_hear_is_sent_again_then_given_up_and_said(rclpy_context):
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from simulation_interfaces.srv import GetSimulationState
    from sim_node.ros.settings import replies
    node = NodeProcess()
    deaf = Caller('deaf_client')
    try:
        diagnostics = Diagnostics(deaf.node)
        deaf.spin_until(lambda: diagnostics.heard, 20)
        assert diagnostics.latest().get('replies_given_up') == '0'
        # wait_for_service would wait for ever: the client sees the reader it can't match
        client = deaf.node.create_client(
            GetSimulationState, 'get_simulation_state',
            qos_profile=QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        deaf.spin_until(lambda: False, 2.0)  # discovered both ways
        future = client.call_async(GetSimulationState.Request())
        hearing = Caller('hearing_client')  # meanwhile others are answered at once
        try:
            fine = hearing.client(GetSimulationState, 'get_simulation_state')
            hearing.spin_until(lambda: False, 0.5)
            for _ in range(20):
                t0 = time.monotonic()
                assert hearing.call(fine, GetSimulationState.Request()) is not None
                assert time.monotonic() - t0 < 1.0
        finally:
            hearing.close()
        deaf.spin_until(lambda: diagnostics.latest().get('replies_waiting') == '1', 5)
        assert diagnostics.latest().get('replies_waiting') == '1'  # kept, tried again
        deaf.spin_until(lambda: diagnostics.latest().get('replies_given_up') == '1',
                        replies.GIVE_UP_SEC + 5)
        values = diagnostics.latest()
        assert (values['replies_given_up'], values['replies_waiting'],
                values['replies_sent_again']) == ('1', '0', '0')
        assert not future.done()
        wait_for(lambda: 'a reply of /get_simulation_state could not be delivered' in
                 node.output(), timeout=5)
        assert 'not matched within' in node.output()
    finally:
        deaf.close()
        code, _ = node.interrupt()
        assert code == 0, node.output()


def test_a_kept_reply_whose_client_is_gone_is_let_go_before_the_bound(rclpy_context):
    """The middleware answers a send to a client that went away as done: nothing is kept."""
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from simulation_interfaces.srv import GetSimulationState
    from sim_node.ros.settings import replies
    node = NodeProcess()
    listener = Caller('listener')
    deaf = Caller('deaf_client')
    try:
        diagnostics = Diagnostics(listener.node)
        client = deaf.node.create_client(
            GetSimulationState, 'get_simulation_state',
            qos_profile=QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        listener.spin_until(lambda: diagnostics.heard, 20)
        listener.spin_until(lambda: False, 2.0)
        client.call_async(GetSimulationState.Request())
        listener.spin_until(lambda: diagnostics.latest().get('replies_waiting') == '1', 5)
        assert diagnostics.latest().get('replies_waiting') == '1'
        t0 = time.monotonic()
        deaf.close()  # the client goes: its request writer is unmatched
        listener.spin_until(lambda: diagnostics.latest().get('replies_waiting') == '0',
                            replies.GIVE_UP_SEC + 5)
        assert time.monotonic() - t0 < replies.GIVE_UP_SEC / 2
        values = diagnostics.latest()
        assert (values['replies_given_up'], values['replies_sent_again']) == ('0', '1')
    finally:
        listener.close()
        code, _ = node.interrupt()
        assert code == 0, node.output()


def test_a_reply_nobody_hears_is_tried_again_a_bounded_few_times(rclpy_context):
    """
    Each try that fails holds the GIL for the middleware's 100 ms: the waits between them grow.

    Tried every 50 ms, a reply no client could hear held a ticking thread of the process back
    65% of the time until it was given up. A service and a deaf client in this process, a
    resender of its own that gives up after 3 s: 0.1, 0.3, 0.7, 1.5 and 3 s.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_srvs.srv import Trigger
    from sim_node.ros.settings import replies
    node = rclpy.create_node('replies_server')
    resender = replies.Resender(give_up_sec=3.0)
    resender.watch(node.create_service(Trigger, 'replies_probe', lambda q, r: r))
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    deaf = Caller('replies_deaf')
    try:
        client = deaf.node.create_client(
            Trigger, 'replies_probe',
            qos_profile=QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        deadline = time.monotonic() + 2.0  # discovered both ways
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            deaf.executor.spin_once(timeout_sec=0.0)
        client.call_async(Trigger.Request())
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not resender.given_up:
            executor.spin_once(timeout_sec=0.05)
        assert resender.given_up == 1 and resender.sent_again == 0
        assert resender.tries <= 5, resender.tries
    finally:
        deaf.close()
        executor.shutdown()
        node.destroy_node()


def test_an_action_servers_goal_response_no_client_can_hear_is_kept_and_sent_again(
        rclpy_context):
    """
    A goal's response goes through the resender, as a service's reply does.

    A trajectory server and two action clients in this process: one whose goal service's reply
    reader the server's volatile writer can never match (transient-local), one that hears. The
    deaf client's goal response is kept while the other's goal is answered; when the deaf client
    goes, the middleware takes the kept response as done (sent again, nothing given up).
    """
    import rclpy
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sim_node.ros.commands.trajectories import LeavableActionServer
    from sim_node.ros.settings import replies

    def execute(goal_handle):
        goal_handle.succeed()
        return FollowJointTrajectory.Result()
    node = rclpy.create_node('replies_action_server')
    server = LeavableActionServer(node, FollowJointTrajectory, 'replies_probe', execute)
    caller = Caller('replies_action_clients')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    resender = replies.resender()
    before = (resender.sent_again, resender.given_up)

    def spin(done, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while not done() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
            caller.executor.spin_once(timeout_sec=0.02)
    try:
        deaf = ActionClient(caller.node, FollowJointTrajectory, 'replies_probe',
                            goal_service_qos_profile=QoSProfile(
                                depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        hearing = ActionClient(caller.node, FollowJointTrajectory, 'replies_probe')
        spin(lambda: False, 2.0)  # discovered both ways
        unheard = deaf.send_goal_async(FollowJointTrajectory.Goal())
        spin(lambda: resender.waiting == 1, 5)
        assert resender.waiting == 1  # the deaf client's goal response, kept
        heard = hearing.send_goal_async(FollowJointTrajectory.Goal())
        spin(heard.done, 5)
        assert heard.done() and heard.result().accepted
        result = heard.result().get_result_async()
        spin(result.done, 5)
        assert result.done()
        assert not unheard.done()
        deaf.destroy()  # the deaf client goes: the kept response is let go
        spin(lambda: resender.waiting == 0, replies.GIVE_UP_SEC / 2)
        assert resender.waiting == 0
        assert (resender.sent_again - before[0], resender.given_up - before[1]) == (1, 0)
    finally:
        hearing.destroy()
        server.destroy()
        caller.close()
        executor.shutdown()
        node.destroy_node()


def _readers(stop, callers: list, errors: list, index: int) -> None:
    """Fresh clients asking at once, with no settling: the race the middleware loses."""
    from simulation_interfaces.srv import GetEntities, GetEntityState, GetSimulationState
    caller = Caller(f'reader_{index}')
    callers.append(caller)
    try:
        while not stop.is_set():
            for srv_type, name, request in (
                    (GetSimulationState, 'get_simulation_state', GetSimulationState.Request()),
                    (GetEntities, 'get_entities', GetEntities.Request()),
                    (GetEntityState, 'get_entity_state', GetEntityState.Request(entity='box'))):
                client = caller.client(srv_type, name)
                for _ in range(10):
                    caller.call(client, request)
                caller.node.destroy_client(client)
    except Exception as exc:  # noqa: B902 (said by the test)
        errors.append(exc)


def _rounds(stop, callers: list, errors: list, name: str, one_round) -> None:
    """Spawn and delete through clients of one caller: ``one_round(caller, spawn, delete, i)``."""
    from simulation_interfaces.srv import DeleteEntity, SpawnEntity
    caller = Caller(name)
    callers.append(caller)
    try:
        spawn = caller.client(SpawnEntity, 'spawn_entity')
        delete = caller.client(DeleteEntity, 'delete_entity')
        i = 0
        while not stop.is_set():
            i += 1
            one_round(caller, spawn, delete, i)
    except Exception as exc:  # noqa: B902 (said by the test)
        errors.append(exc)


def _editor(stop, callers: list, errors: list) -> None:
    """Spawn a box and delete it, again and again."""
    from simulation_interfaces.srv import DeleteEntity, SpawnEntity

    def one_round(caller, spawn, delete, i):
        request = SpawnEntity.Request(name=f'crate_{i}', uri='box')
        request.initial_pose.pose.position.x = 2.0 + (i % 5)
        caller.call(spawn, request)
        caller.call(delete, DeleteEntity.Request(entity=f'crate_{i}'))
    _rounds(stop, callers, errors, 'editor', one_round)


def _managers(stop, callers: list, errors: list, folder) -> None:
    """Spawn a robot, ask its controller manager, delete it: again and again."""
    from controller_manager_msgs.srv import ListControllers, ListHardwareInterfaces
    from simulation_interfaces.srv import DeleteEntity, SpawnEntity
    yaml = corpus.write(folder, 'cart_position.yaml', corpus.cart_yaml('position'))

    def one_round(caller, spawn, delete, i):
        ns = f'/cart_{i}'
        request = SpawnEntity.Request(name=f'cart_{i}', entity_namespace=ns,
                                      resource_string=corpus.cart('position', yaml, ns))
        request.initial_pose.pose.position.y = -3.0
        caller.call(spawn, request)
        listing = caller.client(ListControllers, f'{ns}/controller_manager/list_controllers')
        interfaces = caller.client(ListHardwareInterfaces,
                                   f'{ns}/controller_manager/list_hardware_interfaces')
        for _ in range(5):
            caller.call(listing, ListControllers.Request())
            caller.call(interfaces, ListHardwareInterfaces.Request())
        caller.node.destroy_client(listing)
        caller.node.destroy_client(interfaces)
        caller.call(delete, DeleteEntity.Request(entity=f'cart_{i}'))
    _rounds(stop, callers, errors, 'managers', one_round)


def _trajectories(stop, callers: list, errors: list) -> None:
    """
    Spawn an arm, send its trajectory server a goal, wait for the result, delete the arm.

    A fresh action client on a fresh server each round: the goal's response and its result
    are two more replies that must come (two calls each round).
    """
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient
    from simulation_interfaces.srv import DeleteEntity, SpawnEntity
    from trajectory_msgs.msg import JointTrajectoryPoint

    def one_round(caller, spawn, delete, i):
        name = f'arm_{i}'
        request = SpawnEntity.Request(name=name, resource_string=TWO_JOINT_ARM)
        request.initial_pose.pose.position.x = -3.0
        request.initial_pose.pose.position.z = 1.0
        caller.call(spawn, request)
        client = ActionClient(caller.node, FollowJointTrajectory,
                              f'{name}/follow_joint_trajectory')
        try:
            deadline = time.monotonic() + 20
            while not client.server_is_ready():
                assert time.monotonic() < deadline, f'{name} has no trajectory server'
                caller.spin_until(lambda: False, 0.05)
            goal = FollowJointTrajectory.Goal()
            goal.trajectory.joint_names = [f'{name}/j1', f'{name}/j2']
            goal.trajectory.points = [JointTrajectoryPoint(positions=[0.1, 0.0])]
            goal.trajectory.points[0].time_from_start.nanosec = 200_000_000
            handle = caller.ask(lambda: client.send_goal_async(goal), f'{name} goal response')
            if handle is not None and handle.accepted:
                caller.ask(handle.get_result_async, f'{name} goal result')
        finally:
            client.destroy()
        caller.call(delete, DeleteEntity.Request(entity=name))
    _rounds(stop, callers, errors, 'trajectories', one_round)


def test_over_a_thousand_calls_under_spawns_deletes_managers_and_lossy_discovery_none_is_lost(
        rclpy_context, tmp_path):
    node = NodeProcess(f'resource_paths:=["{tmp_path}"]')
    listener = Caller('diagnostics_listener')
    stop, callers, errors = threading.Event(), [], []
    flood = None
    try:
        diagnostics = Diagnostics(listener.node)
        listener.spin_until(lambda: diagnostics.heard, 20)
        from simulation_interfaces.srv import SpawnEntity
        listener.call(listener.client(SpawnEntity, 'spawn_entity'),
                      SpawnEntity.Request(name='box', uri='box'))
        port = lossy_discovery.discovery_port(node.proc.pid, int(os.environ['ROS_DOMAIN_ID']))
        flood = lossy_discovery.Flood(tmp_path / 'flood.stop', node.proc.pid, port)
        threads = [threading.Thread(target=_readers, args=(stop, callers, errors, i))
                   for i in range(3)]
        threads += [threading.Thread(target=_editor, args=(stop, callers, errors)),
                    threading.Thread(target=_managers, args=(stop, callers, errors, tmp_path)),
                    threading.Thread(target=_trajectories, args=(stop, callers, errors))]
        for t in threads:
            t.start()

        def sent_again() -> int:
            return int(diagnostics.latest().get('replies_sent_again', '0'))
        # Until the calls are made and the lossy discovery made one reply wait for its client.
        deadline = time.monotonic() + 150
        while (sum(c.calls for c in callers) < 1200
               or (sent_again() < 1 and not any(c.asked_again for c in callers))) \
                and time.monotonic() < deadline and not errors:
            listener.spin_until(lambda: False, 0.5)
        stop.set()
        for t in threads:
            t.join(2 * LOST_AFTER_SEC + 20)
        flooded = flood.stop()
        listener.spin_until(lambda: False, 1.5)  # the next once-a-second report
        assert not errors, errors
        calls = sum(c.calls for c in callers)
        lost = [name for c in callers for name in c.lost]
        again = [name for c in callers for name in c.asked_again]
        values = diagnostics.latest()
        print(f'{calls} calls, {len(again)} asked again {again}, {len(lost)} lost; the node '
              f'sent {values["replies_sent_again"]} replies again and gave up '
              f'{values["replies_given_up"]}; its discovery port dropped {flooded["dropped"]} '
              f'of {flooded["sent"]} junk datagrams and the announcements among them')
        assert calls >= 1000 and not lost, lost
        assert len(again) <= ASKED_AGAIN_AT_MOST, again
        assert values['replies_given_up'] == '0'
        # The race happened, and its reply came: else this run did not test the fix.
        assert sent_again() >= 1, f'no reply had to wait for its client: {flooded}'
        manager_calls = next(c.calls for c in callers if c.node.get_name() == 'managers')
        assert manager_calls >= 24  # two robots came and went at least
        # Four calls a round: the spawn, the goal's response, its result and the delete.
        arm_calls = next(c.calls for c in callers if c.node.get_name() == 'trajectories')
        print(f"{arm_calls} calls of the arms' rounds ({arm_calls // 4} goals)")
        assert arm_calls >= 8  # two arms came and went, each answering a goal and its result
        # /diagnostics kept coming all along: once a second, and at once with each change.
        # Heard here up to 3.6 s apart while the flood took one of two cores (3.0 s before it).
        times = [t for t, _ in diagnostics.heard]
        assert max(b - a for a, b in zip(times, times[1:])) < 5.0
    finally:
        stop.set()
        if flood is not None:
            flood.kill()
        for c in callers:
            c.close()
        listener.close()
        code, _ = node.interrupt()
        assert code == 0, node.output()
