"""
Laser scans on the wire: publishers by laser, poses asked of the world at their rates, rays cast.

A laser's rate is simulated time's: the stepping side copies where the laser and every geom are
at each due time (:meth:`~sim_node.core.world.World.scan_lasers`), and the perception thread
casts the rays against those poses later (:meth:`~sim_node.core.lidar.LaserScanner.cast`).
A scan is late when that thread is (a camera being drawn, cores short), never left out, and
stamped with its due time. Published on its declared topic (LaserScan, or PointCloud2 for a 3D
lidar) in its declared frame, else on ``lasers/<site>/scan`` in the site's frame.
"""

import threading
from typing import Callable

from msg_adapters import perception as pm
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan, PointCloud2

from ...core.base.config import PerceptionConfig
from ...core.base.records import ModelInfo, Snapshot
from ...core.lidar import LaserConfig


class Scans:
    """
    The laser publishers of a node's perception, by site, and the scans they send.

    :param create_publisher: makes a publisher that may be destroyed while the node runs.
    :param publishing: held while scans are checked against the world's resets and published
        (the perception's, shared with its cameras: see ``Perception.settle``).
    :param resets: the world's resets of state so far, read without the world lock.
    :param running: the perception's; cleared, no scan is published any more (checked under
        `publishing`: ``Perception.stop``).
    """

    def __init__(self, node: Node, config: PerceptionConfig, frame_prefix: str,
                 create_publisher: Callable, publishing: threading.Lock,
                 resets: Callable[[], int], running: threading.Event):
        self._node = node
        self.config = config
        self.laser_config = LaserConfig(
            angle_min=config.lidar_angle_min, angle_max=config.lidar_angle_max,
            samples=config.lidar_samples, range_min=config.lidar_range_min,
            range_max=config.lidar_range_max)
        self._prefix = frame_prefix
        self._create_publisher = create_publisher
        self._publishing = publishing
        self._resets = resets
        self._running = running
        self.pubs: dict = {}  # site name -> publisher
        self._decl: dict = {}  # site name -> its DeclaredLaser (None: the node's)

    def sync(self, info: ModelInfo, sites: tuple) -> None:
        """Make publishers for exactly `sites` (one whose declaration changed: anew)."""
        for gone in [k for k in self.pubs if k not in sites]:
            self._node.destroy_publisher(self.pubs.pop(gone))
        for site in sites:
            declared = info.lasers.get(site)
            if self._decl.get(site) != declared and site in self.pubs:
                self._node.destroy_publisher(self.pubs.pop(site))
            if site not in self.pubs:
                self.pubs[site] = self._publisher(site, declared)
            self._decl[site] = declared

    def _publisher(self, site: str, declared) -> Publisher:
        """LaserScan, or PointCloud2 for a 3D lidar; on its declared topic where it has one."""
        points = declared is not None and declared.points
        msg_type = PointCloud2 if points else LaserScan
        default = f'lasers/{pm.topic_token(site)}/{"points" if points else "scan"}'
        topic = declared.topic if declared is not None and declared.topic else default
        try:
            return self._create_publisher(msg_type, topic, qos_profile_sensor_data)
        except Exception as exc:  # noqa: B902 (a name rclpy refuses: ours instead)
            self._node.get_logger().warning(
                f'laser {site!r}: topic {topic!r} is refused ({exc}); publishing on {default}')
            return self._create_publisher(msg_type, default, qos_profile_sensor_data)

    def due(self, st, snap: Snapshot, info_now: Callable) -> None:
        """
        Ask the world for the lasers' poses at their rates; cast and publish those so far.

        :param st: the perception thread's state: its world, scanner, sites, their declared
            rates and sweeps, and what the world was last asked for (``requested``).
        :param info_now: the world's model info now (the scans are of its generation).
        """
        rates = {site: st.scan_rates.get(site, self.config.lidar_rate_hz)
                 for site in st.sites if self._wanted(site, snap.info)}
        if rates != st.requested:
            st.world.scan_lasers(rates)
            st.requested = rates
        poses = st.world.take_laser_poses()
        if not poses:
            return
        resets = self._resets()
        readings = st.scanner.cast(poses, st.sweeps, resets)
        info = info_now()
        with self._publishing:
            if not self._running.is_set():
                return  # perception stopped: the node may be going (Perception.stop)
            if self._resets() != resets or info is None:
                return  # a reset came while the rays were cast: those are of a past time
            for reading in readings:
                self._publish(reading, info, 1.0 / rates.get(
                    reading.site, self.config.lidar_rate_hz))

    def _wanted(self, site: str, info: ModelInfo) -> bool:
        """Say whether a laser scans now: one declared not ``always_on`` only while heard."""
        declared = info.lasers.get(site)
        if declared is None or declared.always_on:
            return True
        pub = self.pubs.get(site)
        return pub is not None and pub.get_subscription_count() > 0

    def _publish(self, reading, info: ModelInfo, period: float) -> None:
        pub = self.pubs.get(reading.site)
        site = next((s for s in info.sites if s.name == reading.site), None)
        if pub is None or site is None:
            return
        declared = info.lasers.get(reading.site)
        frame = (self._prefix + declared.frame if declared is not None and declared.frame
                 else pm.site_frame(info, site, self._prefix))
        if declared is not None and declared.points:
            # in its declared frame: the site's pose in its link when that is the link named
            on_link = declared.frame == info.body_names[site.body] or (
                info.body_alias[info.body_root[site.body]] == declared.frame
                and site.body == info.body_root[site.body])
            where = (site.pos, site.quat_wxyz) if on_link else ()
            pub.publish(pm.laser_points(reading, frame, *where))
            return
        pub.publish(pm.laser_scan(reading, self.laser_config, frame, period))
