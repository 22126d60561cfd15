"""Older path of :mod:`sim_node.core.stepping.loop`, kept for existing scripts."""

from .stepping.loop import *  # noqa: F401,F403
