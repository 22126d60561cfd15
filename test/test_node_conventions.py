"""ROS conventions as users meet them: integers typed for double parameters, and /clock that
goes on while the simulation is paused."""

import time

from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters

from conftest import NodeProcess, Watcher, wait_for
from sim_node.client import SimClient


def set_param(sim: SimClient, name: str, value: ParameterValue):
    req = SetParameters.Request(parameters=[ParameterMsg(name=name, value=value)])
    return sim.call('sim/set_parameters', SetParameters, req).results[0]


def test_integers_for_doubles_and_clock_while_paused(rclpy_context):
    node = NodeProcess('real_time_factor:=0', 'kp:=300')  # integers, as the README types them
    sim = SimClient(timeout_sec=30)
    watch = Watcher()
    try:
        got = sim.call('sim/get_parameters', GetParameters,
                       GetParameters.Request(names=['real_time_factor', 'kp'])).values
        assert [(v.type, v.double_value) for v in got] == [
            (ParameterType.PARAMETER_DOUBLE, 0.0), (ParameterType.PARAMETER_DOUBLE, 300.0)]
        t0 = wait_for(watch.latest_clock)
        time.sleep(1.0)
        assert watch.latest_clock() - t0 > 2.0  # as fast as possible: far beyond real time
        ok = set_param(sim, 'real_time_factor',
                       ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=1))
        assert ok.successful, ok.reason
        for bad in (ParameterValue(type=ParameterType.PARAMETER_STRING, string_value='1'),
                    ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=-1)):
            assert not set_param(sim, 'real_time_factor', bad).successful
        # Paused: /clock keeps coming, with the same time.
        sim.pause()
        time.sleep(0.3)
        n0 = len(watch.clock)
        time.sleep(1.0)
        with watch.lock:
            paused = watch.clock[n0:]
        assert len(paused) > 50 and len(set(paused)) == 1
    finally:
        watch.close()
        sim.close()
        node.close()
