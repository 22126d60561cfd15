"""
The topics and point cloud a depth camera's OpenNI Kinect Gazebo plugin names.

Gazebo classic's ``libgazebo_ros_openni_kinect.so`` is the camera plugin the description
packages this project reads use most (16 plugin tags in 9 of example-robot-data's URDFs: Go1's
five depth cameras, Talos's and TIAGo's heads; next come the bumper plugin, 8, and P3D, 4).
Inside a ``<sensor type="depth">``, its tags name each stream's topic, resolved in the
namespace of its ``<cameraName>`` unless absolute, with the plugin's documented defaults:

* ``imageTopicName`` (``image_raw``), ``cameraInfoTopicName`` (``camera_info``): the colour
  image and its camera info;
* ``depthImageTopicName`` (``depth/image_raw``): the depth image (32FC1 metres, as the
  plugin's);
* ``pointCloudTopicName`` (``points``), ``pointCloudCutoff`` (0.4 m) and
  ``pointCloudCutoffMax`` (5 m): the point cloud, published always, NaN outside the cutoffs.

``frameName`` is read with every plugin's (:func:`.sensor_tags.camera`);
``depthImageCameraInfoTopicName`` is not: one camera info is published per camera. A name ROS
refuses or a cutoff that is not a distance is left out with a warning naming the plugin.
"""

from dataclasses import replace
import logging
from xml.etree import ElementTree as ET

from .sensor_tags import plugin_range, valid_topic
from ..base.records import DeclaredCamera

log = logging.getLogger(__name__)

#: tag -> the plugin's default, for each topic it names.
TOPICS = {'imageTopicName': 'image_raw', 'cameraInfoTopicName': 'camera_info',
          'depthImageTopicName': 'depth/image_raw', 'pointCloudTopicName': 'points'}
#: The point cloud's cutoffs (m) when the plugin gives none.
CUTOFFS = (0.4, 5.0)
WARN = 'OpenNI Kinect plugin {plugin!r}: {tag} {value!r} {why}; its default is used'


def plugin_of(sensor: ET.Element):
    """Return the sensor's OpenNI Kinect plugin element, or None."""
    for plugin in sensor.iter('plugin'):
        if 'openni_kinect' in (plugin.get('filename') or '').lower():
            return plugin
    return None


def named(camera: DeclaredCamera, sensor: ET.Element) -> DeclaredCamera:
    """Return `camera` with the topics and cutoffs its OpenNI Kinect plugin names, if any."""
    plugin = plugin_of(sensor)
    if plugin is None:
        return camera
    label = plugin.get('name') or sensor.get('name') or camera.camera

    def warn(tag, value, why):
        log.warning(WARN.format(plugin=label, tag=tag, value=value, why=why))
    base = (plugin.findtext('cameraName') or '').strip().strip('/')
    topics = {}
    for tag, default in TOPICS.items():
        given = (plugin.findtext(tag) or '').strip()
        if given and not valid_topic(given):
            warn(tag, given, 'is not a name ROS takes')
            given = ''
        topic = given or default
        topics[tag] = topic if topic.startswith('/') or not base else f'{base}/{topic}'
    cut = plugin_range(plugin, ('pointCloudCutoff', 'pointCloudCutoffMax'), CUTOFFS,
                       'pointCloudCutoff', warn)
    return replace(camera, topic=camera.topic or base, depth=True, points=True,
                   points_clip=cut, image_topic=topics['imageTopicName'],
                   info_topic=topics['cameraInfoTopicName'],
                   depth_topic=topics['depthImageTopicName'],
                   points_topic=topics['pointCloudTopicName'])
