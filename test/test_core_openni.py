"""
A depth camera as its OpenNI Kinect Gazebo plugin declares it (issue 53, item 4).

The plugin is the camera plugin example-robot-data's URDFs use most (Go1's five depth cameras,
Talos's and TIAGo's heads). FACE is a robot written the way Go1 writes its face camera: a
``<sensor type="depth">`` whose plugin names each stream's topic (absolute), its frame and the
point cloud's cutoffs; PLAIN names only its camera, so the plugin's defaults apply. Before,
both published under ``<cameraName>/...`` names the node made up, the cloud clipped at the
sensor's far plane.
"""

import logging

import pytest
from sim_node.core.base.records import DeclaredCamera
from sim_node.core.models import sources

_INERTIA = '<inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/>'


def robot(plugin_body: str) -> str:
    """Return a one-camera robot whose depth sensor's OpenNI plugin has `plugin_body`."""
    return f"""<robot name="face">
  <link name="world"/>
  <link name="camera_face"><inertial><mass value="0.07"/>{_INERTIA}</inertial></link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="camera_face"/>
    <origin xyz="0 0 1.0"/></joint>
  <link name="camera_optical_face"/>
  <joint name="optical" type="fixed"><parent link="camera_face"/>
    <child link="camera_optical_face"/><origin rpy="-1.5708 0 -1.5708"/></joint>
  <gazebo reference="camera_face">
    <sensor name="camera_face_camera" type="depth"><update_rate>16</update_rate>
      <camera><horizontal_fov>2.094</horizontal_fov>
        <image><width>160</width><height>120</height><format>R8G8B8</format></image>
        <clip><near>0.1</near><far>5</far></clip></camera>
      <plugin filename="libgazebo_ros_openni_kinect.so" name="camera_face_controller">
        {plugin_body}</plugin>
    </sensor>
  </gazebo>
</robot>"""


FACE = robot("""<alwaysOn>true</alwaysOn><updateRate>0.0</updateRate>
        <cameraName>camera_face_ir</cameraName>
        <imageTopicName>/camera_face/color/image_raw</imageTopicName>
        <cameraInfoTopicName>/camera_face/color/camera_info</cameraInfoTopicName>
        <depthImageTopicName>/camera_face/depth/image_raw</depthImageTopicName>
        <pointCloudTopicName>/cam1/point_cloud_face</pointCloudTopicName>
        <frameName>camera_optical_face</frameName>
        <pointCloudCutoff>0.1</pointCloudCutoff><pointCloudCutoffMax>1.5</pointCloudCutoffMax>""")
PLAIN = robot('<cameraName>head_kinect</cameraName>')


def camera(text: str) -> DeclaredCamera:
    (cam,) = [d for d in sources.from_model_text(text).urdf_notes.sensors
              if isinstance(d, DeclaredCamera)]
    return cam


def test_each_stream_goes_where_the_plugin_names_it():
    cam = camera(FACE)
    assert (cam.image_topic, cam.info_topic, cam.depth_topic, cam.points_topic) == (
        '/camera_face/color/image_raw', '/camera_face/color/camera_info',
        '/camera_face/depth/image_raw', '/cam1/point_cloud_face')
    assert cam.frame == 'camera_optical_face'
    assert (cam.depth, cam.points, cam.points_clip, cam.clip) == (True, True, (0.1, 1.5),
                                                                  (0.1, 5.0))


def test_the_plugins_defaults_under_its_camera_name():
    cam = camera(PLAIN)
    assert (cam.image_topic, cam.info_topic, cam.depth_topic, cam.points_topic) == (
        'head_kinect/image_raw', 'head_kinect/camera_info', 'head_kinect/depth/image_raw',
        'head_kinect/points')
    assert cam.points_clip == (0.4, 5.0)


@pytest.mark.parametrize('body, what', [
    ('<cameraName>k</cameraName><pointCloudTopicName>bad name!</pointCloudTopicName>',
     'pointCloudTopicName'),
    ('<cameraName>k</cameraName><pointCloudCutoffMax>nan</pointCloudCutoffMax>',
     'pointCloudCutoffMax'),
    ('<cameraName>k</cameraName><pointCloudCutoff>3</pointCloudCutoff>'
     '<pointCloudCutoffMax>1</pointCloudCutoffMax>', 'pointCloudCutoff'),
])
def test_a_bad_tag_keeps_the_default_with_a_warning_naming_the_plugin(body, what, caplog):
    with caplog.at_level(logging.WARNING, logger='sim_node'):
        cam = camera(robot(body))
    assert cam.points_topic == 'k/points' and cam.points_clip == (0.4, 5.0)
    assert any('camera_face_controller' in r.getMessage() and what in r.getMessage()
               for r in caplog.records), [r.getMessage() for r in caplog.records]
