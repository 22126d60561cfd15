"""
The process's memory and glibc's allocator: freed memory goes back to the system.

No-ops where the C library is not glibc.
"""

import ctypes
import gc
import os
import threading
import time
from typing import Optional

#: Blocks this large or larger get a mapping of their own (glibc's M_MMAP_THRESHOLD, fixed).
MMAP_THRESHOLD_BYTES = 4 << 20
#: Free memory at the top of the heap is given back by free() only past this much (glibc's
#: M_TRIM_THRESHOLD, fixed with the other); the session gives it back on its own schedule.
TRIM_THRESHOLD_BYTES = 32 << 20
_M_TRIM_THRESHOLD = -1  # from glibc's malloc.h
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8
#: How many heaps (arenas) glibc's allocator may keep: one, the main heap, shared by every
#: thread. glibc gives each thread that allocates while another holds the heap a heap of its own
#: (up to eight per core), and what a thread's heap freed stayed resident after a trim: a 250k-face
#: STL and a 259k-face Collada dome spawned and deleted over the wire left the node 30-55 MiB
#: larger; with one heap -3 to +3 MiB, with two +3 to +19 MiB (3 runs each, measured). The cost,
#: threads waiting on one lock to allocate, is small here: Python's small objects come from
#: its own pools, and the stepping thread's mj_step allocates nothing.
ARENAS = 1


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        'arena', 'ordblks', 'smblks', 'hblks', 'hblkhd', 'usmblks', 'fsmblks', 'uordblks',
        'fordblks', 'keepcost')]


def _glibc() -> Optional[ctypes.CDLL]:
    try:
        libc = ctypes.CDLL('libc.so.6')
    except OSError:
        return None
    if not (hasattr(libc, 'malloc_trim') and hasattr(libc, 'mallopt')):
        return None
    if hasattr(libc, 'mallinfo2'):  # glibc 2.33 and later
        libc.mallinfo2.restype = _MallInfo2
    return libc


_LIBC = _glibc()


def free_heap_bytes() -> Optional[int]:
    """Return the bytes freed but kept in the heap (glibc's ``mallinfo2``), or None if unknown."""
    if _LIBC is None or not hasattr(_LIBC, 'mallinfo2'):
        return None
    return int(_LIBC.mallinfo2().fordblks)


def release_free_memory(at_least: int = 0) -> bool:
    """
    Give memory freed by dropped models back to the system (glibc's ``malloc_trim(0)``).

    glibc keeps it otherwise: a 400-box spawn-and-delete storm left 300 MiB of free heap in
    the process, measured. A trim walks the whole heap with the allocator locked: 20-66 ms
    at the peak of that storm, during which every thread that allocates waits (``/clock``
    stood still as long). So a busy caller passes `at_least`: trim only when that many bytes
    are free to give back (``mallinfo2``, a few milliseconds).

    :returns: whether it trimmed.
    """
    if _LIBC is None:
        return False
    if at_least:
        free = free_heap_bytes()
        if free is not None and free < at_least:
            return False
    _LIBC.malloc_trim(0)
    return True


def keep_large_blocks_mapped() -> None:
    """
    Give every block of :data:`MMAP_THRESHOLD_BYTES` or more a mapping of its own, for good.

    glibc raises its threshold after a large block is freed, so later ones land in the heap
    and stay there: six refused 10 MB names left the node 51-67 MiB larger, measured; with the
    threshold fixed, 1 MiB. Not lower: a mapping of its own costs a page fault per 4 kB on
    every use, and the default scene's sky texture (1.2 MB) is copied with every edit's spec
    and compiled into every model: at 1 MiB each copy took 0.9 ms instead of 0.06 ms. Fixing
    one threshold fixes glibc's other (trim on free, 128 kB), which gave the heap's top back
    and faulted it in again at each such copy (0.45 ms): it is set to
    :data:`TRIM_THRESHOLD_BYTES`, and :func:`release_free_memory` gives the rest back.
    """
    if _LIBC is not None:
        _LIBC.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
        _LIBC.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)


def share_one_heap() -> bool:
    """
    Make every thread allocate from one heap (glibc's ``M_ARENA_MAX``, see :data:`ARENAS`).

    Call before the process starts its threads: heaps already made stay. Left alone where the
    user chose (``MALLOC_ARENA_MAX``, or ``glibc.malloc.arena_max`` in ``GLIBC_TUNABLES``).

    :returns: whether it was set.
    """
    chosen = 'MALLOC_ARENA_MAX' in os.environ or 'arena_max' in os.environ.get(
        'GLIBC_TUNABLES', '')
    if _LIBC is None or chosen:
        return False
    return bool(_LIBC.mallopt(_M_ARENA_MAX, ARENAS))


def freeze_long_lived() -> int:
    """
    Leave the objects alive now out of every later garbage collection (``gc.freeze``).

    For a process that has just started: its modules, classes and first world stay for its life.
    Python's full collection walks every object it tracks with the GIL held: in the node (72,000
    objects after start-up) one took 42 ms during a spawn, and /clock stood still for 47 ms.
    Frozen, they are still freed when nothing refers to them; only a reference cycle among them
    outlives its last use.

    :returns: how many objects were frozen.
    """
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


#: Freed heap goes back to the system every TRIM_PERIOD_SEC; while the model keeps changing, only
#: once BUSY_TRIM_BYTES are free (a trim stalled every allocating thread for up to 66 ms under a
#: storm of edits); once the model has stood still QUIET_SEC, once QUIET_TRIM_BYTES are. Not
#: less: memory given back is faulted in again, a page at a time, by the next edit (a small
#: robot's spawn took 2,600 page faults, 3-5 ms of its 20, after each trim of everything).
TRIM_PERIOD_SEC = 2.0
BUSY_TRIM_BYTES = 64 << 20
QUIET_TRIM_BYTES = 16 << 20
QUIET_SEC = 0.5


class HeapTrimmer:
    """
    Gives freed heap back to the system on its own thread, when it is cheap enough.

    Told of every new model (:meth:`model_changed`, a listener of the session); a trim stalls
    every thread that allocates, so it waits for a quiet model or a lot of free memory.
    """

    def __init__(self):
        self._changed = self._trimmed = time.monotonic()
        self._owed = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim-heap-trim', daemon=True)
        self._thread.start()

    def model_changed(self, *_) -> None:
        """Note that the model changed now (any arguments: a session listener's)."""
        self._changed = time.monotonic()

    def close(self) -> None:
        self._stop.set()

    def tick(self, now: float) -> None:
        """Trim if it is due at `now` (see :data:`TRIM_PERIOD_SEC`)."""
        quiet = now - self._changed >= QUIET_SEC
        if now - self._trimmed >= TRIM_PERIOD_SEC or (quiet and self._owed):
            self._trimmed = now
            # Skipped while busy: owed, and made as soon as the model stands still.
            self._owed = not release_free_memory(
                at_least=QUIET_TRIM_BYTES if quiet else BUSY_TRIM_BYTES)

    def _run(self) -> None:
        while not self._stop.wait(QUIET_SEC / 5):
            self.tick(time.monotonic())
