"""
Service latency while the world steps at 1 kHz, side by side with the same world paused.

The installed node on the default scene with a 1 ms step at real_time_factor 1 (1,000 steps a
wall second). Two client processes, each its own rclpy context, call `get_entity_state` at
100 Hz for the measured window, and one of them calls `get_simulation_state` between its
calls. The same clients then measure the node paused, and a bare rclpy node serving the same
two services that answers at once (rclpy's and DDS's own round trip on this machine). Printed:
p50, p99 and max per service and case, the p99 ratio node / bare server, and a verdict on issue
21's target (p99 < 20 ms while playing).

Run with `make bench-latency` (about a minute).
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
from leave import leave  # noqa: E402, I100
from verdict import summary, verdict  # noqa: E402, I100

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(120, 200)))
NAMESPACE, TRIVIAL = '/latency_bench', '/latency_trivial'
RATE_HZ, WINDOW_SEC, TARGET_P99_MS = 100.0, 10.0, 20.0


def trivial_server() -> None:
    """Serve the same two services from a bare rclpy node that answers at once (rclpy's cost)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from simulation_interfaces import srv
    rclpy.init()
    node = Node('trivial', namespace=TRIVIAL)

    def answer(request, response):
        response.result.result = 1
        return response
    node.create_service(srv.GetEntityState, 'get_entity_state', answer)
    node.create_service(srv.GetSimulationState, 'get_simulation_state', answer)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):  # terminated: the benchmark's end
        pass


def client(seconds: float, with_state: bool, namespace: str) -> None:
    """Call at RATE_HZ for `seconds`; print {service: [latency ms, ...]} as JSON."""
    import rclpy
    from sim_node.ros.client import SimClient
    from simulation_interfaces import srv
    rclpy.init()
    c = SimClient(namespace=namespace, timeout_sec=30)
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
    leave()  # both clients leave at once: see leave.py


def measure(seconds: float, namespace: str = NAMESPACE) -> dict:
    """Run the two clients at once; return {service: sorted latencies (ms)}."""
    procs = [subprocess.Popen([sys.executable, __file__, '--client', str(seconds), str(i == 0),
                               namespace], stdout=subprocess.PIPE, text=True)
             for i in range(2)]
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
    from sim_node.ros.client import SimClient
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
    server = subprocess.Popen([sys.executable, __file__, '--trivial'])
    try:
        time.sleep(2.0)
        trivial = measure(WINDOW_SEC, TRIVIAL)
    finally:
        server.terminate()
        server.wait(10)
    for service in playing:
        print(f'  {service}', flush=True)
        for label, v in (('node, world at 1 kHz', playing[service]),
                         ('node, world paused', paused[service]),
                         ('bare rclpy server', trivial[service])):
            print(f'    {label:22s} p50 {pct(v, 0.5):6.2f} ms  p99 {pct(v, 0.99):6.2f} ms  '
                  f'max {v[-1]:6.2f} ms  ({len(v)} calls)', flush=True)
        a, t = pct(playing[service], 0.99), pct(trivial[service], 0.99)
        print(f'    p99 ratio node at 1 kHz / bare rclpy server: {a / t:4.2f}', flush=True)
        verdict(a < TARGET_P99_MS, f'{service} p99 {a:.2f} ms with the world at 1 kHz '
                f'(target < {TARGET_P99_MS:g} ms; a bare rclpy server: {t:.2f} ms)')
    summary()


if __name__ == '__main__':
    if sys.argv[1:2] == ['--client']:
        client(float(sys.argv[2]), sys.argv[3] == 'True', sys.argv[4])
    elif sys.argv[1:2] == ['--trivial']:
        trivial_server()
    elif sys.argv[1:2] == ['--pause']:
        set_paused(True)
    else:
        main()
