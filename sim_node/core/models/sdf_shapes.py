"""
SDF geometry and materials made MJCF: geoms, and the meshes, textures and height fields they use.

Shapes as MuJoCo has them: ``box`` (SDF gives full sizes, MJCF half), ``sphere``,
``cylinder`` and ``capsule`` (SDF's length is the cylinder's, MJCF takes half), ``ellipsoid``
(radii), ``plane`` (turned to its normal; infinite for contacts, its size drawn). Made into
meshes: ``polyline`` (each outline extruded to its height, triangulated by ear clipping) and
SDF 1.11's ``cone``. ``mesh`` files are read as a URDF's are (STL and OBJ as MuJoCo reads them,
Collada, glTF, PLY and OFF converted, over 200,000 faces decimated: :mod:`.meshes`), scaled by
``<scale>``; a ``<submesh>`` is drawn as its whole file (said once). ``heightmap`` images
(PNG) become a height field of the given ``<size>``, offset by ``<pos>``; other image kinds
(DEM GeoTIFF) are refused as unsupported assets. ``image`` geometry is not read.

Materials: a visual's ``<diffuse>`` (else its ``<ambient>``), ``<specular>``, ``<emissive>``
and ``<transparency>``; a Gazebo material script's name (``Gazebo/Grey`` ...) as its colour;
a PBR ``<albedo_map>`` as a texture (drawn on OBJ meshes and primitive shapes: meshes
converted to STL keep no texture coordinates). A mesh visual without a material takes its file's
colour, as a URDF's does. :class:`Assets` names each asset once per document.
"""

import hashlib
import logging
import math
from pathlib import Path
from typing import Optional, Sequence
import xml.etree.ElementTree as ET

import numpy as np

from . import asset_store, assets, meshes, prepare, sdf_files
from .sdf_files import Places
from ..base import quat
from ..base.errors import OutsideFoldersError, ResourceParseError, UnsupportedAssetsError

log = logging.getLogger(__name__)

#: Colours of Gazebo's material scripts by name (approximations of what Gazebo draws).
SCRIPT_COLOURS = {
    'Gazebo/Grey': (0.7, 0.7, 0.7, 1), 'Gazebo/Gray': (0.7, 0.7, 0.7, 1),
    'Gazebo/DarkGrey': (0.35, 0.35, 0.35, 1), 'Gazebo/DarkGray': (0.35, 0.35, 0.35, 1),
    'Gazebo/LightGrey': (0.85, 0.85, 0.85, 1), 'Gazebo/White': (1, 1, 1, 1),
    'Gazebo/FlatBlack': (0.1, 0.1, 0.1, 1), 'Gazebo/Black': (0.05, 0.05, 0.05, 1),
    'Gazebo/Red': (0.8, 0.05, 0.05, 1), 'Gazebo/RedBright': (0.95, 0.1, 0.1, 1),
    'Gazebo/Green': (0.05, 0.75, 0.05, 1), 'Gazebo/Blue': (0.05, 0.05, 0.8, 1),
    'Gazebo/SkyBlue': (0.5, 0.75, 0.95, 1), 'Gazebo/Yellow': (0.95, 0.9, 0.05, 1),
    'Gazebo/ZincYellow': (0.95, 0.85, 0.3, 1), 'Gazebo/DarkYellow': (0.6, 0.55, 0.05, 1),
    'Gazebo/Purple': (0.55, 0.05, 0.6, 1), 'Gazebo/Turquoise': (0.05, 0.7, 0.7, 1),
    'Gazebo/Orange': (0.95, 0.5, 0.05, 1), 'Gazebo/Indigo': (0.3, 0.05, 0.55, 1),
    'Gazebo/Gold': (0.85, 0.65, 0.15, 1), 'Gazebo/Wood': (0.55, 0.38, 0.22, 1),
    'Gazebo/LightWood': (0.75, 0.6, 0.4, 1), 'Gazebo/WoodFloor': (0.6, 0.45, 0.3, 1),
    'Gazebo/WoodPallet': (0.65, 0.5, 0.32, 1), 'Gazebo/Bricks': (0.6, 0.3, 0.2, 1),
    'Gazebo/CeilingTiled': (0.9, 0.9, 0.88, 1), 'Gazebo/PaintedWall': (0.9, 0.88, 0.82, 1),
    'Gazebo/Residential': (0.8, 0.75, 0.65, 1), 'Gazebo/Road': (0.25, 0.25, 0.25, 1),
    'Gazebo/Asphalt': (0.2, 0.2, 0.2, 1), 'Gazebo/Grass': (0.3, 0.55, 0.2, 1),
    'Gazebo/Rocky': (0.5, 0.45, 0.4, 1), 'Gazebo/Chrome': (0.8, 0.8, 0.82, 1),
}
#: Suffixes read as glowing or see-through variants of a script colour.
_SCRIPT_ALPHA = {'Transparent': 0.5}
#: Image kinds a height field is read from (MuJoCo reads PNG height fields itself).
HEIGHTMAP_SUFFIXES = ('.png',)
#: Segments of a generated cone's circle.
CONE_SEGMENTS = 32
#: The most convex parts a mesh with ``optimization="convex_decomposition"`` becomes where its
#: ``<max_convex_hulls>`` says none (sdformat's default).
SDF_MAX_HULLS = 16
#: Most points a polyline outline may have.
MAX_POLYLINE_POINTS = 10_000
#: The geom type each SDF shape becomes.
PRIMITIVES = ('box', 'sphere', 'cylinder', 'capsule', 'ellipsoid', 'plane')
SHAPES = PRIMITIVES + ('mesh', 'polyline', 'cone', 'heightmap')

ERR_SIZE = '{where}: <{shape}> needs {what} (positive finite numbers), got {got!r}'
ERR_HEIGHTMAP_KIND = ('{where}: the heightmap {uri!r} is a {kind!r} image; height fields are '
                      'read from PNG (a DEM needs converting to a 16-bit PNG first)')
ERR_POLYLINE = '{where}: a <polyline> needs at least 3 points and a positive height'


def positive(text: Optional[str], n: int, where: str, shape: str, what: str) -> list:
    """Return `n` positive finite numbers of an element's text, else refuse naming it."""
    try:
        values = [float(v) for v in (text or '').split()]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) and v > 0 for v in values):
        raise ResourceParseError(ERR_SIZE.format(where=where, shape=shape, what=what,
                                                 got=(text or '').strip()[:60]))
    return values


def numbers(text: Optional[str], default: Sequence[float], where: str = '',
            what: str = 'values') -> list:
    """Return the finite numbers of an element's text, else `default`; refuse NaN or inf."""
    if text is None or not text.strip():
        return list(default)
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        raise ResourceParseError(f'{where}: {what} {text.strip()[:60]!r} are not numbers') \
            from None
    if len(values) != len(default) or not all(math.isfinite(v) for v in values):
        raise ResourceParseError(f'{where}: {what} {text.strip()[:60]!r} are not '
                                 f'{len(default)} finite numbers')
    return values


class Assets:
    """
    The ``<asset>`` of one MJCF document being built.

    Each mesh, material, texture and height field once, named ``<prefix><kind>_<n>_<stem>``.

    :param reader: reads (checks, copies, budgets) every file.
    :param places: where ``model://`` and Fuel URIs lead.
    """

    def __init__(self, reader: assets.Reader, places: Places, prefix: str = '',
                 skipped: Optional[list] = None):
        self.reader, self.places, self.prefix = reader, places, prefix
        self.elements: list = []
        self._names: dict = {}
        self._meshes: list = []  # (asset element, value, stored) to convert
        self.notes: list = []  # what was drawn otherwise than declared
        #: What was left out for an asset missing or unsupported, where a load ignores them
        #: (load_world's ``ignore_missing_or_unsupported_assets``); None: they fail it.
        self.skipped = skipped

    def leave_out(self, where: str, exc: Exception) -> None:
        """
        Leave out what names a missing or unsupported asset (:attr:`skipped`), or raise `exc`.

        A file outside the readable folders is refused all the same.
        """
        if self.skipped is None or isinstance(exc, OutsideFoldersError):
            raise exc
        self.skipped.append(f'{where}: {exc}')

    def _name(self, kind: str, key, stem: str) -> tuple:
        """Return (name, new) for the asset of `kind` keyed `key`."""
        found = self._names.get((kind, key))
        if found is not None:
            return found, False
        safe = ''.join(c if c.isalnum() or c in '_-' else '_' for c in stem)[:40]
        name = f'{self.prefix}{kind}_{len(self._names)}_{safe}'.rstrip('_')
        self._names[(kind, key)] = name
        return name, True

    def read(self, uri: str, folder: Optional[Path], tag: str):
        """Return the checked copy of a file an element names (see :mod:`.sdf_files`)."""
        found = sdf_files.candidates(uri, folder, self.places)
        return self.reader.read(uri, found, tag, urdf_mesh=tag == 'mesh')

    def mesh(self, uri: str, folder: Optional[Path], scale: Sequence[float]) -> str:
        stored = self.read(uri, folder, 'mesh')
        kind = Path(uri).suffix.lower()
        if kind not in assets.MUJOCO_MESH_SUFFIXES + meshes.CONVERTED_SUFFIXES:
            raise UnsupportedAssetsError(prepare.ERR_URDF_MESH_KIND.format(value=uri, kind=kind))
        name, new = self._name('mesh', (stored.path, tuple(scale)), Path(uri).stem)
        if new:
            elem = ET.Element('mesh', name=name, file=stored.path, scale=_text(scale),
                              inertia='shell')
            self.elements.append(elem)
            self._meshes.append((elem, uri, stored))
        return name

    def generated(self, stem: str, vertices: np.ndarray, faces: np.ndarray) -> str:
        """Add a mesh made here (a polyline's prism, a cone): an OBJ copy in the asset store."""
        lines = [f'v {x:.9g} {y:.9g} {z:.9g}' for x, y, z in vertices]
        lines += [f'f {a + 1} {b + 1} {c + 1}' for a, b, c in faces]
        data = ('\n'.join(lines) + '\n').encode()
        digest = hashlib.blake2b(data, digest_size=16).hexdigest()
        name, new = self._name('mesh', digest, stem)
        if new:
            key = ('sdf-generated', digest)
            stored = asset_store.store().cached(key) or asset_store.store().put(
                key, f'{digest}.obj', data)
            self.reader.hold(stored.path)
            self.elements.append(ET.Element('mesh', name=name, file=stored.path))
        return name

    def material(self, rgba: Sequence[float], specular: float = 0.5, emission: float = 0.0,
                 texture: str = '') -> str:
        key = (tuple(round(float(c), 6) for c in rgba), round(specular, 4), round(emission, 4),
               texture)
        name, new = self._name('material', key, 'sdf')
        if new:
            elem = ET.Element('material', name=name, rgba=_text(rgba),
                              specular=f'{specular:.4g}', emission=f'{emission:.4g}')
            if texture:
                elem.set('texture', texture)
            self.elements.append(elem)
        return name

    def texture(self, uri: str, folder: Optional[Path]) -> str:
        stored = self.read(uri, folder, 'texture')
        name, new = self._name('texture', stored.path, Path(uri).stem)
        if new:
            self.elements.append(ET.Element('texture', name=name, type='2d', file=stored.path))
        return name

    def hfield(self, uri: str, folder: Optional[Path], size: Sequence[float], where: str) -> str:
        kind = Path(uri).suffix.lower()
        if kind not in HEIGHTMAP_SUFFIXES:
            raise UnsupportedAssetsError(ERR_HEIGHTMAP_KIND.format(where=where, uri=uri,
                                                                   kind=kind))
        stored = self.read(uri, folder, 'hfield')
        half = [size[0] / 2, size[1] / 2, size[2], max(size[2] * 0.1, 0.01)]
        name, new = self._name('hfield', (stored.path, tuple(half)), Path(uri).stem)
        if new:
            self.elements.append(ET.Element('hfield', name=name, file=stored.path,
                                            size=_text(half)))
        return name

    def finish(self) -> dict:
        """
        Convert the meshes MuJoCo cannot read (one batch); return mesh name -> its own colour.

        :raises UnsupportedAssetsError: a mesh that cannot be converted, naming it.
        """
        todo = [(e, v, s) for e, v, s in self._meshes if meshes.needs_conversion(v, s)]
        colours = {}
        if todo:
            for (elem, value, _), done in zip(todo, meshes.convert([(v, s) for _, v, s in todo])):
                prepare.hold_if_stored(self.reader, done.path)
                elem.set('file', done.path)
                if done.decimated:
                    log.warning('the mesh %s has %d faces, more than MuJoCo reads (%d): '
                                'decimated to %d', value, done.faces_in,
                                meshes.MUJOCO_MAX_FACES, done.faces)
                if done.rgba is not None:
                    colours[elem.get('name')] = tuple(done.rgba)
        self._meshes = []
        return colours


def _text(values: Sequence[float]) -> str:
    return ' '.join(f'{float(v):.12g}' for v in values)


def geom(shape_parent: ET.Element, where: str, folder: Optional[Path],
         out: Assets) -> Optional[dict]:
    """
    Return the MJCF attributes of a ``<geometry>`` (``type``, ``size``, ``mesh`` ...).

    Also ``pos``/``quat`` of the shape within its element where the shape itself is placed
    (a plane's normal, a heightmap's ``<pos>``). None: ``<empty>`` or no shape (said in notes).

    :raises ResourceParseError: a size that is not positive and finite.
    """
    shapes = [e for e in shape_parent if e.tag in SHAPES + ('empty', 'image')]
    if not shapes or shapes[0].tag == 'empty':
        return None
    s = shapes[0]
    kind = s.tag
    if kind == 'box':
        size = positive(s.findtext('size'), 3, where, kind, 'a <size> of 3 values')
        return {'type': 'box', 'size': _text([v / 2 for v in size])}
    if kind == 'sphere':
        return {'type': 'sphere',
                'size': _text(positive(s.findtext('radius'), 1, where, kind, 'a <radius>'))}
    if kind in ('cylinder', 'capsule'):
        (r,) = positive(s.findtext('radius'), 1, where, kind, 'a <radius>')
        (length,) = positive(s.findtext('length'), 1, where, kind, 'a <length>')
        return {'type': kind, 'size': _text([r, length / 2])}
    if kind == 'ellipsoid':
        return {'type': 'ellipsoid',
                'size': _text(positive(s.findtext('radii'), 3, where, kind, '<radii>'))}
    if kind == 'plane':
        normal = numbers(s.findtext('normal'), (0, 0, 1), where, 'a plane normal')
        size = numbers(s.findtext('size'), (1, 1), where, 'a plane size')
        n = np.asarray(normal, float)
        if not np.linalg.norm(n) > 0 or min(size) < 0:
            raise ResourceParseError(f'{where}: a plane needs a non-zero normal and a size')
        out_ = {'type': 'plane', 'size': _text([max(size[0] / 2, 0.01),
                                                max(size[1] / 2, 0.01), 0.05])}
        q = _turn_z_to(n / np.linalg.norm(n))
        if q is not None:
            out_['quat'] = q
        return out_
    if kind == 'mesh':
        uri = (s.findtext('uri') or '').strip()
        if not uri:
            raise ResourceParseError(f'{where}: a <mesh> without a <uri>')
        scale = numbers(s.findtext('scale'), (1, 1, 1), where, 'a mesh scale')
        if not all(v != 0 for v in scale):
            raise ResourceParseError(f'{where}: a mesh scale of zero')
        if s.find('submesh') is not None:
            out.notes.append(f'{where}: <submesh> {s.findtext("submesh/name")!r}: its whole '
                             'mesh file is drawn')
        attrs = {'type': 'mesh', 'mesh': out.mesh(uri, folder, scale)}
        optimization = (s.get('optimization') or '').strip()
        if optimization:
            attrs['optimization'] = optimization
            hulls = (s.findtext('convex_decomposition/max_convex_hulls') or '').strip()
            # sdformat's default: 16 parts at most
            attrs['max_convex_hulls'] = hulls if hulls.isdigit() else str(SDF_MAX_HULLS)
        return attrs
    if kind == 'cone':
        (r,) = positive(s.findtext('radius'), 1, where, kind, 'a <radius>')
        (length,) = positive(s.findtext('length'), 1, where, kind, 'a <length>')
        return {'type': 'mesh', 'mesh': out.generated('cone', *cone_mesh(r, length))}
    if kind == 'polyline':
        return {'type': 'mesh', 'mesh': out.generated('polyline', *polyline_mesh(
            [e for e in shape_parent if e.tag == 'polyline'], where))}
    if kind == 'heightmap':
        uri = (s.findtext('uri') or '').strip()
        size = positive(s.findtext('size') or '1 1 1', 3, where, kind, 'a <size> of 3 values')
        pos = numbers(s.findtext('pos'), (0, 0, 0), where, 'a heightmap pos')
        return {'type': 'hfield', 'hfield': out.hfield(uri, folder, size, where),
                'pos': _text(pos)}
    out.notes.append(f'{where}: <image> geometry is not read')
    return None


def _turn_z_to(n: np.ndarray) -> Optional[str]:
    """Return the quaternion (MJCF text) turning +z onto the unit vector `n` (None: it is)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    if np.linalg.norm(axis) < 1e-12:
        return None if n[2] > 0 else _text([0, 1, 0, 0])
    return _text(quat.from_axis_angle(axis, math.acos(max(-1.0, min(1.0, float(n @ z))))))


def cone_mesh(radius: float, length: float) -> tuple:
    """Return (vertices (n, 3), faces (m, 3)) of a cone: base at -length/2, apex at +length/2."""
    k = CONE_SEGMENTS
    angles = np.linspace(0, 2 * math.pi, k, endpoint=False)
    rim = np.stack([radius * np.cos(angles), radius * np.sin(angles),
                    np.full(k, -length / 2)], axis=1)
    vertices = np.vstack([rim, [[0, 0, length / 2], [0, 0, -length / 2]]])
    apex, centre = k, k + 1
    faces = [(i, (i + 1) % k, apex) for i in range(k)]
    faces += [((i + 1) % k, i, centre) for i in range(k)]
    return vertices, np.array(faces)


def polyline_mesh(lines: Sequence[ET.Element], where: str) -> tuple:
    """
    Return (vertices, faces) of SDF polylines: each outline extruded from 0 to its height.

    The outline is triangulated by ear clipping (it may be concave; its winding is made
    counter-clockwise first), its sides are quads split in two.
    """
    vertices, faces = [], []
    for line in lines:
        points = []
        for p in line.findall('point'):
            points.append(numbers(p.text, (0, 0), where, 'a polyline point'))
            if len(points) > MAX_POLYLINE_POINTS:
                raise ResourceParseError(f'{where}: a polyline of more than '
                                         f'{MAX_POLYLINE_POINTS} points')
        (height,) = numbers(line.findtext('height'), (1.0,), where, 'a polyline height')
        if len(points) > 2 and np.allclose(points[0], points[-1]):
            points = points[:-1]
        if len(points) < 3 or not height > 0:
            raise ResourceParseError(ERR_POLYLINE.format(where=where))
        pts = np.asarray(points, float)
        x, y = pts[:, 0], pts[:, 1]
        if float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) < 0:
            pts = pts[::-1]
        n, base = len(pts), len(vertices)
        vertices += [(px, py, 0.0) for px, py in pts] + [(px, py, height) for px, py in pts]
        for a, b, c in _ear_clip(pts):
            faces.append((base + c, base + b, base + a))  # the bottom faces down
            faces.append((base + n + a, base + n + b, base + n + c))
        for i in range(n):
            j = (i + 1) % n
            faces += [(base + i, base + j, base + n + j), (base + i, base + n + j, base + n + i)]
    return np.asarray(vertices, float), np.asarray(faces, int)


def _ear_clip(pts: np.ndarray) -> list:
    """Triangles (index triples) of a simple counter-clockwise polygon."""
    left = list(range(len(pts)))
    out = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    guard = 0
    while len(left) > 3 and guard < 4 * len(pts) ** 2:
        guard += 1
        for k in range(len(left)):
            i, j, m = left[k - 1], left[k], left[(k + 1) % len(left)]
            a, b, c = pts[i], pts[j], pts[m]
            if cross(a, b, c) <= 0:
                continue
            if any(cross(a, b, pts[q]) >= 0 and cross(b, c, pts[q]) >= 0
                   and cross(c, a, pts[q]) >= 0 for q in left if q not in (i, j, m)):
                continue
            out.append((i, j, m))
            left.pop(k)
            break
        else:
            break  # not simple: fan the rest
    out += [(left[0], left[k], left[k + 1]) for k in range(1, len(left) - 1)]
    return out


def colour(material: Optional[ET.Element], where: str,
           transparency: float = 0.0) -> Optional[dict]:
    """
    Return {'rgba', 'specular', 'emission', 'albedo_map'} of a visual's ``<material>``.

    None: no material (the mesh file's colour, else the default grey).
    """
    if material is None:
        return None if transparency <= 0 else {'rgba': (0.7, 0.7, 0.7, 1 - transparency),
                                               'specular': 0.5, 'emission': 0.0,
                                               'albedo_map': ''}

    def rgba(tag):
        text = material.findtext(tag)
        if text is None or not text.strip():
            return None
        values = numbers(text, (0, 0, 0, 1) if len(text.split()) == 4 else (0, 0, 0), where,
                         f'a material <{tag}>')
        return [min(max(v, 0.0), 1.0) for v in values] + ([1.0] if len(values) == 3 else [])
    diffuse = rgba('diffuse') or rgba('ambient')
    if diffuse is None:
        name = (material.findtext('script/name') or '').strip()
        base = name
        for suffix in _SCRIPT_ALPHA:
            base = base.replace(suffix, '')
        found = SCRIPT_COLOURS.get(base)
        if found is not None:
            diffuse = list(found)
            diffuse[3] = min(diffuse[3], _SCRIPT_ALPHA.get(name[len(base):], 1.0))
        else:
            diffuse = [0.7, 0.7, 0.7, 1.0]
    specular = rgba('specular') or [0.5, 0.5, 0.5, 1.0]
    emissive = rgba('emissive') or [0.0, 0.0, 0.0, 1.0]
    brightness = max(sum(diffuse[:3]) / 3, 1e-3)
    diffuse[3] = min(diffuse[3], 1.0 - max(0.0, min(transparency, 1.0)))
    albedo = (material.findtext('pbr/metal/albedo_map')
              or material.findtext('pbr/specular/albedo_map') or '').strip()
    return {'rgba': tuple(diffuse), 'specular': float(min(1.0, sum(specular[:3]) / 3)),
            'emission': float(min(1.0, sum(emissive[:3]) / 3 / brightness)),
            'albedo_map': albedo}
