"""
What an SDF link holds, made MJCF: its inertial, collisions, visuals and lights.

* ``<inertial>``: its ``<mass>`` (SDF's default 1 kg), ``<inertia>`` (default the identity)
  and ``<pose>`` in the link frame; an inertia MuJoCo refuses is repaired as a URDF's is
  (:func:`.inertias.valid_inertia`, said once), a moving link without mass gets 1 g. SDF
  1.11's ``<inertial auto="true">`` leaves it to MuJoCo, from the collisions' ``<density>``.
* ``<collision>``: a geom that collides (``contype``/``conaffinity`` from
  ``<collide_bitmask>`` and ``<category_bitmask>``, every bit by default), hidden behind the
  link's visuals where it has any (group 3, as a URDF's). Its ``<surface>``: ``<friction>``
  ``<ode><mu>`` (or ``<bullet><friction>``) as the sliding coefficient, ``<torsional>`` with a
  patch radius as the torsional one; ``<bounce><restitution_coefficient>`` as the bounce a
  world's own restitution setting gives (:func:`.base.surfaces.restitution_to_solref`); the
  contact's ``<ode><kp>``/``<kd>`` as MuJoCo's direct stiffness and damping per unit of the
  link's mass. Gazebo takes the smaller friction of two touching surfaces, MuJoCo the larger:
  each collision's contact priority rises as its friction falls (:func:`friction_priority`),
  so the surface with less friction sets a contact's, as in Gazebo.
* ``<visual>``: a geom that collides with nothing (group 1) with its material
  (:func:`.sdf_shapes.colour`), ``<transparency>`` as its alpha.
* ``<light>``: a light of the body (directional, point or spot).
"""

import math
from pathlib import Path
from typing import Optional
import xml.etree.ElementTree as ET

import numpy as np

from . import inertias, sdf_frames, sdf_shapes
from .sdf_shapes import Assets, numbers
from ..base import quat
from ..base.errors import MissingAssetsError, ResourceParseError, UnsupportedAssetsError
from ..base.surfaces import restitution_to_solref

#: The geom group of collisions a visual draws for, and of visuals.
COLLISION_GROUP, VISUAL_GROUP = 3, 1
#: What a moving link without mass gets (kg, kg m^2), as a URDF's.
MIN_MASS, MIN_INERTIA = inertias.MIN_MASS, inertias.MIN_INERTIA
#: Contact priority steps per tenfold of friction (see :func:`friction_priority`).
PRIORITY_PER_DECADE = 20
#: Gazebo's collide bitmask when a collision gives none: every bit.
ALL_BITS = 0xFFFF

ERR_MASS = '{where}: <mass>{text}</mass> is not a finite number >= 0'
ERR_INERTIA = '{where}: <inertia> {key} {text!r} is not a finite number'


def friction_priority(mu: float) -> int:
    """
    Return the contact priority of a collision of friction `mu` (1: 0; lower: higher).

    MuJoCo takes a contact's friction from its higher-priority geom (the larger of the two
    when equal); Gazebo's engines take the smaller. A priority that rises as friction falls
    (``round(-20 log10 mu)``: one step per 12%) gives the smaller its say.
    """
    return int(round(-PRIORITY_PER_DECADE * math.log10(min(max(mu, 1e-6), 1e6))))


def inertial(link: ET.Element, where: str, moving: bool, notes: list) -> Optional[ET.Element]:
    """Return the MJCF ``<inertial>`` of a link (None: ``auto``, MuJoCo computes it)."""
    elem = link.find('inertial')
    if elem is not None and (elem.get('auto') or '').strip().lower() in ('true', '1'):
        return None
    mass, tensor, pose = 1.0, (1.0, 1.0, 1.0, 0.0, 0.0, 0.0), sdf_frames.identity()
    if elem is not None:
        text = elem.findtext('mass')
        if text is not None and text.strip():
            try:
                mass = float(text)
            except ValueError:
                mass = float('nan')
            if not (math.isfinite(mass) and mass >= 0):
                raise ResourceParseError(ERR_MASS.format(where=where, text=text.strip()[:40]))
        tensor = _tensor(elem.find('inertia'), where)
        pose = sdf_frames.parse_pose(elem.find('pose'), where)
    if moving and mass <= 0:
        notes.append(f'{where}: moves but has no mass: it gets {MIN_MASS} kg')
        mass, tensor = MIN_MASS, (MIN_INERTIA,) * 3 + (0.0,) * 3
    if not (moving or mass > 0):
        return None
    if pose[1] == (1.0, 0.0, 0.0, 0.0) and not any(tensor[3:]) and \
            inertias.accepts(tensor[:3], moving):  # most links: said in 3 numbers, no numpy
        return ET.Element('inertial', pos=_text(pose[0]), mass=f'{mass:.12g}',
                          diaginertia=_text(tensor[:3]))
    ixx, iyy, izz, ixy, ixz, iyz = tensor
    matrix = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    fixed = inertias.valid_inertia(matrix, moving)
    if fixed is not None:
        notes.append(f'{where}: its inertia is one MuJoCo refuses (not positive definite, or '
                     'breaking the triangle inequality): the nearest valid one is used')
        matrix = fixed
    turn = quat.to_matrix(pose[1])  # the tensor in the link frame: MJCF takes it so
    t = turn @ matrix @ turn.T
    full = [t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]]
    return ET.Element('inertial', pos=_text(pose[0]), mass=f'{mass:.12g}',
                      fullinertia=_text(full))


def _tensor(elem: Optional[ET.Element], where: str) -> tuple:
    """Return (ixx, iyy, izz, ixy, ixz, iyz) of an ``<inertia>`` (SDF's defaults: 1 and 0)."""
    if elem is None:
        return (1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
    values = []
    for key, default in (('ixx', 1.0), ('iyy', 1.0), ('izz', 1.0), ('ixy', 0.0), ('ixz', 0.0),
                         ('iyz', 0.0)):
        text = elem.findtext(key)
        try:
            v = float(text) if text is not None and text.strip() else default
        except ValueError:
            v = float('nan')
        if not math.isfinite(v):
            raise ResourceParseError(ERR_INERTIA.format(where=where, key=key,
                                                        text=(text or '')[:40]))
        values.append(v)
    return tuple(values)


def _text(values) -> str:
    return ' '.join(f'{float(x):.12g}' for x in values)


def _number(elem: Optional[ET.Element], path: str, default: float, where: str) -> float:
    text = elem.findtext(path) if elem is not None else None
    return numbers(text, (default,), where, f'<{path}>')[0]


def collision(part: ET.Element, name: str, where: str, folder: Optional[Path], out: Assets,
              hidden: bool, mass: float, auto_inertia: bool) -> Optional[ET.Element]:
    """
    Return (the MJCF geom of a ``<collision>``, its mesh ``optimization`` and most hulls).

    None: no shape. The geom is placed in its link frame by the caller.
    """
    attrs = _shape(part, where, folder, out)
    if attrs is None:
        return None
    optimization = (attrs.pop('optimization', ''), attrs.pop('max_convex_hulls', ''))
    g = ET.Element('geom', name=name, **attrs)
    surface = part.find('surface')
    mu = _number(surface, 'friction/ode/mu', 1.0, where) if surface is not None and \
        surface.find('friction/ode/mu') is not None else (
            _number(surface, 'friction/bullet/friction', 1.0, where)
            if surface is not None and surface.find('friction/bullet/friction') is not None
            else 1.0)
    if mu < 0:
        raise ResourceParseError(f'{where}: a friction coefficient below zero ({mu:g})')
    torsional = 0.0
    if surface is not None and surface.find('friction/torsional') is not None:
        coefficient = _number(surface, 'friction/torsional/coefficient', 1.0, where)
        radius = _number(surface, 'friction/torsional/patch_radius', 0.0, where)
        torsional = max(coefficient * radius, 0.0)
    g.set('friction', _text([mu, torsional or 0.005, 0.0001]))
    if torsional > 0:
        g.set('condim', '4')
    if mu != 1.0:
        g.set('priority', str(friction_priority(mu)))
    e = _number(surface, 'bounce/restitution_coefficient', 0.0, where) \
        if surface is not None else 0.0
    if e > 0:
        g.set('solref', _text(restitution_to_solref(min(e, 1.0))))
    kp = _number(surface, 'contact/ode/kp', 0.0, where) if surface is not None else 0.0
    kd = _number(surface, 'contact/ode/kd', 0.0, where) if surface is not None else 0.0
    if kp > 0 and mass > 0 and e <= 0:
        g.set('solref', _text([-kp / mass, -max(kd, 0.0) / mass]))
    collide = surface.find('contact/collide_bitmask') if surface is not None else None
    category = surface.find('contact/category_bitmask') if surface is not None else None
    if collide is not None or category is not None:
        mask = _bits(collide, where)
        g.set('contype', str(_bits(category, where) if category is not None else mask))
        g.set('conaffinity', str(mask))
    if hidden:
        g.set('group', str(COLLISION_GROUP))
    if auto_inertia:
        g.set('density', f'{_number(part, "density", 1000.0, where):.9g}')
    return g, optimization


def _bits(elem: Optional[ET.Element], where: str) -> int:
    text = (elem.text or '').strip() if elem is not None else ''
    try:
        return int(text, 0) if text else ALL_BITS
    except ValueError:
        raise ResourceParseError(f'{where}: a bitmask {text[:20]!r} that is not a number') \
            from None


def _shape(part: ET.Element, where: str, folder: Optional[Path], out: Assets) -> Optional[dict]:
    """Return the geom attributes of a collision's or visual's ``<geometry>`` (None: none)."""
    try:
        return sdf_shapes.geom(part.find('geometry') if part.find('geometry') is not None
                               else ET.Element('geometry'), where, folder, out)
    except (MissingAssetsError, UnsupportedAssetsError) as exc:
        out.leave_out(where, exc)  # a load that ignores missing assets goes on without it
        return None


def visual(part: ET.Element, name: str, where: str, folder: Optional[Path],
           out: Assets) -> Optional[tuple]:
    """
    Return (the MJCF geom of a ``<visual>``, whether it takes its mesh file's colour).

    None: no shape. The geom is placed in its link frame by the caller.
    """
    attrs = _shape(part, where, folder, out)
    if attrs is None:
        return None
    attrs.pop('optimization', None)
    attrs.pop('max_convex_hulls', None)
    g = ET.Element('geom', name=name, contype='0', conaffinity='0', group=str(VISUAL_GROUP),
                   density='0', **attrs)
    transparency = _number(part, 'transparency', 0.0, where)
    look = sdf_shapes.colour(part.find('material'), where, transparency)
    if look is not None:
        texture = ''
        if look['albedo_map']:
            try:
                texture = out.texture(look['albedo_map'], folder)
            except (MissingAssetsError, UnsupportedAssetsError) as exc:
                out.leave_out(f'{where}: its albedo map', exc)
        rgba = (1.0, 1.0, 1.0, look['rgba'][3]) if texture else look['rgba']
        g.set('material', out.material(rgba, look['specular'], look['emission'], texture))
        return g, False
    g.set('rgba', '0.7 0.7 0.7 1')
    return g, attrs['type'] == 'mesh'  # a mesh's file colour, once the meshes are converted


LIGHT_KINDS = {'directional': 'directional', 'point': 'point', 'spot': 'spot'}


def light(elem: ET.Element, pose: sdf_frames.Pose, name: str, where: str) -> ET.Element:
    """Return the MJCF ``<light>`` of an SDF ``<light>`` at `pose` (in its parent's frame)."""
    kind = LIGHT_KINDS.get((elem.get('type') or 'point').strip(), 'point')
    direction = np.asarray(numbers(elem.findtext('direction'), (0, 0, -1), where,
                                   'a light <direction>'), float)
    if not np.linalg.norm(direction) > 0:
        direction = np.array([0.0, 0.0, -1.0])
    world_dir = quat.rotate(pose[1], direction / np.linalg.norm(direction))
    diffuse = numbers(elem.findtext('diffuse'), (1, 1, 1, 1), where, 'a light <diffuse>')
    specular = numbers(elem.findtext('specular'), (0.1, 0.1, 0.1, 1), where,
                       'a light <specular>')
    out = ET.Element('light', name=name, pos=_text(pose[0]), dir=_text(world_dir),
                     diffuse=_text(diffuse[:3]), specular=_text(specular[:3]),
                     castshadow='true' if (elem.findtext('cast_shadows') or '').strip().lower()
                     in ('true', '1') else 'false')
    out.set('type', kind)
    att = elem.find('attenuation')
    if att is not None and kind != 'directional':
        out.set('attenuation', _text([_number(att, 'constant', 1.0, where),
                                      _number(att, 'linear', 0.0, where),
                                      _number(att, 'quadratic', 0.0, where)]))
    if kind == 'spot':
        outer = _number(elem, 'spot/outer_angle', 0.5, where)
        out.set('cutoff', f'{min(max(math.degrees(outer), 1.0), 90.0):.6g}')
        out.set('exponent', f'{max(_number(elem, "spot/falloff", 1.0, where), 0.0):.6g}')
    return out
