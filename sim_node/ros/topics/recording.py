"""
The ``record`` parameter: what the node publishes, written into rosbag2 bags as it goes out.

Every publisher the node makes on a selected topic (``record_topics``, shell patterns on the
full name; camera images only with ``record_cameras``) is wrapped: a message is serialized
once, those bytes are published and queued for :class:`~sim_node.record.bag.BagWriter`,
with the simulation time the message is of (its header's stamp, a Clock's time) as the log
time, else the simulation time now. Latched topics (``/tf_static``,
``robot_description``, markers) keep transient-local durability in the bag's QoS metadata.
"""

import fnmatch
from typing import Callable, Optional

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message

from ...record.bag import BagWriter, Limits

#: Never recorded: ROS's own plumbing.
NOT_RECORDED = ('/parameter_events', '/rosout', '/_sim_instances')


def type_name(msg_type) -> str:
    """Return ``package/msg/Name`` of a message class."""
    package = msg_type.__module__.split('.')[0]
    return f'{package}/msg/{msg_type.__name__}'


class RecordingPublisher:
    """A publisher whose every message also goes into the bag (see the module docstring)."""

    def __init__(self, publisher, writer: BagWriter, msgtype: str, clock: Callable[[], float],
                 latched: bool, reliable: bool):
        self.publisher, self._writer, self._type = publisher, writer, msgtype
        self._clock, self._latched, self._reliable = clock, latched, reliable

    def publish(self, msg) -> None:
        raw = isinstance(msg, (bytes, bytearray))
        data = msg if raw else serialize_message(msg)
        self.publisher.publish(data)
        stamp = _stamp_ns(data) if raw else _own_stamp_ns(msg)
        if stamp is None:
            stamp = int(round(self._clock() * 1e9))
        self._writer.put(self.publisher.topic_name, self._type, data, stamp, self._latched,
                         self._reliable)

    def __getattr__(self, name):
        return getattr(self.publisher, name)


def _own_stamp_ns(msg) -> Optional[int]:
    """Return the simulation time a message is of (its header, a Clock's time), or None."""
    stamp = getattr(getattr(msg, 'header', None), 'stamp', None)
    if stamp is None:
        stamp = getattr(msg, 'clock', None)
    if stamp is None and getattr(msg, 'transforms', None):
        stamp = msg.transforms[0].header.stamp
    return None if stamp is None else stamp.sec * 10 ** 9 + stamp.nanosec


def _stamp_ns(data: bytes) -> Optional[int]:
    """Return the stamp of a serialized TFMessage's first transform (the node's bytes)."""
    if len(data) < 16 or int.from_bytes(data[4:8], 'little') == 0:
        return None
    return int.from_bytes(data[8:12], 'little', signed=True) * 10 ** 9 + \
        int.from_bytes(data[12:16], 'little')


class Recording:
    """
    The node's recording: which topics, the bag writer, its end.

    :param clock: returns the simulation time now (s), the log time of every message.
    """

    def __init__(self, folder: str, topics: list, cameras: bool, limits: Limits,
                 clock: Callable[[], float], on_error: Callable[[str], None]):
        self.topics, self.cameras, self._clock = topics or ['*'], cameras, clock
        self.writer = BagWriter(folder, limits, on_error=on_error)

    def wants(self, topic: str) -> bool:
        if '/' + topic.rsplit('/', 1)[-1] in NOT_RECORDED or (
                not self.cameras and '/cameras/' in topic + '/'):
            return False
        return any(fnmatch.fnmatchcase(topic, p) or fnmatch.fnmatchcase(topic.lstrip('/'), p)
                   for p in self.topics)

    def wrap(self, publisher, msg_type, qos) -> Optional[RecordingPublisher]:
        """Return the recording publisher of a new publisher, or None (not recorded)."""
        if not self.wants(publisher.topic_name):
            return None
        profile = qos if isinstance(qos, QoSProfile) else None
        latched = profile is not None and profile.durability == \
            DurabilityPolicy.TRANSIENT_LOCAL
        reliable = profile is None or profile.reliability != ReliabilityPolicy.BEST_EFFORT
        return RecordingPublisher(publisher, self.writer, type_name(msg_type), self._clock,
                                  latched, reliable)

    def close(self) -> None:
        self.writer.close()
