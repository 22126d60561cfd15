"""Entry point of `ros2 run sim node`: start the node and its loop; stop cleanly on SIGINT."""

import faulthandler
import os
import sys
import threading
import time

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor

from . import middleware
from ..settings.params import parameter_error
from ...core.base import memory
from ...core.base.errors import SimError
from ...core.models import asset_store

#: How long a thread may hold the GIL before another that waits for it gets it (s; Python's
#: default is 0.005). The stepping loop needs the GIL for a moment between batches of
#: ``mj_step`` (which releases it); the executor's threads hold it for milliseconds of pure
#: Python per callback. With both mobile bases of the mobile scene driven, the loop stepped at
#: 55,000-82,000 steps/s with the default and 81,000-85,000 with this (``make bench-bases``).
SWITCH_INTERVAL_SEC = 0.001
#: How long main waits, after the node's shutdown, for its threads to end (s; see
#: :func:`_join_own_threads`).
OWN_THREADS_SEC = 3.0
#: How long destroying the node and shutting rclpy down may take before the process leaves
#: with every thread's stack printed and exit code 1 (s). Fast DDS 2.14, as the PyPI wheels
#: build it, deletes the node's participant by waiting, with the participant's listener
#: mutex held, for any discovery callback in flight to end; the wait never lets the mutex
#: go, so a callback that came just then (another process leaving) blocks on it for ever and
#: the process spins on a core, the GIL held, until it is killed (seen with gdb in a client
#: of ``make bench-storm``: 10 minutes in ``DomainParticipant::set_listener`` under
#: ``rmw_destroy_node``). ``faulthandler``'s timer needs no GIL, so it still ends it.
TEARDOWN_SEC = 10.0
#: The node's threads waited for at exit (by name; ``sim-listen`` and ``sim-publisher`` stand
#: for every thread whose name begins so): those that touch ROS once started. Not the ones
#: that live as long as the process (the replies' resender, the mesh converters' reaper), nor
#: a spawn's helpers (mesh conversion, xacro), which the exit abandons with their spawn.
ROS_THREADS = ('sim-listen', 'sim-perception', 'sim-publisher', 'sim-clock', 'sim-commands',
               'sim-loop', 'sim-session', 'sim-viewer', 'sim-web-view', 'sim-recorder')


def main(args=None) -> int:
    # A crash in native code (MuJoCo, the middleware, OpenGL) prints every thread's Python
    # stack before the process dies: a node that ends on a signal says where it was.
    faulthandler.enable()
    middleware.configure()  # before rclpy reads the environment
    sys.setswitchinterval(SWITCH_INTERVAL_SEC)
    rclpy.init(args=args)  # returns None on Jazzy: no `with` block
    node = executor = None
    code = 0
    try:
        from .node import SimNode
        node = SimNode()
        executor = MultiThreadedExecutor(num_threads=4)
        executor.add_node(node)
        node.start()  # the loop thread starts here, not in __init__
        memory.freeze_long_lived()  # later full collections walk only what came after
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SimError as exc:
        print(f'[sim] cannot start: {exc}', file=sys.stderr)
        code = 2
    except ParameterException as exc:  # a wrong type or range on the command line
        print(f'[sim] cannot start: {parameter_error(exc)}', file=sys.stderr)
        code = 2
    except Exception:  # noqa: B902
        if rclpy.ok():
            raise
        # SIGINT or SIGTERM shut the context down while the executor was building its wait
        # set: rclpy raises from there. That is a normal shutdown, not a failure.
    finally:
        # Order matters: the loop first, then the executor, then the node.
        if node is not None:
            node.shutdown()
            _join_own_threads(OWN_THREADS_SEC)
        if executor is not None:
            executor.shutdown(timeout_sec=0.5)
        faulthandler.dump_traceback_later(TEARDOWN_SEC, exit=True)  # see TEARDOWN_SEC
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        faulthandler.cancel_dump_traceback_later()
    code = code or getattr(node, 'exit_code', 0)  # 2: another simulator had this name
    _exit_if_busy(code)
    return code


def _join_own_threads(timeout: float) -> None:
    """
    Wait (at most `timeout` s in all) for the node's threads to end before ROS is torn down.

    Each was told to stop by the node's shutdown, and joined there for a while; one that was
    still in a listener's hook (publishers and servers of a new model) or a first render when
    that wait ran out would otherwise meet its node or the middleware destroyed under it
    (:data:`ROS_THREADS`). One still alive at the end is left to the exit.
    """
    end = time.monotonic() + timeout
    for thread in threading.enumerate():
        if thread is not threading.current_thread() and thread.name.startswith(ROS_THREADS):
            thread.join(max(0.0, end - time.monotonic()))


def _exit_if_busy(code: int) -> None:
    """
    Exit now if a callback is still working (a spawn compiling a large model, say).

    Python would otherwise wait for the executor's worker threads at exit: SIGTERM 1.5 s into
    a long spawn left the process alive for seconds. Everything that needs an orderly end
    (the loop, the publishers, the node, rclpy) has ended by now.
    """
    busy = [t for t in threading.enumerate()
            if t is not threading.main_thread() and not t.daemon and t.is_alive()]
    if busy:
        sys.stdout.flush()
        sys.stderr.flush()
        asset_store.store().remove()  # os._exit runs no atexit: the copies of model files go here
        os._exit(code)


if __name__ == '__main__':
    sys.exit(main())
