"""
Run the node with its locks watched: ``python lock_watch.py --ros-args ...`` (test_node_locks).

Every lock the ROS layer's modules, the controllers' laws and their managers' bookkeeping make
(``threading.Lock`` and ``RLock`` inside them) is a :class:`Watched` lock, named by the
attribute it is made for (``controller_manager._sync_lock``); the world lock (``WorldLock``)
and the edits' turn (``Transaction.edit_lock``) check, as they are taken, that the taking
thread holds none of them (docs/threading.md: no node lock is held while calling into the
world; a world method that takes neither, as draining the sample queue, waits for nobody).
What is seen is written, one JSON line each, to ``$SIM_LOCK_REPORT``:

* ``{"pair": [outer, inner]}`` the first time a thread takes `inner` while holding `outer`;
* ``{"world": what, "held": [...], "thread": ..., "stack": [...]}`` for the world lock or an
  edit's turn taken with node locks held.

The test compares the pairs with the order docs/threading.md gives.
"""

import inspect
import json
import linecache
import os
import re
import sys
import threading
import traceback
import types

REPORT = os.environ['SIM_LOCK_REPORT']
_local = threading.local()
_seen: set = set()
_write_lock = threading.Lock()  # the report file's; not watched
ATTRIBUTE = re.compile(r'(?:self\.)?(\w+)\s*=\s*threading\.(?:R?Lock)\(')


def _write(entry: dict) -> None:
    with _write_lock:
        with open(REPORT, 'a') as f:
            f.write(json.dumps(entry) + '\n')


def held() -> list:
    stack = getattr(_local, 'stack', None)
    if stack is None:
        stack = _local.stack = []
    return stack


class Watched:
    """A lock that records which watched locks its taker held (see the module docstring)."""

    def __init__(self, inner, name: str):
        self._inner, self.name = inner, name

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        stack = held()
        for outer in stack:
            pair = (outer.name, self.name)
            if outer is not self and pair not in _seen:
                _seen.add(pair)
                _write({'pair': list(pair), 'thread': threading.current_thread().name,
                        'stack': traceback.format_stack(limit=8)[:-1]})
        ok = self._inner.acquire(blocking, timeout)
        if ok:
            stack.append(self)
        return ok

    def release(self) -> None:
        stack = held()
        for i in range(len(stack) - 1, -1, -1):
            if stack[i] is self:
                del stack[i]
                break
        self._inner.release()

    def locked(self) -> bool:
        return self._inner.locked()

    def __enter__(self):
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _threading_for(module, wrap=None) -> types.SimpleNamespace:
    """Return a stand-in for `module`'s ``threading`` whose locks are watched (or `wrap`ped)."""
    short = module.__name__.rsplit('.', 1)[-1]

    def make(factory):
        def lock():
            caller = inspect.currentframe().f_back
            line = linecache.getline(caller.f_code.co_filename, caller.f_lineno)
            match = ATTRIBUTE.search(line)
            made = Watched(factory(), f'{short}.{match.group(1) if match else caller.f_lineno}')
            return wrap(made) if wrap else made
        return lock

    stand_in = types.SimpleNamespace(**{k: getattr(threading, k) for k in dir(threading)
                                        if not k.startswith('__')})
    stand_in.Lock, stand_in.RLock = make(threading.Lock), make(threading.RLock)
    return stand_in


def install() -> None:
    """Watch the ROS layer's and the laws' locks, and the world lock's takers."""
    import importlib
    import pkgutil

    import sim_node.ros
    from sim_node.core.control import laws, manager
    modules = [laws, manager]
    for info in pkgutil.walk_packages(sim_node.ros.__path__, 'sim_node.ros.'):
        modules.append(importlib.import_module(info.name))
    for module in modules:
        if getattr(module, 'threading', None) is threading:
            module.threading = _threading_for(module)
    from sim_node.core.editing import transaction
    from sim_node.core.stepping.lock import WorldLock
    enter = WorldLock.__enter__

    def world_lock(self) -> None:
        _check('the world lock')
        enter(self)
    WorldLock.__enter__ = world_lock
    transaction.threading = _threading_for(transaction, lambda lock: _Checked(lock))


def _check(what: str) -> None:
    stack = held()
    if stack:
        _write({'world': what, 'held': [lock.name for lock in stack],
                'thread': threading.current_thread().name,
                'stack': traceback.format_stack(limit=10)[:-2]})


class _Checked(Watched):
    """A core lock (the edits' turn) whose taker must hold no node lock; not itself tracked."""

    def __init__(self, lock: Watched):
        super().__init__(lock._inner, lock.name)

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        _check(self.name)
        return self._inner.acquire(blocking, timeout)

    def release(self) -> None:
        self._inner.release()


if __name__ == '__main__':
    install()
    from sim_node.ros.node.main import main
    sys.exit(main())
