"""
xacro description files (``.urdf.xacro``, ``.xacro``), expanded to URDF in an isolated process.

A description file is code: xacro evaluates the expressions in it, and its sandbox can be
escaped. So xacro never runs in the node: :func:`expand` runs it in a child process
(:mod:`.xacro_worker`) with an empty environment, limits on memory, CPU time and wall time, no
writes, and a check of every file it opens against the readable folders; the text it returns is
bounded. ``xacro`` (the ROS 2 release on the package index) must be installed where the node's
Python finds it.

An expansion is kept (:data:`CACHE_ENTRIES`, :data:`CACHE_BYTES`, least recently used out
first) with the files it read, as the child names them; the same request is answered from it
while every one of those files holds what it held (their contents' digests), so a robot spawned
again does not start xacro again. A folder that appears later (a package ``$(find)`` would now
find first) is not noticed: the files read are.
"""

from collections import OrderedDict
import hashlib
import importlib.util
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
from typing import Mapping, Optional, Sequence

from ..base.errors import FeatureUnsupportedError, ResourceParseError

#: Suffixes of description files xacro expands.
XACRO_SUFFIXES = ('.xacro',)
#: Wall time a description may take to expand, and the most text it may give. The 25 xacro
#: robots of the ROS corpus take 0.85 s at most here; a macro that calls itself ten times, ten
#: deep, would take hours.
TIMEOUT_SEC = 5.0
MAX_OUTPUT_BYTES = 20_000_000
#: The xacro process's own limits: address space and CPU time (it is killed past the latter).
MEMORY_BYTES = 512 << 20
CPU_SECONDS = 5
_WORKER = Path(__file__).with_name('xacro_worker.py')
#: Expansions this process keeps: how many, and the most URDF text in all.
CACHE_ENTRIES = 32
CACHE_BYTES = 64 << 20

_cache: OrderedDict = OrderedDict()  # digest of the request -> (URDF, ((file, digest), ...))
_cache_lock = threading.Lock()
_runs = [0]

ERR_NO_XACRO = ('{what} is a xacro file, and the xacro package is not installed: pip install '
                'xacro (or, on a ROS machine, apt install ros-jazzy-xacro), or spawn the URDF '
                'that xacro makes of it')
ERR_FAILED = 'xacro could not expand {what}: {why}'
ERR_TIME = 'xacro took longer than {limit:g} s to expand {what}; it may loop or grow without bound'
ERR_SIZE = 'xacro made more than {limit} bytes of {what}; it may grow without bound'
ERR_ARG = ('xacro argument {arg!r} is not of the form name:=value with a name of letters, digits '
           'and underscores')


def is_xacro(name: str, text: str = '') -> bool:
    """Whether a file (by its name) or a text (by its xacro elements) is a xacro description."""
    if Path(name).suffix.lower() in XACRO_SUFFIXES:
        return True
    return bool(text) and 'xmlns:xacro' in text[:4000] and '<xacro:' in text


def parse_args(items: Sequence[str]) -> dict:
    """``['name:=value', ...]`` -> ``{name: value}``; :raises ResourceParseError: bad form."""
    out = {}
    for item in items:
        name, sep, value = item.partition(':=')
        if not sep or not name.replace('_', 'a').isalnum() or len(item) > 4096:
            raise ResourceParseError(ERR_ARG.format(arg=item[:100]))
        out[name] = value
    return out


def _installed_shares() -> dict:
    """Return package -> share folder of every package in the ament index (for $(find))."""
    try:
        from ament_index_python.packages import get_packages_with_prefixes
        return {name: os.path.join(prefix, 'share', name)
                for name, prefix in get_packages_with_prefixes().items()}
    except Exception:  # noqa: B902 (no ament index here: $(find) reads the roots only)
        return {}


def expand(roots: Sequence[str], path: Optional[str] = None, text: str = '',
           args: Optional[Mapping[str, str]] = None) -> str:
    """
    Return the URDF xacro makes of a file (`path`) or of `text`, with `args` (``key:=value``).

    :param roots: the folders it may read (includes, ``load_yaml``, ``$(find)``).
    :raises FeatureUnsupportedError: xacro is not installed.
    :raises ResourceParseError: xacro failed, took too long or made too much.
    """
    what = Path(path).name if path else 'the resource_string'
    spec = importlib.util.find_spec('xacro')
    if spec is None or not spec.submodule_search_locations:
        raise FeatureUnsupportedError(ERR_NO_XACRO.format(what=what))
    paths = sorted({str(Path(p).parent) for p in [
        spec.submodule_search_locations[0],
        *(importlib.util.find_spec(m).origin for m in ('yaml', 'defusedxml')
          if importlib.util.find_spec(m) is not None)]})
    request = {'file': str(path) if path else '', 'text': text, 'args': dict(args or {}),
               'roots': list(roots), 'shares': _installed_shares()}
    # Kept by digest: xacro text given as a resource_string may be 20 MB, not counted by the
    # cache's bound were it the key itself.
    key = hashlib.blake2b(json.dumps(request, sort_keys=True).encode(),
                          digest_size=16).hexdigest()
    with _cache_lock:
        kept = _cache.get(key)
    if kept is not None and _digests(name for name, _ in kept[1]) == kept[1]:
        with _cache_lock:
            if key in _cache:
                _cache.move_to_end(key)
        return kept[0]
    job = json.dumps({**request, 'paths': paths, 'memory_bytes': MEMORY_BYTES,
                      'cpu_seconds': CPU_SECONDS})
    with _cache_lock:
        _runs[0] += 1
    env = {'PATH': '/usr/bin:/bin', 'LANG': 'C.UTF-8', 'HOME': '/nonexistent'}
    proc = subprocess.Popen([sys.executable, '-I', '-S', str(_WORKER), job], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd='/',
                            start_new_session=True, close_fds=True)
    out = _Bounded(proc, proc.stdout, MAX_OUTPUT_BYTES + 1)
    err = _Bounded(proc, proc.stderr, 65536)
    try:
        proc.wait(timeout=TIMEOUT_SEC)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise ResourceParseError(ERR_TIME.format(limit=TIMEOUT_SEC, what=what)) from None
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    text, why = out.result(), err.result().decode(errors='replace')
    if len(text) > MAX_OUTPUT_BYTES:
        raise ResourceParseError(ERR_SIZE.format(limit=MAX_OUTPUT_BYTES, what=what))
    if proc.returncode != 0:
        lines = [ln for ln in why.splitlines() if ln.startswith('error')]
        reason = lines[-1][len('error: '):] if lines else _signal_text(proc.returncode)
        raise ResourceParseError(ERR_FAILED.format(what=what, why=reason))
    urdf = text.decode('utf-8', errors='replace')
    _keep(key, urdf, why)
    return urdf


def runs() -> int:
    """Return how many times this process has started xacro (a kept expansion starts none)."""
    return _runs[0]


def _digests(files) -> Optional[tuple]:
    """Return ((file, digest of its content), ...), or None if one cannot be read."""
    out = []
    for name in files:
        try:
            with open(name, 'rb') as f:
                out.append((name, hashlib.blake2b(f.read(), digest_size=16).hexdigest()))
        except OSError:
            return None
    return tuple(out)


def _keep(key: str, urdf: str, stderr: str) -> None:
    """Keep an expansion with the digests of the files the child says it read."""
    said = [ln for ln in stderr.splitlines() if ln.startswith('read: ')]
    try:
        files = json.loads(said[-1][len('read: '):]) if said else None
    except ValueError:
        files = None
    read = _digests(files) if isinstance(files, list) else None
    if read is None or len(urdf) > CACHE_BYTES:
        return
    with _cache_lock:
        _cache[key] = (urdf, read)
        _cache.move_to_end(key)
        while len(_cache) > CACHE_ENTRIES or sum(len(t) for t, _ in _cache.values()) > \
                CACHE_BYTES:
            _cache.popitem(last=False)


class _Bounded:
    """Read a pipe on a thread, keeping at most `limit` bytes (the child is killed past it)."""

    def __init__(self, proc: subprocess.Popen, pipe, limit: int):
        self._chunks, self._size, self._limit, self._pipe = [], 0, limit, pipe
        self._proc = proc
        self._thread = threading.Thread(target=self._pump, name='sim-xacro', daemon=True)
        self._thread.start()

    def _pump(self) -> None:
        while self._size < self._limit:
            chunk = self._pipe.read1(65536)
            if not chunk:
                return
            self._chunks.append(chunk)
            self._size += len(chunk)
        self._proc.kill()  # over the limit: it is not read any further

    def result(self) -> bytes:
        self._thread.join(5.0)
        return b''.join(self._chunks)[:self._limit]


def _signal_text(code: int) -> str:
    if code == -signal.SIGXCPU:
        return f'it used more than its {CPU_SECONDS} s of CPU time'
    if code < 0:
        return (f'it was stopped by signal {-code} (over its limits: {MEMORY_BYTES >> 20} MiB, '
                f'{CPU_SECONDS} s of CPU time)')
    return f'it exited with status {code}'
