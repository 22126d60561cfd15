"""The path scripts import :mod:`sim_node.core.base.records` by; it holds the same names."""

from .base.records import *  # noqa: F401,F403
