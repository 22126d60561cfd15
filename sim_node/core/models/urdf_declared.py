"""
What a URDF declares for a simulator, made into MJCF: Gazebo sensors and ros2_control interfaces.

Called on the spec MuJoCo imported from a URDF (:func:`.urdf.finish`), with the extension
elements :func:`.urdf.prepare` kept:

* ``<gazebo reference="link"><sensor type=...>`` (and a ``<sensor>`` of current Gazebo in a
  link): ``camera``, ``depth``, ``rgbd_camera``/``rgbd`` become a camera on the link (looking
  along the link's x, z up, as Gazebo's do; vertical field of view from ``horizontal_fov`` and
  the tag's image size); ``imu`` a site ``<sensor>_imu`` with a framequat, a gyro and an
  accelerometer; ``ray``, ``gpu_ray``, ``lidar``, ``gpu_lidar`` a site ``<sensor>_lidar``;
  ``magnetometer`` and ``navsat`` (``gps``) a site ``<sensor>_<kind>``
  (:mod:`sim_node.core.stepping.geo` samples them);
  ``force_torque`` on a joint a site on its child; ``contact`` reports on the link's
  collisions. What each tag declares (rates, sizes, sweeps, noise, frames, topics) is read by
  :mod:`.sensor_tags`; a sensor's ``<pose>`` places it on the link. The cameras a RealSense
  plugin drives take the topics, frames and depth format it names (:mod:`.realsense`), and
  a depth camera with an OpenNI Kinect plugin the topics and cutoffs it names (:mod:`.openni`).
* ``<gazebo><plugin filename="libgazebo_ros_p3d.so">``: a link's true pose and twist as
  odometry, on a site of the link (:mod:`.p3d`).
* ``<ros2_control>`` joints: a joint whose command interfaces are velocity without position
  gets a velocity actuator (``kv`` the link's inertia over twice a 2 ms step: a 4 ms time
  constant, stable; ``ctrlrange`` from the interface's min/max or the URDF velocity limit,
  ``forcerange`` from the effort limit); effort only, a motor within the effort
  limit. Position interfaces need nothing: joint commands and trajectories drive them by PD.
  ``<transmission>`` joints with a velocity or effort ``hardwareInterface`` likewise.
"""

import logging
import math
from typing import Optional
from xml.etree import ElementTree as ET

import mujoco
import numpy as np

from . import openni, p3d, realsense, sensor_tags
from ..base import loads, quat

log = logging.getLogger(__name__)

CAMERAS = ('camera', 'depth', 'depth_camera', 'rgbd_camera', 'rgbd', 'multicamera')
LASERS = ('ray', 'gpu_ray', 'lidar', 'gpu_lidar')
#: Sensor types sampled as :class:`~..base.records.DeclaredGeo` (Gazebo classic's ``gps`` is
#: current Gazebo's ``navsat``).
GEO = {'magnetometer': 'magnetometer', 'navsat': 'navsat', 'gps': 'navsat'}
#: A velocity interface's actuator gain: its joint's link inertia times this, over STEP.
VELOCITY_GAIN, STEP = 0.5, 0.002


def add(spec: mujoco.MjSpec, extensions: list, limits: dict,
        joints: Optional[dict] = None, collisions: Optional[dict] = None) -> tuple:
    """
    Add the declared sensors and interfaces to `spec`.

    :param limits: joint -> {'velocity', 'effort'} from the URDF (:func:`joint_limits`).
    :param joints: joint -> (parent link, child link), for sensors on joints
        (:func:`joint_links`).
    :param collisions: geom name -> Gazebo's collision name, for contact sensors.
    :returns: (what was added, as text; the declared lasers and force-torque sensors,
        :class:`.records.DeclaredLaser` and :class:`.records.DeclaredWrench` with the robot's
        own names, read by :mod:`.sensor_tags`).
    """
    done, declared = [], []
    joints = joints or {}
    bodies = {b.name: b for b in spec.bodies if b.name}
    for ext in extensions:
        if ext.tag != 'gazebo':
            continue
        link = ext.get('reference', '')
        for sensor in ext.iter('sensor'):
            body = bodies.get(link)
            if (sensor.get('type') or '').lower() == 'force_torque' and link in joints:
                text = _force_torque(spec, link, joints[link], sensor, declared)
                if text:
                    done.append(text)
                continue
            if body is None:
                log.warning('URDF sensor %r names link %r, which the model lacks: left out',
                            sensor.get('name'), link)
                continue
            if (sensor.get('type') or '').lower() == 'contact':
                own = {gz: g.name for g in body.geoms if g.name
                       for gz in [(collisions or {}).get(g.name)] if gz}
                declared.append(sensor_tags.contact(
                    sensor, sensor.get('name') or f'{link}_contact', link, own))
                done.append(f'contact sensor {sensor.get("name")!r} on {link!r}')
                continue
            try:
                text = _sensor(spec, body, sensor, declared)
            except ValueError as exc:  # MuJoCo refused a name or value: the robot still spawns
                log.warning('URDF sensor %r on %r left out: %s', sensor.get('name'), link, exc)
                continue
            if text:
                done.append(text)
    for joint, interfaces in _interfaces(extensions).items():
        try:
            text = _actuator(spec, joint, interfaces, limits.get(joint, {}))
        except ValueError as exc:
            log.warning('URDF interfaces of joint %r left out: %s', joint, exc)
            continue
        if text:
            done.append(text)
    declared = realsense.apply(declared, extensions, [b.name for b in spec.bodies if b.name])
    done += p3d.add(spec, extensions, declared)
    return done, declared


def _sensor(spec, body, sensor: ET.Element, declared: list) -> str:
    kind = (sensor.get('type') or '').lower()
    name = _free_name(spec, sensor.get('name') or f'{body.name}_{kind}')
    pose = sensor_tags.floats(sensor.findtext('pose'), 6) or [0.0] * 6
    pos, orientation = np.array(pose[:3]), quat.from_rpy(*pose[3:])
    if kind in CAMERAS:
        width = _number(sensor, './/image/width', 640.0)
        height = _number(sensor, './/image/height', 480.0)
        hfov = _number(sensor, './/horizontal_fov', 1.047)
        if not (0 < hfov < math.pi and width > 0 and height > 0):
            log.warning('URDF camera %r: field of view %g rad or image %gx%g is not a '
                        "camera's; the node's defaults are used", name, hfov, width, height)
            hfov, width, height = 1.047, 640.0, 480.0
        fovy = math.degrees(2 * math.atan(math.tan(hfov / 2) * height / width))
        # MuJoCo's camera looks along its -z with y up; Gazebo's along the link's x, z up.
        turn = quat.mul(orientation, quat.from_xyaxes((0, -1, 0), (0, 0, 1)))
        body.add_camera(name=name, pos=pos, quat=turn, fovy=fovy)
        declared.append(openni.named(sensor_tags.camera(
            sensor, name, [b.name for b in spec.bodies if b.name]), sensor))
        return f'camera {name!r} on {body.name!r}'
    if kind == 'imu':
        site = body.add_site(name=f'{name}_imu', pos=pos, quat=orientation)
        for stype, suffix in ((mujoco.mjtSensor.mjSENS_FRAMEQUAT, 'orientation'),
                              (mujoco.mjtSensor.mjSENS_GYRO, 'gyro'),
                              (mujoco.mjtSensor.mjSENS_ACCELEROMETER, 'accel')):
            spec.add_sensor(name=f'{name}_{suffix}', type=stype,
                            objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site.name)
        links = [b.name for b in spec.bodies if b.name]
        declared.append(sensor_tags.imu(sensor, site.name, body.name, links))
        return f'IMU {name!r} on {body.name!r}'
    if kind in LASERS:
        body.add_site(name=f'{name}_lidar', pos=pos, quat=orientation)
        links = [b.name for b in spec.bodies if b.name]
        declared.append(sensor_tags.laser(sensor, f'{name}_lidar', body.name, links))
        return f'laser {name!r} on {body.name!r}'
    if kind in GEO:
        kind = GEO[kind]
        body.add_site(name=f'{name}_{kind}', pos=pos, quat=orientation)
        links = [b.name for b in spec.bodies if b.name]
        declared.append(sensor_tags.geo(sensor, f'{name}_{kind}', kind, body.name, links))
        return f'{kind} {name!r} on {body.name!r}'
    log.warning('URDF sensor %r of type %r: not a kind this simulator makes (cameras, IMUs, '
                'lasers, contact, force_torque, magnetometer, navsat); left out', name, kind)
    return ''


def _force_torque(spec, joint: str, links: tuple, sensor: ET.Element, declared: list) -> str:
    """Add a force-torque sensor on a joint: force and torque sensors on a site of its child."""
    parent, child = links
    body = spec.body(child)
    if body is None:
        log.warning('URDF sensor %r: joint %r has no child link the model keeps; left out',
                    sensor.get('name'), joint)
        return ''
    name = _free_name(spec, sensor.get('name') or f'{joint}_ft')
    frame = (sensor.findtext('force_torque/frame') or 'child').strip().lower()
    given = sensor_tags.floats(sensor.findtext('pose'), 6) if frame == 'sensor' else None
    pose = given or [0.0] * 6
    site = body.add_site(name=f'{name}_ft', pos=pose[:3], quat=quat.from_rpy(*pose[3:]))
    for stype, suffix in ((mujoco.mjtSensor.mjSENS_FORCE, 'force'),
                          (mujoco.mjtSensor.mjSENS_TORQUE, 'torque')):
        spec.add_sensor(name=f'{name}_{suffix}', type=stype, objtype=mujoco.mjtObj.mjOBJ_SITE,
                        objname=site.name)
    declared.append(sensor_tags.force_torque(sensor, site.name, parent, child,
                                             [b.name for b in spec.bodies if b.name]))
    return f'force-torque sensor {name!r} on joint {joint!r}'


def joint_links(root: ET.Element) -> dict:
    """Return joint -> (parent link, child link) of a URDF's joints."""
    return {j.get('name', ''): (j.find('parent').get('link', ''), j.find('child').get('link', ''))
            for j in root.findall('joint')
            if j.find('parent') is not None and j.find('child') is not None}


def _free_name(spec, name: str) -> str:
    """
    Return `name`, or `name_2`, `name_3`... if a sensor's element already takes it.

    Gazebo tells sensors apart by link; URDFs reuse a name on one link (an RGB and a depth
    sensor both called ``rgbd_frame_sensor``), which MuJoCo refuses.
    """
    def taken(n):
        return (spec.camera(n) is not None or spec.site(f'{n}_imu') is not None
                or spec.site(f'{n}_lidar') is not None or spec.site(f'{n}_ft') is not None
                or spec.site(f'{n}_magnetometer') is not None
                or spec.site(f'{n}_navsat') is not None
                or spec.sensor(f'{n}_orientation') is not None)
    out, k = name, 1
    while taken(out):
        k += 1
        out = f'{name}_{k}'
    return out


def _number(el: ET.Element, path: str, default: float) -> float:
    try:
        value = float(el.findtext(path) or default)
    except ValueError:
        return default
    return value if math.isfinite(value) else default


def _interfaces(extensions: list) -> dict:
    """Joint -> {interface: (min, max)} from <ros2_control> and <transmission> elements."""
    out: dict = {}
    for ext in extensions:
        if ext.tag == 'ros2_control':
            for joint in ext.iter('joint'):
                for ci in joint.findall('command_interface'):
                    lo = hi = None
                    for p in ci.findall('param'):
                        if p.get('name') == 'min':
                            lo = sensor_tags.floats(p.text, 1)
                        elif p.get('name') == 'max':
                            hi = sensor_tags.floats(p.text, 1)
                    out.setdefault(joint.get('name', ''), {})[(ci.get('name') or '').lower()] = (
                        lo[0] if lo else None, hi[0] if hi else None)
        elif ext.tag == 'transmission':
            for joint in ext.iter('joint'):
                for hw in joint.iter('hardwareInterface'):
                    kind = (hw.text or '').lower()
                    for name in ('velocity', 'effort', 'position'):
                        if name in kind:
                            out.setdefault(joint.get('name', ''), {})[name] = (None, None)
    return out


def joint_limits(root: ET.Element) -> dict:
    """Return joint -> {'velocity', 'effort'} of a URDF's <limit> elements (0: none)."""
    out = {}
    for joint in root.findall('joint'):
        limit = joint.find('limit')
        if limit is None:
            continue
        values = {}
        for key in ('velocity', 'effort'):
            got = sensor_tags.floats(limit.get(key), 1)
            values[key] = got[0] if got else 0.0
        out[joint.get('name', '')] = values
    return out


def _actuator(spec, joint: str, interfaces: dict, limit: dict) -> str:
    if spec.joint(joint) is None or 'position' in interfaces:
        if spec.joint(joint) is None and interfaces:
            log.warning('ros2_control names joint %r, which the model lacks: left out', joint)
        return ''
    effort = abs(limit.get('effort') or 0.0)
    if 'velocity' in interfaces:
        lo, hi = interfaces['velocity']
        speed = abs(limit.get('velocity') or 0.0)
        if lo is None and hi is None and speed > 0:
            lo, hi = -speed, speed
        # Held under the load the joint moves (its links and all they carry), stiff enough to
        # keep its velocity as Gazebo's joint velocity command does, not so stiff that an
        # explicit step overshoots: that load over twice a 2 ms step (a 4 ms time constant).
        # A wheel's gain is set again at spawn by the robot's weight it carries
        # (:func:`~sim_node.core.control.wheels.add_wheel_actuators`).
        kv = max(loads.moved_inertia(spec.joint(joint)), 1e-6) * VELOCITY_GAIN / STEP
        act = spec.add_actuator(name=f'{joint}_velocity', target=joint,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_velocity(kv=kv)
        if lo is not None and hi is not None and lo < hi:
            act.ctrlrange, act.ctrllimited = [lo, hi], mujoco.mjtLimited.mjLIMITED_TRUE
        if effort > 0:
            act.forcerange, act.forcelimited = [-effort, effort], mujoco.mjtLimited.mjLIMITED_TRUE
        return f'velocity interface on {joint!r}'
    if 'effort' in interfaces:
        act = spec.add_actuator(name=f'{joint}_effort', target=joint,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_motor()
        if effort > 0:
            act.ctrlrange, act.ctrllimited = [-effort, effort], mujoco.mjtLimited.mjLIMITED_TRUE
        return f'effort interface on {joint!r}'
    return ''
