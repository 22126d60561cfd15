"""
The edit phase's state: what the world is made of, as one value replaced whole by each edit.

A :class:`Design` holds the world's spec (kept uncompiled) and what the world knows about it that
MuJoCo does not: the entities spawned since load (:class:`Spawned`, one typed record each), the
contact settings of single entities and of the whole world (:class:`Contact`), and how many
spawned entities (and how many bytes of their meshes) were removed since the spec was last
compacted. It is never changed in place:
:meth:`Design.build` applies an :class:`Edit` to a copy and compiles it, giving the next design
and its model, and the world commits both together or neither (``Transaction.change``,
:mod:`.transaction`).
Rolling a failed commit back is putting the old design back.

No locks here and no live state (MjData): a design is built outside the world lock.
"""

from dataclasses import dataclass, field, replace
import logging
import time
from types import MappingProxyType
from typing import Any, Callable, Mapping, NamedTuple, Optional, Sequence, Tuple

import mujoco
import numpy as np

from ..base import thread_warnings
from ..base.errors import ResourceParseError
from ..models import asset_store

log = logging.getLogger(__name__)

#: The contact priority of geoms with contact settings of their own (friction, restitution):
#: they win a contact over geoms without, and MuJoCo then uses their solref and friction
#: instead of mixing them (the editor sets it; the design keeps it across recompiles).
OWN_CONTACT_PRIORITY = 1

ERR_COMPILE = 'the model does not compile: {err}'
#: How MuJoCo's warning of a setting an attached part has other than the world begins: the world
#: keeps its own (MuJoCo's attach policy 'warning').
ATTACH_CONFLICT = 'Attach conflict'
#: Compact the spec (:meth:`Design.compacted`) after this many spawned entities were removed.
COMPACT_AFTER_REMOVALS = 32
#: ... or once the removed entities' meshes held this much of the model: the spec keeps every
#: mesh it ever processed until it is compacted (a 200,000-face mesh: 93 MiB kept after its
#: entity was deleted, measured), so one large robot deleted is worth a compaction.
COMPACT_AFTER_MESH_BYTES = 4 << 20
#: Model sizes a compaction must keep (it is the same world written out and read back).
_COMPACT_SIZES = ('nq', 'nv', 'na', 'nu', 'nbody', 'njnt', 'ngeom', 'nmocap', 'neq',
                  'nuserdata')


@dataclass(frozen=True)
class Spawned:
    """
    An entity spawned since load, as the spec holds it: what a delete removes, what describes it.

    :param frame: the frame in the world body it is attached through (its spawn pose).
    :param bodies: its top-level bodies' names, the root (named as the entity) first.
    :param root_link: ``<entity>/<root body's name in its own model>``, its own frame's name.
    :param defaults: the default classes it brought (``<entity>/<class>``), outermost first.
    :param assets: names of the asset files it brought (removed with it).
    :param description: what it was spawned from, for ``get_entities``' description.
    :param namespace: the ROS namespace it was spawned with ('' for none).
    :param urdf: a URDF source's own text ('' when spawned from anything else).
    :param world_link: for a URDF fixed to a link named ``world``, that link's pose in the root
        link's frame (see :attr:`.models.urdf.Prepared.world_link`).
    """

    frame: str
    bodies: Tuple[str, ...]
    root_link: str
    defaults: Tuple[str, ...] = ()
    assets: Tuple[str, ...] = ()
    description: str = ''
    namespace: str = ''
    urdf: str = ''
    world_link: Optional[tuple] = None
    #: A URDF's Gazebo drive plugin (:func:`sim_node.core.control.bases.drive_plugin`).
    drive: Optional[dict] = None
    #: The sensors its robot file declares (:class:`~sim_node.core.records.DeclaredLaser`,
    #: :class:`~sim_node.core.records.DeclaredWrench`), under its name and namespace.
    sensors: tuple = ()
    #: Bytes of its meshes in the model (:func:`mesh_bytes`), set by the build that spawned it.
    mesh_bytes: int = 0
    #: Bytes its spawn added to MuJoCo's cache of processed meshes (0: they were there).
    cached_bytes: int = 0
    #: A URDF's geoms (own names) -> the names Gazebo gives those collisions.
    collisions: dict = field(default_factory=dict)
    #: A URDF's ros2_control declaration (:class:`~.models.ros2_control.Ros2Control`), its
    #: namespace the spawn's when one was given.
    ros2_control: Optional[object] = None
    #: The gz-sim systems an SDF model declares (:class:`~.control.gz_systems.GzSystem`).
    systems: tuple = ()
    #: The gz-sim systems an SDF model names that are not run here (their names).
    systems_not_run: tuple = ()
    #: Part of the loaded world (an SDF world's model made on its own), not spawned since: a
    #: delete refuses it and a reset of the spawned keeps it, as for the world's other
    #: entities.
    world: bool = False


@dataclass(frozen=True)
class Contact:
    """Friction (MuJoCo's 3 coefficients) and restitution set by a user; None: not set."""

    friction: Optional[Tuple[float, float, float]] = None
    restitution: Optional[float] = None

    def merged(self, friction: Optional[Sequence[float]] = None,
               restitution: Optional[float] = None) -> 'Contact':
        """Return these settings with the ones given (not None) replaced."""
        return Contact(self.friction if friction is None else tuple(float(f) for f in friction),
                       self.restitution if restitution is None else float(restitution))

    @property
    def is_set(self) -> bool:
        return self.friction is not None or self.restitution is not None


@dataclass(frozen=True)
class Edit:
    """
    A structural edit, planned under the world lock and built outside it.

    :param apply: changes a copy of the spec; what it returns goes to `redesign`. None: there
        is nothing to change (no compile, no commit).
    :param check: ``check(model, data, spec)`` under the world lock at the commit, with the new
        model and data ready (state carried over, poses computed) and the live world still the
        old one: it may refuse (raise), or settle what depends on the live state at that
        instant in the new model, data and spec. A failed check changes nothing.
    :param redesign: ``redesign(design, applied)`` gives the next design's tables from the
        edited one's (the spec is already the edited one); None: the tables stay.
    :param result: what the edit's public method returns.
    :param batchable: it may be made together with other such edits queued at once, in one
        compile and one commit (spawns and deletes: they touch their own entities only).
    """

    apply: Optional[Callable[[mujoco.MjSpec], Any]]
    check: Optional[Callable[[mujoco.MjModel, mujoco.MjData, mujoco.MjSpec], None]] = None
    redesign: Optional[Callable[['Design', Any], 'Design']] = None
    result: Any = None
    batchable: bool = False


#: The edit that changes nothing.
NOTHING = Edit(None)


class Released(NamedTuple):
    """A removed entity's meshes kept in MuJoCo's cache: its description, bytes, when (s)."""

    description: str
    nbytes: int
    at: float  # time.monotonic() of the removal


@dataclass(frozen=True)
class Design:
    """
    The world's spec and its tables (see the module docstring).

    :param spec: uncompiled: copying a compiled spec copies every processed mesh with the GIL
        held (190 ms for three arms, measured), an uncompiled one takes a few milliseconds.
    :param arena: (base bytes, bytes per body) when the scene left MuJoCo's arena to us (see
        ``WorldConfig.arena_bytes_per_body``): every build sizes it for the edited world.
    :param spawned: entity name -> its record, for the entities spawned since load.
    :param contacts: entity name -> its own contact settings (set_friction, set_restitution).
    :param default_contact: the world's, for every geom without its own.
    :param removals: spawned entities removed since the spec was last compacted.
    :param removed_mesh_bytes: the bytes of their meshes in the model (:attr:`Spawned.mesh_bytes`).
    :param released: the mesh cache's bytes that removed entities brought and no entity left
        uses (:class:`Released`, oldest first): kept for a while so that the same robot
        spawned again finds its meshes processed, then evicted by the transaction
        (:meth:`Transaction.release_meshes <sim_node.core.editing.transaction.Transaction>`,
        :func:`.asset_store.evict_meshes`). An entity spawned from the same description as a
        removed one inherits its bytes instead: its meshes are the ones cached.
    :param baked: textures MuJoCo generates (``builtin``) held as their pixels in `spec`:
        (name, (builtin, width, height, nchannel)) to write them out as they were given.
        Generating a 256-pixel skybox took 3 of the default scene's 3.3 ms compile, on every
        spawn and delete.
    """

    spec: mujoco.MjSpec
    arena: Optional[Tuple[int, int]] = None
    spawned: Mapping[str, Spawned] = field(default_factory=lambda: MappingProxyType({}))
    contacts: Mapping[str, Contact] = field(default_factory=lambda: MappingProxyType({}))
    default_contact: Contact = Contact()
    removals: int = 0
    removed_mesh_bytes: int = 0
    released: Tuple['Released', ...] = ()
    baked: Tuple[tuple, ...] = ()

    @classmethod
    def start(cls, spec: mujoco.MjSpec,
              arena: Optional[Tuple[int, int]]) -> Tuple['Design', mujoco.MjModel]:
        """
        Return the design of a loaded scene and its model.

        `spec` is compiled; the design keeps an uncompiled copy made just before.

        :raises ResourceParseError: the scene does not compile.
        """
        _size_arena(spec, arena)
        keep = spec.copy()
        try:
            model = spec.compile()
        except ValueError as exc:
            raise ResourceParseError(f'the scene does not compile: {exc}') from None
        return cls(keep, arena, baked=_bake_textures(keep, model, ())), model

    # ---------------------------------------------------------------- reading

    def deletable(self) -> list:
        """Return the names of the entities spawned since load (not the world's own)."""
        return [n for n, rec in self.spawned.items() if not rec.world]

    def frame_of(self, name: str) -> Optional[str]:
        """Return the frame a spawned entity hangs from (None: an entity of the scene)."""
        rec = self.spawned.get(name)
        return rec.frame if rec else None

    def contact_of(self, name: Optional[str]) -> tuple:
        """
        Return (friction, restitution, priority) for the geoms of entity `name` (None: none).

        Its own settings where it has them, else the world's; own settings win contacts
        (:data:`OWN_CONTACT_PRIORITY`).
        """
        own = self.contacts.get(name, Contact()) if name is not None else Contact()
        d = self.default_contact
        friction = own.friction if own.friction is not None else d.friction
        return (None if friction is None else np.array(friction),
                own.restitution if own.restitution is not None else d.restitution,
                OWN_CONTACT_PRIORITY if own.is_set else 0)

    @property
    def due_for_compaction(self) -> bool:
        return (self.removals >= COMPACT_AFTER_REMOVALS
                or self.removed_mesh_bytes >= COMPACT_AFTER_MESH_BYTES)

    # ---------------------------------------------------------------- the next design

    def with_spawned(self, name: str, rec: Spawned) -> 'Design':
        return replace(self, spawned=MappingProxyType({**self.spawned, name: rec}))

    def without(self, names: Sequence[str]) -> 'Design':
        """Return the tables with spawned entities `names` gone (counted for compaction)."""
        doomed = set(names)
        gone = [self.spawned[n] for n in doomed if n in self.spawned]
        kept = {k: v for k, v in self.spawned.items() if k not in doomed}
        released = list(self.released)
        for rec in gone:  # its cached meshes stay if an entity of the same source stays
            heir = next((k for k, v in kept.items() if v.description == rec.description
                         and v.cached_bytes < rec.cached_bytes), None)
            if heir is not None:
                kept[heir] = replace(kept[heir], cached_bytes=rec.cached_bytes)
            elif rec.cached_bytes > 0:
                released.append(Released(rec.description, rec.cached_bytes, time.monotonic()))
        return replace(
            self, spawned=MappingProxyType(kept),
            contacts=MappingProxyType({k: v for k, v in self.contacts.items()
                                       if k not in doomed}),
            removals=self.removals + len(gone),
            removed_mesh_bytes=self.removed_mesh_bytes + sum(r.mesh_bytes for r in gone),
            released=tuple(released))

    def with_contact(self, name: str, contact: Contact) -> 'Design':
        return replace(self, contacts=MappingProxyType({**self.contacts, name: contact}))

    def with_default_contact(self, contact: Contact) -> 'Design':
        return replace(self, default_contact=contact)

    def build(self, edit: Edit) -> Tuple['Design', mujoco.MjModel]:
        """
        Return the next design and its compiled model: `edit` applied to a copy of the spec.

        Slow (the compile; MuJoCo releases the GIL in it): called with no lock held.

        :raises ResourceParseError: the edited spec does not compile (this design stays).
        """
        trial = self.spec.copy()
        applied = edit.apply(trial)
        _size_arena(trial, self.arena)
        # One thread: the world runs meanwhile, and MuJoCo's compile threads took both cores
        # of two from the loop and /clock (gaps of 40-50 ms while a robot with 12 meshes
        # compiled), for no gain in compile time (tiago 113 ms on one thread, 136 on two).
        trial.compiler.usethread = False
        keep = trial.copy()  # uncompiled: cheap to copy for the next edit
        cached = asset_store.mesh_cache_bytes()
        # This thread's own: the services' threads warn meanwhile too (thread_warnings).
        with thread_warnings.caught(ATTACH_CONFLICT) as conflicts:
            try:
                model = trial.compile()
            except ValueError as exc:
                raise ResourceParseError(ERR_COMPILE.format(err=exc)) from None
        for text in conflicts:  # "Attach conflict ... keeping parent value": the documented rule
            log.info('the world keeps its own settings: %s', ' '.join(text.split()))
        nxt = replace(self, spec=keep, baked=_bake_textures(keep, model, self.baked))
        if edit.redesign is not None:
            nxt = edit.redesign(nxt, applied)
            new = [n for n in nxt.spawned if n not in self.spawned]
            if new:  # what they weigh: only this build knows
                share = max(0, asset_store.mesh_cache_bytes() - cached) // len(new)
                released = list(nxt.released)
                weighed = {}
                for n in new:
                    mine = share
                    # Spawned again while a removed one's meshes were kept: they are its own.
                    again = next((r for r in released
                                  if r.description == nxt.spawned[n].description), None)
                    if again is not None and share == 0:
                        released.remove(again)
                        mine = again.nbytes
                    weighed[n] = replace(nxt.spawned[n], mesh_bytes=mesh_bytes(model, n),
                                         cached_bytes=mine)
                nxt = replace(nxt, spawned=MappingProxyType({**nxt.spawned, **weighed}),
                              released=tuple(released))
        return nxt, model

    def compacted(self, model: mujoco.MjModel) -> Optional[Tuple['Design', mujoco.MjModel]]:
        """
        Return this design with its spec written out and read back, and its model, or None.

        MuJoCo keeps every model ever attached to a spec, deleted or not (about 35 kB for a
        box, measured): a world that spawns and deletes for days would grow without end. The
        round trip compiles to the same model as `model` (same sizes, checked: None if not, or
        if it fails; the world then keeps its spec and tries another time).
        """
        try:
            given = self.spec.copy()
            _unbake_textures(given, self.baked)  # XML holds no pixel buffers
            clean = replace(self, spec=mujoco.MjSpec.from_string(given.to_xml()), baked=())
            nxt, compiled = clean.build(NOTHING_TO_APPLY)
        except (ValueError, ResourceParseError) as exc:
            log.debug('could not compact the model spec: %s', exc)
            return None
        if any(getattr(compiled, k) != getattr(model, k) for k in _COMPACT_SIZES):
            log.debug('compacting the model spec changed its layout; kept the spec as it is')
            return None
        return replace(nxt, removals=0, removed_mesh_bytes=0), compiled


def mesh_bytes(model: mujoco.MjModel, entity: str) -> int:
    """Return the bytes the meshes of spawned `entity` (``<entity>/...``) take in `model`."""
    total = 0
    for k in range(model.nmesh):
        if model.mesh(k).name.startswith(f'{entity}/'):
            total += (24 * int(model.mesh_vertnum[k]) + 36 * int(model.mesh_facenum[k])
                      + 12 * int(model.mesh_normalnum[k]))
    return total


def _bake_textures(spec: mujoco.MjSpec, model: mujoco.MjModel, baked: tuple) -> tuple:
    """
    Hold each named builtin texture of `spec` as the pixels `model` has for it.

    :returns: `baked` and the textures baked now (see :attr:`Design.baked`).
    """
    out = list(baked)
    for tex in spec.textures:
        if tex.builtin == mujoco.mjtBuiltin.mjBUILTIN_NONE or not tex.name:
            continue
        t = model.texture(tex.name).id
        w, h, nc = (int(model.tex_width[t]), int(model.tex_height[t]),
                    int(model.tex_nchannel[t]))
        out.append((tex.name, (tex.builtin, tex.width, tex.height, tex.nchannel)))
        adr = int(model.tex_adr[t])
        tex.builtin = mujoco.mjtBuiltin.mjBUILTIN_NONE
        tex.width, tex.height, tex.nchannel = w, h, nc
        tex.data = model.tex_data[adr:adr + w * h * nc].tobytes()
    return tuple(out)


def _unbake_textures(spec: mujoco.MjSpec, baked: tuple) -> None:
    """Give the textures :func:`_bake_textures` baked their builtin back (gone ones: none)."""
    for name, (builtin, width, height, nchannel) in baked:
        tex = spec.texture(name)
        if tex is not None:
            tex.builtin, tex.width, tex.height, tex.nchannel = builtin, width, height, nchannel
            tex.data = b''


#: An edit that compiles the spec as it is (a compaction's round trip).
NOTHING_TO_APPLY = Edit(lambda spec: None)


def _size_arena(spec: mujoco.MjSpec, arena: Optional[Tuple[int, int]]) -> None:
    """Give a spec whose scene did not size MuJoCo's arena one proportional to its bodies."""
    if arena is not None:
        spec.memory = arena[0] + arena[1] * len(spec.bodies)
