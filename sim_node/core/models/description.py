"""
URDF robot descriptions of the world's entities, for robot_state_publisher, RViz and MoveIt.

An entity spawned from URDF is described by its own text (:func:`renamed_urdf`: its joints
renamed as the spawn renamed them). Any other entity with joints is described from the compiled
model (:func:`from_model`):

* one link per body. A link's name is its frame without the ``<entity>/`` prefix, so
  robot_state_publisher with ``frame_prefix: <entity>/`` names every link as ``/tf`` does; the
  root link is the root body's frame ``<entity>/<root>`` (:attr:`.records.ModelInfo.body_alias`);
* hinge -> revolute (continuous when unlimited), slide -> prismatic, welded -> fixed,
  ball and free -> floating (robot_state_publisher cannot move those: their bodies' frames come
  from ``/tf`` only). Joint names are those on ``joint_states``. MuJoCo turns a body about each
  joint's anchor, in order, by ``qpos - qpos0``; URDF turns a child link about its joint's
  origin by the joint value. A body whose joint is off its origin, or that has several joints,
  therefore gets an intermediate link per joint (``<link>/<joint>``, on ``/tf`` through
  :func:`chain_frames`) and a fixed joint back to the body's own link; a joint's ``ref`` is
  folded into its origin;
* ``<limit>``: the joint's range; effort from the joint's or its actuator's force range;
  velocity 0 (MuJoCo has no velocity limit; MoveIt reads its own from joint_limits.yaml).
  An unlimited slide is written with +-1e6 m, as URDF requires bounds for prismatic joints;
* inertials as compiled (principal axes); visual geometry for visible geoms (groups 0-2),
  collision geometry for geoms that collide. Boxes, spheres and cylinders as themselves, a
  capsule as a cylinder and two spheres, an ellipsoid and a mesh as binary STL files written
  under `mesh_dir` (named by content, written once) and named by ``file://`` URIs, which RViz
  reads on the same machine. Planes and height fields are left out.
"""

import copy
from dataclasses import dataclass
import hashlib
import os
from pathlib import Path
import tempfile
from typing import Optional, Sequence
from xml.etree import ElementTree as ET  # writing only: parsing goes through defusedxml

import defusedxml.ElementTree as SafeET
import mujoco
import numpy as np

from ..base import quat as rotations

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
_BOX, _SPHERE, _CAPSULE, _CYLINDER, _ELLIPSOID, _MESH = (
    int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_SPHERE),
    int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER),
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID), int(mujoco.mjtGeom.mjGEOM_MESH))
UNLIMITED_SLIDE_M = 1e6
_EPS = 1e-12


class Descriptions:
    """
    The URDF text of entities built from a model, kept until what an entity is made of changes.

    Every new model asks again for every entity (a spawn elsewhere recompiles the world, not
    this entity): the text is written again only when the entity's own part of the model is.
    """

    def __init__(self):
        self._known: dict = {}  # entity -> (what it was made of, its URDF text)

    def of(self, name: str, model: mujoco.MjModel, info, rec, mesh_dir: Optional[str]) -> str:
        """Return the URDF of entity `rec` (named `name`) of `model` (see :func:`from_model`)."""
        alias, mount = info.body_alias[rec.root_body], info.body_mount[rec.root_body]
        key = (model_key(model, rec.body_ids), alias, mount, mesh_dir)
        known = self._known.get(name)
        if known is not None and known[0] == key:
            return known[1]
        text = from_model(model, rec.body_ids, alias, mount,
                          None if mesh_dir is None else Path(mesh_dir))
        if len(self._known) > 4 * len(info.entities) + 16:  # of entities gone
            self._known.clear()
        self._known[name] = (key, text)
        return text


def renamed_urdf(text: str, entity: str) -> str:
    """Return a spawned URDF as given, its joints named as on joint_states (``<entity>/<j>``)."""
    root = SafeET.fromstring(text)
    for joint in root.iter('joint'):  # <robot><joint> and <transmission><joint>
        if joint.get('name'):
            joint.set('name', f'{entity}/{joint.get("name")}')
    for mimic in root.iter('mimic'):
        if mimic.get('joint'):
            mimic.set('joint', f'{entity}/{mimic.get("joint")}')
    return ET.tostring(root, encoding='unicode')


def link_name(entity: str, body_name: str) -> str:
    """Return the link of a non-root body: its frame (``<entity>/<name>``) less the prefix."""
    prefix = entity + '/'
    return body_name[len(prefix):] if body_name.startswith(prefix) else body_name


def from_model(m: mujoco.MjModel, bodies: Sequence[int], root_frame: str,
               mount_frame: str = '', mesh_dir: Optional[Path] = None) -> str:
    """
    Return the URDF of one entity, from a compiled model.

    :param bodies: the entity's bodies in model order, its root first.
    :param root_frame: the root body's own frame, ``<entity>/<root link>``.
    :param mount_frame: ``<entity>/world``, a frame at the world's origin, for an entity whose
        root body has joints of its own or that has several top-level bodies: the URDF's root
        link, which its top-level bodies hang from by their joints.
    :param mesh_dir: where mesh and ellipsoid geometry is written as STL (None: left out).
    """
    entity, links, mount, taken = _links(m, bodies, root_frame, mount_frame)
    robot = ET.Element('robot', name=entity)
    joint_names = set()
    writer = _Writer(m, mesh_dir)
    if mount:
        ET.SubElement(robot, 'link', name=mount)
    for b in bodies:
        link = ET.SubElement(robot, 'link', name=links[b])
        _inertial(m, b, link)
        for g in range(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b]):
            writer.geom(g, link)
    for b in bodies[0 if mount else 1:]:
        parent = int(m.body_parentid[b])
        steps, fixed = _chain(m, b, entity, links[b], taken)
        _joints(m, steps, fixed, links[parent] if parent else mount, links[b], robot,
                joint_names)
    ET.indent(robot)
    return ET.tostring(robot, encoding='unicode')


def model_key(m: mujoco.MjModel, bodies: Sequence[int]) -> bytes:
    """
    Return a digest of what :func:`from_model` reads of an entity: equal digests, equal text.

    Its bodies, joints, the actuators on those joints, geoms, materials' colours and meshes'
    names and sizes, and all their names; ids relative to the entity's first body, so an
    entity that only moved in the model (another one deleted before it) keeps its digest.
    """
    b = np.asarray(bodies, dtype=int)
    h = hashlib.blake2b(digest_size=16)
    j = np.concatenate([np.arange(m.body_jntadr[x], m.body_jntadr[x] + m.body_jntnum[x])
                        for x in b]).astype(int) if len(b) else np.zeros(0, int)
    g = np.concatenate([np.arange(m.body_geomadr[x], m.body_geomadr[x] + m.body_geomnum[x])
                        for x in b]).astype(int) if len(b) else np.zeros(0, int)
    acts = [a for a in range(m.nu) if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
            and m.actuator_trnid[a, 0] in set(j.tolist())]
    mats = m.geom_matid[g]
    meshes = [int(x) for x, t in zip(m.geom_dataid[g], m.geom_type[g]) if t == _MESH]
    for arr in (m.body_pos[b], m.body_quat[b], m.body_mass[b], m.body_inertia[b],
                m.body_ipos[b], m.body_iquat[b], m.body_parentid[b] - (b[0] if len(b) else 0),
                m.jnt_type[j], m.jnt_pos[j], m.jnt_axis[j], m.jnt_range[j], m.jnt_limited[j],
                m.qpos0[m.jnt_qposadr[j]], m.jnt_actfrcrange[j], m.jnt_actfrclimited[j],
                m.actuator_gear[acts], m.actuator_ctrlrange[acts], m.actuator_forcerange[acts],
                m.actuator_ctrllimited[acts], m.actuator_forcelimited[acts],
                m.actuator_biastype[acts], m.geom_type[g], m.geom_size[g], m.geom_pos[g],
                m.geom_quat[g], m.geom_rgba[g], m.geom_group[g], m.geom_contype[g],
                m.geom_conaffinity[g], m.mat_rgba[mats[mats >= 0]], m.mesh_vertnum[meshes],
                m.mesh_facenum[meshes]):
        h.update(np.ascontiguousarray(arr).tobytes())
    for kind, ids in ((mujoco.mjtObj.mjOBJ_BODY, b), (mujoco.mjtObj.mjOBJ_JOINT, j),
                      (mujoco.mjtObj.mjOBJ_MESH, meshes)):
        h.update('\0'.join(mujoco.mj_id2name(m, kind, int(i)) or '' for i in ids).encode())
    return h.digest()


@dataclass(frozen=True)
class ChainFrame:
    """
    An intermediate link of a description (see the module's notes): where it is on /tf.

    ``static``: at ``offset`` from the body's own frame, always (the link of the body's last
    joint). Otherwise it moves with the joints before it: its pose in the parent body's frame
    is the product over ``steps`` of ``origin * motion(q)``, each step (origin position (3,),
    origin quaternion wxyz (4,), the joint's MuJoCo id, hinge (else slide), axis (3,)).
    """

    frame: str  # ``<entity>/<link>``, as robot_state_publisher with frame_prefix names it
    body: int  # the body whose joints it stands between
    parent: int  # that body's parent (0: the world, or the entity's mount at its origin)
    static: bool
    offset: tuple
    steps: tuple


def chain_frames(m: mujoco.MjModel, bodies: Sequence[int], root_frame: str,
                 mount_frame: str = '') -> list:
    """
    Return the intermediate links of :func:`from_model`'s description, as :class:`ChainFrame`.

    Links between ball or free joints are left out (robot_state_publisher cannot move those
    either).
    """
    entity, links, mount, taken = _links(m, bodies, root_frame, mount_frame)
    out = []
    for b in bodies[0 if mount else 1:]:
        steps, fixed = _chain(m, b, entity, links[b], taken)
        movable = True
        for k, (to, direct, jpos, jquat, j) in enumerate(steps):
            movable = movable and int(m.jnt_type[j]) in (_HINGE, _SLIDE)
            if direct:
                continue
            if k == len(steps) - 1:
                out.append(ChainFrame(f'{entity}/{to}', b, int(m.body_parentid[b]), True,
                                      tuple(-np.asarray(fixed[0])), ()))
            elif movable:
                out.append(ChainFrame(
                    f'{entity}/{to}', b, int(m.body_parentid[b]), False, (),
                    tuple((tuple(p), tuple(q), jj, int(m.jnt_type[jj]) == _HINGE,
                           tuple(m.jnt_axis[jj])) for _, _, p, q, jj in steps[:k + 1])))
    return out


def _links(m: mujoco.MjModel, bodies: Sequence[int], root_frame: str,
           mount_frame: str) -> tuple:
    """Return (entity, body -> link name, mount link or '', names taken)."""
    root = bodies[0]
    entity = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, root)
    links = {root: link_name(entity, root_frame)}
    for b in bodies[1:]:
        links[b] = link_name(entity, _body_name(m, b))
    taken = set(links.values())
    mount = link_name(entity, mount_frame) if mount_frame else ''
    if mount:
        taken.add(mount)
    return entity, links, mount, taken


def _body_name(m: mujoco.MjModel, b: int) -> str:
    return mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f'body_{b}'


def _unique(name: str, taken: set) -> str:
    out, i = name, 1
    while out in taken:
        i += 1
        out = f'{name}_{i}'
    taken.add(out)
    return out


def _chain(m: mujoco.MjModel, b: int, entity: str, child: str, taken: set) -> tuple:
    """
    Plan the URDF joints from body `b`'s parent link to its link `child`.

    :returns: (steps, fixed): per joint (link it leads to, whether that is `child` itself,
        origin position, origin quaternion wxyz, joint id); then the origin (position,
        quaternion) of the fixed joint to `child` that follows an intermediate link (or of
        the fixed joint of a welded body).
    """
    # The transform still to place, in the parent link's frame: the body's pose in its parent.
    pos, quat = m.body_pos[b].copy(), m.body_quat[b].copy()
    jids = range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
    steps = []
    for k, j in enumerate(jids):
        jtype = int(m.jnt_type[j])
        jname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f'joint_{j}'
        anchor = m.jnt_pos[j] if jtype not in (_SLIDE, _FREE) else np.zeros(3)
        axis = m.jnt_axis[j]
        ref = float(m.qpos0[m.jnt_qposadr[j]]) if jtype in (_HINGE, _SLIDE) else 0.0
        # The joint's frame: at the anchor, turned (or shifted) back by its reference value.
        jpos = pos + rotations.rotate(quat, anchor)
        jquat = quat
        if jtype == _HINGE and ref:
            jquat = rotations.mul(quat, rotations.from_axis_angle(axis, -ref))
        elif jtype == _SLIDE and ref:
            jpos = jpos - rotations.rotate(quat, axis * ref)
        direct = k == len(jids) - 1 and not np.any(np.abs(anchor) > _EPS)
        to = child if direct else _unique(f'{child}/{link_name(entity, jname)}', taken)
        steps.append((to, direct, jpos, jquat, j))
        pos, quat = -np.asarray(anchor, dtype=float), np.array([1.0, 0.0, 0.0, 0.0])
    return steps, (pos, quat)


def _joints(m: mujoco.MjModel, steps: list, fixed: tuple, parent: str, child: str,
            robot: ET.Element, joint_names: set) -> None:
    """Write the URDF joints that :func:`_chain` planned."""
    for to, direct, jpos, jquat, j in steps:
        jname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f'joint_{j}'
        if not direct:
            ET.SubElement(robot, 'link', name=to)
        joint = ET.SubElement(robot, 'joint', name=_unique(jname, joint_names),
                              type=_urdf_type(m, j))
        _origin(joint, jpos, jquat)
        ET.SubElement(joint, 'parent', link=parent)
        ET.SubElement(joint, 'child', link=to)
        if int(m.jnt_type[j]) in (_HINGE, _SLIDE):
            ET.SubElement(joint, 'axis', xyz=_fmt(m.jnt_axis[j]))
            _limit(m, j, joint)
        parent = to
    if parent != child:  # welded, or after an intermediate link: a fixed joint to the body
        joint = ET.SubElement(robot, 'joint', name=_unique(f'{child}_fixed', joint_names),
                              type='fixed')
        _origin(joint, *fixed)
        ET.SubElement(joint, 'parent', link=parent)
        ET.SubElement(joint, 'child', link=child)


def _urdf_type(m: mujoco.MjModel, j: int) -> str:
    jtype = int(m.jnt_type[j])
    if jtype == _HINGE:
        return 'revolute' if m.jnt_limited[j] else 'continuous'
    if jtype == _SLIDE:
        return 'prismatic'
    return 'floating'


def _limit(m: mujoco.MjModel, j: int, joint: ET.Element) -> None:
    effort = _effort(m, j)
    if int(m.jnt_type[j]) == _HINGE and not m.jnt_limited[j]:
        if effort:
            ET.SubElement(joint, 'limit', effort=_num(effort), velocity='0')
        return
    lo, hi = ((float(m.jnt_range[j, 0]), float(m.jnt_range[j, 1])) if m.jnt_limited[j]
              else (-UNLIMITED_SLIDE_M, UNLIMITED_SLIDE_M))
    ET.SubElement(joint, 'limit', lower=_num(lo), upper=_num(hi), effort=_num(effort),
                  velocity='0')


def _effort(m: mujoco.MjModel, j: int) -> float:
    """Return the largest force of a joint: its own force range, else its actuators'."""
    if m.jnt_actfrclimited[j]:
        return float(np.max(np.abs(m.jnt_actfrcrange[j])))
    best = 0.0
    for a in range(m.nu):
        if m.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT or m.actuator_trnid[a, 0] != j:
            continue
        gear = abs(float(m.actuator_gear[a, 0]))
        if m.actuator_forcelimited[a]:
            best = max(best, float(np.max(np.abs(m.actuator_forcerange[a]))) * gear)
        elif m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE and m.actuator_ctrllimited[a]:
            best = max(best, float(np.max(np.abs(m.actuator_ctrlrange[a]))) * gear)
    return best


def _inertial(m: mujoco.MjModel, b: int, link: ET.Element) -> None:
    mass = float(m.body_mass[b])
    if mass <= 0:
        return
    inertial = ET.SubElement(link, 'inertial')
    _origin(inertial, m.body_ipos[b], m.body_iquat[b])
    ET.SubElement(inertial, 'mass', value=_num(mass))
    i = m.body_inertia[b]
    ET.SubElement(inertial, 'inertia', ixx=_num(i[0]), ixy='0', ixz='0', iyy=_num(i[1]),
                  iyz='0', izz=_num(i[2]))


class _Writer:
    """Visual and collision elements of geoms; mesh files written once per content."""

    def __init__(self, m: mujoco.MjModel, mesh_dir: Optional[Path]):
        self._m = m
        self._dir = mesh_dir
        self._meshes: dict = {}  # mesh id -> URI

    def geom(self, g: int, link: ET.Element) -> None:
        m = self._m
        rgba = m.mat_rgba[m.geom_matid[g]] if m.geom_matid[g] >= 0 else m.geom_rgba[g]
        visible = m.geom_group[g] <= 2 and rgba[3] > 0
        collides = bool(m.geom_contype[g] or m.geom_conaffinity[g])
        parts = self._shapes(g) if visible or collides else []
        for pos, quat, shape in parts:
            for tag, on in (('visual', visible), ('collision', collides)):
                if not on:
                    continue
                el = ET.SubElement(link, tag)
                _origin(el, pos, quat)
                el.append(copy.deepcopy(shape))
                if tag == 'visual':
                    mat = ET.SubElement(el, 'material', name=f'rgba_{_fmt(rgba, 3, "_")}')
                    ET.SubElement(mat, 'color', rgba=_fmt(rgba, 6))

    def _shapes(self, g: int) -> list:
        """(pos, quat, <geometry>) in the body frame: one, or three for a capsule."""
        m = self._m
        kind, size = int(m.geom_type[g]), m.geom_size[g]
        pos, quat = m.geom_pos[g], m.geom_quat[g]

        def geometry(tag: str, **attrs) -> ET.Element:
            el = ET.Element('geometry')
            ET.SubElement(el, tag, **attrs)
            return el

        if kind == _BOX:
            return [(pos, quat, geometry('box', size=_fmt(2 * size)))]
        if kind == _SPHERE:
            return [(pos, quat, geometry('sphere', radius=_num(size[0])))]
        if kind == _CYLINDER:
            return [(pos, quat, geometry('cylinder', radius=_num(size[0]),
                                         length=_num(2 * size[1])))]
        if kind == _CAPSULE:
            ends = [pos + rotations.rotate(quat, np.array([0.0, 0.0, s * size[1]]))
                    for s in (1, -1)]
            return [(pos, quat, geometry('cylinder', radius=_num(size[0]),
                                         length=_num(2 * size[1])))] + [
                (end, quat, geometry('sphere', radius=_num(size[0]))) for end in ends]
        if kind == _ELLIPSOID and self._dir is not None:
            return [(pos, quat, geometry('mesh', filename=self._write(*_unit_sphere()),
                                         scale=_fmt(size)))]
        if kind == _MESH and self._dir is not None:
            mid = int(m.geom_dataid[g])
            if mid not in self._meshes:
                va, vn = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
                fa, fn = m.mesh_faceadr[mid], m.mesh_facenum[mid]
                self._meshes[mid] = self._write(m.mesh_vert[va:va + vn],
                                                m.mesh_face[fa:fa + fn])
            return [(pos, quat, geometry('mesh', filename=self._meshes[mid]))]
        return []

    def _write(self, verts: np.ndarray, faces: np.ndarray) -> str:
        """Write a binary STL named by its content (once) and return its file:// URI."""
        verts = np.ascontiguousarray(verts, dtype=np.float32)
        faces = np.ascontiguousarray(faces, dtype=np.int32)
        digest = hashlib.blake2b(verts.tobytes(), digest_size=16)
        digest.update(faces.tobytes())
        path = Path(self._dir) / f'{digest.hexdigest()}.stl'
        if not path.exists():  # the triangles only when the file is new
            tri = verts[faces]
            normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            lengths = np.linalg.norm(normals, axis=1, keepdims=True)
            normals = np.divide(normals, lengths, out=np.zeros_like(normals),
                                where=lengths > 0)
            rec = np.zeros(len(tri), dtype=[('n', '<f4', 3), ('v', '<f4', (3, 3)),
                                            ('a', '<u2')])
            rec['n'], rec['v'] = normals, tri
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, suffix='.part')
            with os.fdopen(fd, 'wb') as f:
                f.write(b'sim: MuJoCo mesh'.ljust(80, b' '))
                f.write(np.uint32(len(tri)).tobytes())
                f.write(rec.tobytes())
            os.chmod(tmp, 0o644)
            os.replace(tmp, path)
        return path.resolve().as_uri()


_SPHERE_MESH: Optional[tuple] = None


def _unit_sphere(n: int = 16) -> tuple:
    """(vertices, faces) of a unit UV sphere (for ellipsoids, scaled)."""
    global _SPHERE_MESH
    if _SPHERE_MESH is None:
        th = np.linspace(0, np.pi, n + 1)
        ph = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
        v = np.array([[np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]
                      for t in th for p in ph])
        w = 2 * n
        f = []
        for i in range(n):
            for k in range(w):
                a, b = i * w + k, i * w + (k + 1) % w
                c, d = a + w, b + w
                f += [(a, c, b), (b, c, d)]
        _SPHERE_MESH = (v, np.array(f))
    return _SPHERE_MESH


# ---------------------------------------------------------------------- numbers and frames

def _num(x: float, digits: int = 12) -> str:
    return f'{float(x) + 0.0:.{digits}g}'  # + 0.0: no '-0'


def _fmt(values, digits: int = 12, sep: str = ' ') -> str:
    return sep.join(_num(v, digits) for v in values)


def _origin(el: ET.Element, pos, quat_wxyz) -> None:
    ET.SubElement(el, 'origin', xyz=_fmt(pos), rpy=_fmt(rotations.to_rpy(quat_wxyz)))
