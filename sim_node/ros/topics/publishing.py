"""
What the node publishes of the simulation: from snapshots, and once per model.

From snapshots: /clock, /tf, joint_states and sensors; per model: /tf_static and markers.

:class:`StatePublisher` runs two threads paced to absolute deadlines: ``sim-publisher``
(/tf every tf period through :class:`~msg_adapters.tf_stream.TfStream`, joint_states and sensor
messages every joint-states period) and ``sim-clock`` (/clock alone, so time flows for every
``use_sim_time`` node however long /tf of a big world takes: under 8 clients spawning and
deleting, a publisher cycle with /tf of 400 bodies and a new model took up to 146 ms). rclpy
timers woke the executor 150 times a second (each wake rebuilds its wait set while holding the
GIL), which cost the physics several percent, and drifted below their rate.

:class:`ModelTopics` is a session listener: on each new model (on the session's thread) it sends
/tf_static and every marker anew; when the world is unloaded, an empty /tf_static and a
DELETEALL. Both cost up to hundreds of milliseconds for a mesh-heavy robot, which is why they
are not on the publisher thread.
"""

import threading
import time
from typing import Callable, Optional

from msg_adapters import convert, markers
from msg_adapters.tf_stream import TfStream
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from ..settings.params import Frames
from ..settings.qos import LATCHED_QOS
from ...core.base.records import Snapshot
from ...session import Loaded


def _next_deadline(deadline: float, period: float, now: float) -> float:
    """Return the next absolute deadline; one period from now if more than a period behind."""
    deadline += period
    return deadline if deadline > now else now + period


class StatePublisher:
    """
    /clock, /tf, joint_states and sensor messages of the session's newest snapshot.

    A listener of the session (:meth:`on_model`) like the node's other parts: it records which
    world is loaded, and its threads read that world's newest snapshot at their rates.

    :param publish_sensors: called with each snapshot at the joint_states rate.
    :param report_failure: called as ``report_failure(what, exc)`` when a job fails.
    """

    def __init__(self, node: Node, frames: Frames, tf_period: float,
                 joint_states_period: float, publish_clock: bool,
                 publish_sensors: Callable[[Snapshot], None],
                 report_failure: Callable[[str, Exception], None]):
        self._loaded: Optional[Loaded] = None  # which world: told by the session (on_model)
        self._tf_period, self._js_period = tf_period, joint_states_period
        self._publish_sensors = publish_sensors
        self._report_failure = report_failure
        self._clock_pub = node.create_publisher(Clock, '/clock', 10) if publish_clock else None
        self._tf_pub = node.create_publisher(TFMessage, '/tf', 100)
        self._joint_pub = node.create_publisher(JointState, 'joint_states', 10)
        self._tf = TfStream(frames.world, frames.prefix)
        self.running = threading.Event()
        self._threads: list = []

    def on_model(self, loaded: Optional[Loaded], snap: Optional[Snapshot]) -> None:
        """Note which world is loaded (the session's listener); the publisher threads read it."""
        self._loaded = loaded

    def start(self) -> None:
        self.running.set()
        jobs = [('sim-publisher', 'publishing', [(self._tf_period, self._publish_tf),
                                                 (self._js_period, self._publish_joint_states)])]
        if self._clock_pub is not None:
            jobs.append(('sim-clock', 'publishing /clock',
                         [(self._tf_period, self._publish_clock)]))
        for name, what, job in jobs:
            thread = threading.Thread(target=self._paced, args=(what, job), name=name,
                                      daemon=True)
            thread.start()
            self._threads.append(thread)

    def set_tf_elsewhere(self, entities: frozenset) -> None:
        """Leave these entities' world transforms to another publisher (mobile bases)."""
        self._tf.set_elsewhere(entities)

    def stop(self) -> None:
        self.running.clear()
        for thread in self._threads:
            thread.join(2.0)

    def _paced(self, what: str, jobs: list) -> None:
        """
        Run each job ``(period, fn)`` every period, to absolute deadlines, while running.

        Re-syncs after a stall instead of bursting. A failure is reported and every job goes
        on one period later.
        """
        deadlines = [time.perf_counter()] * len(jobs)
        while self.running.is_set():
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
                self._report_failure(what, exc)
                deadlines = [now + period for period, _ in jobs]

    def _publish_clock(self) -> None:
        loaded = self._loaded
        if loaded is not None:
            # /clock goes on while paused (the same time), as Gazebo's does: nodes started with
            # use_sim_time then still start their timers, and RViz shows the time.
            self._clock_pub.publish(convert.clock(loaded.loop.latest_snapshot().time))

    def _publish_tf(self) -> None:
        loaded = self._loaded
        if loaded is None:
            return
        seq, snap = loaded.loop.wait_snapshot(-1, 0)
        msg = self._tf.message(loaded.loop, seq, snap)
        if msg is not None:
            self._tf_pub.publish(msg)

    def _publish_joint_states(self) -> None:
        loaded = self._loaded
        if loaded is None:
            return
        snap = loaded.loop.latest_snapshot()
        if snap.info.joint_names:
            self._joint_pub.publish(convert.joint_state(snap.info, snap))
        self._publish_sensors(snap)  # its sensors, and what the loop sampled (contacts...)


class ModelTopics:
    """
    /tf_static and markers per model, as a session listener (see the module docstring).

    :param device_transforms: ``(info, sim_time, frames)`` -> the static transforms of the
        model's published cameras and sensors, sent with the bodies'.
    """

    def __init__(self, node: Node, frames: Frames, device_transforms: Callable):
        self._frames = frames
        self._device_transforms = device_transforms
        self._tf_static_pub = node.create_publisher(TFMessage, '/tf_static', LATCHED_QOS)
        self._marker_pub = node.create_publisher(MarkerArray, 'markers', LATCHED_QOS)
        self._time = 0.0  # of the last model, for the markers' DELETEALL on unload
        self._shown = False

    def __call__(self, loaded: Optional[Loaded], snap: Optional[Snapshot]) -> None:
        if snap is None:
            if self._shown:  # unloaded: nothing of the old world lingers in RViz
                self._marker_pub.publish(markers.clear_markers(self._time,
                                                               self._frames.out_world))
                self._tf_static_pub.publish(TFMessage())
                self._shown = False
            return
        info, prefix = snap.info, self._frames.prefix
        frames = convert.frame_names(info, self._frames.world, prefix)
        static = convert.static_transforms(info, snap.time, frames, prefix)
        static.transforms += self._device_transforms(info, snap.time, frames)
        self._tf_static_pub.publish(static)  # one latched message: every static frame
        self._marker_pub.publish(markers.markers(info, snap.time, frames))
        self._time, self._shown = snap.time, True
