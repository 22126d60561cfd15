"""
Where spawnable resources and scenes live, and which URIs may be read (no ROS imports).

URIs a caller may give:

* a spawnable name, e.g. ``box``: a file ``<name>.<ext>`` in an ``objects/`` folder of the
  installed scenes, or directly in one of the resource paths;
* ``package://sim/<path>``: a file in the installed share folder of `sim`;
* ``file:///abs/path`` (or an absolute path): a file inside one of the resource paths.

Files outside the resource paths (judged once ``..`` and links are resolved) are refused
before anything opens them.
"""

from dataclasses import dataclass
import os
from pathlib import Path
from typing import Mapping, Optional, Sequence, Tuple
from urllib.parse import unquote, urlparse

from . import sdf_files, sources
from .sdf_files import Places
from ..base.errors import (FeatureUnsupportedError, MissingAssetsError, NoResourceError,
                           NotFoundError, UnsupportedFormatError)

SPAWNABLE_SUFFIXES = sources.MODEL_SUFFIXES + sources.MESH_SUFFIXES
PACKAGE = 'sim'


@dataclass(frozen=True)
class Readable:
    """
    The folders requests may read files from.

    :param roots: resolved folders: the installed scenes (unless left out), the resource paths,
        and Gazebo's model folders of the environment (``GZ_SIM_RESOURCE_PATH`` and its older
        names, Fuel's cache: :class:`.sdf_files.Places`), which whoever starts the node sets
        as they set its parameters.
    :param scenes_dir: the installed scenes folder (``package://sim/...`` reads its parent).
    :param places: where SDF's ``model://`` and Fuel URIs lead.
    """

    roots: Tuple[str, ...]
    scenes_dir: Path
    places: Places = Places()

    @classmethod
    def of(cls, resource_paths: Sequence[str], scenes_dir: Path,
           builtin: bool = True, environ: Optional[Mapping] = None) -> 'Readable':
        """
        `resource_paths` added to the installed scenes and objects (`builtin`: kept).

        With them, the model folders Gazebo would search (:meth:`.sdf_files.Places.of` of
        `environ`, None: this process's environment).
        """
        own = [str(scenes_dir)] if builtin else []
        places = Places.of(resource_paths, environ, scenes_dir if builtin else None)
        roots = [str(Path(r).resolve()) for r in own + list(resource_paths) if r]
        roots += [str(Path(r).resolve()) for r in places.roots()]
        return cls(tuple(dict.fromkeys(roots)), Path(scenes_dir), places)

    def redact(self, text: str) -> str:
        """Say `text` without where the server keeps its files (see :func:`redact`)."""
        return redact(text, self.roots, self.scenes_dir)


@dataclass(frozen=True)
class SpawnOptions:
    """
    What a spawn URI's query asks for: ``?static=true&name:=value&...``.

    :param fixed: ``static=true``: a URDF's root stays where it is spawned, as Gazebo's
        ``<static>`` makes a model static.
    :param xacro_args: every ``name:=value``: the arguments of a xacro file.
    """

    fixed: bool = False
    xacro_args: Optional[dict] = None


ERR_OPTION = ('spawn option {item!r} is not supported: a uri may end in ?static=true (a URDF '
              'that stays where it is spawned) and name:=value xacro arguments, joined by &')


def split_options(uri: str) -> Tuple[str, SpawnOptions]:
    """Return the uri without its query, and the spawn options the query gives."""
    base, sep, query = uri.strip().partition('?')
    if not sep:
        return uri, SpawnOptions()
    fixed, args = False, {}
    for item in filter(None, query.split('&')):
        item = unquote(item)
        name, is_arg, value = item.partition(':=')
        if is_arg:
            args[name] = value
        elif item.lower() in ('static=true', 'static=1', 'static'):
            fixed = True
        elif item.lower() not in ('static=false', 'static=0'):
            raise FeatureUnsupportedError(ERR_OPTION.format(item=item[:100]))
    return base, SpawnOptions(fixed, args or None)


def source_scenes_dir() -> Path:
    """Return the scenes folder of a source checkout (used when the package is not installed)."""
    return Path(__file__).resolve().parents[3] / 'scenes'


def installed_scenes_dir() -> Path:
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(PACKAGE)) / 'scenes'
    except (ImportError, LookupError, ValueError, OSError):  # no ament index: a source tree
        return source_scenes_dir()


def resolve_uri(uri: str, resource_paths: Sequence[str], scenes_dir: Path,
                places: Optional[Places] = None) -> Path:
    """
    Resolve a spawn or world URI to a checked file path.

    The file must lie inside the resource paths (``package://sim/...``: inside this package's
    share folder); only then is its existence checked, so a refused path says nothing about
    what exists on the server. A Gazebo model folder is its model's file; ``model://`` and
    Fuel URIs lead where `places` say (None: the resource paths).

    :raises NoResourceError: empty URI.
    :raises NotFoundError: no such file, package or spawnable.
    :raises MissingAssetsError: outside the directories the node may read, once '..' and
        symbolic links are resolved.
    :raises UnsupportedFormatError: a URI scheme other than package:// and file://.
    """
    if not uri or not uri.strip():
        raise NoResourceError('the uri is empty: give a spawnable name, package://sim/..., '
                              'file:///... or a resource_string')
    uri = uri.strip()
    parsed = urlparse(uri)
    roots = list(resource_paths)
    if sdf_files.is_model_uri(uri):
        return resolve_model(uri, roots, places or Places.of(roots))
    if parsed.scheme == 'package':
        rel = unquote(parsed.path).lstrip('/')
        if parsed.netloc == PACKAGE:
            root = scenes_dir.parent
            roots = [str(root)]
        else:
            root = _package_share(parsed.netloc)
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
    # Judged where the path really leads ('..' and links resolved), before its existence.
    if not sources.inside_roots(str(path), roots):
        raise MissingAssetsError(sources.ERR_FILE_OUTSIDE.format(path=uri))
    try:
        exists = path.exists()
    except OSError:  # a name too long for the file system, say
        exists = False
    if not exists:
        raise NotFoundError(f'no file at {uri}; get_spawnables lists what can be spawned')
    if path.is_dir():  # a model folder (Gazebo's): the file its model.config names
        path = model_folder_file(path, roots)
    sources.check_path(str(path), roots)
    return path


def model_folder_file(folder: Path, roots: Sequence[str]) -> Path:
    """
    Return the file of a Gazebo model folder.

    The one its model.config names for the newest SDF version (:func:`.sdf_files.model_file`),
    else its model.sdf.

    :raises MissingAssetsError: no model.config entry and no model.sdf, or outside `roots`.
    """
    config = folder / 'model.config'
    data = None
    if config.is_file():
        data = sources.check_path(str(config), roots).read_bytes()
    return sdf_files.model_file(folder, data)


def resolve_model(uri: str, roots: Sequence[str], places: Places) -> Path:
    """
    Return the file a ``model://`` or Fuel URI names, inside `roots`.

    A model folder gives its model.config's file; ``model://name/path`` a file inside it.

    :raises MissingAssetsError: no such model (where it was looked for is said), or outside
        the readable folders.
    """
    for candidate in sdf_files.candidates(uri, None, places):
        if not sources.inside_roots(str(candidate), roots):
            raise MissingAssetsError(sources.ERR_FILE_OUTSIDE.format(path=uri))
        if candidate.is_dir():
            return model_folder_file(candidate, roots)
        if candidate.exists():
            sources.check_path(str(candidate), roots)
            return candidate
    raise NotFoundError(f'no file at {uri}; get_spawnables lists what can be spawned')


def _package_share(package: str) -> Path:
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except (ImportError, LookupError, ValueError):
        raise NotFoundError(f'package {package!r} is not installed') from None


#: How many names an error message lists at most.
MAX_LISTED_NAMES = 40


def _names_hint(names: Sequence[str]) -> str:
    shown = ', '.join(names[:MAX_LISTED_NAMES])
    more = len(names) - MAX_LISTED_NAMES
    return shown + (f' and {more} more' if more > 0 else '') if names else '(none)'


def find_spawnable(name: str, resource_paths: Sequence[str], scenes_dir: Path) -> Path:
    """Return the file of a spawnable name; an unknown name is answered with the valid ones."""
    if '/' not in name and '..' not in name and len(name.encode()) < 250:
        for folder in [scenes_dir / 'objects'] + [Path(p) for p in resource_paths]:
            for suffix in SPAWNABLE_SUFFIXES:
                candidate = folder / f'{name}{suffix}'
                if candidate.is_file():
                    return candidate
    names = sorted({Path(uri).stem for uri, _ in list_spawnables(resource_paths, scenes_dir)})
    raise NotFoundError(f'no spawnable named {name[:200]!r}; spawnable names: '
                        f'{_names_hint(names)} (or give a package:// or file:// uri)')


def resolve_world(uri: str, resource_paths: Sequence[str], scenes_dir: Path) -> Path:
    """Resolve a load_world URI: a world name from get_available_worlds, or a file URI."""
    if uri and uri.strip() and urlparse(uri.strip()).scheme == '' and \
            not os.path.isabs(uri.strip()):
        name = uri.strip()
        found = dict(_world_files(scenes_dir))
        if name in found:
            return found[name]
        names = list(found)
        raise NotFoundError(f'no world named {name[:200]!r}; worlds: {_names_hint(names)} '
                            '(or give a package:// or file:// uri)')
    return resolve_uri(uri, resource_paths, scenes_dir)


def redact(text: str, resource_paths: Sequence[str], scenes_dir: Path,
           limit: int = 2000) -> str:
    """
    Return an error text fit to send to a client: no server paths, and not too long.

    The resource paths become ``<resource_paths[i]>`` and this package's share folder
    ``package://sim``, so a message says what was wrong with the request, never where the
    server keeps its files; anything over `limit` characters is cut (a huge name sent by a
    client is not echoed back whole).
    """
    aliases = {}
    for i, root in enumerate(resource_paths):
        for form in {str(root).rstrip('/'), os.path.realpath(root)}:
            aliases[form] = f'<resource_paths[{i}]>'
    share = scenes_dir.parent
    for form in {str(share), os.path.realpath(share)}:
        aliases[form] = f'package://{PACKAGE}'
    for real in sorted((a for a in aliases if len(a) > 1), key=len, reverse=True):
        text = text.replace(real, aliases[real])
    if len(text) > limit:
        text = text[:limit] + f'... ({len(text) - limit} more characters)'
    return text


def list_spawnables(resource_paths: Sequence[str], scenes_dir: Path,
                    extra_sources: Optional[Sequence[str]] = None,
                    unrecognised: Optional[list] = None,
                    places: Optional[Places] = None) -> list:
    """
    Return (uri, description) of the installed objects and of files under the resource paths.

    A Gazebo model folder (its ``model.config``) is one entry, ``model://<name>`` where it lies
    on a model path of `places`, its files none; an SDF world file is none (load_world loads
    it), nor is a model folder that holds only a light, nor the stand-ins this package ships
    for classic worlds' ``model://sun`` and ``model://ground_plane`` (an endless plane).

    :param extra_sources: more folders (inside the resource paths) to list.
    :param unrecognised: if given, an extra source that cannot be listed is skipped and why is
        appended here (GetSpawnables answers OK and names them); otherwise it raises.
    """
    out = []
    seen = set()
    folders = [scenes_dir / 'objects'] + [Path(p) for p in resource_paths]
    for src in extra_sources or ():
        try:
            folders.append(check_folder(src, resource_paths))
        except MissingAssetsError as exc:
            if unrecognised is None:
                raise
            unrecognised.append(f'{src!r}: {exc}')
    model_paths = {Path(p).resolve() for p in (places.model_paths if places else ())}
    builtin = (scenes_dir / sdf_files.BUILTIN_MODELS).resolve()
    for folder in folders:
        if not folder.is_dir():
            continue
        models = sorted(c.parent for c in folder.rglob('model.config'))
        for m in models:
            if m in seen or not _has_model(m) or m.resolve().parent == builtin:
                continue
            seen.add(m)
            uri = (f'model://{m.name}' if m.resolve().parent in model_paths
                   else m.resolve().as_uri())
            out.append((uri, f'Gazebo model {m.name}'))
        for f in sorted(folder.rglob('*')):
            if any(p in models for p in f.parents) or (
                    f.suffix.lower() in sdf_files.SUFFIXES and not _has_model(f)):
                continue
            if f.suffix.lower() in SPAWNABLE_SUFFIXES and f.is_file() and f not in seen:
                seen.add(f)
                if f.parent == scenes_dir and _bodiless_world(f):
                    continue  # an empty world (scenes/empty.xml): nothing to spawn
                if f.parent == scenes_dir / 'objects':
                    uri = f'package://{PACKAGE}/scenes/objects/{f.name}'
                else:
                    uri = f.resolve().as_uri()
                out.append((uri, f'{f.suffix[1:].upper()} file {f.name}'))
    return out


def _has_model(path: Path) -> bool:
    """Whether an SDF file (or a model folder's files) holds a model, not only a world or light."""
    files = [path] if path.is_file() else sorted(path.glob('*.sdf'))
    for f in files:
        try:
            with open(f, 'rb') as stream:
                head = stream.read(1 << 16)
        except OSError:
            continue
        if b'<model' in head and b'<world' not in head:
            return True
    return False


def _bodiless_world(path: Path) -> bool:
    """Whether an installed world file has no body (only ground and lights): not a model."""
    try:
        return '<body' not in path.read_text(errors='replace')
    except OSError:
        return False


def check_folder(folder: str, resource_paths: Sequence[str]) -> Path:
    """Check that a directory a caller names lies inside the resource paths."""
    p = Path(unquote(urlparse(folder).path) if folder.startswith('file://') else folder)
    if not sources.inside_roots(str(p), resource_paths):
        raise MissingAssetsError(sources.ERR_FILE_OUTSIDE.format(path=folder))
    real = Path(os.path.realpath(p))
    if not real.is_dir():
        raise MissingAssetsError(f'not a directory: {folder}')
    return real


def _world_files(scenes_dir: Path) -> list:
    """(name, path) of every world file at the top of the installed scenes folder."""
    return [(f.stem, f) for f in sorted(scenes_dir.glob('*'))
            if f.suffix in ('.xml',) + sdf_files.SUFFIXES and f.is_file()]


def list_worlds(scenes_dir: Path) -> list:
    """(name, uri) for every world file (MJCF, SDF) at the top of the installed scenes folder."""
    return [(name, f'package://{PACKAGE}/scenes/{f.name}') for name, f in _world_files(scenes_dir)]


def resolve_scene(scene: str, scenes_dir: Path) -> Path:
    """Return a scene parameter: a path to a file, or a scene name from the installed scenes."""
    if scene.startswith('package://') or scene.startswith('file://'):
        return resolve_uri(scene, [str(scenes_dir)] + [os.path.dirname(unquote(
            urlparse(scene).path))], scenes_dir)
    p = Path(scene)
    if p.is_file():
        return p
    found = dict(_world_files(scenes_dir))
    if scene in found:
        return found[scene]
    names = list(found)
    raise MissingAssetsError(f'no scene {scene!r}: give a file path or one of {names}')
