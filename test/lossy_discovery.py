"""
Discovery that loses announcements, for the reply tests (issue 52, item 4).

How a reply came to be lost: a node learns of a new client from two announcements the client's
participant sends to the node's discovery (metatraffic) port, one for the client's reply reader
and one for its request writer. rmw_fastrtps makes the reader first, and the node takes the
two in the order they came on one thread, so on a quiet loopback the reader is always matched
before the request can be taken. When the reader's announcement is lost and the writer's is not,
the node takes the request, tries to reply to a reader it does not know yet, and the middleware
drops the reply after its 100 ms wait; the client's participant sends the reader's announcement
again only when the node's discovery asks for what it missed (here 0.1 to 2 s later). A loaded
or lossy host loses such datagrams: a socket whose receive buffer is full drops what comes.

Here that is made to happen on purpose, to the node under test and to nobody else: a
:class:`Flood` keeps the node's discovery port so busy with junk datagrams that about a tenth of
what comes to it is dropped (read from the kernel's count of that socket's drops, and held
there: more junk when fewer are dropped, less when more). Clients made afresh then race as
described, one in ten to twenty here.

Run as a script, this file is the flood: ``<stop file> <pid> <port>``; it goes on until its stop
file exists (or LONGEST_SEC pass), then prints one JSON line of what it did.
"""

import json
import os
from pathlib import Path
import socket
import subprocess
import sys
import time

#: RTPS's well-known ports: the discovery (metatraffic unicast) port of participant `i` in domain
#: `d` is PORT_BASE + DOMAIN_GAIN * d + META_UNICAST_OFFSET + PARTICIPANT_GAIN * i.
PORT_BASE, DOMAIN_GAIN, PARTICIPANT_GAIN, META_UNICAST_OFFSET = 7400, 250, 2, 10
#: The share of the discovery port's datagrams the flood has the kernel drop: low enough that
#: most announcements come through (the node must go on discovering), high enough that among
#: a few hundred fresh clients some lose their reader's announcement and not their writer's.
TARGET_DROP = (0.05, 0.2)
#: Junk datagrams: about the size of an announcement, so both fit in a full buffer alike.
JUNK_BYTES = 300


def _udp_sockets(pid: int) -> dict:
    """Return {local port: (inode, drops)} of the UDP sockets process `pid` holds."""
    inodes = set()
    for fd in Path(f'/proc/{pid}/fd').iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    found = {}
    for line in Path(f'/proc/{pid}/net/udp').read_text().splitlines()[1:]:
        fields = line.split()
        if fields[9] in inodes:
            found[int(fields[1].split(':')[1], 16)] = (fields[9], int(fields[-1]))
    return found


def discovery_port(pid: int, domain: int, timeout: float = 20.0) -> int:
    """Return the discovery port of process `pid`'s participant in `domain`, once it is bound."""
    first = PORT_BASE + DOMAIN_GAIN * domain + META_UNICAST_OFFSET
    deadline = time.monotonic() + timeout
    while True:
        ports = [p for p in _udp_sockets(pid)
                 if p >= first and (p - first) % PARTICIPANT_GAIN == 0 and p < first + 240]
        if ports:
            return min(ports)
        if time.monotonic() > deadline:
            raise RuntimeError(f'process {pid} bound no discovery port in domain {domain}')
        time.sleep(0.2)


#: The longest the flood runs if nobody stops it (s).
LONGEST_SEC = 600.0


class Flood:
    """Junk to process `pid`'s discovery `port` (see the module) until `stop()`."""

    def __init__(self, stop_file: Path, pid: int, port: int):
        self.stop_file = Path(stop_file)
        self.stop_file.unlink(missing_ok=True)
        self.proc = subprocess.Popen(
            [sys.executable, __file__, str(stop_file), str(pid), str(port)],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def stop(self, timeout: float = 10.0) -> dict:
        """End the flood; return what it sent and what the port dropped meanwhile."""
        self.stop_file.touch()
        out, _ = self.proc.communicate(timeout=timeout)
        lines = [ln for ln in out.splitlines() if ln.startswith('{')]
        assert self.proc.returncode == 0 and lines, out
        return json.loads(lines[-1])

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.communicate()


def _flood(stop_file: str, pid: int, port: int) -> dict:
    """Send junk in bursts each millisecond, the burst steered to drop TARGET_DROP of it."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    junk = b'\0' * JUNK_BYTES
    burst, sent, shares = 100, 0, []
    start_drops = last_drops = _udp_sockets(pid)[port][1]
    last_sent, next_look = 0, time.monotonic() + 0.5
    end = time.monotonic() + LONGEST_SEC
    while time.monotonic() < end and not os.path.exists(stop_file):
        for _ in range(burst):
            sock.sendto(junk, ('127.0.0.1', port))
        sent += burst
        time.sleep(0.001)
        if time.monotonic() >= next_look:
            drops = _udp_sockets(pid)[port][1]
            share = (drops - last_drops) / max(1, sent - last_sent)
            shares.append(round(share, 3))
            if share < TARGET_DROP[0]:
                burst = min(2000, int(burst * 1.3) + 1)
            elif share > TARGET_DROP[1]:
                burst = max(10, int(burst / 1.3))
            last_drops, last_sent, next_look = drops, sent, time.monotonic() + 0.5
    dropped = _udp_sockets(pid)[port][1] - start_drops
    return {'sent': sent, 'dropped': dropped, 'last_burst': burst, 'shares': shares}


if __name__ == '__main__':
    print(json.dumps(_flood(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))))
