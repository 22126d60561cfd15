"""Older path of :mod:`sim_node.core.devices.lidar`, kept for existing scripts."""

from .devices.lidar import *  # noqa: F401,F403
