"""Older path of :mod:`sim_node.ros.client`, kept for existing scripts."""

from .ros.client.sim_client import *  # noqa: F401,F403
