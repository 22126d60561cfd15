"""
Service latency while the world steps at 1 kHz, side by side with the same world paused.

The installed node on the default scene with a 1 ms step at real_time_factor 1 (1,000 steps a
wall second). Two client processes, each its own rclpy context, call `get_entity_state` at
100 Hz for the measured window, and one of them calls `get_simulation_state` between its
calls. The same clients then measure the node paused. Printed: p50, p99 and max per service
and state, the ratio playing / paused, and a verdict on issue 21's target (p99 < 20 ms while
playing).

Run with `make bench-latency` (about 40 s).
"""

import json
import os
from pathlib import Path
import random
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'benchmarks'))
from verdict import summary, verdict  # noqa: E402, I100

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(120, 200)))
NAMESPACE = '/latency_bench'
RATE_HZ, WINDOW_SEC, TARGET_P99_MS = 100.0, 10.0, 20.0


def client(seconds: float, with_state: bool) -> None:
    """Call at RATE_HZ for `seconds`; print {service: [latency ms, ...]} as JSON."""
    import rclpy
    from sim_node.client import SimClient
    from simulation_interfaces import srv
    rclpy.init()
    c = SimClient(namespace=NAMESPACE, timeout_sec=30)
    calls = [('get_entity_state', srv.GetEntityState, srv.GetEntityState.Request(
        entity='box_a'))]
    if with_state:
        calls.append(('get_simulation_state', srv.GetSimulationState,
                      srv.GetSimulationState.Request()))
    for service, srv_type, req in calls:  # connected before the window starts
        c.call(service, srv_type, req)
    out = {service: [] for service, _, _ in calls}
    period = 1.0 / RATE_HZ
    start = next_due = time.perf_counter()
    while time.perf_counter() - start < seconds:
        for service, srv_type, req in calls:
            t0 = time.perf_counter()
            c.call(service, srv_type, req)
            out[service].append((time.perf_counter() - t0) * 1e3)
        next_due += period
        time.sleep(max(0.0, next_due - time.perf_counter()))
    print(json.dumps(out), flush=True)
    c.close()
    rclpy.shutdown()


def measure(seconds: float) -> dict:
    """Run the two clients at once; return {service: sorted latencies (ms)}."""
    procs = [subprocess.Popen([sys.executable, __file__, '--client', str(seconds), str(i == 0)],
                              stdout=subprocess.PIPE, text=True) for i in range(2)]
    merged: dict = {}
    for p in procs:
        out, _ = p.communicate(timeout=seconds + 90)
        for service, values in json.loads(out.strip().splitlines()[-1]).items():
            merged.setdefault(service, []).extend(values)
    return {k: sorted(v) for k, v in merged.items()}


def pct(values: list, q: float) -> float:
    return values[min(len(values) - 1, int(q * len(values)))]


def set_paused(paused: bool) -> None:
    import rclpy
    from sim_node.client import SimClient
    rclpy.init()
    c = SimClient(namespace=NAMESPACE, timeout_sec=30)
    c.pause() if paused else c.play()
    c.close()
    rclpy.shutdown()


def main() -> None:
    node = subprocess.Popen([os.path.join(os.environ['SIM_PREFIX'], 'lib', 'sim', 'node'),
                             '--ros-args', '-p', 'timestep:=0.001', '-r',
                             f'__ns:={NAMESPACE}'],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(3.0)
        print(f'[latency] default scene, 1 ms step at real_time_factor 1; two clients at '
              f'{RATE_HZ:g} Hz for {WINDOW_SEC:g} s each, then the same paused', flush=True)
        playing = measure(WINDOW_SEC)
        subprocess.run([sys.executable, __file__, '--pause'], check=True)
        paused = measure(WINDOW_SEC)
    finally:
        node.terminate()
        node.wait(10)
    for service in playing:
        a, b = playing[service], paused[service]
        print(f'  {service:22s} playing at 1 kHz: p50 {pct(a, 0.5):5.2f} ms  p99 '
              f'{pct(a, 0.99):5.2f} ms  max {a[-1]:6.2f} ms ({len(a)} calls) | paused: p50 '
              f'{pct(b, 0.5):5.2f} p99 {pct(b, 0.99):5.2f} max {b[-1]:6.2f} | p99 ratio '
              f'{pct(a, 0.99) / pct(b, 0.99):4.2f}', flush=True)
        verdict(pct(a, 0.99) < TARGET_P99_MS,
                f'{service} p99 {pct(a, 0.99):.2f} ms with the world at 1 kHz '
                f'(target < {TARGET_P99_MS:g} ms)')
    summary()


if __name__ == '__main__':
    if sys.argv[1:2] == ['--client']:
        client(float(sys.argv[2]), sys.argv[3] == 'True')
    elif sys.argv[1:2] == ['--pause']:
        set_paused(True)
    else:
        main()
