"""
A RealSense as its Gazebo plugin declares it (issue 53, item 4): topics, frames, rates, depth.

HEAD is a robot's head with a D435 written the way the RealSense descriptions write one: four
camera sensors named after the plugin's prefix (``head_front_cameracolor``, ...``ired1``,
...``ired2``, ...``depth``) and one plugin tag naming each stream's topic and optical frame,
the depth range and the point cloud. Before, those cameras published under names the node
made up (``head_front_cameracolor/image_raw`` in ``head_front_cameracolor_optical_frame``).
"""

import logging

from conftest import DEFAULT_SCENE
from msg_adapters import perception as pm
import numpy as np
import pytest
from sim_node.core.models import sources
from sim_node.core.world import World

_INERTIA = '<inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/>'
PREFIX = 'head_front_camera'
FRAMES = ('color', 'depth', 'infra1', 'infra2')


def _sensor(name: str, kind: str, fmt: str, rate: str = '') -> str:
    return f"""
    <sensor name="{PREFIX}{name}" type="{kind}">{rate and f'<update_rate>{rate}</update_rate>'}
      <camera><horizontal_fov>1.211</horizontal_fov>
        <image><width>160</width><height>120</height><format>{fmt}</format></image>
        <clip><near>0.1</near><far>20</far></clip></camera>
    </sensor>"""


def head(plugin_body: str) -> str:
    """Return the robot with the plugin tag's children `plugin_body`."""
    frames = ''.join(f"""
  <link name="{PREFIX}_{f}_optical_frame"/>
  <joint name="{PREFIX}_{f}_optical_joint" type="fixed"><parent link="{PREFIX}_link"/>
    <child link="{PREFIX}_{f}_optical_frame"/><origin rpy="-1.5708 0 -1.5708"/></joint>"""
                     for f in FRAMES)
    return f"""<robot name="head">
  <link name="world"/>
  <link name="{PREFIX}_link"><inertial><mass value="0.07"/>{_INERTIA}</inertial></link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="{PREFIX}_link"/>
    <origin xyz="0 0 1.0"/></joint>{frames}
  <gazebo reference="{PREFIX}_link">{_sensor('color', 'camera', 'RGB_INT8', '30')}
    {_sensor('ired1', 'camera', 'L_INT8', '90')}{_sensor('ired2', 'camera', 'L_INT8', '90')}
    {_sensor('depth', 'depth', 'R8G8B8')}
  </gazebo>
  <gazebo>
    <plugin name="{PREFIX}" filename="librealsense_gazebo_plugin.so">{plugin_body}</plugin>
  </gazebo>
</robot>"""


D435 = head(f"""
      <prefix>{PREFIX}</prefix>
      <depthUpdateRate>15.0</depthUpdateRate><colorUpdateRate>30.0</colorUpdateRate>
      <infraredUpdateRate>90.0</infraredUpdateRate>
      <depthTopicName>depth/image_raw</depthTopicName>
      <depthCameraInfoTopicName>depth/camera_info</depthCameraInfoTopicName>
      <colorTopicName>color/image_raw</colorTopicName>
      <colorCameraInfoTopicName>color/camera_info</colorCameraInfoTopicName>
      <infrared1TopicName>infra1/image_raw</infrared1TopicName>
      <infrared2TopicName>infra2/image_raw</infrared2TopicName>
      <colorOpticalframeName>{PREFIX}_color_optical_frame</colorOpticalframeName>
      <depthOpticalframeName>{PREFIX}_depth_optical_frame</depthOpticalframeName>
      <infrared1OpticalframeName>{PREFIX}_infra1_optical_frame</infrared1OpticalframeName>
      <infrared2OpticalframeName>{PREFIX}_infra2_optical_frame</infrared2OpticalframeName>
      <rangeMinDepth>0.3</rangeMinDepth><rangeMaxDepth>3.0</rangeMaxDepth>
      <pointCloud>true</pointCloud><pointCloudTopicName>depth/color/points</pointCloudTopicName>
      <pointCloudCutoff>0.4</pointCloudCutoff><pointCloudCutoffMax>2.0</pointCloudCutoffMax>""")


def declared(w: World, stream: str):
    return w.model_info.cameras_declared[f'bot/{PREFIX}{stream}']


def test_each_stream_publishes_on_the_topic_and_frame_the_plugin_names():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('bot', sources.from_model_text(D435), position=[0.0, 0.0, 0.0])
    color = declared(w, 'color')
    assert (color.image_topic, color.info_topic, color.frame, color.encoding) == (
        f'{PREFIX}/color/image_raw', f'{PREFIX}/color/camera_info',
        f'bot/{PREFIX}_color_optical_frame', 'rgb8')
    assert (color.rate_hz, color.depth_topic, color.points) == (30.0, '-', False)
    ired2 = declared(w, 'ired2')
    assert (ired2.image_topic, ired2.info_topic, ired2.frame, ired2.encoding) == (
        f'{PREFIX}/infra2/image_raw', f'{PREFIX}/infra2/camera_info',
        f'bot/{PREFIX}_infra2_optical_frame', 'mono8')
    depth = declared(w, 'depth')
    assert (depth.image_topic, depth.depth_topic, depth.info_topic, depth.frame) == (
        '-', f'{PREFIX}/depth/image_raw', f'{PREFIX}/depth/camera_info',
        f'bot/{PREFIX}_depth_optical_frame')
    # the sensor gives no update_rate: the plugin's; its depth in mm within its range
    assert (depth.rate_hz, depth.depth_mm, depth.clip) == (15.0, True, (0.3, 3.0))
    assert (depth.points, depth.points_topic, depth.points_clip) == (
        True, f'{PREFIX}/depth/color/points', (0.4, 2.0))
    # a namespace puts every stream under it, as it puts the robot's other topics
    w.spawn('bot2', sources.from_model_text(D435), position=[1.0, 0.0, 0.0], namespace='two')
    two = w.model_info.cameras_declared[f'bot2/{PREFIX}depth']
    assert (two.depth_topic, two.info_topic, two.points_topic) == (
        f'/two/{PREFIX}/depth/image_raw', f'/two/{PREFIX}/depth/camera_info',
        f'/two/{PREFIX}/depth/color/points')


def test_a_tag_that_names_little_takes_the_descriptions_names():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('bot', sources.from_model_text(head(f'<prefix>{PREFIX}</prefix>')),
            position=[0.0, 0.0, 0.0])
    assert declared(w, 'ired1').image_topic == f'{PREFIX}/infra1/image_raw'
    assert declared(w, 'ired1').frame == f'bot/{PREFIX}_infra1_optical_frame'
    depth = declared(w, 'depth')
    assert (depth.depth_topic, depth.clip, depth.points) == (
        f'{PREFIX}/depth/image_raw', (0.2, 10.0), False)


def test_absurd_values_are_left_out_with_a_warning_naming_them_and_the_robot_spawns(caplog):
    odd = head(f"""<prefix>{PREFIX}</prefix><colorTopicName>bad topic!</colorTopicName>
      <colorOpticalframeName>no_such_link</colorOpticalframeName>
      <depthUpdateRate>fast</depthUpdateRate><rangeMinDepth>-1</rangeMinDepth>
      <rangeMaxDepth>nan</rangeMaxDepth><pointCloudCutoff>3</pointCloudCutoff>
      <pointCloudCutoffMax>1</pointCloudCutoffMax><pointCloud>true</pointCloud>""")
    w = World.from_file(str(DEFAULT_SCENE))
    with caplog.at_level(logging.WARNING):
        w.spawn('bot', sources.from_model_text(odd), position=[0.0, 0.0, 0.0])
    said = ' '.join(r.getMessage() for r in caplog.records if 'RealSense' in r.getMessage())
    for value in ("'bad topic!'", "'no_such_link'", "'fast'", "'-1'", "'nan'", '(3.0, 1.0)'):
        assert value in said, (value, said)
    color, depth = declared(w, 'color'), declared(w, 'depth')
    assert color.image_topic == f'{PREFIX}/color/image_raw'
    assert color.frame == ''  # the node's own optical frame of the camera
    assert (depth.rate_hz, depth.clip, depth.points_clip) == (None, (0.2, 10.0), (0.0, 5.0))


def test_depth_in_millimetres_is_zero_where_nothing_is_seen_within_the_range():
    depth = np.array([[0.25, 0.3, 1.2345], [2.9999, 3.5, np.inf]], np.float32)
    msg = pm.depth_image_mm(depth, 1.5, 'f', (0.3, 3.0))
    assert (msg.encoding, msg.step, msg.header.frame_id) == ('16UC1', 6, 'f')
    mm = np.frombuffer(bytes(msg.data), '<u2').reshape(2, 3)
    np.testing.assert_array_equal(mm, [[0, 300, 1234], [2999, 0, 0]])
    far = pm.depth_image_mm(np.array([[70.0]], np.float32), 0.0, 'f')  # beyond 65.535 m
    assert np.frombuffer(bytes(far.data), '<u2')[0] == 0


@pytest.mark.parametrize('filename', ['librealsense_gazebo_plugin.so', 'RealSenseGzPlugin'])
def test_the_plugin_is_known_by_its_file_name(filename):
    w = World.from_file(str(DEFAULT_SCENE))
    src = D435.replace('librealsense_gazebo_plugin.so', filename)
    w.spawn('bot', sources.from_model_text(src), position=[0.0, 0.0, 0.0])
    assert declared(w, 'color').image_topic == f'{PREFIX}/color/image_raw'
