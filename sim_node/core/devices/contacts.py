"""
Contacts as a contact sensor reports them: what touches what, where, how deep, how hard.

Each geom is named as Gazebo scopes a collision, ``model::link::collision`` (:func:`scoped`):
the entity, its link (a body's name inside its entity) and the collision (a URDF's collision by
the name Gazebo's URDF reader gives it; any other geom by its own name, or ``geom<id>``).
Geoms of the world body are ``world::world::<geom>``.

A report (:func:`read`) groups MuJoCo's active contacts by pair of geoms, the sensor's own geom
first: per contact point its position, its normal (pointing from the sensor's geom to the
other, world frame), its depth (penetration, m) and the force the other geom applies to the
sensor's geom (world frame, N; its torque about the point is zero). ROS-free.
"""

from typing import NamedTuple, Optional

import mujoco
import numpy as np

from ..base.records import DeclaredContact

_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
_BODY = int(mujoco.mjtObj.mjOBJ_BODY)
_SUBTREE = int(mujoco.mjtObj.mjOBJ_XBODY)
_SITE = int(mujoco.mjtObj.mjOBJ_SITE)
_CONTACT = int(mujoco.mjtSensor.mjSENS_CONTACT)
_TOUCH = int(mujoco.mjtSensor.mjSENS_TOUCH)


class Touch(NamedTuple):
    """The contact points of one pair of geoms: the sensor's (`geom1`) and another."""

    geom1: int
    geom2: int
    positions: np.ndarray  # (n, 3) world
    normals: np.ndarray  # (n, 3) from geom1 to geom2
    depths: np.ndarray  # (n,) penetration, m
    forces: np.ndarray  # (n, 3) on geom1's body, world frame


class ContactReport(NamedTuple):
    """A contact sensor's report at one simulated time: :class:`Touch` per pair touching."""

    name: str
    time: float
    touches: tuple
    generation: int = 0  # the model generation its geom ids are of


def scoped(m: mujoco.MjModel, body_names: tuple, root_of: np.ndarray, spawned) -> tuple:
    """Return every geom's ``model::link::collision`` name (see the module docstring)."""
    out = []
    for g in range(m.ngeom):
        b = int(m.geom_bodyid[g])
        name = mujoco.mj_id2name(m, _GEOM, g) or ''
        if b == 0:
            out.append(f'world::world::{name or f"geom{g}"}')
            continue
        entity = body_names[int(root_of[b])]
        own = spawned.get(entity)
        prefix = f'{entity}/'
        link = body_names[b][len(prefix):] if body_names[b].startswith(prefix) else ''
        if not link:  # the root body, named as the entity: its link's own name
            link = own.root_link[len(prefix):] if own is not None else entity
        local = name[len(prefix):] if name.startswith(prefix) else name
        if own is not None:
            local = own.collisions.get(local, local)
        out.append(f'{entity}::{link}::{local or f"geom{g}"}')
    return tuple(out)


def declared(m: mujoco.MjModel, spawned) -> dict:
    """
    Return name -> :class:`DeclaredContact` (geoms as ids of `m`) of every contact sensor.

    The spawned robots' declared ones, and MuJoCo ``contact`` sensors (their ``geom1``,
    ``body1`` or ``subtree1`` against ``geom2``, ``body2``, ``subtree2``, or anything) and
    ``touch`` sensors (every geom of their site's body).
    """
    out = {}
    ids = {mujoco.mj_id2name(m, _GEOM, g): g for g in range(m.ngeom)}
    for rec in spawned.values():
        for decl in rec.sensors:
            if isinstance(decl, DeclaredContact):
                geoms = tuple(ids[g] for g in decl.geoms if g in ids)
                out[decl.name] = DeclaredContact(
                    name=decl.name, geoms=geoms, rate_hz=decl.rate_hz,
                    always_on=decl.always_on, topic=decl.topic)
    for i in range(m.nsensor):
        kind = int(m.sensor_type[i])
        if kind not in (_CONTACT, _TOUCH):
            continue
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SENSOR, i) or f'sensor{i}'
        if kind == _TOUCH:
            mine = _geoms_of(m, _BODY, int(m.site_bodyid[m.sensor_objid[i]]))
            others = ()
        else:
            mine = _geoms_of(m, int(m.sensor_objtype[i]), int(m.sensor_objid[i]))
            others = _geoms_of(m, int(m.sensor_reftype[i]), int(m.sensor_refid[i]))
            others = () if len(others) == m.ngeom else others
        out.setdefault(name, DeclaredContact(name=name, geoms=mine, others=others))
    return out


def entity_geoms(m: mujoco.MjModel, root_of: np.ndarray, root: int) -> tuple:
    """Return the ids of every geom of the entity whose root body is `root`."""
    return tuple(int(g) for g in np.flatnonzero(root_of[m.geom_bodyid] == root))


def _geoms_of(m: mujoco.MjModel, objtype: int, objid: int) -> tuple:
    if objtype == _GEOM and objid >= 0:
        return (objid,)
    if objtype == _BODY and objid >= 0:
        return tuple(int(g) for g in np.flatnonzero(m.geom_bodyid == objid))
    if objtype == _SUBTREE and objid >= 0:
        inside = np.zeros(m.nbody, bool)
        for b in range(m.nbody):  # parents come before children
            inside[b] = b == objid or (b > 0 and inside[m.body_parentid[b]])
        return tuple(int(g) for g in np.flatnonzero(inside[m.geom_bodyid]))
    return tuple(range(m.ngeom))


def read(m: mujoco.MjModel, d: mujoco.MjData, mine: np.ndarray,
         others: Optional[np.ndarray] = None) -> tuple:
    """
    Return the :class:`Touch` es of the geoms `mine` (a (ngeom,) mask) now, by pair.

    :param others: a (ngeom,) mask the other geom must be in; None: any.
    """
    n = d.ncon
    if n == 0:
        return ()
    con = d.contact
    geom = con.geom[:n]
    active = con.exclude[:n] == 0
    first, second = mine[geom[:, 0]] & active, mine[geom[:, 1]] & active
    if others is not None:
        first &= others[geom[:, 1]]
        second &= others[geom[:, 0]]
    pairs: dict = {}
    wrench = np.zeros(6)
    for i in np.flatnonzero(first | second):
        frame = con.frame[i].reshape(3, 3)
        mujoco.mj_contactForce(m, d, int(i), wrench)
        on_second = frame.T @ wrench[:3]  # MuJoCo's force acts on geom2, along frame rows
        g1, g2 = (int(geom[i, 0]), int(geom[i, 1])) if first[i] else \
            (int(geom[i, 1]), int(geom[i, 0]))
        sign = -1.0 if first[i] else 1.0  # the force on the sensor's geom; normal away from it
        pairs.setdefault((g1, g2), []).append(
            (con.pos[i].copy(), -sign * frame[0], -float(con.dist[i]), sign * on_second))
    return tuple(Touch(g1, g2, np.array([p[0] for p in pts]), np.array([p[1] for p in pts]),
                       np.array([p[2] for p in pts]), np.array([p[3] for p in pts]))
                 for (g1, g2), pts in pairs.items())
