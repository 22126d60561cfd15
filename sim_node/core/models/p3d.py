"""
Gazebo's P3D plugin in a URDF: a body's true pose and twist as nav_msgs/Odometry.

``<gazebo><plugin filename="libgazebo_ros_p3d.so">`` (gazebo_ros_p3d; ROS 1's
``<controller:gazebo_ros_p3d plugin="libgazebo_ros_p3d.so">`` too) publishes where one link
truly is and how it moves: ground truth for localisation, a robot's ``base_pose_ground_truth``.
Its tags, in ROS 2's names and ROS 1's:

* ``body_name`` / ``bodyName``: the link (required);
* ``frame_name`` / ``frameName``: ``world`` (the default) or ``map`` give the pose in the
  world, under that frame id; a link of the robot gives the pose relative to that link, and
  the twist as the difference of the two links' velocities turned into its frame;
* ``xyz_offsets`` / ``xyzOffsets`` and ``rpy_offsets`` / ``rpyOffsets``: added to the position,
  and turned before the orientation, as the plugin applies them;
* ``gaussian_noise`` / ``gaussianNoise``: the standard deviation of a Gaussian noise added to
  every twist component (not to the pose), and the covariance diagonals it is the root of;
* ``update_rate`` / ``updateRate``: Hz of simulated time; 0 or none: every step (at most
  :data:`~sim_node.core.stepping.odometers.MAX_ODOMETER_RATE_HZ`);
* the topic: ``odom`` renamed by ``<ros><remapping>odom:=...`` under ``<ros><namespace>``, or
  ROS 1's ``topicName`` under ``robotNamespace``; a spawn's namespace goes before it as before
  every declared topic.

The link gets a site ``<name>_p3d`` at its origin; the stepping loop samples it at its rate
(:mod:`sim_node.core.stepping.odometers`). A tag with a value that cannot be meant is named in
a warning and its default used; a plugin with no body the model has is left out, said.
"""

import logging
import math
from xml.etree import ElementTree as ET

import mujoco

from . import sensor_tags
from ..base import quat
from ..base.records import DeclaredOdometer

log = logging.getLogger(__name__)

LIBRARY = 'gazebo_ros_p3d'
#: Frame names that mean the world.
WORLD_FRAMES = ('world', 'map', '/world', '/map')


def plugins(extensions: list) -> list:
    """Return the P3D plugin elements among a URDF's ``<gazebo>`` extensions."""
    return [el for ext in extensions if ext.tag == 'gazebo' for el in ext.iter()
            if LIBRARY in (el.get('filename') or el.get('plugin') or '')]


def add(spec: mujoco.MjSpec, extensions: list, declared: list) -> list:
    """Add a site for each P3D plugin of `extensions` and its record to `declared`; say what."""
    done = []
    bodies = {b.name for b in spec.bodies if b.name}
    for plugin in plugins(extensions):
        label = plugin.get('name') or 'p3d'
        body = _text(plugin, 'body_name', 'bodyName')
        if body not in bodies:
            log.warning('URDF P3D plugin %r: body %r is not a link of the model; left out',
                        label, body)
            continue
        name, k = f'{label}_p3d', 1
        while spec.site(name) is not None:
            k += 1
            name = f'{label}_{k}_p3d'
        spec.body(body).add_site(name=name)
        declared.append(read(plugin, name, body, bodies))
        done.append(f'P3D odometry {label!r} of {body!r}')
    return done


def read(plugin: ET.Element, site: str, body: str, links) -> DeclaredOdometer:
    """Read one P3D plugin's tags (see the module) for its site on `body`."""
    label = plugin.get('name') or site

    def warn(tag: str, value, why: str, default: str) -> None:
        log.warning('URDF P3D plugin %r: %s %r %s; %s is used', label, tag, value, why,
                    default)
    frame = _text(plugin, 'frame_name', 'frameName') or 'world'
    reference = ''
    if frame not in WORLD_FRAMES:
        if frame in links:
            reference = frame
        else:
            warn('frame_name', frame, 'is neither world, map nor a link of the model',
                 'world')
            frame = 'world'
    offsets = []
    for tags in (('xyz_offsets', 'xyzOffsets'), ('rpy_offsets', 'rpyOffsets')):
        given = _text(plugin, *tags)
        values = sensor_tags.floats(given, 3)
        if given and values is None:
            warn(tags[0], given, 'is not three finite numbers', '0 0 0')
        offsets.append(values or (0.0, 0.0, 0.0))
    noise = _number(plugin, warn, ('gaussian_noise', 'gaussianNoise'))
    rate = _number(plugin, warn, ('update_rate', 'updateRate'))
    return DeclaredOdometer(
        site=site, body=body, rate_hz=rate, frame=frame.lstrip('/'), reference=reference,
        offset_pos=tuple(offsets[0]),
        offset_quat=tuple(float(v) for v in quat.from_rpy(*offsets[1])),
        noise=noise, topic=_topic(plugin))


def _topic(plugin: ET.Element) -> str:
    """Return the topic as declared, relative names kept relative."""
    topic = sensor_tags.in_namespace(sensor_tags.plugin_namespace(plugin),
                                     sensor_tags.plugin_output(plugin, ('odom', '~/odom'))
                                     or 'odom')
    if not sensor_tags.valid_topic(topic):
        log.warning('URDF P3D plugin %r: topic %r is not a name ROS takes; odom is used',
                    plugin.get('name') or 'p3d', topic)
        return 'odom'
    return topic


def _text(plugin: ET.Element, *tags: str) -> str:
    return next((t.strip() for tag in tags for t in [plugin.findtext(tag)] if t and t.strip()),
                '')


def _number(plugin: ET.Element, warn, tags: tuple) -> float:
    """Return a tag's number >= 0 (0 where none is given, or one that cannot be meant, said)."""
    given = _text(plugin, *tags)
    if not given:
        return 0.0
    try:
        value = float(given)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        warn(tags[0], given, 'is not a finite number >= 0', '0')
        return 0.0
    return value
