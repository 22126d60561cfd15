"""
Recording runs as rosbag2 bags, read back with independent readers (``mcap``, ``rosbags``).

A node records a run with a spawn, a FollowJointTrajectory goal and its camera; the bag holds
every topic with its type, log times that are the simulation's, latched topics marked
transient local. SIGTERM closes it; after kill -9 its MCAP file still reads up to the last
chunk; bags split by simulated time; a cap ends the recording with one clear message. A
session records with no ROS at all.
"""

import os
from pathlib import Path
import signal
import time

from conftest import DEFAULT_SCENE, NodeProcess, wait_for


def mcap_messages(path: Path) -> list:
    """Every (topic, schema name, log time ns, data) of a bag's MCAP files, by mcap's reader."""
    from mcap.reader import make_reader
    out = []
    for f in sorted(path.glob('*.mcap')):
        with open(f, 'rb') as stream:
            for schema, channel, message in make_reader(stream).iter_messages():
                out.append((channel.topic, schema.name, message.log_time, message.data))
    return out


def mcap_records_until_cut(path: Path) -> list:
    """Every (topic, log time) of an MCAP file read as a stream, up to where it was cut."""
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader
    channels, out = {}, []
    with open(path, 'rb') as stream:
        try:
            for record in StreamReader(stream).records:
                if isinstance(record, Channel):
                    channels[record.id] = record.topic
                elif isinstance(record, Message):
                    out.append((channels[record.channel_id], record.log_time))
        except Exception:  # noqa: B902 (the cut: a record torn in half)
            pass
    return out


def bags(folder: Path) -> list:
    return sorted(p for p in folder.iterdir() if p.is_dir())


def test_a_recorded_run_reads_back_with_its_topics_types_and_sim_time(rclpy_context, tmp_path):
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient
    from rosbags.rosbag2 import Reader
    from sim_node.ros.client import SimClient
    from sim_node.ros.trajectories import duration
    from trajectory_msgs.msg import JointTrajectoryPoint
    folder = tmp_path / 'run'
    node = NodeProcess(f'record:={folder}', 'record_cameras:=true', 'camera_rate_hz:=5.0',
                       namespace='/rec')
    sim = SimClient(namespace='/rec', timeout_sec=30)
    try:
        sim.spawn('crate', uri='box', position=(0.75, 0.3, 1.0))
        client = ActionClient(sim.node, FollowJointTrajectory,
                              '/rec/robot/follow_joint_trajectory')
        assert client.wait_for_server(timeout_sec=15)
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = ['left_elbow']
        goal.trajectory.points = [JointTrajectoryPoint(positions=[0.4],
                                                       time_from_start=duration(1.0))]
        client.send_goal_async(goal)
        sim.spin_for(3.0)
        client.destroy()
    finally:
        sim.close()
        node.proc.send_signal(signal.SIGTERM)
        assert node.proc.wait(20) == 0, node.output()
    [bag] = bags(folder)
    assert (bag / 'metadata.yaml').is_file()  # closed properly
    with Reader(bag) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        durability = {c.topic: c.ext.offered_qos_profiles[0].durability.name
                      for c in reader.connections}
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert types['/tf'] == 'tf2_msgs/msg/TFMessage'  # absolute names stay absolute
    assert types['/clock'] == 'rosgraph_msgs/msg/Clock'
    assert types['/rec/joint_states'] == 'sensor_msgs/msg/JointState'
    assert types['/rec/robot/controller_state'] == \
        'control_msgs/msg/JointTrajectoryControllerState'
    assert types['/rec/cameras/overview/image_raw'] == 'sensor_msgs/msg/Image'
    assert durability['/tf_static'] == durability['/rec/robot/robot_description'] == \
        'TRANSIENT_LOCAL'
    assert durability['/tf'] == 'VOLATILE'
    assert counts['/tf'] > 100 and counts['/rec/cameras/overview/image_raw'] >= 5
    # the independent MCAP reader sees the same messages; log time is simulation time
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    messages = mcap_messages(bag)
    assert len(messages) == sum(counts.values())
    states = [(t, deserialize_message(d, JointState)) for topic, _, t, d in messages
              if topic == '/rec/joint_states']
    for log_time, msg in states[:50]:
        assert log_time == msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
    elbow = [m.position[list(m.name).index('left_elbow')] for _, m in states]
    assert max(elbow) > 0.3  # the trajectory is in it


def test_after_kill_9_the_mcap_file_reads_up_to_its_last_chunk(tmp_path):
    folder = tmp_path / 'killed'
    node = NodeProcess(f'record:={folder}', 'cameras:=[none]', namespace='/killed')
    wait_for(lambda: folder.exists() and bags(folder)
             and any(f.stat().st_size > 400_000 for f in bags(folder)[0].glob('*.mcap')),
             timeout=60, interval=0.2)
    node.proc.send_signal(signal.SIGKILL)
    node.proc.wait(10)
    [bag] = bags(folder)
    assert not (bag / 'metadata.yaml').exists()  # never closed
    [mcap_file] = bag.glob('*.mcap')
    messages = mcap_records_until_cut(mcap_file)
    assert len(messages) > 100
    assert {'/tf', '/killed/joint_states'} <= {m[0] for m in messages}
    from sim_node.record.replay import summary  # and the replay tool says what it holds
    text = summary(folder)
    assert 'not closed (no metadata.yaml)' in text and '/killed/joint_states' in text


def test_bags_split_by_simulated_time(tmp_path):
    from rosbags.rosbag2 import Reader
    folder = tmp_path / 'split'
    node = NodeProcess(f'record:={folder}', 'cameras:=[none]', 'record_split_s:=1.0',
                       namespace='/split')
    wait_for(lambda: folder.exists() and len(bags(folder)) >= 4, timeout=60, interval=0.2)
    node.proc.send_signal(signal.SIGINT)
    assert node.proc.wait(20) == 0
    found = sorted(bags(folder), key=lambda p: int(p.name.rsplit('_', 1)[1]))
    starts = []
    for bag in found:
        with Reader(bag) as reader:  # each opens
            clock = [t for c, t, _ in reader.messages() if c.topic == '/clock']
            assert not clock or clock[-1] - clock[0] <= 1.0e9  # a second of /clock each
            assert '/tf_static' in {c.topic for c in reader.connections}  # latched: in each
            assert '/split/_sim_instances' not in {c.topic for c in reader.connections}
            starts.append(reader.start_time)
    assert starts == sorted(starts)


def test_a_size_cap_ends_the_recording_once_with_bags_that_open(tmp_path):
    from rosbags.rosbag2 import Reader
    folder = tmp_path / 'capped'
    node = NodeProcess(f'record:={folder}', 'cameras:=[none]', 'real_time_factor:=0.0',
                       'record_max_mb:=2.0', namespace='/capped')
    wait_for(lambda: 'record_max_mb' in node.output(), timeout=60, interval=0.2)
    time.sleep(0.5)
    node.proc.send_signal(signal.SIGINT)
    assert node.proc.wait(20) == 0
    total = 0
    for bag in bags(folder):
        with Reader(bag) as reader:
            assert reader.message_count > 0
        total += sum(f.stat().st_size for f in bag.glob('*.mcap'))
    assert total < 3 * 2 ** 20
    assert node.output().count('the recording reached record_max_mb') == 1


def test_a_session_records_without_ros(tmp_path):
    from rosbags.rosbag2 import Reader
    from sim_node.core.config import WorldConfig
    from sim_node.record.session import SessionRecorder
    from sim_node.session import Session
    with Session() as session:
        recorder = SessionRecorder(session, str(tmp_path / 'own'), rate_hz=50)
        session.load_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=0))
        session.pause()
        for _ in range(10):
            session.step(50)  # 1 s of simulated time in all
            time.sleep(0.05)
        recorder.close()
    [bag] = bags(tmp_path / 'own')
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert set(counts) == {'/clock', '/tf', '/joint_states'}
    assert counts['/clock'] >= 5


def test_the_replay_tool_summarises_a_bag(tmp_path):
    import subprocess
    import sys
    from sim_node.core.config import WorldConfig
    from sim_node.record.session import SessionRecorder
    from sim_node.session import Session
    with Session() as session, SessionRecorder(session, str(tmp_path / 'r')):
        session.load_file(str(DEFAULT_SCENE), WorldConfig(real_time_factor=0))
        session.pause()
        session.step(100)
        time.sleep(0.3)
    out = subprocess.run([sys.executable, '-m', 'sim_node.record.replay', str(tmp_path / 'r'),
                          '--echo', '/clock'], capture_output=True, text=True,
                         env=dict(os.environ), timeout=60)
    assert out.returncode == 0, out.stderr
    assert '/joint_states' in out.stdout and 'sensor_msgs/msg/JointState' in out.stdout
    assert 'first /clock at' in out.stdout
