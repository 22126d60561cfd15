"""
The one commit path of every structural edit: plan under the lock, build outside it, commit.

An edit is planned under the world lock (it checks against the live world and returns an
:class:`~.design.Edit`), built from a copy of the :class:`~.design.Design` and compiled with the
lock released (MuJoCo's mesh cache makes the entities already there cheap, and the compile
releases the GIL), then committed under the lock if the world is still the one it was planned
on: the live state carried over by element names (:mod:`.transfer`), the check, the switch
(:meth:`Live.switch_locked <.live.Live.switch_locked>`). Otherwise it is planned again.
Compaction of the spec goes the same way.
"""

from dataclasses import replace
import logging
import threading
import time
from typing import Callable, Optional, Sequence

import mujoco

from . import transfer
from ..base.memory import release_free_memory
from ..compiled import index as model_index
from ..models import asset_store
from ..stepping.design import Design, Edit
from ..stepping.live import Live

#: Times an edit is built outside the lock before it is done under it (see Transaction.change).
EDIT_ATTEMPTS = 3
#: A compaction gives freed memory back once this much is free (a trim stalls allocations).
TRIM_AFTER_COMPACTION_BYTES = 32 << 20

log = logging.getLogger(__name__)


class Transaction:
    """
    Makes structural edits of a world, one group at a time.

    The world is its :class:`~sim_node.core.stepping.live.Live`.

    Lock order: :attr:`edit_lock` is taken before the world lock, never while holding it; the
    queue's lock is a leaf.
    """

    def __init__(self, live: Live):
        self.live = live
        self.edit_lock = threading.Lock()  # structural edits take turns
        self._queue_lock = threading.Lock()  # a leaf: the edits waiting for edit_lock
        self._queued: list = []

    def change(self, plan_locked: Callable[[], Edit]):
        """
        Apply a structural edit with the world lock held only to plan and to commit.

        ``plan_locked()`` runs under the lock, validates against the live world, and returns
        the :class:`Edit`. Its design is built and compiled with the lock released, so the loop
        steps and readers read meanwhile; edits take turns (``edit_lock``), and if the world
        changed in between (a state write that moved a welded entity, an edit made inside
        ``World.locked()``), the edit is planned again on the new world.

        Edits that queued while another was being made are made together when they can be
        (spawns and deletes, :attr:`Edit.batchable`): one compile and one commit for all of
        them, as a database commits a group. Under 8 clients spawning and deleting, each edit
        cost the process a compile of the whole world, and the node ran out of CPU. When the
        group fails anywhere (one name twice, an overlap between two of them, over
        ``max_bodies``), its edits are made one by one, each with its own answer.

        :returns: the edit's ``result``.
        """
        live = self.live
        if live.holds_lock():  # called inside locked(): waiting for edit_lock could
            with live.lock:  # deadlock with an edit waiting for the world lock
                edit = plan_locked()
                self.edit_locked(edit)
                return edit.result
        pending = _Pending(plan_locked)
        with self._queue_lock:
            self._queued.append(pending)
        with self.edit_lock:
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
                self._release_meshes_locked(time.monotonic())
        return pending.outcome()

    def edit_locked(self, edit: Edit) -> None:
        """
        Build and commit `edit` all under the lock.

        For edits that read the live state as they are made (moving a welded entity within a
        state write) and edits made inside ``World.locked()``; every other edit goes through
        :meth:`change`. A failed compile or check leaves the world, its design and its
        generation exactly as they were.
        """
        if edit.apply is None:  # nothing to change
            return
        nxt, model = self.live.design.build(edit)
        self._commit_locked(nxt, model, edit.check)

    # ---------------------------------------------------------------- groups and single edits

    def _make_group(self, group: list) -> None:
        """Make the queued edits `group` (:class:`_Pending`): together where they can be."""
        live = self.live
        alone = group
        if len(group) > 1:
            with live.lock:
                generation, design, old = live.generation, live.design, live.model
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
        group = grouped(edits)
        try:
            nxt, model = design.build(group)
            return (model.nbody <= self.live.config.max_bodies and
                    self._commit_if_unchanged(generation, old, nxt, model, group.check))
        except Exception as exc:  # noqa: B902 (each edit is made alone, and answered, next)
            log.debug('%d edits could not be made together (%s): one by one', len(edits), exc)
            return False

    def _make_one(self, plan_locked: Callable[[], Edit]):
        """Make one edit (see :meth:`change`); ``edit_lock`` held. Returns its result."""
        live = self.live
        for _ in range(EDIT_ATTEMPTS):
            with live.lock:
                generation, design, old = live.generation, live.design, live.model
                edit = plan_locked()
            if edit.apply is None:
                return edit.result
            nxt, model = design.build(edit)
            if self._commit_if_unchanged(generation, old, nxt, model, edit.check):
                return edit.result
        with live.lock:  # the world kept changing: do it all under the lock
            edit = plan_locked()
            self.edit_locked(edit)
        return edit.result

    # ---------------------------------------------------------------- commits

    def _commit_if_unchanged(self, generation: int, old: mujoco.MjModel, nxt: Design,
                             model: mujoco.MjModel,
                             check: Optional[Callable[..., None]]) -> bool:
        """
        Prepare `model` with the lock released, then commit it if the world is still `generation`.

        :returns: whether it committed (False: changed meanwhile, nothing done).
        """
        prepared = _prepare(old, model, generation, nxt)
        live = self.live
        with live.lock:
            if live.generation != generation:
                return False
            self._commit_locked(nxt, model, check, prepared)
        return True

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
        live = self.live
        if prepared is None:
            index, data = None, transfer.transfer(live.model, live.data, model)
        else:
            index, matching, data = prepared
            transfer.carry(matching, live.data, data)
        if check is not None:
            # The checks see the new world's poses and contacts, all they read: the position
            # stage once for them all (a group of spawns checks each), not mj_forward, which
            # the switch runs anyway once the commands are bound. Each MuJoCo call gives the
            # GIL away, and the world lock is held (see editor.find_overlap).
            mujoco.mj_fwdPosition(model, data)
            check(model, data, nxt.spec)
        live.switch_locked(nxt, model, data, index)

    def release_meshes(self, now: float) -> bool:
        """
        Evict the kept meshes of removed entities that are due at `now` (time.monotonic()).

        For a periodic caller (the session's thread): skipped while an edit is being made,
        which does it itself when it ends. Returns whether it ran.
        """
        if not self.edit_lock.acquire(blocking=False):
            return False
        try:
            self._release_meshes_locked(now)
        finally:
            self.edit_lock.release()
        return True

    def _release_meshes_locked(self, now: float) -> None:
        """
        Drop from MuJoCo's mesh cache what removed entities brought, once it is not kept.

        A removed entity's meshes stay cached ``mesh_cache_keep_sec`` seconds, and the kept
        ones at most ``mesh_cache_keep_mb`` MiB, oldest out first: the same robot spawned
        again meanwhile finds them processed (its spawn inherits them). The cache's least
        recently used entries are the removed ones: the last compile of the world used every
        live mesh, and the oldest removals are the least recent. Called with ``edit_lock``.
        """
        config = self.live.config
        with self.live.lock:
            design = self.live.design
            released = list(design.released)
            budget = config.mesh_cache_keep_mb * 2 ** 20
            kept, evicted = sum(r.nbytes for r in released), 0
            while released and (now - released[0].at >= config.mesh_cache_keep_sec
                                or kept > budget):
                oldest = released.pop(0)
                kept, evicted = kept - oldest.nbytes, evicted + oldest.nbytes
            if evicted:
                self.live.design = replace(design, released=tuple(released))
        if evicted:
            asset_store.evict_meshes(evicted)
            release_free_memory(at_least=TRIM_AFTER_COMPACTION_BYTES)

    def kept_mesh_bytes(self) -> int:
        """Return the bytes of removed entities' meshes kept in the cache now."""
        with self.live.lock:
            return sum(r.nbytes for r in self.live.design.released)

    def _compact_if_due(self) -> None:
        """
        Replace the spec by the same world written out and read back, once enough were removed.

        See :meth:`Design.compacted`; the state carries over by names like any other edit.
        Built outside the world lock; called with ``edit_lock``.
        """
        live = self.live
        with live.lock:
            if not live.design.due_for_compaction:
                return
            generation, design, old = live.generation, live.design, live.model
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
    """An edit waiting for its turn (:meth:`Transaction.change`): its plan, then its answer."""

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


def grouped(edits: Sequence[Edit]) -> Edit:
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
