"""
Sensor broadcasters as ros2_controllers' have them: a ros2_control sensor's values on a topic.

A ``<sensor name=...>`` of a robot's ``<ros2_control>`` block is, as gz_ros2_control has it,
the Gazebo sensor of the same name its URDF declares (:mod:`sim_node.core.models.sensor_tags`):

* ``imu_sensor_broadcaster/IMUSensorBroadcaster``: ``~/imu`` (sensor_msgs/Imu) of its
  ``sensor_name``'s IMU, in ``frame_id``, with the YAML's ``static_covariance_orientation``,
  ``..._angular_velocity`` and ``..._linear_acceleration`` (9 values each);
* ``force_torque_sensor_broadcaster/ForceTorqueSensorBroadcaster``: ``~/wrench``
  (geometry_msgs/WrenchStamped) of its ``sensor_name``'s force-torque sensor, in ``frame_id``,
  with SDF's measure direction as declared.

Both at their update rate of simulated time, from the values MuJoCo's sensors had then.
"""

from geometry_msgs.msg import WrenchStamped
from msg_adapters import convert
from sensor_msgs.msg import Imu

from .controllers import NO_EVENTS, Runtime


class _Broadcaster(Runtime):
    """What both broadcasters share: a sensor group of the robot's model, found by name."""

    kind = ''
    suffix = ''

    def make(self) -> None:
        self.sensor = self.params['sensor_name']
        self.frame = self.params['frame_id']
        self.site = f'{self.host.entity}/{self.sensor}{self.suffix}'
        self.adr = None
        self.adr_generation = None

    def _parts(self, sample):
        """Return the sensor's parts' values in `sample` (None: not in the model now)."""
        info = self.host.info
        if sample.sensordata is None or info is None or info.generation != sample.generation:
            return None
        if self.adr_generation != info.generation:
            group = next((s for s in info.sensors if s.kind == self.kind
                          and s.name == self.site), None)
            self.adr = None if group is None else group.adr
            self.adr_generation = info.generation
        if self.adr is None:
            return None
        return {k: sample.sensordata[a:a + n] for k, (a, n) in self.adr.items()}


class ImuBroadcaster(_Broadcaster):
    """imu_sensor_broadcaster: ``~/imu``."""

    kind, suffix = 'imu', '_imu'

    def make(self) -> None:
        super().make()
        self.covariance = {k: list(self.params[f'static_covariance_{k}'])
                           for k in ('orientation', 'angular_velocity', 'linear_acceleration')}
        self.pub = self.node.create_publisher(Imu, '~/imu', 10, **NO_EVENTS)

    def update(self, sample, index: dict) -> None:
        parts = self._parts(sample)
        if parts is None:
            return
        msg = Imu()
        msg.header.stamp, msg.header.frame_id = convert.stamp(sample.time), self.frame
        if 'quat' in parts:
            msg.orientation = convert.quat_to_msg(parts['quat'])
        if 'gyro' in parts:
            msg.angular_velocity = convert.vec(parts['gyro'])
        if 'accelerometer' in parts:
            msg.linear_acceleration = convert.vec(parts['accelerometer'])
        msg.orientation_covariance = self.covariance['orientation']
        msg.angular_velocity_covariance = self.covariance['angular_velocity']
        msg.linear_acceleration_covariance = self.covariance['linear_acceleration']
        self.pub.publish(msg)


class ForceTorqueBroadcaster(_Broadcaster):
    """force_torque_sensor_broadcaster: ``~/wrench``."""

    kind, suffix = 'wrench', '_ft'

    def make(self) -> None:
        super().make()
        self.pub = self.node.create_publisher(WrenchStamped, '~/wrench', 10, **NO_EVENTS)

    def update(self, sample, index: dict) -> None:
        parts = self._parts(sample)
        if parts is None:
            return
        decl = self.host.info.wrenches.get(self.site)
        sign = decl.sign if decl is not None else 1.0
        msg = WrenchStamped()
        msg.header.stamp, msg.header.frame_id = convert.stamp(sample.time), self.frame
        if 'force' in parts:
            msg.wrench.force = convert.vec(sign * parts['force'])
        if 'torque' in parts:
            msg.wrench.torque = convert.vec(sign * parts['torque'])
        self.pub.publish(msg)
