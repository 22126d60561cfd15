"""The path scripts import :mod:`sim_node.core.base.errors` by; it holds the same names."""

from .base.errors import *  # noqa: F401,F403
