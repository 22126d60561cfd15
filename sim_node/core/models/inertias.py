"""
URDF inertias as Gazebo loads them: what MuJoCo's compiler refuses is repaired, and said.

A moving link without mass (with what is welded to it) gets its inertia from its collision
geometry, or a small mass when it has none; an inertia that is not positive definite or breaks
the triangle inequality gets the nearest one that is. :mod:`.urdf` calls :func:`repair` on the
parsed document, after it refused negative and non-finite numbers.
"""

from typing import Optional
import xml.etree.ElementTree as ET

import numpy as np

#: URDF joint types that move.
MOVING = ('revolute', 'continuous', 'prismatic', 'floating', 'planar')
#: What a moving link without mass or geometry gets (kg, kg m^2).
MIN_MASS, MIN_INERTIA = 1e-3, 1e-6
#: The smallest principal moment an inertia is raised to, relative to its largest.
MIN_MOMENT_RATIO = 1e-6
#: How far past equality a repaired inertia meets the triangle inequality, relative.
TRIANGLE_MARGIN = 1e-4


def repair(root: ET.Element, links: list, joint_of: dict, repairs: list, root_moves: bool,
           root_link: str) -> None:
    """
    Repair what MuJoCo's compiler refuses (see the module docstring).

    MuJoCo refuses a moving body whose mass, with the bodies welded to it, is zero; a link
    welded to a massive child may have none of its own (an empty ``base`` link, say).
    """
    by_name = {link.get('name'): link for link in links}
    welded = {}  # link -> links joined to it by fixed joints
    for child, joint in joint_of.items():
        if joint.get('type') == 'fixed':
            welded.setdefault(joint.find('parent').get('link'), []).append(child)

    def group_mass(name: str) -> float:
        return _mass(by_name[name].find('inertial')) + sum(
            group_mass(c) for c in welded.get(name, ()) if c in by_name)

    from_geometry, given_mass, rebalanced = [], [], []
    for link in links:
        name = link.get('name')
        joint = joint_of.get(name)
        moving = (joint is not None and joint.get('type') in MOVING) or (
            root_moves and name == root_link)
        inertial = link.find('inertial')
        mass = _mass(inertial)
        if moving and group_mass(name) <= 0:
            if link.find('collision') is not None:
                if inertial is not None:
                    link.remove(inertial)
                from_geometry.append(name)
            else:
                _set_inertial(link, inertial, MIN_MASS, np.eye(3) * MIN_INERTIA)
                given_mass.append(name)
            continue
        if inertial is None or mass <= 0:
            continue
        alone = moving and group_mass(name) == mass  # nothing welded to it carries inertia
        fixed = valid_inertia(_inertia(inertial), alone)
        if fixed is not None:
            _set_inertial(link, inertial, mass, fixed)
            rebalanced.append(name)
    for names, text in ((from_geometry, 'move but have no mass: their inertia is computed '
                         'from their collision geometry'),
                        (given_mass, f'move but have no mass and no collision geometry: each '
                         f'gets {MIN_MASS} kg'),
                        (rebalanced, 'have inertias MuJoCo refuses (not positive definite, or '
                         'breaking the triangle inequality): each gets the nearest valid one')):
        if names:
            repairs.append(f'links {listed(names)} {text}')


def _mass(inertial: Optional[ET.Element]) -> float:
    if inertial is None or inertial.find('mass') is None:
        return 0.0
    return float(inertial.find('mass').get('value', '0') or 0)


def _inertia(inertial: ET.Element) -> np.ndarray:
    e = inertial.find('inertia')
    g = (lambda k: float(e.get(k, '0') or 0)) if e is not None else (lambda k: 0.0)
    return np.array([[g('ixx'), g('ixy'), g('ixz')], [g('ixy'), g('iyy'), g('iyz')],
                     [g('ixz'), g('iyz'), g('izz')]])


def accepts(moments, moving: bool) -> bool:
    """Whether principal moments (3 floats) are ones MuJoCo takes as they are (no numpy)."""
    a, b, c = sorted(float(m) for m in moments)
    top = max(c, MIN_INERTIA if moving else 0.0)
    return a >= max(top * MIN_MOMENT_RATIO, 1e-12) and a + b >= c - 1e-9 * max(top, 1e-12)


def valid_inertia(inertia: np.ndarray, moving: bool) -> Optional[np.ndarray]:
    """Return the nearest inertia MuJoCo accepts, or None when this one is accepted."""
    moments, axes = np.linalg.eigh(inertia)
    if accepts(moments, moving):
        return None
    top = max(float(moments.max()), MIN_INERTIA if moving else 0.0)
    floor = max(top * MIN_MOMENT_RATIO, 1e-12)
    if top <= 0:
        return None if not moving else np.eye(3) * MIN_INERTIA
    fixed = np.maximum(moments, floor)
    order = np.argsort(fixed)
    lo, mid, hi = fixed[order]
    if lo + mid < hi:  # raise the two smaller moments to meet the triangle inequality (with
        lift = (hi - lo - mid) / 2.0 + TRIANGLE_MARGIN * hi  # a margin: MuJoCo's own rounding)
        fixed[order[0]], fixed[order[1]] = lo + lift, mid + lift
    return axes @ np.diag(fixed) @ axes.T


def _set_inertial(link: ET.Element, inertial: Optional[ET.Element], mass: float,
                  inertia: np.ndarray) -> None:
    if inertial is None:
        inertial = ET.SubElement(link, 'inertial')
    m = inertial.find('mass')
    if m is None:
        m = ET.SubElement(inertial, 'mass')
    m.set('value', repr(float(mass)))
    e = inertial.find('inertia')
    if e is None:
        e = ET.SubElement(inertial, 'inertia')
    for key, (i, j) in {'ixx': (0, 0), 'ixy': (0, 1), 'ixz': (0, 2), 'iyy': (1, 1),
                        'iyz': (1, 2), 'izz': (2, 2)}.items():
        e.set(key, repr(float(inertia[i, j])))


def listed(names: list, most: int = 12) -> str:
    """Return up to `most` names, quoted, and how many more there are."""
    shown = ', '.join(repr(n) for n in names[:most])
    return shown + (f' and {len(names) - most} more' if len(names) > most else '')
