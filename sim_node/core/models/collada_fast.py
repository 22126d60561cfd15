"""
A fast reader of the Collada files ROS description packages ship (no sim_node imports).

Used by :mod:`.mesh_worker` before trimesh and pycollada, which read a 28 MB Collada file in
about 1.2 s of pure Python: nearly all of such a file is numbers, in a few ``<float_array>`` and
``<p>`` elements. Here those are lifted out of the text with one regular expression and parsed by
numpy, the rest (a small skeleton) is parsed as XML, and the scene's triangles are gathered with
their node transforms: 3-5 times faster. Anything this reader does not know (a primitive it does
not read, a missing reference) raises :class:`Unsupported`, and the worker falls back to
trimesh, which reads the rest of Collada.

What it reads: ``<triangles>``, ``<polylist>`` and ``<polygons>`` of ``<mesh>`` geometries;
``<vertices>``, ``<source>`` and ``<accessor>`` (stride, offsets); the node tree of the scene's
visual scene (``<matrix>``, ``<translate>``, ``<rotate>``, ``<scale>``, ``<instance_geometry>``,
``<instance_node>``), or every geometry when there is no scene; materials' diffuse colours.
"""

import re
import xml.etree.ElementTree as ET

import numpy as np

#: Elements whose text is numbers: lifted out of the text before it is parsed as XML.
_NUMBERS = re.compile(rb'(<(float_array|p|vcount)\b[^>]*>)([^<]*)(</\2>)')
#: Deepest node tree (and instance_node chain) read.
MAX_DEPTH = 64


class Unsupported(ValueError):
    """The file uses something this reader does not read: use the full reader."""


class Malformed(ValueError):
    """The file's declared counts disagree with its data: no reader should trust it."""


ERR_ARRAY_COUNT = 'a <float_array> says count="{count}" but holds {n} values'
ERR_ACCESSOR = 'an <accessor> reads {need} values of an array that holds {n}'
_COUNT = re.compile(rb'\bcount\s*=\s*"\s*(\d+)\s*"')
_ID = re.compile(rb'\bid\s*=\s*"([^"]*)"')
_ACCESSOR = re.compile(rb'<accessor\b[^>]*>')
_ATTR = re.compile(rb'\b(source|count|stride|offset)\s*=\s*"([^"]*)"')


def check_counts(data: bytes) -> None:
    """
    Refuse a file whose ``count`` attributes disagree with the data they describe.

    Each ``<float_array count>`` must be the number of values it holds, and each ``<accessor>``
    must fit in the array it reads (offset + count * stride values). A full reader sizes its
    arrays by these counts: one that claims 500 million floats and holds 12 would have it
    allocate gigabytes. Read with plain searches, no XML parsing: it costs a scan of the file.

    :raises Malformed: naming the first count that lies.
    """
    held = {}
    for m in _NUMBERS.finditer(data):
        if m.group(2) != b'float_array':
            continue
        n = len(m.group(3).split())
        count = _COUNT.search(m.group(1))
        if count is not None and int(count.group(1)) != n:
            raise Malformed(ERR_ARRAY_COUNT.format(count=int(count.group(1)), n=n))
        ident = _ID.search(m.group(1))
        if ident is not None:
            held[ident.group(1).decode(errors='replace')] = n
    for m in _ACCESSOR.finditer(data):
        attrs = {k.decode(): v.decode(errors='replace') for k, v in _ATTR.findall(m.group(0))}
        n = held.get(attrs.get('source', '').lstrip('#'))
        try:
            need = int(attrs.get('offset', 0)) + int(attrs.get('count', 0)) * max(
                int(attrs.get('stride', 1)), 1)
        except ValueError:
            raise Malformed('an <accessor> whose count, stride or offset is not a number') \
                from None
        if n is not None and need > n:
            raise Malformed(ERR_ACCESSOR.format(need=need, n=n))


def _tag(elem: ET.Element) -> str:
    return elem.tag.rsplit('}', 1)[-1]


def _children(elem: ET.Element, name: str) -> list:
    return [c for c in elem if _tag(c) == name]


def _child(elem: ET.Element, name: str):
    for c in elem:
        if _tag(c) == name:
            return c
    return None


def read(data: bytes) -> tuple:
    """
    Return (vertices (n, 3) float64, faces (m, 3) int64, rgba or None) of a Collada file.

    Vertices are in the file's units (the caller applies ``<unit meter>``), with every node's
    transform applied. :raises Unsupported: anything it does not read.
    """
    texts: list = []

    def lift(m: re.Match) -> bytes:
        texts.append(m.group(3))
        return m.group(1) + b'@' + str(len(texts) - 1).encode() + m.group(4)
    skeleton = _NUMBERS.sub(lift, data)
    try:
        root = ET.fromstring(skeleton)
    except ET.ParseError as exc:
        raise Unsupported(f'not XML: {exc}') from None
    ids = {e.get('id'): e for e in root.iter() if e.get('id')}

    def numbers(elem, dtype=float) -> np.ndarray:
        text = (elem.text or '').strip()
        if not text.startswith('@'):
            values = np.array(text.split(), dtype=dtype)
        else:
            values = np.array(texts[int(text[1:])].split(), dtype=dtype)
        count = elem.get('count') if _tag(elem) == 'float_array' else None
        if count is not None and count.strip() != str(len(values)):
            raise Malformed(ERR_ARRAY_COUNT.format(count=count.strip()[:20], n=len(values)))
        return values

    def ref(url: str):
        target = ids.get((url or '').lstrip('#'))
        if target is None:
            raise Unsupported(f'missing reference {url!r}')
        return target

    def positions(source) -> np.ndarray:
        if _tag(source) == 'vertices':
            pos = [i for i in _children(source, 'input') if i.get('semantic') == 'POSITION']
            if not pos:
                raise Unsupported('vertices without POSITION')
            source = ref(pos[0].get('source'))
        arr = _child(source, 'float_array')
        acc = source.find('.//{*}accessor')
        if arr is None:
            raise Unsupported('a source without float_array')
        values = numbers(arr)
        stride = int(acc.get('stride', '3')) if acc is not None else 3
        offset = int(acc.get('offset', '0')) if acc is not None else 0
        count = int(acc.get('count', str(len(values) // max(stride, 1)))) if acc is not None \
            else len(values) // stride
        if stride < 3:
            raise Unsupported('an accessor of fewer than 3 values a vertex')
        if offset + count * stride > len(values):
            raise Malformed(ERR_ACCESSOR.format(need=offset + count * stride, n=len(values)))
        return values[offset:offset + count * stride].reshape(count, stride)[:, :3]

    def primitives(geometry) -> list:
        """Return [(vertices, faces, material symbol)] of a <geometry>'s mesh."""
        mesh = _child(geometry, 'mesh')
        if mesh is None:
            raise Unsupported('a geometry that is not a mesh')
        out = []
        for prim in mesh:
            kind = _tag(prim)
            if kind in ('source', 'vertices', 'extra', 'lines', 'linestrips'):
                continue
            if kind not in ('triangles', 'polylist', 'polygons'):
                raise Unsupported(f'<{kind}>')
            inputs = _children(prim, 'input')
            vert = [i for i in inputs if i.get('semantic') == 'VERTEX']
            if not vert:
                raise Unsupported('a primitive without VERTEX')
            stride = max(int(i.get('offset', '0')) for i in inputs) + 1
            voff = int(vert[0].get('offset', '0'))
            pts = positions(ref(vert[0].get('source')))
            ps = _children(prim, 'p')
            if not ps:
                continue
            if kind == 'polygons':
                polys = [numbers(p, np.int64).reshape(-1, stride)[:, voff] for p in ps]
                faces = np.array([[poly[0], poly[i], poly[i + 1]] for poly in polys
                                  for i in range(1, len(poly) - 1)], dtype=np.int64)
            else:
                index = numbers(ps[0], np.int64)
                if len(index) % stride:
                    raise Unsupported('a <p> that does not fit its inputs')
                corners = index.reshape(-1, stride)[:, voff]
                if kind == 'triangles':
                    faces = corners[:len(corners) // 3 * 3].reshape(-1, 3)
                else:
                    faces = _fan(corners, numbers(_child(prim, 'vcount'), np.int64))
            if len(faces) and (faces.min() < 0 or faces.max() >= len(pts)):
                raise Unsupported('an index past its vertices')
            out.append((pts, faces.reshape(-1, 3), prim.get('material', '')))
        return out

    def colours(instance) -> dict:
        """Return material symbol -> RGBA of an <instance_geometry>'s bound materials."""
        found = {}
        for inst in instance.iter():
            if _tag(inst) != 'instance_material':
                continue
            try:
                material = ref(inst.get('target'))
                effect = ref(_child(material, 'instance_effect').get('url'))
            except (Unsupported, AttributeError):
                continue
            diffuse = effect.find('.//{*}diffuse/{*}color')
            if diffuse is not None:
                rgba = np.array(diffuse.text.split(), dtype=float)
                if rgba.size >= 3:
                    found[inst.get('symbol')] = np.append(rgba[:4], [1.0] * (4 - rgba[:4].size))
        return found

    parts = []  # (vertices in the scene's frame, faces, rgba or None)

    def visit(node, transform: np.ndarray, depth: int) -> None:
        if depth > MAX_DEPTH:
            raise Unsupported('a node tree too deep')
        for item in node:
            kind = _tag(item)
            if kind in ('matrix', 'translate', 'rotate', 'scale'):
                transform = transform @ _transform(kind, numbers(item))
        for item in node:
            kind = _tag(item)
            if kind == 'instance_geometry':
                bound = colours(item)
                for pts, faces, symbol in primitives(ref(item.get('url'))):
                    moved = pts @ transform[:3, :3].T + transform[:3, 3]
                    parts.append((moved, faces, bound.get(symbol)))
            elif kind == 'node':
                visit(item, transform, depth + 1)
            elif kind == 'instance_node':
                visit(ref(item.get('url')), transform, depth + 1)

    scene = root.find('{*}scene/{*}instance_visual_scene')
    if scene is None:
        scene = root.find('scene/instance_visual_scene')
    if scene is not None:
        visit(ref(scene.get('url')), np.eye(4), 0)
    else:
        for geometry in root.iter():
            if _tag(geometry) == 'geometry':
                parts += [(pts, faces, None) for pts, faces, _ in primitives(geometry)]
    parts = [p for p in parts if len(p[1])]
    if not parts:
        raise Unsupported('no triangles')
    verts, faces, base = [], [], 0
    for pts, f, _ in parts:
        verts.append(pts)
        faces.append(f + base)
        base += len(pts)
    vertices, all_faces = np.concatenate(verts), np.concatenate(faces)
    return vertices, all_faces, _mean_colour(parts)


def _fan(corners: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Triangulate polygons (`counts` corners each, in order) as fans."""
    if counts.sum() != len(corners) or (counts < 3).any():
        raise Unsupported('a <vcount> that does not fit its <p>')
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    n_tri = counts - 2
    first = np.repeat(starts, n_tri)
    step = np.arange(n_tri.sum()) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    return np.stack([corners[first], corners[first + step + 1], corners[first + step + 2]],
                    axis=1)


def _transform(kind: str, v: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    if kind == 'matrix' and v.size == 16:
        return v.reshape(4, 4)
    if kind == 'translate' and v.size == 3:
        t[:3, 3] = v
    elif kind == 'scale' and v.size == 3:
        t[:3, :3] = np.diag(v)
    elif kind == 'rotate' and v.size == 4:
        axis = v[:3] / (np.linalg.norm(v[:3]) or 1.0)
        a = np.radians(v[3])
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        t[:3, :3] = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k
    else:
        raise Unsupported(f'a <{kind}> of {v.size} values')
    return t


def _mean_colour(parts: list):
    """Area-weighted colour of the parts that have one, or None."""
    total, weight = np.zeros(4), 0.0
    for pts, faces, rgba in parts:
        if rgba is None:
            continue
        tri = pts[faces]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                    axis=1).sum()
        total += np.clip(rgba, 0, 1) * area
        weight += area
    return (total / weight).round(4).tolist() if weight > 0 else None


def binary_stl(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """Return binary STL bytes of a triangle mesh (normals from the winding)."""
    tri = vertices[faces].astype(np.float32)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    rec = np.zeros(len(faces), dtype=[('n', '<f4', 3), ('v', '<f4', (3, 3)), ('a', '<u2')])
    rec['n'], rec['v'] = normal, tri
    header = b'binary STL by sim'.ljust(80, b' ')
    return header + np.uint32(len(faces)).tobytes() + rec.tobytes()
