"""
Structural edits of a world and its physics parameters, each planned here.

They are made by the one commit path, :mod:`.transaction`.

Spawn, add a body, delete, the removal of the spawned on reset, contact, mass, welds, gravity
and timestep. Each public method validates its arguments, then hands a plan to
:meth:`Transaction.change <.transaction.Transaction.change>`: the plan runs under the world
lock, checks against the live world (:class:`~sim_node.core.stepping.live.Live`), and returns an
:class:`~.design.Edit`, which is compiled with the lock released and committed, or changes
nothing.
"""

from dataclasses import replace
import itertools
import logging
from typing import Optional, Sequence

import mujoco
import numpy as np

from . import editor
from .transaction import grouped, Transaction
from ..base import checks, quat
from ..base.checks import check_finite, check_pose
from ..base.errors import (CapacityError, IncorrectStateError, InvalidArgumentError,
                           InvalidPoseError, NameNotUniqueError, NamespaceInvalidError)
from ..base.records import ROBOT, STATIC
from ..base.surfaces import MAX_RESTITUTION
from ..compiled import state
from ..control import bases, laws
from ..models import sensor_tags, sources
from ..stepping.design import Contact, Edit, NOTHING, Spawned
from ..stepping.live import Live

ERR_CAPACITY = ('the world would hold {n} bodies, over its limit of {limit} (parameter '
                'max_bodies): delete entities first, or raise the limit')
ERR_DUPLICATE = 'an entity or body named {name!r} exists; pick another name or allow renaming'
ERR_INTERPENETRATION = ('at this pose {name!r} would overlap {other!r} by {depth:.4f} m; move '
                        'it, or allow interpenetration')
ERR_NOT_SPAWNED = '{name!r} is part of the loaded scene; only spawned entities can be deleted'
ERR_ROBOT_WELD = '{name!r} is a robot: give it a positive mass'
ERR_NO_MASS = '{name!r} has no mass to scale'
ERR_MANAGER_TAKEN = ("{name!r}'s ros2_control joints and controller manager would share "
                     "{ns} with {other!r}'s (joint_states, controller_manager): spawn it with "
                     'a namespace of its own')
ERR_TOPIC_TAKEN = ('{name!r} declares its sensor {site!r} on topic {topic!r}, which {other!r} '
                   'already publishes on: spawn it with a namespace of its own')
log = logging.getLogger(__name__)
_SPAWNS = itertools.count(1)  # numbers the spawns of ros2_control robots


class Edits:
    """Structural and physics-parameter changes of a world (its :class:`Live`)."""

    def __init__(self, live: Live, transaction: Transaction):
        self.live = live
        self.transaction = transaction

    def _check_capacity_locked(self, new_bodies: int) -> None:
        total = self.live.model.nbody + new_bodies
        if total > self.live.config.max_bodies:
            raise CapacityError(ERR_CAPACITY.format(n=total, limit=self.live.config.max_bodies))

    def _unique_name_locked(self, base: str) -> str:
        taken = self.live.index.body_ids
        base = base if checks.NAME_RE.match(base or '') else 'entity'
        name, i = base, 0
        while name in taken:
            i += 1
            name = f'{base}_{i}'
        return name

    def spawn(self, name: str, source: sources.SpawnSource,
              position: Sequence[float] = (0.0, 0.0, 0.0),
              quat_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0), reference: str = '',
              allow_renaming: bool = False, namespace: str = '',
              allow_interpenetration: Optional[bool] = None) -> str:
        """
        Add an entity at a pose (world frame, or `reference` entity's frame) while running.

        Its root body is named `name` (when empty, the name the resource gives itself: MJCF's
        ``model``, URDF's ``robot name``); every other element ``name/<original>`` (unnamed ones
        get ``name/<kind>_<i>``). All or nothing: on any error the world is exactly as
        before. `namespace` (a ROS namespace) is kept in its record: the node puts the
        entity's own interfaces there (:attr:`EntityRecord.namespace`).

        :returns: the entity's name (differs from `name` only when renaming was allowed).
        """
        try:
            pos, q = check_pose(position, quat_wxyz)
            checks.check_namespace(namespace)
            name = name or source.name  # the standard: else the name the resource gives itself
            if not allow_renaming:
                checks.check_name(name)
            overlap_ok = (self.live.config.allow_interpenetration
                          if allow_interpenetration is None else allow_interpenetration)
            # The compile, the slow part, runs outside the world lock (Transaction.change):
            # the loop steps and /clock goes on meanwhile.
            result = self.transaction.change(lambda: self._plan_spawn_locked(
                name, source, pos, q, reference, allow_renaming, overlap_ok, namespace))
        except BaseException:
            source.settle(spawned=False)  # its copied files go, unless others use them
            raise
        source.settle(spawned=True)
        self._hold_spawned(result, getattr(source.urdf_notes, 'ros2_control', None))
        return result

    def spawn_world(self, entities: Sequence[tuple]) -> None:
        """
        Attach a loaded world's own entities, all in one build (a world being made).

        `entities` are ``(name, source, position (3,), quat wxyz (4,))``: the models of an SDF
        world made on their own (:attr:`.models.world_sources.WorldSource.entities`), placed where
        the world file puts them (no overlap check: the file says where). Their records are the
        world's (:attr:`Spawned.world`): a delete or a reset of the spawned leaves them.
        All or nothing: the first that fails refuses the world.
        """
        def plan() -> Edit:
            edits = []
            for name, source, pos, q in entities:
                pos, q = check_pose(pos, q)
                checks.check_name(name)
                edit = self._plan_spawn_locked(name, source, pos, q, '', False, True)
                spawned = edit.redesign

                def redesign(nxt, applied, spawned=spawned, name=name):
                    nxt = spawned(nxt, applied)
                    return nxt.with_spawned(name, replace(nxt.spawned[name], world=True))
                edits.append(replace(edit, redesign=redesign))
            return grouped(edits)
        try:
            self.transaction.change(plan)
        except BaseException:
            for _, source, _, _ in entities:
                source.settle(spawned=False)
            raise
        for name, source, _, _ in entities:
            source.settle(spawned=True)
            self._hold_spawned(name, getattr(source.urdf_notes, 'ros2_control', None))

    def _hold_spawned(self, name: str, control) -> None:
        """
        Hold a gz_ros2_control robot's position joints where they spawned (``hold_joints``).

        As Gazebo holds them from the robot's first step, before its controller manager is up
        (the node's own hold, ``laws.HoldLaw``, takes over from its first joint sample).
        """
        if control is None or not control.hold_joints or not control.simulated:
            return
        live = self.live
        with live.lock:
            index = live.index
            held = laws.held_interfaces({j.name: j.command for j in control.joints().values()})
            names = [f'{name}/{j}' for j, how in held.items()
                     if how == 'position' and f'{name}/{j}' in index.joint_index]
            if names:
                adr = index.joint_qposadr[[index.joint_index[n] for n in names]]
                live.control.stage(index, names, [float(q) for q in live.data.qpos[adr]],
                                   'position')

    def _plan_spawn_locked(self, name: str, source: sources.SpawnSource, pos: np.ndarray,
                           q: np.ndarray, reference: str, allow_renaming: bool,
                           overlap_ok: bool, namespace: str = '') -> Edit:
        """Return the spawn's edit: its result is the checked name."""
        self._check_capacity_locked(len(source.spec.bodies) - 1)
        if not name or name in self.live.index.body_ids:
            if not allow_renaming:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=name))
            name = self._unique_name_locked(name or source.kind)
        if reference:
            pos, q = quat.from_frame(*self.live.pose_frame_locked(reference), pos, q)
        checks.check_extent(pos, self.live.config.world_extent)
        design = self.live.design
        contact = design.contact_of(None) if design.default_contact.is_set else None
        casters_roll = self.live.config.casters_roll

        tops = [b.name for b in source.spec.worldbody.bodies]
        sensors = tuple(sensor_tags.entity_sensor(d, name, namespace, tops[0] if tops else '')
                        for d in getattr(source.urdf_notes, 'sensors', ()))
        _check_topics(name, sensors, design.spawned)
        not_run = tuple(getattr(source.urdf_notes, 'systems_not_run', ()))
        if not_run:
            log.warning('%r names gz-sim systems that are not run here: %s (what is: '
                        'docs/sdf.md)', name, ', '.join(not_run))
        control = getattr(source.urdf_notes, 'ros2_control', None)
        if control is not None:
            control = replace(control, namespace=namespace.strip('/') or control.namespace,
                              spawn=next(_SPAWNS))
            _check_managers(name, control, design.spawned)

        def apply(spec: mujoco.MjSpec) -> Spawned:
            frame, bodies, root, defaults = editor.attach(spec, name, source, pos, q,
                                                          casters_roll)
            if contact is not None:
                geoms = [g.name for b in bodies
                         for g in spec.body(b).find_all(mujoco.mjtObj.mjOBJ_GEOM)]
                editor.apply_contact(spec, geoms, *contact)
            # Its root body's own frame (see ModelInfo.body_alias), and a URDF's own text.
            return Spawned(frame=frame, bodies=bodies, root_link=f'{name}/{root}',
                           defaults=defaults, assets=tuple(source.assets),
                           description=source.description, namespace=namespace,
                           urdf=source.text if source.kind == 'urdf' else '',
                           world_link=getattr(source.urdf_notes, 'world_link', None),
                           collisions=dict(getattr(source.urdf_notes, 'collisions', {})),
                           ros2_control=control,
                           drive=bases.drive_plugin(getattr(source.urdf_notes, 'extensions',
                                                            ())),
                           sensors=sensors,
                           systems=tuple(getattr(source.urdf_notes, 'systems', ())),
                           systems_not_run=not_run)

        def check(model: mujoco.MjModel, data: mujoco.MjData, keep: mujoco.MjSpec) -> None:
            hit = editor.find_overlap(model, data, name,  # the commit ran mj_fwdPosition
                                      self.live.config.interpenetration_tolerance)
            if hit is not None:
                raise InvalidPoseError(ERR_INTERPENETRATION.format(
                    name=name, other=hit[0], depth=hit[1]))

        return Edit(apply, None if overlap_ok else check,
                    lambda nxt, spawned: nxt.with_spawned(name, spawned), result=name,
                    batchable=True)

    def add_body(self, name: str, parent: str, shape: str, size: Sequence[float],
                 position: Sequence[float] = (0.0, 0.0, 0.0),
                 quat_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0), mass: float = 0.0,
                 joint: Optional[str] = None, axis: Sequence[float] = (0.0, 0.0, 1.0),
                 rgba: Sequence[float] = (0.7, 0.7, 0.7, 1.0)) -> str:
        """
        Add a body with one geom under an existing body of a spawned entity, while running.

        :param parent: name of the parent body (an entity or one of its bodies).
        :param position: in the parent's frame.
        :param joint: None (welded: the body becomes part of its parent), 'hinge' or 'slide'
            about/along `axis` (in the body frame).
        :param mass: kg; 0 uses the geom's default density.
        """
        pos, q = check_pose(position, quat_wxyz)
        ax = check_finite('axis', axis, 3)
        checks.check_name(name)
        if joint not in (None, 'hinge', 'slide'):
            raise InvalidArgumentError(f"joint must be None, 'hinge' or 'slide', got {joint!r}")
        full_size = sources.primitive_size(shape, size)
        colour = sources.check_rgba(rgba)
        sources.check_mass(mass)

        def plan() -> Edit:  # compiled outside the world lock (_change)
            root = self.live.index.entity_of_body(parent)
            if root not in self.live.design.deletable():
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=root))
            self._check_capacity_locked(1)
            full = f'{root}/{name}'
            if full in self.live.index.body_ids:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=full))
            return Edit(lambda spec: editor.add_child(
                spec, parent, full, shape, full_size, pos, q, mass, joint, ax, colour),
                result=full)

        return self.transaction.change(plan)

    def delete(self, name: str) -> None:
        """
        Remove a spawned entity with its joints, geoms, actuators, sensors, equality constraints.

        Contact pairs, excludes and joint commands; everything else keeps its state exactly.
        """
        def plan() -> Edit:
            self.live.index.entity(name)
            if name not in self.live.design.deletable():
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=name))
            return self._plan_removal_locked([name])

        self.transaction.change(plan)

    def remove_spawned(self) -> None:
        """Remove every entity spawned since load (a reset of the spawned), outside the lock."""
        with self.live.lock:
            anything = bool(self.live.design.deletable())
        if anything:
            self.transaction.change(
                lambda: self._plan_removal_locked(self.live.design.deletable()))

    def _plan_removal_locked(self, names: Sequence[str]) -> Edit:
        """Return the edit that removes spawned entities `names`."""
        doomed = {n: self.live.design.spawned[n] for n in names}
        return Edit(lambda spec: [editor.remove(spec, n, rec.frame, rec.assets, rec.defaults)
                                  for n, rec in doomed.items()],
                    redesign=lambda nxt, _: nxt.without(list(doomed)), batchable=True)

    # ---------------------------------------------------------------- physics parameters

    def set_gravity(self, gravity: Sequence[float]) -> None:
        g = check_finite('gravity', gravity, 3)
        self.transaction.change(
            lambda: Edit(lambda spec: setattr(spec.option, 'gravity', g.tolist())))

    def set_timestep(self, timestep: float) -> None:
        (dt,) = check_finite('timestep', [timestep], 1)
        if not 0 < dt <= 0.1:
            raise InvalidArgumentError(f'timestep must be in (0, 0.1] s, got {timestep}')
        self.transaction.change(
            lambda: Edit(lambda spec: setattr(spec.option, 'timestep', float(dt))))

    def set_friction(self, name: str, sliding: float, torsional: Optional[float] = None,
                     rolling: Optional[float] = None) -> None:
        """
        Friction of every geom of an entity (MuJoCo's three coefficients).

        It wins over surfaces without friction of their own (see :func:`editor.apply_contact`).
        """
        def plan() -> Edit:
            rec = self.live.index.entity(name)
            cur = (self.live.model.geom_friction[rec.geom_ids[0]] if rec.geom_ids
                   else np.array([1.0, 0.005, 0.0001]))
            f = check_finite('friction', [sliding, cur[1] if torsional is None else torsional,
                                          cur[2] if rolling is None else rolling], 3)
            if np.any(f < 0):
                raise InvalidArgumentError(f'friction must be >= 0, got {f.tolist()}')
            return self._plan_contact_locked(name, friction=f)
        self.transaction.change(plan)

    def set_restitution(self, name: str, restitution: float) -> None:
        """
        Bounciness in [0, 0.8] of an entity's geoms.

        A bounce off any surface without a restitution of its own has that coefficient (see
        :func:`editor.apply_contact`).
        """
        e = self._check_restitution(restitution)
        self.transaction.change(lambda: self._plan_contact_locked(name, restitution=e))

    def _plan_contact_locked(self, name: str, friction: Optional[np.ndarray] = None,
                             restitution: Optional[float] = None) -> Edit:
        """Return the edit that gives one entity its own friction and/or restitution."""
        geoms = [self.live.index.geom_names[g] for g in self.live.index.entity(name).geom_ids]
        own = self.live.design.contacts.get(name, Contact()).merged(friction, restitution)
        contact = self.live.design.with_contact(name, own).contact_of(name)
        return Edit(lambda spec: editor.apply_contact(spec, geoms, *contact),
                    redesign=lambda nxt, _: nxt.with_contact(name, own))

    def set_default_contact(self, friction: Optional[Sequence[float]] = None,
                            restitution: Optional[float] = None) -> None:
        """Global friction (3 values) and/or restitution for every geom without its own."""
        f = None if friction is None else check_finite('friction', friction, 3)
        e = None if restitution is None else self._check_restitution(restitution)

        def plan() -> Edit:  # compiled outside the world lock (_change)
            default = self.live.design.default_contact.merged(f, e)
            nxt, idx = self.live.design.with_default_contact(default), self.live.index
            groups = [([idx.geom_names[g] for g in r.geom_ids], nxt.contact_of(r.name))
                      for r in idx.entities]
            groups.append(([n for g, n in enumerate(idx.geom_names)
                            if self.live.model.geom_bodyid[g] == 0], nxt.contact_of(None)))
            return Edit(lambda spec: [editor.apply_contact(spec, geoms, *contact)
                                      for geoms, contact in groups],
                        redesign=lambda after, _: after.with_default_contact(default))
        self.transaction.change(plan)

    @staticmethod
    def _check_restitution(restitution: float) -> float:
        (e,) = check_finite('restitution', [restitution], 1)
        if not 0.0 <= e <= MAX_RESTITUTION:
            raise InvalidArgumentError(
                f'restitution must be in [0, {MAX_RESTITUTION}], got {restitution}')
        return float(e)

    def _weld(self, name: str) -> None:
        """
        Weld a free entity to the world where it is at the commit (a static one: nothing).

        Compiled with the lock released, as every structural edit: the object moves meanwhile,
        so the commit puts the welded body where the object is at that instant, in the new model
        and in the kept spec alike.
        """
        def plan() -> Edit:
            rec = self.live.index.entity(name)
            if rec.category == ROBOT:
                raise IncorrectStateError(ERR_ROBOT_WELD.format(name=name))
            if not rec.has_free_joint:  # static already: nothing to compile
                return NOTHING
            frame = self.live.design.frame_of(name)
            self.live.kinematics_locked()
            pos, q = state.body_pose(self.live.data, rec.root_body)

            def here_now(model: mujoco.MjModel, data: mujoco.MjData,
                         keep: mujoco.MjSpec) -> None:
                self.live.kinematics_locked()  # the live (old) world, as it is at the commit
                now_pos, now_q = state.body_pose(self.live.data, rec.root_body)
                body = model.body(name).id
                model.body_pos[body], model.body_quat[body] = now_pos, now_q
                editor.weld_in_place(keep, frame, rec, now_pos, now_q)  # the spec agrees
                mujoco.mj_forward(model, data)
            return Edit(lambda spec: editor.weld_in_place(spec, frame, rec, pos, q), here_now)
        self.transaction.change(plan)

    def set_mass(self, name: str, mass: float) -> None:
        """
        Total mass of an entity (kg); each body's mass and inertia scale by one factor.

        A body without mass is static: giving a static (jointless) entity a mass frees it
        where it is (it gets a free joint and falls), and a mass of 0 welds a free object to
        the world where it is now.
        """
        (m_new,) = check_finite('mass', [mass], 1)
        if m_new < 0:
            raise InvalidArgumentError(f'mass must be >= 0, got {mass}')
        if m_new == 0:
            self._weld(name)
            return

        def plan() -> Edit:
            rec = self.live.index.entity(name)
            total = float(sum(self.live.model.body_mass[b] for b in rec.body_ids))
            if total <= 0:
                raise IncorrectStateError(ERR_NO_MASS.format(name=name))
            model, index = self.live.model, self.live.index
            return Edit(lambda spec: (
                editor.free(spec, rec) if rec.category == STATIC else None,
                editor.scale_mass(spec, model, index, rec, m_new / total)))
        self.transaction.change(plan)


def _check_topics(name: str, sensors: tuple, spawned) -> None:
    """Refuse a spawn whose declared sensor topics another entity's already use."""
    taken = {_absolute(d.topic): other for other, rec in spawned.items()
             for d in rec.sensors if d.topic}
    for d in sensors:
        other = taken.get(_absolute(d.topic)) if d.topic else None
        if other is not None:
            raise NamespaceInvalidError(ERR_TOPIC_TAKEN.format(
                name=name, site=getattr(d, 'site', '') or getattr(d, 'camera', '')
                or getattr(d, 'name', ''),
                topic=d.topic, other=other))


def _check_managers(name: str, control, spawned) -> None:
    """Refuse a ros2_control robot whose controller manager another's namespace holds."""
    if not control.simulated:
        return
    where = control.namespace.strip('/')
    for other, rec in spawned.items():
        theirs = rec.ros2_control
        if theirs is not None and theirs.namespace.strip('/') == where \
                and theirs.simulated and control.simulated:
            raise NamespaceInvalidError(ERR_MANAGER_TAKEN.format(
                name=name, other=other, ns=f'/{where}' if where else 'the root namespace'))


def _absolute(topic: str) -> str:
    return topic if topic.startswith('/') else f'/{topic}'
