"""
/tf is written as bytes from numpy arrays.

Read back by rclpy's own deserializer, it has rclpy's layout, one stamp, and composes back into the
world's poses.
"""

import os

from conftest import DEFAULT_SCENE
import gymnasium
from msg_adapters import convert
import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from sim_node.core.base import quat
from sim_node.core.models import sources
from sim_node.core.world import World
from tf2_msgs.msg import TFMessage

ANT = os.path.join(os.path.dirname(gymnasium.__file__), 'envs', 'mujoco', 'assets', 'ant.xml')


def test_published_tf_bytes_are_the_worlds_poses():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('ant', sources.from_file(ANT), position=[2.5, 2.5, 1.0])
    w.step(123)
    snap = w.snapshot()
    info = snap.info
    bodies = convert.moving_body_ids(info)
    template = convert.moving_tf_template(info, bodies, convert.frame_names(info, 'world'))
    data = convert.moving_tf(template, info, snap, bodies)
    msg = deserialize_message(data, TFMessage)
    # The same length as rclpy's own serialization (padding bytes are unspecified on the wire).
    assert len(serialize_message(msg)) == len(data)
    assert len(msg.transforms) == len(bodies)
    stamps = {(t.header.stamp.sec, t.header.stamp.nanosec) for t in msg.transforms}
    assert stamps == {(0, int(round(snap.time * 1e9)))}
    ids = {n: b for b, n in enumerate(convert.frame_names(info, 'world'))}
    # A robot's links hang from its root body's own frame (the identity from the root's).
    ids.update({alias: b for b, alias in enumerate(info.body_alias) if alias})
    for t in msg.transforms:
        b, p = ids[t.child_frame_id], ids[t.header.frame_id]
        tr, r = t.transform.translation, t.transform.rotation
        pos, q = quat.from_frame(snap.body_xpos[p], snap.body_xquat_wxyz[p],
                                 np.array([tr.x, tr.y, tr.z]), np.array([r.w, r.x, r.y, r.z]))
        np.testing.assert_allclose(pos, snap.body_xpos[b], atol=1e-12)
        assert abs(abs(np.dot(q, snap.body_xquat_wxyz[b])) - 1) < 1e-12
    assert {'ant', 'ant/aux_1', 'box_a', 'robot/left_link1'} <= {t.child_frame_id
                                                                 for t in msg.transforms}


# base_link -(revolute)- link1 -(fixed)- tool0, as robot_state_publisher would see it.
ARM_URDF = """<robot name="arm">
  <link name="base_link"><visual><geometry><box size=".1 .1 .1"/></geometry></visual>
    <inertial><mass value="1"/><inertia ixx=".01" iyy=".01" izz=".01" ixy="0" ixz="0"
    iyz="0"/></inertial></link>
  <link name="link1"><inertial><mass value=".5"/><inertia ixx=".01" iyy=".01" izz=".01"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tool0"><inertial><mass value=".1"/><inertia ixx=".001" iyy=".001" izz=".001"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base_link"/><child link="link1"/>
    <origin xyz="0 0 .1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10"
    velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="link1"/><child link="tool0"/>
    <origin xyz=".2 0 0"/></joint>
</robot>"""


def test_one_frame_rule_and_urdf_links_named_as_robot_state_publisher_names_them():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('arm', sources.from_model_text(ARM_URDF), position=[1.5, -1.5, 0.0])
    w.step(5)
    snap = w.snapshot()
    info = snap.info
    prefix = 'r2/'
    frames = convert.frame_names(info, 'world', prefix)
    bodies = convert.moving_body_ids(info)
    moving = deserialize_message(convert.moving_tf(
        convert.moving_tf_template(info, bodies, frames, prefix), info, snap, bodies), TFMessage)
    static = convert.static_transforms(info, snap.time, frames, prefix)
    edges = [(t.header.frame_id, t.child_frame_id)
             for t in list(moving.transforms) + list(static.transforms)]
    # A tree: every frame has exactly one parent.
    children = [c for _, c in edges]
    assert len(children) == len(set(children))
    # Scene robot links are <entity>/<body> too, like spawned ones, and hang from the root
    # body's own frame <entity>/<root> (the root link of the robot's description).
    assert ('r2/robot/robot', 'r2/robot/left_link1') in edges
    assert ('r2/robot', 'r2/robot/robot') in edges
    # With frame_prefix:=r2/arm/, robot_state_publisher publishes exactly these link frames.
    assert {('r2/arm/base_link', 'r2/arm/link1'), ('r2/arm/link1', 'r2/arm/tool0')} <= set(edges)
    assert ('r2/world', 'r2/arm') in edges and ('r2/arm', 'r2/arm/base_link') in edges
    alias = next(t for t in static.transforms if t.child_frame_id == 'r2/arm/base_link')
    r = alias.transform.rotation
    assert (r.w, r.x, r.y, r.z) == (1.0, 0.0, 0.0, 0.0)
