"""Older path of :mod:`sim_node.core.control.bases`, kept for existing scripts."""

from .control.bases import *  # noqa: F401,F403
from .control.drives import *  # noqa: F401,F403
