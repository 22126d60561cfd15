"""
How a benchmark's client process ends: at once, without tearing the middleware down.

Fast DDS 2.14 (the PyPI wheels') deletes a participant by waiting, with the participant's
listener mutex held, for any discovery callback in flight to end. That callback needs the same
mutex, so the wait never ends: the process spins on a core for ever, the GIL held. Found with
gdb in a client of ``make bench-storm``, 10 minutes in ``DomainParticipant::set_listener``
under ``rmw_destroy_node``, its discovery thread blocked on the mutex the spinning thread owned.
Eight clients leaving at once make such a callback likely, and the spinning took the core the
node being measured needed. A client that has printed what it measured has nothing left to
do: it leaves, and the node sees its participant go when the lease runs out.
"""

import os
import sys


def leave(code: int = 0) -> None:
    """Flush what was printed, then end the process with `code` (no middleware teardown)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
