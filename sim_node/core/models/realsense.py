"""
The RealSense Gazebo plugin's streams: what its tag names, read onto the cameras it drives.

A robot made for Gazebo with an Intel RealSense (the D435 descriptions of PAL Robotics' and
their forks, Gazebo classic and ROS 2) declares four camera sensors on the camera's link,
named ``<prefix>color``, ``<prefix>ired1``, ``<prefix>ired2`` and ``<prefix>depth``, and one
plugin, ``<plugin filename="librealsense_gazebo_plugin.so">`` (any file name with
``realsense`` in it), whose children name each stream:

* ``<prefix>``: the sensors' names begin with it, and every topic is ``<prefix>/<topic>``;
* ``colorTopicName``, ``infrared1TopicName``, ``infrared2TopicName``, ``depthTopicName``:
  each stream's image topic; its camera_info goes beside it (``.../camera_info``), as an
  image_transport camera publisher puts it;
* ``colorOpticalframeName``, ``infrared1OpticalframeName``, ``infrared2OpticalframeName``,
  ``depthOpticalframeName``: the frame each stream's messages name (a link of the robot);
* ``colorUpdateRate``, ``infraredUpdateRate``, ``depthUpdateRate``: the plugin publishes each
  image its sensor draws, so a sensor's own ``<update_rate>`` comes first and these fill in
  for a sensor that gives none;
* ``rangeMinDepth``, ``rangeMaxDepth``: the depth stream is 16UC1 in millimetres, 0 nearer
  or farther than these (and beyond 65.535 m);
* ``pointCloud``, ``pointCloudTopicName``, ``pointCloudCutoff``, ``pointCloudCutoffMax``:
  an organized cloud in the depth stream's frame, NaN outside the cutoffs.

A name the tag leaves out takes the name of the D435 description (``color/image_raw``,
``infra1/image_raw``, ``infra2/image_raw``, ``depth/image_raw``, ``depth/color/points``; the
frames ``<prefix>_color_optical_frame``, ...); depth from 0.2 to 10 m, points to 5 m (the
plugin's own default). A value that is absurd is left out with a warning naming it.
"""

from dataclasses import replace
import logging
from typing import Optional, Sequence
from xml.etree import ElementTree as ET

from .sensor_tags import MAX_RATE_HZ, plugin_number, plugin_range, valid_topic
from ..base.records import DeclaredCamera, NO_TOPIC

log = logging.getLogger(__name__)

#: stream -> (topic tag, frame tag, rate tag, default topic, default frame suffix)
STREAMS = {
    'color': ('colorTopicName', 'colorOpticalframeName', 'colorUpdateRate',
              'color/image_raw', 'color_optical_frame'),
    'ired1': ('infrared1TopicName', 'infrared1OpticalframeName', 'infraredUpdateRate',
              'infra1/image_raw', 'infra1_optical_frame'),
    'ired2': ('infrared2TopicName', 'infrared2OpticalframeName', 'infraredUpdateRate',
              'infra2/image_raw', 'infra2_optical_frame'),
    'depth': ('depthTopicName', 'depthOpticalframeName', 'depthUpdateRate',
              'depth/image_raw', 'depth_optical_frame'),
}
#: Depth range (m) and the points' cutoffs when the tag gives none.
DEPTH_RANGE, POINTS_CUTOFF = (0.2, 10.0), (0.0, 5.0)
WARN = 'RealSense plugin {plugin!r}: {what} {value!r} {why}; {then}'


def plugins(extensions: Sequence[ET.Element]) -> list:
    """Return the RealSense plugin elements of a robot's ``<gazebo>`` extensions."""
    return [p for ext in extensions if ext.tag == 'gazebo' for p in ext.iter('plugin')
            if 'realsense' in (p.get('filename') or '').lower()]


def apply(declared: list, extensions: Sequence[ET.Element], links: Sequence[str]) -> list:
    """
    Return `declared` with the cameras a RealSense plugin drives named as it names them.

    :param declared: the robot's declared sensors (:class:`DeclaredCamera` and others).
    :param links: every link of the robot (the frames a stream may name).
    """
    out = list(declared)
    for plugin in plugins(extensions):
        prefix = (plugin.findtext('prefix') or '').strip()
        name = plugin.get('name') or prefix or 'realsense'

        def warn(what, value, why, then="the plugin's default is used"):
            log.warning(WARN.format(plugin=name, what=what, value=value, why=why, then=then))
        for i, d in enumerate(out):
            stream = _stream(d, prefix)
            if stream is not None:
                out[i] = _named(d, plugin, prefix, stream, links, warn)
    return out


def _stream(d, prefix: str) -> Optional[str]:
    if not isinstance(d, DeclaredCamera):
        return None
    for stream in STREAMS:
        if d.camera == prefix + stream:
            return stream
    return None


def _named(d: DeclaredCamera, plugin: ET.Element, prefix: str, stream: str,
           links: Sequence[str], warn) -> DeclaredCamera:
    topic_tag, frame_tag, rate_tag, topic_default, frame_suffix = STREAMS[stream]
    topic = _text(plugin, topic_tag) or topic_default
    if not valid_topic(topic):
        warn(topic_tag, topic, 'is not a name ROS takes')
        topic = topic_default
    full = f'{prefix}/{topic}' if prefix else topic
    base = full.rsplit('/', 1)[0] if '/' in full else ''
    info = f'{base}/camera_info' if base else 'camera_info'
    frame = _text(plugin, frame_tag) or (f'{prefix}_{frame_suffix}' if prefix else frame_suffix)
    if frame not in links:
        if _text(plugin, frame_tag):
            warn(frame_tag, frame, 'is not a link of the robot', "the sensor's frame is used")
        frame = d.frame
    rate = d.rate_hz
    if rate is None:
        rate = plugin_number(plugin, rate_tag, MAX_RATE_HZ, warn)
    changes = {'topic': base or d.topic, 'info_topic': info, 'frame': frame, 'rate_hz': rate}
    if stream != 'depth':  # an image stream alone: no depth nor points beside it
        return replace(d, image_topic=full, depth_topic=NO_TOPIC, points=False, **changes)
    clip = plugin_range(plugin, ('rangeMinDepth', 'rangeMaxDepth'), DEPTH_RANGE, 'depth range',
                        warn)
    cloud = (_text(plugin, 'pointCloud') or 'false').lower() in ('1', 'true')
    points_topic = _text(plugin, 'pointCloudTopicName') or 'depth/color/points'
    if not valid_topic(points_topic):
        warn('pointCloudTopicName', points_topic, 'is not a name ROS takes')
        points_topic = 'depth/color/points'
    cut = plugin_range(plugin, ('pointCloudCutoff', 'pointCloudCutoffMax'), POINTS_CUTOFF,
                       'point cloud cutoffs', warn)
    return replace(d, image_topic=NO_TOPIC, depth_topic=full, depth_mm=True, clip=clip,
                   depth=True, points=cloud, points_clip=cut,
                   points_topic=f'{prefix}/{points_topic}' if prefix else points_topic,
                   **changes)


def _text(plugin: ET.Element, tag: str) -> str:
    return (plugin.findtext(tag) or '').strip()
