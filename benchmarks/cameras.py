"""
Camera cost, measured side by side in one run on the default scene.

1. Frames per second of one camera (colour and depth, as the node publishes them) per
   resolution, with the world idle.
2. The stepping loop's steps per second (real_time_factor 0) with one 320x240 camera rendering
   at 10 Hz of wall time (a 10 Hz camera of a world in real time) over the same loop with no
   camera, and with that camera rendering as fast as it can (a 10 Hz camera of simulated time
   when the world runs 40 times faster than real time). Interleaved runs, medians.

3. The node itself (real_time_factor 0): simulated seconds per wall second with its default
   camera and scanner over the same node with both off (``cameras:=[none]``); at 40 times real
   time a 10 Hz camera of simulated time renders as fast as it can, so this is the worst case.

Run with `make bench` (all benchmarks) or `make bench-cameras`.
"""

import os
from pathlib import Path
import signal
import statistics
import subprocess
import sys
import threading
import time

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from sim_node.core.cameras import CameraRig  # noqa: E402
from sim_node.core.config import WorldConfig  # noqa: E402
from sim_node.core.devices.rendering import choose_backend  # noqa: E402
from sim_node.core.loop import SimLoop  # noqa: E402
from sim_node.core.world import World  # noqa: E402
sys.path.insert(0, str(Path(__file__).resolve().parent))
from verdict import verdict  # noqa: E402, I100

SCENE = str(Path(__file__).resolve().parent.parent / 'scenes' / 'default.xml')
RESOLUTIONS = ((160, 120), (320, 240), (640, 480))


def frames_per_sec(width: int, height: int, seconds: float = 3.0) -> float:
    world = World.from_file(SCENE)
    rig = CameraRig(world, width, height)
    rig.capture()  # the first frame uploads the model
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        rig.capture()
        n += 1
    rate = n / (time.perf_counter() - t0)
    rig.close()
    return rate


def loop_steps_per_sec(camera_period: float, seconds: float) -> tuple:
    """Measure a free-running loop's steps/s; camera_period None: no camera, 0: flat out."""
    world = World.from_file(SCENE, WorldConfig(real_time_factor=0))
    loop = SimLoop(world)
    stop = threading.Event()
    frames = [0]

    def camera():
        rig = CameraRig(world, 320, 240)
        rig.capture()
        deadline = time.perf_counter()
        while not stop.is_set():
            rig.capture()
            frames[0] += 1
            deadline += camera_period
            stop.wait(max(0.0, deadline - time.perf_counter()))
        rig.close()

    cam = threading.Thread(target=camera) if camera_period is not None else None
    if cam is not None:
        cam.start()
        time.sleep(0.5)  # the renderer is up before counting
    loop.start()
    time.sleep(0.3)
    s0, t0 = world.step_count, time.perf_counter()
    f0 = frames[0]
    time.sleep(seconds)
    rate = (world.step_count - s0) / (time.perf_counter() - t0)
    fps = (frames[0] - f0) / (time.perf_counter() - t0)
    stop.set()
    loop.stop()
    if cam is not None:
        cam.join()
    return rate, fps


def node_rate(params: list, seconds: float = 4.0) -> tuple:
    """Return (simulated s per wall s, images per wall s) of the node run with `params`."""
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image
    from sim_node.ros.client import SimClient
    exe = Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / 'node'
    proc = subprocess.Popen([str(exe), '--ros-args', '-p', 'real_time_factor:=0',
                             *sum((['-p', p] for p in params), [])],
                            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                            start_new_session=True)
    client = SimClient(timeout_sec=60)
    counter = rclpy.create_node(f'image_counter_{os.getpid()}')
    images = [0]
    counter.create_subscription(Image, 'cameras/overview/image_raw',
                                lambda m: images.__setitem__(0, images[0] + 1),
                                qos_profile_sensor_data)
    try:
        client.entities()
        end = time.monotonic() + 1.0
        while time.monotonic() < end:  # warm up: the renderer starts
            rclpy.spin_once(counter, timeout_sec=0.05)
        i0, t0, w0 = images[0], client.entity_state('box_a')['stamp'], time.monotonic()
        while time.monotonic() - w0 < seconds:
            rclpy.spin_once(counter, timeout_sec=0.05)
        t1, w1 = client.entity_state('box_a')['stamp'], time.monotonic()
        return (t1 - t0) / (w1 - w0), (images[0] - i0) / (w1 - w0)
    finally:
        counter.destroy_node()
        client.close()
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(10)


def node_main(rounds: int = 2) -> None:
    import rclpy
    rclpy.init()
    try:
        off, on, fps = [], [], []
        for _ in range(rounds):
            off.append(node_rate(['cameras:=[none]', 'lidar_sites:=[none]'])[0])
            rate, f = node_rate([])
            on.append(rate)
            fps.append(f)
    finally:
        rclpy.try_shutdown()
    off_m, on_m = statistics.median(off), statistics.median(on)
    print('  node rtf=0, camera and scanner off : '
          f'{off_m:6.1f} x real time')
    print(f'  node rtf=0, default camera + lidar : {on_m:6.1f} x real time '
          f'({statistics.median(fps):.1f} images/s received)')
    print(f'  ratio                              : {on_m / off_m:6.2f}')


def main(seconds: float = 3.0, rounds: int = 3) -> None:
    print(f'[cameras] backend {choose_backend()}, {os.cpu_count()} cores, default scene')
    for w, h in RESOLUTIONS:
        print(f'  {w}x{h} colour+depth: {frames_per_sec(w, h):6.1f} frames/s')
    runs = {'none': [], '10hz': [], 'flat': []}
    fps = {'10hz': [], 'flat': []}
    for _ in range(rounds):
        runs['none'].append(loop_steps_per_sec(None, seconds)[0])
        for key, period in (('10hz', 0.1), ('flat', 0.0)):
            rate, f = loop_steps_per_sec(period, seconds)
            runs[key].append(rate)
            fps[key].append(f)
    none = statistics.median(runs['none'])
    ten = statistics.median(runs['10hz'])
    flat = statistics.median(runs['flat'])
    print(f'  loop rtf=0, no camera              : {none:9.0f} steps/s')
    print(f'  loop rtf=0, one 320x240 at 10 Hz   : {ten:9.0f} steps/s '
          f'({statistics.median(fps["10hz"]):.1f} frames/s)')
    print(f'  ratio 10 Hz camera / none          : {ten / none:9.2f}   (target >= 0.9)')
    verdict(ten / none >= 0.9, f'loop with a 10 Hz camera / without, {ten / none:.2f} '
            '(target >= 0.9)')
    print(f'  loop rtf=0, one 320x240 flat out   : {flat:9.0f} steps/s '
          f'({statistics.median(fps["flat"]):.1f} frames/s)')
    print(f'  ratio flat-out camera / none       : {flat / none:9.2f}')
    if os.environ.get('SIM_PREFIX'):
        node_main()


if __name__ == '__main__':
    main()
