"""
The world lock: reentrant, and fair enough that the stepping loop steps aside for callers.

A plain lock is not fair: a reader waited up to 2.5 s behind a loop that re-took the lock at
once. Callers that had to wait are counted, and the loop calls :meth:`WorldLock.wait_for_callers`
before each batch.
"""

import threading


class WorldLock:
    """
    Context manager for the world lock (a class: cheaper than a generator per step).

    Each acquisition records whether it had to wait (and so was counted as a waiter),
    innermost last; only the thread holding the lock touches that record.
    """

    __slots__ = ('lock', '_waiting', '_waiting_cv', '_loop_waiting', '_counted')

    def __init__(self):
        self.lock = threading.RLock()
        self._waiting = 0
        self._waiting_cv = threading.Condition(threading.Lock())
        self._loop_waiting = False
        self._counted: list = []

    def __enter__(self) -> None:
        if self.lock.acquire(blocking=False):
            self._counted.append(False)  # never waited: nobody needs to step aside for us
            return
        with self._waiting_cv:
            self._waiting += 1
        self.lock.acquire()
        self._counted.append(True)

    def __exit__(self, *exc) -> None:
        counted = self._counted.pop()
        self.lock.release()
        if not counted:
            return
        with self._waiting_cv:
            self._waiting -= 1
            if self._loop_waiting and not self._waiting:
                self._waiting_cv.notify_all()

    def wait_for_callers(self, timeout: float) -> None:
        """Let callers waiting for the lock go first (at most `timeout` seconds)."""
        with self._waiting_cv:
            if self._waiting:
                self._loop_waiting = True
                self._waiting_cv.wait_for(lambda: self._waiting == 0, timeout)
                self._loop_waiting = False
