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
from sim_node.core import quat, sources
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
    ids = {n: b for b, n in enumerate(info.body_names)}
    for t in msg.transforms:
        b, parent = ids[t.child_frame_id], t.header.frame_id
        p = ids[parent] if parent != 'world' else 0
        tr, r = t.transform.translation, t.transform.rotation
        pos, q = quat.from_frame(snap.body_xpos[p], snap.body_xquat_wxyz[p],
                                 np.array([tr.x, tr.y, tr.z]), np.array([r.w, r.x, r.y, r.z]))
        np.testing.assert_allclose(pos, snap.body_xpos[b], atol=1e-12)
        assert abs(abs(np.dot(q, snap.body_xquat_wxyz[b])) - 1) < 1e-12
    assert {'ant', 'ant/aux_1', 'box_a', 'left_link1'} <= {t.child_frame_id
                                                           for t in msg.transforms}
