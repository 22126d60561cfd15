"""
The node tells when the physics cannot keep the requested real-time factor.

And keeps /tf at its rate.
"""

import time

from conftest import NodeProcess, wait_for, Watcher
from sim_node.client import SimClient
from simulation_interfaces.srv import GetSimulationState


def test_get_simulation_state_says_when_the_factor_is_not_kept(rclpy_context):
    node = NodeProcess('real_time_factor:=1000.0')
    sim = SimClient(timeout_sec=30)
    watch = Watcher()
    try:
        def message():
            return sim.call('get_simulation_state', GetSimulationState,
                            GetSimulationState.Request()).result.error_message
        text = wait_for(message, timeout=15, interval=0.5)
        assert 'cannot keep real_time_factor 1000' in text
        wait_for(lambda: 'cannot keep' in node.output(), timeout=5)  # the log says it, once
        time.sleep(2.5)
        assert node.output().count('cannot keep') == 1
        n0, t0 = len(watch.tf_stamps), time.monotonic()
        time.sleep(2.0)
        rate = (len(watch.tf_stamps) - n0) / (time.monotonic() - t0)
        assert rate > 80, f'/tf at {rate:.0f} Hz, 100 wanted'
    finally:
        watch.close()
        sim.close()
        node.close()
