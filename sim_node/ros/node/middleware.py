"""
Process settings the node makes before rclpy starts: memory comes back after large requests.

Two things kept a refused request's memory for the life of the node (measured with a 50 MB
``resource_string`` and three 10 MB names: 49-77 MiB kept):

* Fast DDS's request readers keep every payload in a pool that only grows
  (``PREALLOCATED_WITH_REALLOC``, what rmw_fastrtps sets for every endpoint). The node loads
  ``fastdds_profiles.xml``, which keeps rmw_fastrtps' settings for every endpoint but gives
  service request readers ``DYNAMIC`` memory (freed with each request). Only when the user has
  not configured Fast DDS already (``FASTRTPS_DEFAULT_PROFILES_FILE`` or
  ``RMW_FASTRTPS_USE_QOS_FROM_XML`` set, or another middleware chosen): theirs wins.
* glibc's allocator kept large blocks in its heap: see
  :func:`~sim_node.core.base.memory.keep_large_blocks_mapped`.
"""

import os
from pathlib import Path

from ...core.base import memory

PROFILES = Path(__file__).with_name('fastdds_profiles.xml')


def configure() -> None:
    """Apply both settings to this process; call before ``rclpy.init``."""
    env = os.environ
    fastdds = env.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp').startswith('rmw_fastrtps')
    if (fastdds and PROFILES.is_file() and 'FASTRTPS_DEFAULT_PROFILES_FILE' not in env
            and 'RMW_FASTRTPS_USE_QOS_FROM_XML' not in env):
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILES)
        env['RMW_FASTRTPS_USE_QOS_FROM_XML'] = '1'
    memory.keep_large_blocks_mapped()
