"""
The edit phase of a :class:`~sim_node.core.world.World`: every structural change, one commit path.

Spawn, add a body, delete, the removal of the spawned on reset, contact, mass, welds, gravity
and timestep. Each public method validates its arguments, then hands a plan to
:meth:`WorldEdits._change`: the plan runs under the world lock, checks against the live
world, and returns an :class:`~.design.Edit`; the edit is applied to a copy of the world's
:class:`~.design.Design` and compiled with the lock released, and the commit under the lock
swaps design, model, data and index together, carrying the state over by names
(:mod:`.transfer`), or changes nothing. Compaction (:meth:`Design.compacted`) goes the same way.

What this mixin uses of the run phase (``world.py``), and nothing else: the lock
(``_locked``, ``holds_lock``, ``_edit_lock``), the current ``_model``, ``_data``, ``_index``
and ``_generation``, ``_kinematics_locked`` and ``_pose_frame_locked`` to read poses, and
``_adopt_locked`` with ``_control``'s held commands to switch models. What it owns:
``_design``.
"""

import logging
from typing import Callable, Optional, Sequence

import mujoco
import numpy as np

from . import checks, editor, quat, sources, state, transfer
from . import index as model_index
from .checks import check_finite, check_pose
from .design import Contact, Design, Edit, NOTHING, Spawned
from .errors import (CapacityError, IncorrectStateError, InvalidArgumentError, InvalidPoseError,
                     NameNotUniqueError)
from .index import ModelIndex
from .memory import release_free_memory
from .records import ROBOT, STATIC

ERR_CAPACITY = ('the world would hold {n} bodies, over its limit of {limit} (parameter '
                'max_bodies): delete entities first, or raise the limit')
ERR_DUPLICATE = 'an entity or body named {name!r} exists; pick another name or allow renaming'
ERR_INTERPENETRATION = ('at this pose {name!r} would overlap {other!r} by {depth:.4f} m; move '
                        'it, or allow interpenetration')
ERR_NOT_SPAWNED = '{name!r} is part of the loaded scene; only spawned entities can be deleted'
ERR_ROBOT_WELD = '{name!r} is a robot: give it a positive mass'
ERR_NO_MASS = '{name!r} has no mass to scale'
#: Times an edit is built outside the lock before it is done under it (see WorldEdits._change).
EDIT_ATTEMPTS = 3
#: A compaction gives freed memory back once this much is free (a trim stalls allocations).
TRIM_AFTER_COMPACTION_BYTES = 32 << 20

log = logging.getLogger(__name__)


class WorldEdits:
    """Structural and physics-parameter changes of a :class:`World` (see its docstring)."""

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
        # The compile, the slow part, runs outside the world lock (_change): the loop
        # steps and /clock goes on meanwhile.
        return self._change(lambda: self._plan_spawn_locked(
            name, source, pos, q, reference, allow_renaming, overlap_ok, namespace))

    def _plan_spawn_locked(self, name: str, source: sources.SpawnSource, pos: np.ndarray,
                           q: np.ndarray, reference: str, allow_renaming: bool,
                           overlap_ok: bool, namespace: str = '') -> Edit:
        """Return the spawn's edit: its result is the checked name."""
        self._check_capacity_locked(len(source.spec.bodies) - 1)
        if not name or name in self._index.body_ids:
            if not allow_renaming:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=name))
            name = self._unique_name_locked(name or source.kind)
        if reference:
            pos, q = quat.from_frame(*self._pose_frame_locked(reference), pos, q)
        checks.check_extent(pos, self.config.world_extent)
        design = self._design
        contact = design.contact_of(None) if design.default_contact.is_set else None

        def apply(spec: mujoco.MjSpec) -> Spawned:
            frame, bodies, root, defaults = editor.attach(spec, name, source, pos, q)
            if contact is not None:
                geoms = [g.name for b in bodies
                         for g in spec.body(b).find_all(mujoco.mjtObj.mjOBJ_GEOM)]
                editor.apply_contact(spec, geoms, *contact)
            # Its root body's own frame (see ModelInfo.body_alias), and a URDF's own text.
            return Spawned(frame=frame, bodies=bodies, root_link=f'{name}/{root}',
                           defaults=defaults, assets=tuple(source.assets),
                           description=source.description, namespace=namespace,
                           urdf=source.text if source.kind == 'urdf' else '')

        def check(model: mujoco.MjModel, data: mujoco.MjData, keep: mujoco.MjSpec) -> None:
            hit = editor.find_overlap(model, data, name, self.config.interpenetration_tolerance)
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
            root = self._index.entity_of_body(parent)
            if root not in self._design.spawned:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=root))
            self._check_capacity_locked(1)
            full = f'{root}/{name}'
            if full in self._index.body_ids:
                raise NameNotUniqueError(ERR_DUPLICATE.format(name=full))
            return Edit(lambda spec: editor.add_child(
                spec, parent, full, shape, full_size, pos, q, mass, joint, ax, colour),
                result=full)

        return self._change(plan)

    def delete(self, name: str) -> None:
        """
        Remove a spawned entity with its joints, geoms, actuators, sensors, equality constraints.

        Contact pairs, excludes and joint commands; everything else keeps its state exactly.
        """
        def plan() -> Edit:
            self._index.entity(name)
            if name not in self._design.spawned:
                raise IncorrectStateError(ERR_NOT_SPAWNED.format(name=name))
            return self._plan_removal_locked([name])

        self._change(plan)

    def _plan_removal_locked(self, names: Sequence[str]) -> Edit:
        """Return the edit that removes spawned entities `names`."""
        doomed = {n: self._design.spawned[n] for n in names}
        return Edit(lambda spec: [editor.remove(spec, n, rec.frame, rec.assets, rec.defaults)
                                  for n, rec in doomed.items()],
                    redesign=lambda nxt, _: nxt.without(list(doomed)), batchable=True)

    # ---------------------------------------------------------------- physics parameters

    def set_gravity(self, gravity: Sequence[float]) -> None:
        g = check_finite('gravity', gravity, 3)
        self._change(lambda: Edit(lambda spec: setattr(spec.option, 'gravity', g.tolist())))

    def set_timestep(self, timestep: float) -> None:
        (dt,) = check_finite('timestep', [timestep], 1)
        if not 0 < dt <= 0.1:
            raise InvalidArgumentError(f'timestep must be in (0, 0.1] s, got {timestep}')
        self._change(lambda: Edit(lambda spec: setattr(spec.option, 'timestep', float(dt))))

    def set_friction(self, name: str, sliding: float, torsional: Optional[float] = None,
                     rolling: Optional[float] = None) -> None:
        """
        Friction of every geom of an entity (MuJoCo's three coefficients).

        It wins over surfaces without friction of their own (see :func:`editor.apply_contact`).
        """
        def plan() -> Edit:
            rec = self._index.entity(name)
            cur = (self._model.geom_friction[rec.geom_ids[0]] if rec.geom_ids
                   else np.array([1.0, 0.005, 0.0001]))
            f = check_finite('friction', [sliding, cur[1] if torsional is None else torsional,
                                          cur[2] if rolling is None else rolling], 3)
            if np.any(f < 0):
                raise InvalidArgumentError(f'friction must be >= 0, got {f.tolist()}')
            return self._plan_contact_locked(name, friction=f)
        self._change(plan)

    def set_restitution(self, name: str, restitution: float) -> None:
        """
        Bounciness in [0, 0.8] of an entity's geoms.

        A bounce off any surface without a restitution of its own has that coefficient (see
        :func:`editor.apply_contact`).
        """
        e = self._check_restitution(restitution)
        self._change(lambda: self._plan_contact_locked(name, restitution=e))

    def _plan_contact_locked(self, name: str, friction: Optional[np.ndarray] = None,
                             restitution: Optional[float] = None) -> Edit:
        """Return the edit that gives one entity its own friction and/or restitution."""
        geoms = [self._index.geom_names[g] for g in self._index.entity(name).geom_ids]
        own = self._design.contacts.get(name, Contact()).merged(friction, restitution)
        contact = self._design.with_contact(name, own).contact_of(name)
        return Edit(lambda spec: editor.apply_contact(spec, geoms, *contact),
                    redesign=lambda nxt, _: nxt.with_contact(name, own))

    def set_default_contact(self, friction: Optional[Sequence[float]] = None,
                            restitution: Optional[float] = None) -> None:
        """Global friction (3 values) and/or restitution for every geom without its own."""
        f = None if friction is None else check_finite('friction', friction, 3)
        e = None if restitution is None else self._check_restitution(restitution)

        def plan() -> Edit:  # compiled outside the world lock (_change)
            default = self._design.default_contact.merged(f, e)
            nxt, idx = self._design.with_default_contact(default), self._index
            groups = [([idx.geom_names[g] for g in r.geom_ids], nxt.contact_of(r.name))
                      for r in idx.entities]
            groups.append(([n for g, n in enumerate(idx.geom_names)
                            if self._model.geom_bodyid[g] == 0], nxt.contact_of(None)))
            return Edit(lambda spec: [editor.apply_contact(spec, geoms, *contact)
                                      for geoms, contact in groups],
                        redesign=lambda after, _: after.with_default_contact(default))
        self._change(plan)

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
        def plan() -> Edit:
            rec = self._index.entity(name)
            if rec.category == ROBOT:
                raise IncorrectStateError(ERR_ROBOT_WELD.format(name=name))
            if not rec.has_free_joint:  # static already: nothing to compile
                return NOTHING
            frame = self._design.frame_of(name)
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
            return Edit(lambda spec: editor.weld_in_place(spec, frame, rec, pos, q), here_now)
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

        def plan() -> Edit:
            rec = self._index.entity(name)
            total = float(sum(self._model.body_mass[b] for b in rec.body_ids))
            if total <= 0:
                raise IncorrectStateError(ERR_NO_MASS.format(name=name))
            model, index = self._model, self._index
            return Edit(lambda spec: (
                editor.free(spec, rec) if rec.category == STATIC else None,
                editor.scale_mass(spec, model, index, rec, m_new / total)))
        self._change(plan)

    # ---------------------------------------------------------------- the one commit path
    #
    # An edit is planned under the world lock, built from a copy of the design and compiled
    # with the lock released (MuJoCo's mesh cache makes the entities already there cheap, and
    # the compile releases the GIL); only the commit runs under the world lock: the live state
    # carried over by element names (:mod:`.transfer`), the check, the switch.

    def _change(self, plan_locked: Callable[[], Edit]):
        """
        Apply a structural edit with the world lock held only to plan and to commit.

        ``plan_locked()`` runs under the lock, validates against the live world, and returns
        the :class:`Edit`. Its design is built and compiled with the lock released, so the loop
        steps and readers read meanwhile; edits take turns (``_edit_lock``), and if the world
        changed in between (a state write that moved a welded entity, an edit made inside
        ``locked()``), the edit is planned again on the new world.

        Edits that queued while another was being made are made together when they can be
        (spawns and deletes, :attr:`Edit.batchable`): one compile and one commit for all of
        them, as a database commits a group. Under 8 clients spawning and deleting, each edit
        cost the process a compile of the whole world, and the node ran out of CPU. When the
        group fails anywhere (one name twice, an overlap between two of them, over
        ``max_bodies``), its edits are made one by one, each with its own answer.

        :returns: the edit's ``result``.
        """
        if self.holds_lock():  # called inside locked(): waiting for _edit_lock could
            with self._locked():  # deadlock with an edit waiting for the world lock
                edit = plan_locked()
                self._edit_locked(edit)
                return edit.result
        pending = _Pending(plan_locked)
        with self._queue_lock:
            self._queued.append(pending)
        with self._edit_lock:
            if not pending.done:  # else an edit before it made it
                with self._queue_lock:
                    group, self._queued = self._queued, []
                try:
                    self._make_group(group)
                finally:
                    for p in group:  # never leave a caller without an answer
                        if not p.done:
                            p.finish(error=RuntimeError('the edit was not made'))
                self._compact_if_due()
        return pending.outcome()

    def _make_group(self, group: list) -> None:
        """Make the queued edits `group` (:class:`_Pending`): together where they can be."""
        alone = group
        if len(group) > 1:
            with self._locked():
                generation, design, old = self._generation, self._design, self._model
                planned = []
                for p in group:
                    try:
                        planned.append((p, p.plan_locked()))
                    except Exception as exc:  # noqa: B902 (refused: that caller's answer)
                        p.finish(error=exc)
            together = [(p, e) for p, e in planned if e.batchable and e.apply is not None]
            edits = [e for _, e in together]
            if len(edits) > 1 and self._commit_group(edits, generation, design, old):
                for p, e in together:
                    p.finish(e.result)
            alone = [p for p, _ in planned if not p.done]
        for p in alone:
            try:
                p.finish(self._make_one(p.plan_locked))
            except Exception as exc:  # noqa: B902 (refused: that caller's answer)
                p.finish(error=exc)

    def _commit_group(self, edits: list, generation: int, design: Design,
                      old: mujoco.MjModel) -> bool:
        """Build and commit `edits` as one; False (nothing changed) if anything fails."""
        group = _grouped(edits)
        try:
            nxt, model = design.build(group)
            return (model.nbody <= self.config.max_bodies and
                    self._commit_if_unchanged(generation, old, nxt, model, group.check))
        except Exception as exc:  # noqa: B902 (each edit is made alone, and answered, next)
            log.debug('%d edits could not be made together (%s): one by one', len(edits), exc)
            return False

    def _make_one(self, plan_locked: Callable[[], Edit]):
        """Make one edit (see :meth:`_change`); ``_edit_lock`` held. Returns its result."""
        for _ in range(EDIT_ATTEMPTS):
            with self._locked():
                generation, design, old = self._generation, self._design, self._model
                edit = plan_locked()
            if edit.apply is None:
                return edit.result
            nxt, model = design.build(edit)
            if self._commit_if_unchanged(generation, old, nxt, model, edit.check):
                return edit.result
        with self._locked():  # the world kept changing: do it all under the lock
            edit = plan_locked()
            self._edit_locked(edit)
        return edit.result

    def _commit_if_unchanged(self, generation: int, old: mujoco.MjModel, nxt: Design,
                             model: mujoco.MjModel,
                             check: Optional[Callable[..., None]]) -> bool:
        """
        Prepare `model` with the lock released, then commit it if the world is still `generation`.

        :returns: whether it committed (False: changed meanwhile, nothing done).
        """
        prepared = _prepare(old, model, generation, nxt)
        with self._locked():
            if self._generation != generation:
                return False
            self._commit_locked(nxt, model, check, prepared)
        return True

    def _edit_locked(self, edit: Edit) -> None:
        """
        Build and commit `edit` all under the lock.

        For edits that read the live state as they are made (moving a welded entity within a
        state write) and edits made inside :meth:`locked`; every other edit goes through
        :meth:`_change`. A failed compile or check leaves the world, its design and its
        generation exactly as they were.
        """
        if edit.apply is None:  # nothing to change
            return
        nxt, model = self._design.build(edit)
        self._commit_locked(nxt, model, edit.check)

    def _commit_locked(self, nxt: Design, model: mujoco.MjModel,
                       check: Optional[Callable[..., None]],
                       prepared: Optional[tuple] = None) -> None:
        """
        Make a built design and its model the world, carrying the live state over by names.

        The world must be the one the design was built from (same generation): the caller
        checks. `check` (see :class:`Edit`) runs last; if it raises, nothing changed.

        :param prepared: (index, state mapping, fresh data) made beforehand by :func:`_prepare`
            for this generation, or None to make them here.
        """
        if prepared is None:
            index, data = None, transfer.transfer(self._model, self._data, model)
        else:
            index, matching, data = prepared
            transfer.carry(matching, self._data, data)
        if check is not None:
            mujoco.mj_forward(model, data)  # the check sees the new world's poses
            check(model, data, nxt.spec)
        self._switch_locked(nxt, model, data, index)

    def _switch_locked(self, nxt: Design, model: mujoco.MjModel, data: mujoco.MjData,
                       index: Optional[ModelIndex] = None) -> None:
        """Switch the world to a new design, model and data together, or not at all."""
        saved = (self._design, self._generation, self._model, self._data,
                 self._control.held_copy())
        try:
            self._design = nxt
            self._generation += 1
            self._adopt_locked(model, data, index)
        except BaseException:
            # Whatever failed while switching over (index, commands, guard), the world goes
            # back to exactly what it was: a request that fails changes nothing.
            self._design, self._generation, model, data, held = saved
            self._control.restore_held(held)
            self._adopt_locked(model, data)
            raise

    def _compact_if_due(self) -> None:
        """
        Replace the spec by the same world written out and read back, once enough were removed.

        See :meth:`Design.compacted`; the state carries over by names like any other edit.
        Built outside the world lock; called with ``_edit_lock``.
        """
        with self._locked():
            if not self._design.due_for_compaction:
                return
            generation, design, old = self._generation, self._design, self._model
        compacted = design.compacted(old)
        if compacted is None:  # keep the spec; try again after the next edit
            return
        nxt, model = compacted
        if not self._commit_if_unchanged(generation, old, nxt, model, None):
            return  # changed meanwhile (an edit inside locked()): compact another time
        del old, compacted
        release_free_memory(at_least=TRIM_AFTER_COMPACTION_BYTES)


def _prepare(old: mujoco.MjModel, model: mujoco.MjModel, generation: int,
             nxt: Design) -> tuple:
    """
    Prepare a commit of `model` outside the world lock: what needs no live state.

    For the generation after `generation`, with the design `nxt`: the index (names, visuals,
    meshes for markers), the name matching of `old`'s state, the new data.
    """
    return (model_index.build(model, generation + 1, nxt.spawned), transfer.mapping(old, model),
            mujoco.MjData(model))


class _Pending:
    """An edit waiting for its turn (:meth:`WorldEdits._change`): its plan, then its answer."""

    __slots__ = ('plan_locked', 'done', 'result', 'error')

    def __init__(self, plan_locked: Callable[[], Edit]):
        self.plan_locked = plan_locked
        self.done, self.result, self.error = False, None, None

    def finish(self, result=None, error: Optional[BaseException] = None) -> None:
        self.result, self.error, self.done = result, error, True

    def outcome(self):
        """Return the edit's result, or raise what refused it."""
        if self.error is not None:
            raise self.error
        return self.result


def _grouped(edits: Sequence[Edit]) -> Edit:
    """Return one edit that makes `edits` in order: applies, checks and tables."""
    def apply(spec: mujoco.MjSpec) -> list:
        return [e.apply(spec) for e in edits]

    def check(model: mujoco.MjModel, data: mujoco.MjData, spec: mujoco.MjSpec) -> None:
        for e in edits:
            if e.check is not None:
                e.check(model, data, spec)

    def redesign(design: Design, applied: list) -> Design:
        for e, a in zip(edits, applied):
            if e.redesign is not None:
                design = e.redesign(design, a)
        return design

    return Edit(apply, check, redesign, [e.result for e in edits])
