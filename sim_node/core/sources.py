"""Older path of :mod:`sim_node.core.models.sources`, kept for existing scripts."""

from .models.sources import *  # noqa: F401,F403
