"""
What can be loaded as a world: MJCF, URDF or SDF text, read and checked as a spawn's is.

:func:`world_source` is load_world's and the scene parameter's way in: the text's files are
read here (safe XML, budgets, every file from inside the readable folders), elements not read
are named (or, asked to fail on unsupported elements, refused), and an SDF world comes with
the models it makes on their own (:class:`WorldSource`). Nothing here touches a live world.
"""

from dataclasses import dataclass, field
import functools
from pathlib import Path
import re
from typing import Optional, Sequence
import xml.etree.ElementTree as ET

import mujoco

from . import assets, sdf_read, sdf_world, sources
from .assets import Reader
from .sdf_files import Places
from ..base.errors import (FeatureUnsupportedError, MissingAssetsError, UnsupportedAssetsError,
                           UnsupportedElementsError)

#: Elements MuJoCo's XML reader expands before it checks its schema, which does not list them.
_EXPANDED_FIRST = frozenset({'include', 'mujocoinclude', 'frame', 'replicate', 'composite'})
ERR_UNKNOWN_ELEMENTS = ('the world uses elements MuJoCo does not know: {tags} (asked to fail on '
                        'unsupported elements; without fail_on_unsupported_element they are '
                        'left out)')

ERR_IGNORE_ASSETS = ('loading a world without its missing or unsupported assets is not supported '
                     '(ignore_missing_or_unsupported_assets): {err}')


@functools.lru_cache(maxsize=1)
def mjcf_elements() -> frozenset:
    """Every element name MuJoCo's MJCF reader knows: its schema's, and those it expands first."""
    names = re.findall(r'^\s*(?:\(world\))?(\w+) \(.\)', mujoco.mj_printSchema(False, False),
                       re.M)
    return frozenset(names) | {'worldbody'} | _EXPANDED_FIRST


def element_list(tags: Sequence[str]) -> str:
    """Name up to ten element tags as ``<a>, <b>``, each cut to 50 characters."""
    return ', '.join(f'<{t[:50]}>' for t in tags[:10])


def drop_unknown_elements(root: ET.Element, fail: bool) -> list:
    """
    Remove the elements of an MJCF document MuJoCo knows nowhere; return their names.

    With `fail`, refuse the document instead (:class:`UnsupportedElementsError`). A known
    element in the wrong place is left for MuJoCo to refuse (RESOURCE_PARSE_ERROR).
    """
    known = mjcf_elements()
    found = sorted({e.tag for e in root.iter() if e.tag not in known})
    if found and fail:
        raise UnsupportedElementsError(ERR_UNKNOWN_ELEMENTS.format(tags=element_list(found)))
    for parent in list(root.iter()):
        for child in [c for c in parent if c.tag not in known]:
            parent.remove(child)
    return found


def world_spec(text: str, base_dir: Optional[str] = None,
               allowed_roots: Optional[Sequence[str]] = None,
               max_bytes: int = sources.LIMITS.max_resource_bytes,
               max_faces: int = sources.LIMITS.max_mesh_faces,
               fail_on_unsupported_element: bool = False,
               ignore_missing_assets: bool = False) -> tuple:
    """
    Return (spec of a whole world (load_world), unknown elements dropped) from untrusted text.

    Files are read here. Elements MuJoCo does not know are dropped, or with
    `fail_on_unsupported_element` refused (LoadWorld's two modes). Missing or unusable assets
    always fail: `ignore_missing_assets` (loading without them) is not supported and says so.
    """
    root = sources.check_model_text(text, base_dir, allowed_roots, max_bytes)
    try:
        assets.sandbox(root, Path(base_dir) if base_dir else None, allowed_roots,
                       sources.budget(max_bytes, max_faces))
    except (MissingAssetsError, UnsupportedAssetsError) as exc:
        if ignore_missing_assets:
            raise FeatureUnsupportedError(ERR_IGNORE_ASSETS.format(err=exc)) from None
        raise
    dropped = drop_unknown_elements(root, fail_on_unsupported_element) \
        if root.tag == 'mujoco' else []
    # its marked meshes are split by World (split_marked_meshes)
    return sources.spec_from(root), dropped


@dataclass
class WorldSource:
    """
    A world to load: its spec, the entities to attach as it is made, what it said.

    :param entities: ``(name, SpawnSource, position (3,), quat wxyz (4,))`` of the models
        made on their own (an SDF world's models with sensors or systems, its URDF includes).
    :param name: the name the world gives itself ('' : none; MJCF's is its file's).
    :param dropped: the elements not read (named in the answer, or refused with
        ``fail_on_unsupported_element``).
    :param real_time_factor: the pace the world file asks for (None: it asks none).
    :param systems: plugins the world names that this simulator does not run.
    """

    spec: mujoco.MjSpec
    entities: list = field(default_factory=list)
    name: str = ''
    dropped: list = field(default_factory=list)
    real_time_factor: Optional[float] = None
    systems: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    reader: Optional[Reader] = None
    #: What an SDF world left out for a missing or unsupported asset, as
    #: ``ignore_missing_or_unsupported_assets`` asks (an include, a mesh, a texture).
    skipped: list = field(default_factory=list)

    def settle(self, loaded: bool) -> None:
        """Say the world was loaded, or refused: a refused one's copied files go."""
        for _, source, _, _ in self.entities:
            source.settle(loaded)
        if self.reader is not None:
            self.reader.settle(keep=loaded)


def world_source(text: str, base_dir: Optional[str] = None,
                 allowed_roots: Optional[Sequence[str]] = None,
                 max_bytes: int = sources.LIMITS.max_resource_bytes,
                 max_faces: int = sources.LIMITS.max_mesh_faces,
                 fail_on_unsupported_element: bool = False,
                 ignore_missing_assets: bool = False,
                 places: Optional[Places] = None, name: str = '') -> WorldSource:
    """
    Return the world of untrusted MJCF, URDF or SDF text (load_world, the scene parameter).

    MJCF and URDF as :func:`world_spec` reads them; SDF by :mod:`.sdf_world`. Elements not read
    are named in :attr:`WorldSource.dropped`, or with `fail_on_unsupported_element` refused.
    With `ignore_missing_assets`, an SDF world goes on without what names a missing or
    unsupported asset (:attr:`WorldSource.skipped`; a file outside the readable folders is
    refused all the same); an MJCF or URDF world refuses it as not supported.

    :param name: what the text is called in messages (its file's name; '' : the SDF).
    """
    if not sdf_read.is_sdf(text):
        spec, dropped = world_spec(text, base_dir, allowed_roots, max_bytes, max_faces,
                                   fail_on_unsupported_element, ignore_missing_assets)
        return WorldSource(spec, dropped=dropped)
    sources.check_text_size(text, max_bytes)
    places = places or Places.of(allowed_roots or ())
    reader = assets.Reader(allowed_roots, sources.budget(max_bytes, sources.URDF_MAX_INPUT_FACES))
    made: list = []
    try:
        expanded = sdf_read.expand(text, Path(base_dir) if base_dir else None, reader,
                                   places, name, skip_missing=ignore_missing_assets)
        plan = sdf_world.world(expanded, reader, places)
        if plan.not_read and fail_on_unsupported_element:
            raise UnsupportedElementsError(ERR_UNKNOWN_ELEMENTS.format(
                tags=element_list(plan.not_read)))
        for e in plan.entities:
            source = (sources.from_file(e.urdf, allowed_roots, fixed=e.static) if e.urdf else
                      sources.SpawnSource(spec=e.spec, kind='sdf', description=e.description,
                                          name=e.name, urdf_notes=e.notes))
            made.append((e.name, source, e.pose[0], e.pose[1]))
    except BaseException:
        reader.settle(keep=False)
        for _, source, _, _ in made:
            source.settle(False)
        raise
    return WorldSource(plan.spec, made, plan.name, plan.not_read, plan.real_time_factor,
                       plan.systems, plan.notes, reader, expanded.skipped or [])
