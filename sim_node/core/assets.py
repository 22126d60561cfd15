"""
Untrusted model text made safe to hand to MuJoCo: MuJoCo never opens a file itself.

A client's MJCF or URDF is parsed with defusedxml (no DOCTYPE, no entities, bounded nesting),
its ``<include>`` elements are expanded here, and every file any attribute names (``file``,
``filename``, a cube texture's ``fileright`` ...: every attribute whose name starts with
``file``) is read here: a regular file inside the allowed directories, within the size and
face budgets. The attribute is rewritten to the name of an in-memory asset, and MuJoCo gets
the text plus those bytes (``MjSpec.from_string(text, assets=...)``).
"""

from dataclasses import dataclass
import os
from pathlib import Path
import stat
import struct
from typing import Optional, Sequence
import uuid
import xml.etree.ElementTree as ET

import defusedxml
import defusedxml.ElementTree as SafeET

from .errors import (MissingAssetsError, ResourceParseError, UnsupportedAssetsError,
                     UnsupportedFormatError)

#: Deepest element nesting accepted (a real robot is a few dozen deep).
MAX_DEPTH = 200
#: <include> elements per model, and how deep includes may include others.
MAX_INCLUDES, MAX_INCLUDE_DEPTH = 100, 8
#: Largest texture or height field image, in pixels.
MAX_IMAGE_PIXELS = 4096 * 4096
_DIR_ATTRIBUTES = ('meshdir', 'texturedir', 'assetdir')
_MESH_TAGS = ('mesh', 'skin', 'flexcomp')
_IMAGE_TAGS = ('texture', 'hfield')

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
ERR_INCLUDES = 'the model has more than {limit} <include> elements or nests them deeper than {d}'
ERR_INCLUDE_ROOT = 'the included file {value!r} is not MJCF: its root is <{tag}>'
ERR_SUBMODEL = ('<model> assets (a model file inside a model) are not supported: spawn that '
                'model on its own')


@dataclass(frozen=True)
class Budget:
    """What one model may read: bytes per file, bytes in all, faces per mesh."""

    max_file_bytes: int
    max_total_bytes: int
    max_mesh_faces: int


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
    stack = [(root, 1)]
    while stack:  # iterative: a hostile depth cannot exhaust Python's stack here
        elem, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise ResourceParseError(ERR_DEPTH.format(limit=MAX_DEPTH))
        stack.extend((child, depth + 1) for child in elem)
    return root


def inside_roots(path, roots: Sequence[str]) -> bool:
    """Return True if `path`, with symbolic links resolved, is one of `roots` or inside one."""
    real = Path(os.path.realpath(path))
    reals = [Path(os.path.realpath(r)) for r in roots]
    return any(real == r or r in real.parents for r in reals)


def sandbox(root: ET.Element, base_dir: Optional[Path], allowed_roots: Optional[Sequence[str]],
            budget: Budget) -> dict:
    """
    Expand includes and read every file the document names; rewrite it to use the copies.

    :param base_dir: where relative names resolve (None: text from a client, absolute only).
    :param allowed_roots: directories files may be read from (None: anywhere).
    :returns: asset name -> bytes, for ``MjSpec.from_string(..., assets=...)``.
    :raises MissingAssetsError: a file missing, outside the allowed directories, or relative
        in text without a folder.
    :raises UnsupportedAssetsError: not a regular file, or over a budget.
    """
    is_urdf = root.tag == 'robot'
    reader = _Reader(allowed_roots, budget)
    if not is_urdf:
        _expand_includes(root, base_dir, reader, 0, [0])
        if root.find('asset/model') is not None:
            raise UnsupportedFormatError(ERR_SUBMODEL)
    compiler = root.find('mujoco/compiler' if is_urdf else 'compiler')
    dirs = {}
    for c in ([compiler] if compiler is not None else []) + root.findall('.//compiler'):
        for key in _DIR_ATTRIBUTES:
            if key in c.attrib:
                dirs.setdefault(key, c.attrib.pop(key))  # the copies are flat: no folders
    for elem in root.iter():
        for attr in [a for a in elem.attrib if a.startswith('file')]:
            value = elem.attrib[attr]
            candidates = _candidates(value, elem.tag, dirs, base_dir, is_urdf)
            elem.set(attr, reader.read(value, candidates, elem.tag))
    return reader.assets


def _candidates(value: str, tag: str, dirs: dict, base: Optional[Path], is_urdf: bool) -> list:
    """Where a file name may be, first match wins."""
    if is_urdf and value.startswith('package://'):
        package, _, rel = value[len('package://'):].partition('/')
        share = _package_share(package)
        name = Path(rel).name
        out = [share / rel] if share is not None else []
        return out + ([base / name] if base is not None else [])
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


def _package_share(package: str) -> Optional[Path]:
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except (ImportError, LookupError, ValueError):
        return None


def _expand_includes(elem: ET.Element, base: Optional[Path], reader: '_Reader', depth: int,
                     count: list) -> None:
    """Replace each <include file=...> by the children of the file's <mujoco> root."""
    for i, child in enumerate(list(elem)):
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
        if included.tag != 'mujoco':
            raise ResourceParseError(ERR_INCLUDE_ROOT.format(value=value, tag=included.tag))
        _expand_includes(included, base, reader, depth + 1, count)
        index = list(elem).index(child)
        elem.remove(child)
        for k, grandchild in enumerate(list(included)):
            elem.insert(index + k, grandchild)


class _Reader:
    """Reads files for one model: checked, budgeted, each file once."""

    def __init__(self, allowed_roots: Optional[Sequence[str]], budget: Budget):
        self.roots = allowed_roots
        self.budget = budget
        self.assets: dict = {}
        self._names: dict = {}  # real path -> asset name
        self._total = 0
        # Names unique to this model: the world holds the assets of every entity at once.
        self._prefix = uuid.uuid4().hex[:12]

    def read(self, value: str, candidates: list, tag: str) -> str:
        """Return the in-memory asset name for a file the model names (read once)."""
        path = self._pick(value, candidates)
        real = os.path.realpath(path)
        if real not in self._names:
            data = self._load_checked(value, path)
            _check_content(value, Path(real).suffix.lower(), tag, data, self.budget)
            name = f'{self._prefix}_{len(self.assets)}_{Path(real).name}'
            self.assets[name] = data
            self._names[real] = name
        return self._names[real]

    def load(self, value: str, candidates: list) -> bytes:
        return self._load_checked(value, self._pick(value, candidates))

    def _pick(self, value: str, candidates: list) -> Path:
        if '..' in Path(value).parts:
            raise MissingAssetsError(f"'..' is not allowed in file names: {value!r}")
        for path in candidates:
            if self.roots is not None and not inside_roots(path, self.roots):
                raise MissingAssetsError(ERR_OUTSIDE.format(value=value))
            try:
                path.lstat()
                return path
            except (OSError, ValueError):
                continue
        raise MissingAssetsError(ERR_NOT_FOUND.format(value=value))

    def _load_checked(self, value: str, path: Path) -> bytes:
        limit = self.budget.max_file_bytes
        try:  # O_NONBLOCK: a FIFO put there meanwhile cannot block the open
            fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        except OSError:
            raise MissingAssetsError(ERR_NOT_FOUND.format(value=value)) from None
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode):
                raise UnsupportedAssetsError(ERR_NOT_REGULAR.format(value=value))
            if st.st_size > limit:
                raise UnsupportedAssetsError(ERR_TOO_LARGE.format(value=value, size=st.st_size,
                                                                  limit=limit))
            with os.fdopen(fd, 'rb', closefd=False) as f:
                data = f.read(limit + 1)
        finally:
            os.close(fd)
        if len(data) > limit:
            raise UnsupportedAssetsError(ERR_TOO_LARGE.format(value=value, size=len(data),
                                                              limit=limit))
        self._total += len(data)
        if self._total > self.budget.max_total_bytes:
            raise UnsupportedAssetsError(ERR_TOTAL.format(limit=self.budget.max_total_bytes))
        return data


def _check_content(value: str, suffix: str, tag: str, data: bytes, budget: Budget) -> None:
    """Bound what MuJoCo would build from a file before it builds it: faces and pixels."""
    faces = mesh_faces(suffix, data)
    if faces is not None and faces > budget.max_mesh_faces:
        raise UnsupportedAssetsError(ERR_FACES.format(value=value, n=faces,
                                                      limit=budget.max_mesh_faces))
    if tag in _IMAGE_TAGS and data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) >= 24:
        width, height = struct.unpack('>II', data[16:24])
        if width * height > MAX_IMAGE_PIXELS:
            raise UnsupportedAssetsError(ERR_PIXELS.format(value=value, n=width * height,
                                                           limit=MAX_IMAGE_PIXELS))


def mesh_faces(suffix: str, data: bytes) -> Optional[int]:
    """Return the number of faces of an STL or OBJ file from its bytes (None: another kind)."""
    if suffix == '.stl':
        if len(data) >= 84:
            n = struct.unpack('<I', data[80:84])[0]
            if 84 + 50 * n == len(data):  # binary STL
                return n
        return data.count(b'facet normal')
    if suffix == '.obj':
        return sum(1 for line in data.splitlines() if line.startswith(b'f '))
    return None
