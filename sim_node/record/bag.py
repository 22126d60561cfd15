"""
Writing rosbag2 bags (MCAP storage) on a thread of their own, with the ``rosbags`` library.

:class:`BagWriter` takes serialized messages (CDR bytes, as they go on the wire) with their
topic, type, QoS and log time (simulation time) from any thread without waiting: a bounded
queue, a message dropped and counted when it is full, so the physics never waits for the disk.
Its thread writes them into ``<folder>/<name>_<n>/`` bags: a new one when the current reaches
``split_bytes`` or ``split_seconds`` of simulated time, none after ``max_bytes`` in all. A
write that fails (a full disk) ends the recording with one error, and the bag written so far is
closed so that it opens. Each bag is a folder with ``metadata.yaml`` (written at close) and an
MCAP file, whose chunks are readable up to the last one written even after a kill -9.

Types are those of ROS 2 Jazzy known to rosbags, and others (control_msgs, ...) read from the
``.msg`` files of the packages on ``AMENT_PREFIX_PATH``.
"""

from dataclasses import dataclass
import logging
import os
from pathlib import Path
import queue
import threading
import time
from typing import Callable, Optional

log = logging.getLogger(__name__)

#: Messages waiting for the writer thread; beyond, messages are dropped (and counted).
QUEUE_LENGTH = 20_000


@dataclass(frozen=True)
class Limits:
    """Where a bag ends (0: never): its size, its simulated duration, and all bags' size."""

    split_bytes: int = 0
    split_seconds: float = 0.0
    max_bytes: int = 0


def _typestore():
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


def _register(store, msgtype: str) -> bool:
    """Add a type (and what it names) from its .msg file on AMENT_PREFIX_PATH; False if none."""
    from rosbags.typesys import get_types_from_msg
    pending, added = [msgtype], {}
    while pending:
        name = pending.pop()
        if name in store.types or name in added:
            continue
        package, _, type_name = name.split('/')
        text = None
        for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
            path = Path(prefix) / 'share' / package / 'msg' / f'{type_name}.msg'
            if prefix and path.is_file():
                text = path.read_text()
                break
        if text is None:
            return False
        found = get_types_from_msg(text, name)
        added.update(found)
        for fields in found.values():
            for _, (kind, detail) in fields[1]:
                nested = detail if kind == 2 else None  # a message, or a sequence of them
                if kind in (3, 4) and detail[0][0] == 2:
                    nested = detail[0][1]
                if isinstance(nested, str) and '/' in nested:
                    pending.append(nested)
    store.register(added)
    return True


def qos(latched: bool, reliable: bool = True, depth: int = 10):
    """Return a rosbags QoS profile: transient local for latched topics."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)
    never = QosTime(sec=0, nsec=0)
    return Qos(history=QosHistory.KEEP_LAST, depth=depth,
               reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               durability=(QosDurability.TRANSIENT_LOCAL if latched
                           else QosDurability.VOLATILE),
               deadline=never, lifespan=never, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=never, avoid_ros_namespace_conventions=False)


class BagWriter:
    """
    Serialized messages into rosbag2 bags, written on a thread of its own.

    :param folder: where the bags go (made if missing).
    :param on_error: called once, with a message, when the recording ends on an error.
    """

    def __init__(self, folder: str, limits: Limits = Limits(), name: str = 'sim',
                 on_error: Optional[Callable[[str], None]] = None):
        self.folder = Path(folder).expanduser()
        self.limits, self.name = limits, name
        self._on_error = on_error or (lambda text: log.error(text))
        self._queue: queue.Queue = queue.Queue(QUEUE_LENGTH)
        self.dropped = 0
        self.written = 0
        self.bags: list = []  # the bag folders written, in order
        self.failed = ''
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim-recorder', daemon=True)
        self._thread.start()

    def put(self, topic: str, msgtype: str, data: bytes, stamp_ns: int,
            latched: bool = False, reliable: bool = True) -> None:
        """Queue one message; never blocks (a full queue drops it)."""
        if self.failed or self._stop.is_set():
            return
        try:
            self._queue.put_nowait((topic, msgtype, bytes(data), int(stamp_ns), latched,
                                    reliable))
        except queue.Full:
            self.dropped += 1

    def close(self, timeout: float = 10.0) -> None:
        """Write what is queued, close the bag (its metadata.yaml), stop the thread."""
        self._stop.set()
        self._thread.join(timeout)

    # ------------------------------------------------------------------ the thread

    def _run(self) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        store = _typestore()
        writer, connections, size, start, total = None, {}, 0, None, 0
        latched: dict = {}  # topic -> the last message of a latched topic: into every new bag
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            while not (self._stop.is_set() and self._queue.empty()):
                try:
                    item = self._queue.get(timeout=0.1)
                except queue.Empty:
                    continue
                topic, msgtype, data, stamp, is_latched, reliable = item
                if is_latched:
                    latched[topic] = item
                lim = self.limits
                if writer is not None and ((lim.split_bytes and size >= lim.split_bytes) or (
                        lim.split_seconds and stamp - start >= lim.split_seconds * 1e9)):
                    writer.close()
                    writer = None
                if lim.max_bytes and total >= lim.max_bytes:
                    raise _Full(f'the recording reached record_max_mb ({lim.max_bytes} '
                                f'bytes); it ends here, its bags in {self.folder}')
                if writer is None:
                    path = self._next_path()
                    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
                    writer.open()
                    self.bags.append(path)
                    connections, size, start = {}, 0, stamp
                    for old in list(latched.values()):  # a new bag starts with them,
                        if old is not item:  # logged at its start
                            size += self._write(writer, connections, store,
                                                old[:3] + (stamp,) + old[4:])
                    total += size
                n = self._write(writer, connections, store, item)
                size, total = size + n, total + n
                self.written += 1
        except _Full as exc:
            self.failed = str(exc)
            self._on_error(self.failed)
        except OSError as exc:  # a full disk, a folder gone
            self.failed = (f'the recording stopped: {exc.strerror or exc} writing to '
                           f'{self.folder}; the bag so far is closed and opens')
            self._on_error(self.failed)
        finally:
            if writer is not None:
                try:
                    writer.close()
                except OSError as exc:
                    log.error('the last bag could not be closed: %s', exc)

    def _write(self, writer, connections: dict, store, item) -> int:
        topic, msgtype, data, stamp, is_latched, reliable = item
        conn = connections.get(topic)
        if conn is None:
            if msgtype not in store.types and not _register(store, msgtype):
                log.warning('not recording %s: its type %s is unknown here', topic, msgtype)
                connections[topic] = conn = False
            else:
                conn = connections[topic] = writer.add_connection(
                    topic, msgtype, typestore=store,
                    offered_qos_profiles=[qos(is_latched, reliable)])
        if conn is False:
            return 0
        writer.write(conn, stamp, data)
        return len(data)

    def _next_path(self) -> Path:
        stamp = time.strftime('%Y%m%d_%H%M%S')
        n = len(self.bags)
        path = self.folder / f'{self.name}_{stamp}_{n}'
        while path.exists():
            n += 1
            path = self.folder / f'{self.name}_{stamp}_{n}'
        return path


class _Full(Exception):
    """The recording reached its total size."""
