"""
Where spawnable resources and scenes live, and which URIs may be read (no ROS imports).

URIs a caller may give:

* a spawnable name, e.g. ``box``: a file ``<name>.<ext>`` in an ``objects/`` folder of the
  installed scenes, or directly in one of the resource paths;
* ``package://sim/<path>``: a file in the installed share folder of `sim`;
* ``file:///abs/path`` (or an absolute path): a file inside one of the resource paths.

Paths with ``..`` and files outside the resource paths are refused before anything opens them.
"""

import os
from pathlib import Path
from typing import Optional, Sequence
from urllib.parse import unquote, urlparse

from .core import sources
from .core.errors import MissingAssetsError, NoResourceError, UnsupportedFormatError

SPAWNABLE_SUFFIXES = sources.MODEL_SUFFIXES + sources.MESH_SUFFIXES
PACKAGE = 'sim'


def source_scenes_dir() -> Path:
    """Return the scenes folder of a source checkout (used when the package is not installed)."""
    return Path(__file__).resolve().parent.parent / 'scenes'


def installed_scenes_dir() -> Path:
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(PACKAGE)) / 'scenes'
    except (ImportError, LookupError, ValueError):
        return source_scenes_dir()


def resolve_uri(uri: str, resource_paths: Sequence[str], scenes_dir: Path) -> Path:
    """
    Resolve a spawn or world URI to a checked file path.

    :raises NoResourceError: empty URI.
    :raises MissingAssetsError: nothing there, '..', or outside the resource paths.
    :raises UnsupportedFormatError: a URI scheme other than package:// and file://.
    """
    if not uri or not uri.strip():
        raise NoResourceError('the uri is empty: give a spawnable name, package://sim/..., '
                              'file:///... or a resource_string')
    uri = uri.strip()
    parsed = urlparse(uri)
    if parsed.scheme == 'package':
        if parsed.netloc != PACKAGE:
            root = _package_share(parsed.netloc)
        else:
            root = scenes_dir.parent
        rel = unquote(parsed.path).lstrip('/')
        if '..' in Path(rel).parts:
            raise MissingAssetsError(sources.ERR_DOTDOT.format(path=uri))
        path = root / rel
    elif parsed.scheme == 'file':
        path = Path(unquote(parsed.path))
    elif parsed.scheme == '' and os.path.isabs(uri):
        path = Path(uri)
    elif parsed.scheme == '':
        path = find_spawnable(uri, resource_paths, scenes_dir)
    else:
        raise UnsupportedFormatError(f'unsupported uri scheme {parsed.scheme!r}; use a '
                                     'spawnable name, package:// or file://')
    sources.check_path(str(path), list(resource_paths))
    return path


def _package_share(package: str) -> Path:
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except (ImportError, LookupError, ValueError):
        raise MissingAssetsError(f'package {package!r} is not installed') from None


def find_spawnable(name: str, resource_paths: Sequence[str], scenes_dir: Path) -> Path:
    if '/' in name or '..' in name:
        raise MissingAssetsError(f'{name!r} is not a spawnable name; see get_spawnables')
    for folder in [scenes_dir / 'objects'] + [Path(p) for p in resource_paths]:
        for suffix in SPAWNABLE_SUFFIXES:
            candidate = folder / f'{name}{suffix}'
            if candidate.is_file():
                return candidate
    raise MissingAssetsError(f'no spawnable named {name!r}; see get_spawnables')


def list_spawnables(resource_paths: Sequence[str], scenes_dir: Path,
                    extra_sources: Optional[Sequence[str]] = None) -> list:
    """(uri, description) of the installed objects and of files under the resource paths."""
    out = []
    seen = set()
    folders = [scenes_dir / 'objects'] + [Path(p) for p in resource_paths]
    for src in extra_sources or ():
        folders.append(check_folder(src, resource_paths))
    for folder in folders:
        if not folder.is_dir():
            continue
        for f in sorted(folder.rglob('*')):
            if f.suffix.lower() in SPAWNABLE_SUFFIXES and f.is_file() and f not in seen:
                seen.add(f)
                if f.parent == scenes_dir / 'objects':
                    uri = f'package://{PACKAGE}/scenes/objects/{f.name}'
                else:
                    uri = f.resolve().as_uri()
                out.append((uri, f'{f.suffix[1:].upper()} file {f.name}'))
    return out


def check_folder(folder: str, resource_paths: Sequence[str]) -> Path:
    """Check that a directory a caller names lies inside the resource paths."""
    p = Path(unquote(urlparse(folder).path) if folder.startswith('file://') else folder)
    if '..' in p.parts:
        raise MissingAssetsError(sources.ERR_DOTDOT.format(path=folder))
    if not sources.inside_roots(str(p), resource_paths):
        raise MissingAssetsError(sources.ERR_FILE_OUTSIDE.format(
            path=folder, roots=[os.path.realpath(r) for r in resource_paths]))
    real = Path(os.path.realpath(p))
    if not real.is_dir():
        raise MissingAssetsError(f'not a directory: {folder}')
    return real


def list_worlds(scenes_dir: Path) -> list:
    """(name, uri) for every scene file at the top of the installed scenes folder."""
    return [(f.stem, f'package://{PACKAGE}/scenes/{f.name}')
            for f in sorted(scenes_dir.glob('*.xml'))]


def resolve_scene(scene: str, scenes_dir: Path) -> Path:
    """Return a scene parameter: a path to a file, or a scene name from the installed scenes."""
    if scene.startswith('package://') or scene.startswith('file://'):
        return resolve_uri(scene, [str(scenes_dir)] + [os.path.dirname(unquote(
            urlparse(scene).path))], scenes_dir)
    p = Path(scene)
    if p.is_file():
        return p
    candidate = scenes_dir / f'{scene}.xml'
    if candidate.is_file():
        return candidate
    names = [n for n, _ in list_worlds(scenes_dir)]
    raise MissingAssetsError(f'no scene {scene!r}: give a file path or one of {names}')
