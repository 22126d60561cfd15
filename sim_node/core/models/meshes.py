"""
Meshes MuJoCo cannot read as they are, converted to binary STL in child processes.

ROS description packages ship Collada (``.dae``, ``.DAE``) visuals, ASCII STL, and meshes with
more faces than MuJoCo's STL decoder takes (200,000). :func:`convert` hands such files (their
checked copies in the :class:`~.assets.AssetStore`) to :mod:`.mesh_worker` processes, which
load them with trimesh and pycollada, keep Collada's ``<unit>``, decimate what is over the
limit with fast-simplification, and write binary STL into the store. They run as children
because the files are untrusted and the libraries are pure Python: a child limits its own
memory, CPU time, writes and file opens, and the node's threads never wait for its GIL. Results
are kept by content: a second spawn of the same robot converts nothing.
"""

from dataclasses import dataclass
import json
import os
from pathlib import Path
import subprocess
import sys
import threading
from typing import Optional, Sequence

from . import assets
from ..errors import UnsupportedAssetsError

#: The most faces MuJoCo's STL decoder reads; a mesh with more is decimated to this.
MUJOCO_MAX_FACES = 200_000
#: Suffixes converted whatever their content (MuJoCo reads STL, OBJ and MSH itself).
CONVERTED_SUFFIXES = ('.dae', '.ply', '.glb', '.gltf', '.off')
#: Wall time one worker gets for its files (each also limits its own CPU time).
WORKER_TIMEOUT_SEC = 180.0
#: How many workers convert at once (a robot's files are shared out among them).
MAX_WORKERS = 2
_WORKER = Path(__file__).with_name('mesh_worker.py')

ERR_CONVERT = ('the mesh {value!r} could not be converted ({why}); check that it opens in a '
               'mesh viewer, or export it as binary STL')
ERR_XML = ('the mesh {value!r} declares a DOCTYPE or entities: Collada files may not (remove '
           'the declaration)')
ERR_DEPENDENCY = ('the mesh {value!r} is Collada, which needs the pycollada package: pip install '
                  'pycollada')


@dataclass(frozen=True)
class Converted:
    """A mesh as MuJoCo reads it: its path, faces before and after, its own colour if any."""

    path: str
    faces_in: int
    faces: int
    rgba: Optional[tuple] = None

    @property
    def decimated(self) -> bool:
        return self.faces < self.faces_in


_lock = threading.Lock()
_done: dict = {}  # (source copy, max faces) -> Converted


def needs_conversion(name: str, stored: assets.StoredFile, max_faces: int = MUJOCO_MAX_FACES
                     ) -> bool:
    """Whether MuJoCo cannot read this file (its checked copy) as it is."""
    suffix = Path(name).suffix.lower()
    if suffix in CONVERTED_SUFFIXES:
        return True
    if suffix == '.stl' and not _binary_stl(stored.path):
        return True  # ASCII STL: MuJoCo reads binary only
    return suffix in ('.stl', '.obj') and (stored.faces or 0) > max_faces


def _binary_stl(path: str) -> bool:
    size = os.path.getsize(path)
    with open(path, 'rb') as f:
        head = f.read(84)
    return len(head) == 84 and 84 + 50 * int.from_bytes(head[80:84], 'little') == size


def convert(items: Sequence[tuple], max_faces: int = MUJOCO_MAX_FACES) -> list:
    """
    Convert ``(value, stored)`` pairs (the name the model gives, the checked copy) to STL.

    Returns one :class:`Converted` per item, in order.

    :raises UnsupportedAssetsError: a file that cannot be converted, naming it and why.
    """
    out: list = [None] * len(items)
    todo, first = [], {}  # one job per distinct copy: a mesh used by many links is one file
    for k, (value, stored) in enumerate(items):
        with _lock:
            found = _done.get((stored.path, max_faces))
        if found is not None:
            out[k] = found
            continue
        if stored.path in first:
            continue
        first[stored.path] = k
        kind = Path(value).suffix.lower().lstrip('.') or 'stl'
        if kind == 'dae':
            with open(stored.path, 'rb') as f:
                head = f.read(1 << 16)
            if b'<!DOCTYPE' in head or b'<!ENTITY' in head:
                raise UnsupportedAssetsError(ERR_XML.format(value=value))
        target = f'{stored.path}.{max_faces}.stl'
        todo.append((k, value, {'src': stored.path, 'kind': kind, 'out': target,
                                'max_faces': max_faces}))
    if todo:
        _run(todo, out, max_faces)
    for k, (value, stored) in enumerate(items):
        if out[k] is None:
            out[k] = out[first[stored.path]]
    return out


def forget(paths: Sequence[str]) -> None:
    """Forget conversions from or to files that are gone (see ``AssetStore.settle``)."""
    gone = set(paths)
    with _lock:
        for key in [k for k, c in _done.items() if k[0] in gone or c.path in gone]:
            del _done[key]


def _run(todo: list, out: list, max_faces: int) -> None:
    """Share `todo` out among worker processes; fill `out` (raises on the first failure)."""
    n = min(MAX_WORKERS, len(todo), os.cpu_count() or 1)
    shares = [todo[i::n] for i in range(n)]
    procs = [subprocess.Popen([sys.executable, str(_WORKER)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              start_new_session=True, close_fds=True) for _ in shares]
    results = []

    def work(proc: subprocess.Popen, share: list) -> None:
        try:
            text, err = proc.communicate(json.dumps([job for _, _, job in share]).encode(),
                                         timeout=WORKER_TIMEOUT_SEC)
        except subprocess.TimeoutExpired:
            proc.kill()
            text, err = b'', b'it took longer than the time a mesh may take'
        lines = text.decode(errors='replace').splitlines()
        why = err.decode(errors='replace').strip().splitlines()[-1:] or ['it failed']
        for (k, value, job), line in zip(share, lines + [''] * len(share)):
            results.append((k, value, job, _parse(line, why[0])))

    threads = [threading.Thread(target=work, args=pair, name='sim-meshes', daemon=True)
               for pair in zip(procs, shares)]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    for k, value, job, result in sorted(results, key=lambda r: r[0]):
        if 'error' in result:
            if 'No module named' in result['error'] and job['kind'] == 'dae':
                raise UnsupportedAssetsError(ERR_DEPENDENCY.format(value=value))
            raise UnsupportedAssetsError(ERR_CONVERT.format(value=value, why=result['error']))
        converted = Converted(job['out'], result['faces_in'], result['faces'],
                              tuple(result['rgba']) if result.get('rgba') else None)
        with _lock:
            _done[(job['src'], max_faces)] = converted
        out[k] = converted


def _parse(line: str, why: str) -> dict:
    try:
        result = json.loads(line)
        return result if isinstance(result, dict) else {'error': why}
    except ValueError:
        return {'error': why}
