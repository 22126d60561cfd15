"""
World model edits.

Spawn, add a body, delete, and physics parameters (contact, mass, gravity, timestep). A mixin of
:class:`~sim_node.core.world.World`, split out only to keep one file per job: each method locks,
validates, and hands a spec edit to ``World._edit_locked`` (the recompile and generation stay in
``world.py``).
"""

from types import SimpleNamespace
from typing import Optional, Sequence

import mujoco
import numpy as np

from . import checks, editor, quat, sources, state
from .checks import check_finite, check_pose
from .errors import (CapacityError, IncorrectStateError, InvalidArgumentError, InvalidPoseError,
                     NameNotUniqueError)
from .records import ROBOT, STATIC

ERR_CAPACITY = ('the world would hold {n} bodies, over its limit of {limit} (parameter '
                'max_bodies): delete entities first, or raise the limit')
ERR_DUPLICATE = 'an entity or body named {name!r} exists; pick another name or allow renaming'
ERR_INTERPENETRATION = ('at this pose {name!r} would overlap {other!r} by {depth:.4f} m; move '
                        'it, or allow interpenetration')
ERR_NOT_SPAWNED = '{name!r} is part of the loaded scene; only spawned entities can be deleted'
ERR_ROBOT_WELD = '{name!r} is a robot: give it a positive mass'
ERR_NO_MASS = '{name!r} has no mass to scale'


class WorldEdits:
    """Structural and physics-parameter changes of a :class:`World` (see its docstring)."""

    def _frame_of(self, name: str) -> Optional[str]:
        """Return the name of the frame a spawned entity hangs from (None: a scene entity)."""
        meta = self._spawned.get(name)
        return meta['frame'] if meta else None

    def _check_capacity_locked(self, new_bodies: int) -> None:
        total = self._model.nbody + new_bodies
        if total > self.config.max_bodies:
            raise CapacityError(ERR_CAPACITY.format(n=total, limit=self.config.max_bodies))

    def unique_name(self, base: str) -> str:
        """Return `base`, or `base_<n>` with the smallest n not taken by an entity or body."""
        with self._locked():
            return self._unique_name_locked(base)

    def _unique_name_locked(self, base: str) -> str:
        taken = self._index.body_ids
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
        pos, q = check_pose(position, quat_wxyz)
        checks.check_namespace(namespace)
        name = name or source.name  # the standard: else the name the resource gives itself
        if not allow_renaming:
            checks.check_name(name)
        overlap_ok = (self.config.allow_interpenetration if allow_interpenetration is None
                      else allow_interpenetration)
        # The compile, the slow part, runs outside the world lock (World._change): the loop
        # steps and /clock goes on meanwhile.

        def plan() -> tuple:
            p = self._plan_spawn_locked(name, source, pos, q, reference, allow_renaming,
                                        overlap_ok, namespace)
            return p.edit, p.check, p.spawned, None, 0, p.name

        return self._change(plan)

    def _plan_spawn_locked(self, name: str, source: sources.SpawnSource, pos: np.ndarray,
                           q: np.ndarray, reference: str, allow_renaming: bool,
                           overlap_ok: bool, namespace: str = '') -> SimpleNamespace:
        """Return the checked name, the spec edit, the overlap check and the new table."""
        self._check_capacity_locked(len(source.spec.bodies) - 1)
        if not name or name in self._index.body_ids:
            if not allow_renaming:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=name))
            name = self._unique_name_locked(name or source.kind)
        if reference:
            pos, q = quat.from_frame(*self._pose_frame_locked(reference), pos, q)
        checks.check_extent(pos, self.config.world_extent)
        meta = {'assets': tuple(source.assets), 'description': source.description,
                'namespace': namespace}
        contact = (self._contact_of({}) if self._default_friction is not None
                   or self._default_restitution is not None else None)

        def edit(spec: mujoco.MjSpec) -> None:
            (meta['frame'], meta['bodies'], root,
             meta['defaults']) = editor.attach(spec, name, source, pos, q)
            # Its root body's own frame (see ModelInfo.body_alias), and a URDF's own text.
            meta['root_link'] = f'{name}/{root}'
            meta['urdf'] = source.text if source.kind == 'urdf' else ''
            if contact is not None:
                geoms = [g.name for b in meta['bodies']
                         for g in spec.body(b).find_all(mujoco.mjtObj.mjOBJ_GEOM)]
                editor.apply_contact(spec, geoms, *contact)

        def check(model: mujoco.MjModel, data: mujoco.MjData, keep: mujoco.MjSpec) -> None:
            hit = editor.find_overlap(model, data, name, self.config.interpenetration_tolerance)
            if hit is not None:
                raise InvalidPoseError(ERR_INTERPENETRATION.format(
                    name=name, other=hit[0], depth=hit[1]))

        return SimpleNamespace(name=name, edit=edit, check=None if overlap_ok else check,
                               spawned={**self._spawned, name: meta})

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

        def plan() -> tuple:  # compiled outside the world lock (World._change)
            root = self._index.entity_of_body(parent)
            if root not in self._spawned:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=root))
            self._check_capacity_locked(1)
            full = f'{root}/{name}'
            if full in self._index.body_ids:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=full))
            return (lambda spec: editor.add_child(
                spec, parent, full, shape, full_size, pos, q, mass, joint, ax, colour),
                None, None, None, 0, full)

        return self._change(plan)

    def delete(self, name: str) -> None:
        """
        Remove a spawned entity with its joints, geoms, actuators, sensors, equality constraints.

        Contact pairs, excludes and joint commands; everything else keeps its state exactly.
        """
        def plan() -> tuple:
            self._index.entity(name)
            if name not in self._spawned:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=name))
            return self._plan_removal_locked([name])

        self._change(plan)

    def _plan_removal_locked(self, names: Sequence[str]) -> tuple:
        """Return the World._change plan that removes spawned entities `names`."""
        doomed = {n: self._spawned[n] for n in names}
        return (lambda spec: [editor.remove(spec, n, meta['frame'], meta['assets'],
                                            meta.get('defaults', ()))
                              for n, meta in doomed.items()],
                None, {k: v for k, v in self._spawned.items() if k not in doomed},
                {k: v for k, v in self._overrides.items() if k not in doomed}, len(doomed),
                None)

    # ---------------------------------------------------------------- physics parameters

    def set_gravity(self, gravity: Sequence[float]) -> None:
        g = check_finite('gravity', gravity, 3)
        self._change(lambda: (lambda spec: setattr(spec.option, 'gravity', g.tolist()),
                              None, None, None, 0, None))

    def set_timestep(self, timestep: float) -> None:
        (dt,) = check_finite('timestep', [timestep], 1)
        if not 0 < dt <= 0.1:
            raise InvalidArgumentError(f'timestep must be in (0, 0.1] s, got {timestep}')
        self._change(lambda: (lambda spec: setattr(spec.option, 'timestep', float(dt)),
                              None, None, None, 0, None))

    def set_friction(self, name: str, sliding: float, torsional: Optional[float] = None,
                     rolling: Optional[float] = None) -> None:
        """
        Friction of every geom of an entity (MuJoCo's three coefficients).

        It wins over surfaces without friction of their own (see :func:`editor.apply_contact`).
        """
        def plan() -> tuple:
            rec = self._index.entity(name)
            cur = (self._model.geom_friction[rec.geom_ids[0]] if rec.geom_ids
                   else np.array([1.0, 0.005, 0.0001]))
            f = check_finite('friction', [sliding, cur[1] if torsional is None else torsional,
                                          cur[2] if rolling is None else rolling], 3)
            if np.any(f < 0):
                raise InvalidArgumentError(f'friction must be >= 0, got {f.tolist()}')
            return self._plan_override_locked(name, 'friction', f)
        self._change(plan)

    def set_restitution(self, name: str, restitution: float) -> None:
        """
        Bounciness in [0, 0.8] of an entity's geoms.

        A bounce off any surface without a restitution of its own has that coefficient (see
        :func:`editor.apply_contact`).
        """
        e = self._check_restitution(restitution)
        self._change(lambda: self._plan_override_locked(name, 'restitution', e))

    def _plan_override_locked(self, name: str, key: str, value) -> tuple:
        """Return the World._change plan of one entity's contact setting."""
        own = {**self._overrides.get(name, {}), key: value}
        geoms = [self._index.geom_names[g] for g in self._index.entity(name).geom_ids]
        contact = self._contact_of(own)
        return (lambda spec: editor.apply_contact(spec, geoms, *contact), None, None,
                {**self._overrides, name: own}, 0, None)

    def _contact_of(self, own: dict) -> tuple:
        """(friction, restitution, priority) for geoms with settings `own` (maybe none)."""
        return (own.get('friction', self._default_friction),
                own.get('restitution', self._default_restitution),
                editor.OWN_CONTACT_PRIORITY if own else 0)

    def set_default_contact(self, friction: Optional[Sequence[float]] = None,
                            restitution: Optional[float] = None) -> None:
        """Global friction (3 values) and/or restitution for every geom without its own."""
        f = None if friction is None else check_finite('friction', friction, 3)
        e = None if restitution is None else self._check_restitution(restitution)
        with self._locked():
            old = self._default_friction, self._default_restitution

        def plan() -> tuple:  # compiled outside the world lock (World._change); edits take
            self._default_friction = old[0] if f is None else f  # turns, so no other edit
            self._default_restitution = old[1] if e is None else e  # plans meanwhile
            idx = self._index
            groups = [([idx.geom_names[g] for g in r.geom_ids],
                       self._contact_of(self._overrides.get(r.name, {}))) for r in idx.entities]
            groups.append(([n for g, n in enumerate(idx.geom_names)
                            if self._model.geom_bodyid[g] == 0], self._contact_of({})))
            return (lambda spec: [editor.apply_contact(spec, geoms, *contact)
                                  for geoms, contact in groups], None, None, None, 0, None)
        try:
            self._change(plan)
        except Exception:
            with self._locked():
                self._default_friction, self._default_restitution = old
            raise

    @staticmethod
    def _check_restitution(restitution: float) -> float:
        (e,) = check_finite('restitution', [restitution], 1)
        if not 0.0 <= e <= editor.MAX_RESTITUTION:
            raise InvalidArgumentError(
                f'restitution must be in [0, {editor.MAX_RESTITUTION}], got {restitution}')
        return float(e)

    def _weld(self, name: str) -> None:
        """
        Weld a free entity to the world where it is at the commit (a static one: nothing).

        Compiled with the lock released, as every structural edit: the object moves meanwhile,
        so the commit puts the welded body where the object is at that instant, in the new model
        and in the kept spec alike.
        """
        def plan() -> tuple:
            rec = self._index.entity(name)
            if rec.category == ROBOT:
                raise IncorrectStateError(ERR_ROBOT_WELD.format(name=name))
            if not rec.has_free_joint:  # static already: nothing to compile
                return None, None, None, None, 0, None
            frame = self._frame_of(name)
            self._kinematics_locked()
            pos, q = state.body_pose(self._data, rec.root_body)

            def here_now(model: mujoco.MjModel, data: mujoco.MjData,
                         keep: mujoco.MjSpec) -> None:
                self._kinematics_locked()  # the live (old) world, as it is at the commit
                now_pos, now_q = state.body_pose(self._data, rec.root_body)
                body = model.body(name).id
                model.body_pos[body], model.body_quat[body] = now_pos, now_q
                editor.weld_in_place(keep, frame, rec, now_pos, now_q)  # the spec agrees
                mujoco.mj_forward(model, data)
            return (lambda spec: editor.weld_in_place(spec, frame, rec, pos, q), here_now,
                    None, None, 0, None)
        self._change(plan)

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

        def plan() -> tuple:
            rec = self._index.entity(name)
            total = float(sum(self._model.body_mass[b] for b in rec.body_ids))
            if total <= 0:
                raise IncorrectStateError(ERR_NO_MASS.format(name=name))
            model, index = self._model, self._index
            return (lambda spec: (
                editor.free(spec, rec) if rec.category == STATIC else None,
                editor.scale_mass(spec, model, index, rec, m_new / total)),
                None, None, None, 0, None)
        self._change(plan)
