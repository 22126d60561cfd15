"""
Gazebo's P3D plugin in a URDF: a link's true pose and twist (issue 53, item 4).

TIAGo, PR2 and HyQ (the ROS corpus) declare gazebo_ros_p3d for their ground truth. These
tests hold the samples the stepping loop takes to theory, not to the implementation: a body
in free fall is at ``z0 - g t^2 / 2`` moving at ``-g t``; a link fixed to another is, in that
link's frame, where its joint puts it and does not move, whatever both do in the world; the
offsets move and turn the pose; the noise has the deviation declared; the rate is the
plugin's in simulated time; a tag that cannot be meant is said and its default used.
"""

import logging
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from sim_node.core.base import quat
from sim_node.core.models import p3d, sources
from sim_node.core.stepping.odometers import OdometerSample
from sim_node.core.world import World

EMPTY = str(__import__('pathlib').Path(__file__).resolve().parent.parent / 'scenes' / 'empty.xml')
_I = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
G = 9.81


def robot(*plugins: str) -> str:
    """Return a 1 kg box with a mast fixed 0.3 m ahead of it and 0.2 m up, and P3D plugins."""
    tags = ''.join(f'<gazebo>{p}</gazebo>' for p in plugins)
    return f"""<robot name="probe">
  <link name="base_link"><inertial><mass value="1"/>{_I}</inertial>
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="mast"><inertial><mass value="0.1"/>{_I}</inertial></link>
  <joint name="mast_joint" type="fixed"><parent link="base_link"/><child link="mast"/>
    <origin xyz="0.3 0 0.2"/></joint>{tags}
</robot>"""


def plugin(name: str, body: str, extra: str = '') -> str:
    return (f'<plugin name="{name}" filename="libgazebo_ros_p3d.so">'
            f'<body_name>{body}</body_name>{extra}</plugin>')


def _samples(world: World, site: str) -> list:
    return [s for s in world.take_sensor_samples()
            if isinstance(s, OdometerSample) and s.site == site]


def _spawn(*plugins: str, yaw: float = 0.0, z: float = 20.0) -> World:
    world = World.from_file(EMPTY)
    world.spawn('probe', sources.from_model_text(robot(*plugins)), position=(1.0, 2.0, z),
                quat_wxyz=tuple(quat.from_rpy(0.0, 0.0, yaw)))
    world.take_sensor_samples()
    return world


def test_a_falling_links_ground_truth_is_where_free_fall_puts_it_at_the_plugins_rate():
    world = _spawn(plugin('truth', 'base_link', '<update_rate>50</update_rate>'))
    world.step(round(1.0 / world.timestep))
    got = _samples(world, 'probe/truth_p3d')
    # the first after the first step, then at 0.02, 0.04, ..., 1.0 s of simulated time
    times = np.array([s.time for s in got])
    assert len(got) == 50 + 1
    assert times[1:] == pytest.approx(0.02 * np.arange(1, 51), abs=1e-9)
    last = got[-1]
    t = last.time
    assert last.position == pytest.approx([1.0, 2.0, 20.0 - G * t ** 2 / 2], abs=0.01)
    assert last.linear == pytest.approx([0.0, 0.0, -G * t], abs=0.01)
    assert last.angular == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    state = world.get_entity_state('probe')  # the entity's own account agrees
    assert last.position == pytest.approx(state.position, abs=1e-9)


def test_in_a_links_frame_a_link_fixed_to_it_stays_where_its_joint_puts_it():
    # The base turned 90 degrees and falling: in the world the mast is 0.3 m along +y from
    # the base and falls; in the base's frame it is at (0.3, 0, 0.2) and does not move.
    world = _spawn(plugin('mast_world', 'mast'),
                   plugin('mast_in_base', 'mast', '<frame_name>base_link</frame_name>'),
                   yaw=math.pi / 2)
    world.step(round(0.5 / world.timestep))
    samples = world.take_sensor_samples()
    rel = [s for s in samples if getattr(s, 'site', '') == 'probe/mast_in_base_p3d'][-1]
    abs_ = [s for s in samples if getattr(s, 'site', '') == 'probe/mast_world_p3d'][-1]
    assert rel.position == pytest.approx([0.3, 0.0, 0.2], abs=1e-6)
    assert abs(rel.quat_wxyz[0]) == pytest.approx(1.0, abs=1e-6)
    assert rel.linear == pytest.approx([0, 0, 0], abs=1e-6)
    assert rel.angular == pytest.approx([0, 0, 0], abs=1e-6)
    t = abs_.time
    assert abs_.position == pytest.approx([1.0, 2.3, 20.2 - G * t ** 2 / 2], abs=0.01)
    assert abs_.linear[2] == pytest.approx(-G * t, abs=0.01)
    assert abs(quat.yaw_of(abs_.quat_wxyz)) == pytest.approx(math.pi / 2, abs=1e-6)
    # a plugin without a rate: a sample every step
    assert len([s for s in samples if getattr(s, 'site', '') == 'probe/mast_world_p3d']) == \
        round(0.5 / world.timestep)


def test_offsets_move_and_turn_the_pose_and_the_noise_has_the_declared_deviation():
    world = _spawn(plugin('shifted', 'base_link',
                          '<xyzOffsets>25.7 25.7 0</xyzOffsets><rpyOffsets>0 0 0.5</rpyOffsets>'
                          '<gaussianNoise>0.1</gaussianNoise>'), z=0.11)
    world.step(round(2.0 / world.timestep))  # at rest on the floor, every step a sample
    got = _samples(world, 'probe/shifted_p3d')[-1000:]
    assert got[-1].position == pytest.approx([26.7, 27.7, 0.1], abs=0.01)
    assert quat.yaw_of(got[-1].quat_wxyz) == pytest.approx(0.5, abs=1e-3)
    twist = np.array([np.concatenate([s.linear, s.angular]) for s in got])
    assert np.std(twist, axis=0) == pytest.approx(np.full(6, 0.1), rel=0.1)
    assert np.mean(twist, axis=0) == pytest.approx(np.zeros(6), abs=0.02)
    positions = np.array([s.position for s in got])  # the pose has none
    assert np.ptp(positions, axis=0) == pytest.approx([0, 0, 0], abs=1e-4)


def test_a_plugins_topic_is_read_as_ros_2_and_ros_1_name_it():
    def topic(inner: str) -> str:
        el = ET.fromstring(f'<plugin filename="libgazebo_ros_p3d.so">{inner}</plugin>')
        return p3d.read(el, 'p_p3d', 'base_link', ['base_link']).topic
    assert topic('') == 'odom'
    assert topic('<ros><namespace>demo</namespace></ros>') == 'demo/odom'
    assert topic('<ros><namespace>/demo</namespace>'
                 '<remapping>odom:=ground_truth</remapping></ros>') == '/demo/ground_truth'
    assert topic('<robotNamespace>/hyq</robotNamespace><topicName>ground_truth</topicName>') \
        == '/hyq/ground_truth'
    assert topic('<topicName>/base_pose_ground_truth</topicName>') == '/base_pose_ground_truth'


def test_what_a_plugin_cannot_mean_is_said_and_its_default_used(caplog):
    with caplog.at_level(logging.WARNING):
        world = _spawn(
            plugin('nobody', 'no_such_link'),
            '<plugin name="unnamed" filename="libgazebo_ros_p3d.so"></plugin>',
            plugin('odd', 'base_link', '<frame_name>nowhere</frame_name>'
                   '<xyz_offsets>1 2</xyz_offsets><gaussian_noise>-1</gaussian_noise>'
                   '<update_rate>fast</update_rate><topicName>bad topic!</topicName>'))
    said = '\n'.join(r.getMessage() for r in caplog.records if r.levelno == logging.WARNING)
    assert "'nobody': body 'no_such_link' is not a link" in said
    assert "'unnamed': body '' is not a link" in said
    for what in ("frame_name 'nowhere'", "xyz_offsets '1 2'", "gaussian_noise '-1'",
                 "update_rate 'fast'", "topic 'bad topic!'"):
        assert what in said, what
    decl = world.model_info.odometers['probe/odd_p3d']
    assert (decl.frame, decl.offset_pos, decl.noise, decl.rate_hz, decl.topic) == (
        'world', (0.0, 0.0, 0.0), 0.0, 0.0, 'odom')
    assert set(world.model_info.odometers) == {'probe/odd_p3d'}  # the others left out
    world.step(10)
    assert len(_samples(world, 'probe/odd_p3d')) == 10  # and the world steps
