"""
Untrusted model text made safe to hand to MuJoCo: MuJoCo opens only checked copies.

A client's MJCF or URDF is parsed with defusedxml (no DOCTYPE, no entities, bounded nesting),
its ``<include>`` elements are expanded here (an included file's root may be ``<mujoco>`` or
``<mujocoinclude>``), and every file any attribute names (``file``, ``filename``, a cube
texture's ``fileright`` ...: every attribute whose name starts with ``file``) is resolved here,
once: the name is resolved (``..`` and symbolic links included) and accepted only when the real
file lies inside the allowed directories, is a regular file and stays within the size, face and
pixel budgets. The file is then copied into the :class:`AssetStore`, a private folder, named by
the file's identity, and the attribute is rewritten to that copy's absolute path. MuJoCo reads
nothing else.

Why copies on disk and not ``MjSpec.from_string(text, assets=...)``: MuJoCo's mesh cache works
for files (a second compile of a 58-mesh arm: 62 ms, against 225 ms from an asset dict), and a
compile that reads files releases the GIL throughout, while one that reads an asset dict held
it for 160-330 ms at a time (measured), stalling every other Python thread, the stepping loop
included. A copy per file identity also lets MuJoCo's cache serve a second spawn of the same
robot, and the store remembers each checked file by (path, inode, size, mtime), so a second
spawn reads and checks nothing again.
"""

from dataclasses import dataclass
import os
from pathlib import Path
import stat
from typing import Optional, Sequence
import xml.etree.ElementTree as ET

import defusedxml
import defusedxml.ElementTree as SafeET

from . import meshes
from .asset_store import store, StoredFile
from .meshes import CONVERTED_SUFFIXES
from .paths import inside_real_roots, real_path, real_roots
from ..base.errors import (MissingAssetsError, OutsideFoldersError, ResourceParseError,
                           UnsupportedAssetsError, UnsupportedFormatError)

#: Deepest element nesting accepted (a real robot is a few dozen deep).
MAX_DEPTH = 200
#: <include> elements per model, and how deep includes may include others.
MAX_INCLUDES, MAX_INCLUDE_DEPTH = 100, 8
#: Largest texture or height field image, in pixels.
MAX_IMAGE_PIXELS = 4096 * 4096
_DIR_ATTRIBUTES = ('meshdir', 'texturedir', 'assetdir')
_MESH_TAGS = ('mesh', 'skin', 'flexcomp')
#: The mesh files MuJoCo decodes itself (a <mesh> may name another kind with content_type).
MUJOCO_MESH_SUFFIXES = ('.stl', '.obj', '.msh')
#: Mesh suffixes converted to STL whatever their content (:mod:`.meshes`).
_IMAGE_TAGS = ('texture', 'hfield')
#: Root elements an included file may have (MuJoCo accepts both).
INCLUDE_ROOTS = ('mujoco', 'mujocoinclude')

ERR_DTD = ('the resource declares a DOCTYPE or entities ({what}); they are not accepted: '
           'remove the declaration')
ERR_DEPTH = 'the resource nests elements deeper than {limit} levels'
ERR_XML = 'resource does not parse as XML: {err}'
ERR_RELATIVE = ('{value!r} is a relative path in a resource_string: give files by absolute path '
                'inside resource_paths, or spawn the model file by uri')
ERR_NOT_FOUND = 'the file {value!r} the model names does not exist'
ERR_OUTSIDE = ('the file {value!r} the model names is not inside the directories this node may '
               'read (its resource_paths parameter)')
ERR_NOT_REGULAR = 'the file {value!r} the model names is not a regular file'
ERR_TOO_LARGE = 'the file {value!r} has {size} bytes, over the limit of {limit}'
ERR_TOTAL = "the model's files add up to more than {limit} bytes"
ERR_FACES = 'the mesh {value!r} has {n} faces, over the limit of {limit}; simplify it'
ERR_PIXELS = 'the image {value!r} has {n} pixels, over the limit of {limit}'
ERR_MESH_KIND = ('the mesh {value!r} is of a kind MuJoCo cannot read ({kind!r}): give an STL, OBJ '
                 'or MSH file (a lone mesh file of another kind spawns by uri)')
ERR_INCLUDES = 'the model has more than {limit} <include> elements or nests them deeper than {d}'
ERR_INCLUDE_ROOT = ('the included file {value!r} is not MJCF: its root is <{tag}> (expected '
                    '<mujoco> or <mujocoinclude>)')
ERR_SUBMODEL = ('<model> assets (a model file inside a model) are not supported: spawn that '
                'model on its own')


@dataclass(frozen=True)
class Budget:
    """What one model may read: bytes per file (a mesh's may differ), bytes in all, faces."""

    max_file_bytes: int
    max_total_bytes: int
    max_mesh_faces: int
    max_mesh_bytes: int = 0  # 0: as max_file_bytes

    @property
    def mesh_bytes(self) -> int:
        return self.max_mesh_bytes or self.max_file_bytes


def parse(text: str) -> ET.Element:
    """Parse untrusted XML: no DOCTYPE or entity declarations, nesting bounded."""
    try:
        root = SafeET.fromstring(text, forbid_dtd=True, forbid_entities=True,
                                 forbid_external=True)
    except defusedxml.DTDForbidden:
        raise ResourceParseError(ERR_DTD.format(what='DOCTYPE')) from None
    except (defusedxml.EntitiesForbidden, defusedxml.ExternalReferenceForbidden):
        raise ResourceParseError(ERR_DTD.format(what='entity')) from None
    except ET.ParseError as exc:
        raise ResourceParseError(ERR_XML.format(err=exc)) from None
    level, depth = [root], 1
    while level:  # level by level: a hostile depth cannot exhaust Python's stack here
        if depth > MAX_DEPTH:
            raise ResourceParseError(ERR_DEPTH.format(limit=MAX_DEPTH))
        level = [child for elem in level for child in elem]
        depth += 1
    return root


# ------------------------------------------------------------------------- the store


# ------------------------------------------------------------------------- one model


def sandbox(root: ET.Element, base_dir: Optional[Path], allowed_roots: Optional[Sequence[str]],
            budget: Budget, reader: Optional['Reader'] = None) -> list:
    """
    Expand includes and check every file the document names; rewrite it to use the copies.

    In MJCF every attribute whose name starts with ``file`` names a file; in URDF only a
    ``<mesh filename>`` of a visual or a collision does (extensions are taken out first, see
    :mod:`.urdf`), and its mesh may be of any kind (:mod:`.meshes` converts it).

    :param base_dir: where relative names resolve (None: text from a client, absolute only).
    :param allowed_roots: directories files may be read from (None: anywhere).
    :param reader: the reader to read with (it holds the copies it returns; see
        :meth:`AssetStore.settle`); None: a new one.
    :returns: ``(element, value, stored)`` of each URDF mesh read (empty for MJCF).
    :raises MissingAssetsError: a file missing, outside the allowed directories, or relative
        in text without a folder.
    :raises UnsupportedAssetsError: not a regular file, or over a budget.
    """
    is_urdf = root.tag == 'robot'
    reader = reader or Reader(allowed_roots, budget)
    if not is_urdf:
        _expand_includes(root, base_dir, reader, 0, [0])
        if root.find('asset/model') is not None:
            raise UnsupportedFormatError(ERR_SUBMODEL)
    dirs = {}
    for c in root.iter('compiler'):  # document order, includes expanded: the last one wins,
        for key in _DIR_ATTRIBUTES:  # as in MuJoCo's parser
            if key in c.attrib:
                dirs[key] = c.attrib.pop(key)  # the copies have absolute paths
    if is_urdf:
        named = [(mesh, 'filename') for kind in ('visual', 'collision') for part in root.iter(kind)
                 for mesh in part.iter('mesh') if 'filename' in mesh.attrib]
    else:
        named = [(elem, attr) for elem in root.iter() for attr in elem.attrib
                 if attr.startswith('file')]
    meshes = []
    for elem, attr in named:
        value = elem.attrib[attr]
        candidates = _candidates(value, elem.tag, dirs, base_dir, is_urdf, allowed_roots)
        stored = reader.read(value, candidates, elem.tag, urdf_mesh=is_urdf)
        kind = Path(value).suffix.lower()
        if is_urdf:
            meshes.append((elem, value, stored))
        elif elem.tag == 'mesh' and 'content_type' not in elem.attrib \
                and kind not in MUJOCO_MESH_SUFFIXES:
            raise UnsupportedAssetsError(ERR_MESH_KIND.format(value=value, kind=kind))
        elem.set(attr, stored.path)
    return meshes


def _candidates(value: str, tag: str, dirs: dict, base: Optional[Path], is_urdf: bool,
                roots: Optional[Sequence[str]] = None) -> list:
    """Where a file name may be, first match wins."""
    if is_urdf and value.startswith('package://'):
        # package:///pkg/... (three slashes) is read as package://pkg/..., as meant
        package, _, rel = value[len('package://'):].lstrip('/').partition('/')
        out = [share / rel for share in package_folders(package, roots or ())]
        # then beside the file: the package's path under the URDF's folder, or just the name
        return out + ([base / package / rel, base / Path(rel).name] if base is not None
                      else [])
    if value.startswith('file://'):
        value = value[len('file://'):]
    if os.path.isabs(value):
        return [Path(value)]
    if base is None:
        raise MissingAssetsError(ERR_RELATIVE.format(value=value))
    if is_urdf:  # MuJoCo's own URDF rule: beside the file (or in its meshdir), by name
        name = Path(value).name
        folder = dirs.get('meshdir', dirs.get('assetdir', ''))
        return [base / value, base / folder / name, base / name]
    if tag in _MESH_TAGS:
        folder = dirs.get('meshdir', dirs.get('assetdir', ''))
    elif tag in _IMAGE_TAGS:
        folder = dirs.get('texturedir', dirs.get('assetdir', ''))
    else:
        folder = ''
    return [base / folder / value]


def package_folders(package: str, roots: Sequence[str]) -> list:
    """
    Return where ``package://<package>/`` may point, in order.

    ``<root>/<package>`` for each allowed root (a folder of ROS packages given as a resource
    path, as on a machine without ROS), then the package's share folder in the ament index.
    """
    out = [Path(r) / package for r in roots]
    share = _SHARES.get(package)
    if share is None:
        try:
            from ament_index_python.packages import get_package_share_directory
            share = _SHARES.setdefault(package, Path(get_package_share_directory(package)))
        except (ImportError, LookupError, ValueError, OSError):
            return out  # not remembered: a package installed later is found then
    return out + [share]


#: Packages found in the ament index: their share folders (a lookup per mesh was 0.2 ms).
_SHARES: dict = {}


def _expand_includes(elem: ET.Element, base: Optional[Path], reader: 'Reader', depth: int,
                     count: list) -> None:
    """Replace each <include file=...> by the children of the file's root element."""
    for child in list(elem):
        if child.tag != 'include':
            _expand_includes(child, base, reader, depth, count)
            continue
        count[0] += 1
        if count[0] > MAX_INCLUDES or depth >= MAX_INCLUDE_DEPTH:
            raise UnsupportedAssetsError(ERR_INCLUDES.format(limit=MAX_INCLUDES,
                                                             d=MAX_INCLUDE_DEPTH))
        value = child.attrib.get('file', '')
        data = reader.load(value, _candidates(value, 'include', {}, base, False))
        try:
            included = parse(data.decode('utf-8'))
        except UnicodeDecodeError:
            raise ResourceParseError(f'the included file {value!r} is not UTF-8 text') from None
        if included.tag not in INCLUDE_ROOTS:
            raise ResourceParseError(ERR_INCLUDE_ROOT.format(value=value, tag=included.tag))
        _expand_includes(included, base, reader, depth + 1, count)
        index = list(elem).index(child)
        elem.remove(child)
        for k, grandchild in enumerate(list(included)):
            elem.insert(index + k, grandchild)


class Reader:
    """
    Reads the files of one model: resolved, checked and budgeted in one place.

    Every check a file gets is here: the name resolved (``..`` and links) and inside the
    allowed roots, a regular file (a FIFO or device is never opened for reading), within the
    size budget, and for meshes and images within the face and pixel budgets.
    """

    def __init__(self, allowed_roots: Optional[Sequence[str]], budget: Budget):
        self.roots = allowed_roots
        self._real_roots = None if allowed_roots is None else real_roots(allowed_roots)
        self.budget = budget
        self._total = 0
        #: The copies this reader returned, each held in the store until :meth:`settle`.
        self.held: list = []

    def read(self, value: str, candidates: list, tag: str,
             urdf_mesh: bool = False) -> StoredFile:
        """Return the checked copy of a file the model names (held until :meth:`settle`)."""
        limit = self.budget.mesh_bytes if tag in _MESH_TAGS else self.budget.max_file_bytes
        real, st = self.resolve(value, candidates, limit=limit)
        key = (real, st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
        if urdf_mesh and Path(value).suffix.lower() in CONVERTED_SUFFIXES:
            done = meshes.converted_before(key)
            if done is not None:  # a Collada file converted in an earlier run: not read again
                self._count(st.st_size)
                return StoredFile(real, st.st_size, None, None, key, done)
            meshes.warm()  # the converters start while the rest of the files are read
        stored = store().cached(key)
        if stored is None:
            stored = store().put(key, real, self._read_bytes(value, real, st, limit))
        self.hold(stored.path)
        self._count(stored.size)
        self._check_content(value, tag, stored)
        return stored

    def allows(self, real: str) -> bool:
        """Whether the resolved path `real` lies inside this reader's roots (any: no roots)."""
        return self._real_roots is None or inside_real_roots(real, self._real_roots)

    def hold(self, path: str) -> None:
        """Hold a file made for this model (a copy, a conversion) until :meth:`settle`."""
        store().hold(path)
        self.held.append(path)

    def settle(self, keep: bool) -> list:
        """Release the files held: the model was made (`keep`) or refused (AssetStore.settle)."""
        held, self.held = self.held, []
        gone = store().settle(held, keep)
        if gone:
            # the conversions of gone files are gone too
            meshes.forget(gone)
        return gone

    def load(self, value: str, candidates: list) -> bytes:
        """Return the bytes of a file the model names (an included file), checked."""
        real, st = self.resolve(value, candidates)
        data = self._read_bytes(value, real, st)
        self._count(len(data))
        return data

    def resolve(self, value: str, candidates: list, messages: Optional[dict] = None,
                limit: Optional[int] = None) -> tuple:
        """
        Return (real path, stat) of the first candidate that exists, inside the roots.

        :param messages: texts for 'outside', 'missing', 'not_regular', 'too_large' (formatted
            with ``size`` and ``limit``) instead of the ones about a file a model names.
        """
        msg = messages or {}
        limit = self.budget.max_file_bytes if limit is None else limit
        for path in candidates:
            try:
                real = real_path(path)
            except (OSError, ValueError):
                continue
            # Judged before existence: a refusal says nothing about what exists outside.
            if self._real_roots is not None and not inside_real_roots(real, self._real_roots):
                raise OutsideFoldersError(msg.get('outside') or ERR_OUTSIDE.format(value=value))
            try:
                st = os.stat(real)
            except (OSError, ValueError):
                continue
            if not stat.S_ISREG(st.st_mode):
                raise UnsupportedAssetsError(msg.get('not_regular')
                                             or ERR_NOT_REGULAR.format(value=value))
            if st.st_size > limit:
                raise UnsupportedAssetsError(
                    msg.get('too_large', ERR_TOO_LARGE).format(
                        value=value, size=st.st_size, limit=limit))
            return real, st
        raise MissingAssetsError(msg.get('missing') or ERR_NOT_FOUND.format(value=value))

    def _read_bytes(self, value: str, real: str, st: os.stat_result,
                    limit: Optional[int] = None) -> bytes:
        limit = self.budget.max_file_bytes if limit is None else limit
        try:  # O_NONBLOCK: a FIFO put there meanwhile cannot block the open
            fd = os.open(real, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
        except OSError:
            raise MissingAssetsError(ERR_NOT_FOUND.format(value=value)) from None
        try:
            now = os.fstat(fd)
            same = (now.st_dev, now.st_ino) == (st.st_dev, st.st_ino)
            if not stat.S_ISREG(now.st_mode) or not same:  # swapped since it was checked
                raise UnsupportedAssetsError(ERR_NOT_REGULAR.format(value=value))
            with os.fdopen(fd, 'rb', closefd=False) as f:
                data = f.read(limit + 1)
        finally:
            os.close(fd)
        if len(data) > limit:
            raise UnsupportedAssetsError(ERR_TOO_LARGE.format(value=value, size=len(data),
                                                              limit=limit))
        return data

    def _count(self, n_bytes: int) -> None:
        self._total += n_bytes
        if self._total > self.budget.max_total_bytes:
            raise UnsupportedAssetsError(ERR_TOTAL.format(limit=self.budget.max_total_bytes))

    def _check_content(self, value: str, tag: str, stored: StoredFile) -> None:
        """Bound what MuJoCo would build from a file before it builds it: faces and pixels."""
        if stored.faces is not None and stored.faces > self.budget.max_mesh_faces:
            raise UnsupportedAssetsError(ERR_FACES.format(value=value, n=stored.faces,
                                                          limit=self.budget.max_mesh_faces))
        if tag in _IMAGE_TAGS and stored.pixels is not None and stored.pixels > MAX_IMAGE_PIXELS:
            raise UnsupportedAssetsError(ERR_PIXELS.format(value=value, n=stored.pixels,
                                                           limit=MAX_IMAGE_PIXELS))
