"""
Forward kinematics of a URDF, written from the URDF specification for tests.

Independent of the code that writes our descriptions: each joint's origin (xyz, then rpy as
fixed-axis roll, pitch, yaw), then its motion about or along its axis, from the root link.
"""

import math

import defusedxml.ElementTree as SafeET
import numpy as np


def _rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), \
        math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def _vec(el, attr: str, default: str) -> np.ndarray:
    return np.array([float(x) for x in (el.get(attr, default) if el is not None
                                        else default).split()])


def urdf_fk(text: str, values: dict) -> tuple:
    """Return (root link, {link: (position (3,), rotation (3, 3))} in the root link's frame)."""
    robot = SafeET.fromstring(text)
    joints = {j.find('child').get('link'): j for j in robot.findall('joint')}
    links = [link.get('name') for link in robot.findall('link')]
    roots = [name for name in links if name not in joints]
    assert len(roots) == 1, f'a URDF has one root link, got {roots}'
    poses = {roots[0]: (np.zeros(3), np.eye(3))}

    def pose(link: str) -> tuple:
        if link not in poses:
            j = joints[link]
            pp, pr = pose(j.find('parent').get('link'))
            origin = j.find('origin')
            op = _vec(origin, 'xyz', '0 0 0')
            orot = _rpy_matrix(*_vec(origin, 'rpy', '0 0 0'))
            p, r = pp + pr @ op, pr @ orot
            q = values.get(j.get('name'), 0.0)
            axis = _vec(j.find('axis'), 'xyz', '1 0 0')
            if j.get('type') in ('revolute', 'continuous'):
                r = r @ _axis_rotation(axis, q)
            elif j.get('type') == 'prismatic':
                p = p + r @ (axis / np.linalg.norm(axis)) * q
            poses[link] = (p, r)
        return poses[link]

    for name in links:
        pose(name)
    return roots[0], poses
