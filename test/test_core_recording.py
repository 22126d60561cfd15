"""
The bag writer on its own: where the bag goes, its splits, what a kill leaves, a refusing disk.

A bag is read back by an independent reader (``mcap``'s) as well as by ``rosbags``, the library
that wrote it, the way ``ros2 bag info`` finds it: from the folder's ``metadata.yaml``.
"""

import shutil
import time

from conftest import mcap_records_until_cut
import pytest
from sim_node.record.bag import BagWriter, FLUSH_SEC, Limits, RecordingError

CLOCK = 'rosgraph_msgs/msg/Clock'


def clock(sec: int, nanosec: int = 0) -> bytes:
    """Return a serialized rosgraph_msgs/Clock (CDR, little endian)."""
    return b'\x00\x01\x00\x00' + sec.to_bytes(4, 'little') + nanosec.to_bytes(4, 'little')


def metadata(bag) -> dict:
    import yaml
    return yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']


def mcap_clock(path) -> list:
    """Return the /clock log times of an MCAP file read as a stream, up to where it ends."""
    return [t for topic, t in mcap_records_until_cut(path) if topic == '/clock']


def test_the_folder_given_is_the_bag_and_a_bag_there_is_never_overwritten(tmp_path):
    from rosbags.rosbag2 import Reader
    bag = tmp_path / 'run1'
    writer = BagWriter(str(bag))
    for i in range(10):
        writer.put('/clock', CLOCK, clock(i), i * 10 ** 9)
    writer.close()
    assert (bag / 'metadata.yaml').is_file()  # `ros2 bag info run1` finds it
    assert metadata(bag)['relative_file_paths'] == ['run1_0.mcap']
    with Reader(bag) as reader:
        assert reader.message_count == 10
    before = {p.name: p.stat().st_mtime_ns for p in bag.iterdir()}
    with pytest.raises(RecordingError, match='is never overwritten'):
        BagWriter(str(bag))
    (tmp_path / 'a_file').write_text('x')
    with pytest.raises(RecordingError, match='exists and is not empty'):
        BagWriter(str(tmp_path / 'a_file'))
    assert {p.name: p.stat().st_mtime_ns for p in bag.iterdir()} == before


def test_a_split_adds_a_file_to_the_one_bag_and_readers_read_it_whole(tmp_path):
    from rosbags.rosbag2 import Reader
    bag = tmp_path / 'split'
    writer = BagWriter(str(bag), Limits(split_seconds=1.0))
    for i in range(40):  # 4 s of simulated time at 10 Hz: four files
        writer.put('/clock', CLOCK, clock(i // 10, (i % 10) * 10 ** 8), i * 10 ** 8)
    writer.close()
    info = metadata(bag)
    assert info['relative_file_paths'] == [f'split_{n}.mcap' for n in range(4)]
    assert sorted(p.name for p in bag.iterdir()) == sorted(info['relative_file_paths']
                                                           + ['metadata.yaml'])
    assert info['message_count'] == 40
    assert [f['message_count'] for f in info['files']] == [10, 10, 10, 10]
    with Reader(bag) as reader:  # the writer's library, through metadata.yaml
        times = [t for _, t, _ in reader.messages()]
    assert times == [i * 10 ** 8 for i in range(40)]
    independent = [t for f in info['relative_file_paths'] for t in mcap_clock(bag / f)]
    assert independent == times  # mcap's own reader, file by file as listed


def test_a_writer_that_falls_behind_drops_what_its_queue_cannot_hold_and_counts_it(
        tmp_path, monkeypatch):
    """The sender never waits for the disk: past the queue's bound a message is dropped."""
    from rosbags.rosbag2 import Reader
    from sim_node.record import bag as bag_module
    monkeypatch.setattr(bag_module, 'QUEUE_LENGTH', 50)
    bag = tmp_path / 'behind'
    writer = BagWriter(str(bag))
    sent = 20_000  # far faster than a writer can write them, one after another
    for i in range(sent):
        writer.put('/clock', CLOCK, clock(i // 1000, (i % 1000) * 10 ** 6), i * 10 ** 6)
    writer.close()
    assert writer.dropped > 0
    assert writer.written + writer.dropped == sent
    assert metadata(bag)['message_count'] == writer.written
    with Reader(bag) as reader:
        times = [t for _, t, _ in reader.messages()]
    assert len(times) == writer.written and times == sorted(set(times))  # in order, no twice


@pytest.mark.slow  # waits for the flushes
def test_what_was_written_a_second_ago_survives_a_kill(tmp_path):
    """The bag as kill -9 leaves it (copied while the writer still runs) reads back."""
    bag = tmp_path / 'live'
    writer = BagWriter(str(bag))
    try:
        for i in range(30):
            writer.put('/clock', CLOCK, clock(i // 10, (i % 10) * 10 ** 8), i * 10 ** 8)
        time.sleep(3 * FLUSH_SEC)  # nothing more comes; the writer is never closed
        shutil.copytree(bag, tmp_path / 'killed')
    finally:
        writer.close()
    killed = tmp_path / 'killed'
    info = metadata(killed)  # metadata.yaml lists the file being written
    assert info['message_count'] == 30
    [path] = info['relative_file_paths']
    assert mcap_clock(killed / path) == [i * 10 ** 8 for i in range(30)]


def test_a_folder_that_cannot_be_written_ends_the_recording_with_one_message(tmp_path):
    blocker = tmp_path / 'not_a_folder'
    blocker.write_text('a file where the bags should go')
    said = []
    writer = BagWriter(str(blocker / 'bags'), on_error=said.append)
    for i in range(100):
        writer.put('/clock', CLOCK, bytes(12), i)
    writer.close()
    assert len(said) == 1 and 'the recording stopped' in said[0] and str(blocker) in said[0]
    assert writer.failed and writer.written == 0
    writer.put('/clock', CLOCK, bytes(12), 101)  # and takes no more


def test_messages_of_an_unknown_type_are_left_out_and_the_rest_recorded(tmp_path):
    from rosbags.rosbag2 import Reader
    writer = BagWriter(str(tmp_path))
    writer.put('/odd', 'no_such_pkg/msg/Thing', b'\x00\x01\x00\x00', 1)
    writer.put('/clock', CLOCK, clock(0), 2)
    writer.close()
    with Reader(tmp_path) as reader:
        assert {c.topic for c in reader.connections} == {'/clock'}
