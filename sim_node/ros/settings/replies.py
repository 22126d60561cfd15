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

Action servers' three replies (a goal's response, a cancel's, a result) fail alike, with the
same warning, inside rclpy's own coroutines, which send them through the server's handle. A
:class:`ResendingActionServer` has its handle made of a subclass whose three sends go through
the resender (see :func:`_resending_handles`: the handle is a pybind object whose class cannot
be changed once it is made).

The warning is caught where it is raised, on the sending thread only
(`sim_node.core.base.thread_warnings`): no other thread's warnings are touched. The node's own
code catches warnings that way everywhere: a ``warnings.catch_warnings`` on another thread takes
every thread's warnings while it lasts (a spawn's compile did: the failure went unheard, and the
reply unsent).
"""

import contextlib
import functools
import logging
import threading
import time
from typing import Optional

from rclpy.action import ActionServer
from rclpy.action import server as _action_module
from rclpy.exceptions import InvalidHandle

from ...core.base import thread_warnings

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


def _send_once(send, response, header) -> Optional[str]:
    """Send a reply once; return None if the middleware took it, else what it said."""
    with thread_warnings.caught(FAILED) as heard:
        send(response, header)
    return heard[0] if heard else None


class Resender:
    """Replies kept because the middleware could not send them, tried again on a thread."""

    def __init__(self, first_retry_sec: float = FIRST_RETRY_SEC,
                 give_up_sec: float = GIVE_UP_SEC, max_pending: int = MAX_PENDING):
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


#: The action-server handle types made by :func:`_resending_handle_type`, by rclpy's own type.
_handle_types: dict = {}
#: Held while rclpy's action module makes its handles of a resending type (one server at once).
_making_lock = threading.Lock()


def _resending_handle_type(base: type) -> type:
    """Return a subclass of rclpy's action-server handle `base` whose replies resend."""
    if base not in _handle_types:
        def reply(send_name: str):
            send = getattr(base, send_name)

            def resend(self, header, response) -> None:
                resender()._send(self.reply_name, lambda r, h: send(self, h, r), response, header)
            resend.__name__ = send_name
            return resend

        _handle_types[base] = type('ResendingActionServerHandle', (base,), {
            'reply_name': 'an action server',  # its own, once made (_WithResendingHandles)
            **{name: reply(name) for name in ('send_goal_response', 'send_cancel_response',
                                              'send_result_response')}})
    return _handle_types[base]


class _WithResendingHandles:
    """rclpy's implementation module, but for the action-server handles it makes (`name`'s)."""

    def __init__(self, implementation, name: str):
        self._implementation, self._name = implementation, name
        self._handle_type = _resending_handle_type(implementation.ActionServer)

    def ActionServer(self, *args, **kwargs):  # noqa: N802 (stands for rclpy's type)
        handle = self._handle_type(*args, **kwargs)
        handle.reply_name = self._name
        return handle

    def __getattr__(self, name: str):
        return getattr(self._implementation, name)


@contextlib.contextmanager
def _resending_handles(name: str):
    """
    While an action server is made, rclpy's action module makes its handle resend.

    rclpy's ActionServer makes its handle from the implementation module it names ``_rclpy``;
    here that name stands for a stand-in that makes the handle of the resending subclass and
    passes every other name through, so a thread of rclpy's action module that looks a name
    up meanwhile gets the very same thing. An rclpy without that name leaves the handle as
    made: its action replies are then not sent again.
    """
    implementation = getattr(_action_module, '_rclpy', None)
    if implementation is None or not hasattr(implementation, 'ActionServer'):
        yield
        return
    with _making_lock:
        _action_module._rclpy = _WithResendingHandles(implementation, name)
        try:
            yield
        finally:
            _action_module._rclpy = implementation


class ResendingActionServer(ActionServer):
    """An action server whose goal, cancel and result replies go through the resender."""

    def __init__(self, node, action_type, action_name: str, *args, **kwargs):
        ns = node.get_namespace().rstrip('/')
        name = action_name if action_name.startswith('/') else f'{ns}/{action_name}'
        with _resending_handles(name):
            super().__init__(node, action_type, action_name, *args, **kwargs)
