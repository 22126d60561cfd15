"""Older path of :mod:`sim_node.ros.qos`, kept for existing scripts."""

from .ros.qos import *  # noqa: F401,F403
