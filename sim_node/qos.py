"""Older path of :mod:`sim_node.ros.node.qos`, kept for existing scripts."""

from .ros.settings.qos import *  # noqa: F401,F403
