"""A node process for the benchmarks, and /clock as the benchmark's process hears it."""

import os
from pathlib import Path
import signal
import subprocess
import threading
import time


def longest_still(samples: list) -> float:
    """
    Return the longest wall time (s) over which simulated time did not advance.

    :param samples: (wall time, simulated time) of successive /clock messages.
    """
    still, start = 0.0, None
    for (w0, c0), (w1, c1) in zip(samples, samples[1:]):
        if c1 <= c0:
            start = w0 if start is None else start
            still = max(still, w1 - start)
        else:
            start = None
    return still


class ClockedNode:
    """
    ``node --ros-args -p <params>``, with a subscription to /clock spun on a thread.

    Subclasses add their own subscriptions and publishers before :meth:`start`, and their own
    per-spin work in :meth:`tick`.
    """

    def __init__(self, *params: str):
        import rclpy
        from rosgraph_msgs.msg import Clock
        exe = Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / 'node'
        args = [str(exe), '--ros-args']
        for p in params:
            args += ['-p', p]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
        if not rclpy.ok():
            rclpy.init()
        self.node = rclpy.create_node(f'bench_{os.getpid()}_{id(self)}')
        self.clock: list = []  # (wall time, simulated time) of every /clock heard
        self.node.create_subscription(Clock, '/clock', lambda m: self.clock.append(
            (time.perf_counter(), m.clock.sec + m.clock.nanosec * 1e-9)), 100)
        self._stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)

    def start(self, settle: float = 1.0) -> None:
        """Spin; return once /clock is heard and `settle` more seconds have passed."""
        self.thread.start()
        deadline = time.monotonic() + 60
        while not self.clock and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(settle)

    def tick(self) -> None:
        """Work done between spins (a subclass publishes here)."""

    def _spin(self) -> None:
        import rclpy
        while not self._stop:
            rclpy.spin_once(self.node, timeout_sec=0.01)
            self.tick()

    def rate(self, seconds: float) -> float:
        """Return simulated seconds per wall second over the next `seconds`."""
        t0 = time.perf_counter()
        time.sleep(seconds)
        window = [(w, s) for w, s in list(self.clock) if w >= t0]
        (w0, s0), (w1, s1) = window[0], window[-1]
        return (s1 - s0) / (w1 - w0)

    def close(self) -> float:
        """Stop the node (SIGINT: it ends cleanly); return the last simulated time heard."""
        self._stop = True
        self.thread.join(2)
        self.node.destroy_node()
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait(20)
        return self.clock[-1][1] if self.clock else 0.0
