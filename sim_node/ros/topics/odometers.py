"""
P3D plugins' ground truth on the wire: nav_msgs/Odometry, as gazebo_ros_p3d sends it.

One publisher per plugin a spawned robot declares (:mod:`sim_node.core.models.p3d`), on the
topic it names (``odom`` by default, under the spawn's namespace), reliable
(:data:`ODOMETER_QOS`). Samples are taken in the stepping loop at the plugin's rate of
simulated time (:mod:`sim_node.core.stepping.odometers`), stamped with it, and sent from the
publisher thread (:meth:`OdometerPublishers.publish`). Frame ids: the plugin's
``frame_name`` (``world`` is the node's world frame, ``map`` stays ``map``, a link is
``<entity>/<link>`` as on /tf); the child is the body's link, ``<entity>/<link>``.
"""

import threading

from msg_adapters import odometry as om
from nav_msgs.msg import Odometry
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from ...core.base.records import ModelInfo

#: The sensor data QoS made reliable, as gazebo_ros_p3d's publisher: best-effort subscribers
#: (the sensor data QoS) and reliable ones both match it.
ODOMETER_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)


class OdometerPublishers:
    """The P3D publishers of a node."""

    def __init__(self, node: Node, world_frame: str, prefix: str):
        self._node, self._world, self._prefix = node, world_frame, prefix
        self._pubs: dict = {}  # site -> (topic, publisher)
        self._lock = threading.Lock()  # publish (publisher thread) and sync (model thread)

    def publish(self, sample, info: ModelInfo) -> None:
        """Send one sample of `info`'s model (from the publisher thread)."""
        decl = info.odometers.get(sample.site)
        if decl is None or sample.generation != info.generation:
            return  # its model is gone
        with self._lock:
            have = self._pubs.get(sample.site)
            if have is None or have[0] != decl.topic:
                if have is not None:
                    self._node.destroy_publisher(have[1])
                have = self._pubs[sample.site] = (decl.topic, self._create(decl.topic))
        frame = self._world if decl.frame == 'world' else \
            self._prefix + decl.frame if decl.reference else decl.frame
        child = self._prefix + self._link_frame(info, decl.body)
        have[1].publish(om.ground_truth(sample, frame, child, decl.noise))

    def sync(self, info) -> None:
        """Destroy the publishers of plugins a new model no longer has."""
        keep = set(info.odometers if info is not None else ())
        with self._lock:
            gone = [self._pubs.pop(k)[1] for k in list(self._pubs) if k not in keep]
        for pub in gone:
            self._node.destroy_publisher(pub)

    @staticmethod
    def _link_frame(info: ModelInfo, body: str) -> str:
        """Return a body's frame on /tf: a URDF's root body goes by ``<entity>/<root link>``."""
        if body in info.body_names:
            alias = info.body_alias[info.body_names.index(body)]
            if alias:
                return alias
        return body

    def _create(self, topic: str):
        """Make a publisher without QoS event handlers (see Perception._create_publisher)."""
        return self._node.create_publisher(
            Odometry, topic, ODOMETER_QOS,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
