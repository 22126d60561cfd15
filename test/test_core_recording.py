"""The bag writer on its own: what a recording does when the disk refuses it."""

from sim_node.record.bag import BagWriter


def test_a_folder_that_cannot_be_written_ends_the_recording_with_one_message(tmp_path):
    blocker = tmp_path / 'not_a_folder'
    blocker.write_text('a file where the bags should go')
    said = []
    writer = BagWriter(str(blocker / 'bags'), on_error=said.append)
    for i in range(100):
        writer.put('/clock', 'rosgraph_msgs/msg/Clock', bytes(12), i)
    writer.close()
    assert len(said) == 1 and 'the recording stopped' in said[0] and str(blocker) in said[0]
    assert writer.failed and writer.written == 0
    writer.put('/clock', 'rosgraph_msgs/msg/Clock', bytes(12), 101)  # and takes no more


def test_messages_of_an_unknown_type_are_left_out_and_the_rest_recorded(tmp_path):
    from rosbags.rosbag2 import Reader
    writer = BagWriter(str(tmp_path))
    writer.put('/odd', 'no_such_pkg/msg/Thing', b'\x00\x01\x00\x00', 1)
    writer.put('/clock', 'rosgraph_msgs/msg/Clock', b'\x00\x01\x00\x00' + bytes(8), 2)
    writer.close()
    [bag] = [p for p in tmp_path.iterdir() if p.is_dir()]
    with Reader(bag) as reader:
        assert {c.topic for c in reader.connections} == {'/clock'}
