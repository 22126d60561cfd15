"""
Recording runs as rosbag2 bags, read back with independent readers (``mcap``, ``rosbags``).

A node records a run with a spawn, a FollowJointTrajectory goal and its camera into the bag
``record`` names (the folder is the bag, as ``ros2 bag record -o`` makes it); the bag holds
every topic with its type, log times that are the simulation's, latched topics marked
transient local. SIGTERM closes it; after kill -9 it keeps all but its last second; splits by
simulated time are files of the one bag; a cap ends the recording with one clear message; a
bag already there is refused, never overwritten. A session records with no ROS at all.
"""

import os
from pathlib import Path
import signal
import time

from conftest import action_client, DEFAULT_SCENE, mcap_records_until_cut, NodeProcess, wait_for


def listed_files(bag: Path) -> list:
    """Return the files the bag's metadata.yaml lists, in order (as ros2 bag reads them)."""
    import yaml
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())
    return [bag / f for f in info['rosbag2_bagfile_information']['relative_file_paths']]


def mcap_messages_of(path: Path) -> list:
    """Every (topic, schema name, log time ns, data) of one MCAP file, by mcap's reader."""
    from mcap.reader import make_reader
    with open(path, 'rb') as stream:
        return [(channel.topic, schema.name, message.log_time, message.data)
                for schema, channel, message in make_reader(stream).iter_messages()]


def mcap_messages(bag: Path) -> list:
    """Every message of a bag's files as its metadata.yaml lists them, by mcap's reader."""
    return [m for f in listed_files(bag) for m in mcap_messages_of(f)]


def test_a_recorded_run_reads_back_with_its_topics_types_and_sim_time(rclpy_context, tmp_path):
    from control_msgs.action import FollowJointTrajectory
    from rosbags.rosbag2 import Reader
    from sim_node.ros.client import SimClient
    from sim_node.ros.commands.trajectories import duration
    from trajectory_msgs.msg import JointTrajectoryPoint
    folder = tmp_path / 'run'
    node = NodeProcess(f'record:={folder}', 'record_cameras:=true', 'camera_rate_hz:=5.0',
                       namespace='/rec')
    sim = SimClient(namespace='/rec', timeout_sec=30)
    try:
        sim.spawn('crate', uri='box', position=(0.75, 0.3, 1.0))
        client = action_client(sim.node, FollowJointTrajectory,
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
    bag = folder  # the folder record names is the bag
    assert sorted(p.name for p in bag.iterdir()) == ['metadata.yaml', 'run_0.mcap']  # closed
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


def test_after_kill_9_the_bag_keeps_all_but_its_last_second(tmp_path, watcher):
    """Killed 3 s after it started: at least 2 s of /clock read back, as the bag lists them."""
    folder = tmp_path / 'killed'
    node = NodeProcess(f'record:={folder}', 'cameras:=[none]', namespace='/killed')
    first = wait_for(watcher.latest_clock, timeout=30)
    wait_for(lambda: (watcher.latest_clock() or 0) >= first + 3.0, timeout=30)
    node.proc.send_signal(signal.SIGKILL)
    node.proc.wait(10)
    records = [r for f in listed_files(folder) for r in mcap_records_until_cut(f)]
    clock = [t for topic, t in records if topic == '/clock']
    assert clock and (clock[-1] - clock[0]) / 1e9 >= 2.0, len(clock)
    assert {'/tf', '/killed/joint_states'} <= {topic for topic, _ in records}
    from sim_node.record.replay import summary  # and the replay tool says what it holds
    text = summary(folder)
    assert 'not closed' in text and '/killed/joint_states' in text


def test_bags_split_by_simulated_time(tmp_path):
    from rosbags.rosbag2 import Reader
    folder = tmp_path / 'split'
    node = NodeProcess(f'record:={folder}', 'cameras:=[none]', 'record_split_s:=1.0',
                       namespace='/split')
    wait_for(lambda: len(list(folder.glob('*.mcap'))) >= 3, timeout=60, interval=0.2)
    node.proc.send_signal(signal.SIGINT)
    assert node.proc.wait(20) == 0
    files = listed_files(folder)  # one bag, its files listed in its one metadata.yaml
    assert [f.name for f in files] == [f'split_{n}.mcap' for n in range(len(files))]
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [f.name for f in files] + ['metadata.yaml'])
    starts = []
    for f in files:  # each file by mcap's own reader: a second of /clock each, latched in each
        messages = [(topic, t) for topic, _, t, _ in mcap_messages_of(f)]
        clock = [t for topic, t in messages if topic == '/clock']
        assert not clock or clock[-1] - clock[0] <= 1.0e9
        assert '/tf_static' in {topic for topic, _ in messages}
        assert '/split/_sim_instances' not in {topic for topic, _ in messages}
        starts.append(min(t for _, t in messages))
    assert starts == sorted(starts)
    with Reader(folder) as reader:  # and as one bag, all of it
        assert reader.message_count == sum(len(mcap_messages_of(f)) for f in files)


def test_a_bag_already_there_is_refused_and_kept(tmp_path):
    bag = tmp_path / 'earlier'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('an earlier run')
    node = NodeProcess(f'record:={bag}', 'cameras:=[none]', namespace='/earlier')
    assert node.proc.wait(30) == 2
    assert 'cannot start' in node.output() and 'is never overwritten' in node.output()
    assert [p.name for p in bag.iterdir()] == ['metadata.yaml']
    assert (bag / 'metadata.yaml').read_text() == 'an earlier run'


def test_a_size_cap_ends_the_recording_once_with_bags_that_open(tmp_path):
    from rosbags.rosbag2 import Reader
    folder = tmp_path / 'capped'
    node = NodeProcess(f'record:={folder}', 'cameras:=[none]', 'real_time_factor:=0.0',
                       'record_max_mb:=2.0', namespace='/capped')
    wait_for(lambda: 'record_max_mb' in node.output(), timeout=60, interval=0.2)
    time.sleep(0.5)
    node.proc.send_signal(signal.SIGINT)
    assert node.proc.wait(20) == 0
    with Reader(folder) as reader:
        assert reader.message_count > 0
    assert sum(f.stat().st_size for f in listed_files(folder)) < 3 * 2 ** 20
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
    with Reader(tmp_path / 'own') as reader:
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
