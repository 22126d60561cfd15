"""
The newest snapshot of a running world, handed from the loop to every reader.

:class:`Snapshots` keeps only the newest :class:`~sim_node.core.records.Snapshot` by its
``seq``: two threads that raced to publish (the loop after a batch, a service after a change)
never make a consumer see time go backwards. Its condition is a leaf of the lock order.
"""

import threading

from ..base.records import Snapshot


class Snapshots:
    """The newest snapshot and a count of those handed out; readers may wait for a newer one."""

    def __init__(self, first: Snapshot):
        self._cv = threading.Condition()
        self._latest = first
        self._count = 0

    @property
    def latest(self) -> Snapshot:
        return self._latest

    def offer(self, snap: Snapshot) -> bool:
        """Keep `snap` if it is newer than the one kept; return whether it was."""
        with self._cv:
            if snap.seq <= self._latest.seq:
                return False  # another thread published a newer one meanwhile
            self._latest = snap
            self._count += 1
            self._cv.notify_all()
            return True

    def wait(self, after: int, timeout: float) -> tuple:
        """Block until more than `after` snapshots were kept; return ``(count, snapshot)``."""
        with self._cv:
            self._cv.wait_for(lambda: self._count > after, timeout)
            return self._count, self._latest
