"""
What a robot file's sensor tags declare, read and checked: a laser's sweep, rate, frame, topic.

Lasers (:func:`laser`), cameras (:func:`camera`), IMUs (:func:`imu`), magnetometers and NavSat
receivers (:func:`geo`), force-torque sensors on joints (:func:`force_torque`: SDF's
``<frame>`` and ``<measure_direction>``, a frame id and a topic as for lasers) and contact
sensors (:func:`contact`: the link's collisions by
the names Gazebo gives them, a topic from ``<topic>``, ``<contact><topic>`` or the bumper
plugin's ``bumper_states`` remapping).

A ``<sensor type="ray|gpu_ray|lidar|gpu_lidar">`` of Gazebo classic (``<ray>``) or current Gazebo
(``<lidar>``) gives its ``<update_rate>``, ``<always_on>``, ``<scan><horizontal>`` and
``<vertical>`` (``samples`` times ``resolution``, ``min_angle``, ``max_angle``), ``<range>``
(``min``, ``max``) and ``<noise>`` (``gaussian``: ``mean``, ``stddev``); its frame comes from
the plugin's ``frame_name`` (``frameName`` of ROS 1) or ``<gz_frame_id>``, else its link; its
topic from ``<topic>``, the plugin's ``<ros><namespace>`` and ``<remapping>~/out:=...``, or
``topicName``. A value that is absurd (a rate above :data:`MAX_RATE_HZ`, more than
:data:`MAX_RAYS` rays a sweep, a negative or infinite range, noise that is not a number, a frame
that is not a link of the robot, a topic ROS would refuse) is left out with a warning naming the
sensor and the value: the node's own setting applies to it, and the robot still spawns.

ROS-free; the names it returns are the robot's own (:func:`entity_laser` puts them under the
entity's name and namespace at a spawn).
"""

from dataclasses import replace
import logging
import math
import re
from typing import Optional, Sequence
from xml.etree import ElementTree as ET

from ..base.records import (DeclaredCamera, DeclaredContact, DeclaredGeo, DeclaredImu,
                            DeclaredLaser, DeclaredOdometer, DeclaredWrench, NO_TOPIC)

log = logging.getLogger(__name__)

#: The most scans (or samples) per simulated second a declared sensor may ask for.
MAX_RATE_HZ = 1000.0
#: The largest image a declared camera may ask for (pixels a side).
MAX_IMAGE_SIDE = 4096
#: An IMU's (a magnetometer's, a NavSat's) samples per simulated second when its tag gives no
#: update_rate.
DEFAULT_IMU_RATE_HZ = 100.0
#: The most rays one sweep of a declared laser may cast (horizontal times vertical).
MAX_RAYS = 100_000
#: The farthest a declared laser may see (m).
MAX_RANGE = 10_000.0
#: A camera tag's image <format> (Gazebo classic's and current Gazebo's names) -> encoding.
FORMATS = {'R8G8B8': 'rgb8', 'RGB_INT8': 'rgb8', 'B8G8R8': 'bgr8', 'BGR_INT8': 'bgr8',
           'L8': 'mono8', 'L_INT8': 'mono8', 'L16': 'mono16', 'L_INT16': 'mono16'}
#: Camera sensor types that see depth (they publish depth images and points).
DEPTH_CAMERAS = ('depth', 'depth_camera', 'rgbd_camera', 'rgbd')
_TOKEN = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*$')
WARN = "URDF sensor {sensor!r}: {what} {value!r} {why}; the node's own setting is used"


def laser(sensor: ET.Element, site: str, link: str, links: Sequence[str]) -> DeclaredLaser:
    """
    Read a laser sensor tag: what it declares, checked (see the module docstring).

    :param site: the site made for it in the robot's model (``<sensor>_lidar``).
    :param link: the link it is on; `links`: every link of the robot (frames it may name).
    """
    ray = _first(sensor, 'ray', 'lidar')
    warn = _warner(sensor, site)
    out = DeclaredLaser(site=site, rate_hz=_rate(sensor, warn),
                        always_on=_always_on(sensor))
    if ray is not None:
        out = _sweep(out, ray, warn)
    out = replace(out, frame=_frame(sensor, link, links, warn), topic=_topic(sensor, warn))
    plugin = sensor.find('plugin')
    output = (plugin.findtext('output_type') or '') if plugin is not None else ''
    vertical = out.vertical[0] if out.vertical else 1
    return replace(out, points=vertical > 1 or 'pointcloud' in output.lower())


def _sweep(out: DeclaredLaser, ray: ET.Element, warn) -> DeclaredLaser:
    """Read the horizontal and vertical sweeps, the range and the noise of a <ray>/<lidar>."""
    scan = ray.find('scan')
    horizontal = _axis(scan.find('horizontal') if scan is not None else None)
    vertical = _axis(scan.find('vertical') if scan is not None else None)
    rays = (horizontal[0] or 1) * (vertical[0] or 1)
    if horizontal[0] is not None and not 1 <= horizontal[0] <= MAX_RAYS:
        warn('horizontal samples', horizontal[0], f'are not in [1, {MAX_RAYS}]')
        horizontal = (None,) + horizontal[1:]
    elif rays > MAX_RAYS:
        warn('rays a sweep', rays, f'are more than {MAX_RAYS}')
        horizontal = vertical = (None, None, None)
    samples, lo, hi = horizontal
    if (lo is None) != (hi is None) or (lo is not None and not (
            -2 * math.pi - 1e-6 <= lo <= hi <= 2 * math.pi + 1e-6 and hi - lo <= 2 * math.pi
            + 1e-6)):
        warn('horizontal angles', (lo, hi), 'are not a sweep of at most a turn')
        lo = hi = None
    out = replace(out, samples=samples, angle_min=lo, angle_max=hi)
    if vertical[0] is not None:
        vs, vlo, vhi = vertical
        vlo, vhi = (0.0 if vlo is None else vlo), (0.0 if vhi is None else vhi)
        if not (1 <= vs <= MAX_RAYS and -math.pi / 2 <= vlo <= vhi <= math.pi / 2):
            warn('vertical sweep', (vs, vlo, vhi), 'is not 1 or more samples within +-90 deg')
        else:
            out = replace(out, vertical=(int(vs), vlo, vhi))
    rng = ray.find('range')
    if rng is not None:
        rmin, rmax = _number(rng.findtext('min')), _number(rng.findtext('max'))
        if rmin is not None or rmax is not None:
            if rmin is None or rmax is None or not 0 <= rmin < rmax <= MAX_RANGE:
                warn('range', (rng.findtext('min'), rng.findtext('max')),
                     f'is not 0 <= min < max <= {MAX_RANGE:g} m')
            else:
                out = replace(out, range_min=rmin, range_max=rmax)
    noise = ray.find('noise')
    if noise is not None and (noise.findtext('type') or 'gaussian').strip() == 'gaussian':
        mean = _number(noise.findtext('mean'), nan_ok=True) or 0.0
        std = _number(noise.findtext('stddev'), nan_ok=True)
        if std is not None and (not math.isfinite(std) or std < 0 or not math.isfinite(mean)):
            warn('noise', (noise.findtext('mean'), noise.findtext('stddev')),
                 'is not a finite mean and a standard deviation >= 0')
        elif std:
            out = replace(out, noise=(mean, std))
    return out


def _axis(el: Optional[ET.Element]) -> tuple:
    """Return (samples x resolution, min angle, max angle) of a <horizontal>/<vertical>."""
    if el is None:
        return (None, None, None)
    samples = _number(el.findtext('samples'))
    resolution = _number(el.findtext('resolution'))
    if samples is not None and resolution is not None and resolution >= 1:
        samples *= resolution
    return (None if samples is None else int(round(samples)),
            _number(el.findtext('min_angle')), _number(el.findtext('max_angle')))


def _frame(sensor: ET.Element, link: str, links: Sequence[str], warn) -> str:
    """Return the frame its messages name: the plugin's or gz_frame_id if a link, else the link."""
    names = [t for t in ('frame_name', 'frameName') for p in sensor.iter('plugin')
             for t in [p.findtext(t)] if t] + [sensor.findtext('gz_frame_id') or '',
                                               sensor.findtext('ign_frame_id') or '']
    given = next((n.strip() for n in names if n and n.strip()), '')
    if given and given not in links:
        warn('frame', given, 'is not a link of the robot')
        return link
    return given or link


def _topic(sensor: ET.Element, warn, outs: tuple = ('~/out', 'out'),
           old: str = 'topicName') -> str:
    """
    Return its topic as declared ('' : none), relative names kept relative.

    :param outs: the names the plugin publishes on that a ``<remapping>`` may rename.
    :param old: the plugin's ROS 1 element naming its topic.
    """
    plugin = sensor.find('plugin')
    topic = (sensor.findtext('topic') or sensor.findtext('contact/topic') or '').strip()
    if plugin is not None:
        named = plugin_output(plugin, outs, old)
        if not named and plugin_namespace(plugin):
            named = f'{plugin.get("name") or sensor.get("name")}/out'
        topic = in_namespace(plugin_namespace(plugin), named) or topic
    if topic and not valid_topic(topic):
        warn('topic', topic, 'is not a name ROS takes')
        return ''
    return topic


def plugin_namespace(plugin: ET.Element) -> str:
    """Return a gazebo_ros plugin's namespace: ``<ros><namespace>``, ROS 1's ``robotNamespace``."""
    ns = plugin.findtext('ros/namespace') or plugin.findtext('robotNamespace') or ''
    return ns.strip().rstrip('/')


def plugin_output(plugin: ET.Element, outs: tuple, old: str = 'topicName') -> str:
    """
    Return the topic a gazebo_ros plugin names for its output, or ''.

    A ``<remapping>`` of one of `outs` (the names it publishes on), the last one, else ROS 1's
    `old` element; not yet under the plugin's namespace (:func:`in_namespace`).
    """
    out = ''
    for remap in plugin.iter('remapping'):
        src, _, dst = (remap.text or '').partition(':=')
        if src.strip() in outs and dst.strip():
            out = dst.strip()
    return out or (plugin.findtext(old) or '').strip()


def in_namespace(namespace: str, topic: str) -> str:
    """Return a plugin's `topic` under its `namespace`, unless absolute ('' stays '')."""
    return topic if not topic or topic.startswith('/') or not namespace \
        else f'{namespace}/{topic}'


def floats(text: Optional[str], n: int) -> Optional[list]:
    """Return `n` finite numbers a tag or attribute gives, or None."""
    try:
        values = [float(v) for v in (text or '').split()]
    except ValueError:
        return None
    return values if len(values) == n and all(math.isfinite(v) for v in values) else None


def valid_topic(name: str) -> bool:
    """Return whether ROS takes `name` as a topic (tokens of letters, digits, _; / between)."""
    body = name[1:] if name.startswith('/') else name
    return bool(body) and all(_TOKEN.match(t) for t in body.split('/'))


def contact(sensor: ET.Element, name: str, link: str, collisions: dict) -> DeclaredContact:
    """
    Read a contact sensor tag on `link`: the collisions it reports on, its rate and topic.

    :param collisions: Gazebo's name -> geom name of the link's collisions. A ``<collision>``
        the link lacks is left out with a warning; none given (or none left): all of them.
    """
    warn = _warner(sensor, name)
    named = [(c.text or '').strip() for c in sensor.iter('collision') if (c.text or '').strip()]
    geoms = []
    for given in named:
        # A lumped link's collision (sdformat's <parent>_fixed_joint_lump__<link>_collision):
        # this simulator keeps links apart, so it is that link's own collision.
        own = given.split('_fixed_joint_lump__', 1)[-1]
        if own in collisions:
            geoms.append(collisions[own])
        else:
            log.warning('URDF sensor %r: collision %r is not a collision of link %r (it has '
                        '%s): left out', name, given, link, ', '.join(sorted(collisions))
                        or 'none')
    frame = next((t.strip() for p in sensor.iter('plugin')
                  for t in [p.findtext('frame_name') or p.findtext('frameName')] if t), '')
    if frame and frame != 'world':
        log.warning("URDF sensor %r: frame %r is not 'world': its contacts are reported in "
                    'the world frame', name, frame)
    return DeclaredContact(name=name, geoms=tuple(dict.fromkeys(geoms or collisions.values())),
                           rate_hz=_rate(sensor, warn), always_on=_always_on(sensor),
                           topic=_topic(sensor, warn, ('bumper_states', '~/bumper_states',
                                                       '~/out', 'out'), 'bumperTopicName'))


def _always_on(sensor: ET.Element) -> bool:
    return (sensor.findtext('always_on') or 'true').strip().lower() not in ('0', 'false')


def entity_sensor(decl, entity: str, namespace: str, root: str = ''):
    """Return a declared sensor's record under `entity` (see :func:`entity_laser`)."""
    if isinstance(decl, DeclaredContact):
        return replace(decl, name=f'{entity}/{decl.name}',
                       geoms=tuple(f'{entity}/{g}' for g in decl.geoms),
                       topic=_under(namespace, decl.topic))
    if isinstance(decl, DeclaredWrench):
        return entity_wrench(decl, entity, namespace, root)
    if isinstance(decl, DeclaredCamera):
        return replace(decl, camera=f'{entity}/{decl.camera}',
                       frame=f'{entity}/{decl.frame}' if decl.frame else '',
                       topic=_under(namespace, decl.topic),
                       image_topic=_under(namespace, decl.image_topic),
                       info_topic=_under(namespace, decl.info_topic),
                       depth_topic=_under(namespace, decl.depth_topic),
                       points_topic=_under(namespace, decl.points_topic))
    if isinstance(decl, (DeclaredImu, DeclaredGeo)):
        return replace(decl, site=f'{entity}/{decl.site}', frame=f'{entity}/{decl.frame}',
                       topic=_under(namespace, decl.topic))
    if isinstance(decl, DeclaredOdometer):
        return replace(decl, site=f'{entity}/{decl.site}',
                       body=_link_body(entity, root, decl.body),
                       frame=f'{entity}/{decl.reference}' if decl.reference else decl.frame,
                       reference=_link_body(entity, root, decl.reference)
                       if decl.reference else '',
                       topic=_under(namespace, decl.topic))
    return entity_laser(decl, entity, namespace)


def entity_laser(decl: DeclaredLaser, entity: str, namespace: str) -> DeclaredLaser:
    """
    Return `decl` with its site and frame under `entity` and its topic under `namespace`.

    A spawn's namespace goes before the declared topic, absolute or not, as a Gazebo spawn's
    robot namespace goes before its plugins' namespaces: two robots spawned with namespaces
    of their own never share a topic.
    """
    return replace(decl, site=f'{entity}/{decl.site}', frame=f'{entity}/{decl.frame}',
                   topic=_under(namespace, decl.topic))


def camera(sensor: ET.Element, name: str, links: Sequence[str]) -> DeclaredCamera:
    """
    Read a camera tag: its image size and rate, the frame and topics its plugin names.

    :param name: its camera in the robot's model; `links`: every link of the robot.
    """
    warn = _warner(sensor, name)
    width = _number(sensor.findtext('.//image/width'))
    height = _number(sensor.findtext('.//image/height'))
    if width is not None or height is not None:
        if not (width and height and 1 <= width <= MAX_IMAGE_SIDE
                and 1 <= height <= MAX_IMAGE_SIDE):
            warn('image size', (sensor.findtext('.//image/width'),
                                sensor.findtext('.//image/height')),
                 f'is not 1 to {MAX_IMAGE_SIDE} pixels a side')
            width = height = None
    plugin = sensor.find('plugin')
    frame = ''
    given = ''
    if plugin is not None:
        given = (plugin.findtext('frame_name') or plugin.findtext('frameName') or '').strip()
    given = given or (sensor.findtext('gz_frame_id') or '').strip()
    if given and given not in links:
        warn('frame', given, 'is not a link of the robot')
    elif given:
        frame = given
    topic = ''
    if plugin is not None:
        ns = (plugin.findtext('ros/namespace') or '').strip().rstrip('/')
        cam = (plugin.findtext('camera_name') or plugin.findtext('cameraName') or '').strip()
        if cam or ns:
            topic = f'{ns}/{cam or sensor.get("name") or name}' if ns else cam
    topic = topic or (sensor.findtext('topic') or '').strip()
    if topic and not valid_topic(topic):
        warn('topic', topic, 'is not a name ROS takes')
        topic = ''
    fmt = (sensor.findtext('.//image/format') or 'R8G8B8').strip()
    encoding = FORMATS.get(fmt.upper())
    if encoding is None:
        warn('image format', fmt, f'is not one of {", ".join(sorted(FORMATS))}')
        encoding = 'rgb8'
    near, far = (_number(sensor.findtext(f'.//clip/{k}')) for k in ('near', 'far'))
    clip = None
    if sensor.find('.//clip') is not None:
        if near is not None and far is not None and 0 <= near < far <= MAX_RANGE:
            clip = (near, far)
        else:
            warn('clip', (sensor.findtext('.//clip/near'), sensor.findtext('.//clip/far')),
                 f'is not 0 <= near < far <= {MAX_RANGE:g} m')
    return DeclaredCamera(camera=name, width=None if width is None else int(width),
                          height=None if height is None else int(height),
                          rate_hz=_rate(sensor, warn),
                          always_on=_always_on(sensor), frame=frame, topic=topic,
                          encoding=encoding, clip=clip,
                          depth=(sensor.get('type') or '').lower() in DEPTH_CAMERAS)


def imu(sensor: ET.Element, site: str, link: str, links: Sequence[str]) -> DeclaredImu:
    """Read an IMU tag: its rate, its gyro's and accelerometer's noise, frame and topic."""
    warn = _warner(sensor, site)
    rate = _rate(sensor, warn)
    noises = {}
    for part in ('angular_velocity', 'linear_acceleration'):
        axes = [sensor.find(f'imu/{part}/{axis}/noise') for axis in 'xyz']
        if not any(a is not None for a in axes):
            continue
        mean, std = [0.0] * 3, [0.0] * 3
        for k, noise in enumerate(axes):
            if noise is None or (noise.get('type') or noise.findtext('type') or
                                 'gaussian').strip() != 'gaussian':
                continue
            m = _number(noise.findtext('mean'), nan_ok=True) or 0.0
            sd = _number(noise.findtext('stddev'), nan_ok=True) or 0.0
            if not (math.isfinite(m) and math.isfinite(sd) and sd >= 0):
                warn(f'{part} noise', (noise.findtext('mean'), noise.findtext('stddev')),
                     'is not a finite mean and a standard deviation >= 0')
                continue
            mean[k], std[k] = m, sd
        if any(std) or any(mean):
            noises[part] = (tuple(mean), tuple(std))
    return DeclaredImu(site=site, rate_hz=rate or DEFAULT_IMU_RATE_HZ,
                       gyro_noise=noises.get('angular_velocity'),
                       accel_noise=noises.get('linear_acceleration'),
                       always_on=_always_on(sensor),
                       frame=_frame(sensor, link, links, warn), topic=_topic(sensor, warn))


def geo(sensor: ET.Element, site: str, kind: str, link: str,
        links: Sequence[str]) -> DeclaredGeo:
    """Read a magnetometer or NavSat tag (``kind``): its rate, frame and topic."""
    warn = _warner(sensor, site)
    return DeclaredGeo(site=site, kind=kind, rate_hz=_rate(sensor, warn) or DEFAULT_IMU_RATE_HZ,
                       always_on=_always_on(sensor), frame=_frame(sensor, link, links, warn),
                       topic=_topic(sensor, warn))


def force_torque(sensor: ET.Element, site: str, parent: str, child: str,
                 links: Sequence[str]) -> DeclaredWrench:
    """
    Read a force_torque tag on a joint: its frame, measure direction, frame id and topic.

    :param parent, child: the joint's links; `links`: every link of the robot.
    """
    warn = _warner(sensor, site)
    frame = (sensor.findtext('force_torque/frame') or 'child').strip().lower()
    if frame not in ('child', 'parent', 'sensor'):
        warn('frame', frame, "is not 'child', 'parent' or 'sensor'")
        frame = 'child'
    direction = (sensor.findtext('force_torque/measure_direction') or 'child_to_parent')
    direction = direction.strip().lower()
    if direction not in ('child_to_parent', 'parent_to_child'):
        warn('measure_direction', direction, "is not 'child_to_parent' or 'parent_to_child'")
        direction = 'child_to_parent'
    own = {'child': child, 'parent': parent, 'sensor': site}[frame]
    frame_id = _frame(sensor, own, list(links) + [site], warn)
    return DeclaredWrench(site=site, sign=-1.0 if direction == 'child_to_parent' else 1.0,
                          frame=frame, parent=parent, frame_id=frame_id,
                          topic=_topic(sensor, warn))


def entity_wrench(decl: DeclaredWrench, entity: str, namespace: str,
                  root: str = '') -> DeclaredWrench:
    """
    Return `decl` under `entity` (and its topic under `namespace`), as :func:`entity_laser`.

    :param root: the robot's root link: its body is the entity itself.
    """
    return replace(decl, site=f'{entity}/{decl.site}',
                   parent=_link_body(entity, root, decl.parent),
                   frame_id=f'{entity}/{decl.frame_id}', topic=_under(namespace, decl.topic))


def _link_body(entity: str, root: str, link: str) -> str:
    """Return the body a robot's link is once spawned as `entity` (its root link: the entity)."""
    return entity if link == root else f'{entity}/{link}'


def _under(namespace: str, topic: str) -> str:
    """
    Return a declared `topic` under a spawn's `namespace` (absolute or not).

    '' stays '', as does :data:`~..records.NO_TOPIC` (a camera's stream that is not there).
    """
    if topic and topic != NO_TOPIC and namespace:
        return f'/{namespace.strip("/")}/{topic.lstrip("/")}'
    return topic


def _warner(sensor: ET.Element, site: str):
    """Return a function that warns, naming the sensor, the value and why it is left out."""
    name = sensor.get('name') or site

    def warn(what: str, value, why: str) -> None:
        log.warning(WARN.format(sensor=name, what=what, value=value, why=why))
    return warn


def _rate(sensor: ET.Element, warn) -> Optional[float]:
    """Return the tag's update rate (Hz); None where it gives none or an absurd one (said)."""
    rate = _number(sensor.findtext('update_rate'))
    if rate is not None and not 0 < rate <= MAX_RATE_HZ:
        warn('update_rate', sensor.findtext('update_rate'), f'is not in (0, {MAX_RATE_HZ:g}] Hz')
        return None
    return rate


def _first(el: ET.Element, *tags: str) -> Optional[ET.Element]:
    for tag in tags:
        found = el.find(tag)
        if found is not None:
            return found
    return None


def _number(text: Optional[str], nan_ok: bool = False) -> Optional[float]:
    try:
        value = float((text or '').strip())
    except ValueError:
        return math.nan if nan_ok and text and text.strip() else None
    return value if nan_ok or math.isfinite(value) else None


def plugin_number(plugin: ET.Element, tag: str, most: float, warn,
                  zero: bool = False) -> Optional[float]:
    """
    Return a plugin tag's number in (0, most] ([0, most] with `zero`); None if absent or absurd.

    An absurd one is said with ``warn(tag, text, why)``. The camera plugins' own tags
    (:mod:`.realsense`, :mod:`.openni`) are read with it.
    """
    text = (plugin.findtext(tag) or '').strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if math.isfinite(value) and (0 <= value if zero else 0 < value) and value <= most:
        return value
    warn(tag, text, f'is not in {"[" if zero else "("}0, {most:g}]')
    return None


def plugin_range(plugin: ET.Element, tags: tuple, default: tuple, what: str, warn) -> tuple:
    """
    Return the (near, far) metres a plugin's two tags give (a depth range, a cloud's cutoffs).

    Each absent or absurd one is `default`'s (warned by :func:`plugin_number`); a pair that is
    not near < far is `default`, with ``warn(what, pair, why)``.
    """
    near = plugin_number(plugin, tags[0], MAX_RANGE, warn, zero=True)
    far = plugin_number(plugin, tags[1], MAX_RANGE, warn)
    pair = (default[0] if near is None else near, default[1] if far is None else far)
    if not pair[0] < pair[1]:
        warn(what, pair, 'is not near < far')
        return default
    return pair
