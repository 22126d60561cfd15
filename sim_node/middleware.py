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
* glibc raises its mmap threshold after a large block is freed, so the next ones (a 10 MB name
  copied between the middleware and Python) land in the heap and stay. A fixed threshold of
  :data:`MMAP_THRESHOLD_BYTES` keeps every large block in its own mapping, unmapped when freed.
"""

import ctypes
import logging
import os
from pathlib import Path

log = logging.getLogger(__name__)

PROFILES = Path(__file__).with_name('fastdds_profiles.xml')
#: Blocks this large or larger get their own mapping (glibc's M_MMAP_THRESHOLD, fixed).
MMAP_THRESHOLD_BYTES = 1 << 20
_M_MMAP_THRESHOLD = -3  # from glibc's malloc.h


def configure() -> list:
    """
    Apply both settings to this process; call before ``rclpy.init``.

    :returns: what was applied, for the log (empty on a system where neither applies).
    """
    done = []
    env = os.environ
    fastdds = env.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp').startswith('rmw_fastrtps')
    if (fastdds and PROFILES.is_file() and 'FASTRTPS_DEFAULT_PROFILES_FILE' not in env
            and 'RMW_FASTRTPS_USE_QOS_FROM_XML' not in env):
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILES)
        env['RMW_FASTRTPS_USE_QOS_FROM_XML'] = '1'
        done.append(f'Fast DDS profiles {PROFILES.name}')
    try:
        mallopt = ctypes.CDLL('libc.so.6').mallopt
    except (OSError, AttributeError):  # not glibc
        return done
    if mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1:
        done.append(f'mmap threshold {MMAP_THRESHOLD_BYTES >> 20} MiB')
    return done
