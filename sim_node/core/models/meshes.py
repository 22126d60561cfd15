"""
Meshes MuJoCo cannot read as they are, converted to binary STL in child processes.

ROS description packages ship Collada (``.dae``, ``.DAE``) visuals, ASCII STL, and meshes with
more faces than MuJoCo's STL decoder takes (200,000). :func:`convert` hands such files (their
checked copies in the :class:`~.asset_store.AssetStore`) to :mod:`.mesh_worker` processes, which
load them with trimesh and pycollada, keep Collada's ``<unit>``, decimate what is over the
limit with fast-simplification, and write binary STL. They run as children because the files
are untrusted and the libraries are pure Python: a child limits its own memory, CPU time, writes
and file opens, and the node's threads never wait for its GIL.

Two workers are kept running once a URDF is read (:func:`warm`), so a robot's meshes convert
two at a time without paying for a Python start each; they leave after a minute without work.
Results are kept by the source's content: in this process, and in a cache folder
(``$SIM_MESH_CACHE``, else ``$XDG_CACHE_HOME/sim/converted``, ``~/.cache/sim/converted``; empty:
none) so that a robot converted once converts nothing again, in this node or the next. The
cache keeps at most :data:`CACHE_BYTES`, oldest first out.
"""

from dataclasses import dataclass
import json
import os
from pathlib import Path
import queue
import subprocess
import sys
import threading
import time
from typing import Optional, Sequence

from . import asset_store
from ..base.errors import UnsupportedAssetsError

#: The most faces MuJoCo's STL decoder reads; a mesh with more is decimated to this.
MUJOCO_MAX_FACES = 200_000
#: Suffixes converted whatever their content (MuJoCo reads STL, OBJ and MSH itself).
#: Mesh kinds MuJoCo cannot read, converted to OBJ before it sees them.
CONVERTED_SUFFIXES = ('.dae', '.ply', '.glb', '.gltf', '.off')
#: Wall time one file may take to convert (each worker also limits its own CPU time).
FILE_TIMEOUT_SEC = 120.0
#: How many workers convert at once, and how long an idle one stays.
MAX_WORKERS = 2
IDLE_SEC = 60.0
#: Most bytes the conversion cache keeps, and most file identities it remembers.
CACHE_BYTES = 2 << 30
MAX_SOURCES = 100_000
_WORKER = Path(__file__).with_name('mesh_worker.py')
_VERSION = 3  # of what a conversion makes: a change invalidates the cache

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
_done: dict = {}  # (source digest, max faces) -> Converted
_sources: dict = {}  # file identity -> content digest, as the cache folder records it


def needs_conversion(name: str, stored: asset_store.StoredFile, max_faces: int = MUJOCO_MAX_FACES
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


def cache_dir() -> Optional[Path]:
    """Return the conversion cache folder (made if missing), or None when it is off."""
    given = os.environ.get('SIM_MESH_CACHE')
    if given is not None:
        folder = Path(given) if given else None
    else:
        base = os.environ.get('XDG_CACHE_HOME') or str(Path.home() / '.cache')
        folder = Path(base) / 'sim' / 'converted'
    if folder is None:
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    except OSError:
        return None
    return folder


def warm() -> None:
    """Start the conversion workers now, so that a URDF's meshes find them running."""
    _POOL.start()


def convert(items: Sequence[tuple], max_faces: int = MUJOCO_MAX_FACES) -> list:
    """
    Convert ``(value, stored)`` pairs (the name the model gives, the checked copy) to STL.

    Returns one :class:`Converted` per item, in order.

    :raises UnsupportedAssetsError: a file that cannot be converted, naming it and why.
    """
    out: list = [None] * len(items)
    todo, first = [], {}  # one job per distinct content: a mesh many links use is one file
    folder = cache_dir()
    # conversions are named by content: a mesh many files (or runs) have is converted once
    digests = [None if stored.converted else asset_store.store().digest(stored.path)
               for _, stored in items]
    for k, (value, stored) in enumerate(items):
        if stored.converted is not None:
            out[k] = stored.converted
            continue
        digest = digests[k]
        if folder is not None and stored.source is not None:
            _remember_source(folder, stored.source, digest)
        key = (digest, max_faces)
        with _lock:
            found = _done.get(key)
        if found is None and folder is not None:
            found = _cached(folder, digest, max_faces)
        if found is not None:
            out[k] = found
            continue
        if key in first:
            continue
        first[key] = k
        kind = Path(value).suffix.lower().lstrip('.') or 'stl'
        if kind == 'dae':
            with open(stored.path, 'rb') as f:
                head = f.read(1 << 16)
            if b'<!DOCTYPE' in head or b'<!ENTITY' in head:
                raise UnsupportedAssetsError(ERR_XML.format(value=value))
        target = (str(folder / f'{digest}_{max_faces}_v{_VERSION}.stl') if folder is not None
                  else f'{stored.path}.{max_faces}.stl')
        todo.append((k, value, key, {'src': stored.path, 'kind': kind, 'out': target,
                                     'max_faces': max_faces}))
    results = _POOL.run([t[3] for t in todo]) if todo else []
    _converted[0] += len(todo)
    for (k, value, key, job), result in zip(todo, results):
        if 'error' in result:
            if 'No module named' in result['error'] and job['kind'] == 'dae':
                raise UnsupportedAssetsError(ERR_DEPENDENCY.format(value=value))
            raise UnsupportedAssetsError(ERR_CONVERT.format(value=value, why=result['error']))
        converted = Converted(job['out'], result['faces_in'], result['faces'],
                              tuple(result['rgba']) if result.get('rgba') else None)
        if folder is not None:
            _remember(folder, job['out'], converted)
        with _lock:
            _done[key] = converted
        out[k] = converted
    for k in range(len(items)):
        if out[k] is None:
            out[k] = out[first[(digests[k], max_faces)]]
    return out


def converted_before(source: tuple, max_faces: int = MUJOCO_MAX_FACES) -> Optional[Converted]:
    """
    Return the cached conversion of the file with identity `source`, or None.

    Found by the file's identity, which the cache remembers beside the content digest each
    conversion is named by: a new process need not read and hash a robot's Collada files again
    (most of a first spawn's reading: 60 of icub's 97 ms, 120 of romeo's 170). A file changed
    since has another identity (its size or modification time), so it is read and converted.
    """
    folder = cache_dir()
    if folder is None:
        return None
    with _lock:
        digest = _sources.get(source)
    if digest is None:  # first in this process: the cache folder's record
        try:
            digest = (folder / _source_name(source)).read_text()
        except (OSError, UnicodeDecodeError):
            return None
        if len(digest) != 32 or not all(c in '0123456789abcdef' for c in digest):
            return None
        with _lock:
            _sources[source] = digest
    key = (digest, max_faces)
    with _lock:
        found = _done.get(key)
    if found is None:  # first in this process (the cache marks it used, which MuJoCo's own
        found = _cached(folder, digest, max_faces)  # mesh cache takes for a changed file)
        if found is not None:
            with _lock:
                found = _done.setdefault(key, found)
    return found


def _source_name(source: tuple) -> str:
    return f'{asset_store.identity_name(source)}_v{_VERSION}.source'


def _remember_source(folder: Path, source: tuple, digest: str) -> None:
    """Remember the content digest of the file with identity `source` (see converted_before)."""
    with _lock:
        if _sources.get(source) == digest:
            return
        _sources[source] = digest
    path = folder / _source_name(source)
    if path.exists():
        return
    tmp = path.with_suffix(f'.part{threading.get_ident()}')
    try:
        tmp.write_text(digest)
        os.replace(tmp, path)
    except OSError:
        pass


def forget(paths: Sequence[str]) -> None:
    """Forget conversions written to files that are gone (see ``AssetStore.settle``)."""
    gone = set(paths)
    with _lock:
        for key in [k for k, c in _done.items() if c.path in gone]:
            del _done[key]


def _cached(folder: Path, digest: str, max_faces: int) -> Optional[Converted]:
    """Return a conversion the cache folder holds (its STL and what was measured), or None."""
    path = folder / f'{digest}_{max_faces}_v{_VERSION}.stl'
    try:
        meta = json.loads(path.with_suffix('.json').read_text())
        if not path.is_file():
            return None
        os.utime(path)  # recently used: pruned last
        return Converted(str(path), int(meta['faces_in']), int(meta['faces']),
                         tuple(meta['rgba']) if meta.get('rgba') else None)
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _remember(folder: Path, path: str, converted: Converted) -> None:
    meta = Path(path).with_suffix('.json')
    tmp = meta.with_suffix('.json.part')
    try:
        tmp.write_text(json.dumps({'faces_in': converted.faces_in, 'faces': converted.faces,
                                   'rgba': converted.rgba}))
        os.replace(tmp, meta)
    except OSError:
        return
    _prune(folder)


def drop_oldest(entries: list, limit: int, drop) -> None:
    """Call ``drop(item)`` on (time used, bytes, item) entries, oldest first, until <= `limit`."""
    total = sum(size for _, size, _ in entries)
    for _, size, item in sorted(entries, key=lambda e: e[:2]):
        if total <= limit:
            break
        drop(item)
        total -= size


def _prune(folder: Path, limit: int = CACHE_BYTES) -> None:
    """Keep the cache under `limit` bytes, the least recently used out first."""
    try:
        files = [(p.stat().st_mtime, p.stat().st_size, p) for p in folder.glob('*_v*.stl')]
    except OSError:
        return

    def drop(path: Path) -> None:
        for p in (path, path.with_suffix('.json')):
            try:
                p.unlink()
            except OSError:
                pass
    drop_oldest(files, limit, drop)
    try:  # the files' identities (tiny), past a bound the oldest first
        sources = sorted((p.stat().st_mtime, p) for p in folder.glob('*.source'))
    except OSError:
        return
    for _, path in sources[:max(0, len(sources) - MAX_SOURCES)]:
        try:
            path.unlink()
        except OSError:
            pass


class _Worker:
    """One worker process: a JSON line in (a file to convert), a JSON line out."""

    def __init__(self):
        self.proc = subprocess.Popen([sys.executable, str(_WORKER)], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     start_new_session=True, close_fds=True)
        self.used = time.monotonic()

    @property
    def alive(self) -> bool:
        return self.proc.poll() is None

    def convert(self, job: dict) -> dict:
        """Convert one file; on a timeout or a death the worker is gone and says why."""
        self.used = time.monotonic()
        answer: list = []
        reader = threading.Thread(target=lambda: answer.append(self.proc.stdout.readline()),
                                  name='sim-meshes', daemon=True)
        try:
            self.proc.stdin.write(json.dumps(job).encode() + b'\n')
            self.proc.stdin.flush()
        except OSError:
            return {'error': 'its converter stopped'}
        reader.start()
        reader.join(FILE_TIMEOUT_SEC)
        if reader.is_alive() or not answer or not answer[0]:
            self.close(kill=True)
            why = ('it took longer than the time a mesh may take' if reader.is_alive() else
                   'converting it needs more memory or time than a mesh may take')
            return {'error': why}
        self.used = time.monotonic()
        try:
            result = json.loads(answer[0])
            return result if isinstance(result, dict) else {'error': 'its converter failed'}
        except ValueError:
            return {'error': 'its converter failed'}

    def close(self, kill: bool = False) -> None:
        if self.alive:
            if kill:
                self.proc.kill()
            else:
                try:
                    self.proc.stdin.close()
                except OSError:
                    pass
        try:
            self.proc.wait(5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class _Pool:
    """Up to MAX_WORKERS workers, started on demand, leaving after IDLE_SEC without work."""

    def __init__(self):
        self._lock = threading.Lock()
        self._idle: list = []  # workers free to take a file
        self._count = 0  # workers alive, busy or idle
        self._reaper: Optional[threading.Thread] = None

    def start(self) -> None:
        with self._lock:
            missing = MAX_WORKERS - self._count
            self._count += max(missing, 0)
        for _ in range(max(missing, 0)):
            self._give_back(_Worker())
        self._ensure_reaper()

    def run(self, jobs: list) -> list:
        """Convert `jobs` on the workers, as many at once as there are; results in order."""
        if not jobs:
            return []
        results: list = [None] * len(jobs)
        todo: queue.Queue = queue.Queue()
        for k, job in enumerate(jobs):
            todo.put((k, job))

        def drain() -> None:
            worker = self._take()
            try:
                while True:
                    try:
                        k, job = todo.get_nowait()
                    except queue.Empty:
                        return
                    results[k] = worker.convert(job)
                    if not worker.alive:
                        self._lost()
                        worker = self._take()
            finally:
                self._give_back(worker)
        threads = [threading.Thread(target=drain, name='sim-meshes', daemon=True)
                   for _ in range(min(MAX_WORKERS, len(jobs)))]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        return results

    def _take(self) -> _Worker:
        with self._lock:
            while self._idle:
                worker = self._idle.pop()
                if worker.alive:
                    return worker
                self._count -= 1
            self._count += 1
        self._ensure_reaper()
        return _Worker()

    def _give_back(self, worker: _Worker) -> None:
        with self._lock:
            if worker.alive:
                self._idle.append(worker)
            else:
                self._count -= 1

    def _lost(self) -> None:
        with self._lock:
            self._count -= 1

    def _ensure_reaper(self) -> None:
        with self._lock:
            if self._reaper is not None and self._reaper.is_alive():
                return
            self._reaper = threading.Thread(target=self._reap, name='sim-meshes-idle',
                                            daemon=True)
            self._reaper.start()

    def _reap(self) -> None:
        """Close workers idle for IDLE_SEC; end when none is left."""
        while True:
            time.sleep(min(IDLE_SEC / 4, 5.0))
            now = time.monotonic()
            with self._lock:
                stale = [w for w in self._idle if now - w.used > IDLE_SEC or not w.alive]
                self._idle = [w for w in self._idle if w not in stale]
                self._count -= len(stale)
                empty = self._count == 0
            for w in stale:
                w.close()
            if empty:
                return


_POOL = _Pool()
_converted = [0]  # files the workers converted in this process


def files_converted() -> int:
    """Return how many files the converter workers converted in this process (cache hits not)."""
    return _converted[0]
