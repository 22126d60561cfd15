"""
Warnings caught on the thread that raised them, and only there.

``warnings.catch_warnings`` swaps the process's ``warnings.showwarning`` and filters for as long
as it lasts, for every thread: a warning another thread raises meanwhile goes to its record,
not where it belongs. Measured in the node: a spawn's compile (about 100 ms, off the stepping
thread) caught MuJoCo's attach conflicts that way, and with them rclpy's "failed to send
response (timeout)" raised by a service's thread at the same moment. The reply's resender never
heard of the failure, took the reply for sent, and the client waited in vain; the compile logged
the failure as a setting the world kept (``test_node_replies.py``, under lossy discovery).

:func:`caught` does the same job for one thread: one hook, put in place of
``warnings.showwarning`` when needed, hands a warning to the innermost :func:`caught` of the
thread that raised it if its text starts as that one asks, and shows it as before otherwise. The
messages asked for are let through every time (a filter "always" for each, set again if a
``catch_warnings`` ending took it away), where Python's default shows each message once per
place it is raised from.
"""

import contextlib
import re
import sys
import threading
import warnings

_local = threading.local()  # .catchers: [(prefixes, heard)], innermost last
_lock = threading.Lock()


def _show(message, category, filename, lineno, file=None, line=None):
    text = str(message)
    for prefixes, heard in reversed(getattr(_local, 'catchers', ())):
        if text.startswith(prefixes):
            heard.append(text)
            return
    # A hook put in after this one and calling it back would come round again: plain display.
    show = _display if getattr(_local, 'showing', False) else _show.previous
    _local.showing = True
    try:
        show(message, category, filename, lineno, file, line)
    finally:
        _local.showing = False


def _display(message, category, filename, lineno, file=None, line=None) -> None:
    (file or sys.stderr).write(warnings.formatwarning(message, category, filename, lineno, line))


def _hook(prefixes: tuple) -> None:
    """Put the hook in place (again, if something replaced it since) and let `prefixes` by."""
    with _lock:
        if warnings.showwarning is not _show:
            _show.previous = warnings.showwarning
            warnings.showwarning = _show
        for prefix in prefixes:  # looked for each time: a catch_warnings ending drops it
            pattern = re.escape(prefix)
            if not any(f[0] == 'always' and f[1] is not None and f[1].pattern == pattern
                       for f in warnings.filters):
                warnings.filterwarnings('always', message=pattern)


@contextlib.contextmanager
def caught(*prefixes: str):
    """
    Catch this thread's warnings whose text starts with one of `prefixes`; yield their texts.

    Other threads' warnings, and this thread's others, are shown as they would have been.
    """
    if not prefixes:
        raise ValueError('name the warnings to catch: at least one prefix of their text')
    _hook(prefixes)
    heard: list = []
    catchers = _local.__dict__.setdefault('catchers', [])
    catchers.append((prefixes, heard))
    try:
        yield heard
    finally:
        catchers.pop()
