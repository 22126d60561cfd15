"""
Quaternion maths in MuJoCo's (w, x, y, z) order, on one (4,) or many (n, 4) at once.

The one place rotations are written: the core uses it for reference frames, the adapters for
relative transforms.
"""

import numpy as np


def mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of (4,) or (n, 4) quaternions."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def conj(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion, (4,) or (n, 4)."""
    out = np.array(q, dtype=float, copy=True)
    out[..., 1:] *= -1
    return out


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate (3,) or (n, 3) vectors by unit quaternions (4,) or (n, 4)."""
    q, v = np.asarray(q, float), np.asarray(v, float)
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def to_frame(frame_pos: np.ndarray, frame_quat: np.ndarray, pos: np.ndarray,
             quat: np.ndarray) -> tuple:
    """Return a world pose expressed in another frame: (position (3,), quat (4,))."""
    inv = conj(frame_quat)
    return rotate(inv, np.asarray(pos) - frame_pos), mul(inv, quat)


def from_frame(frame_pos: np.ndarray, frame_quat: np.ndarray, pos: np.ndarray,
               quat: np.ndarray) -> tuple:
    """Return a pose given in another frame, expressed in the world: (position (3,), quat (4,))."""
    return frame_pos + rotate(frame_quat, pos), mul(frame_quat, quat)
