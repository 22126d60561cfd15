"""
A child process that turns mesh files MuJoCo cannot read into binary STL (no sim_node imports).

Run as ``python mesh_worker.py`` by :mod:`.meshes`, and kept running: it reads one JSON line
per file from stdin (``{"src", "kind", "out", "max_faces"}``) and answers each with one JSON
line on stdout (``{"faces_in", "faces", "rgba", "unit"}`` or ``{"error"}``), until stdin ends.
It reads each file from its bytes, never by name, so nothing the file names (textures, an OBJ's
``mtllib``) is ever opened: Collada first with :mod:`collada_fast`, then, for what that does not
read, and for every other kind, with trimesh (Collada through pycollada); merges a scene into
one mesh with every node's transform; scales it by Collada's ``<unit meter>`` (Collada's
``up_axis`` is ignored, as RViz ignores it: ROS description packages ship Z-up meshes that
declare Y_UP); decimates it to ``max_faces`` with fast-simplification when it has more; and
writes binary STL.

The files are untrusted (a Collada file may claim hundreds of millions of values), so the
process limits itself before it reads any: address space, CPU time, the size of what it writes,
and an audit hook that refuses to open anything but its inputs and outputs, to start processes
or to open sockets. What a hostile file can do is fail, here, alone.
"""

import io
import json
import os
import re
import resource
import sys

#: Limits of one worker process.
#: This process's scheduling priority, below the node's: on a machine with few cores its work
#: took the CPU from the node's stepping and publishing threads (long /clock gaps in a spawn).
NICE = 10
MEMORY_BYTES = 3 << 30
CPU_SECONDS = 120
WRITE_BYTES = 256 << 20
_UNIT = re.compile(rb'<unit\b[^>]*\bmeter\s*=\s*"([^"]+)"')
_BIND_MATERIAL = re.compile(rb'<bind_material\b.*?</bind_material>', re.S)


ALLOWED: set = set()  # what the file being converted may open: its source, its output


def sandbox(memory: int = MEMORY_BYTES, who: str = 'the mesh worker') -> None:
    """
    Limit this process: its memory and writes, and what it may open (:data:`ALLOWED`).

    Its audit hook refuses to open anything but ALLOWED (and modules), to start processes, to
    open sockets or to load libraries; :mod:`.decompose_worker` runs in it too.
    """
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    resource.setrlimit(resource.RLIMIT_FSIZE, (WRITE_BYTES, WRITE_BYTES))

    def hook(event: str, args: tuple) -> None:
        if event == 'open':
            path = args[0]
            if isinstance(path, int):
                return
            real = os.path.realpath(os.fsdecode(path))
            if real not in ALLOWED and not real.endswith(('.py', '.pyc', '.so')):
                raise PermissionError(f'{who} may not open {real}')
        elif event.split('.')[0] in ('subprocess', 'socket') or event in (
                'os.system', 'os.exec', 'os.fork', 'os.forkpty', 'os.posix_spawn', 'os.spawn',
                'ctypes.dlopen', 'os.startfile'):
            raise PermissionError(f'{who} may not {event}')
    sys.addaudithook(hook)


def _allow(job: dict) -> None:
    """Let this file's source and output be opened, nothing else; give it its CPU time."""
    ALLOWED.clear()
    ALLOWED.update({os.path.realpath(job['src']), os.path.realpath(job['out']),
                    os.path.realpath(job['out'] + '.part')})
    used = resource.getrusage(resource.RUSAGE_SELF)
    spent = int(used.ru_utime + used.ru_stime) + 1
    resource.setrlimit(resource.RLIMIT_CPU, (spent + CPU_SECONDS, resource.RLIM_INFINITY))


def _unit(data: bytes) -> float:
    """Return Collada's metres per unit (<asset><unit meter>), 1 when it says nothing."""
    m = _UNIT.search(data[:20000])
    try:
        unit = float(m.group(1)) if m else 1.0
    except ValueError:
        unit = 1.0
    return unit if unit > 0 and unit < 1e6 else 1.0


def _colour(scene) -> list:
    """Return the area-weighted diffuse colour of a scene's materials (RGBA 0-1), or None."""
    import numpy as np
    total, weight = np.zeros(4), 0.0
    for geom in scene.geometry.values():
        material = getattr(getattr(geom, 'visual', None), 'material', None)
        colour = getattr(material, 'main_color', None)
        if colour is None or not hasattr(geom, 'area'):
            continue
        total += np.asarray(colour, dtype=float)[:4] / 255.0 * geom.area
        weight += geom.area
    return (total / weight).round(4).tolist() if weight > 0 else None


def convert(src: str, kind: str, out: str, max_faces: int) -> dict:
    import numpy as np
    with open(src, 'rb') as f:
        data = f.read()
    unit = _unit(data) if kind == 'dae' else 1.0
    import collada_fast
    try:
        found = _read_fast(data) if kind == 'dae' else _read_stl(data) if kind == 'stl' else None
        if found is None and kind == 'dae':  # the full reader sizes its arrays by the counts
            collada_fast.check_counts(data)
    except collada_fast.Malformed as exc:
        return {'error': f'it is malformed: {exc}'}
    if found is None:
        found = _read_trimesh(data, kind)
        if isinstance(found, dict):
            return found  # an error
    vertices, faces, rgba = found
    faces_in = int(len(faces))
    if faces_in == 0:
        return {'error': 'it has no triangles'}
    if not np.all(np.isfinite(vertices)):
        return {'error': 'it has non-finite vertices'}
    vertices = vertices * unit
    if faces_in > max_faces:
        try:
            import fast_simplification
        except ImportError:
            return {'error': f'it has {faces_in} faces, more than {max_faces}, and cutting it '
                    'down needs the fast-simplification package: pip install '
                    'fast-simplification'}
        # A triangle soup (an STL repeats each vertex per face) has no edge to collapse: the
        # simplifier could only drop whole faces. Joined, it collapses edges, and MuJoCo
        # processes a quarter of the vertices (its compile 1.2 s -> 1.0 s). Faces that are a
        # point or a line, or repeat another, have nothing to collapse either: with a fifth
        # of them so, the simplifier took 7.6 s and kept 590,000 of 764,000 faces.
        vertices, faces = _clean(*_weld(vertices, faces))
        for _ in range(2):  # a second pass where the first fell short
            if len(faces) <= max_faces:
                break
            vertices, faces = fast_simplification.simplify(
                vertices, faces.astype(np.int32), 1.0 - max_faces / len(faces))
        if len(faces) > max_faces:
            return {'error': f'it has {faces_in} faces, more than {max_faces}, and cutting it '
                    f'down kept {len(faces)}; decimate it in a mesh editor'}
    with open(out + '.part', 'wb') as f:
        f.write(collada_fast.binary_stl(np.asarray(vertices, dtype=float), np.asarray(faces)))
    os.replace(out + '.part', out)
    return {'faces_in': faces_in, 'faces': int(len(faces)), 'rgba': rgba, 'unit': unit}


def _read_stl(data: bytes):
    """
    Read a binary STL whose size is what its count says: (corners, faces, None); else None.

    Its triangles as they are, each with its own three corners (:func:`_weld` joins them), as
    the float32 the file holds (the simplifier takes those: no round trip through float64); an
    ASCII file, or one whose count lies, goes to the full reader, which says what is wrong.
    """
    import numpy as np
    if len(data) < 84:
        return None
    n = int.from_bytes(data[80:84], 'little')
    if n == 0 or len(data) != 84 + 50 * n:
        return None
    record = np.dtype([('normal', '<f4', 3), ('corners', '<f4', (3, 3)), ('attr', '<u2')])
    corners = np.frombuffer(data, dtype=record, count=n, offset=84)['corners'].reshape(-1, 3)
    return np.ascontiguousarray(corners), np.arange(3 * n).reshape(-1, 3), None


def _weld(vertices, faces):
    """
    Join the vertices that are the same point, exactly (as float32): (vertices, faces).

    By their bits, sorted (0.4 s for 2 million corners, where hashing rows took 0.9 s); -0.0
    is 0.0.
    """
    import numpy as np
    points = np.ascontiguousarray(vertices, dtype=np.float32) + np.float32(0.0)
    bits = points.view(np.uint32).reshape(-1, 3)
    high = (bits[:, 0].astype(np.uint64) << np.uint64(32)) | bits[:, 1].astype(np.uint64)
    order = np.lexsort((bits[:, 2], high))
    first = np.ones(len(order), bool)
    first[1:] = (high[order][1:] != high[order][:-1]) | \
        (bits[order, 2][1:] != bits[order, 2][:-1])
    index = np.empty(len(order), np.int64)
    index[order] = np.cumsum(first) - 1
    return points[order[first]], index[np.asarray(faces)]


def _clean(vertices, faces):
    """Drop the faces that are a point or a line, and those that repeat another's corners."""
    import numpy as np
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    faces = faces[(a != b) & (b != c) & (a != c)]
    corners = np.sort(faces, axis=1)
    n = np.int64(len(vertices))
    if n < (1 << 21):  # three indices in one int64
        _, keep = np.unique((corners[:, 0] * n + corners[:, 1]) * n + corners[:, 2],
                            return_index=True)
    else:
        _, keep = np.unique(corners, axis=0, return_index=True)
    return vertices, faces[np.sort(keep)]


def _read_fast(data: bytes):
    """
    Read Collada with :mod:`collada_fast`; None when it needs the full reader.

    :raises collada_fast.Malformed: its counts lie (no reader should read it).
    """
    import collada_fast
    try:
        return collada_fast.read(data)
    except collada_fast.Malformed:
        raise
    except (collada_fast.Unsupported, ValueError, IndexError, KeyError, TypeError):
        return None


def _read_trimesh(data: bytes, kind: str):
    """Read any mesh trimesh reads: (vertices, faces, rgba), or an error dict."""
    import numpy as np
    import trimesh
    loaded = trimesh.load(io.BytesIO(data), file_type=kind, force='scene', process=False)
    if kind == 'dae' and not loaded.geometry:
        # pycollada drops a node whose material is broken (a texture that is not there): read
        # the geometry without its materials, as a viewer shows it grey
        loaded = trimesh.load(io.BytesIO(_BIND_MATERIAL.sub(b'', data)), file_type=kind,
                              force='scene', process=False)
    if not loaded.geometry:
        return {'error': 'it has no triangles'}
    mesh = loaded.to_mesh() if hasattr(loaded, 'to_mesh') else loaded.dump(concatenate=True)
    rgba = _colour(loaded) if kind in ('dae', 'glb', 'gltf', 'obj') else None
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces), rgba


def main() -> None:
    os.nice(NICE)  # the physics of the node that asked goes first, from the imports on
    import numpy  # noqa: F401 (imported before the limits: they refuse opening modules' data)
    import collada_fast  # noqa: F401
    import trimesh  # noqa: F401
    import trimesh.exchange.dae  # noqa: F401
    import trimesh.grouping  # noqa: F401
    try:
        import fast_simplification  # noqa: F401
        import collada  # noqa: F401
    except ImportError:
        pass  # said per file below
    sandbox()
    for line in sys.stdin:
        try:
            item = json.loads(line)
            _allow(item)
            result = convert(item['src'], item['kind'], item['out'], int(item['max_faces']))
        except MemoryError:
            result = {'error': 'converting it needs more memory than a mesh may take'}
        except Exception as exc:  # noqa: B902 (any failure of a hostile file is its answer)
            result = {'error': f'{type(exc).__name__}: {exc}'[:300]}
        print(json.dumps(result), flush=True)


if __name__ == '__main__':
    main()
