"""Joint commands coalesced from their serialized form: the newest per joint, nothing else lost."""

from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from sim_node.ros.commands.command_drain import coalesce, joint_names


def wire(names, frame='', value=1.0) -> bytes:
    msg = JointState(name=names, position=[value] * len(names))
    msg.header.frame_id = frame
    return serialize_message(msg)


def test_joint_names_are_read_from_the_bytes_for_any_alignment():
    for names in (['a'], ['ab', 'abc', 'abcd', 'abcde'], [], ['\u00fc', 'x' * 7],
                  [f'arm/joint_{i}' for i in range(40)]):
        for frame in ('', 'f', 'fr', 'fra', 'fram'):
            assert joint_names(wire(names, frame)) == tuple(n.encode() for n in names)


def test_coalesce_keeps_the_newest_command_per_joint_in_order():
    a1, b1, ab, a2 = wire(['a'], value=1), wire(['b'], value=1), wire(['a', 'b']), wire(['a'])
    assert coalesce([a1, b1, a2]) == [b1, a2]
    assert coalesce([a1, ab, a2]) == [ab, a2]  # ab still carries the newest b
    assert coalesce([ab, a2, b1]) == [a2, b1]
    assert coalesce([]) == []


def test_unreadable_or_nameless_messages_are_kept_for_the_node_to_refuse():
    broken, empty = b'\x00\x01\x00\x00\x01', wire([])
    assert coalesce([broken, empty, wire(['a'])]) == [broken, empty, wire(['a'])]
