"""The path scripts import :mod:`sim_node.core.base.config` by; it holds the same names."""

from .base.config import *  # noqa: F401,F403
