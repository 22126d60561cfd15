"""
A child process that turns mesh files MuJoCo cannot read into binary STL (no sim_node imports).

Run as ``python mesh_worker.py`` by :mod:`.meshes`: it reads one JSON job from stdin (a list of
``{"src", "kind", "out", "max_faces"}``) and writes one JSON line per item to stdout
(``{"faces_in", "faces", "rgba", "unit"}`` or ``{"error"}``). It loads each file with trimesh
(Collada through pycollada) from its bytes, never by name, so nothing the file names (textures,
an OBJ's ``mtllib``) is ever opened; merges a scene into one mesh with every node's transform;
scales it by Collada's ``<unit meter>`` (Collada's ``up_axis`` is ignored, as RViz ignores it:
ROS description packages ship Z-up meshes that declare Y_UP); decimates it to ``max_faces``
with fast-simplification when it has more; and writes binary STL.

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
MEMORY_BYTES = 3 << 30
CPU_SECONDS = 120
WRITE_BYTES = 256 << 20
_UNIT = re.compile(rb'<unit\b[^>]*\bmeter\s*=\s*"([^"]+)"')
_BIND_MATERIAL = re.compile(rb'<bind_material\b.*?</bind_material>', re.S)


def _limit(inputs: list, outputs: list) -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_BYTES, MEMORY_BYTES))
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS))
    resource.setrlimit(resource.RLIMIT_FSIZE, (WRITE_BYTES, WRITE_BYTES))
    allowed = {os.path.realpath(p) for p in inputs + outputs}
    allowed |= {os.path.realpath(p) + '.part' for p in outputs}

    def hook(event: str, args: tuple) -> None:
        if event == 'open':
            path = args[0]
            if isinstance(path, int):
                return
            real = os.path.realpath(os.fsdecode(path))
            if real not in allowed and not real.endswith(('.py', '.pyc', '.so')):
                raise PermissionError(f'the mesh worker may not open {real}')
        elif event.split('.')[0] in ('subprocess', 'socket') or event in (
                'os.system', 'os.exec', 'os.fork', 'os.forkpty', 'os.posix_spawn', 'os.spawn',
                'ctypes.dlopen', 'os.startfile'):
            raise PermissionError(f'the mesh worker may not {event}')
    sys.addaudithook(hook)


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
    import trimesh
    with open(src, 'rb') as f:
        data = f.read()
    unit = _unit(data) if kind == 'dae' else 1.0
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
    faces_in = int(len(mesh.faces))
    if faces_in == 0:
        return {'error': 'it has no triangles'}
    if not np.all(np.isfinite(mesh.vertices)):
        return {'error': 'it has non-finite vertices'}
    if unit != 1.0:
        mesh.apply_scale(unit)
    if faces_in > max_faces:
        mesh = mesh.simplify_quadric_decimation(face_count=max_faces)
    with open(out + '.part', 'wb') as f:
        f.write(mesh.export(file_type='stl'))
    os.replace(out + '.part', out)
    return {'faces_in': faces_in, 'faces': int(len(mesh.faces)), 'rgba': rgba, 'unit': unit}


def main() -> None:
    job = json.loads(sys.stdin.read())
    import numpy  # noqa: F401 (imported before the limits: they refuse opening modules' data)
    import trimesh  # noqa: F401
    import trimesh.exchange.dae  # noqa: F401
    try:
        import fast_simplification  # noqa: F401
        import collada  # noqa: F401
    except ImportError:
        pass  # said per file below
    _limit([item['src'] for item in job], [item['out'] for item in job])
    os.nice(5)  # the physics of the node that asked goes first
    for item in job:
        try:
            result = convert(item['src'], item['kind'], item['out'], int(item['max_faces']))
        except MemoryError:
            result = {'error': 'converting it needs more memory than a mesh may take'}
        except Exception as exc:  # noqa: B902 (any failure of a hostile file is its answer)
            result = {'error': f'{type(exc).__name__}: {exc}'[:300]}
        print(json.dumps(result), flush=True)


if __name__ == '__main__':
    main()
