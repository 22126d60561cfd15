"""
Recording: what writing the run into a bag costs the loop, and how much it writes.

A node on the default scene at real_time_factor 0 (as fast as it goes): simulated seconds per
wall second from /clock without recording, then with ``record`` (every topic but images), each
measured twice, alternating, so that the machine's drift falls on both; then the same with the
scene's one camera published, without and with ``record_cameras``. Each run's bag is weighed:
bytes written per simulated second.

    make bench-record
"""

import os
from pathlib import Path
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'benchmarks'))
from clocked_node import ClockedNode  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402

TARGET = 0.95  # steps per second recording over not, default scene
TARGET_CAMERA = 0.9  # the same with the camera published and recorded
SECONDS = 5.0


def measure(folder: Path, camera: bool, record: bool) -> tuple:
    """Return (simulated s per wall s, bytes per simulated s, bytes per wall s) of a run."""
    params = [f'cameras:=[{"overview" if camera else "none"}]']
    if record:
        params += [f'record:={folder}', f'record_cameras:={str(camera).lower()}']
    started = time.perf_counter()
    node = ClockedNode('real_time_factor:=0.0', *params)
    node.start(settle=1.5)
    try:
        rate = node.rate(SECONDS)
    finally:
        end = node.close()
    wall = time.perf_counter() - started
    written = sum(f.stat().st_size for f in folder.rglob('*') if f.is_file()) if record else 0
    return rate, (written / end if end > 0 else 0.0), written / wall


def main() -> int:
    import rclpy
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(50 + os.getpid() % 50))
    print(f'[record] the default scene at real_time_factor 0; {os.cpu_count()} cores')
    results = {}
    with tempfile.TemporaryDirectory(prefix='sim_bench_record_') as tmp:
        for camera in (False, True):
            for i, record in enumerate((False, True, False, True)):
                folder = Path(tmp) / f'run_{camera}_{i}'
                rate, per_s, per_wall = measure(folder, camera, record)
                results.setdefault((camera, record), []).append((rate, per_s, per_wall))
                print(f'  camera {"on " if camera else "off"} record {"on " if record else "off"}'
                      f': {rate / 0.002:9.0f} steps/s'
                      + (f', {per_s / 1e3:7.1f} kB per simulated s, {per_wall / 1e3:7.1f} kB '
                         'per wall s' if record else ''), flush=True)
    rclpy.shutdown()

    def mean(key, k=0):
        return sum(r[k] for r in results[key]) / len(results[key])
    plain = mean((False, True)) / mean((False, False))
    camera = mean((True, True)) / mean((True, False))
    # Topics are paced by the wall clock (tf_rate_hz, camera_rate_hz...): at
    # real_time_factor 0 a simulated second is a sliver of a wall second; at 1 they are equal.
    print(f'written per wall second: {mean((False, True), 2) / 1e3:.0f} kB without images, '
          f'{mean((True, True), 2) / 1e3:.0f} kB with the camera (per simulated second at '
          f'real_time_factor 1; at 0 a simulated second takes a sliver of one)')
    verdict(plain >= TARGET, f'steps/s recording over not, default scene: {plain:.2f}x '
            f'(target >= {TARGET}x)')
    verdict(camera >= TARGET_CAMERA, f'steps/s recording over not, one camera recorded: '
            f'{camera:.2f}x (target >= {TARGET_CAMERA}x)')
    summary()
    return 0


if __name__ == '__main__':
    sys.exit(main())
