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
        self._frames: dict = {}  # (model generation, site) -> (frame id, child frame id)
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
            key = (info.generation, sample.site)  # found once a model, not at every sample
            frames = self._frames.get(key)
            if frames is None:
                frames = self._frames[key] = self._frame_ids(info, decl)
        have[1].publish(om.ground_truth(sample, *frames, decl.noise))

    def sync(self, info) -> None:
        """Destroy the publishers of plugins a new model no longer has."""
        keep = set(info.odometers if info is not None else ())
        with self._lock:
            gone = [self._pubs.pop(k)[1] for k in list(self._pubs) if k not in keep]
            self._frames.clear()
        for pub in gone:
            self._node.destroy_publisher(pub)

    def _frame_ids(self, info: ModelInfo, decl) -> tuple:
        """
        Return (frame id, child frame id) of a plugin's messages, as /tf names the frames.

        The frame: the node's world frame for ``world``, ``map`` as it is, else the reference
        link's frame. The child: the body's link; a URDF's root body goes by
        ``<entity>/<root link>`` (its alias).
        """
        frame = self._world if decl.frame == 'world' else \
            self._prefix + decl.frame if decl.reference else decl.frame
        child = decl.body
        if child in info.body_names:
            child = info.body_alias[info.body_names.index(child)] or child
        return frame, self._prefix + child

    def _create(self, topic: str):
        """Make a publisher without QoS event handlers (see Perception._create_publisher)."""
        return self._node.create_publisher(
            Odometry, topic, ODOMETER_QOS,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
