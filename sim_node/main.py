"""Entry point of `ros2 run sim node`: start the node and its loop; stop cleanly on SIGINT."""

import sys

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor

from .core.errors import SimError


def main(args=None) -> int:
    rclpy.init(args=args)  # returns None on Jazzy: no `with` block
    node = executor = None
    code = 0
    try:
        from .node import SimNode
        node = SimNode()
        executor = MultiThreadedExecutor(num_threads=4)
        executor.add_node(node)
        node.start()  # the loop thread starts here, not in __init__
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:  # noqa: B902
        if rclpy.ok():
            raise
        # SIGINT or SIGTERM shut the context down while the executor was building its wait
        # set: rclpy raises from there. That is a normal shutdown, not a failure.
    except SimError as exc:
        print(f'[sim] cannot start: {exc}', file=sys.stderr)
        code = 2
    finally:
        # Order matters: the loop first, then the executor, then the node.
        if node is not None:
            node.shutdown()
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
