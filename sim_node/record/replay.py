"""
``python -m sim_node.record.replay [--wait S] [--web PORT] <bag or folder>``: see a recording.

Prints each bag's topics with their types, message counts and durability, its simulated
duration and its first and last log times; with ``--echo TOPIC``, the first message of that
topic too. With ``--web PORT``, plays a node's recording into a browser page at
http://localhost:PORT in its simulated time (:mod:`.playback`), then keeps the last picture for
``--hold`` seconds (default: until Ctrl-C). For a user with ROS: ``ros2 bag play`` and Foxglove
open the same bags.
"""

import argparse
from pathlib import Path
import sys
import time


def mcap_files(bag: Path) -> list:
    """Return a bag's MCAP files: closed ones, and one still being written (in a folder)."""
    return sorted(bag.glob('*.mcap')) + sorted(bag.glob('*/*.mcap'))


def bags_in(path: Path) -> list:
    """Return the bag folders at `path` (closed or still open): itself, or those inside it."""
    def is_bag(p: Path) -> bool:
        return (p / 'metadata.yaml').is_file() or bool(mcap_files(p))
    if not path.is_dir():
        return []
    if is_bag(path):
        return [path]
    return sorted((p for p in path.iterdir() if p.is_dir() and is_bag(p)),
                  key=lambda p: (len(p.name), p.name))


def _unclosed(bag: Path) -> list:
    """Lines for a bag still being written, or cut (a kill -9): its MCAP files as streams."""
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader
    lines = []
    for f in mcap_files(bag):
        schemas, channels, counts, times = {}, {}, {}, []
        with open(f, 'rb') as stream:
            try:
                for record in StreamReader(stream).records:
                    if isinstance(record, Schema):
                        schemas[record.id] = record.name
                    elif isinstance(record, Channel):
                        channels[record.id] = (record.topic, schemas.get(record.schema_id, ''))
                    elif isinstance(record, Message):
                        counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
                        times.append(record.log_time)
            except Exception:  # noqa: B902 (where it is being written, or was cut)
                pass
        span = (max(times) - min(times)) / 1e9 if times else 0.0
        lines.append(f'{f}: not closed: {sum(counts.values())} messages over {span:.3f} s of '
                     'simulated time, read up to its last whole record')
        for cid, (topic, msgtype) in sorted(channels.items(), key=lambda c: c[1][0]):
            lines.append(f'  {topic:40s} {msgtype:45s} {counts.get(cid, 0):7d}')
    return lines


def summary(path: Path, echo: str = '') -> str:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import get_typestore, Stores
    lines = []
    for bag in bags_in(path):
        if not (bag / 'metadata.yaml').is_file() or any(bag.glob('*/*.mcap')):
            lines += _unclosed(bag)  # a file is still being written, or was cut
            continue
        with Reader(bag) as reader:
            lines.append(f'{bag}: {reader.message_count} messages over '
                         f'{reader.duration / 1e9:.3f} s of simulated time '
                         f'({reader.start_time / 1e9:.3f} to {reader.end_time / 1e9:.3f})')
            for c in sorted(reader.connections, key=lambda c: c.topic):
                qos = c.ext.offered_qos_profiles
                durability = qos[0].durability.name.lower() if qos else 'unknown'
                lines.append(f'  {c.topic:40s} {c.msgtype:45s} {c.msgcount:7d}  {durability}')
            if echo:
                store = get_typestore(Stores.ROS2_JAZZY)
                wanted = [c for c in reader.connections if c.topic == echo]
                for conn, stamp, data in reader.messages(connections=wanted):
                    lines.append(f'  first {echo} at {stamp / 1e9:.3f} s: '
                                 f'{store.deserialize_cdr(data, conn.msgtype)}')
                    break
    if not lines:
        raise SystemExit(f'no bag at {path} (a folder with metadata.yaml, or one holding such)')
    return '\n'.join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog='python -m sim_node.record.replay',
                                description=__doc__.split('\n')[1])
    p.add_argument('path', type=Path)
    p.add_argument('--echo', default='', help='print the first message of this topic')
    p.add_argument('--wait', type=float, default=0.0,
                   help='seconds to wait for a bag to appear (a recording about to start)')
    p.add_argument('--web', type=int, default=0,
                   help='play it into a browser page on this port (0: only the summary)')
    p.add_argument('--speed', type=float, default=1.0, help='playback speed (1: real time)')
    p.add_argument('--hold', type=float, default=-1.0,
                   help='seconds to keep the page after the end (default: until Ctrl-C)')
    args = p.parse_args(argv)
    deadline = time.monotonic() + args.wait
    while not any(f.stat().st_size for b in bags_in(args.path) for f in mcap_files(b)) \
            and time.monotonic() < deadline:
        time.sleep(0.2)
    print(summary(args.path, args.echo), flush=True)
    if args.web:
        return _play(bags_in(args.path), args)
    return 0


def _play(bags: list, args) -> int:
    from .playback import BagPlayer
    player = BagPlayer(bags, port=args.web, speed=args.speed)
    print(f'replaying into {player.url} (Ctrl-C ends)', flush=True)
    try:
        length = player.play()
        print(f'replayed {length:.3f} s of simulated time', flush=True)
        time.sleep(args.hold if args.hold >= 0 else 1e9)
    except KeyboardInterrupt:
        pass
    finally:
        player.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
