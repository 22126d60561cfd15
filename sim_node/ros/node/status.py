"""
What the node says about itself: /diagnostics, the core's log lines, the `paused` parameter.

The session's state comes to :meth:`Status.on_state` (a listener of the session, on its own
thread) with every change: /diagnostics goes out at once with it and the `paused` parameter
follows it, whoever changed it (a service, the parameter, a limit, a divergence, a failure).
Nothing here asks the session for its state in a loop. The node's housekeeping timer (every
0.2 s, on the executor) drains the core's log lines (its threads never call rclpy) into the ROS
logger and sends /diagnostics again once a second, as diagnostic_updater does, with the last
state received, the loop's rate and the mesh cache's size (and what deleted robots keep in
it), the replies the middleware could not send at once (sent again, given up, waiting:
:mod:`..settings.replies`), the concave meshes being decomposed into convex parts, if any, and
the gz-sim systems an SDF world or model names that are not run here; a refused joint command
or goal goes out at once too.
"""

import collections
import logging
import threading
import time
from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray
from msg_adapters import diagnostics
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..settings import replies
from ...core.models import asset_store, decompose
from ...session import LOADING_WORLD, NO_WORLD, PLAYING, Session, StateEvent

#: How long a refused joint command stays in /diagnostics (wall seconds).
REFUSAL_SHOWN_SEC = 10.0


class LogForwarder(logging.Handler):
    """Core log records go to a queue the node drains on its own thread (see the module)."""

    def __init__(self):
        super().__init__(logging.INFO)
        self.records = collections.deque(maxlen=200)

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


class Status:
    """/diagnostics, forwarded log lines and the `paused` parameter of a node over a session."""

    def __init__(self, node: Node, session: Session):
        self._node = node
        self._session = session
        self._pub = node.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._name = f'{node.get_fully_qualified_name()}: physics'
        self._last_sent = 0.0  # wall time /diagnostics last went out
        self._publish_lock = threading.Lock()  # the listener's thread and the executor's
        self._refused: dict = {}  # topic -> (what, why, names, wall time), the latest
        self._forwarder = LogForwarder()
        logging.getLogger('sim_node').addHandler(self._forwarder)
        logging.getLogger('sim_node').setLevel(logging.INFO)
        self.syncing_thread: Optional[int] = None  # set while we mirror `paused` ourselves
        self._param_lock = threading.Lock()
        self._event: StateEvent = session.state_event()
        self._handle = session.add_listener(on_state=self.on_state, name='status')

    def close(self) -> None:
        self._session.remove_listener(self._handle)
        logging.getLogger('sim_node').removeHandler(self._forwarder)

    def on_state(self, event: StateEvent) -> None:
        """Take a new state of the session's (as its listener): /diagnostics now, `paused`."""
        self._event = event
        self.sync_paused_parameter(event)
        self.publish(force=True)

    def housekeeping(self) -> None:
        self.drain_logs()
        self.publish(force=False)

    def refused_command(self, why: str, names: list) -> None:
        """Log a refused joint command, and say so on /diagnostics now."""
        self.refused('joint_commands', 'joint command', why, names)

    def refused(self, topic: str, what: str, why: str, names: list,
                verdict: str = 'refused') -> None:
        """
        Log a refused request on `topic` (a joint command, a goal); /diagnostics now.

        `verdict`: what became of it, when it was taken in part ('clamped', 'taken in part').
        """
        self._node.get_logger().warning(f'{what} {verdict}: {why}', throttle_duration_sec=1.0)
        self._refused[topic] = (what, why, names, time.monotonic(), verdict)
        self.publish(force=True, at_most_every=0.1)

    def publish(self, force: bool, at_most_every: float = 0.0) -> None:
        """
        /diagnostics once a second, and at once (`force`) with a new state or a refusal.

        A refused joint command or goal adds a status ``<node>: <topic>`` that says why (the
        joint, and for an unknown name the closest valid ones) and stays in the messages for
        REFUSAL_SHOWN_SEC; a flood of refusals is sent `at_most_every` seconds. Every state
        event is sent: a new state is never held back.
        """
        loaded = self._session.loaded
        if loaded is None or loaded.loop is None:
            return
        kept = loaded.world.kept_mesh_bytes()  # the world lock: never inside a node lock
        not_run = loaded.world.systems_not_run()
        with self._publish_lock:
            now = time.monotonic()
            if now - self._last_sent < (at_most_every if force else 1.0):
                return
            self._last_sent = now
            event = self._event
            cache = {'mesh_cache_mib': f'{asset_store.mesh_cache_bytes() / 2 ** 20:.1f}',
                     'mesh_cache_kept_mib': f'{kept / 2 ** 20:.1f}'}
            cache.update(replies.resender().counts())  # replies sent again, given up
            busy = decompose.running()
            if busy:  # a spawn waiting on a concave mesh's parts says why it takes a while
                cache['decomposing'] = ', '.join(f'{label} ({sec:.0f} s of at most '
                                                 f'{decompose.SECONDS:g})'
                                                 for label, sec in busy)
            if not_run:  # an SDF file's systems this simulator does not run, by whose
                cache['gz_systems_not_run'] = '; '.join(f'{owner}: {", ".join(names)}'
                                                        for owner, names in not_run.items())
            msg = diagnostics.diagnostics(loaded.loop.status(), self._name, event.state,
                                          event.reason, event.divergence, cache)
            for topic, (what, why, names, when, verdict) in list(self._refused.items()):
                if now - when < REFUSAL_SHOWN_SEC:
                    msg.status.append(diagnostics.refused_command(
                        why, names, f'{self._node.get_fully_qualified_name()}: {topic}', what,
                        verdict))
            self._pub.publish(msg)

    def drain_logs(self) -> None:
        log = self._node.get_logger()
        records = self._forwarder.records
        while records:
            rec = records.popleft()
            text = rec.getMessage()
            if rec.levelno >= logging.ERROR:
                log.error(text)
            elif rec.levelno >= logging.WARNING:
                log.warning(text, throttle_duration_sec=1.0)
            else:
                log.info(text)

    def sync_paused_parameter(self, event: Optional[StateEvent] = None) -> None:
        """
        Mirror the session's state in the `paused` parameter, so `ros2 param get` is true.

        The state changes through services, limits and divergence too, not only the parameter.
        `event`: the state to mirror (a listener's); None: the session's now (a service that
        changed it mirrors it before it answers).
        """
        state = (event or self._session.state_event()).state
        if state in (NO_WORLD, LOADING_WORLD):
            return
        paused = state != PLAYING
        with self._param_lock:
            if self._node.get_parameter('paused').value != paused:
                self.syncing_thread = threading.get_ident()
                try:
                    self._node.set_parameters([Parameter('paused', Parameter.Type.BOOL,
                                                         paused)])
                finally:
                    self.syncing_thread = None
