"""
Benchmarks of the world core, each a ratio measured side by side in this one run.

1. Loop throughput: our stepping loop (as fast as possible, a snapshot consumer at 100 Hz)
   over a bare Python `mj_step` loop on the same scene.
2. Spawn latency into a running world of 10, 100 and 500 bodies (median, 95th percentile),
   and of a whole model file (Gymnasium's humanoid) into the default scene.
3. Real-time tracking at factor 1.0: simulated time over wall time.
4. Gym env.step throughput over Gymnasium's own Pusher-v5 and Reacher-v5 on the same model
   files, and over a MujocoEnv subclass running the same Task code (gym_step.py).
5. Scale: the node free-running on 1,000 boxes and on the default scene over bare mj_step,
   /tf and marker costs, spawn latency at 1,000 bodies, peak RSS (scale.py).
6. A 10 kHz joint-command flood: the node's rate under it over its rate without
   (command_flood.py).
7. Cameras: frames per second per resolution; the loop's steps per second with one 320x240
   camera at 10 Hz over the loop with none (cameras.py).

Run with `make bench`; set SIM_BENCH_RT_SEC to shorten the real-time run (default 20 s).
"""

import os
from pathlib import Path
import statistics
import sys
import threading
import time

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from sim_node.core import sources  # noqa: E402
from sim_node.core.config import WorldConfig  # noqa: E402
from sim_node.core.loop import SimLoop  # noqa: E402
from sim_node.core.world import World  # noqa: E402
from verdict import summary, verdict  # noqa: E402, I100

SCENE = str(Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml')


def bare_steps_per_sec(seconds: float) -> float:
    m = mujoco.MjModel.from_xml_path(SCENE)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    n = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        for _ in range(100):
            mujoco.mj_step(m, d)
        n += 100
    return n / (time.perf_counter() - t0)


def loop_steps_per_sec(seconds: float) -> float:
    world = World.from_file(SCENE, WorldConfig(real_time_factor=0, snapshot_rate_hz=100))
    loop = SimLoop(world)
    stop = threading.Event()
    consumed = [0]

    def consumer():  # a 100 Hz reader, like the node's publishers
        seq = -1
        while not stop.is_set():
            seq, snap = loop.wait_snapshot(seq, 0.1)
            consumed[0] += 1
            time.sleep(0.01)
    th = threading.Thread(target=consumer)
    th.start()
    loop.start()
    s0, t0 = world.step_count, time.perf_counter()
    time.sleep(seconds)
    rate = (world.step_count - s0) / (time.perf_counter() - t0)
    loop.stop()
    stop.set()
    th.join()
    return rate


def bench_throughput(seconds: float = 3.0) -> None:
    rates_bare, rates_loop = [], []
    for _ in range(3):  # interleaved, so drift on the machine hits both alike
        rates_bare.append(bare_steps_per_sec(seconds))
        rates_loop.append(loop_steps_per_sec(seconds))
    bare, ours = statistics.median(rates_bare), statistics.median(rates_loop)
    print(f'[throughput] default scene, 3 interleaved runs of {seconds:.0f} s each (median)')
    print(f'  bare Python mj_step loop : {bare:10.0f} steps/s')
    print(f'  SimLoop rtf=0 + 100 Hz consumer: {ours:10.0f} steps/s')
    print(f'  ratio loop/bare          : {ours / bare:10.2f}   (target >= 0.9)')
    verdict(ours / bare >= 0.9, f'loop / bare mj_step, {ours / bare:.2f} (target >= 0.9)')


def world_with_bodies(n_bodies: int) -> World:
    spec = mujoco.MjSpec.from_file(SCENE)
    extra = n_bodies - 9
    for i in range(max(extra, 0)):
        b = spec.worldbody.add_body(name=f'filler_{i}',
                                    pos=[-2 - (i % 20) * 0.25, (i // 20) * 0.25 - 3, 0.05])
        b.add_freejoint()
        b.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 0.05, 0.05])
    return World(spec, WorldConfig(real_time_factor=1.0))


def bench_spawn(counts=(10, 100, 500), n_spawns: int = 30) -> None:
    print('[spawn latency] spawning a box into a world running in real time')
    src = sources.primitive('box', [0.03] * 3, mass=0.1)
    for count in counts:
        world = world_with_bodies(count)
        loop = SimLoop(world)
        loop.start()
        lat = []
        for i in range(n_spawns):
            t0 = time.perf_counter()
            world.spawn(f'probe_{i}', src, position=[2 + (i % 10) * 0.1, (i // 10) * 0.1, 1])
            lat.append((time.perf_counter() - t0) * 1e3)
        loop.stop()
        nb = world.model_info.body_names.__len__() - n_spawns
        print(f'  {nb:4d} bodies: median {statistics.median(lat):6.1f} ms, '
              f'p95 {float(np.percentile(lat, 95)):6.1f} ms   (target < 50 ms at 100)')
        if nb == 100:
            p95 = float(np.percentile(lat, 95))
            verdict(p95 < 50, f'spawn into a 100-body world, p95 {p95:.1f} ms (target < 50 ms)')


def bench_spawn_model(model: str = 'humanoid', n_spawns: int = 10) -> None:
    """
    Time the spawn of a whole standalone model file.

    (Gymnasium's humanoid, 13 bodies, 17 motors) spawned into the default scene running in real
    time, then deleted, n times.
    """
    import gymnasium
    path = os.path.join(os.path.dirname(gymnasium.__file__), 'envs', 'mujoco', 'assets',
                        f'{model}.xml')
    world = World.from_file(SCENE, WorldConfig(real_time_factor=1.0))
    loop = SimLoop(world)
    loop.start()
    parse, spawn = [], []
    for _ in range(n_spawns):
        t0 = time.perf_counter()
        src = sources.from_file(path)
        t1 = time.perf_counter()
        world.spawn(model, src, position=[2.5, 2.5, 1.5])
        t2 = time.perf_counter()
        world.delete(model)
        parse.append((t1 - t0) * 1e3)
        spawn.append((t2 - t1) * 1e3)
    loop.stop()
    print(f'[spawn a model file] Gymnasium {model}.xml into the running default scene, '
          f'{n_spawns} times')
    print(f'  parse and check (outside the world lock): median '
          f'{statistics.median(parse):6.1f} ms; spawn: median {statistics.median(spawn):6.1f} '
          f'ms, p95 {float(np.percentile(spawn, 95)):6.1f} ms')


def bench_realtime(seconds: float) -> None:
    world = World.from_file(SCENE, WorldConfig(real_time_factor=1.0))
    loop = SimLoop(world)
    loop.start()
    time.sleep(0.5)
    s0, w0 = world.time, time.perf_counter()
    time.sleep(seconds)
    ratio = (world.time - s0) / (time.perf_counter() - w0)
    loop.stop()
    print(f'[real time] factor 1.0 over {seconds:.0f} s: sim/wall = {ratio:.4f} '
          f'(error {abs(ratio - 1) * 100:.2f} %, target within 0.5 %)')
    verdict(abs(ratio - 1) <= 0.005, f'real-time factor 1.0 tracked to '
            f'{abs(ratio - 1) * 100:.2f} % (target within 0.5 %)')


def main() -> None:
    print(f'mujoco {mujoco.__version__}, {os.cpu_count()} cores')
    bench_throughput()
    bench_spawn()
    bench_spawn_model()
    bench_realtime(float(os.environ.get('SIM_BENCH_RT_SEC', '20')))
    import gym_step
    gym_step.main()
    import scale
    scale.main()
    import command_flood
    command_flood.main()
    import cameras
    cameras.main()
    summary()


if __name__ == '__main__':
    main()
