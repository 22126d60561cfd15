"""
Replies the middleware could not deliver at once, sent again until the client can hear them.

A service's reply goes out on a writer of its own, to the reply reader of the client that
asked. rmw_fastrtps (Jazzy) knows that reader only once discovery has matched it; a request can
come before that (the client saw the service and asked at once, or discovery is slow on a
loaded host). It then waits up to 100 ms for the match, and failing that returns a timeout;
rclpy turns the timeout into a RuntimeWarning, "failed to send response (timeout)", and drops
the reply. The client waits for it until its own timeout: 10 to 30 s in our tests and benchmarks,
forever for a plain ``call``.

:func:`deliver` makes a service's replies go through a :class:`Resender`: a reply that fails so
is kept and sent again from a thread of its own, FIRST_RETRY_SEC after it failed and then at
twice the last wait each time, until it goes out (the client was matched), the middleware says
the client is gone (rmw_fastrtps then answers OK and sends nothing), the service itself is
destroyed, or GIVE_UP_SEC pass. The waits grow because each try that fails costs the whole
process: rclpy holds the GIL while the middleware waits its 100 ms for the match, and every
other thread (the stepping loop, /clock) stands still meanwhile; tried every 50 ms, a reply
nobody could hear held the process 65% of the time for its 15 s. Doubling, it is tried 8
times. At most MAX_PENDING replies are kept (the oldest are given up first). What the
middleware took on a later try (the client matched, or gone), what was given up and what is
still kept are counted on /diagnostics (``replies_sent_again``, ``replies_given_up``,
``replies_waiting``) and each reply given up is logged with its service: a call that hangs
says why.

Action servers are not covered: rclpy's raises RCLError on the same timeout inside its own
coroutines (logged "Failed to send goal response") where no caller can catch it.

The warning is caught where it is raised, on the sending thread only (a thread-local flag read
by a ``warnings.showwarning`` hook): no other thread's warnings are touched, and the warnings
filters are not changed while the node runs (one filter, set once, lets every such warning
through, where Python's default shows only the first of each place).
"""

import functools
import logging
import threading
import time
from typing import Optional
import warnings

from rclpy.exceptions import InvalidHandle

#: From a reply's failure to its first try again (s); each wait after is twice the one before.
#: Each try that fails holds the GIL for the middleware's 100 ms wait (see the module).
FIRST_RETRY_SEC = 0.1
#: How long a reply is kept and tried again (s): longer than the 10 s a client here waits least.
GIVE_UP_SEC = 15.0
#: The most replies kept at once.
MAX_PENDING = 256
#: What rclpy says when the middleware could not send a reply.
FAILED = 'failed to send response'

_log = logging.getLogger('sim_node.replies')
_sending = threading.local()  # .failed: the warning's text, on the thread that sends
_hook_lock = threading.Lock()
_hook_installed = False


def _install_hook() -> None:
    """Catch rclpy's warning where a reply is sent (see the module); once per process."""
    global _hook_installed
    with _hook_lock:
        if _hook_installed:
            return
        previous = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if getattr(_sending, 'active', False) and issubclass(category, RuntimeWarning) \
                    and str(message).startswith(FAILED):
                _sending.failed = str(message)
                return
            previous(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        warnings.filterwarnings('always', message=FAILED, category=RuntimeWarning)
        _hook_installed = True


def _send_once(send, response, header) -> Optional[str]:
    """Send a reply once; return None if the middleware took it, else what it said."""
    _sending.active, _sending.failed = True, None
    try:
        send(response, header)
    finally:
        _sending.active = False
    return _sending.failed


class Resender:
    """Replies kept because the middleware could not send them, tried again on a thread."""

    def __init__(self, first_retry_sec: float = FIRST_RETRY_SEC,
                 give_up_sec: float = GIVE_UP_SEC, max_pending: int = MAX_PENDING):
        _install_hook()
        self.first_retry_sec, self.give_up_sec = first_retry_sec, give_up_sec
        self.max_pending = max_pending
        #: Oldest first: [next try at, wait before it, given up at, name, send, response, header]
        self._pending: list = []
        self._kept = threading.Condition()
        self._thread: Optional[threading.Thread] = None
        self.sent_again = 0  # replies the middleware took on a later try (matched, or gone)
        self.given_up = 0  # replies never sent
        self.tries = 0  # sends tried again, taken or not
        #: Called with (service name, why) for each reply given up (the node's logger).
        self.on_given_up = lambda name, why: _log.warning(
            f'a reply of {name} could not be delivered: {why}')

    @property
    def waiting(self) -> int:
        return len(self._pending)

    def counts(self) -> dict:
        """Return the counts /diagnostics shows."""
        return {'replies_sent_again': str(self.sent_again),
                'replies_given_up': str(self.given_up), 'replies_waiting': str(self.waiting)}

    def watch(self, service) -> None:
        """Send `service`'s replies through this resender (rclpy's executor calls them so)."""
        name = service.service_name  # resolved: /<namespace>/controller_manager/...
        service.send_response = functools.partial(self._send, name, service.send_response)

    def _send(self, name: str, send, response, header) -> None:
        if _send_once(send, response, header) is not None:
            self._keep(name, send, response, header)

    def _keep(self, name: str, send, response, header) -> None:
        now = time.monotonic()
        with self._kept:
            self._pending.append([now + self.first_retry_sec, self.first_retry_sec,
                                  now + self.give_up_sec, name, send, response, header])
            dropped = self._pending[:-self.max_pending]
            del self._pending[:-self.max_pending]
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name='sim-replies',
                                                daemon=True)
                self._thread.start()
            self._kept.notify()
        for entry in dropped:
            self._give_up(entry[3], f'more than {self.max_pending} replies were waiting')

    def _give_up(self, name: str, why: str) -> None:
        self.given_up += 1
        self.on_given_up(name, why)

    def _run(self) -> None:
        while True:
            with self._kept:
                if not self._pending:
                    self._kept.wait()
                    continue
                entry = min(self._pending, key=lambda e: e[0])
                early = entry[0] - time.monotonic()
                if early > 0:
                    self._kept.wait(early)
                    continue
                self._pending.remove(entry)
            self._try(entry)

    def _try(self, entry: list) -> None:
        _, wait, deadline, name, send, response, header = entry
        self.tries += 1
        try:
            failed = _send_once(send, response, header)
        except InvalidHandle:  # the service is gone (a controller manager with its robot)
            self._give_up(name, 'the service was destroyed')
            return
        except Exception as exc:  # the middleware refused it otherwise: said, not retried
            self._give_up(name, repr(exc))
            return
        now = time.monotonic()
        if failed is None:
            self.sent_again += 1
        elif now >= deadline:
            self._give_up(name, f'the client was not matched within {self.give_up_sec:g} s '
                                f'({failed})')
        else:
            entry[0], entry[1] = min(now + 2 * wait, deadline), 2 * wait
            with self._kept:
                self._pending.append(entry)

    def clear(self) -> None:
        """Drop what is kept, untried (a node shutting down: its services go with it)."""
        with self._kept:
            self._pending.clear()


_default: Optional[Resender] = None
_default_lock = threading.Lock()


def resender() -> Resender:
    """Return the one resender of this process, made on first use."""
    global _default
    with _default_lock:
        if _default is None:
            _default = Resender()
        return _default


def deliver(service):
    """Send `service`'s replies through the process's resender; return the service."""
    resender().watch(service)
    return service
