"""
The process's checked copies of model files: a private folder MuJoCo reads, one copy per file.

:class:`AssetStore` keeps what :mod:`.assets` checked, named by the file's identity (path,
device, inode, size, modification time), so a second spawn of the same robot reads and checks
nothing again and MuJoCo's mesh cache serves it; :mod:`.meshes` names its conversions by the
store's identities and digests. Also the header counts the checks use: faces of an STL or OBJ,
pixels of a PNG, read without building anything.
"""

import atexit
from dataclasses import dataclass
import hashlib
import os
from pathlib import Path
import re
import shutil
import struct
import tempfile
import threading
from typing import Optional, Sequence

import mujoco


@dataclass(frozen=True)
class StoredFile:
    """A checked copy of one file: where it is and what was measured of it."""

    path: str
    size: int
    faces: Optional[int]  # meshes (STL, OBJ)
    pixels: Optional[int]  # PNG images
    #: The identity of the file it is a copy of (path, device, inode, size, modification time).
    source: Optional[tuple] = None
    #: Its conversion (a ``meshes.Converted``), when one made in an earlier run is known by
    #: `source`: then nothing was read or copied, and `path` is the file itself.
    converted: Optional[object] = None


_SAFE_NAME = re.compile(r'[^A-Za-z0-9._-]')


def strip_mtllib(data: bytes) -> list:
    """
    Return OBJ text without its ``mtllib`` lines (each emptied, its line break kept), in pieces.

    By plain searches for the word: a multi-line regular expression took 140 ms over a robot's
    58 OBJ files (most of its spawn's reading). The pieces are views of `data`, written one
    after the other, never joined (a copy of the whole text). No line is joined to another,
    so the faces are those of `data`.
    """
    view, parts, start = memoryview(data), [], 0
    i = data.find(b'mtllib')
    while i >= 0:
        line = data.rfind(b'\n', 0, i) + 1
        after = data[i + 6:i + 7]
        if not data[line:i].strip(b' \t') and not (after.isalnum() or after == b'_'):
            end = data.find(b'\n', i)
            parts.append(view[start:line])
            start = len(data) if end < 0 else end
        i = data.find(b'mtllib', i + 6)
    parts.append(view[start:])
    return parts


class AssetStore:
    """
    Checked copies of model files in a private folder, one per file identity; thread-safe.

    One per process (:func:`store`). Files are only ever added: a copy is immutable once
    written, so MuJoCo's own cache of processed meshes (keyed by file) stays right, and the
    same file spawned twice is the same copy. The folder (mode 0700) is removed at exit.
    """

    def __init__(self, folder: Optional[str] = None):
        self._folder = folder
        self._lock = threading.Lock()
        self._by_file: dict = {}  # (real path, dev, inode, size, mtime_ns) -> StoredFile
        self._digests: dict = {}  # copy path -> content digest (see digest)
        self._pending: dict = {}  # path -> models being read or spawned that use it
        self._kept: set = set()  # paths an entity or a world was made with

    def hold(self, path: str) -> None:
        """Count a model being made that uses the copy at `path` (see :meth:`settle`)."""
        with self._lock:
            self._pending[path] = self._pending.get(path, 0) + 1

    def settle(self, paths: Sequence[str], keep: bool) -> list:
        """
        Release `paths` held by a model that was made (`keep`) or refused; refused copies go.

        A copy goes when no model being made holds it and nothing made was made with it: a
        refused spawn leaves no file behind. Returns the paths removed.
        """
        gone = []
        with self._lock:
            for path in paths:
                left = self._pending.get(path, 0) - 1
                if left > 0:
                    self._pending[path] = left
                else:
                    self._pending.pop(path, None)
                if keep:
                    self._kept.add(path)
                elif left <= 0 and path not in self._kept:
                    gone.append(path)
            if gone:
                dead = set(gone)
                self._by_file = {k: v for k, v in self._by_file.items() if v.path not in dead}
                self._digests = {k: v for k, v in self._digests.items() if k not in dead}
        for path in gone:
            try:
                os.unlink(path)
            except OSError:
                pass
        return gone

    def remove(self) -> None:
        """Remove the folder and everything in it (at exit)."""
        with self._lock:
            folder, self._folder = self._folder, None
            self._by_file.clear()
            self._digests.clear()
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)

    @property
    def folder(self) -> str:
        with self._lock:
            if self._folder is None:
                _sweep_dead_folders()
                self._folder = tempfile.mkdtemp(prefix=f'{FOLDER_PREFIX}{os.getpid()}_')
                atexit.register(self.remove)
            return self._folder

    def cached(self, key: tuple) -> Optional[StoredFile]:
        """Return the copy of a file already checked with this identity (None: read it)."""
        with self._lock:
            return self._by_file.get(key)

    def put(self, key: tuple, name: str, data: bytes) -> StoredFile:
        """
        Store `data` (the bytes of the file `name` whose identity is `key`) and return its copy.

        Copies are named by the file's identity (path, device, inode, size, modification time),
        not by their content: hashing every byte took a quarter of reading a robot's 50 MB of
        meshes. A file changed since is another identity, so another copy (MuJoCo's mesh cache
        never serves the old one); what is converted is named by content (:meth:`digest`).

        An OBJ's ``mtllib`` lines are left out of its copy: MuJoCo would open the material
        library beside it (a FIFO put there would block it forever), and draws none of it.
        """
        suffix = Path(name).suffix.lower()
        parts = strip_mtllib(data) if suffix == '.obj' else [data]
        size = sum(len(p) for p in parts)
        base = _SAFE_NAME.sub('_', Path(name).name)[-80:] or 'file'
        path = os.path.join(self.folder, f'{identity_name(key)}_{base}')
        if not os.path.exists(path):
            fd, tmp = tempfile.mkstemp(dir=self.folder)
            with os.fdopen(fd, 'wb') as f:
                f.writelines(parts)  # not joined: one copy of a 5 MB OBJ fewer
            os.replace(tmp, path)  # atomic: MuJoCo never sees half a file
        found = StoredFile(path, size, mesh_faces(suffix, data), image_pixels(data), key)
        with self._lock:  # a reader that read the same file meanwhile gets the same copy
            return self._by_file.setdefault(key, found)

    def digest(self, path: str) -> str:
        """Return the content digest of the copy at `path` (read once; copies never change)."""
        with self._lock:
            found = self._digests.get(path)
        if found is None:
            h = hashlib.blake2b(digest_size=16)
            with open(path, 'rb') as f:
                for chunk in iter(lambda: f.read(1 << 20), b''):
                    h.update(chunk)
            found = h.hexdigest()
            with self._lock:
                self._digests[path] = found
        return found


def identity_name(key: tuple) -> str:
    """Return a file name for a file identity (path, device, inode, size, modification time)."""
    return hashlib.blake2b(repr(key).encode(), digest_size=16).hexdigest()


#: The store's folder is ``<tmp>/sim_assets_<pid>_<random>``.
FOLDER_PREFIX = 'sim_assets_'


def _sweep_dead_folders() -> None:
    """Remove store folders left by processes of ours that are gone (a node killed with -9)."""
    tmp = Path(tempfile.gettempdir())
    for folder in tmp.glob(f'{FOLDER_PREFIX}*_*'):
        pid = folder.name[len(FOLDER_PREFIX):].split('_')[0]
        if not pid.isdigit() or folder.is_symlink() or not folder.is_dir():
            continue
        try:
            if folder.stat().st_uid != os.getuid():
                continue
            os.kill(int(pid), 0)  # alive: its folder stays
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
        except OSError:
            continue


_STORE = AssetStore()


def set_mesh_cache(capacity_mib: int) -> None:
    """Size MuJoCo's process-wide cache of processed meshes (``WorldConfig.mesh_cache_mb``)."""
    mujoco.mj_setCacheCapacity(mujoco.mj_getCache(), int(capacity_mib) * 2 ** 20)


def mesh_cache_bytes() -> int:
    """Return the bytes MuJoCo's process-wide cache of processed meshes holds now."""
    return int(mujoco.mj_getCacheSize(mujoco.mj_getCache()))


def evict_meshes(nbytes: int) -> None:
    """
    Drop the `nbytes` least recently used bytes of MuJoCo's mesh cache.

    The cache is LRU and has no call to drop one entry: its capacity is lowered to evict and
    put back. Called right after a compile of the whole world, which used every live mesh:
    what goes first is what no live entity uses (a world of its own in the same process may
    lose some of its meshes; its next compile processes them again).
    """
    cache = mujoco.mj_getCache()
    capacity = mujoco.mj_getCacheCapacity(cache)
    mujoco.mj_setCacheCapacity(cache, max(0, mesh_cache_bytes() - int(nbytes)))
    mujoco.mj_setCacheCapacity(cache, capacity)


def store() -> AssetStore:
    """Return the process's asset store."""
    return _STORE


def image_pixels(data: bytes) -> Optional[int]:
    """Return the pixel count of a PNG from its header (None: not a PNG)."""
    if data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) >= 24:
        width, height = struct.unpack('>II', data[16:24])
        return width * height
    return None


def mesh_faces(suffix: str, data: bytes) -> Optional[int]:
    """
    Return the number of faces of an STL or OBJ file from its bytes (None: another kind).

    Counted without building the mesh: a binary STL says it in its header; text is counted
    with ``bytes.count`` (C speed; 140k faces in a few milliseconds).
    """
    if suffix == '.stl':
        if len(data) >= 84:
            n = struct.unpack('<I', data[80:84])[0]
            if 84 + 50 * n == len(data):  # binary STL
                return n
        return data.count(b'facet normal')
    if suffix == '.obj':
        return data.count(b'\nf ') + int(data.startswith(b'f '))
    return None
