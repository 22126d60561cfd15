"""
Older path of :mod:`sim_node.gym.env`, kept for existing scripts.

``gymnasium.make('sim_node.gym_env:sim/PushBox-v0')`` imports this module: the ids are
registered on import, as they are by :mod:`sim_node.gym.env`.
"""

from .gym.env import *  # noqa: F401,F403
from .gym.env import register_envs, Task  # noqa: F401 (named by older code)
