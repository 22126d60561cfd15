"""
The per-model index: every name <-> id and address table of one compiled model.

:func:`build` runs once per recompile; the result is frozen. It is the only place in the core
that turns names into MuJoCo ids and addresses, so nothing can hold an address of an older
model without holding that model's index too (compare ``index.generation``).
"""

from dataclasses import dataclass, replace
from typing import Iterable, Mapping, Optional

import mujoco
import numpy as np

from ..base.checks import closest_hint
from ..base.errors import NotFoundError
from ..base.records import (DeclaredCamera, DeclaredGeo, DeclaredImu, DeclaredLaser,
                            DeclaredOdometer, DeclaredWrench, DYNAMIC, EFFORT, EntityRecord,
                            GeomVisual, ModelInfo, ORIGIN_NUMERIC, POSITION, ROBOT, STATIC,
                            VELOCITY)
from ..devices import catalog, contacts
from ..models import description

ERR_UNKNOWN_ENTITY = 'no entity named {name!r}; existing: {names}'
ERR_UNKNOWN_JOINT = 'no commandable (hinge or slide) joint named {name!r}'
ERR_UNKNOWN_BODY = 'no body named {name!r}'

# Enum membership must be tested on ints: numpy ints and MuJoCo enums do not hash alike.
_ONE_DOF_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_JOINT_TRN = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
STATE_SPEC = int(mujoco.mjtState.mjSTATE_INTEGRATION)
#: The frame a root body with joints of its own is moved from (``<entity>/world``).
MOUNT = 'world'
_GEOM_TYPES = {int(mujoco.mjtGeom.mjGEOM_PLANE): 'plane',
               int(mujoco.mjtGeom.mjGEOM_SPHERE): 'sphere',
               int(mujoco.mjtGeom.mjGEOM_CAPSULE): 'capsule',
               int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): 'ellipsoid',
               int(mujoco.mjtGeom.mjGEOM_CYLINDER): 'cylinder',
               int(mujoco.mjtGeom.mjGEOM_BOX): 'box', int(mujoco.mjtGeom.mjGEOM_MESH): 'mesh'}


@dataclass(frozen=True)
class ModelIndex:
    """
    Names and addresses of one model generation.

    Arrays are (njoint,) over the commandable (hinge and slide) joints, in model order.
    """

    generation: int
    state_size: int
    body_names: tuple  # (nbody,) body 0 is 'world'
    body_ids: dict  # name -> id
    joint_names: tuple
    joint_index: dict  # name -> position in joint_names
    joint_ids: np.ndarray  # MuJoCo joint ids
    joint_qposadr: np.ndarray
    joint_dofadr: np.ndarray
    joint_actuators: tuple  # per joint: {mode: actuator id}
    geom_names: tuple  # (ngeom,) '' for unnamed
    entities: tuple  # EntityRecord, in model order
    entity_by_name: dict
    info: ModelInfo

    def entity(self, name: str) -> EntityRecord:
        rec = self.entity_by_name.get(name)
        if rec is None:
            raise NotFoundError(ERR_UNKNOWN_ENTITY.format(name=name,
                                                          names=list(self.entity_by_name)))
        return rec

    def body(self, name: str) -> int:
        b = self.body_ids.get(name)
        if b is None:
            raise NotFoundError(ERR_UNKNOWN_BODY.format(name=name))
        return b

    def entity_of_body(self, name: str) -> str:
        """Return the name of the entity (top-level body) a body belongs to."""
        return self.body_names[self.info.body_root[self.body(name)]]

    def joints(self, names: Iterable[str]) -> np.ndarray:
        """Positions of joint names in :attr:`joint_names`; unknown names raise."""
        idx = []
        for n in names:
            i = self.joint_index.get(n)
            if i is None:
                raise NotFoundError(ERR_UNKNOWN_JOINT.format(name=n)
                                    + closest_hint(n, self.joint_names))
            idx.append(i)
        return np.asarray(idx, dtype=int)


def build(m: mujoco.MjModel, generation: int, spawned: Mapping) -> ModelIndex:
    """
    Index a compiled model.

    :param spawned: entity name -> :class:`~sim_node.core.stepping.design.Spawned` for the
        entities spawned since load (their top-level bodies, description, namespace). Every
        other top-level body is an entity of its own.
    """
    names = tuple('world' if b == 0 else (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
                                          or f'body_{b}') for b in range(m.nbody))
    jids = [j for j in range(m.njnt) if int(m.jnt_type[j]) in _ONE_DOF_JOINTS]
    jnames = tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f'joint_{j}'
                   for j in jids)
    parent = m.body_parentid.copy()
    top_of = np.zeros(m.nbody, dtype=int)
    for b in range(1, m.nbody):  # parents come before children
        top_of[b] = b if parent[b] == 0 else top_of[parent[b]]
    # A spawned model may bring several top-level bodies: all belong to its root's entity.
    entity_root = np.arange(m.nbody)
    ids = {n: b for b, n in enumerate(names)}
    for rec in spawned.values():
        group = [ids[n] for n in rec.bodies if n in ids]
        entity_root[group] = group[0] if group else 0
    root_of = entity_root[top_of]
    root_of[0] = 0
    entities = _entity_records(m, names, root_of, spawned)
    joint_entity = tuple(names[root_of[m.jnt_bodyid[j]]] for j in jids)
    alias = _root_aliases(entities, spawned, set(joint_entity), m.nbody)
    mount = [''] * m.nbody
    for rec in entities:  # a root moved by joints of its own (not free), several top bodies
        jnt = range(m.body_jntadr[rec.root_body],
                    m.body_jntadr[rec.root_body] + m.body_jntnum[rec.root_body])
        tops = sum(1 for b in rec.body_ids if parent[b] == 0)
        if alias[rec.root_body] and (tops > 1 or any(int(m.jnt_type[j]) != _FREE
                                                     for j in jnt)):
            mount[rec.root_body] = f'{rec.name}/{MOUNT}'
    position = {j: i for i, j in enumerate(jids)}
    chains = tuple(
        replace(c, steps=tuple(
            (p, q, position[j], hinge, axis) for p, q, j, hinge, axis in c.steps))
        for rec in entities if alias[rec.root_body] and rec.name in set(joint_entity)
        and not getattr(spawned.get(rec.name), 'urdf', '')
        for c in description.chain_frames(m, rec.body_ids, alias[rec.root_body],
                                          mount[rec.root_body]))
    info = ModelInfo(
        generation=generation, timestep=float(m.opt.timestep), body_names=names,
        body_parent=parent, body_root=root_of, body_has_joint=m.body_jntnum > 0,
        body_local_pos=m.body_pos.copy(), body_local_quat_wxyz=m.body_quat.copy(),
        body_alias=alias, body_mount=tuple(mount), joint_names=jnames, geoms=_geom_visuals(m),
        entities=entities,
        cameras=catalog.cameras(m), sensors=catalog.sensors(m), sites=catalog.sites(m),
        joint_entity=joint_entity, chains=chains,
        link_frames=tuple((alias[rec.root_body], f'{rec.name}/world', *own.world_link)
                          for rec in entities for own in [spawned.get(rec.name)]
                          if own is not None and own.world_link and alias[rec.root_body]),
        lasers={d.site: d for rec in spawned.values() for d in rec.sensors
                if isinstance(d, DeclaredLaser)},
        wrenches={d.site: d for rec in spawned.values() for d in rec.sensors
                  if isinstance(d, DeclaredWrench)},
        imus={d.site: d for rec in spawned.values() for d in rec.sensors
              if isinstance(d, DeclaredImu)},
        odometers={d.site: d for rec in spawned.values() for d in rec.sensors
                   if isinstance(d, DeclaredOdometer)},
        cameras_declared={d.camera: d for rec in spawned.values() for d in rec.sensors
                          if isinstance(d, DeclaredCamera)},
        contacts=contacts.declared(m, spawned),
        geom_scoped=contacts.scoped(m, names, root_of, spawned),
        geom_body=m.geom_bodyid.copy(),
        ros2_control={n: rec.ros2_control for n, rec in spawned.items()
                      if rec.ros2_control is not None
                      and (rec.ros2_control.simulated or rec.ros2_control.topic_based)},
        gz_systems={n: (rec.namespace, rec.systems) for n, rec in spawned.items()
                    if rec.systems},
        geo={d.site: d for rec in spawned.values() for d in rec.sensors
             if isinstance(d, DeclaredGeo)},
        sensor_frames=tuple((d.site, d.frame) for rec in spawned.values() for d in rec.sensors
                            if getattr(d, 'own_frame', False)),
        spherical=_origin(m))
    return ModelIndex(
        generation=generation, state_size=mujoco.mj_stateSize(m, STATE_SPEC),
        body_names=names, body_ids=ids,
        joint_names=jnames, joint_index={n: i for i, n in enumerate(jnames)},
        joint_ids=np.array(jids, dtype=int),
        joint_qposadr=m.jnt_qposadr[jids].astype(int) if jids else np.zeros(0, int),
        joint_dofadr=m.jnt_dofadr[jids].astype(int) if jids else np.zeros(0, int),
        joint_actuators=_classify_actuators(m, jids),
        geom_names=tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or ''
                         for g in range(m.ngeom)),
        entities=entities, entity_by_name={e.name: e for e in entities}, info=info)


def _grouped(keys: np.ndarray) -> dict:
    """Return key -> the indices holding it, in order (one pass)."""
    out: dict = {}
    for i, k in enumerate(keys.tolist()):
        out.setdefault(k, []).append(i)
    return out


def _origin(m: mujoco.MjModel) -> Optional[tuple]:
    """Return the world's origin on the Earth as the model keeps it, or None (not said)."""
    try:
        return tuple(float(v) for v in m.numeric(ORIGIN_NUMERIC).data)
    except KeyError:
        return None


def _root_aliases(entities: tuple, spawned: Mapping, with_joints: set, nbody: int) -> tuple:
    """
    Return each root body's own frame ``<entity>/<root>`` (robots and spawned URDFs).

    ``<root>`` is the root body's name in its own model (a scene entity's: the entity's name;
    a spawned model's: its first top-level body's, before the spawn renamed it), so the
    entity's robot description has a root link that robot_state_publisher, given
    ``frame_prefix: <entity>/``, names as we do.
    """
    alias = [''] * nbody
    for rec in entities:
        own = spawned.get(rec.name)
        if rec.name in with_joints or (own is not None and own.urdf):
            alias[rec.root_body] = (own.root_link if own is not None else '') or \
                f'{rec.name}/{rec.name}'
    return tuple(alias)


def _classify_actuators(m: mujoco.MjModel, jids: list) -> tuple:
    """For each commandable joint: {mode: actuator id} of its single-joint actuators."""
    by_joint = {j: {} for j in jids}
    for a in range(m.nu):
        if m.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        j = int(m.actuator_trnid[a, 0])
        if j not in by_joint or m.actuator_dyntype[a] != mujoco.mjtDyn.mjDYN_NONE:
            continue
        bias = m.actuator_biasprm[a]
        if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE:
            mode = EFFORT
        elif bias[1] != 0:
            mode = POSITION
        elif bias[2] != 0:
            mode = VELOCITY
        else:
            continue
        by_joint[j].setdefault(mode, a)
    return tuple(by_joint[j] for j in jids)


def _geom_visuals(m: mujoco.MjModel) -> tuple:
    out = []
    # Read as Python lists once: a numpy scalar read per geom and field took 48 ms for a world
    # of 6,000 geoms.
    types, groups = m.geom_type.tolist(), m.geom_group.tolist()
    matids, bodies = m.geom_matid.tolist(), m.geom_bodyid.tolist()
    rgbas, mat_rgba = m.geom_rgba.tolist(), m.mat_rgba.tolist()
    sizes, poss, quats = m.geom_size.tolist(), m.geom_pos.tolist(), m.geom_quat.tolist()
    for g in range(m.ngeom):
        kind = _GEOM_TYPES.get(types[g])
        rgba = mat_rgba[matids[g]] if matids[g] >= 0 else rgbas[g]
        if kind is None or groups[g] > 2 or rgba[3] <= 0:
            continue
        verts = faces = None
        if kind == 'mesh':
            mid = m.geom_dataid[g]
            va, vn = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
            fa, fn = m.mesh_faceadr[mid], m.mesh_facenum[mid]
            verts = m.mesh_vert[va:va + vn].copy()
            faces = m.mesh_face[fa:fa + fn].copy()
        out.append(GeomVisual(
            name=mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f'geom_{g}',
            body=bodies[g], type=kind, size=tuple(sizes[g]),
            pos=tuple(poss[g]), quat_wxyz=tuple(quats[g]), rgba=tuple(rgba),
            mesh_vertices=verts, mesh_faces=faces))
    return tuple(out)


def _entity_records(m: mujoco.MjModel, names: tuple, root_of: np.ndarray,
                    spawned: Mapping) -> tuple:
    """One record per entity root, grouped in one pass over each array (O(n), not O(n^2))."""
    jroot = root_of[m.jnt_bodyid]
    groot = root_of[m.geom_bodyid]
    trn_joint = np.isin(m.actuator_trntype, _JOINT_TRN)
    aroot = np.where(trn_joint, jroot[np.where(trn_joint, m.actuator_trnid[:, 0], 0)], -1) \
        if m.nu else np.zeros(0, int)
    bodies, joints, geoms = _grouped(root_of), _grouped(jroot), _grouped(groot)
    actuated = set(aroot.tolist())
    jtype, jbody = m.jnt_type.tolist(), m.jnt_bodyid.tolist()
    recs = []
    for root in np.nonzero(root_of == np.arange(m.nbody))[0][1:] if m.nbody > 1 else []:
        root = int(root)
        own_joints = joints.get(root, ())
        has_free = any(jtype[j] == _FREE and jbody[j] == root for j in own_joints)
        other_joints = any(jtype[j] != _FREE for j in own_joints)
        category = ROBOT if other_joints or root in actuated else \
            DYNAMIC if has_free else STATIC
        name = names[root]
        own = spawned.get(name)
        recs.append(EntityRecord(
            name=name, category=category, root_body=root,
            body_ids=tuple(bodies.get(root, ())), geom_ids=tuple(geoms.get(root, ())),
            spawned=own is not None and not own.world,
            description=own.description if own is not None else 'from the scene',
            has_free_joint=has_free, namespace=own.namespace if own is not None else ''))
    return tuple(recs)
