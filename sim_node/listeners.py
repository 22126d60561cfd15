"""
A listener of a :class:`~sim_node.session.Session`: its hooks, its own thread, its mailbox.

The session offers each listener the newest model and every state event; the listener's thread
calls its hooks (``on_model(loaded, snapshot)``, ``on_state(event)``) with what its mailbox
holds, so a slow or stuck listener holds back nobody but itself. No ROS.
"""

import collections
import logging
import threading
from typing import Any, Callable, Optional

log = logging.getLogger(__name__)

#: State events a listener's mailbox keeps when it falls behind (the newest win).
STATES_KEPT = 64

#: ``on_model(loaded, snapshot)``: a :class:`~sim_node.session.Loaded` (or None) and the
#: snapshot of its new model (or None).
Listener = Callable[[Any, Any], None]
#: ``on_state(event)``: a :class:`~sim_node.session.StateEvent`.
StateListener = Callable[[Any], None]


class Mailbox:
    """
    A listener: its hooks, the model it last saw, and its own thread and mailbox.

    The mailbox holds the newest model offered (older ones are replaced: a listener that falls
    behind skips them) and the state events, in order (at most :data:`STATES_KEPT`). Its lock
    is a leaf: offering never waits for the listener.
    """

    def __init__(self, on_model: Optional[Listener], on_state: Optional[StateListener],
                 name: str, seen: Callable[[], None]):
        self.on_model, self.on_state = on_model, on_state
        self.seen: tuple = ('never', None)  # the model key the listener has been called with
        self.offered: tuple = ('never', None)
        self._told_seen = seen
        self._cv = threading.Condition()
        self._model: Optional[tuple] = None
        self._states: collections.deque = collections.deque(maxlen=STATES_KEPT)
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=f'sim-listen {name}'[:60],
                                        daemon=True)
        self._thread.start()

    def offer_model(self, key: tuple, loaded: Any, snap) -> None:
        self.offered = key
        if self.on_model is None:
            self.seen = key
            return
        with self._cv:
            self._model = (key, loaded, snap)
            self._cv.notify()

    def offer_state(self, event) -> None:
        if self.on_state is None:
            return
        with self._cv:
            self._states.append(event)
            self._cv.notify()

    def close(self) -> None:
        with self._cv:
            self._closed = True
            self._cv.notify()
        if self._thread is not threading.current_thread():
            self._thread.join(1.0)

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._closed and self._model is None and not self._states:
                    self._cv.wait()
                if self._closed:
                    return
                model, self._model = self._model, None
                states = list(self._states)
                self._states.clear()
            if model is not None:
                key, loaded, snap = model
                try:
                    self.on_model(loaded, snap)
                except Exception:  # noqa: B902 (one listener must not stop the next events)
                    log.exception('a listener of new models failed: %r', self.on_model)
                self.seen = key
                self._told_seen()
            for event in states:
                try:
                    self.on_state(event)
                except Exception:  # noqa: B902 (one listener must not stop the next events)
                    log.exception('a listener of states failed: %r', self.on_state)
