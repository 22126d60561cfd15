"""
Messages written straight to their wire form (CDR, little endian), for the big ones.

rclpy publishes ``bytes`` as an already serialized message. Building a TFMessage of 1,000
transforms from Python objects costs about 30 us a transform; here its bytes are laid out once
per model generation (:class:`TfTemplate`) and each tick only the stamp and the numbers are
written, from numpy arrays in one pass. Markers are written once per model change by a small
writer instead of one message object per geom. The layout is ROS 2's: a 4-byte encapsulation
header (CDR little endian), then every primitive aligned to its size relative to the body.
"""

import struct
from typing import Sequence

import numpy as np

_HEADER = b'\x00\x01\x00\x00'  # CDR_LE encapsulation, no options


class CdrWriter:
    """Appends CDR-encoded values to a buffer."""

    def __init__(self):
        self.buf = bytearray(_HEADER)

    def align(self, n: int) -> None:
        self.buf += b'\0' * (-(len(self.buf) - 4) % n)

    def i32(self, v: int) -> int:
        """Write an int32; returns its offset in the buffer."""
        self.align(4)
        at = len(self.buf)
        self.buf += struct.pack('<i', v)
        return at

    def u32(self, v: int) -> int:
        self.align(4)
        at = len(self.buf)
        self.buf += struct.pack('<I', v)
        return at

    def boolean(self, v: bool) -> None:
        self.buf += b'\x01' if v else b'\x00'

    def string(self, s: str) -> None:
        data = s.encode()
        self.u32(len(data) + 1)
        self.buf += data + b'\0'

    def f64s(self, values: Sequence[float]) -> int:
        """Write float64 values; returns the offset of the first."""
        self.align(8)
        at = len(self.buf)
        self.buf += np.asarray(values, dtype='<f8').tobytes()
        return at

    def f32s(self, values: Sequence[float]) -> None:
        self.align(4)
        self.buf += np.asarray(values, dtype='<f4').tobytes()

    def stamp(self, sec: int, nanosec: int) -> int:
        at = self.i32(sec)
        self.u32(nanosec)
        return at


def split_time(t: float) -> tuple:
    """(sec, nanosec) of a non-negative time in seconds."""
    ns = int(round(t * 1e9))
    return ns // 1_000_000_000, ns % 1_000_000_000


class TfTemplate:
    """
    The bytes of a tf2_msgs/TFMessage with fixed frame names, to be filled each tick.

    :param parents: (n,) frame_id of each transform.
    :param children: (n,) child_frame_id of each transform.
    """

    def __init__(self, parents: Sequence[str], children: Sequence[str]):
        w = CdrWriter()
        w.u32(len(children))
        stamps, values = [], []
        for parent, child in zip(parents, children):
            stamps.append(w.stamp(0, 0))
            w.string(parent)
            w.string(child)
            values.append(w.f64s(np.zeros(7)))  # translation x y z, rotation x y z w
        self._buf = w.buf
        self.size = len(children)
        # Views: int32 words over the whole buffer; float64 words from the body's start (byte
        # 4), where every double is aligned.
        n_words = len(self._buf) // 4
        self._i32 = np.ndarray((n_words,), dtype='<i4', buffer=self._buf)
        self._u32 = np.ndarray((n_words,), dtype='<u4', buffer=self._buf)
        self._f64 = np.ndarray(((len(self._buf) - 4) // 8,), dtype='<f8', buffer=self._buf,
                               offset=4)
        self._sec_at = np.asarray(stamps, dtype=int) // 4
        self._val_at = ((np.asarray(values, dtype=int) - 4) // 8)[:, None] + np.arange(7)

    def fill(self, sim_time: float, pos: np.ndarray, quat_xyzw: np.ndarray) -> bytes:
        """
        Return the serialized message for one tick: every transform stamped `sim_time`.

        :param pos: (n, 3) translations.
        :param quat_xyzw: (n, 4) rotations in ROS order.
        """
        sec, nsec = split_time(sim_time)
        self._i32[self._sec_at] = sec
        self._u32[self._sec_at + 1] = nsec
        self._f64[self._val_at] = np.concatenate([pos, quat_xyzw], axis=1)
        return bytes(self._buf)
