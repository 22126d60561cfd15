"""
An SDF ``<model>`` made MJCF bodies: its links a tree joined by its joints.

Nested models are flattened into their top model (their links and joints scoped
``nested/link``, placed by :class:`.sdf_frames.Scope`). The links form a tree from the roots
(links no joint moves, the model frame's canonical link's first): each link a body placed in
its parent's frame, each joint in its child's. A root floats (a free joint) unless the model is
``<static>`` (every link welded where it is) or a joint holds it to ``world`` (``fixed``:
welded; a revolute or prismatic one: it moves about the world). A joint that closes a loop
becomes an equality constraint: ``fixed`` a weld, ``ball`` a connect, ``revolute`` and
``continuous`` two connects along the axis.

Joints are :mod:`.sdf_joints`'. Links do not collide with each other unless the model or one
of the two links says ``<self_collide>``, as in Gazebo. A link with ``<gravity>false</gravity>``
is compensated against gravity.

Names: with an entity name the bodies are ``<entity>`` (the root) and ``<entity>/<link>`` and
every other element ``<entity>/<name>``, as a spawn's attach makes them; without one, the
model's own names (a source a spawn attaches).
"""

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional
import xml.etree.ElementTree as ET

from . import sdf_frames, sdf_joints, sdf_parts
from .sdf_frames import Pose, Scope
from .sdf_read import FOLDER
from .sdf_shapes import Assets, numbers
from ..base.errors import ResourceParseError

ERR_SELF = '{where}: its parent and child are the same link'
ERR_NO_LINK = 'the model {model!r} has no <link>: nothing to make of it'


@dataclass
class _Link:
    scoped: str
    elem: ET.Element
    pose: Pose
    static: bool
    scope: Scope
    local: str
    folder: Optional[str]


@dataclass
class Built:
    """
    What one model made (see the module docstring).

    :param bodies: the top-level MJCF ``<body>`` elements, the root first.
    :param extensions: what the model declares beyond its bodies, as a URDF's extension
        elements are kept (:mod:`.urdf_declared`, :mod:`.ros2_control`, the drive plugins):
        ``<gazebo reference="<body>">`` holding a link's (or joint's) sensors, placed in its
        frame; ``<gazebo>`` holding the model's plugins; its ``<ros2_control>`` blocks.
    :param collisions: geom name -> the collision's own name (Gazebo scopes contacts by it).
    :param decompose: geom name -> (``optimization``, most hulls) of mesh collisions that say.
    """

    name: str
    bodies: list = field(default_factory=list)
    equalities: list = field(default_factory=list)
    excludes: list = field(default_factory=list)
    extensions: list = field(default_factory=list)
    joint_limits: dict = field(default_factory=dict)
    joint_links: dict = field(default_factory=dict)
    collisions: dict = field(default_factory=dict)
    decompose: dict = field(default_factory=dict)
    mesh_colour: list = field(default_factory=list)
    root_link: str = ''
    #: The model's joints by their SDF names (a nested model's ``nested::joint``).
    joint_names: list = field(default_factory=list)
    static: bool = False
    moving_joints: int = 0
    notes: list = field(default_factory=list)


class _Names:
    """The names of a model's elements: its own, or under an entity's."""

    def __init__(self, entity: str):
        self.entity = entity

    def local(self, scoped: str) -> str:
        own = scoped.replace('::', '/')
        return f'{self.entity}/{own}' if self.entity else own

    def body(self, scoped: str, root: bool) -> str:
        return self.entity if root and self.entity else self.local(scoped)


def _flatten(scope: Scope, at: Pose, static: bool, prefix: str, folder: Optional[str],
             links: dict, joints: list) -> None:
    """Gather the links and joints of `scope` and its nested models, placed in the top frame."""
    static = static or (scope.model.findtext('static') or '').strip().lower() in ('true', '1')
    folder = scope.model.get(FOLDER) or folder
    for name, elem in scope.elems.items():
        scoped = f'{prefix}{name}'
        if elem.tag == 'link' and name == 'world' and not prefix and not len(
                [e for e in elem if e.tag in ('collision', 'visual')]):
            continue  # pybullet's files name the world a link: joints to it are to the world
        if elem.tag == 'link':
            links[scoped] = _Link(scoped, elem, sdf_frames.compose(at, scope.pose(name)),
                                  static, scope, name, folder)
        elif elem.tag == 'joint':
            joints.append(sdf_joints.read(scope, name, elem, at, prefix))
        elif elem.tag == 'model':
            _flatten(scope.nested[name], sdf_frames.compose(at, scope.pose(name)), static,
                     f'{scoped}::', folder, links, joints)


def build(model: ET.Element, version: tuple, out: Assets, entity: str = '',
          at: Optional[Pose] = None, topics=None) -> Built:
    """
    Return the MJCF of one model (see the module docstring).

    :param entity: the entity's name in a world made as one document ('' : own names).
    :param at: where the model frame is (in the world: its pose; None: at the origin).
    :param topics: ``topics(link, sensor)`` the sensor's topic when it names none, or None
        (``topics(joint, sensor, 'joint')`` for a joint's).
    """
    scope = Scope(model, version)
    links, joints = {}, []
    _flatten(scope, at or sdf_frames.identity(), False, '', None, links, joints)
    if not links:
        raise ResourceParseError(ERR_NO_LINK.format(model=scope.name))
    names = _Names(entity)
    built = Built(name=scope.name, joint_names=[j.scoped for j in joints])
    built.static = all(link.static for link in links.values())
    canonical = scope.canonical() or next(iter(links))
    tree, closures = _tree(links, joints, canonical)
    bodies, body_of = {}, {}
    for scoped, parent, joint in tree:
        link = links[scoped]
        name = names.body(scoped, not body_of)
        if not body_of:
            built.root_link = scoped.replace('::', '/')
        body_of[scoped] = name
        base = links[parent].pose if parent is not None else sdf_frames.identity()
        pos, q = sdf_frames.relative(base, link.pose)
        body = ET.Element('body', name=name)
        _set_pose(body, (pos, q))
        (built.bodies if parent is None else bodies[parent]).append(body)
        bodies[scoped] = body
        floating = parent is None and joint is None and not link.static
        if floating:
            ET.SubElement(body, 'freejoint', name=names.local(f'{scoped}_floating'))
        if joint is not None and not link.static:
            sdf_joints.make(body, joint, link.pose, names.local, built, body_of, topics)
        moving = floating or (joint is not None and joint.kind != 'fixed' and not link.static)
        _fill(body, link, names, built, out, moving, topics)
    for joint in closures:
        sdf_joints.close(joint, links[joint.child].pose, body_of, built)
    _self_collide(scope, links, tree, body_of, built)
    return built


def _tree(links: dict, joints: list, canonical: str) -> tuple:
    """Return ([(link, parent link or None, joint or None)] parents first, loop closures)."""
    incoming: dict = {}
    world: dict = {}
    outgoing: dict = {}
    closures = []
    for j in joints:
        if j.child == j.parent:
            raise ResourceParseError(ERR_SELF.format(where=j.where))
        if j.child not in links:
            raise ResourceParseError(sdf_joints.ERR_LINK.format(
                where=j.where, end='child', name=j.child, model=''))
        if not j.parent:
            if j.child in world:
                closures.append(j)
            else:
                world[j.child] = j
            continue
        incoming.setdefault(j.child, []).append(j)
        outgoing.setdefault(j.parent, []).append(j)
    roots = [n for n in links if n not in incoming]
    start = canonical
    seen = {start}
    while start in incoming and incoming[start][0].parent not in seen:
        start = incoming[start][0].parent
        seen.add(start)
    order = ([start] if start in roots else []) + [n for n in roots if n != start]
    tree, placed, used = [], set(), set()
    pending = list(order)
    while len(placed) < len(links):
        if not pending:  # a loop with no root: its first link is one
            pending = [start if start not in placed
                       else next(n for n in links if n not in placed)]
        root = pending.pop(0)
        if root in placed:
            continue
        queue = [(root, None, world.get(root))]
        while queue:
            name, parent, joint = queue.pop(0)
            if name in placed:
                if joint is not None and id(joint) not in used:
                    closures.append(joint)
                    used.add(id(joint))
                continue
            placed.add(name)
            if joint is not None:
                used.add(id(joint))
            tree.append((name, parent, joint))
            queue += [(j.child, name, j) for j in outgoing.get(name, ())]
    closures += [j for j in joints if id(j) not in used and j not in closures]
    return tree, closures


def _text(values) -> str:
    return ' '.join(f'{float(v):.12g}' for v in values)


def _fill(body: ET.Element, link: _Link, names: _Names, built: Built, out: Assets,
          moving: bool, topics) -> None:
    """Give a link's body its inertial, geoms, lights, and its sensors as extensions."""
    elem, where = link.elem, link.scope.where(link.elem)
    folder = Path(link.folder) if link.folder else None
    auto = elem.find('inertial') is not None and (
        elem.find('inertial').get('auto') or '').strip().lower() in ('true', '1')
    inertial = sdf_parts.inertial(elem, where, moving, built.notes)
    mass = float(inertial.get('mass')) if inertial is not None else 0.0
    if inertial is not None:
        body.insert(0, inertial)
    if (elem.findtext('gravity') or '').strip().lower() in ('false', '0'):
        body.set('gravcomp', '1')
    here = link.scope.pose(link.local)
    hidden = elem.find('visual') is not None
    local = link.scoped.replace('::', '/')
    used: set = set()
    for kind in ('collision', 'visual'):
        for part in elem.findall(kind):
            own = part.get('name') or kind
            name, i = names.local(f'{local}/{own}'), 0
            while name in used:  # a visual named as a collision, or a name given twice
                i += 1
                name = names.local(f'{local}/{own}_{kind if i == 1 else f"{kind}{i}"}')
            used.add(name)
            w = f'{kind} {own!r} of link {link.scoped!r}'
            pose = sdf_frames.relative(here, link.scope.place(
                sdf_frames.parse_pose(part.find('pose'), w),
                sdf_frames.pose_attr(part.find('pose'), link.scope.version) or link.local, w))
            if kind == 'collision':
                made = sdf_parts.collision(part, name, w, folder, out, hidden, mass, auto)
                if made is None:
                    continue
                geom, optimization = made
                built.collisions[name[len(names.entity) + 1:] if names.entity else name] = own
                if optimization[0]:
                    built.decompose[name] = optimization
            else:
                made = sdf_parts.visual(part, name, w, folder, out)
                if made is None:
                    continue
                geom, from_file = made
                if from_file:
                    built.mesh_colour.append(geom)
            _place(geom, pose)
            body.append(geom)
    for light in elem.findall('light'):
        w = f'light {light.get("name")!r} of link {link.scoped!r}'
        pose = sdf_frames.relative(here, link.scope.place(
            sdf_frames.parse_pose(light.find('pose'), w),
            sdf_frames.pose_attr(light.find('pose'), link.scope.version) or link.local, w))
        body.append(sdf_parts.light(light, pose, names.local(
            f'{local}/{light.get("name") or "light"}'), w))
    sensors = elem.findall('sensor')
    if sensors:
        ext = ET.Element('gazebo', reference=body.get('name'))
        for sensor in sensors:
            w = f'sensor {sensor.get("name")!r} of link {link.scoped!r}'
            pose = sdf_frames.relative(here, link.scope.place(
                sdf_frames.parse_pose(sensor.find('pose'), w),
                sdf_frames.pose_attr(sensor.find('pose'), link.scope.version) or link.local, w))
            ext.append(sdf_joints.sensor_copy(
                sensor, pose, topics(link.scoped, sensor) if topics is not None else ''))
        built.extensions.append(ext)


def _place(geom: ET.Element, pose: Pose) -> None:
    """Put a geom at `pose` in its body, after any placement of its own shape (a plane)."""
    own = (tuple(numbers(geom.get('pos'), (0, 0, 0))), tuple(numbers(geom.get('quat'),
                                                                     (1, 0, 0, 0))))
    _set_pose(geom, sdf_frames.compose(pose, own))


def _set_pose(elem: ET.Element, pose: Pose) -> None:
    """Give an MJCF element its pos and quat, leaving out what is MuJoCo's default."""
    pos, q = pose
    if any(abs(v) > 1e-15 for v in pos):
        elem.set('pos', _text(pos))
    elif 'pos' in elem.attrib:
        del elem.attrib['pos']
    if abs(q[0]) < 1.0 - 1e-15 or any(abs(v) > 1e-15 for v in q[1:]):
        elem.set('quat', _text(q))
    elif 'quat' in elem.attrib:
        del elem.attrib['quat']


def _self_collide(scope: Scope, links: dict, tree: list, body_of: dict, built: Built) -> None:
    """Exclude contacts between the model's links that do not self-collide (SDF's default)."""
    model_flag = (scope.model.findtext('self_collide') or '').strip().lower() in ('true', '1')
    solid = []
    for scoped, _, _ in tree:
        link = links[scoped]
        if link.elem.find('collision') is None:
            continue
        own = (link.elem.findtext('self_collide') or '').strip().lower()
        solid.append((body_of[scoped], own in ('true', '1') if own else model_flag))
    for i, (a, fa) in enumerate(solid):
        for b, fb in solid[i + 1:]:
            if not (fa or fb):
                built.excludes.append(ET.Element('exclude', body1=a, body2=b))
