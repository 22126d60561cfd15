"""
Pure conversions for what the robot sees and feels.

Images, camera info, IMU, wrench, range, laser scans, magnetic fields, NavSat fixes, generic
sensor values, and the TF frames they are given in.

Frames of cameras and sensor sites are named by the one frame rule (see
:func:`msg_adapters.convert.frame_names`): ``<entity>/<element>`` for an element of an entity,
``<element>`` on the world body; a camera's optical frame (REP 103: z forward, x right, y
down) is ``<that>_optical_frame``, a rangefinder's ``<sensor>`` frame has x along the ray, as
sensor_msgs/Range measures.
"""

import array
import math
import re
from typing import Optional, Sequence

from geometry_msgs.msg import WrenchStamped
import numpy as np
from sensor_msgs.msg import (CameraInfo, Image, Imu, LaserScan, MagneticField, NavSatFix,
                             NavSatStatus, PointCloud2, PointField, Range)
from sim_node.core.base import quat
from sim_node.core.base.records import CameraSpec, EntityRecord, ModelInfo, SensorSpec, SiteSpec
from sim_node.core.cameras import OPTICAL_FROM_MUJOCO_WXYZ
from sim_node.core.lidar import LaserConfig, LaserReading
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from tf2_msgs.msg import TFMessage

from .convert import element_frame, quat_to_msg, stamp, transform, vec

#: A rangefinder's frame from its site's: MuJoCo measures along the site's z, Range along x
#: (a quarter turn about y, w x y z).
RANGE_FROM_SITE_WXYZ = (math.sqrt(0.5), 0.0, -math.sqrt(0.5), 0.0)
_NOT_IN_NAME = re.compile(r'[^A-Za-z0-9_/]')


def topic_token(name: str) -> str:
    """Turn a MuJoCo name into valid ROS name tokens (``a b/1x`` -> ``a_b/_1x``)."""
    parts = [p for p in _NOT_IN_NAME.sub('_', name).split('/') if p]
    return '/'.join('_' + p if p[0].isdigit() else p for p in parts) or '_'


def interface_base(entity: EntityRecord) -> str:
    """Where an entity's own interfaces go: the namespace it was spawned with, else its name."""
    return entity.namespace.rstrip('/') or topic_token(entity.name)


def camera_frame(info: ModelInfo, cam: CameraSpec, prefix: str = '') -> str:
    return element_frame(info, cam.body, cam.name, prefix) + '_optical_frame'


def range_frame(info: ModelInfo, sensor: SensorSpec, prefix: str = '') -> str:
    return element_frame(info, sensor.site.body, sensor.name, prefix)


def site_frame(info: ModelInfo, site: SiteSpec, prefix: str = '') -> str:
    return element_frame(info, site.body, site.name, prefix)


def device_transforms(info: ModelInfo, sim_time: float, frames: Sequence[str],
                      cameras: Sequence[CameraSpec], sites: Sequence[SiteSpec],
                      ranges: Sequence[SensorSpec], prefix: str = '',
                      own: Sequence[tuple] = ()) -> list:
    """
    Return the fixed frames of devices in their bodies, for /tf_static.

    Fixed cameras' optical frames, sensor and scanner sites, rangefinders, and the frames of
    declared sensors that are their own (`own`: (site, frame name) each, the frame at the
    site; :attr:`~sim_node.core.base.records.ModelInfo.sensor_frames`).

    :param frames: (nbody,) body frames from :func:`msg_adapters.convert.frame_names`.
    """
    t = stamp(sim_time)
    out = []
    for cam in cameras:
        if cam.fixed:
            q = quat.mul(np.asarray(cam.quat_wxyz), np.asarray(OPTICAL_FROM_MUJOCO_WXYZ))
            out.append(transform(frames[cam.body], camera_frame(info, cam, prefix),
                                 cam.pos, q, t))
    seen = set()
    for site in sites:
        if site.site_id not in seen:
            seen.add(site.site_id)
            out.append(transform(frames[site.body], site_frame(info, site, prefix),
                                 site.pos, site.quat_wxyz, t))
    for sensor in ranges:
        q = quat.mul(np.asarray(sensor.site.quat_wxyz), np.asarray(RANGE_FROM_SITE_WXYZ))
        out.append(transform(frames[sensor.site.body], range_frame(info, sensor, prefix),
                             sensor.site.pos, q, t))
    out += [transform(frames[site.body], prefix + frame, site.pos, site.quat_wxyz, t)
            for site, frame in own]
    return out


def moving_camera_tf(frame: str, world_frame: str, pos, q_wxyz, sim_time: float) -> TFMessage:
    """Return a tracking camera's optical frame in the world, at the time of its image."""
    return TFMessage(transforms=[transform(world_frame, frame, pos, q_wxyz, stamp(sim_time))])


def image(rgb: np.ndarray, sim_time: float, frame: str, encoding: str = 'rgb8') -> Image:
    """
    (h, w, 3) uint8 -> sensor_msgs/Image in `encoding`: rgb8, bgr8, mono8 or mono16.

    Grey is the luma of ITU-R BT.601 (what image_proc and OpenCV take); mono16 spans 0-65535.
    """
    h, w = rgb.shape[:2]
    if encoding == 'bgr8':
        pixels, step = rgb[..., ::-1], 3 * w
    elif encoding in ('mono8', 'mono16'):
        grey = rgb.astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
        pixels = (np.round(grey).astype(np.uint8) if encoding == 'mono8'
                  else np.round(grey * 257.0).astype('<u2'))
        step = w * pixels.itemsize
    else:
        encoding, pixels, step = 'rgb8', rgb, 3 * w
    msg = Image(height=h, width=w, encoding=encoding, is_bigendian=0, step=step)
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    msg.data = array.array('B', np.ascontiguousarray(pixels).tobytes())
    return msg


def clipped(depth: np.ndarray, clip: Optional[tuple]) -> np.ndarray:
    """Return `depth` with what is nearer than clip[0] at -inf, farther than clip[1] +inf."""
    if clip is None:
        return depth
    out = depth.copy()
    out[depth < clip[0]] = -np.inf
    out[depth > clip[1]] = np.inf
    return out


def depth_image(depth: np.ndarray, sim_time: float, frame: str) -> Image:
    """(h, w) float32 metres -> sensor_msgs/Image 32FC1 (little-endian, as on this machine)."""
    h, w = depth.shape
    msg = Image(height=h, width=w, encoding='32FC1', is_bigendian=0, step=4 * w)
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    msg.data = array.array('B', depth.astype('<f4').tobytes())
    return msg


#: The farthest a 16UC1 depth image in millimetres can say (m).
MM_MAX = 65.535


def depth_image_mm(depth: np.ndarray, sim_time: float, frame: str,
                   clip: Optional[tuple] = None) -> Image:
    """
    (h, w) float32 metres -> sensor_msgs/Image 16UC1 in millimetres, as a RealSense sends it.

    0 where nothing is seen: nearer than clip[0], farther than clip[1] or than 65.535 m.
    """
    h, w = depth.shape
    near, far = clip if clip is not None else (0.0, MM_MAX)
    seen = np.isfinite(depth) & (depth >= near) & (depth <= min(far, MM_MAX))
    mm = np.floor(np.where(seen, depth, 0.0) * 1000.0).astype('<u2')  # (0 where unseen)
    msg = Image(height=h, width=w, encoding='16UC1', is_bigendian=0, step=2 * w)
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    msg.data = array.array('B', mm.tobytes())
    return msg


def camera_info(intrinsics: Sequence[float], width: int, height: int, sim_time: float,
                frame: str) -> CameraInfo:
    """
    Convert a pinhole model to sensor_msgs/CameraInfo: K and P, no distortion (plumb_bob).

    :param intrinsics: (fx, fy, cx, cy) in pixels (a :class:`CameraFrame`'s).
    """
    fx, fy, cx, cy = intrinsics
    msg = CameraInfo(height=height, width=width, distortion_model='plumb_bob')
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    msg.d = [0.0] * 5
    msg.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    msg.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return msg


def points(depth: np.ndarray, rgb: np.ndarray, intrinsics: Sequence[float], sim_time: float,
           frame: str) -> PointCloud2:
    """
    Turn a depth image into an organized point cloud in the optical frame (x, y, z, rgb).

    One point per pixel, row by row as in the image; NaN where nothing was hit (is_dense
    false). ``rgb`` is packed into a float32 as RViz and PCL read it.

    :param depth: (h, w) float32 metres along the optical axis; `rgb` (h, w, 3) uint8.
    :param intrinsics: (fx, fy, cx, cy) in pixels, as the frame's camera_info gives them.
    """
    h, w = depth.shape
    fx, fy, cx, cy = intrinsics
    z = np.where(np.isfinite(depth), depth, np.nan).astype(np.float32)
    u = np.arange(w, dtype=np.float32)[None, :]
    v = np.arange(h, dtype=np.float32)[:, None]
    cloud = np.empty((h, w, 4), dtype='<f4')
    cloud[..., 0] = (u - cx) * z / fx
    cloud[..., 1] = (v - cy) * z / fy
    cloud[..., 2] = z
    packed = ((rgb[..., 0].astype(np.uint32) << 16) | (rgb[..., 1].astype(np.uint32) << 8)
              | rgb[..., 2].astype(np.uint32))
    cloud[..., 3] = packed.view(np.float32)
    msg = PointCloud2(height=h, width=w, is_bigendian=False, point_step=16, row_step=16 * w,
                      is_dense=False)
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate(('x', 'y', 'z', 'rgb'))]
    msg.data = array.array('B', cloud.tobytes())
    return msg


def _values(sensordata: np.ndarray, adr: Optional[tuple]) -> Optional[np.ndarray]:
    if adr is None:
        return None
    start, size = adr
    return sensordata[start:start + size]


def imu(sensor: SensorSpec, sensordata: np.ndarray, sim_time: float, frame: str) -> Imu:
    """
    One site's framequat, gyro and accelerometer as sensor_msgs/Imu.

    A missing part has its covariance's first element at -1, as Imu.msg asks.
    """
    return imu_sample(_values(sensordata, sensor.adr.get('quat')),
                      _values(sensordata, sensor.adr.get('gyro')),
                      _values(sensordata, sensor.adr.get('accelerometer')), sim_time, frame)


def imu_sample(q, gyro, acc, sim_time: float, frame: str) -> Imu:
    """Return an IMU's orientation (wxyz), angular velocity and acceleration as Imu (None: -1)."""
    msg = Imu()
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    if q is not None:
        msg.orientation = quat_to_msg(q)
    else:
        msg.orientation_covariance[0] = -1.0
    if gyro is not None:
        msg.angular_velocity = vec(gyro)
    else:
        msg.angular_velocity_covariance[0] = -1.0
    if acc is not None:
        msg.linear_acceleration = vec(acc)
    else:
        msg.linear_acceleration_covariance[0] = -1.0
    return msg


def wrench(sensor: SensorSpec, sensordata: np.ndarray, sim_time: float,
           frame: str) -> WrenchStamped:
    """One site's force and torque sensors (either may be missing: zeros)."""
    msg = WrenchStamped()
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    force = _values(sensordata, sensor.adr.get('force'))
    torque = _values(sensordata, sensor.adr.get('torque'))
    if force is not None:
        msg.wrench.force = vec(force)
    if torque is not None:
        msg.wrench.torque = vec(torque)
    return msg


def range_reading(sensor: SensorSpec, sensordata: np.ndarray, sim_time: float,
                  frame: str) -> Range:
    """
    Convert a rangefinder to sensor_msgs/Range: one ray (field of view 0).

    +inf when MuJoCo saw nothing (-1), as REP 117 asks.
    """
    value = float(_values(sensordata, sensor.adr['value'])[0])
    msg = Range(radiation_type=Range.INFRARED, field_of_view=0.0, min_range=0.0,
                max_range=sensor.cutoff if sensor.cutoff > 0 else math.inf,
                range=value if value >= 0 else math.inf)
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    return msg


def magnetic_field(field, sim_time: float, frame: str) -> MagneticField:
    """Return a magnetometer's field (3,), tesla in its frame; its covariance unknown (zeros)."""
    msg = MagneticField(magnetic_field=vec(field))
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    return msg


def nav_sat_fix(where: tuple, sim_time: float, frame: str) -> NavSatFix:
    """Return a NavSat's (latitude deg, longitude deg, altitude m) as a fix, covariance unknown."""
    msg = NavSatFix(latitude=float(where[0]), longitude=float(where[1]),
                    altitude=float(where[2]),
                    position_covariance_type=NavSatFix.COVARIANCE_TYPE_UNKNOWN)
    msg.status = NavSatStatus(status=NavSatStatus.STATUS_FIX, service=NavSatStatus.SERVICE_GPS)
    msg.header.stamp = stamp(sim_time)
    msg.header.frame_id = frame
    return msg


def generic(sensor: SensorSpec, sensordata: np.ndarray) -> Float64MultiArray:
    """
    Any other sensor: its values as MuJoCo gives them, labelled with its type.

    Unstamped (std_msgs has no stamped array): the values are those of /clock's time.
    """
    values = _values(sensordata, sensor.adr['value'])
    msg = Float64MultiArray(data=[float(v) for v in values])
    msg.layout.dim = [MultiArrayDimension(label=sensor.type_name, size=len(values),
                                          stride=len(values))]
    return msg


def laser_scan(reading: LaserReading, config: LaserConfig, frame: str,
               period_sec: float) -> LaserScan:
    """
    One sweep as sensor_msgs/LaserScan (all rays at one instant: time_increment 0).

    `config`: the node's; a reading of a declared scanner carries its own (its sweep's).
    """
    if reading.sweep is not None:
        config = reading.sweep.config
    msg = LaserScan(angle_min=config.angle_min, angle_max=config.angle_max,
                    angle_increment=config.angle_increment, time_increment=0.0,
                    scan_time=period_sec, range_min=config.range_min,
                    range_max=config.range_max)
    msg.header.stamp = stamp(reading.time)
    msg.header.frame_id = frame
    msg.ranges = array.array('f', reading.ranges.astype(np.float32).tobytes())
    return msg


def laser_points(reading: LaserReading, frame: str, pos=None, quat_wxyz=None) -> PointCloud2:
    """
    Return a 3D lidar's sweep as an organized PointCloud2: one row per ring, x y z float32.

    Points where a ray hit within range (NaN elsewhere: is_dense false), in the site's frame,
    or in `frame` when the site's pose in it is given (`pos`, `quat_wxyz`).
    """
    sweep = reading.sweep
    ranges = np.atleast_2d(reading.ranges)
    rays = sweep.directions().reshape(ranges.shape + (3,))
    r = np.where(np.isfinite(ranges), ranges, np.nan)[..., None]
    xyz = rays * r
    if pos is not None:
        xyz = quat.rotate(np.asarray(quat_wxyz, dtype=float), xyz.reshape(-1, 3)).reshape(
            xyz.shape) + np.asarray(pos, dtype=float)
    h, w = ranges.shape
    msg = PointCloud2(height=h, width=w, is_bigendian=False, point_step=12, row_step=12 * w,
                      is_dense=False)
    msg.header.stamp = stamp(reading.time)
    msg.header.frame_id = frame
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate(('x', 'y', 'z'))]
    msg.data = array.array('B', xyz.astype('<f4').tobytes())
    return msg


def declared_wrench(msg: WrenchStamped, sign: float, turn_wxyz=None) -> WrenchStamped:
    """
    Return a declared force-torque sensor's message from MuJoCo's reading in `msg`.

    `sign` -1: the wrench the child applies to the parent (SDF's ``child_to_parent``);
    `turn_wxyz`: the child's orientation in the frame to express it in (its parent's).
    """
    w = msg.wrench
    force = sign * np.array([w.force.x, w.force.y, w.force.z])
    torque = sign * np.array([w.torque.x, w.torque.y, w.torque.z])
    if turn_wxyz is not None:
        force, torque = quat.rotate(turn_wxyz, force), quat.rotate(turn_wxyz, torque)
    msg.wrench.force, msg.wrench.torque = vec(force), vec(torque)
    return msg
