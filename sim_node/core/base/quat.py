"""
Quaternion maths in MuJoCo's (w, x, y, z) order, on one (4,) or many (n, 4) at once.

The one place rotations are written: the core uses it for reference frames, the adapters for
relative transforms.
"""

import math

import mujoco
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


def from_axis_angle(axis, angle: float) -> np.ndarray:
    """Return the (4,) quaternion of a turn by `angle` (rad) about `axis` (3,), any length > 0."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    half = 0.5 * float(angle)
    return np.concatenate([[np.cos(half)], np.sin(half) * axis])


def from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """
    Return the (4,) quaternion of URDF's (and SDF's) fixed-axis roll, pitch, yaw.

    R = Rz(yaw) Ry(pitch) Rx(roll): the roll is applied first, about the fixed x axis.
    """
    return mul(mul(from_axis_angle((0, 0, 1), yaw), from_axis_angle((0, 1, 0), pitch)),
               from_axis_angle((1, 0, 0), roll))


def to_matrix(q) -> np.ndarray:
    """Return the (3, 3) rotation matrix of a quaternion (normalised first): MuJoCo's."""
    q = np.asarray(q, dtype=float)
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, q / np.linalg.norm(q))
    return out.reshape(3, 3)


def from_matrix(r) -> np.ndarray:
    """Return the unit (4,) quaternion of a (3, 3) rotation matrix: MuJoCo's."""
    out = np.zeros(4)
    mujoco.mju_mat2Quat(out, np.asarray(r, dtype=float).reshape(9))
    return out


def from_xyaxes(x, y) -> np.ndarray:
    """Return the quaternion of a frame whose x and y axes are `x` and `y` (MJCF's xyaxes)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    return from_matrix(np.stack([x, y, np.cross(x, y)], axis=1))


def to_rpy(q) -> tuple:
    """Return roll, pitch, yaw as URDF has them (fixed axes: R = Rz(yaw) Ry(pitch) Rx(roll))."""
    r = to_matrix(q)
    sp = -r[2, 0]
    if abs(sp) < 1 - 1e-9:
        return (float(np.arctan2(r[2, 1], r[2, 2])), float(np.arcsin(sp)),
                float(np.arctan2(r[1, 0], r[0, 0])))
    # Gimbal lock: pitch +-90 degrees; only yaw - roll (or yaw + roll) is defined.
    return (0.0, float(np.copysign(np.pi / 2, sp)), float(np.arctan2(-r[0, 1], r[1, 1])))


def from_yaw(yaw: float) -> np.ndarray:
    """Return the (4,) quaternion of a heading: a turn by `yaw` (rad) about z."""
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def yaw_of(q) -> float:
    """Return the heading (rotation about z) of a quaternion."""
    w, x, y, z = q.tolist() if isinstance(q, np.ndarray) else (float(v) for v in q)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


# ------------------------------------------------------------------ one pose at a time
# Poses as plain tuples, ((x, y, z), (w, x, y, z)), for code that composes many single poses
# (reading a 3,000-model world file): numpy's per-call cost made them 40 times slower there.


def pose_mul(a: tuple, b: tuple) -> tuple:
    """Return pose `b` (given in frame `a`) in `a`'s parent frame: ``a * b``, as tuples."""
    (px, py, pz), (aw, ax, ay, az) = a
    (bx_, by_, bz_), (bw, bx, by, bz) = b
    # the position: a's plus b's turned by a's rotation (v + 2w (u x v) + 2 u x (u x v))
    tx, ty, tz = 2 * (ay * bz_ - az * by_), 2 * (az * bx_ - ax * bz_), 2 * (ax * by_ - ay * bx_)
    pos = (px + bx_ + aw * tx + ay * tz - az * ty, py + by_ + aw * ty + az * tx - ax * tz,
           pz + bz_ + aw * tz + ax * ty - ay * tx)
    q = (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
         aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)
    return pos, q


def pose_inv(a: tuple) -> tuple:
    """Return the inverse of a pose given as tuples."""
    (px, py, pz), (w, x, y, z) = a
    inv = ((0.0, 0.0, 0.0), (w, -x, -y, -z))
    (qx, qy, qz), _ = pose_mul(inv, ((px, py, pz), (1.0, 0.0, 0.0, 0.0)))
    return (-qx, -qy, -qz), (w, -x, -y, -z)


def rpy_quat(roll: float, pitch: float, yaw: float) -> tuple:
    """Return :func:`from_rpy` as a tuple (R = Rz(yaw) Ry(pitch) Rx(roll))."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr, sy * cp * cr - cy * sp * sr)
