"""
Concave meshes as people ship them, written here as binary STL: a tray, a table, a ring.

Used by the decomposition tests (test_core_decompose.py, test_node_decompose.py) and by
``make bench-meshes``. Each is one file whose collision, as a convex hull, would be a solid
block: the tray is one closed shell (a floor and four walls), the table five shells (a top and
four legs, touching), the ring one closed shell around a hole.
"""

from pathlib import Path

import numpy as np
from sim_node.core.models.collada_fast import binary_stl

#: The tray: 0.4 m x 0.3 m, walls 0.02 m thick and 0.1 m high, floor 0.02 m thick.
TRAY_SIZE, TRAY_WALL, TRAY_HEIGHT, TRAY_FLOOR = (0.4, 0.3), 0.02, 0.1, 0.02
#: The table: a 1.0 m x 0.6 m top, 0.04 m thick, its underside 0.7 m over the floor.
TABLE_TOP, TABLE_UNDER, TABLE_THICK, TABLE_LEG = (1.0, 0.6), 0.7, 0.04, 0.05


def write_stl(path: Path, triangles: np.ndarray) -> Path:
    """Write triangles (n, 3, 3) as binary STL (the package's own writer); return the path."""
    corners = np.asarray(triangles, dtype=float).reshape(-1, 3)
    faces = np.arange(len(corners)).reshape(-1, 3)
    Path(path).write_bytes(binary_stl(corners, faces))
    return Path(path)


def columns(xs, ys, heights) -> np.ndarray:
    """Return the closed surface of columns on a grid: cell (i, j) rises to heights[i][j]."""
    tris = []

    def quad(a, b, c, d):
        tris.extend([(a, b, c), (a, c, d)])
    nx, ny = len(xs) - 1, len(ys) - 1

    def h(i, j):
        return heights[i][j] if 0 <= i < nx and 0 <= j < ny else 0.0
    for i in range(nx):
        for j in range(ny):
            x0, x1, y0, y1, z = xs[i], xs[i + 1], ys[j], ys[j + 1], heights[i][j]
            quad((x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z))
            quad((x0, y0, 0), (x0, y1, 0), (x1, y1, 0), (x1, y0, 0))
            for (di, dj), (a, b) in {(1, 0): ((x1, y0), (x1, y1)), (-1, 0): ((x0, y1), (x0, y0)),
                                     (0, 1): ((x1, y1), (x0, y1)),
                                     (0, -1): ((x0, y0), (x1, y0))}.items():
                low = h(i + di, j + dj)
                if z > low:
                    quad((*a, low), (*b, low), (*b, z), (*a, z))
    return np.array(tris, dtype=float)


def box(size, centre) -> np.ndarray:
    """Return a closed box's triangles (outward), `size` full extents, at `centre`."""
    sx, sy, sz = np.asarray(size, float) / 2
    tris = columns([-sx, sx], [-sy, sy], [[2 * sz]])
    return tris + np.asarray(centre, float) - [0, 0, sz]


def tray(path: Path, cells: int = 1) -> Path:
    """
    Write an open box, one closed shell: its floor's top is TRAY_FLOOR over its base.

    `cells`: its floor's top and base cut into cells x cells squares (4 faces each), as a
    scanned or finely exported tray is (158: about 100,000 faces).
    """
    (lx, ly), w = TRAY_SIZE, TRAY_WALL
    xs = [-lx / 2, *np.linspace(-lx / 2 + w, lx / 2 - w, cells + 1), lx / 2]
    ys = [-ly / 2, *np.linspace(-ly / 2 + w, ly / 2 - w, cells + 1), ly / 2]
    n = cells + 2
    rim = TRAY_HEIGHT
    heights = [[rim if i in (0, n - 1) or j in (0, n - 1) else TRAY_FLOOR for j in range(n)]
               for i in range(n)]
    return write_stl(path, columns(xs, ys, heights))


def slab(path: Path, cells: int) -> Path:
    """Write a convex block, 0.4 m x 0.3 m x 0.1 m, its top and base cut in cells x cells."""
    xs, ys = np.linspace(-0.2, 0.2, cells + 1), np.linspace(-0.15, 0.15, cells + 1)
    return write_stl(path, columns(xs, ys, [[0.1] * cells for _ in range(cells)]))


def table(path: Path) -> Path:
    """Write a top on four legs in one file (five closed shells), standing on its origin."""
    (lx, ly), leg = TABLE_TOP, TABLE_LEG
    parts = [box((lx, ly, TABLE_THICK), (0, 0, TABLE_UNDER + TABLE_THICK / 2))]
    for x in (-lx / 2 + leg, lx / 2 - leg):
        for y in (-ly / 2 + leg, ly / 2 - leg):
            parts.append(box((leg, leg, TABLE_UNDER), (x, y, TABLE_UNDER / 2)))
    return write_stl(path, np.concatenate(parts))


def ring(path: Path, segments: int = 48) -> Path:
    """Write a washer (outer radius 0.2 m, inner 0.1 m, 0.05 m high): one closed shell."""
    t = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ro, ri, hz = 0.2, 0.1, 0.05
    tris = []
    for a, b in zip(t, np.roll(t, -1)):
        oa, ob = (ro * np.cos(a), ro * np.sin(a)), (ro * np.cos(b), ro * np.sin(b))
        ia, ib = (ri * np.cos(a), ri * np.sin(a)), (ri * np.cos(b), ri * np.sin(b))
        for q in (((*ia, hz), (*oa, hz), (*ob, hz), (*ib, hz)),  # top
                  ((*ia, 0), (*ib, 0), (*ob, 0), (*oa, 0)),  # bottom
                  ((*oa, 0), (*ob, 0), (*ob, hz), (*oa, hz)),  # outside
                  ((*ia, 0), (*ia, hz), (*ib, hz), (*ib, 0))):  # inside
            tris.extend([(q[0], q[1], q[2]), (q[0], q[2], q[3])])
    return write_stl(path, np.array(tris, dtype=float))


def bumpy(path: Path, subdivisions: int = 6) -> Path:
    """Write a sphere with three deep lobes (20 * 4^n faces): concave, most of its hull."""
    v, f = _icosphere(subdivisions)
    v = v * (1 + 0.25 * np.sin(3 * np.arctan2(v[:, 1], v[:, 0])))[:, None]
    return write_stl(path, v[f])


def sphere(path: Path, radius: float = 0.1, subdivisions: int = 6) -> Path:
    """Write a sphere of 20 * 4^n faces, every vertex on its hull (10 * 4^n + 2 of them)."""
    v, f = _icosphere(subdivisions)
    return write_stl(path, radius * v[f])


def patch(path: Path, radius: float = 0.1, subdivisions: int = 6, share: float = 0.4,
          noise: float = 0.0, dent: float = 0.0) -> Path:
    """
    Write the first `share` of a sphere's faces: an open, ragged patch, convex everywhere.

    :param noise: each vertex moved along its radius by up to this fraction (a decimation's
        rounding folds edges inwards: the patch is convex only within it).
    :param dent: the tenth of the patch around its middle pushed in by this fraction of the
        radius (a dent: no longer convex).
    """
    v, f = _icosphere(subdivisions)
    f = f[:int(share * len(f))]
    scale = 1 + noise * np.random.default_rng(0).uniform(-1, 1, len(v))
    if dent:
        used = np.unique(f)
        middle = v[used].mean(axis=0)
        along = v @ (middle / np.linalg.norm(middle))
        scale[along > np.quantile(along[used], 0.9)] -= dent
    return write_stl(path, (radius * scale[:, None] * v)[f])


def _icosphere(n: int):
    p = (1 + 5 ** 0.5) / 2
    v = np.array([(-1, p, 0), (1, p, 0), (-1, -p, 0), (1, -p, 0), (0, -1, p), (0, 1, p),
                  (0, -1, -p), (0, 1, -p), (p, 0, -1), (p, 0, 1), (-p, 0, -1), (-p, 0, 1)],
                 float)
    f = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
                  (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
                  (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
                  (8, 6, 7), (9, 8, 1)])
    v /= np.linalg.norm(v, axis=1)[:, None]
    for _ in range(n):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = (v[unique[:, 0]] + v[unique[:, 1]]) / 2
        mid /= np.linalg.norm(mid, axis=1)[:, None]
        m = inverse.reshape(3, -1).T + len(v)
        v = np.concatenate([v, mid])
        f = np.concatenate([np.stack([f[:, 0], m[:, 0], m[:, 2]], 1),
                            np.stack([f[:, 1], m[:, 1], m[:, 0]], 1),
                            np.stack([f[:, 2], m[:, 2], m[:, 1]], 1),
                            np.stack([m[:, 0], m[:, 1], m[:, 2]], 1)])
    return v, f
