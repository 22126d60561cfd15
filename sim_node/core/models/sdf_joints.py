"""
SDF joints made MJCF: the joints of a child body, what couples them, and loops closed.

``revolute`` and ``continuous`` a hinge, ``prismatic`` a slide, ``ball`` a ball,
``universal`` and ``revolute2`` two hinges (the second ``<name>_axis2``), ``screw`` a hinge
and a slide (``<name>_translation``) coupled by the thread's pitch (``screw_thread_pitch`` in m
a turn, right-handed, or the older ``thread_pitch`` in rad/m, left-handed), ``gearbox`` a hinge
(its gearing is not reproduced), ``fixed`` none. Each axis's ``<xyz>`` is expressed in the
joint frame (or its ``expressed_in`` frame; in SDF 1.4 and with ``use_parent_model_frame``,
the model frame); ``<limit>`` lower and upper a range where finite, ``effort`` the actuator
force range on the joint, ``velocity`` kept for its controllers; ``<dynamics>`` damping,
friction, spring stiffness and reference. SDF 1.11's ``<mimic>`` a joint equality
(``follower = multiplier (leader - reference) + offset``). A joint that closes a loop
(:func:`close`) becomes an equality constraint: ``fixed`` a weld, ``ball`` a connect,
``revolute`` and ``continuous`` two connects along the axis. A joint's sensors (a
``force_torque``) are kept as a URDF's ``<gazebo reference="<joint>">`` extension.
"""

import copy
from dataclasses import dataclass
import math
from typing import Callable, Optional
import xml.etree.ElementTree as ET

import numpy as np

from . import sdf_frames
from .sdf_frames import Pose, Scope
from .sdf_shapes import numbers
from ..base import quat
from ..base.errors import ResourceParseError

JOINT_KINDS = ('revolute', 'continuous', 'prismatic', 'ball', 'universal', 'revolute2',
               'screw', 'gearbox', 'fixed')
#: A limit this large or beyond means none (SDF's old defaults are +-1e16).
NO_LIMIT = 1e15
#: A joint whose lower and upper limits are equal is locked there (Gazebo's way); MuJoCo wants
#: a range whose ends differ, so it gets this much either side (rad or m).
LOCKED_GAP = 1e-6

ERR_KIND = '{where}: joint type {kind!r} is not an SDF joint type ({kinds})'
ERR_LINK = '{where}: its {end} {name!r} is not a link of the model {model!r}'
ERR_AXIS = '{where}: its axis <xyz> {xyz!r} has no direction'


@dataclass
class Joint:
    """One joint of a model, placed and its axes turned into the top model's frame."""

    scoped: str
    elem: ET.Element
    kind: str
    parent: str
    child: str
    pose: Pose
    axes: list
    where: str


def read(scope: Scope, name: str, elem: ET.Element, at: Pose, prefix: str) -> Joint:
    """Read joint `name` of `scope` (its model placed at `at` in the top model's frame)."""
    where = scope.where(elem)
    kind = (elem.get('type') or '').strip().lower()
    if kind not in JOINT_KINDS:
        raise ResourceParseError(ERR_KIND.format(where=where, kind=kind,
                                                 kinds=', '.join(JOINT_KINDS)))
    ends = {}
    for end in ('parent', 'child'):
        text = (elem.findtext(end) or '').strip()
        if text == 'world' and end == 'parent':
            ends[end] = ''
            continue
        if not text or not scope.has(text):
            raise ResourceParseError(ERR_LINK.format(where=where, end=end, name=text,
                                                     model=scope.name))
        link = scope.link_of(text)
        ends[end] = f'{prefix}{link}' if link else ''
    pose = sdf_frames.compose(at, scope.pose(name))
    axes = []
    for tag in ('axis', 'axis2'):
        axis = elem.find(tag)
        if axis is None:
            axes.append(None if tag == 'axis2' else (np.array([0.0, 0.0, 1.0]), None))
            continue
        xyz = np.asarray(numbers(axis.findtext('xyz'), (0, 0, 1), where, 'an axis <xyz>'))
        if not np.linalg.norm(xyz) > 1e-12:
            raise ResourceParseError(ERR_AXIS.format(where=where, xyz=axis.findtext('xyz')))
        frame = (axis.find('xyz').get('expressed_in', '') if axis.find('xyz') is not None
                 else '').strip()
        parent_frame = (axis.findtext('use_parent_model_frame') or '').strip().lower() in (
            'true', '1')
        if not frame and (scope.version < (1, 5) or (parent_frame and scope.version < (1, 7))):
            frame = sdf_frames.MODEL_FRAME
        turn = (sdf_frames.compose(at, scope.place(sdf_frames.identity(), frame, where))[1]
                if frame else pose[1])
        axes.append((quat.rotate(turn, xyz / np.linalg.norm(xyz)), axis))
    return Joint(f'{prefix}{name}', elem, kind, ends['parent'], ends['child'], pose, axes,
                 where)


def _limit(axis: Optional[ET.Element], tag: str, default: float, where: str) -> float:
    text = axis.findtext(f'limit/{tag}') if axis is not None else None
    if text is None or not text.strip():
        return default
    if text.strip().lower() in ('inf', '+inf', '-inf'):
        return math.copysign(math.inf, -1 if text.strip().startswith('-') else 1)
    return numbers(text, (default,), where, f'a joint <limit><{tag}>')[0]


def make(body: ET.Element, joint: Joint, link_pose: Pose, local: Callable[[str], str],
         built, body_of: dict, topics: Optional[Callable] = None) -> None:
    """
    Add a tree joint's MJCF joints to its child `body` (at `link_pose`), and what couples them.

    `built` (a :class:`.sdf_model.Built`) gains its equalities, limits, links and sensors;
    `local` names an element of the model; `topics` gives a sensor's default topic
    (:func:`.sdf_world.gz_topics`), or None.
    """
    name = local(joint.scoped)
    built.joint_links[name] = (body_of.get(joint.parent, 'world'), body_of[joint.child])
    sensors = joint.elem.findall('sensor')
    if sensors:
        ext = ET.Element('gazebo', reference=name)
        for sensor in sensors:
            ext.append(sensor_copy(sensor, sdf_frames.relative(link_pose, joint.pose),
                                   topics(joint.scoped, sensor, 'joint') if topics else ''))
        built.extensions.append(ext)
    if joint.kind == 'fixed':
        return
    pos = sdf_frames.relative(link_pose, joint.pose)[0]
    inv = quat.conj(link_pose[1])
    kinds = {'revolute': ['hinge'], 'continuous': ['hinge'], 'gearbox': ['hinge'],
             'prismatic': ['slide'], 'ball': ['ball'], 'universal': ['hinge', 'hinge'],
             'revolute2': ['hinge', 'hinge'], 'screw': ['hinge', 'slide']}[joint.kind]
    if joint.kind == 'gearbox':
        built.notes.append(f'{joint.where}: a gearbox joint turns as a revolute one (its gearing '
                           'is not reproduced)')
    made = []
    for k, mj in enumerate(kinds):
        axis_entry = joint.axes[1] if (k == 1 and joint.kind != 'screw') else joint.axes[0]
        if axis_entry is None:
            axis_entry = (np.array([0.0, 0.0, 1.0]), None)
        vec, axis = axis_entry
        suffix = '' if k == 0 else ('_translation' if joint.kind == 'screw' else '_axis2')
        j = ET.SubElement(body, 'joint', name=f'{name}{suffix}', type=mj, pos=_text(pos))
        if mj != 'ball':
            j.set('axis', _text(quat.rotate(inv, vec)))
        made.append(j)
        if joint.kind == 'screw' and k == 1:
            continue
        lo = _limit(axis, 'lower', -math.inf, joint.where)
        hi = _limit(axis, 'upper', math.inf, joint.where)
        if joint.kind in ('revolute', 'prismatic', 'universal', 'revolute2', 'gearbox') and \
                abs(lo) < NO_LIMIT and abs(hi) < NO_LIMIT:
            if lo <= hi:
                if lo == hi:  # Gazebo's way to lock a joint; MuJoCo's range must be open
                    lo, hi = lo - LOCKED_GAP, hi + LOCKED_GAP
                j.set('range', _text([lo, hi]))
                j.set('limited', 'true')
            else:
                built.notes.append(f'{joint.where}: its lower limit is above its upper: left '
                                   'unlimited')
        effort = _limit(axis, 'effort', math.inf, joint.where)
        if 0 < effort < NO_LIMIT:  # a negative one is not enforced, nor is 0 (drake: none)
            j.set('actuatorfrcrange', _text([-effort, effort]))
            j.set('actuatorfrclimited', 'true')
        velocity = _limit(axis, 'velocity', math.inf, joint.where)
        limits = {}
        if 0 <= velocity < NO_LIMIT:
            limits['velocity'] = velocity
        if 0 < effort < NO_LIMIT:
            limits['effort'] = effort
        if limits:
            built.joint_limits[j.get('name')] = limits
        dyn = axis.find('dynamics') if axis is not None else None
        if dyn is not None:
            for tag, attr in (('damping', 'damping'), ('friction', 'frictionloss'),
                              ('spring_stiffness', 'stiffness'), ('spring_reference',
                                                                  'springref')):
                text = dyn.findtext(tag)
                if text is not None and text.strip():
                    value = numbers(text, (0.0,), joint.where, f'a joint <{tag}>')[0]
                    if attr != 'springref' and value < 0:
                        raise ResourceParseError(f'{joint.where}: a <{tag}> below zero')
                    j.set(attr, f'{value:.12g}')
        mimic = axis.find('mimic') if axis is not None else None
        if mimic is not None:
            _mimic(j.get('name'), mimic, joint, local, built)
    if joint.kind == 'screw':
        pitch_text = joint.elem.findtext('screw_thread_pitch')
        if pitch_text is not None and pitch_text.strip():
            ratio = numbers(pitch_text, (1.0,), joint.where, 'a screw_thread_pitch')[0] / (
                2 * math.pi)
        else:
            legacy = numbers(joint.elem.findtext('thread_pitch'), (1.0,), joint.where,
                             'a thread_pitch')[0]
            ratio = -1.0 / legacy if legacy else 0.0
        built.equalities.append(ET.Element('joint', joint1=made[1].get('name'),
                                           joint2=made[0].get('name'),
                                           polycoef=_text([0, ratio, 0, 0, 0])))
    built.moving_joints += len(made)


def _mimic(follower: str, mimic: ET.Element, joint: Joint, local: Callable[[str], str],
           built) -> None:
    leader = (mimic.get('joint') or '').strip()
    if not leader:
        raise ResourceParseError(f'{joint.where}: a <mimic> without a leader joint')
    scope_prefix = joint.scoped.rpartition('::')[0]
    scoped = f'{scope_prefix}::{leader}' if scope_prefix else leader
    lead = local(scoped) + ('_axis2' if (mimic.get('axis') or '') == 'axis2' else '')
    m = numbers(mimic.findtext('multiplier'), (1.0,), joint.where, 'a mimic multiplier')[0]
    off = numbers(mimic.findtext('offset'), (0.0,), joint.where, 'a mimic offset')[0]
    ref = numbers(mimic.findtext('reference'), (0.0,), joint.where, 'a mimic reference')[0]
    built.equalities.append(ET.Element('joint', joint1=follower, joint2=lead,
                                       polycoef=_text([off - m * ref, m, 0, 0, 0])))


def close(joint: Joint, child_pose: Pose, body_of: dict, built) -> None:
    """Make a joint that closes a loop an equality constraint (see the module docstring)."""
    b1, b2 = body_of[joint.child], body_of.get(joint.parent, 'world')
    anchor = sdf_frames.relative(child_pose, joint.pose)[0]
    if joint.kind == 'fixed':
        built.equalities.append(ET.Element('weld', body1=b1, body2=b2))
    elif joint.kind == 'ball':
        built.equalities.append(ET.Element('connect', body1=b1, body2=b2, anchor=_text(anchor)))
    elif joint.kind in ('revolute', 'continuous'):
        axis = quat.rotate(quat.conj(child_pose[1]), joint.axes[0][0])
        for a in (anchor, anchor + 0.1 * axis):
            built.equalities.append(ET.Element('connect', body1=b1, body2=b2, anchor=_text(a)))
    else:
        built.notes.append(f'{joint.where}: a {joint.kind} joint closing a loop is left out')


def sensor_copy(sensor: ET.Element, pose: Pose, topic: str = '') -> ET.Element:
    """Return a copy of a ``<sensor>`` placed at `pose` (rpy), with `topic` if it names none."""
    out = copy.deepcopy(sensor)
    for p in out.findall('pose'):
        out.remove(p)
    placed = ET.Element('pose')
    placed.text = ' '.join(f'{float(v):.12g}' for v in list(pose[0]) + list(quat.to_rpy(pose[1])))
    out.insert(0, placed)
    if topic and not (out.findtext('topic') or '').strip():
        ET.SubElement(out, 'topic').text = topic
    return out


def _text(values) -> str:
    return ' '.join(f'{float(v):.12g}' for v in values)
