"""
SDF's poses and frames: every link, joint, frame and nested model placed in its model's frame.

A ``<pose>`` is ``x y z roll pitch yaw`` (radians, or degrees with ``degrees="true"``; or
``x y z qx qy qz qw`` with ``rotation_format="quat_xyzw"``), expressed in the frame its
``relative_to`` names, else in a default that depends on the element (SDF 1.7's pose frame
semantics, which sdformat applies to older files once converted):

* a link, a nested model, and a frame without ``attached_to``: the model frame (``__model__``);
* a frame: the frame it is ``attached_to``;
* a joint: its child link;
* a collision, visual, sensor, light or inertial: its link.

In SDF 1.5 and 1.6 the attribute was called ``frame``; before 1.7 nothing could be named but
these defaults. ``relative_to`` may name any frame of the element's own model (a link, joint,
frame, nested model, ``__model__``) and, from 1.8, a frame inside a nested model
(``arm::gripper::tip``). A model's ``placement_frame`` says which of its frames its pose puts
there (the model frame moves to match). A model frame is attached to its canonical link (its
``canonical_link`` attribute, else its first link, else its first nested model's).

:class:`Scope` resolves one model's graph (cycles and unknown names refused, naming them);
:func:`parse_pose` reads one ``<pose>``, refusing a value that is not finite. Poses are
``((x, y, z), (w, x, y, z))`` tuples of floats (:func:`.base.quat.pose_mul`: a world of
3,000 models composes tens of thousands of them).
"""

import math
from typing import Dict, Optional, Tuple
import xml.etree.ElementTree as ET

from .sdf_read import VERSION
from ..base import quat
from ..base.errors import ResourceParseError

Pose = Tuple[tuple, tuple]
MODEL_FRAME = '__model__'
#: Elements whose names are frames of their model.
FRAME_KINDS = ('link', 'joint', 'frame', 'model')

ERR_POSE = ('{where}: <pose>{text}</pose> is not {n} finite numbers ({form}); give '
            'x y z roll pitch yaw')
ERR_UNKNOWN = ('{where}: relative_to {name!r} names no frame of the model {model!r} (its '
               'links, joints, frames, nested models or __model__)')
ERR_CYCLE = 'the poses of the model {model!r} are relative to each other in a loop: {chain}'
ERR_ATTACHED = '{where}: attached_to {name!r} names no frame of the model {model!r}'
ERR_ATTACH_CYCLE = ('the frames of the model {model!r} are attached to each other in a loop: '
                    '{chain}')
ERR_TWICE = ('the {model} names two elements {name!r} (its links, joints, frames and models '
             'share one set of names)')


_IDENTITY = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))


def identity() -> Pose:
    return _IDENTITY


def compose(a: Pose, b: Pose) -> Pose:
    """Return ``a * b``: pose `b` (given in frame `a`) in `a`'s parent frame."""
    if b is _IDENTITY:  # most elements have no pose of their own
        return a
    if a is _IDENTITY:
        return b
    return quat.pose_mul(a, b)


def inverse(a: Pose) -> Pose:
    return quat.pose_inv(a)


def relative(a: Pose, b: Pose) -> Pose:
    """Return `b` (given in the same frame as `a`) in frame `a`: ``a^-1 * b``."""
    return quat.pose_mul(quat.pose_inv(a), b)


def parse_pose(elem: Optional[ET.Element], where: str) -> Pose:
    """Return the pose of a ``<pose>`` element (identity for None or an empty one)."""
    if elem is None or not (elem.text or '').strip():
        return identity()
    text = (elem.text or '').strip()
    form = (elem.get('rotation_format') or 'euler_rpy').strip()
    n = 7 if form == 'quat_xyzw' else 6
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise ResourceParseError(ERR_POSE.format(where=where, text=text[:80], n=n, form=form))
    pos = tuple(values[:3])
    if n == 7:
        q = (values[6], values[3], values[4], values[5])
        norm = math.sqrt(sum(c * c for c in q))
        if norm < 1e-9:
            raise ResourceParseError(ERR_POSE.format(where=where, text=text[:80], n=n,
                                                     form='a zero quaternion'))
        return pos, tuple(c / norm for c in q)
    rpy = values[3:]
    if (elem.get('degrees') or '').strip().lower() in ('true', '1'):
        rpy = [math.radians(v) for v in rpy]
    return pos, quat.rpy_quat(*rpy)


def pose_attr(elem: Optional[ET.Element], version: tuple) -> str:
    """Return the frame a ``<pose>`` names (``relative_to``; 1.5 and 1.6: ``frame``), or ''."""
    if elem is None:
        return ''
    name = elem.get('relative_to', '')
    if not name and version < (1, 7):
        name = elem.get('frame', '')
    return name.strip()


def version_of(elem: ET.Element, default: tuple = (1, 11)) -> tuple:
    """Return the SDF version the reader tagged an element's file with."""
    text = elem.get(VERSION, '')
    try:
        major, minor = text.split('.')
        return int(major), int(minor)
    except ValueError:
        return default


class Scope:
    """
    The frames of one ``<model>``: each one's pose in the model frame, and what it moves with.

    :param model: the ``<model>`` element (includes expanded), or a ``<world>``: its models
        and frames, placed in the world frame (named ``world`` there).
    :param version: its file's SDF version.
    """

    def __init__(self, model: ET.Element, version: tuple):
        self.model = model
        self.name = model.get('name', '')
        self.version = version
        self.root = 'world' if model.tag == 'world' else MODEL_FRAME
        self.elems: Dict[str, ET.Element] = {}
        self.nested: Dict[str, 'Scope'] = {}
        for e in model:
            if e.tag not in FRAME_KINDS:
                continue
            name = e.get('name', '')
            if name in self.elems or name == self.root:
                raise ResourceParseError(ERR_TWICE.format(
                    model=f'{model.tag} {self.name!r}', name=name))
            self.elems[name] = e
            if e.tag == 'model':
                self.nested[name] = Scope(e, version_of(e, version))
        self._poses: Dict[str, Pose] = {self.root: identity()}
        self._placed: Dict[str, Pose] = {}

    # ---------------------------------------------------------------- poses

    def where(self, elem: ET.Element) -> str:
        return f'{elem.tag} {elem.get("name", "")!r} of the model {self.name!r}'

    def pose(self, name: str) -> Pose:
        """Return the pose of frame `name` (scoped with ``::``) in this model's frame."""
        return self._resolve(name, [])

    def place(self, pose: Pose, relative_to: str, where: str) -> Pose:
        """Return a pose given relative to frame `relative_to` of this model, in its frame."""
        return compose(self._frame(relative_to, where, []), pose)

    def placement(self) -> Pose:
        """Return the pose of this model's placement frame in its own frame (identity if none)."""
        name = (self.model.get('placement_frame') or '').strip()
        return self.pose(name) if name else identity()

    def _frame(self, name: str, where: str, chain: list) -> Pose:
        name = name or self.root
        if not self.has(name):
            raise ResourceParseError(ERR_UNKNOWN.format(where=where, name=name,
                                                        model=self.name))
        return self._resolve(name, chain)

    def has(self, name: str) -> bool:
        if name == self.root or name in self.elems:
            return True
        head, sep, rest = name.partition('::')
        return bool(sep) and head in self.nested and self.nested[head].has(rest)

    def _resolve(self, name: str, chain: list) -> Pose:
        done = self._poses.get(name)
        if done is not None:
            return done
        head, sep, rest = name.partition('::')
        if sep:
            if head not in self.nested:
                raise ResourceParseError(ERR_UNKNOWN.format(where=f'the model {self.name!r}',
                                                            name=name, model=self.name))
            out = compose(self._resolve(head, chain), self.nested[head].pose(rest))
            self._poses[name] = out
            return out
        if name in chain:
            raise ResourceParseError(ERR_CYCLE.format(
                model=self.name, chain=' -> '.join(chain[chain.index(name):] + [name])))
        elem = self.elems.get(name)
        if elem is None:
            raise ResourceParseError(ERR_UNKNOWN.format(where=f'the model {self.name!r}',
                                                        name=name, model=self.name))
        where = self.where(elem)
        pose_elem = elem.find('pose')
        own = parse_pose(pose_elem, where)
        base = pose_attr(pose_elem, self.version) or self._default_base(elem)
        if elem.tag == 'model':  # its pose puts its placement frame; its frame follows
            own = compose(own, inverse(self.nested[name].placement()))
        out = compose(self._frame(base, where, chain + [name]), own)
        self._poses[name] = out
        return out

    def _default_base(self, elem: ET.Element) -> str:
        if elem.tag == 'joint':
            return (elem.findtext('child') or '').strip() or self.root
        if elem.tag == 'frame' and self.version >= (1, 7):
            return (elem.get('attached_to') or '').strip() or self.root
        return self.root

    # ---------------------------------------------------------------- attachment

    def canonical(self) -> str:
        """Return the scoped name of the link this model's frame is attached to ('' if none)."""
        name = (self.model.get('canonical_link') or '').strip()
        if name:
            return self.link_of(name)
        links = [n for n, e in self.elems.items() if e.tag == 'link']
        if links:
            return links[0]
        for n, s in self.nested.items():
            inner = s.canonical()
            if inner:
                return f'{n}::{inner}'
        return ''

    def link_of(self, name: str, chain: Optional[list] = None) -> str:
        """Return the scoped link a frame of this model moves with ('' : the world)."""
        chain = chain or []
        if name in ('', MODEL_FRAME):
            return self.canonical()
        if name == 'world':
            return ''
        head, sep, rest = name.partition('::')
        if sep:
            if head not in self.nested:
                raise ResourceParseError(ERR_ATTACHED.format(where=f'the model {self.name!r}',
                                                             name=name, model=self.name))
            inner = self.nested[head].link_of(rest)
            return f'{head}::{inner}' if inner else ''
        elem = self.elems.get(name)
        if elem is None:
            raise ResourceParseError(ERR_ATTACHED.format(where=f'the model {self.name!r}',
                                                         name=name, model=self.name))
        if name in chain:
            raise ResourceParseError(ERR_ATTACH_CYCLE.format(
                model=self.name, chain=' -> '.join(chain + [name])))
        if elem.tag == 'link':
            return name
        if elem.tag == 'model':
            inner = self.nested[name].canonical()
            return f'{name}::{inner}' if inner else ''
        if elem.tag == 'joint':
            return self.link_of((elem.findtext('child') or '').strip(), chain + [name])
        return self.link_of((elem.get('attached_to') or '').strip(), chain + [name])
