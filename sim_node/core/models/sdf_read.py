"""
SDF text read safely, its includes expanded: one tree per world or model file.

The text is parsed as every model file is (:func:`.assets.parse`: no DOCTYPE or entities,
nesting bounded). Its root is ``<sdf version="1.x">``; versions 1.0 to 1.11 are read, each
file by its own version's rules (a 1.6 world may include 1.9 models), so the reader tags each
``<world>`` and ``<model>`` element with the folder and version of the file it came from
(:data:`FOLDER`, :data:`VERSION`).

Each ``<include>`` of a world or a model is replaced by what its URI names
(:mod:`.sdf_files`): a model folder (its model.config's file) or a file, holding one
``<model>`` (or, for a world, a ``<light>`` or an ``<actor>``). The include's ``<name>``,
``<pose>``, ``<static>`` and ``<placement_frame>`` override the model's own; its
``<plugin>`` elements are added to the model's; ``merge="true"`` puts the model's links,
joints, frames and nested models into the including model, with a frame standing for the
merged model's own (``_merged__<name>__model__``), as sdformat merges them. A model whose file
is a URDF is kept as such (:attr:`Expanded.urdf`): the world makes it an entity by the URDF
path. Each file is read once per document (checked by the reader, counted against the
model's budget) and copied for each include of it.

Bounds, each refused with what was found: includes nested deeper than
:data:`MAX_INCLUDE_DEPTH` or a file including itself (a cycle, named), more than
:data:`MAX_INCLUDES` includes, more than :data:`MAX_MODELS` models in all, or more than
:data:`MAX_ELEMENTS` elements once expanded (an include bomb that fans out).
"""

import copy
from dataclasses import dataclass, field
from pathlib import Path
import re
from typing import Optional
import xml.etree.ElementTree as ET

from . import assets, sdf_files
from .paths import real_path
from .sdf_files import Places
from ..base.errors import (MissingAssetsError, OutsideFoldersError, ResourceParseError,
                           UnsupportedFormatError)

#: Attributes the reader sets on each <world> and <model>: its file's folder and SDF version.
FOLDER, VERSION = 'sim:folder', 'sim:version'
#: The attribute a model included from a URDF file carries instead: that file's path.
URDF_FILE = 'sim:urdf'
MAX_INCLUDE_DEPTH = 16
MAX_INCLUDES = 5_000
MAX_MODELS = 20_000
MAX_ELEMENTS = 4_000_000
OLDEST, NEWEST = (1, 0), sdf_files.NEWEST_VERSION
SDF_SUFFIXES = ('.sdf', '.world')
URDF_SUFFIXES = ('.urdf', '.xacro')

ERR_ROOT = ('unsupported format: the root element is <{tag}>; an SDF file starts with '
            '<sdf version="...">')
ERR_VERSION = ('SDF version {version!r} is not one this reader knows (1.0 to '
               f'{NEWEST[0]}.{NEWEST[1]})')
ERR_CYCLE = 'the SDF includes form a cycle: {chain}'
ERR_DEPTH = f'the SDF nests includes deeper than {MAX_INCLUDE_DEPTH} levels: {{chain}}'
ERR_INCLUDES = f'the SDF has more than {MAX_INCLUDES} includes'
ERR_MODELS = f'the SDF holds more than {MAX_MODELS} models once its includes are expanded'
ERR_ELEMENTS = (f'the SDF holds more than {MAX_ELEMENTS} elements once its includes are '
                'expanded')
ERR_NO_URI = 'an <include> without a <uri> (in {where})'
ERR_INCLUDED = ('{uri!r} holds no <model>{more}: an included SDF file holds one model (its '
                'root is <sdf>)')
ERR_INCLUDED_KIND = ('{uri!r} is a {kind} file; an include names an SDF model (a model folder, '
                     'a .sdf file) or a URDF')
ERR_NESTED_URDF = ('{uri!r} is a URDF included inside the model {model!r}: a URDF is included '
                   'at the top of a world')
ERR_MERGE_NAME = ('merging the model {name!r} into {into!r}: {kind} {elem!r} is already a name '
                  'there')


@dataclass
class Expanded:
    """
    A parsed SDF document with its includes expanded.

    :param root: the ``<sdf>`` element.
    :param version: the document's own SDF version, ``(major, minor)``.
    :param urdf: top-level includes of URDF models: the ``<model>`` placeholders
        (:data:`URDF_FILE` names the file) in the world, in order.
    :param skipped: what was left out for a missing or unsupported asset (an include, a
        mesh, a texture), where the load ignores them (``ignore_missing_or_unsupported_assets``);
        None: they fail it.
    """

    root: ET.Element
    version: tuple
    urdf: list = field(default_factory=list)
    skipped: Optional[list] = None

    @property
    def world(self) -> Optional[ET.Element]:
        return self.root.find('world')


#: Where an undeclared prefix (``<gz:policies>``, ``<ignition:...>``) is put while parsing.
_PREFIX_NS = 'urn:sim-sdf-prefix:'


def parse(text: str) -> tuple:
    """
    Return (``<sdf>`` root, version) of SDF text; :raises ResourceParseError: not SDF.

    Gazebo's files use prefixed extension elements (``<gz:policies>``) without declaring the
    prefix, which sdformat's parser takes and an XML namespace parser refuses: each such
    prefix is declared on the root for the parse, and the elements keep ``gz:policies`` as
    their tag.
    """
    text = text.lstrip('\ufeff \t\r\n')
    used = set(re.findall(r'</?([A-Za-z_][\w.-]*):[A-Za-z_]', text)) - {'xml'}
    declared = set(re.findall(r'xmlns:([A-Za-z_][\w.-]*)\s*=', text))
    missing = sorted(used - declared)
    if missing:
        decl = ''.join(f' xmlns:{p}="{_PREFIX_NS}{p}"' for p in missing)
        text = re.sub(r'<sdf(?=[\s>/])', '<sdf' + decl, text, count=1)
    root = assets.parse(text)
    if missing:
        for e in root.iter():
            if isinstance(e.tag, str) and e.tag.startswith('{' + _PREFIX_NS):
                ns, _, local = e.tag[1:].partition('}')
                e.tag = f'{ns[len(_PREFIX_NS):]}:{local}'
    if root.tag != 'sdf':
        raise UnsupportedFormatError(ERR_ROOT.format(tag=str(root.tag)[:100]))
    version = sdf_files.version_of(root.get('version', ''))
    if version is None or not OLDEST <= version <= (NEWEST[0], NEWEST[1] + 1):
        raise ResourceParseError(ERR_VERSION.format(version=root.get('version', '')[:20]))
    return root, version


def is_sdf(text: str) -> bool:
    """Whether model text is SDF (its root element is ``<sdf``), judged from its start."""
    head = text.lstrip('\ufeff \t\r\n')[:4096]
    while head.startswith('<?') or head.startswith('<!--'):
        end = head.find('?>' if head.startswith('<?') else '-->')
        if end < 0:
            return False
        head = head[end + (2 if head.startswith('<?') else 3):].lstrip()
    return head.startswith('<sdf') and (len(head) == 4 or not head[4].isalnum())


def expand(text: str, folder: Optional[Path], reader: assets.Reader, places: Places,
           name: str = '', skip_missing: bool = False) -> Expanded:
    """
    Parse SDF text and expand its includes (see the module docstring).

    :param folder: the folder of the file the text came from (None: text from a client,
        whose relative URIs resolve on the model paths only).
    :param name: what the text is called in messages (its file name).
    :param skip_missing: leave out what names a missing or unsupported asset, saying so in
        :attr:`Expanded.skipped`, rather than fail.
    """
    try:
        root, version = parse(text)
    except ResourceParseError as exc:
        raise ResourceParseError(f'{name}: {exc}' if name else str(exc)) from None
    out = Expanded(root, version, skipped=[] if skip_missing else None)
    _Includes(reader, places, out).run(root, folder, version, name or 'the SDF')
    return out


class _Includes:
    """One document's include expansion: its count, its parsed files, its cycle check."""

    def __init__(self, reader: assets.Reader, places: Places, out: Expanded):
        self.reader, self.places, self.out = reader, places, out
        self.count = 0
        self.models = 0
        self.elements = 0
        self._files: dict = {}  # real path -> (parsed <sdf> root, version)

    def run(self, root: ET.Element, folder: Optional[Path], version: tuple, name: str) -> None:
        for top in root:
            if top.tag in ('world', 'model'):
                self._tag(top, folder, version)
                self._expand(top, folder, version, [('', name)], top.tag == 'world')
        self.elements = sum(1 for _ in root.iter())
        if self.elements > MAX_ELEMENTS:
            raise ResourceParseError(ERR_ELEMENTS)

    def _tag(self, elem: ET.Element, folder: Optional[Path], version: tuple) -> None:
        elem.set(FOLDER, str(folder) if folder is not None else '')
        elem.set(VERSION, f'{version[0]}.{version[1]}')
        if elem.tag == 'model':
            self.models += 1
            if self.models > MAX_MODELS:
                raise ResourceParseError(ERR_MODELS)

    def _expand(self, elem: ET.Element, folder: Optional[Path], version: tuple, chain: list,
                in_world: bool) -> None:
        for child in list(elem):
            if child.tag == 'model':
                self._tag(child, folder, version)
                self._expand(child, folder, version, chain, False)
            elif child.tag == 'include':
                self._include(elem, list(elem).index(child), child, folder, chain, in_world)

    def _include(self, parent: ET.Element, index: int, inc: ET.Element,
                 folder: Optional[Path], chain: list, in_world: bool) -> None:
        self.count += 1
        if self.count > MAX_INCLUDES:
            raise ResourceParseError(ERR_INCLUDES)
        uri = (inc.findtext('uri') or '').strip()
        if not uri:
            raise ResourceParseError(ERR_NO_URI.format(where=parent.get('name') or parent.tag))
        try:
            path = self._find(uri, folder)
        except MissingAssetsError as exc:
            if self.out.skipped is None or isinstance(exc, OutsideFoldersError):
                raise
            self.out.skipped.append(f'the include of {uri!r}: {exc}')
            parent.remove(inc)
            return
        kind = path.suffix.lower()
        parent.remove(inc)
        if kind in URDF_SUFFIXES:
            if not in_world:
                raise UnsupportedFormatError(ERR_NESTED_URDF.format(
                    uri=uri, model=parent.get('name', '')))
            model = ET.Element('model', {'name': inc.findtext('name') or path.stem,
                                         URDF_FILE: str(path)})
            _override(model, inc)
            parent.insert(index, model)
            self.out.urdf.append(model)
            return
        if kind not in SDF_SUFFIXES + ('.xml', ''):
            raise UnsupportedFormatError(ERR_INCLUDED_KIND.format(uri=uri, kind=kind))
        real = str(path)
        if real in [c for c, _ in chain]:
            raise ResourceParseError(ERR_CYCLE.format(
                chain=' -> '.join([n for _, n in chain] + [uri])))
        if len(chain) > MAX_INCLUDE_DEPTH:
            raise ResourceParseError(ERR_DEPTH.format(
                chain=' -> '.join([n for _, n in chain][-4:] + [uri])))
        root, version = self._read(uri, path)
        found = [e for e in root if e.tag in (('model', 'light', 'actor') if in_world
                                              else ('model',))]
        if not found:
            raise ResourceParseError(ERR_INCLUDED.format(
                uri=uri, more=' (or <light>, <actor>)' if in_world else ''))
        item = copy.deepcopy(found[0])
        if item.tag != 'model':
            _override(item, inc)
            parent.insert(index, item)
            return
        self._tag(item, path.parent, version)
        _override(item, inc)
        self._expand(item, path.parent, version, chain + [(real, uri)], False)
        if inc.get('merge', '').strip().lower() in ('true', '1') and parent.tag == 'model':
            _merge(parent, index, item)
        else:
            parent.insert(index, item)

    def _find(self, uri: str, folder: Optional[Path]) -> Path:
        """Return the real file an include's URI names (a model folder: its chosen file)."""
        for candidate in sdf_files.candidates(uri, folder, self.places):
            try:
                real = Path(real_path(candidate))
            except (OSError, ValueError):
                continue
            if not self.reader.allows(str(real)):  # judged before existence: says nothing
                raise OutsideFoldersError(assets.ERR_OUTSIDE.format(value=uri))
            if real.is_dir():
                config = real / 'model.config'
                data = (self.reader.load(f'{uri}/model.config', [config])
                        if config.is_file() else None)
                return Path(real_path(sdf_files.model_file(real, data)))
            if real.exists():
                return real
        raise MissingAssetsError(assets.ERR_NOT_FOUND.format(value=uri))

    def _read(self, uri: str, path: Path) -> tuple:
        key = str(path)
        if key not in self._files:
            data = self.reader.load(uri, [path])
            try:
                text = data.decode('utf-8')
            except UnicodeDecodeError:
                raise ResourceParseError(f'the included file {uri!r} is not UTF-8') from None
            try:
                self._files[key] = parse(text)
            except (ResourceParseError, UnsupportedFormatError) as exc:
                raise type(exc)(f'{uri}: {exc}') from None
        return self._files[key]


def _override(item: ET.Element, inc: ET.Element) -> None:
    """Give an included element the include's name, pose, static, placement and plugins."""
    name = (inc.findtext('name') or '').strip()
    if name:
        item.set('name', name)
    pose = inc.find('pose')
    if pose is not None:
        for old in item.findall('pose'):
            item.remove(old)
        item.insert(0, copy.deepcopy(pose))
    for tag in ('static', 'placement_frame'):
        value = inc.find(tag)
        if value is None:
            continue
        if tag == 'placement_frame':
            item.set('placement_frame', (value.text or '').strip())
            continue
        for old in item.findall(tag):
            item.remove(old)
        item.append(copy.deepcopy(value))
    for plugin in inc.findall('plugin'):
        item.append(copy.deepcopy(plugin))


def _merge(parent: ET.Element, index: int, item: ET.Element) -> None:
    """
    Put a merged model's elements into `parent` at `index` (include ``merge="true"``).

    A frame ``_merged__<name>__model__`` stands for the merged model's own frame, placed where
    the include puts it; its elements' poses that were relative to their model (no
    ``relative_to``) become relative to that frame, and frames attached to the model attach
    to it, so every element keeps its place.
    """
    name = item.get('name', '')
    proxy = f'_merged__{name}__model__'
    taken = {e.get('name') for e in parent if e.tag in ('link', 'joint', 'frame', 'model')}
    frame = ET.Element('frame', {'name': proxy})
    pose = item.find('pose')
    canonical = item.get('canonical_link') or next(
        (e.get('name') for e in item if e.tag == 'link'), '')
    frame.set('attached_to', canonical)
    placed = copy.deepcopy(pose) if pose is not None else ET.Element('pose')
    if not placed.get('relative_to'):  # the include's pose is in the including model's frame
        placed.set('relative_to', '__model__')
    frame.append(placed)
    moved = [frame]
    for e in item:
        if e.tag in ('pose', 'static', 'self_collide', 'allow_auto_disable', 'enable_wind'):
            continue
        if e.tag in ('link', 'joint', 'frame', 'model') and e.get('name') in taken:
            raise ResourceParseError(ERR_MERGE_NAME.format(
                name=name, into=parent.get('name', ''), kind=e.tag, elem=e.get('name')))
        if e.tag in ('link', 'model', 'frame'):
            p = e.find('pose')
            if e.tag == 'frame' and e.get('attached_to', '') in ('', '__model__'):
                e.set('attached_to', proxy)
            elif p is None:
                p = ET.SubElement(e, 'pose', {'relative_to': proxy})
                p.text = '0 0 0 0 0 0'
            elif p.get('relative_to', '') in ('', '__model__'):
                p.set('relative_to', proxy)
        if e.tag == 'joint':
            for end in ('parent', 'child'):
                link = e.find(end)
                if link is not None and (link.text or '').strip() == '__model__':
                    link.text = proxy
        moved.append(e)
    for k, e in enumerate(moved):
        parent.insert(index + k, e)
