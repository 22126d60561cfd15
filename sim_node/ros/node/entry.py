"""
The first code `ros2 run sim node` runs: a process setting that must come before any thread.

glibc fixes how many heaps its allocator may make when a second thread first allocates, and
importing rclpy, numpy or MuJoCo starts threads that allocate (three heaps were already made
once those were imported, measured): so the node's heap setting
(:func:`~sim_node.core.base.memory.share_one_heap`) is made here, before :mod:`.main` and what
it imports. Nothing here imports more than the standard library.
"""

from ...core.base import memory


def main(args=None) -> int:
    """Share one heap among the node's threads, then run the node (:func:`.main.main`)."""
    memory.share_one_heap()
    from .main import main as run_node
    return run_node(args)
