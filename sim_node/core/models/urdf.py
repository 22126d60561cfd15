"""
URDF as ROS description packages ship it, made ready for MuJoCo's own URDF importer.

MuJoCo imports URDF links, joints, inertials, geometry, materials and ``<mimic>`` joints itself.
What a ROS user's file carries beyond that, and what Gazebo and RViz accept that MuJoCo's
compiler refuses, is handled here on the parsed document, before MuJoCo sees it
(:func:`prepare`), and on the imported spec after (:func:`finish`):

* Extension elements (``<gazebo>``, ``<transmission>``, ``<ros2_control>``) are taken out and
  kept (:attr:`Prepared.extensions`): they are never read as file references. Elements URDF
  does not define are named once in a warning.
* Numbers are checked: a NaN or infinite mass, inertia, pose, size, scale or limit, and a
  negative mass or moment of inertia, is refused with the link or joint it is in.
* Inertias MuJoCo's compiler refuses are repaired as Gazebo would load them, each repair named
  in a warning: a moving link without mass gets its inertia from its collision geometry, or a
  small mass when it has none; an inertia that is not positive definite or breaks the triangle
  inequality gets the nearest one that is.
* The root link floats (a free joint) as in Gazebo, unless the URDF joins it to a link named
  ``world`` with a fixed joint (then it stays where it is spawned), or it is static
  (``<gazebo><static>true</static></gazebo>``, or the spawn asks for it).
* ``<mimic>`` joints must name another joint of the file, and no two may mimic each other in a
  loop; MuJoCo then makes each an equality constraint that follows its leader.
* Visual geometry is kept (MuJoCo's URDF default drops it), so what a camera, the viewer and the
  markers show is what RViz shows; its meshes carry no mass, and where a link has a visual its
  collision geometry is hidden (group 3).
* The robot's links do not collide with each other, as in Gazebo, unless the model says
  ``<gazebo><self_collide>true</self_collide></gazebo>``; they collide with everything else.
"""

from dataclasses import dataclass, field
import logging
import math
from typing import Optional
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from . import decompose, inertias, urdf_declared
from .ros2_control import read as read_ros2_control, Ros2Control
from ..base import quat as rotations
from ..base.errors import CapacityError, ResourceParseError

log = logging.getLogger(__name__)

#: What URDF defines, by parent element (anything else is unknown: warned about, left to
#: MuJoCo, which ignores it).
KNOWN = {
    'robot': {'link', 'joint', 'material', 'mujoco'},
    'link': {'inertial', 'visual', 'collision'},
    'joint': {'origin', 'parent', 'child', 'axis', 'calibration', 'dynamics', 'limit', 'mimic',
              'safety_controller'},
    'inertial': {'origin', 'mass', 'inertia'},
    'visual': {'origin', 'geometry', 'material'},
    'collision': {'origin', 'geometry', 'material'},  # a collision's material: tolerated
    'geometry': {'box', 'cylinder', 'sphere', 'mesh', 'capsule'},
    'material': {'color', 'texture'},
}
#: Extension elements of the ROS tools, taken out and kept for what they declare.
EXTENSIONS = ('gazebo', 'transmission', 'ros2_control')
#: The geom group of collision geometry that a visual draws for (hidden by default).
COLLISION_GROUP = 3
#: Numeric attributes checked to be finite: element -> attributes.
#: Numbers that no body has below zero: a negative mass or moment of inertia is refused.
_NOT_NEGATIVE = {'mass': ('value',), 'inertia': ('ixx', 'iyy', 'izz')}
#: How far below zero, relative to the element's largest moment, rounding may put a zero.
NEGATIVE_ROUNDING = 1e-9
_NUMBERS = {'mass': ('value',), 'origin': ('xyz', 'rpy'), 'axis': ('xyz',),
            'inertia': ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz'), 'box': ('size',),
            'cylinder': ('radius', 'length'), 'sphere': ('radius',),
            'capsule': ('radius', 'length'),
            'mesh': ('scale',), 'limit': ('lower', 'upper', 'effort', 'velocity'),
            'dynamics': ('damping', 'friction'), 'mimic': ('multiplier', 'offset'),
            'color': ('rgba',)}

ERR_NO_LINK = 'the URDF has no <link>: nothing to spawn'
ERR_NUMBER = ('{where}: <{tag} {attr}="{value}"> is not a finite number; give finite values '
              '(URDF units: metres, kilograms, radians)')
ERR_NEGATIVE = ('{where}: <{tag} {attr}="{value}"> is negative: a mass and the moments of an '
                'inertia (ixx, iyy, izz) are >= 0 (a zero one is repaired, as Gazebo loads it)')
ERR_LINKS = ('the URDF has {n} links, more than the world may hold ({limit} bodies, parameter '
             'max_bodies)')
ERR_MIMIC_UNKNOWN = 'joint {joint!r} mimics {leader!r}, which is not a joint of this URDF'
ERR_MIMIC_SELF = 'joint {joint!r} mimics itself'
ERR_MIMIC_LOOP = 'joints {joints} mimic each other in a loop: one of them must lead'
ERR_JOINT_LINK = 'joint {joint!r} names link {link!r}, which is not a link of this URDF'
ERR_TWO_ROOTS = ('the URDF has {n} root links ({links}): join them into one tree (URDF allows '
                 'one root)')


@dataclass
class Prepared:
    """What :func:`prepare` found: the root, what floats, and what it changed or left out."""

    root_link: str = ''
    #: The root is joined to a link named ``world`` (by a fixed joint: fixed where spawned; by a
    #: joint that turns or slides: it moves about that anchor, as a pendulum).
    anchored: bool = False
    #: ``<gazebo><static>true</static></gazebo>`` (Gazebo's static model).
    static: bool = False
    #: The spawn asked for the root to stay where it is spawned.
    spawn_fixed: bool = False
    #: ``<gazebo><self_collide>true</self_collide></gazebo>``: its links collide with each
    #: other (Gazebo's default, and this one's, is that they do not).
    self_collide: bool = False
    #: joint -> {'velocity', 'effort'} limits, for the interfaces a URDF declares.
    joint_limits: dict = field(default_factory=dict)
    #: What :mod:`.urdf_declared` made of the extensions (sensors, interfaces), as text.
    declared: list = field(default_factory=list)
    #: What its sensor tags declare (:class:`~sim_node.core.records.DeclaredLaser`,
    #: :class:`~sim_node.core.records.DeclaredWrench`), with its own names.
    sensors: list = field(default_factory=list)
    #: joint -> (parent link, child link).
    joint_links: dict = field(default_factory=dict)
    #: For a root fixed to a link named ``world``: where that link is in the root link's
    #: frame, (position (3,), quaternion wxyz (4,)): the description names it, so /tf has it.
    world_link: Optional[tuple] = None
    #: link -> the names Gazebo gives its collisions (``<name or link>_collision[_<i>]``),
    #: in order; then (:func:`finish`) geom name -> that name, the geoms named where unnamed.
    collisions: dict = field(default_factory=dict)
    #: Its ``<ros2_control>`` blocks and Gazebo control plugin (:mod:`.ros2_control`), or None.
    ros2_control: Optional[Ros2Control] = None
    extensions: list = field(default_factory=list)  # the extension elements, as parsed
    #: An SDF model's gz-sim systems (:class:`~..control.gz_systems.GzSystem`; SDF only).
    systems: tuple = ()
    #: The gz-sim systems an SDF model names that are not run here (named in a warning and on
    #: /diagnostics; SDF only).
    systems_not_run: tuple = ()
    unknown: list = field(default_factory=list)  # element names URDF does not define
    repairs: list = field(default_factory=list)  # one text per inertia repaired

    @property
    def floats(self) -> bool:
        """Whether the root gets a free joint (Gazebo's rule; see :func:`finish`)."""
        return not (self.anchored or self.static or self.spawn_fixed)


def prepare(root: ET.Element, max_bodies: Optional[int] = None,
            fixed: bool = False) -> Prepared:
    """
    Check and repair a parsed URDF in place (see the module docstring); MuJoCo reads the rest.

    :param fixed: the spawn fixes the root where it is (see :func:`finish`).

    :raises ResourceParseError: no link, a non-finite number, a joint naming no link, two
        roots, a joint mimicking itself or joints mimicking each other in a loop.
    :raises CapacityError: more links than the world may hold (before MuJoCo reads them).
    """
    out = Prepared(spawn_fixed=fixed)
    for ext in [e for e in root if e.tag in EXTENSIONS]:
        root.remove(ext)
        out.extensions.append(ext)
    model = [e for e in out.extensions if e.tag == 'gazebo' and 'reference' not in e.attrib]
    out.static = any(_true(e.findtext('static')) for e in model)
    out.joint_limits = urdf_declared.joint_limits(root)
    out.ros2_control = read_ros2_control(out.extensions)
    if out.ros2_control is not None:
        out.ros2_control = out.ros2_control.with_speeds(out.joint_limits)
    out.joint_links = urdf_declared.joint_links(root)
    out.self_collide = any(_true(e.findtext('self_collide')) for e in model)
    out.unknown = _drop_unknown(root)
    links = list(root.findall('link'))
    if not links:
        raise ResourceParseError(ERR_NO_LINK)
    if max_bodies is not None and len(links) > max_bodies:
        raise CapacityError(ERR_LINKS.format(n=len(links), limit=max_bodies))
    _check_numbers(root)
    names = {link.get('name', '') for link in links}
    joints = root.findall('joint')
    children = {}
    for j in joints:
        for end in ('parent', 'child'):
            link = (j.find(end).get('link', '') if j.find(end) is not None else '')
            if link not in names:
                raise ResourceParseError(ERR_JOINT_LINK.format(joint=j.get('name'), link=link))
        children[j.find('child').get('link')] = j
    roots = [n for n in (link.get('name', '') for link in links) if n not in children]
    if 'world' in roots and len(roots) > 1:
        roots.remove('world')
    if len(roots) != 1:
        raise ResourceParseError(ERR_TWO_ROOTS.format(n=len(roots), links=', '.join(
            repr(r) for r in roots[:5])))
    out.root_link = roots[0]
    if out.root_link == 'world':  # world -> base by a joint: the base is the robot's root
        firsts = [j for j in joints if j.find('parent').get('link') == 'world']
        if len(firsts) == 1:
            out.root_link = firsts[0].find('child').get('link')
            out.anchored = firsts[0].get('type') != 'floating'
            if firsts[0].get('type') == 'fixed':
                out.world_link = _inverse_origin(firsts[0].find('origin'))
    _check_mimics(joints)
    gazebo_names = _collision_names(root)
    empty = _drop_empty_geometry(root)
    out.collisions = {link.get('name', ''): [gazebo_names[c] for c in link.findall('collision')]
                      for link in links}
    if empty:
        out.repairs.append(f'links {inertias.listed(empty)} have geometry of size zero, which '
                           'MuJoCo refuses and RViz does not draw: left out')
    inertias.repair(root, links, children, out.repairs, out.floats, out.root_link)
    _keep_visuals(root)
    if out.unknown:
        log.warning('URDF %r: left out elements URDF does not define: %s', root.get('name', ''),
                    ', '.join(sorted(set(out.unknown))[:20]))
    for text in out.repairs:
        log.warning('URDF %r: %s', root.get('name', ''), text)
    return out


def finish(spec: mujoco.MjSpec, prepared: Prepared, labels: Optional[dict] = None) -> None:
    """
    Finish the imported spec: a free joint for a floating root; meshes that weigh nothing.

    Concave collision meshes of a model with no joint (a tray, a table; every model's with
    ``mesh_decomposition`` ``all``) get convex parts (:mod:`.decompose`; `labels`: mesh file
    -> the name the URDF gives it, for its messages), as Gazebo collides them as they are.

    A mesh whose volume no body's inertia comes from (a visual: MuJoCo gives visual geoms no
    density; a collision mesh of a link with its own inertial) is taken as a shell: a thin
    one (a decal, a panel, a fingernail) would otherwise be refused as a mesh whose volume is
    too small, as Gazebo would not refuse it.
    """
    # Meshes whose volume matters: collision geometry of links whose inertia comes from it.
    weighed = {g.meshname for body in spec.bodies if not body.explicitinertial
               for g in body.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH
               and (g.contype or g.conaffinity)}
    for mesh in spec.meshes:
        if mesh.name not in weighed:
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    # What a link looks like is its visual: where it has one, its collision geometry is drawn
    # by no one (group 3, hidden in MuJoCo's renderer, the viewer and the markers).
    for body in spec.bodies:
        geoms = list(body.geoms)
        if any(g.contype == 0 and g.conaffinity == 0 for g in geoms):
            for g in geoms:
                if g.contype or g.conaffinity:
                    g.group = COLLISION_GROUP
    prepared.collisions = _name_collisions(spec, prepared.collisions)
    thing = all(j.type == mujoco.mjtJoint.mjJNT_FREE for j in spec.joints)  # not a robot
    if decompose.mode() == 'all' or thing:
        decompose.split_geoms(spec, labels or {}, collisions=prepared.collisions)
    prepared.declared, prepared.sensors = urdf_declared.add(
        spec, prepared.extensions, prepared.joint_limits, prepared.joint_links,
        prepared.collisions)
    _start_inside_ranges(spec)
    if not prepared.self_collide:
        _exclude_self_contacts(spec)
    if not prepared.floats:
        return
    tops = list(spec.worldbody.bodies)
    if len(tops) == 1 and not tops[0].joints:
        tops[0].add_freejoint(name=f'{prepared.root_link}_floating')


def _inverse_origin(origin: Optional[ET.Element]) -> tuple:
    """Return the inverse of a joint's ``<origin xyz rpy>``: (position (3,), quat wxyz (4,))."""
    def vector(name: str) -> np.ndarray:
        text = origin.get(name, '') if origin is not None else ''
        values = [float(v) for v in text.split()] if text.strip() else [0.0] * 3
        return np.asarray(values[:3] + [0.0] * (3 - len(values[:3])), dtype=float)
    xyz, (roll, pitch, yaw) = vector('xyz'), vector('rpy')
    inv = rotations.conj(rotations.from_rpy(roll, pitch, yaw))  # URDF: Rz(yaw) Ry(pitch) Rx(roll)
    back = rotations.rotate(inv, -xyz)
    return tuple(back), tuple(inv)


def _start_inside_ranges(spec: mujoco.MjSpec) -> None:
    """
    Start a joint whose range leaves out 0 at the nearest end of its range, not outside it.

    URDF has no initial state: every joint starts at 0, and one whose limits leave 0 out (a
    Kinova arm's second joint: 0.82 to 5.46 rad) would be thrown against its limit at once
    (anymal with a Kinova arm diverged within 0.3 s). The joint's reference value becomes the
    nearest end and its body is turned (or moved) by as much in the spec, so a joint value still
    means what the URDF means by it, for /tf, joint_states and mimic joints alike.
    """
    for body in spec.bodies:
        for j in body.joints:
            lo, hi = float(j.range[0]), float(j.range[1])
            if j.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE) \
                    or j.limited == mujoco.mjtLimited.mjLIMITED_FALSE or not lo < hi \
                    or lo <= 0.0 <= hi or len(body.joints) != 1:
                continue
            r = lo if lo > 0 else hi
            axis = np.asarray(j.axis, dtype=float) / np.linalg.norm(j.axis)
            quat = np.asarray(body.quat, dtype=float)
            if j.type == mujoco.mjtJoint.mjJNT_SLIDE:
                shift = axis * r
            else:
                turn = rotations.from_axis_angle(axis, r)
                anchor = np.asarray(j.pos, dtype=float)
                shift = anchor - rotations.rotate(turn, anchor)
                body.quat = rotations.mul(quat, turn)
            body.pos = np.asarray(body.pos, dtype=float) + rotations.rotate(quat, shift)
            j.ref = r


def _exclude_self_contacts(spec: mujoco.MjSpec) -> None:
    """
    Keep the robot's links from colliding with each other, as Gazebo does by default.

    A URDF's links often overlap where they are not parent and child (a gripper's fingers, a
    sensor housing), which Gazebo never notices (``self_collide`` is false unless the model
    says so) and MuJoCo would push apart.
    """
    solid = [b.name for b in spec.bodies if b.name and any(
        g.contype or g.conaffinity for g in b.geoms)]
    # Parent and child too: MuJoCo leaves a pair alone only when the parent moves (a root
    # welded where it is spawned has the world as its weld parent).
    for i, a in enumerate(solid):
        for b in solid[i + 1:]:
            spec.add_exclude(bodyname1=a, bodyname2=b)


def _true(text: Optional[str]) -> bool:
    return (text or '').strip().lower() in ('true', '1')


def _drop_unknown(root: ET.Element) -> list:
    """Take out elements URDF does not define where it defines children; return their tags."""
    unknown = []
    stack = [root]
    while stack:
        elem = stack.pop()
        allowed = KNOWN.get(elem.tag)
        for child in list(elem):
            if allowed is not None and child.tag not in allowed:
                unknown.append(child.tag if isinstance(child.tag, str) else 'comment')
                elem.remove(child)
            elif child.tag != 'mujoco':
                stack.append(child)
    for material in root.iter('material'):  # a texture is for RViz; MuJoCo ignores it
        for tex in material.findall('texture'):
            material.remove(tex)
    return [u for u in unknown if u != 'comment']


def _where(elem: ET.Element, root: ET.Element) -> str:
    for kind in ('link', 'joint'):
        for owner in root.iter(kind):
            if any(e is elem for e in owner.iter()):
                return f'{kind} {owner.get("name")!r}'
    return 'the URDF'


def _collision_names(root: ET.Element) -> dict:
    """
    Return each <collision> element's name as Gazebo's URDF reader makes it.

    Its own name, or else its link's, then ``_collision``, then ``_<i>`` for all but a link's
    first collision: what a contact sensor's ``<collision>`` names, and the middle of the
    ``model::link::collision`` its reports scope it by.
    """
    out = {}
    for link in root.findall('link'):
        for i, part in enumerate(link.findall('collision')):
            name = f"{part.get('name') or link.get('name', '')}_collision"
            out[part] = f'{name}_{i}' if i else name
    return out


def _name_collisions(spec: mujoco.MjSpec, names: dict) -> dict:
    """
    Return geom name -> Gazebo's name of every collision MuJoCo made (see :func:`prepare`).

    MuJoCo imports a link's collisions in order, before its visuals (which collide with
    nothing); an unnamed one (or one whose name another took) is given Gazebo's name.
    """
    out, taken = {}, {g.name for g in spec.geoms if g.name}
    for body in spec.bodies:
        geoms = [g for g in body.geoms if g.contype or g.conaffinity]
        given = names.get(body.name, [])
        if len(geoms) != len(given):
            continue  # not as read: its geoms keep MuJoCo's names
        for geom, name in zip(geoms, given):
            if not geom.name and name not in taken:
                geom.name = name
                taken.add(name)
            if geom.name:
                out[geom.name] = name
    return out


def _drop_empty_geometry(root: ET.Element) -> list:
    """Take out visuals and collisions of a box, sphere or cylinder of size zero."""
    links = []
    for link in root.findall('link'):
        for part in [p for kind in ('visual', 'collision') for p in link.findall(kind)]:
            shape = part.find('geometry/*')
            if shape is None or shape.tag not in ('box', 'sphere', 'cylinder', 'capsule'):
                continue
            values = [float(v) for attr in ('size', 'radius', 'length')
                      for v in (shape.get(attr) or '').split()]
            if values and min(values) <= 0:
                link.remove(part)
                links.append(link.get('name'))
    return sorted(set(links))


def _check_numbers(root: ET.Element) -> None:
    for elem in root.iter():
        for attr in _NUMBERS.get(elem.tag, ()):
            value = elem.get(attr)
            if value is None:
                continue
            try:
                ok = all(math.isfinite(float(v)) for v in value.split())
            except ValueError:
                ok = False
            if not ok:
                raise ResourceParseError(ERR_NUMBER.format(
                    where=_where(elem, root), tag=elem.tag, attr=attr, value=value[:40]))
            if attr in _NOT_NEGATIVE.get(elem.tag, ()) and _negative(elem, float(value)):
                raise ResourceParseError(ERR_NEGATIVE.format(
                    where=_where(elem, root), tag=elem.tag, attr=attr, value=value[:40]))


def _negative(elem: ET.Element, value: float) -> bool:
    """
    Whether a mass or moment is negative beyond rounding.

    Exporters write a zero as -5.4e-20 (iCub's hips): within a billionth of the element's
    largest moment (or 1e-12), a value below zero counts as the zero it is meant to be.
    """
    try:
        moments = [abs(float(elem.get(k) or 0)) for k in _NOT_NEGATIVE.get(elem.tag, ())]
    except ValueError:
        return False  # not a number: refused as such when its turn comes
    return value < -max(NEGATIVE_ROUNDING * max(moments), 1e-12)


def _check_mimics(joints: list) -> None:
    names = {j.get('name') for j in joints}
    leader = {}
    for j in joints:
        mimic = j.find('mimic')
        if mimic is None:
            continue
        name, of = j.get('name'), mimic.get('joint', '')
        if of == name:
            raise ResourceParseError(ERR_MIMIC_SELF.format(joint=name))
        if of not in names:  # robot_state_publisher takes it too; the joint moves freely
            log.warning('URDF: %s; the joint moves freely', ERR_MIMIC_UNKNOWN.format(
                joint=name, leader=of))
            j.remove(mimic)
            continue
        leader[name] = of
    for start in leader:
        seen, cur = [start], leader[start]
        while cur in leader:
            if cur in seen:
                raise ResourceParseError(ERR_MIMIC_LOOP.format(
                    joints=', '.join(repr(n) for n in seen[seen.index(cur):])))
            seen.append(cur)
            cur = leader[cur]


def _keep_visuals(root: ET.Element) -> None:
    """Keep visual geometry (MuJoCo's URDF default drops it) and keep links as bodies."""
    ext = root.find('mujoco')
    if ext is None:
        ext = ET.SubElement(root, 'mujoco')
    compiler = ext.find('compiler')
    if compiler is None:
        compiler = ET.SubElement(ext, 'compiler')
    # Fusing links welded to their parents would take frames from /tf and robot_description.
    compiler.set('fusestatic', 'false')
    compiler.set('discardvisual', 'false')
