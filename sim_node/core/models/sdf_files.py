"""
Where an SDF file's URIs lead: ``model://`` models, Gazebo Fuel's cache, files beside the file.

Gazebo finds a model named in ``<include><uri>model://shelf</uri>`` in the folders of
``GZ_SIM_RESOURCE_PATH`` (colon-separated; ``IGN_GAZEBO_RESOURCE_PATH`` and Gazebo classic's
``GAZEBO_MODEL_PATH`` before it), each holding model folders: ``shelf/model.config`` beside
``shelf/model.sdf``. :class:`Places` is where this simulator looks, in order: those variables,
the node's resource paths, then the few models this package ships for classic worlds that name
them (``sun``, ``ground_plane``), which Gazebo classic installs with itself.

A model folder's ``model.config`` lists its files per SDF version (``<sdf version="1.6">``):
the newest version this reader knows is taken (:func:`model_file`). A URI of Gazebo's model
library (``https://fuel.gazebosim.org/1.0/<owner>/models/<name>[/<version>][/files/<path>]``)
resolves to the local copy Gazebo's Fuel tools keep
(``~/.gz/fuel/<host>/<owner>/models/<name>/<version>/``, owner and name in lower case, the
newest version unless one is named); this machine downloads nothing, so an uncached model is a
missing asset naming the URI and how to fetch it.

Nothing here reads a file's content but a ``model.config``; every path found is still judged
by the reader (:class:`.assets.Reader`: inside the readable folders, a regular file, within
budget). A ``model://`` or Fuel URI that goes up a folder (``..``) is refused before anything
is looked up.
"""

from dataclasses import dataclass
import os
from pathlib import Path
import re
from typing import Mapping, Optional, Sequence, Tuple
from urllib.parse import unquote, urlparse

from . import assets
from ..base.errors import MissingAssetsError, OutsideFoldersError

#: The variables Gazebo finds models on: gz-sim's, its older name, Gazebo classic's.
MODEL_PATH_VARIABLES = ('GZ_SIM_RESOURCE_PATH', 'IGN_GAZEBO_RESOURCE_PATH', 'GAZEBO_MODEL_PATH')
#: Where Gazebo's Fuel tools keep what they downloaded: the variables, then the defaults.
FUEL_CACHE_VARIABLES = ('GZ_FUEL_CACHE_PATH', 'IGN_FUEL_CACHE_PATH')
FUEL_CACHE_DEFAULTS = ('.gz/fuel', '.ignition/fuel')
#: The newest SDF version this reader knows (a model.config entry beyond it is passed over).
NEWEST_VERSION = (1, 11)
#: The models this package ships for classic worlds (scenes/models: sun, ground_plane).
BUILTIN_MODELS = 'models'
#: The suffixes of SDF files.
SUFFIXES = ('.sdf', '.world')

ERR_UP = ('{uri!r} goes up a folder (..): a model:// or Fuel URI names a model and a file '
          'inside it')
ERR_NO_MODEL = ('no model {name!r} for {uri!r}: looked in {where}; put its folder (with its '
                "model.config) on GZ_SIM_RESOURCE_PATH or in the node's resource_paths")
ERR_NO_FILE = 'the model {name!r} has no file {rel!r} ({uri!r})'
ERR_NO_SDF = ('the model folder {folder!r} has no model.config naming its file, and no '
              'model.sdf')
ERR_FUEL = ('{uri!r} is a model of Gazebo Fuel that is not in the local Fuel cache (looked in '
            '{where}); this simulator downloads nothing: fetch it once with `gz fuel download '
            '-u {uri}` on a machine with network, or copy its folder onto GZ_SIM_RESOURCE_PATH')
ERR_FUEL_FORM = ('{uri!r} is not a Fuel model URI: expected https://<host>/<version>/<owner>/'
                 'models/<name>[/<model version>][/files/<path>]')
ERR_REMOTE = ('{uri!r} is a web address: this simulator reads no network; give the model as a '
              'file, model://, or a Fuel model in the local cache')
ERR_SCHEME = 'unsupported URI scheme in {uri!r}: give model://, file://, package:// or a path'

_FUEL = re.compile(r'^/(?:[^/]+/)?(?P<owner>[^/]+)/models/(?P<name>[^/]+)'
                   r'(?:/(?P<version>\d+|tip))?(?:/files/(?P<path>.*))?/?$', re.I)


@dataclass(frozen=True)
class Places:
    """
    Where models are looked for, in order (see the module docstring).

    :param model_paths: folders holding model folders: the environment's, then the resource
        paths, then the models this package ships.
    :param fuel_caches: folders of Fuel's local cache that exist.
    """

    model_paths: Tuple[str, ...] = ()
    fuel_caches: Tuple[str, ...] = ()

    @classmethod
    def of(cls, resource_paths: Sequence[str] = (), environ: Optional[Mapping] = None,
           scenes_dir: Optional[Path] = None) -> 'Places':
        """Return the places of an environment (None: this process's) and resource paths."""
        env = os.environ if environ is None else environ
        paths = [p for var in MODEL_PATH_VARIABLES for p in env.get(var, '').split(':') if p]
        paths += list(resource_paths)
        if scenes_dir is not None:
            paths.append(str(Path(scenes_dir) / BUILTIN_MODELS))
        caches = [env.get(v, '') for v in FUEL_CACHE_VARIABLES if env.get(v)]
        home = env.get('HOME', '')
        caches += [os.path.join(home, d) for d in FUEL_CACHE_DEFAULTS] if home else []
        seen: dict = {}
        for p in paths:
            seen.setdefault(os.path.abspath(p), None)
        return cls(tuple(seen), tuple(dict.fromkeys(c for c in caches if os.path.isdir(c))))

    def roots(self) -> list:
        """Return the folders these places make readable (for :class:`.assets.Reader`)."""
        return [p for p in self.model_paths + self.fuel_caches if os.path.isdir(p)]


def is_model_uri(uri: str) -> bool:
    """Whether `uri` names a model by ``model://`` or a Fuel address."""
    low = uri.strip().lower()
    return low.startswith('model://') or (low.startswith(('https://', 'http://'))
                                          and '/models/' in low)


def candidates(uri: str, folder: Optional[Path], places: Places) -> list:
    """
    Return the paths a URI of an SDF file may name, first match wins.

    ``model://name/rel`` is ``<model path>/name/rel`` on each place; a Fuel URI its cached
    copy; ``file://`` and absolute paths themselves; ``package://`` as a URDF's; anything else
    is relative to `folder` (the file's own), then to each model path, as Gazebo searches.

    :raises MissingAssetsError: a URI going up a folder, an unknown model, an uncached Fuel
        model, a web address or an unknown scheme.
    """
    uri = uri.strip()
    low = uri.lower()
    if low.startswith('model://'):
        name, rel = _split(uri[len('model://'):], uri)
        folders = [Path(p) / name for p in places.model_paths]
        found = [f for f in folders if f.is_dir()]
        if not found:
            where = ', '.join(places.model_paths[:6]) or '(no model paths)'
            raise MissingAssetsError(ERR_NO_MODEL.format(name=name, uri=uri, where=where))
        return [f / rel if rel else f for f in found]
    if low.startswith(('https://', 'http://')):
        return [fuel_path(uri, places)]
    if low.startswith('file://'):
        return [Path(unquote(urlparse(uri).path))]
    if low.startswith('package://'):
        package, _, rel = uri[len('package://'):].lstrip('/').partition('/')
        return [p / rel for p in assets.package_folders(package, places.model_paths)]
    if re.match(r'^[a-z][a-z0-9+.-]*://', low):
        raise MissingAssetsError(ERR_SCHEME.format(uri=uri[:200]))
    if os.path.isabs(uri):  # pybullet's files write '/meshes/x.stl' for one beside them
        beside = folder / uri.lstrip('/') if folder is not None else None
        return [beside, Path(uri)] if beside is not None and beside.exists() else [Path(uri)]
    out = [folder / uri] if folder is not None else []
    return out + [Path(p) / uri for p in places.model_paths]


def _split(rest: str, uri: str) -> tuple:
    """Return (model name, path inside it) of what follows ``model://``; refuse ``..``."""
    parts = [p for p in unquote(rest).split('/') if p not in ('', '.')]
    if not parts or any(p == '..' for p in parts):
        raise OutsideFoldersError(ERR_UP.format(uri=uri[:200]))
    return parts[0], '/'.join(parts[1:])


def fuel_path(uri: str, places: Places) -> Path:
    """
    Return where Fuel's tools keep the model (or file) a Fuel URI names.

    ``<cache>/<host>/<owner>/models/<name>/<version>/[<path>]``, owner and name in lower case
    as the tools write them; the newest version cached unless the URI names one.

    :raises MissingAssetsError: not a Fuel model URI, or not in any cache.
    """
    parsed = urlparse(uri.strip())
    path = unquote(parsed.path)
    if '/models/' not in path.lower():
        raise MissingAssetsError(ERR_REMOTE.format(uri=uri[:200]))
    m = _FUEL.match(path)
    if m is None:
        raise MissingAssetsError(ERR_FUEL_FORM.format(uri=uri[:200]))
    rel = m.group('path') or ''
    if any(p == '..' for p in rel.split('/')) or '..' in (m.group('owner'), m.group('name')):
        raise OutsideFoldersError(ERR_UP.format(uri=uri[:200]))
    version = m.group('version')
    for cache in places.fuel_caches:
        base = Path(cache) / parsed.netloc.lower() / m.group('owner').lower() / 'models' / \
            m.group('name').lower()
        if not base.is_dir():
            continue
        if version and version.lower() != 'tip':
            chosen = base / version
        else:
            numbered = sorted((d for d in base.iterdir() if d.name.isdigit() and d.is_dir()),
                              key=lambda d: int(d.name))
            if not numbered:
                continue
            chosen = numbered[-1]
        if chosen.is_dir():
            return chosen / rel if rel else chosen
    where = ', '.join(places.fuel_caches) or '~/.gz/fuel (absent)'
    raise MissingAssetsError(ERR_FUEL.format(uri=uri[:200], where=where))


def version_of(text: str) -> Optional[Tuple[int, int]]:
    """Return ``(major, minor)`` of an SDF version string ('1.6'), or None."""
    m = re.match(r'^\s*(\d+)\.(\d+)', text or '')
    return (int(m.group(1)), int(m.group(2))) if m else None


def model_file(folder: Path, config: Optional[bytes]) -> Path:
    """
    Return the file of a model folder: its model.config's entry of the newest known version.

    `config` is the content of ``model.config`` (None: there is none). Without one, or with
    no entry, ``model.sdf``.

    :raises MissingAssetsError: no entry and no model.sdf.
    """
    chosen = None
    if config is not None:
        try:
            root = assets.parse(config.decode('utf-8', errors='replace'))
        except Exception:  # noqa: B902 (a broken model.config: the folder's model.sdf, if any)
            root = None
        entries = []
        for e in ([] if root is None else root.iter('sdf')):
            v = version_of(e.get('version', '')) or (0, 0)
            if (e.text or '').strip():
                entries.append((v if v <= NEWEST_VERSION else (-1, -1), e.text.strip()))
        if entries:
            entries.sort(key=lambda x: x[0])
            chosen = entries[-1][1]
    if chosen is not None:
        if any(p == '..' for p in Path(chosen).parts) or os.path.isabs(chosen):
            raise OutsideFoldersError(ERR_UP.format(uri=f'{folder.name}/{chosen}'))
        return folder / chosen
    if (folder / 'model.sdf').exists():
        return folder / 'model.sdf'
    raise MissingAssetsError(ERR_NO_SDF.format(folder=folder.name))
