"""
Sensors sampled in the stepping loop at their own rates of simulated time: declared IMUs.

A robot file's IMU says how often it samples (``update_rate``, :class:`~..records.DeclaredImu`).
Snapshots come at a wall-clock rate, too seldom for a 250 Hz IMU and never in step with
simulated time; so the loop stops its batch of steps at each due time (as it does for a base's
timeout, :mod:`.steps`) and copies the IMU's values, with its Gaussian noise (seeded by the
site's name: a run repeats), into a queue that the node drains and publishes, each sample
stamped with its own simulated time. A time that goes back (a reset) starts the schedule over.
"""

from collections import deque
import math
from typing import Optional
import zlib

import mujoco
import numpy as np

#: Samples kept for the node between two drains (a slow consumer loses the oldest).
SAMPLES_KEPT = 10_000
#: Simulated time within this fraction of a period of a due time counts as due.
DUE_TOLERANCE = 1e-6


class _Entry:
    __slots__ = ('site', 'period', 'quat', 'gyro', 'acc', 'gyro_noise', 'acc_noise', 'rng',
                 'next')

    def __init__(self, site: str, period: float, adr: dict, decl):
        self.site, self.period = site, period
        parts = ('quat', 'gyro', 'accelerometer')
        self.quat, self.gyro, self.acc = (_slice(adr.get(k)) for k in parts)
        self.gyro_noise, self.acc_noise = decl.gyro_noise, decl.accel_noise
        self.rng = np.random.default_rng(zlib.crc32(site.encode()))
        self.next = math.nan


def _slice(adr: Optional[tuple]) -> Optional[slice]:
    return None if adr is None else slice(adr[0], adr[0] + adr[1])


class Sampler:
    """
    The declared IMUs of one model generation, sampled as the loop steps.

    :param info: the generation's :class:`~..records.ModelInfo` (its ``imus`` and the IMU
        sensor groups they are).
    """

    def __init__(self, info, samples: deque):
        self.generation = info.generation
        self._entries = [_Entry(s.name, 1.0 / info.imus[s.name].rate_hz, s.adr,
                                info.imus[s.name])
                         for s in info.sensors if s.kind == 'imu' and s.name in info.imus]
        self._samples = samples
        self._last = -math.inf

    def __bool__(self) -> bool:
        return bool(self._entries)

    def next_due(self, now: float) -> float:
        """Return the earliest simulated time at or after `now` a sample is due."""
        if now < self._last:  # a reset: every schedule starts over
            for e in self._entries:
                e.next = math.nan
        self._last = now
        due = math.inf
        for e in self._entries:
            if math.isnan(e.next):
                e.next = now
            due = min(due, e.next)
        return due

    def collect(self, d: mujoco.MjData) -> None:
        """Take the samples due at the data's time (after a step ended there)."""
        t = float(d.time)
        self._last = t
        for e in self._entries:
            if math.isnan(e.next) or t < e.next - DUE_TOLERANCE * e.period:
                continue
            data = d.sensordata
            quat = data[e.quat].copy() if e.quat is not None else None
            gyro = data[e.gyro].copy() if e.gyro is not None else None
            acc = data[e.acc].copy() if e.acc is not None else None
            if gyro is not None and e.gyro_noise is not None:
                gyro += e.rng.normal(e.gyro_noise[0], e.gyro_noise[1])
            if acc is not None and e.acc_noise is not None:
                acc += e.rng.normal(e.acc_noise[0], e.acc_noise[1])
            self._samples.append((e.site, t, quat, gyro, acc))
            e.next = (math.floor(t / e.period + DUE_TOLERANCE) + 1) * e.period


def new_queue() -> deque:
    """Return the queue a world's samplers fill and its node drains."""
    return deque(maxlen=SAMPLES_KEPT)


def drain(samples: deque) -> list:
    """
    Take every sample queued so far, oldest first; thread-safe, without the world lock.

    Each is (site, simulated time, orientation wxyz, angular velocity, linear acceleration)
    of an IMU a robot file declares, at its own rate; a part the sensor lacks is None.
    """
    out = []
    while True:
        try:
            out.append(samples.popleft())
        except IndexError:
            return out
