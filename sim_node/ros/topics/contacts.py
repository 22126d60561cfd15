"""
Contact reports on the wire: ros_gz_interfaces/msg/Contacts, as Gazebo's contact sensor sends.

One publisher per contact sensor (a robot file's ``<sensor type="contact">``, MuJoCo's
``contact`` and ``touch`` sensors) and per entity named in ``contact_entities``: on the topic
the sensor declares, else ``contacts/<name>``. Reports are taken in the stepping loop at their
rates of simulated time (:mod:`sim_node.core.stepping.sampling`), stamped with it, and sent
from the publisher thread (:meth:`ContactPublishers.publish`).
"""

import threading
from typing import Callable

from msg_adapters import contacts as cm
from msg_adapters import perception as pm
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_gz_interfaces.msg import Contacts

from ...core.base.records import ModelInfo
from ...core.devices.contacts import ContactReport

#: Reliable, as a burst of reports (those of one publishing tick) must all arrive.
CONTACTS_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)


class ContactPublishers:
    """
    The contact publishers of a node.

    :param requested: returns the entities ``contact_entities`` names now.
    """

    def __init__(self, node: Node, world_frame: str, requested: Callable[[], tuple]):
        self._node, self._frame, self._requested = node, world_frame, requested
        self._pubs: dict = {}  # name -> (topic, publisher)
        self._lock = threading.Lock()

    def publish(self, report: ContactReport, info: ModelInfo) -> None:
        """Send one report of `info`'s model (from the publisher thread)."""
        decl = info.contacts.get(report.name)
        topic = (decl.topic if decl is not None else '') or \
            f'contacts/{pm.topic_token(report.name)}'
        with self._lock:
            have = self._pubs.get(report.name)
            if have is None or have[0] != topic:
                if have is not None:
                    self._node.destroy_publisher(have[1])
                have = self._pubs[report.name] = (topic, self._create(topic, report.name))
        if decl is not None and not decl.always_on and have[1].get_subscription_count() == 0:
            return
        have[1].publish(cm.contacts(report, info.geom_scoped, self._frame))

    def sync(self, info) -> None:
        """Destroy the publishers of sensors and entities a new model no longer has."""
        keep = set(info.contacts if info is not None else ()) | set(self._requested())
        with self._lock:
            gone = [self._pubs.pop(k)[1] for k in list(self._pubs) if k not in keep]
        for pub in gone:
            self._node.destroy_publisher(pub)

    def _create(self, topic: str, name: str):
        """Make a publisher without QoS event handlers (see Perception._create_publisher)."""
        try:
            return self._node.create_publisher(
                Contacts, topic, CONTACTS_QOS,
                event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
        except Exception as exc:  # noqa: B902 (a name rclpy refuses: ours instead)
            default = f'contacts/{pm.topic_token(name)}'
            self._node.get_logger().warning(
                f'contact sensor {name!r}: topic {topic!r} is refused ({exc}); publishing on '
                f'{default}')
            return self._node.create_publisher(
                Contacts, default, CONTACTS_QOS,
                event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
