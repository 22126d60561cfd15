"""Older path of :mod:`sim_node.core.devices.cameras`, kept for existing scripts."""

from .devices.cameras import *  # noqa: F401,F403
