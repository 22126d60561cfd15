"""
The model editor.

Every change to the MjSpec (attach, remove, add a body, contact settings, mass, moving welded
bodies). Functions of a spec (and, to read current values, a model); none compiles the live spec or
touches MjData: the world validates, applies and recompiles.
"""

import logging
from typing import Optional, Sequence

import mujoco
import numpy as np

from ..base import native, quat, thread_warnings
from ..base.errors import ResourceParseError
from ..base.records import EntityRecord
from ..base.surfaces import restitution_to_solref
from ..compiled.index import ModelIndex
from ..control import bases, interfaces, wheels
from ..control.gz_systems import velocity_joints
from ..models import sources
from ..stepping import design

log = logging.getLogger(__name__)

ERR_NO_BODY = ('the model has no body besides ground planes: put its geoms in a body to spawn '
               'them')

# Geoms with contact settings of their own win over geoms without (MuJoCo uses the higher
# priority geom's solref and friction instead of mixing them): defined with the design, which
# carries a geom's own settings across recompiles.
OWN_CONTACT_PRIORITY = design.OWN_CONTACT_PRIORITY

_BODY_TYPES = (int(mujoco.mjtObj.mjOBJ_BODY), int(mujoco.mjtObj.mjOBJ_XBODY))
# The frame a spawned entity is attached through: ``<entity>/__spawn_frame``.
SPAWN_FRAME = '__spawn_frame'
#: Integrators that take actuators' velocity gains explicitly: a stiff velocity loop diverges.
EXPLICIT = (mujoco.mjtIntegrator.mjINT_EULER, mujoco.mjtIntegrator.mjINT_RK4)
# Spec element lists swept by name prefix when an entity is removed (what its frame does not
# take with it).
_NAMED_KINDS = ('meshes', 'skins', 'hfields', 'textures', 'materials', 'tendons', 'actuators',
                'sensors', 'equalities', 'excludes', 'pairs', 'numerics', 'texts', 'tuples',
                'keys', 'flexes', 'frames')


def name_unnamed(spec: mujoco.MjSpec, taken: Optional[set] = None) -> None:
    """
    Give every unnamed element that has state or is looked up a name unique in `spec`.

    Bodies, joints, geoms, sites, actuators and equality constraints (not in `taken` either),
    e.g. ``geom_3``: the world looks elements up by name, an edit carries the live state over
    by name (:mod:`.transfer`: an unnamed actuator would lose its control), and an attached copy
    gets them under its prefix, so a model can be spawned any number of times.

    Joints, geoms and sites are gathered body by body, in the same order: MuJoCo's own lists of
    them took 0.9 s for a world of 3,000 shapes (growing faster than the world), its bodies'
    lists 0.1 s.
    """
    bodies = spec.bodies
    groups = (('body', bodies), ('joint', [j for b in bodies for j in b.joints]),
              ('geom', [g for b in bodies for g in b.geoms]),
              ('site', [s for b in bodies for s in b.sites]), ('actuator', spec.actuators),
              ('equality', spec.equalities))
    used = set(taken or ()) | {e.name for _, elems in groups for e in elems if e.name}
    for kind, elems in groups:
        i = 0
        for e in elems:
            if e.name:
                continue
            while f'{kind}_{i}' in used:
                i += 1
            e.name = f'{kind}_{i}'
            used.add(e.name)


def attach(spec: mujoco.MjSpec, name: str, source: sources.SpawnSource, pos: np.ndarray,
           quat_wxyz: np.ndarray, casters_roll: bool = True) -> tuple:
    """
    Attach a copy of a whole model to `spec` through a frame at a world pose.

    Every element comes along under the prefix ``name/``; the first top-level body is renamed
    `name` and is the entity's root. Whole-world furniture follows one rule: ground planes
    directly in the model's <worldbody> are dropped (logged); its other static geometry was
    gathered into a welded body by :mod:`sim_node.core.models.prepare`; its skybox is dropped
    too (the world has its sky); its lights, cameras and other assets come along;
    its keyframes are dropped (the world's keep working: the entity's part of them is its
    spawn state); its <option>, <size> and <visual> give way to the world's (MuJoCo logs each
    difference). Its <compiler> settings (angle units, asset folders) apply to it alone.
    A wheeled base gets velocity actuators for wheels that have none, and its fixed casters
    roll (:func:`.wheels.add_wheel_actuators`, :func:`.wheels.roll_casters`; `casters_roll`).

    :returns: (frame name, names of the entity's top-level bodies, root first, the root body's
        name in the model itself, the default classes it brought, outermost first).
    """
    child = source.spec.copy()
    planes = [g for g in child.worldbody.geoms if g.type == mujoco.mjtGeom.mjGEOM_PLANE]
    for g in planes:
        child.delete(g)
    if planes:
        log.info('spawning %r: dropped its ground plane(s) %s; the world has its own floor',
                 name, ', '.join(repr(g.name or '(unnamed)') for g in planes))
    for key in list(child.keys):
        child.delete(key)
    # A model's skybox: the world has its own sky, and MuJoCo draws one. An 800x800 skybox
    # (Gymnasium-Robotics' point) is 11 MB of texture generated on every compile of the world.
    used = {t for mat in child.materials for t in mat.textures if t}
    skies = [t for t in child.textures
             if t.type == mujoco.mjtTexture.mjTEXTURE_SKYBOX and t.name not in used]
    for t in skies:
        child.delete(t)
    if skies:
        log.info('spawning %r: dropped its skybox; the world has its own sky', name)
    name_unnamed(child)
    plugin = bases.drive_plugin(getattr(source.urdf_notes, 'extensions', ()))
    control = getattr(source.urdf_notes, 'ros2_control', None)
    # A ros2_control robot's wheels: those its velocity interfaces drive (held as a base's
    # wheels are, the gain set by the robot's mass); the others roll freely, as in Gazebo.
    # An SDF model's gz-sim systems hold the velocities they command as Gazebo does too.
    only = None if control is None or not control.simulated else {
        j.name for j in control.joints().values() if 'velocity' in j.command}
    held = {j.replace('::', '/') for s in getattr(source.urdf_notes, 'systems', ())
            for j in velocity_joints(s)}
    if held:
        only = (only or set()) | held
    added = wheels.add_wheel_actuators(
        child, plugin, explicit=spec.option.integrator in EXPLICIT, only=only,
        timestep=spec.option.timestep)
    added += wheels.hold_velocities(child, held, spec.option.timestep,
                                    explicit=spec.option.integrator in EXPLICIT)
    if added:
        log.info('spawning %r: its wheels have no actuators; added velocity actuators %s',
                 name, ', '.join(added))
    if source.kind in ('urdf', 'sdf'):  # <mimic> joints: as stiff as a step allows
        interfaces.stiffen_mimics(child, spec.option.timestep)
    if source.kind == 'sdf':  # and an SDF joint's stops (SDF's stiffness is 1e8 N/m)
        interfaces.stiffen_limits(child, spec.option.timestep)
    alone = wheels.Alone(child, source.assets)  # compiled once, if a rule below needs it
    servos = interfaces.add_position_servos(
        child, control, spec.option.timestep, explicit=spec.option.integrator in EXPLICIT,
        alone=alone)
    if servos:
        log.info('spawning %r: its position interfaces are held as gz_ros2_control holds '
                 'them (%s)', name, ', '.join(servos))
    casters = wheels.roll_casters(child, plugin, alone=alone) if casters_roll else []
    if casters:
        log.info('spawning %r: %s roll as casters (frictionless contacts; the node parameter '
                 'casters_roll turns this off)', name, ', '.join(casters))
    # Its default classes come along as <name>/<class>; a delete must remove them too.
    defaults = [f'{name}/main'] + [f'{name}/{c}' for c in source.default_classes
                                   if c != 'main']
    tops = [b.name for b in child.worldbody.bodies]
    if not tops:  # MJCF text has its static geometry gathered into a body; a spec built in
        raise ResourceParseError(ERR_NO_BODY)  # code must do that itself
    frame = spec.worldbody.add_frame(pos=pos.tolist(), quat=quat_wxyz.tolist())
    frame.name = f'{name}/{SPAWN_FRAME}'
    with thread_warnings.caught(design.ATTACH_CONFLICT) as conflicts:  # this thread's own
        spec.attach(child, prefix=f'{name}/', frame=frame)
    for text in conflicts:  # "Attach conflict ... keeping parent value", one per setting
        log.info('spawning %r: the world keeps its own settings: %s', name,
                 ' '.join(text.split()))
    old_root = f'{name}/{tops[0]}'
    spec.body(old_root).name = name
    _rename_body_references(spec, old_root, name)
    if source.assets:
        spec.assets = {**spec.assets, **source.assets}
    return (frame.name, (name,) + tuple(f'{name}/{t}' for t in tops[1:]), tops[0],
            tuple(defaults))


def remove(spec: mujoco.MjSpec, name: str, frame: str, assets: Sequence[str],
           defaults: Sequence[str] = ()) -> None:
    """
    Remove an attached entity.

    Its frame with everything attached through it (bodies, joints, geoms, lights, cameras;
    actuators, sensors, tendons, equality constraints, contact pairs and excludes that refer to
    them), every other element under its prefix (assets), and its in-memory assets.
    """
    if not native.delete_frame(spec, frame):  # the GIL let go: 26 ms for TIAGo's frame
        spec.delete(spec.frame(frame))
    prefix = f'{name}/'
    for kind in _NAMED_KINDS:
        for e in list(getattr(spec, kind, ())):
            if e.name.startswith(prefix):
                spec.delete(e)
    if assets:
        spec.assets = {k: v for k, v in spec.assets.items() if k not in assets}
    for cls in reversed(defaults):  # innermost first; a class may have gone with its parent
        found = spec.find_default(cls)
        if found is not None:
            spec.delete(found)


def find_overlap(model: mujoco.MjModel, data: mujoco.MjData, name: str,
                 tolerance: float) -> Optional[tuple]:
    """
    Where entity `name`, new in `model` (whose `data` holds the state).

    Would overlap existing geometry by more than `tolerance`: (other geom's name, depth) or None.

    Only pairs MuJoCo would make contact forces for count (geoms that can collide: contype
    and conaffinity, not excluded, not both welded to the world), since only those explode.

    The data's poses and contacts must be computed (``mj_fwdPosition`` or more): the caller
    computes them once for all it checks (a group of spawns). A spawn's commit
    checks with the world lock held, and each MuJoCo call gives the GIL away; under a storm
    of spawns the committing thread then waited for it back, the world lock held, for up to
    70 ms of a commit whose own work was 13 ms (``make bench-storm``).
    """
    try:
        root = model.body(name).id  # an accessor: keeps the GIL, as mj_name2id does not
    except KeyError:
        root = -1
    if root < 0 or not data.ncon:
        return None
    # All contacts at once (a world of 400 resting boxes has some 1,600, and each spawn of a
    # group is checked): the new entity's bodies are root.. (it was attached last).
    geoms = data.contact.geom[:data.ncon]
    dist = data.contact.dist[:data.ncon]
    mine = model.geom_bodyid[geoms] >= root
    hits = np.flatnonzero((mine[:, 0] != mine[:, 1]) & (dist < -tolerance))
    if not hits.size:
        return None
    first = int(hits[0])
    other = int(geoms[first, 1] if mine[first, 0] else geoms[first, 0])
    other_name = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, other)
                  or mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY,
                                       int(model.geom_bodyid[other])) or 'world')
    return other_name, float(-dist[first])


def add_child(spec: mujoco.MjSpec, parent: str, full: str, shape: str, size: list,
              pos: np.ndarray, quat_wxyz: np.ndarray, mass: float, joint: Optional[str],
              axis: np.ndarray, rgba: list) -> None:
    """
    Add a body with one primitive geom (see :func:`sources.primitive_size`) under `parent`.

    Welded or on a hinge/slide joint about `axis`.
    """
    body = spec.body(parent).add_body(name=full, pos=pos.tolist(), quat=quat_wxyz.tolist())
    if joint:
        body.add_joint(name=f'{full}/joint', axis=axis.tolist(), type=getattr(
            mujoco.mjtJoint, 'mjJNT_HINGE' if joint == 'hinge' else 'mjJNT_SLIDE'))
    geom = body.add_geom(name=f'{full}/geom', size=size,
                         type=getattr(mujoco.mjtGeom, f'mjGEOM_{shape.upper()}'), rgba=rgba)
    if mass:
        geom.mass = float(mass)


def apply_contact(spec: mujoco.MjSpec, geom_names: Sequence[str],
                  friction: Optional[np.ndarray], restitution: Optional[float],
                  priority: int) -> None:
    """
    Friction and/or restitution for geoms.

    Geoms given :data:`OWN_CONTACT_PRIORITY` win a contact with geoms of lower priority: MuJoCo
    then uses their solref and friction alone. Between two geoms of equal priority MuJoCo mixes
    them (solref averaged, the larger friction).
    """
    solref = None if restitution is None else restitution_to_solref(restitution)
    for name in geom_names:
        geom = spec.geom(name) if name else None
        if geom is None:
            continue
        if friction is not None:
            geom.friction = [float(f) for f in friction]
        if solref is not None:
            geom.solref = solref
        geom.priority = priority


def move_group(spec: mujoco.MjSpec, frame: Optional[str], body_name: str,
               model_pose: tuple, pos: np.ndarray, quat_wxyz: np.ndarray) -> None:
    """
    Move a welded entity so that its root body is at a world pose.

    A spawned entity by its frame (the welded bodies it came with move along), a scene entity by
    its body.

    :param model_pose: (pos (3,), quat (4,)): the root's compiled pose in the world
        (``model.body_pos``/``body_quat`` of a top-level body).
    """
    if frame is None:
        set_body_pose(spec.body(body_name), pos, quat_wxyz)
        return
    f = spec.frame(frame)
    # The root's pose in its frame, local = F^-1 * model_pose; the new frame is then
    # F' = target * local^-1.
    lpos, lquat = quat.to_frame(np.array(f.pos), np.array(f.quat), *model_pose)
    fquat = quat.mul(quat_wxyz, quat.conj(lquat))
    f.quat = fquat.tolist()
    f.pos = (pos - quat.rotate(fquat, lpos)).tolist()


def weld_in_place(spec: mujoco.MjSpec, frame: Optional[str], rec: EntityRecord,
                  pos: np.ndarray, quat_wxyz: np.ndarray) -> None:
    """
    Remove an entity's free joint.

    Its root body stays at the given world pose (where it is now), relative to its frame if it has
    one.
    """
    body = spec.body(rec.name)
    if frame is not None:
        f = spec.frame(frame)
        pos, quat_wxyz = quat.to_frame(np.array(f.pos), np.array(f.quat), pos, quat_wxyz)
    set_body_pose(body, pos, quat_wxyz)
    for j in list(body.joints):
        spec.delete(j)


def set_body_pose(body, pos: np.ndarray, quat_wxyz: np.ndarray) -> None:
    """
    Set a body's pose in its parent frame.

    As a quaternion (any other orientation form the file used is replaced).
    """
    body.pos, body.quat = list(map(float, pos)), list(map(float, quat_wxyz))
    body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT


def free(spec: mujoco.MjSpec, rec: EntityRecord) -> None:
    """Give a welded entity a free joint: it starts where it is, at rest."""
    spec.body(rec.name).add_freejoint(name=f'{rec.name}/free')


def scale_mass(spec: mujoco.MjSpec, model: mujoco.MjModel, index: ModelIndex,
               rec: EntityRecord, factor: float) -> None:
    """Scale the mass and inertia of every body of an entity by one factor."""
    for b in rec.body_ids:
        bs = spec.body(index.body_names[b])
        bs.explicitinertial = True
        bs.mass = float(model.body_mass[b] * factor)
        bs.inertia = (model.body_inertia[b] * factor).tolist()
        bs.ipos = model.body_ipos[b].tolist()
        bs.iquat = model.body_iquat[b].tolist()


def _rename_body_references(spec: mujoco.MjSpec, old: str, new: str) -> None:
    """After renaming a body, repoint every element that names it."""
    for ex in spec.excludes:
        if ex.bodyname1 == old:
            ex.bodyname1 = new
        if ex.bodyname2 == old:
            ex.bodyname2 = new
    for eq in spec.equalities:
        if int(eq.objtype) in _BODY_TYPES:
            if eq.name1 == old:
                eq.name1 = new
            if eq.name2 == old:
                eq.name2 = new
    for s in spec.sensors:
        if int(s.objtype) in _BODY_TYPES and s.objname == old:
            s.objname = new
        if int(s.reftype) in _BODY_TYPES and s.refname == old:
            s.refname = new
    for a in spec.actuators:
        if a.trntype == mujoco.mjtTrn.mjTRN_BODY and a.target == old:
            a.target = new
    for c in list(spec.cameras) + list(spec.lights):
        if c.targetbody == old:
            c.targetbody = new
    for skin in spec.skins:  # a skinned mesh's bones (dm_control's dog)
        bones = list(skin.bodyname)
        if old in bones:
            skin.bodyname = [new if b == old else b for b in bones]
