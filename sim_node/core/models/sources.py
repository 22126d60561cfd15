"""
What can be spawned: MJCF, URDF or SDF (text or file), primitives and mesh files.

Each builder returns a :class:`SpawnSource`: an MjSpec (one or more top-level bodies: a
standalone model file works as it is) whose files are checked copies.
Parsing, file checks and mesh loading all happen here, outside the world lock. Nothing here
touches a live world.
"""

from dataclasses import dataclass, field
import logging
import math
from pathlib import Path
from typing import Optional, Sequence
import xml.etree.ElementTree as ET

import mujoco

from . import assets, decompose, meshes, prepare, sdf_read, sdf_world, urdf, xacro_files
from .assets import Reader
from .paths import inside_roots  # noqa: F401 (this module's too)
from .prepare import compile_error, WORLD_GEOMS_BODY  # noqa: F401 (named by scripts)
from .sdf_files import Places
from .sdf_frames import version_of
from .urdf import Prepared
from ..base.config import WorldConfig
from ..base.errors import (InvalidArgumentError, NoResourceError, ResourceParseError,
                           UnsupportedAssetsError, UnsupportedFormatError)

MESH_SUFFIXES = ('.stl', '.obj', '.ply', '.glb', '.gltf', '.dae')
MODEL_SUFFIXES = ('.xml', '.mjcf', '.urdf', '.xacro', '.sdf', '.world')
PRIMITIVES = ('box', 'sphere', 'cylinder', 'capsule')

ERR_EMPTY = 'the resource is empty: give MJCF or URDF text, a file, a primitive or a mesh'
ERR_TOO_LARGE = 'resource of {size} bytes is over the limit of {limit} bytes'
ERR_ROOT_TAG = ('unsupported format: the root element is <{tag}>; expected <mujoco> (MJCF), '
                '<robot> (URDF) or <sdf> (SDF)')
ERR_NO_BODY = 'the model has no body and no geom: nothing to spawn'
ERR_NOT_XML = ('unsupported format: the text is not XML (it starts {start!r}); give MJCF '
               '(<mujoco>), URDF (<robot>) or SDF (<sdf>)')
ERR_SDF_WORLD = ('the SDF holds a world and no model to spawn: load it with load_world (or the '
                 'scene parameter)')
ERR_FILE_MISSING = 'file not found: {path}'
ERR_FILE_NOT_REGULAR = 'not a regular file: {path}'
ERR_FILE_OUTSIDE = ('{path} is not inside the directories this node may read (its resource_paths '
                    'parameter); put the file there or add its directory to resource_paths')
ERR_MESH_SUFFIX = 'unsupported mesh format {suffix!r}; supported: ' + ', '.join(MESH_SUFFIXES)
ERR_MESH_LOAD = 'the mesh {path} could not be loaded: {err}'
ERR_MESH_FACES = 'the mesh has {n} faces, over the limit of {limit}; simplify it'
ERR_PRIMITIVE = 'unknown primitive {shape!r}; supported: ' + ', '.join(PRIMITIVES)
ERR_SIZE = '{shape} needs {n} positive finite size values, got {size}'
ERR_MASS = 'mass must be finite and >= 0, got {mass}'
ERR_RGBA = 'rgba must be 4 values in [0, 1], got {rgba}'
#: The MJCF custom text naming the meshes to decompose (see :func:`split_marked_meshes`).
DECOMPOSE_TEXT = 'decompose_meshes'
ERR_MARKED_MESH = ('<custom><text name="decompose_meshes"> names meshes the model does not have: '
                   '{names}; name <mesh> elements of this model')
# Default budgets: the configuration's (the node passes its own WorldConfig's).
LIMITS = WorldConfig()
#: Most faces a URDF mesh may have as it comes (over MuJoCo's limit it is decimated).
URDF_MAX_INPUT_FACES = 4_000_000


log = logging.getLogger(__name__)

ERR_DEGREE_RANGES = ("{what} reads joint angles in degrees (MJCF's default), but these hinge "
                     'ranges look like radians: {joints}. Add <compiler angle="radian"/> if '
                     'you meant radians.')


def warn_radian_like_ranges(spec: mujoco.MjSpec, what: str) -> None:
    """
    Log hinge ranges of a degree-reading model that look like radians.

    All within +-pi and not empty. ``range="-1.57 1.57"`` without ``<compiler angle="radian"/>`` is
    +-1.57 degrees, a joint that barely moves.
    """
    if not spec.compiler.degree:
        return
    joints = []
    for j in spec.joints:
        lo, hi = (float(v) for v in j.range)
        if (int(j.type) == int(mujoco.mjtJoint.mjJNT_HINGE) and (lo, hi) != (0.0, 0.0)
                and max(abs(lo), abs(hi)) <= math.pi + 1e-3):
            joints.append(f'{j.name or "(unnamed)"} [{lo:g}, {hi:g}]')
    if joints:
        log.warning(ERR_DEGREE_RANGES.format(what=what, joints=', '.join(joints)))


@dataclass
class SpawnSource:
    """
    A parsed description of one entity, ready to attach to a world.

    :param spec: MjSpec with at least one top-level body or worldbody geom; the files it names
        are checked copies (:class:`.asset_store.AssetStore`).
    :param assets: file name -> bytes for meshes given in memory (a spec built in code).
    :param kind: 'mjcf', 'urdf', 'primitive' or 'mesh'.
    :param description: short text for entity info.
    """

    spec: mujoco.MjSpec
    assets: dict = field(default_factory=dict)
    kind: str = 'mjcf'
    description: str = ''
    #: Its default classes, outermost first (attached as ``<entity>/<class>``).
    default_classes: tuple = ()
    #: The MJCF or URDF text it was parsed from ('' for primitives, meshes and specs).
    text: str = ''
    #: The name the resource gives itself (MJCF ``model``, URDF ``robot name``; '' if none):
    #: a spawn without a name takes it.
    name: str = ''
    #: What reading the files held in the asset store (see :meth:`settle`).
    reader: Optional[Reader] = None
    #: A URDF's root, extensions and repairs (:class:`.urdf.Prepared`), else None.
    urdf_notes: Optional[Prepared] = None

    def __post_init__(self):
        if self.kind == 'mjcf':
            warn_radian_like_ranges(self.spec, self.description or 'the model')

    def settle(self, spawned: bool) -> None:
        """Say the source was spawned, or refused: a refused one's copied files go."""
        if self.reader is not None:
            self.reader.settle(keep=spawned)


def check_path(path: str, allowed_roots: Optional[Sequence[str]],
               max_bytes: int = LIMITS.max_resource_bytes) -> Path:
    """
    Check that `path` is a readable regular file inside `allowed_roots` (None: anywhere).

    The path is judged by where it really is (``..`` and symbolic links resolved): a FIFO or
    device would block MuJoCo forever, and a path outside the roots would let a caller read any
    file; both are refused before anything opens the file. Returns the resolved path.
    """
    limits = budget(max_bytes, LIMITS.max_mesh_faces)
    real, _ = assets.Reader(allowed_roots, limits).resolve(str(path), [Path(path)], {
        'outside': ERR_FILE_OUTSIDE.format(path=path),
        'missing': ERR_FILE_MISSING.format(path=path),
        'not_regular': ERR_FILE_NOT_REGULAR.format(path=path), 'too_large': ERR_TOO_LARGE})
    return Path(real)


def _check_size(n_bytes: int, limit: int) -> None:
    if n_bytes > limit:
        raise UnsupportedAssetsError(ERR_TOO_LARGE.format(size=n_bytes, limit=limit))


def _finish(spec: mujoco.MjSpec, kind: str, description: str,
            compile_alone: bool = True) -> SpawnSource:
    """
    Return the source of a spec that has something to spawn.

    :param compile_alone: compile it on its own first, so an error names this model alone.
        Model files skip it: the world's compile reports the same errors, and compiling twice
        would double the cost of a mesh-heavy robot (MuJoCo's cold load of the meshes).
    """
    if not len(spec.worldbody.bodies) and not len(spec.worldbody.geoms):
        raise ResourceParseError(ERR_NO_BODY)
    decompose.bound_hulls(spec)
    if compile_alone:
        try:
            spec.compile()
        except ValueError as exc:
            raise compile_error(exc) from None
    return SpawnSource(spec=spec, kind=kind, description=description)


def check_model_text(text: str, base_dir: Optional[str] = None,
                     allowed_roots: Optional[Sequence[str]] = None,
                     max_bytes: int = LIMITS.max_resource_bytes) -> ET.Element:
    """
    Check MJCF/URDF text before MuJoCo sees it: size, safe XML, root tag.

    Returns the parsed root element; :func:`assets.sandbox` then reads the files it names.
    """
    if not text or not text.strip():
        raise NoResourceError(ERR_EMPTY)
    _check_size(len(text.encode()), max_bytes)
    if not text.lstrip('\ufeff \t\r\n').startswith('<'):  # JSON, YAML, USD ascii, OBJ, ...
        raise UnsupportedFormatError(ERR_NOT_XML.format(start=text.strip()[:20]))
    # Blank lines before an XML declaration: expat refuses them, ROS's parsers take them.
    root = assets.parse(text.lstrip('\ufeff \t\r\n'))  # no DOCTYPE, entities; depth bounded
    if root.tag not in ('mujoco', 'robot'):
        raise UnsupportedFormatError(ERR_ROOT_TAG.format(tag=root.tag[:100]))
    return root


def budget(max_bytes: int, max_faces: int) -> assets.Budget:
    """Return what one model may read: `max_bytes` a file, the configured totals, `max_faces`."""
    return assets.Budget(max_file_bytes=max_bytes, max_total_bytes=LIMITS.max_model_bytes,
                         max_mesh_faces=max_faces, max_mesh_bytes=LIMITS.max_mesh_bytes)


def spec_from(root: ET.Element) -> mujoco.MjSpec:
    """Return the spec of a sandboxed document: it names only checked copies of files."""
    try:
        return mujoco.MjSpec.from_string(ET.tostring(root, encoding='unicode'))
    except ValueError as exc:
        raise compile_error(exc) from None


def from_model_text(text: str, base_dir: Optional[str] = None,
                    allowed_roots: Optional[Sequence[str]] = None,
                    max_bytes: int = LIMITS.max_resource_bytes,
                    max_faces: int = LIMITS.max_mesh_faces, fixed: bool = False,
                    max_bodies: Optional[int] = None,
                    places: Optional[Places] = None, world: str = 'default') -> SpawnSource:
    """
    Parse MJCF, URDF or SDF text into what a spawn attaches.

    URDF through MuJoCo's own importer, prepared by :mod:`.urdf`; SDF by :mod:`.sdf_world`.

    :param base_dir: directory relative file names resolve against (None: only absolute).
    :param allowed_roots: directories files may be read from (None: anywhere).
    :param fixed: a URDF's root stays where it is spawned even when it would float.
    :param max_bodies: a URDF with more links is refused before MuJoCo reads it.
    :param places: where an SDF model's ``model://`` URIs lead (None: the allowed roots).
    :param world: the name of the world an SDF model goes into (its sensors' gz-sim topics).
    """
    if sdf_read.is_sdf(text):
        return from_sdf_text(text, base_dir, allowed_roots, max_bytes, fixed, places, world)
    root = check_model_text(text, base_dir, allowed_roots, max_bytes)
    if root.tag == 'robot' and xacro_files.is_xacro('', text):
        text = xacro_files.expand(allowed_roots if allowed_roots is not None else ['/'],
                                  text=text)
        root = check_model_text(text, base_dir, allowed_roots, max_bytes)
    is_urdf = root.tag == 'robot'
    limits = budget(max_bytes, URDF_MAX_INPUT_FACES if is_urdf else max_faces)
    reader = assets.Reader(allowed_roots, limits)
    prepared = None
    try:
        if is_urdf:
            prepared = urdf.prepare(root, max_bodies, fixed)
        found = assets.sandbox(root, Path(base_dir) if base_dir else None, allowed_roots,
                               limits, reader)
        if is_urdf:
            prepare.convert_urdf_meshes(root, found, reader)
        else:
            prepare.gather_world_geoms(root)
        spec = spec_from(root)
        if is_urdf:
            urdf.finish(spec, prepared, {e.get('filename'): value for e, value, _ in found})
        else:
            split_marked_meshes(spec)
        prepare.inline_skin_files(spec)
        kind = 'urdf' if is_urdf else 'mjcf'
        name = root.attrib.get('name') or root.attrib.get('model') or ''
        source = _finish(spec, kind, f'{kind.upper()} model {name[:100]}'.strip(),
                         compile_alone=False)
    except BaseException:
        reader.settle(keep=False)  # a refused model leaves no file behind
        raise
    source.default_classes = tuple(d.attrib['class'] for d in root.iter('default')
                                   if 'class' in d.attrib)
    source.text, source.name = text, name
    source.reader, source.urdf_notes = reader, prepared
    return source


def check_text_size(text: str, max_bytes: int) -> None:
    """Refuse empty text (NO_RESOURCE) and text over `max_bytes` (UNSUPPORTED_ASSETS)."""
    if not text or not text.strip():
        raise NoResourceError(ERR_EMPTY)
    _check_size(len(text.encode()), max_bytes)


def from_sdf_text(text: str, base_dir: Optional[str] = None,
                  allowed_roots: Optional[Sequence[str]] = None,
                  max_bytes: int = LIMITS.max_resource_bytes, fixed: bool = False,
                  places: Optional[Places] = None, world: str = 'default') -> SpawnSource:
    """
    Parse an SDF model (the first top-level ``<model>``, its includes expanded) to spawn.

    A world of one model (pybullet's model files wrap theirs so) spawns that model.

    :param fixed: the model is static where it is spawned (``?static=true``).
    :raises UnsupportedFormatError: the SDF holds a world and no model (load_world loads it).
    """
    check_text_size(text, max_bytes)
    places = places or Places.of(allowed_roots or ())
    reader = assets.Reader(allowed_roots, budget(max_bytes, URDF_MAX_INPUT_FACES))
    try:
        expanded = sdf_read.expand(text, Path(base_dir) if base_dir else None, reader, places)
        model = expanded.root.find('model')
        inside = expanded.world.findall('model') if expanded.world is not None else []
        if model is None and len(inside) == 1:  # a world wrapped round one model (pybullet's)
            model = inside[0]
        if model is None:
            raise UnsupportedFormatError(ERR_SDF_WORLD if expanded.world is not None else
                                         sdf_world.ERR_NO_MODEL.format(what=''))
        name = model.get('name', '')
        spec, notes = sdf_world.model(model, version_of(model, expanded.version), reader,
                                      places, fixed, world=world)
    except BaseException:
        reader.settle(keep=False)
        raise
    for text_ in notes.repairs:
        log.warning('SDF model %r: %s', name, text_)
    return SpawnSource(spec=spec, kind='sdf', description=f'SDF model {name[:100]}',
                       text=text, name=sdf_world.entity_name(name), reader=reader,
                       urdf_notes=notes)


def split_marked_meshes(spec: mujoco.MjSpec) -> int:
    """
    Give the MJCF meshes a model marks convex parts (:mod:`.decompose`); return how many.

    MJCF marks them with a custom text element naming them, as MuJoCo keeps it unread::

        <custom><text name="decompose_meshes" data="tray shelf"/></custom>
    """
    marked = [t for t in spec.texts if t.name == DECOMPOSE_TEXT]
    if not marked:
        return 0
    names = {n for t in marked for n in t.data.split()}
    unknown = sorted(n for n in names if spec.mesh(n) is None)
    if unknown:
        raise ResourceParseError(ERR_MARKED_MESH.format(names=', '.join(unknown[:10])))
    return decompose.split_geoms(spec, {}, only=names)


def read_model_text(path: Path) -> str:
    """Read an MJCF/URDF file as text; a file that is not UTF-8 is a parse error."""
    try:
        return Path(path).read_text(encoding='utf-8')
    except UnicodeDecodeError:
        raise ResourceParseError(f'{Path(path).name} is not UTF-8 text') from None


def from_file(path: str, allowed_roots: Optional[Sequence[str]] = None,
              max_bytes: int = LIMITS.max_resource_bytes,
              max_faces: int = LIMITS.max_mesh_faces, fixed: bool = False,
              xacro_args: Optional[dict] = None, max_bodies: Optional[int] = None,
              places: Optional[Places] = None, world: str = 'default',
              **mesh_options) -> SpawnSource:
    """
    Load an MJCF, URDF, xacro or SDF file, or a mesh file (STL, OBJ, PLY, GLB, DAE), as one entity.

    :param fixed: a URDF's root stays where it is spawned (see :mod:`.urdf`); an SDF model is
        static.
    :param xacro_args: ``{name: value}`` for a xacro file's ``$(arg name)``.
    :param max_bodies: a URDF with more links is refused before MuJoCo reads it.
    :param places: where an SDF model's ``model://`` URIs lead.
    :param world: the name of the world an SDF model goes into (its sensors' gz-sim topics).
    """
    p = check_path(path, allowed_roots, max_bytes)
    suffix = p.suffix.lower()
    if suffix in MESH_SUFFIXES:
        return from_mesh(str(p), allowed_roots=allowed_roots, max_bytes=max_bytes,
                         max_faces=max_faces, **mesh_options)
    if suffix not in MODEL_SUFFIXES:
        raise UnsupportedFormatError(
            f'unsupported file type {suffix!r}; supported: '
            + ', '.join(MODEL_SUFFIXES + MESH_SUFFIXES))
    if xacro_files.is_xacro(p.name):
        # Expanded in a process of its own, reading only inside the readable folders.
        text = xacro_files.expand(allowed_roots if allowed_roots is not None else ['/'],
                                  path=str(p), args=xacro_args)
    else:
        text = read_model_text(p)
    # Relative names resolve against the folder the caller named the file in, as MuJoCo's
    # own loader does (a link to a model file keeps its folder's meaning).
    return from_model_text(text, base_dir=str(Path(path).parent), allowed_roots=allowed_roots,
                           max_bytes=max_bytes, max_faces=max_faces, fixed=fixed,
                           max_bodies=max_bodies, places=places, world=world)


def check_rgba(rgba: Sequence[float]) -> list:
    vals = [float(v) for v in rgba]
    if len(vals) != 4 or not all(math.isfinite(v) and 0.0 <= v <= 1.0 for v in vals):
        raise InvalidArgumentError(ERR_RGBA.format(rgba=list(rgba)))
    return vals


def check_mass(mass: Optional[float]) -> None:
    if mass is not None and not (math.isfinite(mass) and mass >= 0):
        raise InvalidArgumentError(ERR_MASS.format(mass=mass))


def _new_body_spec(static: bool) -> tuple:
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name='body')
    if not static:
        body.add_freejoint(name='free')
    return spec, body


_PRIMITIVE_SIZES = {'box': 3, 'sphere': 1, 'cylinder': 2, 'capsule': 2}


def primitive_size(shape: str, size: Sequence[float]) -> list:
    """
    Return MuJoCo's (3,) geom size for a primitive: box half-sizes x, y, z; sphere radius.

    Cylinder or capsule radius and half-length. Refuses unknown shapes and bad sizes.
    """
    n_size = _PRIMITIVE_SIZES.get(shape)
    if n_size is None:
        raise UnsupportedFormatError(ERR_PRIMITIVE.format(shape=shape))
    vals = [float(s) for s in size]
    if len(vals) != n_size or not all(math.isfinite(s) and s > 0 for s in vals):
        raise InvalidArgumentError(ERR_SIZE.format(shape=shape, n=n_size, size=list(size)))
    return vals + [0.0] * (3 - n_size)


def primitive(shape: str, size: Sequence[float], mass: Optional[float] = 1.0,
              rgba: Sequence[float] = (0.7, 0.7, 0.7, 1.0), static: bool = False,
              friction: Optional[Sequence[float]] = None) -> SpawnSource:
    """
    Build a box (half-sizes x, y, z), sphere (radius), cylinder or capsule (radius, half-length).

    :param mass: kg; a body without mass (0 or None) is welded to the world (static).
    :param static: weld to the world regardless of mass.
    """
    full_size = primitive_size(shape, size)
    check_mass(mass)
    static = static or not mass
    spec, body = _new_body_spec(static)
    geom = body.add_geom(name='geom', type=getattr(mujoco.mjtGeom, f'mjGEOM_{shape.upper()}'),
                         size=full_size, rgba=check_rgba(rgba))
    if mass:
        geom.mass = float(mass)
    if friction is not None:
        geom.friction = [float(f) for f in friction]
    return _finish(spec, 'primitive', f'{shape} {[float(v) for v in size]}')


def from_mesh(path: str, mass: Optional[float] = 1.0,
              rgba: Sequence[float] = (0.7, 0.7, 0.7, 1.0), scale: float = 1.0,
              static: bool = False, allowed_roots: Optional[Sequence[str]] = None,
              max_bytes: int = LIMITS.max_resource_bytes,
              max_faces: int = LIMITS.max_mesh_faces) -> SpawnSource:
    """
    Load a mesh file as one body: STL and OBJ as MuJoCo reads them, others converted.

    PLY, GLB, glTF, DAE and ASCII STL are converted to binary STL (scenes merged into one
    mesh) in a child process (:mod:`.meshes`); a mesh over `max_faces` is decimated.
    """
    p = check_path(path, allowed_roots, max(max_bytes, LIMITS.max_mesh_bytes))
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise UnsupportedAssetsError(ERR_MESH_SUFFIX.format(suffix=suffix))
    check_mass(mass)
    if not (math.isfinite(scale) and scale > 0):
        raise InvalidArgumentError(f'scale must be positive and finite, got {scale}')
    colour = check_rgba(rgba)
    reader = assets.Reader(allowed_roots, budget(max_bytes, URDF_MAX_INPUT_FACES))
    try:
        stored = reader.read(p.name, [p], 'mesh')
        file = stored.path
        if meshes.needs_conversion(p.name, stored, max_faces):
            (converted,) = meshes.convert([(p.name, stored)], max_faces)
            prepare.hold_if_stored(reader, converted.path)
            file = converted.path
            if converted.decimated:
                log.warning('the mesh %s has %d faces, more than a spawn takes (%d): decimated '
                            'to %d', p.name, converted.faces_in, max_faces, converted.faces)
        static = static or not mass
        spec, body = _new_body_spec(static)
        # A mesh file is cached across recompiles; raw vertex arrays would be reprocessed.
        spec.add_mesh(name='mesh', file=file, scale=[float(scale)] * 3)
        geom = body.add_geom(name='geom', type=mujoco.mjtGeom.mjGEOM_MESH, meshname='mesh',
                             rgba=colour)
        if mass:
            geom.mass = float(mass)
        decompose.split_geoms(spec, {file: p.name})
        source = _finish(spec, 'mesh', f'mesh {p.name}')
    except BaseException:
        reader.settle(keep=False)
        raise
    source.reader = reader
    return source
