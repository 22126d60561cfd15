"""
Concave collision meshes split into convex parts, which MuJoCo collides as they are.

MuJoCo collides a mesh as its convex hull; Gazebo collides it as its triangles. A tray, a bin,
a table, a shelf or a mug as one collision mesh is then a solid block here (a box dropped into
a tray rests on an invisible lid at its rim). :func:`split_geoms` gives each such collision
geom convex parts that follow the mesh (:mod:`.decompose_worker` says how they are made: the
mesh's separate shells first, each as its own hull, then CoACD for a shell its hull would
fill with empty space), and keeps the geom itself as what is drawn and what weighs: its mass
and inertia are those they were, the parts collide and weigh nothing.

The work runs in a child process per mesh (two at a time), off the stepping thread, bounded in
wall time (:data:`SECONDS`), CPU time and memory; while it runs, :func:`running` names it
(/diagnostics shows it). A mesh that fails (its budget, a broken file) stays its hull, with a
warning naming it, for the rest of this process. Results are kept by the mesh's content and the
settings: in this process, and in the mesh cache folder's ``decomposed`` folder
(:func:`.meshes.cache_dir`), so a second spawn, or the next node, does not redo it.
:func:`configure` turns it off (hulls, as MuJoCo makes them) or sets the quality (the node's
``mesh_decomposition`` parameters).
"""

from concurrent.futures import ThreadPoolExecutor
import json
import logging
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from typing import Optional, Sequence

import mujoco

from . import asset_store, meshes
from ..base.errors import InvalidArgumentError

log = logging.getLogger(__name__)

#: CoACD's concavity threshold (a fraction of a shell's size): lower follows the mesh closer
#: with more parts (a tray: 0.05 gives 9-14 parts, 0.1 gives 5).
THRESHOLD = 0.05
#: A shell that fills at least this share of its hull's volume stays whole (its hull is close
#: to it: a lobed sphere fills 0.85); one that fills less is decomposed (a tray fills 0.38 of
#: its hull, a torus 0.55, a washer 0.75, a table's top on its legs 0.07).
FILL = 0.8
#: What is decomposed: ``objects`` (meshes spawned by URI, MJCF meshes a model marks, and the
#: collision meshes of URDF models that do not move (no joint but a floating root): trays,
#: tables, shelves, bins); ``all`` (every URDF collision mesh too, robots' links included);
#: ``none`` (every mesh collides as its hull, as MuJoCo makes it). Robots are not by default:
#: of example-robot-data's 256 collision meshes, 81 fill less than 0.6 of their hull and 81
#: more are several shells, so a humanoid's first spawn would take a minute or more, where
#: MuJoCo's users (and its menagerie's arms) collide links as hulls.
MODES = ('objects', 'all', 'none')
#: The most convex parts one mesh becomes (each a geom MuJoCo collides).
MAX_PARTS = 64
#: Wall time one mesh may take (then it stays its hull); its child has as much CPU time, and
#: this much address space (a 105,000-face tray's decomposition peaked at a fraction of it).
#: A tray of 105,000 faces takes 12-17 s on a 2-core machine, a washer of 100,000 20 s; an
#: open, patchy 200,000-face sphere 21-60 s (under load): past the budget, a hull.
SECONDS = 30.0
MEMORY_BYTES = 4 << 30
#: The most bytes the decomposition cache folder keeps, least recently used out first.
CACHE_BYTES = 512 << 20
#: Geoms the parts are put in (hidden in MuJoCo's renderer and the viewer, as URDF collisions).
PART_GROUP = 3
#: The most vertices a mesh's collision hull keeps where its file sets none (MuJoCo's
#: ``maxhullvert``: qhull stops after that many, adding the farthest first, so the hull is a
#: little inside the full one). A mesh whose hull is smaller is untouched. Hulls of a mesh whose
#: every vertex lies on it (a sphere, a dome, a scan of a convex part) are where the time goes:
#: MuJoCo compiled a 200,000-face sphere's in 1.8 s, bounded to 4096 vertices in 0.6 s, and its
#: surface then lies at most 0.04 mm inside (a 0.1 m sphere: the gap between 4096 points).
HULL_VERTICES = 4096
# Of what a decomposition makes: a change invalidates the cache (2: open convex patches whole;
# 3: and those rounding folds, their vertices on their hull).
_VERSION = 3
_WORKER = Path(__file__).with_name('decompose_worker.py')

_settings = {'mode': 'objects', 'threshold': THRESHOLD}
_lock = threading.Lock()
_done: dict = {}  # (digest, settings) -> tuple of part files, or () for "stays whole"
_running: dict = {}  # label -> wall time started
_runs = [0]
_pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix='decompose')


def configure(mode: str = 'objects', threshold: float = THRESHOLD) -> None:
    """Set what is decomposed (:data:`MODES`) and CoACD's concavity threshold (process-wide)."""
    if mode not in MODES:
        raise InvalidArgumentError(f'mesh_decomposition must be one of {", ".join(MODES)}, '
                                   f'got {mode!r}')
    if not 0.0 < float(threshold) <= 1.0:
        raise InvalidArgumentError(f'the decomposition threshold must be in (0, 1], got '
                                   f'{threshold}')
    _settings.update(mode=mode, threshold=float(threshold))


def mode() -> str:
    return _settings['mode']


def runs() -> int:
    """Return how many meshes this process has decomposed (child processes started)."""
    return _runs[0]


def running() -> list:
    """Return (label, seconds so far) of each mesh being decomposed now."""
    now = time.monotonic()
    with _lock:
        return [(label, now - start) for label, start in _running.items()]


def _folder() -> Path:
    base = meshes.cache_dir()
    folder = (base / 'decomposed') if base is not None \
        else Path(asset_store.store().folder) / 'decomposed'
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    return folder


def _key(max_parts: int = MAX_PARTS) -> str:
    return f't{_settings["threshold"]:g}_f{FILL:g}_p{max_parts}_v{_VERSION}'


def parts(path: str, label: str, max_parts: int = MAX_PARTS) -> tuple:
    """
    Return the part files of the mesh at `path` (a checked copy), or () to keep it whole.

    `label` names it in log lines, warnings and /diagnostics (the file the model names);
    `max_parts` bounds the parts it becomes (SDF's ``<max_convex_hulls>``; at most
    :data:`MAX_PARTS`).
    """
    max_parts = max(1, min(int(max_parts), MAX_PARTS))
    try:
        digest = asset_store.store().digest(path)  # read once per file, then remembered
    except OSError:
        return ()
    key = (digest, _key(max_parts))
    with _lock:
        known = _done.get(key)
    # Parts this process made may have gone since: the cache folder pruned, moved elsewhere.
    if known is not None and all(os.path.isfile(f) for f in known):
        return known
    folder = _folder() / f'{digest}_{key[1]}'
    found = _read(folder)
    if found is None:
        found = () if _too_few_faces(path) else _run(path, label, folder, max_parts)
    with _lock:
        if known is not None and _done.get(key) is known:
            del _done[key]  # stale: what was found now replaces it
        return _done.setdefault(key, found)


def _too_few_faces(path: str) -> bool:
    """Whether a mesh has no inside (under 4 faces): MuJoCo takes it whole or refuses it."""
    try:
        with open(path, 'rb') as f:
            faces = asset_store.mesh_faces(Path(path).suffix.lower(), f.read())
    except OSError:
        return True
    return faces is not None and faces < 4


def _read(folder: Path) -> Optional[tuple]:
    """Return what the cache holds for a mesh (its parts, or () for whole), or None."""
    try:
        record = json.loads((folder / 'parts.json').read_text())
        files = tuple(str(folder / name) for name in record['parts'])
        if not all(os.path.isfile(f) for f in files):
            return None
        os.utime(folder)  # recently used: pruned last
        return files
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _run(path: str, label: str, folder: Path, max_parts: int = MAX_PARTS) -> tuple:
    """Decompose in a child process; record the answer in `folder`; a failure keeps it whole."""
    tmp = Path(tempfile.mkdtemp(prefix='part', dir=folder.parent))
    job = {'src': path, 'out': str(tmp), 'threshold': _settings['threshold'], 'fill': FILL,
           'max_parts': max_parts, 'seconds': int(SECONDS), 'memory': MEMORY_BYTES}
    with _lock:
        _running[label] = start = time.monotonic()
        _runs[0] += 1
    log.info('decomposing the collision mesh %s into convex parts (once: it is cached)', label)
    try:
        proc = subprocess.run([sys.executable, str(_WORKER)], input=json.dumps(job) + '\n',
                              capture_output=True, text=True, timeout=SECONDS,
                              env={**os.environ, 'OMP_NUM_THREADS': '1'})
        answer = json.loads(proc.stdout.strip().splitlines()[-1]) if proc.stdout.strip() \
            else {'error': f'its process ended with status {proc.returncode}'}
    except subprocess.TimeoutExpired:
        answer = {'error': f'it took more than {SECONDS:g} s'}
    except (OSError, ValueError) as exc:
        answer = {'error': str(exc)}
    finally:
        with _lock:
            _running.pop(label, None)
    took = time.monotonic() - start
    if 'error' in answer:  # remembered by this process only: a busy machine's timeout
        log.warning('the collision mesh %s could not be decomposed into convex parts (%s): it '
                    'collides as its convex hull', label, answer['error'])
        shutil.rmtree(tmp, ignore_errors=True)  # is not the next node's
        return ()
    names = answer.get('parts', [])
    if names:
        log.info('the collision mesh %s collides as %d convex parts (%d shells; %.1f s)',
                 label, len(names), answer.get('shells', 1), took)
    try:
        (tmp / 'parts.json').write_text(json.dumps({'parts': names, 'answer': answer}))
        shutil.rmtree(folder, ignore_errors=True)
        os.replace(tmp, folder)
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)
        return ()
    prune(folder.parent)
    return tuple(str(folder / name) for name in names)


def _resolved(spec: mujoco.MjSpec, file: str) -> str:
    """Return where a mesh file is: as given when absolute, else as MuJoCo finds it."""
    if os.path.isabs(file):
        return file
    return os.path.join(spec.modelfiledir or '', spec.meshdir or '', file)


def bound_hulls(spec: mujoco.MjSpec) -> None:
    """Keep at most :data:`HULL_VERTICES` in each mesh's hull whose file sets no bound."""
    for mesh in spec.meshes:
        if mesh.maxhullvert < 0:
            mesh.maxhullvert = HULL_VERTICES


def forget() -> None:
    """Forget what this process decomposed: the next spawn reads the disk cache again."""
    with _lock:
        _done.clear()


def prune(root: Path, limit: int = CACHE_BYTES) -> None:
    """Keep the decomposition cache under `limit` bytes, the least recently used out first."""
    try:
        entries = []
        for d in root.iterdir():
            if d.is_dir() and (d / 'parts.json').exists():
                size = sum(f.stat().st_size for f in d.iterdir())
                entries.append((d.stat().st_mtime, size, d))
    except OSError:
        return
    meshes.drop_oldest(entries, limit, lambda d: shutil.rmtree(d, ignore_errors=True))


def split_geoms(spec: mujoco.MjSpec, labels: dict, only: Optional[Sequence[str]] = None,
                collisions: Optional[dict] = None, max_parts: Optional[dict] = None) -> int:
    """
    Give the spec's concave collision meshes convex parts; return how many were split.

    Each colliding mesh geom (of the meshes named in `only`, when given) whose mesh file
    decomposes gets one geom per part beside it, with its placement, contact settings and
    name (``<name>_part<i>``); it keeps its mass and looks, and collides no more.

    :param labels: mesh file (as the spec names it) -> the name the model gave it.
    :param collisions: geom name -> Gazebo's collision name; the parts take their geom's.
    :param max_parts: mesh name -> the most parts it becomes (SDF's ``<max_convex_hulls>``).
    """
    if mode() == 'none':
        return 0
    todo = []
    for body in spec.bodies:
        for geom in body.geoms:
            if geom.type != mujoco.mjtGeom.mjGEOM_MESH or not (geom.contype or geom.conaffinity):
                continue
            mesh = spec.mesh(geom.meshname)
            if mesh is None or not mesh.file or (only is not None and mesh.name not in only):
                continue
            todo.append((body, geom, mesh))
    bound = max_parts or {}
    where = {(m.file, bound.get(m.name, MAX_PARTS)): _resolved(spec, m.file) for _, _, m in todo}
    jobs = sorted(where)
    found = dict(zip(jobs, _pool.map(
        lambda j: parts(where[j], labels.get(j[0], Path(j[0]).name), j[1]), jobs)))
    split = 0
    for body, geom, mesh in todo:
        pieces = found.get((mesh.file, bound.get(mesh.name, MAX_PARTS)))
        if not pieces:
            continue
        most = bound.get(mesh.name, MAX_PARTS)
        for i, file in enumerate(pieces):
            name = f'{mesh.name}_part{i}' if most == MAX_PARTS else f'{mesh.name}_h{most}_part{i}'
            if spec.mesh(name) is None:
                spec.add_mesh(name=name, file=file, scale=list(mesh.scale),
                              inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL)
            part = body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name,
                                 pos=list(geom.pos), quat=list(geom.quat), mass=0.0,
                                 group=PART_GROUP)
            part.alt = geom.alt  # an MJCF euler, axisangle, ... as given
            for attr in ('contype', 'conaffinity', 'condim', 'priority', 'friction', 'solmix',
                         'solref', 'solimp', 'margin', 'gap', 'rgba'):
                setattr(part, attr, getattr(geom, attr))
            if geom.name:
                part.name = f'{geom.name}_part{i}'
                if collisions is not None and geom.name in collisions:
                    collisions[part.name] = collisions[geom.name]
        geom.contype = geom.conaffinity = 0
        split += 1
    return split
