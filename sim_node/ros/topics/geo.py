"""
Magnetometers and NavSat receivers on the wire: sensor_msgs/MagneticField and NavSatFix.

One publisher per sensor a spawned robot or an SDF model declares
(:class:`~sim_node.core.base.records.DeclaredGeo`), on the topic it names (an SDF sensor's
gz-sim default, ``/world/<w>/model/<m>/link/<l>/sensor/<s>/magnetometer`` or ``.../navsat``,
where it names none; a URDF sensor without one: ``sensors/<site>/magnetic_field`` or
``sensors/<site>/fix``), reliable (as ros_gz_bridge's publishers: best-effort subscribers
match too). Samples are taken in the stepping loop at the sensor's rate of simulated time
(:mod:`sim_node.core.stepping.geo`), stamped with it, and sent from the publisher thread
(:meth:`GeoPublishers.publish`); a sensor that is not ``always_on`` sends only to
subscribers, as Gazebo's.
"""

import threading

from msg_adapters import perception as pm
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import MagneticField, NavSatFix

from ...core.base.records import ModelInfo

GEO_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
#: Each kind's message type and the last part of its default topic.
KINDS = {'magnetometer': (MagneticField, 'magnetic_field'), 'navsat': (NavSatFix, 'fix')}


class GeoPublishers:
    """The magnetometer and NavSat publishers of a node."""

    def __init__(self, node: Node, prefix: str):
        self._node, self._prefix = node, prefix
        self._pubs: dict = {}  # site -> (topic, publisher)
        self._lock = threading.Lock()  # publish (publisher thread) and sync (model thread)

    def publish(self, sample, info: ModelInfo) -> None:
        """Send one sample of `info`'s model (from the publisher thread)."""
        decl = info.geo.get(sample.site)
        if decl is None or sample.generation != info.generation:
            return  # its model is gone
        msg_type, leaf = KINDS[decl.kind]
        topic = decl.topic or f'sensors/{pm.topic_token(decl.site)}/{leaf}'
        with self._lock:
            have = self._pubs.get(sample.site)
            if have is None or have[0] != topic:
                if have is not None:
                    self._node.destroy_publisher(have[1])
                have = self._pubs[sample.site] = (topic, self._create(msg_type, topic, decl))
        pub = have[1]
        if not decl.always_on and pub.get_subscription_count() == 0:
            return
        frame = self._prefix + decl.frame
        pub.publish(pm.magnetic_field(sample.value, sample.time, frame)
                    if decl.kind == 'magnetometer' else
                    pm.nav_sat_fix(sample.value, sample.time, frame))

    def sync(self, info) -> None:
        """Destroy the publishers of sensors a new model no longer has."""
        keep = set(info.geo if info is not None else ())
        with self._lock:
            gone = [self._pubs.pop(k)[1] for k in list(self._pubs) if k not in keep]
        for pub in gone:
            self._node.destroy_publisher(pub)

    def _create(self, msg_type, topic: str, decl):
        """Make a publisher without QoS event handlers (see Perception._create_publisher)."""
        events = PublisherEventCallbacks(use_default_callbacks=False)
        try:
            return self._node.create_publisher(msg_type, topic, GEO_QOS,
                                               event_callbacks=events)
        except Exception as exc:  # noqa: B902 (a name rclpy refuses: ours instead)
            default = f'sensors/{pm.topic_token(decl.site)}/{KINDS[decl.kind][1]}'
            self._node.get_logger().warning(
                f'{decl.kind} {decl.site!r}: topic {topic!r} is refused ({exc}); publishing '
                f'on {default}')
            return self._node.create_publisher(msg_type, default, GEO_QOS,
                                               event_callbacks=events)
