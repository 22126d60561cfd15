"""
Writing a rosbag2 bag (MCAP storage) on a thread of its own, with the ``rosbags`` library.

:class:`BagWriter` takes serialized messages (CDR bytes, as they go on the wire) with their
topic, type, QoS and log time (simulation time) from any thread without waiting: a bounded
queue, a message dropped and counted when it is full, so the physics never waits for the disk.
The queue is a plain deque the writer thread polls (:data:`POLL_SEC` when it finds it empty):
``queue.Queue`` takes a lock and wakes the writer at every message, and at real_time_factor 0
the node records thousands of messages a wall second from the threads that share the GIL with
the stepping loop (``make bench-bases``, recording on).

The folder it is given is the bag, as ``ros2 bag record -o`` makes it: ``<bag>/metadata.yaml``
and ``<bag>/<bag name>_<n>.mcap``, a new file when the current one reaches ``split_bytes`` or
``split_seconds`` of simulated time (rosbag2's splits: one bag, its files listed in its one
``metadata.yaml``), none after ``max_bytes`` in all. A folder that holds anything already is
refused: nothing is ever overwritten. A file being written lives in ``<bag>/<bag name>_<n>/``
until it is closed. At least every :data:`FLUSH_SEC` of wall time the messages written go to the
file as a closed chunk and ``metadata.yaml`` lists them, so a run killed with -9 keeps all but
its last second: its files read up to their last chunk. A write that fails (a full disk) ends
the recording with one error, and the bag written so far is closed so that it opens.

Types are those of ROS 2 Jazzy known to rosbags, and others (control_msgs, ...) read from the
``.msg`` files of the packages on ``AMENT_PREFIX_PATH``.
"""

from collections import deque
from dataclasses import dataclass
import logging
import os
from pathlib import Path
import threading
import time
from typing import Callable, Optional

from ..core.base.errors import SimError

log = logging.getLogger(__name__)

#: Messages waiting for the writer thread; beyond, messages are dropped (and counted).
QUEUE_LENGTH = 20_000
#: Wall seconds between flushes of what was written (a chunk to the file, metadata.yaml).
FLUSH_SEC = 0.5
#: How long the writer thread sleeps when it finds no message waiting (s).
POLL_SEC = 0.01
ERR_EXISTS = ('cannot record into {path}: it exists and is not empty (a bag is never '
              'overwritten); give a new path, as for ros2 bag record -o')


class RecordingError(SimError):
    """The recording cannot start where it was asked to."""


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
    Serialized messages into one rosbag2 bag, written on a thread of its own.

    :param folder: the bag (made; refused if it exists and is not empty).
    :param on_error: called once, with a message, when the recording ends on an error.
    :raises RecordingError: `folder` holds something already.
    """

    def __init__(self, folder: str, limits: Limits = Limits(),
                 on_error: Optional[Callable[[str], None]] = None):
        self.folder = Path(folder).expanduser()
        if self.folder.exists() and (not self.folder.is_dir() or any(self.folder.iterdir())):
            raise RecordingError(ERR_EXISTS.format(path=self.folder))
        self.limits = limits
        self._on_error = on_error or (lambda text: log.error(text))
        self._queue: deque = deque()  # appended by any thread, taken by the writer's
        self.dropped = 0
        self.written = 0
        self.failed = ''
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim-recorder', daemon=True)
        self._thread.start()

    def put(self, topic: str, msgtype: str, data: bytes, stamp_ns: int,
            latched: bool = False, reliable: bool = True) -> None:
        """Queue one message; never blocks (a full queue drops it)."""
        if self.failed or self._stop.is_set():
            return
        if len(self._queue) >= QUEUE_LENGTH:
            self.dropped += 1
            return
        self._queue.append((topic, msgtype, bytes(data), int(stamp_ns), latched, reliable))

    def close(self, timeout: float = 10.0) -> None:
        """Write what is queued, close the bag (its metadata.yaml), stop the thread."""
        self._stop.set()
        self._thread.join(timeout)

    # ------------------------------------------------------------------ the thread

    def _run(self) -> None:
        store = _typestore()
        part = None  # the file being written: a _Part
        done: list = []  # what metadata.yaml says of each closed file
        latched: dict = {}  # topic -> the last message of a latched topic: into every new file
        flushed = time.monotonic()
        total = 0
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            while not (self._stop.is_set() and not self._queue):
                if part is not None and time.monotonic() - flushed >= FLUSH_SEC:
                    part.flush()
                    self._write_metadata(done + [part.record()])
                    flushed = time.monotonic()
                try:
                    item = self._queue.popleft()
                except IndexError:
                    time.sleep(POLL_SEC)
                    continue
                topic, msgtype, data, stamp, is_latched, reliable = item
                if is_latched:
                    latched[topic] = item
                lim = self.limits
                if part is not None and ((lim.split_bytes and part.size >= lim.split_bytes) or (
                        lim.split_seconds and stamp - part.start >= lim.split_seconds * 1e9)):
                    done.append(part.close())
                    part = None
                if lim.max_bytes and total >= lim.max_bytes:
                    raise _Full(f'the recording reached record_max_mb ({lim.max_bytes} '
                                f'bytes); it ends here, its bag in {self.folder}')
                if part is None:
                    part = _Part(self.folder, len(done), store, stamp)
                    for old in list(latched.values()):  # a new file starts with them,
                        if old is not item:  # logged at its start
                            total += part.write(old[:3] + (stamp,) + old[4:])
                total += part.write(item)
                self.written += 1
        except _Full as exc:
            self.failed = str(exc)
            self._on_error(self.failed)
        except OSError as exc:  # a full disk, a folder gone
            self.failed = (f'the recording stopped: {exc.strerror or exc} writing to '
                           f'{self.folder}; the bag so far is closed and opens')
            self._on_error(self.failed)
        finally:
            try:
                if part is not None:
                    done.append(part.close())
                if done:
                    self._write_metadata(done)
            except OSError as exc:
                log.error('the bag could not be closed: %s', exc)

    def _write_metadata(self, records: list) -> None:
        import yaml
        tmp = self.folder / 'metadata.yaml.tmp'
        # libyaml's dumper where PyYAML has it: the same text, a fifth of the pure-Python
        # dumper's 2.3 ms, twice a wall second on the writer's thread (which shares the GIL)
        dumper = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)
        with open(tmp, 'w', encoding='utf8') as f:
            yaml.dump(_metadata(records), f, Dumper=dumper, default_flow_style=False,
                      sort_keys=False)
        os.replace(tmp, self.folder / 'metadata.yaml')  # atomic: a reader never sees half


class _Part:
    """
    One file of the bag while it is written: a rosbags writer in ``<bag>/<name>_<n>/``.

    Closed, its MCAP file moves to ``<bag>/<name>_<n>.mcap`` and its own metadata.yaml goes:
    the bag's one metadata.yaml lists it (see :func:`_metadata`).
    """

    def __init__(self, bag: Path, n: int, store, start: int):
        from rosbags.rosbag2 import StoragePlugin, Writer
        self.name = f'{bag.name}_{n}'
        self.bag, self.store, self.start, self.size = bag, store, start, 0
        self.writer = Writer(bag / self.name, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections: dict = {}

    def write(self, item) -> int:
        """Write one queued message; return its bytes (0: a type not known here)."""
        topic, msgtype, data, stamp, is_latched, reliable = item
        conn = self.connections.get(topic)
        if conn is None:
            if msgtype not in self.store.types and not _register(self.store, msgtype):
                log.warning('not recording %s: its type %s is unknown here', topic, msgtype)
                self.connections[topic] = conn = False
            else:
                conn = self.connections[topic] = self.writer.add_connection(
                    topic, msgtype, typestore=self.store,
                    offered_qos_profiles=[qos(is_latched, reliable)])
        if conn is False:
            return 0
        self.writer.write(conn, stamp, data)
        self.size += len(data)
        return len(data)

    def flush(self) -> None:
        """Put what was written into the file as a closed chunk (readable after a kill -9)."""
        storage = self.writer.storage
        if storage.chunk.bio.tell():
            storage.close_chunk()
        storage.bio.flush()

    def record(self, path: Optional[str] = None) -> dict:
        """Return what metadata.yaml says of this file (written so far)."""
        from rosbags.rosbag2.metadata import dump_qos_v9
        w = self.writer
        counts = {x.id: w.counts.get(x.id, 0) for x in w.connections}
        start = w.min_timestamp if sum(counts.values()) else self.start
        return {
            'path': path or f'{self.name}/{self.name}.mcap',
            'start': start, 'end': max(w.max_timestamp, start), 'count': sum(counts.values()),
            'topics': [({'name': x.topic, 'type': x.msgtype,
                         'serialization_format': x.ext.serialization_format,
                         'offered_qos_profiles': dump_qos_v9(x.ext.offered_qos_profiles),
                         'type_description_hash': x.digest}, counts[x.id])
                       for x in w.connections]}

    def close(self) -> dict:
        """Close the file, move it into the bag; return its record."""
        record = self.record(f'{self.name}.mcap')
        self.writer.close()
        folder = self.bag / self.name
        os.replace(folder / f'{self.name}.mcap', self.bag / f'{self.name}.mcap')
        (folder / 'metadata.yaml').unlink(missing_ok=True)
        folder.rmdir()
        return record


def _metadata(records: list) -> dict:
    """Return the bag's metadata.yaml (rosbag2 version 9) listing the files of `records`."""
    start = min(r['start'] for r in records)
    end = max(r['end'] for r in records)
    topics: dict = {}  # name -> [topic metadata, count]
    for r in records:
        for meta, count in r['topics']:
            topics.setdefault(meta['name'], [meta, 0])[1] += count
    return {'rosbag2_bagfile_information': {
        'version': 9, 'storage_identifier': 'mcap',
        'relative_file_paths': [r['path'] for r in records],
        'duration': {'nanoseconds': end - start},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(r['count'] for r in records),
        'topics_with_message_count': [{'topic_metadata': meta, 'message_count': count}
                                      for meta, count in topics.values()],
        'compression_format': '', 'compression_mode': '',
        'files': [{'path': r['path'], 'starting_time': {'nanoseconds_since_epoch': r['start']},
                   'duration': {'nanoseconds': r['end'] - r['start']},
                   'message_count': r['count']} for r in records],
        'custom_data': None, 'ros_distro': 'rosbags'}}


class _Full(Exception):
    """The recording reached its total size."""
