"""
One simulator per name: a newer node beside an older one says why and exits with status 2.

Two would answer one service name at random (seen: 3 of 4 fresh clients talked to one, the
other to the other) and publish two /clock. Each node publishes its start (wall time, pid, host)
on the hidden, latched ``_sim_instances`` topic of its namespace; for a window after its start a
node listens there, and leaves if it hears of an older one (the older never yields, so exactly
one stays). DDS discovery takes about 3 s here: a check before starting would delay every start
by as much.
"""

import os
import socket
import threading
import time
from typing import Callable

from rclpy.node import Node
from std_msgs.msg import String

from ..settings.qos import LATCHED_QOS

DUPLICATE_WINDOW_SEC = 30.0
#: During its window a node says it again this often: a node that starts beside it hears it
#: even if the latched message missed it (a CI run once saw a second node hear nothing in 15 s).
REANNOUNCE_SEC = 1.0
ERR_SECOND_SIMULATOR = ('another simulator already runs in namespace {ns!r}: start '
                        'this one in a namespace of its own with a frame prefix (--ros-args -r '
                        '__ns:=/sim2 -p frame_prefix:=sim2/ -p publish_clock:=false, see the '
                        'README), or set allow_second_simulator:=true')


def announce(node: Node, callback_group, leave: Callable[[str], None], listen: bool,
             window_sec: float = DUPLICATE_WINDOW_SEC) -> None:
    """
    Publish this node's start; if `listen`, call ``leave(why)`` on hearing of an older one.

    `leave` runs once, on a thread of its own.
    """
    me = f'{time.time():.6f} {os.getpid()} {socket.gethostname()}'
    pub = node.create_publisher(String, '_sim_instances', LATCHED_QOS)
    pub.publish(String(data=me))
    if not listen:
        return
    deadline = time.monotonic() + window_sec
    left = threading.Event()

    def heard(msg: String) -> None:
        if time.monotonic() > deadline or msg.data == me or left.is_set():
            return
        try:
            older = (float(msg.data.split()[0]), msg.data) < (float(me.split()[0]), me)
        except (ValueError, IndexError):
            return  # not ours
        if older:
            left.set()
            why = ERR_SECOND_SIMULATOR.format(ns=node.get_namespace())
            threading.Thread(target=leave, args=(why,), name='sim-leave', daemon=True).start()
    node.create_subscription(String, '_sim_instances', heard, LATCHED_QOS,
                             callback_group=callback_group)

    def again() -> None:
        if time.monotonic() > deadline or left.is_set():
            timer.cancel()
            return
        pub.publish(String(data=me))
    timer = node.create_timer(REANNOUNCE_SEC, again, callback_group=callback_group)
