"""
A child process that splits a concave collision mesh into convex parts (no sim_node imports).

Run once per mesh by :mod:`.decompose` as ``python decompose_worker.py`` with one JSON line on
stdin (``{"src", "out", "threshold", "fill", "max_parts", "seconds", "memory"}``); it answers
with one JSON line on stdout: ``{"whole": true}`` when the mesh is one shell its hull stands
for (MuJoCo collides a mesh as its hull), ``{"parts": [file, ...], "shells", "decomposed"}``
with the parts written as binary STL in the folder ``out``, or ``{"error"}``; with
``"fills"``, the filled share of the hull of each shell that was not convex.

How: the mesh (binary STL or OBJ, read from its bytes) is welded (vertices at one place made
one) and cut into its shells (faces joined by shared vertices). A shell that is closed and
convex at every edge is convex: it is one part as it is; so is an open one convex at every edge
two of its faces share, or whose every vertex lies on its hull (a patch of a convex surface,
rounding and all: :func:`_on_hull`). A flat shell (a plate, a decal) has no inside and is left
out (MuJoCo refuses a flat hull; a mesh of flat shells alone stays whole). A shell that fills
at least `fill` of its hull's volume is one part too (an arm's link, a wheel with a hub: its
hull is close to it). The others (a tray, a bin, a table, a shelf, a mug: a hull of mostly
empty space) go to CoACD (collision-aware convex decomposition, Wei et al., SIGGRAPH 2022),
whose concavity `threshold` (a fraction of the shell's size) decides how closely the parts
follow it. An open shell (a cap, a crack, a surface with no thickness) is measured as if its
opening were closed (see :func:`_volume`): a dome is then a solid cap and stays whole, as does
a tray of single faces (its closed box).

The file is untrusted, and CoACD's search may run long on a large mesh, so the process limits
itself first, in the mesh worker's sandbox (:func:`.mesh_worker.sandbox`): address space, CPU
time, written bytes, a lower scheduling priority than the node, and an audit hook refusing to
open anything but its input and its parts, to start processes or to open sockets. What a
hostile file can do is fail, here, alone.
"""

import io
import json
import os
import resource
import sys

NICE = 10
MEMORY_BYTES = 4 << 30
#: A shell whose thinnest extent is this fraction of its largest or less is flat.
FLAT = 1e-6
#: How far (a fraction of the shell's size) an edge may fold inwards and still count convex:
#: rounding only (a finely cut curve folds little at each edge: a washer of 12,500 segments
#: folds 6e-8 of its size). A shell rounding makes look concave is kept whole by its fill.
CONVEX_TOLERANCE = 1e-9
#: An open shell each of whose vertices is the farthest of the shell along its own normal (or
#: against it) within this fraction of the shell's size lies on its hull (:func:`_on_hull`): a
#: patch of a convex surface. Not the edge rule alone: decimated in float32, a 250,000-face
#: patch of a sphere folded some edges inwards by 1e-5 of its size. A dent or a bowl's inside
#: lies deeper than this below its neighbours' reach.
ON_HULL = 1e-3
#: Vertices checked (a random choice), each against every vertex of the shell.
ON_HULL_SAMPLE = 2000
#: The hull a shell's fill is measured against is made of at most this many of its vertices
#: (a random choice): qhull took 5 s for 20,000 points of a washer's rim, 0.2 s for 5,000.
HULL_POINTS = 5000
#: CoACD searches a shell simplified to this many faces at most: collision needs its shape,
#: not its detail, and the search's time grows with the faces (a 2,000-face lobed sphere:
#: 6 s; the same at 82,000 faces: over a minute).
SEARCH_FACES = 2000
#: CoACD's tree search, narrower than its defaults (150 iterations, depth 3): a tray's floor
#: and walls still come out as parts, in a third of the time.
MCTS_ITERATIONS = 50
MCTS_DEPTH = 2


def _limit(src: str, seconds: int, memory: int) -> None:
    """Sandbox this process as the mesh worker is, with `memory` bytes and `seconds` of CPU."""
    import mesh_worker  # the sibling script: one sandbox for both workers
    mesh_worker.ALLOWED.add(os.path.realpath(src))
    mesh_worker.sandbox(memory, 'the decomposition worker')
    resource.setrlimit(resource.RLIMIT_CPU, (seconds, seconds + 5))


def _shells(faces):
    """Return the faces of each shell (faces joined through shared vertices), largest first."""
    import numpy as np
    n = int(faces.max()) + 1 if len(faces) else 0
    label = np.arange(n)
    while True:  # each face pulls its vertices to its least label; pointer jumping after
        low = label[faces].min(axis=1)
        new = label.copy()
        for k in range(3):
            np.minimum.at(new, faces[:, k], low)
        new = new[new]
        if np.array_equal(new, label):
            break
        label = new
    face_label = label[faces[:, 0]]
    order = np.argsort(face_label, kind='stable')
    cuts = np.flatnonzero(np.diff(face_label[order])) + 1
    groups = np.split(order, cuts)
    return sorted(groups, key=len, reverse=True)


def _compact(vertices, faces):
    import numpy as np
    used, inverse = np.unique(faces, return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3)


def _flat(vertices) -> bool:
    import numpy as np
    centred = vertices - vertices.mean(axis=0)
    if len(vertices) < 4:
        return True
    s = np.linalg.svd(centred, compute_uv=False)
    return s[-1] <= FLAT * max(s[0], 1e-300)


def _convex(vertices, faces) -> bool:
    """
    Whether a shell is consistently wound and folds outwards at every edge two faces share.

    Closed or open: an open shell convex at every edge it shares is a patch of a convex surface
    (a dome, a cap, a scan of a ball with its bottom missing), every vertex on its hull, which
    its hull stands for as for a dome (a 250,000-face patch of a sphere went to CoACD for 30 s
    and more, past the budget, to end as its hull all the same).
    """
    import numpy as np
    a, b = faces, np.roll(faces, -1, axis=1)  # directed edges a->b of each face
    edges = np.stack([a.ravel(), b.ravel()], axis=1)
    key = np.sort(edges, axis=1)
    code = key[:, 0].astype(np.int64) * (int(faces.max()) + 1) + key[:, 1]
    order = np.argsort(code, kind='stable')
    _, start, count = np.unique(code[order], return_index=True, return_counts=True)
    if np.any(count > 2):
        return False  # an edge of more than two faces (non-manifold)
    pairs = start[count == 2]
    if not len(pairs):
        return False
    first, second = order[pairs], order[pairs + 1]
    if not np.all(edges[first, 0] == edges[second, 1]):
        return False  # both faces run the edge the same way: winding flips
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face_of = np.repeat(np.arange(len(faces)), 3)
    f1, f2 = face_of[first], face_of[second]
    # The corner of the second face off the shared edge lies on or below the first's plane.
    corner = _opposite(faces[f2], edges[first])
    size = np.ptp(vertices, axis=0).max()
    lift = np.einsum('ij,ij->i', normal[f1], vertices[corner] - tri[f1, 0])
    scale = np.linalg.norm(normal[f1], axis=1) * size
    return bool(np.all(lift <= CONVEX_TOLERANCE * scale))


def _open_edges(faces):
    """Return a shell's edges of one face only (its openings; none when it is closed), (n, 2)."""
    import numpy as np
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]),
                    axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    return unique[count == 1]


def _on_hull(vertices, faces) -> bool:
    """Whether a shell's vertices (a sample) each lie on its hull, by :data:`ON_HULL`."""
    import numpy as np
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # weighted by area
    at = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(at, faces[:, k], normal)
    length = np.linalg.norm(at, axis=1)
    usable = np.flatnonzero(length > 0)
    if not len(usable):
        return False
    pick = usable if len(usable) <= ON_HULL_SAMPLE else np.random.default_rng(0).choice(
        usable, ON_HULL_SAMPLE, replace=False)
    tol = ON_HULL * np.ptp(vertices, axis=0).max()
    for chunk in np.array_split(pick, max(1, len(pick) // 100)):
        direction = at[chunk] / length[chunk, None]
        own = np.einsum('ij,ij->i', vertices[chunk], direction)
        reach = vertices @ direction.T  # (vertices, chunk)
        if not np.all((reach.max(axis=0) - own <= tol) | (own - reach.min(axis=0) <= tol)):
            return False
    return True


def _opposite(faces, edges):
    """Return, for each face, its vertex that is neither end of the given edge."""
    import numpy as np
    off = (faces != edges[:, :1]) & (faces != edges[:, 1:2])
    return faces[np.arange(len(faces)), np.argmax(off, axis=1)]


def _volume(vertices, faces, open_edges) -> float:
    """
    Return the volume a shell encloses: exact when it is closed; an open one as if closed.

    The faces are summed as cones from one point: any point for a closed shell; for an open
    one, the centre of its open edges (:func:`_open_edges`), so that a flat opening (a cap's
    rim, a bowl's) adds a cone of no volume: the shell is measured as if its opening were
    closed.
    """
    import numpy as np
    origin = vertices[np.unique(open_edges)].mean(axis=0) if len(open_edges) \
        else vertices.mean(axis=0)
    tri = vertices[faces] - origin
    return abs(float(np.einsum('ij,ij->i', tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum())
               ) / 6.0


def _hull_volume(vertices) -> float:
    """Return the volume of a shell's convex hull, as MuJoCo makes the hull (qhull)."""
    import mujoco
    import numpy as np
    if len(vertices) > HULL_POINTS:
        pick = np.random.default_rng(0).choice(len(vertices), HULL_POINTS, replace=False)
        vertices = vertices[pick]
    spec = mujoco.MjSpec()
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE
    centre = vertices.mean(axis=0)
    spec.add_mesh(name='m', uservert=(vertices - centre).ravel().tolist(),
                  inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX)
    body = spec.worldbody.add_body(name='b')
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname='m', density=1.0)
    return float(spec.compile().body_mass[1])


def _simplified(vertices, faces, most: int):
    """Return a shell with at most `most` faces (fast-simplification), for CoACD's search."""
    import numpy as np
    if len(faces) <= most:
        return vertices, faces
    import fast_simplification
    v, f = fast_simplification.simplify(vertices.astype(np.float32), faces.astype(np.int32),
                                        target_reduction=1.0 - most / len(faces))
    return np.asarray(v, float), np.asarray(f, np.int64)


def decompose(job: dict) -> dict:
    import numpy as np
    import trimesh
    with open(job['src'], 'rb') as f:
        data = f.read()
    kind = os.path.splitext(job['src'])[1].lower().lstrip('.') or 'stl'
    mesh = trimesh.load(io.BytesIO(data), file_type=kind, force='mesh', process=True)
    vertices = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if not len(faces):
        return {'error': 'it has no faces'}
    shells = _shells(faces)
    if len(shells) > job['max_parts']:
        return {'error': f'it has {len(shells)} separate shells, more than the '
                         f'{job["max_parts"]} convex parts a mesh may become'}
    parts, decomposed, fills = [], 0, []
    for k, group in enumerate(shells):
        v, f = _compact(vertices, faces[group])
        if _flat(v):
            continue  # no inside: MuJoCo would refuse it as a hull of its own
        if _convex(v, f):
            parts.append((v, f))
            continue
        opening = _open_edges(f)
        if len(opening) and _on_hull(v, f):
            parts.append((v, f))
            continue
        fill = _volume(v, f, opening) / max(_hull_volume(v), 1e-300)
        fills.append(round(fill, 3))
        if fill >= job['fill']:  # its hull is close enough to it
            parts.append((v, f))
            continue
        import coacd
        coacd.set_log_level('error')
        room = job['max_parts'] - len(parts) - (len(shells) - k - 1)
        v, f = _simplified(v, f, SEARCH_FACES)
        # What simplification could not bring down (long thin faces: a finely cut washer
        # keeps its 100,000), CoACD remeshes on its voxel grid first, which bounds it.
        remesh = 'on' if len(f) > 4 * SEARCH_FACES else 'auto'
        pieces = coacd.run_coacd(coacd.Mesh(v, f), threshold=job['threshold'],
                                 max_convex_hull=max(1, room), preprocess_mode=remesh,
                                 mcts_iterations=MCTS_ITERATIONS, mcts_max_depth=MCTS_DEPTH,
                                 seed=0)
        decomposed += 1
        parts.extend((pv, pf) for pv, pf in ((np.asarray(pv, float), np.asarray(pf, np.int64))
                                             for pv, pf in pieces) if not _flat(pv))
    if (len(shells) == 1 and not decomposed) or not parts:
        return {'whole': True, 'fills': fills}
    names = []
    import collada_fast  # the sibling module's STL writer, as the mesh worker writes
    import mesh_worker
    for i, (v, f) in enumerate(parts):
        name = f'part_{i:03d}.stl'
        path = os.path.join(job['out'], name)
        mesh_worker.ALLOWED.add(os.path.realpath(path))
        with open(path, 'wb') as out:
            out.write(collada_fast.binary_stl(v, f))
        names.append(name)
    return {'parts': names, 'shells': len(shells), 'decomposed': decomposed, 'fills': fills}


def main() -> None:
    job = json.loads(sys.stdin.readline())
    try:  # the libraries load their own files before the hook
        import coacd  # noqa: F401
        import collada_fast  # noqa: F401
        import fast_simplification  # noqa: F401
        import mujoco  # noqa: F401
        import numpy  # noqa: F401
        import trimesh  # noqa: F401
    except ImportError as exc:
        sys.stdout.write(json.dumps({'error': f'the {exc.name} package is missing: pip install '
                                              f'{exc.name.replace("_", "-")}'}) + '\n')
        return
    trimesh.load(io.BytesIO(b'solid x\nendsolid x\n'), file_type='stl', force='mesh')
    try:
        os.nice(NICE)
    except OSError:
        pass
    memory = int(job.get('memory', MEMORY_BYTES))
    _limit(job['src'], int(job['seconds']), memory)
    try:
        answer = decompose(job)
    except MemoryError:
        answer = {'error': f'it needed more than {memory / 2 ** 30:.2g} GiB'}
    except Exception as exc:  # noqa: B902 (any failure of an untrusted file is its answer)
        answer = {'error': f'{type(exc).__name__}: {str(exc)[:300]}'}
    sys.stdout.write(json.dumps(answer) + '\n')
    sys.stdout.flush()


if __name__ == '__main__':
    main()
