"""
ROS conventions as users meet them.

Integers typed for double parameters, and /clock that goes on while the simulation is paused.
"""

import threading
import time

from conftest import NodeProcess, wait_for, Watcher
import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from sim_node.ros.client import SimClient
from simulation_interfaces.msg import SimulationState


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


def test_two_worlds_in_one_domain_do_not_collide(rclpy_context):
    """The second world: its own namespace, no /clock, every frame under 'robot2/'."""
    first = NodeProcess()
    watch = Watcher()
    wait_for(watch.latest_clock)  # the first world runs ahead
    time.sleep(1.0)
    second = NodeProcess('publish_clock:=false', 'frame_prefix:=robot2/', namespace='/robot2')
    watch2 = Watcher(namespace='/robot2')
    try:
        wait_for(lambda: 'robot2/box_a' in watch.tf and 'box_a' in watch.tf, timeout=15)
        assert watch.tf['robot2/box_a'][1] == 'robot2/world'
        # links hang from the root body's own frame (the root link of robot_description)
        assert watch.tf['robot2/robot/left_link1'][1] == 'robot2/robot/robot'
        wait_for(lambda: watch.tf_static.get('robot2/robot/robot', (0, ''))[1] == 'robot2/robot')
        assert watch.tf['box_a'][1] == 'world'
        wait_for(lambda: watch2.markers, timeout=10)
        frames = {m.header.frame_id for m in watch2.markers.values()}
        assert frames and all(f.startswith('robot2/') for f in frames), frames
        n0 = len(watch.clock)
        time.sleep(1.5)
        with watch.lock:
            clock = watch.clock[n0:]
        assert len(clock) > 50 and all(b >= a for a, b in zip(clock, clock[1:]))
    finally:
        watch2.close()
        watch.close()
        second.close()
        first.close()


# A slide joint far too stiff for the time step, spawned 1 m away from its spring's rest length:
# its first step asks for 1e11 m/s^2, past MuJoCo's bound, whatever else acts on it. Spawned at
# rest length, it diverged only if it moved first: the node holds a newly spawned arm's joints
# where they are (trajectories._hold, PD plus gravity compensation), and when that hold came
# before the first step, the spring stayed exactly at rest and never diverged (1 run in 20 under
# load; the test waited 10 s for /diagnostics and failed CI twice).
STIFF = ('<mujoco><worldbody><body name="spring"><joint name="s" type="slide" axis="0 0 1" '
         'stiffness="1e9" springref="1"/><geom type="box" size=".05 .05 .05" mass=".01" '
         'contype="0" conaffinity="0"/></body></worldbody></mujoco>')


class DiagnosticsWatcher:
    """The newest /diagnostics status of the sim node, received on a thread of its own."""

    def __init__(self):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        self.latest = None
        self.node = rclpy.create_node(f'diag_watch_{id(self):x}')
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on, 10)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on(self, msg) -> None:
        for st in msg.status:
            if st.name.endswith(': physics'):
                self.latest = (st.level, st.message, {kv.key: kv.value for kv in st.values})

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.mark.parametrize('policy', ['pause', 'remove'])
def test_divergence_names_the_culprit_on_diagnostics_and_the_policy_acts(rclpy_context, policy):
    from diagnostic_msgs.msg import DiagnosticStatus
    node = NodeProcess(f'divergence_policy:={policy}')
    watch = DiagnosticsWatcher()
    sim = SimClient(timeout_sec=30)
    try:
        wait_for(lambda: watch.latest is not None and watch.latest[0] == DiagnosticStatus.OK,
                 timeout=15)
        sim.spawn('stiff', resource_string=STIFF, position=(2, 2, 1))
        wait_for(lambda: watch.latest[2].get('divergence_entity') == 'stiff', timeout=10)
        level, message, values = watch.latest
        assert "'stiff'" in message and values['divergence_action'] == policy
        if policy == 'pause':
            assert level == DiagnosticStatus.ERROR
            assert sim.state() == SimulationState.STATE_PAUSED
            assert 'stiff' in sim.entities()
        else:
            assert level == DiagnosticStatus.WARN
            assert sim.state() == SimulationState.STATE_PLAYING
            assert 'stiff' not in sim.entities()
    finally:
        sim.close()
        watch.close()
        code, _ = node.interrupt()
        assert code == 0, node.output()


def test_diagnostics_say_what_get_simulation_state_says_after_each_request(rclpy_context):
    """
    /diagnostics follows the session's one state, told at once with each change.

    At d48b79a the loop kept a state of its own: after a stop /diagnostics said paused while
    get_simulation_state said stopped.
    """
    node = NodeProcess()
    watch = DiagnosticsWatcher()
    sim = SimClient(timeout_sec=30)
    try:
        wait_for(lambda: watch.latest is not None, timeout=15)
        stop = lambda: sim.set_state(SimulationState.STATE_STOPPED)  # noqa: E731
        for request, state, word in ((stop, SimulationState.STATE_STOPPED, 'stopped'),
                                     (sim.play, SimulationState.STATE_PLAYING, 'playing'),
                                     (sim.pause, SimulationState.STATE_PAUSED, 'paused')):
            request()
            assert sim.state() == state
            # At once, not at the next once-a-second refresh.
            wait_for(lambda: watch.latest[2].get('state') == word, timeout=0.9)
            assert watch.latest[1] == word
    finally:
        sim.close()
        watch.close()
        code, _ = node.interrupt()
        assert code == 0, node.output()
