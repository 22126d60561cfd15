"""
A 10 kHz joint-command flood against the node, side by side with no flood.

The node runs as fast as it can (real_time_factor 0) on the default scene; simulated seconds
per wall second are measured three ways in one run: no flood; a 10 kHz flood to a topic
nobody subscribes (the flooding process's own cost on this machine); the same flood to
`joint_commands`. Run with `make bench` (or this file alone after `. .build/env.sh`).
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
from verdict import verdict  # noqa: E402, I100

FLOOD_HZ = 10_000
PHASE_SEC = 4.0


def _flood(topic: str, stop: threading.Event, sent: list) -> None:
    import rclpy
    from sensor_msgs.msg import JointState
    node = rclpy.create_node(f'flooder_{os.getpid()}')
    pub = node.create_publisher(JointState, topic, 1000)
    msg = JointState(name=['left_elbow'], position=[0.3])
    next_at = time.perf_counter()
    while not stop.is_set():
        msg.position = [0.3 if sent[0] % 2 else -0.3]
        pub.publish(msg)
        sent[0] += 1
        next_at += 1.0 / FLOOD_HZ
        delay = next_at - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    node.destroy_node()


def main() -> None:
    import rclpy
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from sim_node.ros.client import SimClient
    exe = Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / 'node'
    proc = subprocess.Popen([str(exe), '--ros-args', '-p', 'real_time_factor:=0'],
                            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                            start_new_session=True)
    rclpy.init()
    client = SimClient(timeout_sec=60)
    try:
        client.entities()

        def rate(topic=None) -> tuple:
            stop, sent = threading.Event(), [0]
            flooder = None
            if topic:
                flooder = threading.Thread(target=_flood, args=(topic, stop, sent))
                flooder.start()
                time.sleep(1.0)
            s0, t0, w0 = sent[0], client.entity_state('box_a')['stamp'], time.monotonic()
            time.sleep(PHASE_SEC)
            t1, w1 = client.entity_state('box_a')['stamp'], time.monotonic()
            stop.set()
            if flooder:
                flooder.join()
            return (t1 - t0) / (w1 - w0), (sent[0] - s0) / (w1 - w0)

        alone, _ = rate()
        control, hz_c = rate('/nobody_listens')
        flooded, hz = rate('/joint_commands')
        print('\n== Joint-command flood (node at real_time_factor 0, default scene)')
        print(f'  no flood                         {alone:7.1f} x real time')
        print(f'  {hz_c:6.0f} Hz to an unheard topic      {control:7.1f}  ({control / alone:.2f})')
        print(f'  {hz:6.0f} Hz to joint_commands         {flooded:7.1f}  ({flooded / alone:.2f})')
        verdict(flooded / alone >= 0.9, f'node rate under a {hz:.0f} Hz joint-command flood / '
                f'without, {flooded / alone:.2f} (target >= 0.9)')
    finally:
        client.close()
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(10)
        rclpy.try_shutdown()


if __name__ == '__main__':
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    main()
