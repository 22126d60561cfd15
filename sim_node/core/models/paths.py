"""
Where a path really leads: the one judgement every file a request names goes through.

A path is judged by where it really is (``..`` components and symbolic links resolved) and
compared with the resolved readable folders, before its existence is.
"""

import os
from typing import Sequence


def real_path(path) -> str:
    """
    Return where `path` really leads, as ``os.path.realpath`` does.

    An existing path is resolved by the kernel (opened with ``O_PATH``, which reads nothing
    and cannot block on a FIFO, and named back through ``/proc``): three system calls instead
    of one ``lstat`` per component, each of which hands Python's lock to the node's other
    threads (a quarter of a small robot's spawn went to them). Anything else takes
    ``os.path.realpath``.
    """
    if _O_PATH is None:
        return os.path.realpath(path)
    try:
        fd = os.open(path, _O_PATH | os.O_CLOEXEC)
    except (OSError, ValueError, TypeError):
        return os.path.realpath(path)
    try:
        real = os.readlink(f'/proc/self/fd/{fd}')
    except OSError:
        real = ''
    finally:
        os.close(fd)
    # a path the kernel cannot name plainly (deleted, another mount namespace) is resolved
    # the long way
    return real if real.startswith('/') and not real.endswith(' (deleted)') \
        else os.path.realpath(path)


_O_PATH = getattr(os, 'O_PATH', None)  # Linux


def real_roots(roots: Sequence[str]) -> tuple:
    """Return `roots` resolved (see :func:`real_path`), for :func:`inside_real_roots`."""
    return tuple(real_path(r) for r in roots)


def inside_real_roots(real: str, reals: Sequence[str]) -> bool:
    """Return True if the resolved path `real` is one of the resolved `reals` or inside one."""
    return any(real == r or real.startswith(r.rstrip('/') + '/') for r in reals)


def inside_roots(path, roots: Sequence[str]) -> bool:
    """
    Return True if `path`, resolved, is one of `roots` or inside one.

    ``..`` components and symbolic links are resolved first (:func:`real_path`), so
    ``meshes/../../scene/table.xml`` is judged by where it really is.
    """
    return inside_real_roots(real_path(path), real_roots(roots))
