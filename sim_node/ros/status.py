"""
What the node says about itself: /diagnostics, the core's log lines, the `paused` parameter.

Run from the node's housekeeping timer (every 0.2 s, on the executor): the core logs to a queue
(its threads never call rclpy) that is drained into the ROS logger here; /diagnostics goes out
once a second and at once when the physics diverges or a joint command is refused; the `paused`
parameter follows the simulation's state, whoever changed it.
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

from ..session import LOADING_WORLD, NO_WORLD, PLAYING, Session

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
        self._diagnosed = (None, 0.0)  # (divergence report, wall time) last published
        self._refused: dict = {}  # topic -> (what, why, names, wall time), the latest
        self._forwarder = LogForwarder()
        logging.getLogger('sim_node').addHandler(self._forwarder)
        logging.getLogger('sim_node').setLevel(logging.INFO)
        self.syncing_thread: Optional[int] = None  # set while we mirror `paused` ourselves

    def close(self) -> None:
        logging.getLogger('sim_node').removeHandler(self._forwarder)

    def housekeeping(self) -> None:
        self.sync_paused_parameter()
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
        self.publish(force=True)

    def publish(self, force: bool) -> None:
        """
        /diagnostics once a second, and at once when the physics diverges.

        Also at once (at most ten times a second) when a joint command is refused: a status
        ``<node>: joint_commands`` says why (the joint, and for an unknown name the closest
        valid ones) and stays in the messages for REFUSAL_SHOWN_SEC.
        """
        loaded = self._session.loaded
        if loaded is None:
            return
        status = loaded.loop.status()
        now = time.monotonic()
        last_report, last_time = self._diagnosed
        if force and now - last_time < 0.1:
            return
        if not force and status.divergence is last_report and now - last_time < 1.0:
            return
        self._diagnosed = (status.divergence, now)
        msg = diagnostics.diagnostics(status, self._name)
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

    def sync_paused_parameter(self) -> None:
        """
        Mirror the session's state in the `paused` parameter, so `ros2 param get` is true.

        The state changes through services, limits and divergence too, not only the parameter.
        """
        state = self._session.state
        if state in (NO_WORLD, LOADING_WORLD):
            return
        paused = state != PLAYING
        if self._node.get_parameter('paused').value != paused:
            self.syncing_thread = threading.get_ident()
            try:
                self._node.set_parameters([Parameter('paused', Parameter.Type.BOOL, paused)])
            finally:
                self.syncing_thread = None
