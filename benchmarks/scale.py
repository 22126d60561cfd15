"""
Scale: a thousand moving bodies with /tf at 100 Hz and physics at full speed.

Measured side by side in one run, on scenes from box_scene.py (n free boxes on a floor):

1. The node free-running (installed executable, real_time_factor 0, /tf at 100 Hz,
   joint_states at 50 Hz) over a bare Python mj_step loop on the same scene, interleaved:
   1,000 boxes and the default scene. Node steps/s are read off /clock at both ends of a
   window in which nothing here listens; /tf messages/s off a raw subscription afterwards.
2. /tf cost per transform in the node's code path, against building the same message from
   Python objects; markers for 1,000 bodies (one message per model change).
3. Spawn latency into a running 1,000-body world.
4. Peak RSS of the node process on the default scene, 100 and 1,000 boxes.
5. What the node says when the physics cannot keep real time (1,000 boxes at factor 1).

Run with `make bench` (all benchmarks) or `make bench-scale` (this one, about 2 minutes).
"""

import os
from pathlib import Path
import random
import statistics
import subprocess
import sys
import tempfile
import time

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'benchmarks'))
from box_scene import box_scene  # noqa: E402, I100
from sim_node.core import sources  # noqa: E402
from sim_node.core.config import WorldConfig  # noqa: E402
from sim_node.core.loop import SimLoop  # noqa: E402
from sim_node.core.world import World  # noqa: E402
from verdict import verdict  # noqa: E402, I100

DEFAULT_SCENE = ROOT / 'scenes' / 'default.xml'
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(120, 200)))


def bare_steps_per_sec(path: str, seconds: float) -> float:
    m = mujoco.MjModel.from_xml_path(path)
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        mujoco.mj_step(m, d, 10)
        n += 10
    return n / (time.perf_counter() - t0)


class NodeRun:
    """
    The installed node on a scene, with its default publishers.

    Nothing here listens while its steps are counted (a subscriber in this process would take CPU
    from it): the simulated time is read off /clock once at each end, /tf's rate in a phase of its
    own.
    """

    def __init__(self, scene: str, *params: str):
        import rclpy
        from sim_node.ros.client import SimClient
        exe = Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / 'node'
        args = [str(exe), '--ros-args', '-p', f'scene:={scene}']
        for p in params:
            args += ['-p', p]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                                     start_new_session=True)
        self.node = rclpy.create_node(f'bench_scale_{os.getpid()}')
        self.client = SimClient(timeout_sec=60)
        self.sim_time()  # up and publishing

    def _collect(self, topic: str, seconds: float, first_only: bool = False) -> list:
        """Receive times (and raw messages) of `topic` for `seconds`, or the first one."""
        import rclpy
        from rosgraph_msgs.msg import Clock
        from tf2_msgs.msg import TFMessage
        got = []
        sub = self.node.create_subscription(Clock if topic == '/clock' else TFMessage, topic,
                                            lambda m: got.append((time.perf_counter(), m)),
                                            100, raw=True)
        deadline = time.perf_counter() + (60 if first_only else seconds)
        while time.perf_counter() < deadline and not (first_only and got):
            rclpy.spin_once(self.node, timeout_sec=0.05)
        self.node.destroy_subscription(sub)
        return got

    def sim_time(self) -> tuple:
        """(wall time, simulated time) of the next /clock message."""
        import struct
        wall, raw = self._collect('/clock', 0, first_only=True)[0]
        sec, nsec = struct.unpack_from('<iI', raw, 4)
        return wall, sec + nsec * 1e-9

    def measure(self, seconds: float, dt: float) -> float:
        """Step per second over the next `seconds`."""
        w0, s0 = self.sim_time()
        time.sleep(seconds)
        w1, s1 = self.sim_time()
        return (s1 - s0) / dt / (w1 - w0)

    def tf_rate(self, seconds: float = 2.0) -> float:
        got = self._collect('/tf', seconds)
        return (len(got) - 1) / (got[-1][0] - got[0][0]) if len(got) > 1 else 0.0

    def peak_rss_mib(self) -> float:
        for line in Path(f'/proc/{self.proc.pid}/status').read_text().splitlines():
            if line.startswith('VmHWM:'):
                return int(line.split()[1]) / 1024
        return float('nan')

    def close(self) -> None:
        self.client.close()
        self.node.destroy_node()
        self.proc.send_signal(2)
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def bench_node_vs_bare(label: str, path: str, target: float, rounds: int = 5,
                       seconds: float = 3.0) -> None:
    dt = mujoco.MjModel.from_xml_path(path).opt.timestep
    run = NodeRun(path, 'real_time_factor:=0.0', 'tf_rate_hz:=100.0',
                  'joint_states_rate_hz:=50.0')
    bare, node, tf = [], [], []
    try:
        for _ in range(rounds):  # interleaved, the node paused while the bare loop runs
            run.client.pause()
            bare.append(bare_steps_per_sec(path, seconds))
            run.client.play()
            time.sleep(0.5)
            node.append(run.measure(seconds, dt))
            tf.append(run.tf_rate())
    finally:
        run.close()
    b, n = statistics.median(bare), statistics.median(node)
    per_round = [x / y for x, y in zip(node, bare)]
    print(f'  {label:15s} bare mj_step {b:8.0f} steps/s   node {n:8.0f} steps/s   '
          f'ratio {n / b:5.2f} (target >= {target}; rounds {min(per_round):.2f}-'
          f'{max(per_round):.2f})   /tf {statistics.median(tf):5.1f} msg/s (target 100)')
    verdict(n / b >= target, f'{label}: node / bare mj_step, {n / b:.2f} (target >= {target})')
    verdict(statistics.median(tf) >= 95, f'{label}: /tf at {statistics.median(tf):.1f} msg/s '
            '(target 100, within 5 %)')


def bench_message_costs(n: int = 1000) -> None:
    from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
    from msg_adapters import convert, markers
    from tf2_msgs.msg import TFMessage
    w = World.from_string(box_scene(n))
    w.step(10)
    snap = w.snapshot()
    info = snap.info
    bodies = convert.moving_body_ids(info)
    frames = convert.frame_names(info, 'world')
    template = convert.moving_tf_template(info, bodies, frames)
    reps = 200
    t0 = time.perf_counter()
    for _ in range(reps):
        convert.moving_tf(template, info, snap, bodies)
    ours = (time.perf_counter() - t0) / reps / len(bodies) * 1e6
    t0 = time.perf_counter()
    for _ in range(5):  # the same message from Python objects, as before
        pos, rot = convert.relative_poses(snap, bodies, info.body_parent[bodies])
        TFMessage(transforms=[TransformStamped(
            child_frame_id=info.body_names[b], transform=Transform(
                translation=Vector3(x=p[0], y=p[1], z=p[2]),
                rotation=Quaternion(x=q[1], y=q[2], z=q[3], w=q[0])))
            for b, p, q in zip(bodies, pos, rot)])
    objects = (time.perf_counter() - t0) / 5 / len(bodies) * 1e6
    t0 = time.perf_counter()
    data = markers.markers(info, snap.time, frames)
    marker_ms = (time.perf_counter() - t0) * 1e3
    verdict(ours <= 1.0, f'/tf serialization, {ours:.3f} us per transform (target <= 1 us)')
    print(f'  /tf for {len(bodies)} bodies: {ours:.3f} us per transform (target <= 1 us); '
          f'from Python objects {objects:.1f} us ({objects / ours:.0f}x)')
    print(f'  markers for {len(info.geoms)} geoms on a model change: one message of '
          f'{len(data) / 1024:.0f} KiB in {marker_ms:.1f} ms')


def bench_spawn_into_big_world(n: int = 1000, spawns: int = 20) -> None:
    w = World.from_string(box_scene(n), WorldConfig(real_time_factor=0))
    loop = SimLoop(w)
    loop.start()
    src = sources.primitive('box', [0.03] * 3, mass=0.1)
    lat = []
    try:
        for i in range(spawns):
            t0 = time.perf_counter()
            w.spawn(f'probe_{i}', src, position=[0.1 * i, 0, 2.0])
            lat.append((time.perf_counter() - t0) * 1e3)
    finally:
        loop.stop()
    print(f'  spawn into a running {n}-body world: median {statistics.median(lat):.1f} ms, '
          f'p95 {float(np.percentile(lat, 95)):.1f} ms')


def bench_memory_and_lag(paths: dict) -> None:
    for label, path in paths.items():
        run = NodeRun(path)
        try:
            time.sleep(4.0)
            rss = run.peak_rss_mib()
            lag = run.client.call('get_simulation_state', *_state_srv()).result.error_message
        finally:
            run.close()
        target = '  (target <= 150 MiB)' if label == 'default scene' else ''
        print(f'  node peak RSS, {label:15s}: {rss:6.0f} MiB{target}')
        if label == 'default scene':
            verdict(rss <= 150, f'node peak RSS on the default scene, {rss:.0f} MiB '
                    '(target <= 150 MiB)')
        if lag:
            print(f'    get_simulation_state at real_time_factor 1: "{lag}"')


def _state_srv() -> tuple:
    from simulation_interfaces.srv import GetSimulationState
    return GetSimulationState, GetSimulationState.Request()


def main() -> None:
    import rclpy
    rclpy.init()
    tmp = Path(tempfile.mkdtemp(prefix='sim_scale_'))
    scenes = {}
    for n in (100, 1000):
        scenes[n] = tmp / f'boxes_{n}.xml'
        scenes[n].write_text(box_scene(n))
    try:
        print(f'[scale] mujoco {mujoco.__version__}, {os.cpu_count()} cores')
        print('[scale] node free-running (real_time_factor 0, /tf 100 Hz, joint_states 50 Hz) '
              'over bare mj_step on the same scene, interleaved, median of 5')
        bench_node_vs_bare('1,000 boxes', str(scenes[1000]), 0.8)
        bench_node_vs_bare('default scene', str(DEFAULT_SCENE), 0.95)
        print('[scale] message costs')
        bench_message_costs()
        print('[scale] spawn latency')
        bench_spawn_into_big_world()
        print('[scale] memory (and what a lagging node says)')
        bench_memory_and_lag({'default scene': str(DEFAULT_SCENE),
                              '100 boxes': str(scenes[100]), '1,000 boxes': str(scenes[1000])})
    finally:
        rclpy.try_shutdown()
        for f in tmp.iterdir():
            f.unlink()
        tmp.rmdir()


if __name__ == '__main__':
    main()
