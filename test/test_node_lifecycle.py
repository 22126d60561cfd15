"""The installed executable starts, publishes /clock, and stops cleanly on SIGINT."""

from conftest import wait_for
import pytest


def test_node_publishes_clock_and_exits_cleanly_on_sigint(start_node, watcher):
    node = start_node()
    first = wait_for(watcher.latest_clock, timeout=20)
    later = wait_for(lambda: (watcher.latest_clock() or 0) > first + 0.2 and
                     watcher.latest_clock(), timeout=10)
    assert later > first
    code, _ = node.interrupt()  # killed after 5 s: how fast it ends is make bench-pacing's
    assert code == 0, node.output()


def test_bad_scene_parameter_exits_with_a_message(start_node):
    node = start_node('scene:=no_such_scene')
    code = node.proc.wait(20)
    assert code != 0
    assert 'no scene' in node.output() and 'default' in node.output()


@pytest.mark.parametrize('param, says', [
    ('real_time_factor:=fast', "parameter real_time_factor: 'fast' is a string, but it takes a "
                               'double'),
    ('tf_rate_hz:=0', 'parameter tf_rate_hz: 0.0 is out of its range, 1.0 to 1000.0'),
    ('max_bodies:=1.5', "parameter max_bodies: '1.5' is a double, but it takes an integer"),
    ('divergence_policy:=explode', "divergence_policy must be one of ['pause', 'remove', "
                                   "'reset'], got 'explode'"),
    ('mesh_decomposition:=sometimes', 'mesh_decomposition must be one of objects, all, none, '
                                      "got 'sometimes'"),
    ('mesh_decomposition:=off', "parameter mesh_decomposition: 'False' is a bool, but it takes "
                                'a string'),  # ROS reads off as false: hence none
    ('mesh_decomposition_threshold:=0', 'parameter mesh_decomposition_threshold: 0.0 is out of '
                                        'its range, 0.001 to 1.0'),
])
def test_a_wrong_parameter_ends_the_start_with_one_line_and_status_2(start_node, param, says):
    node = start_node(param)
    assert node.proc.wait(20) == 2
    lines = node.output().strip().splitlines()
    assert lines == [f'[sim] cannot start: {says}'], node.output()


def test_an_unknown_parameter_is_named_with_the_closest_one(start_node, watcher):
    node = start_node('real_time_facter:=2.0')
    wait_for(watcher.latest_clock, timeout=20)
    assert "unknown parameter 'real_time_facter' ignored; did you mean 'real_time_factor'?" \
        in node.output()
    assert node.interrupt()[0] == 0


def test_a_clean_stop_prints_no_error(start_node, watcher):
    """Ctrl-C or SIGTERM while publishing: no ERROR line, nothing about a dead context."""
    import signal
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGINT, signal.SIGTERM):
        node = start_node()
        first = wait_for(watcher.latest_clock, timeout=20)
        wait_for(lambda: (watcher.latest_clock() or 0) > first + 0.5, timeout=10)
        node.proc.send_signal(sig)
        assert node.proc.wait(10) == 0, node.output()
        out = node.output()
        for bad in ('ERROR', 'Failed to publish', 'context is invalid', 'Traceback'):
            assert bad not in out, out
        watcher.clock.clear()


def test_sigterm_ends_a_busy_node_cleanly(start_node, watcher):
    """Status 0, no traceback (how fast: make bench-pacing, target within 2 s)."""
    import signal
    for _ in range(3):
        node = start_node('real_time_factor:=0')
        wait_for(watcher.latest_clock, timeout=20)
        node.proc.send_signal(signal.SIGTERM)
        code = node.proc.wait(10)
        assert code == 0, node.output()
        assert 'Traceback' not in node.output()
        watcher.clock.clear()


def test_sigterm_during_a_long_spawn_ends_the_node_cleanly(start_node, client, tmp_path):
    """A spawn compiling a 190k-face mesh (about 3 s here) is abandoned, not waited for."""
    import signal
    import threading
    import time
    from conftest import write_mesh_model
    model = write_mesh_model(tmp_path, 190_000)
    node = start_node(f"resource_paths:=['{tmp_path}']")
    client.entities()  # up and answering
    spawner = threading.Thread(target=lambda: _ignore(lambda: client.spawn(
        'big', uri=model.as_uri(), position=(0, 2, 1))), daemon=True)
    spawner.start()
    time.sleep(0.7)
    node.proc.send_signal(signal.SIGTERM)
    code = node.proc.wait(10)
    assert code == 0, node.output()
    assert 'Traceback' not in node.output()


def test_a_crash_in_native_code_prints_where_each_thread_was(start_node, watcher):
    """A segmentation fault (MuJoCo, the middleware, OpenGL) leaves the threads' stacks."""
    import signal
    node = start_node(namespace='/crasher')
    wait_for(lambda: (watcher.latest_clock() or 0) > 0.2, timeout=20)
    node.proc.send_signal(signal.SIGSEGV)  # as a fault in native code would raise it
    assert node.proc.wait(10) == -signal.SIGSEGV
    out = node.output()
    assert 'Fatal Python error: Segmentation fault' in out, out
    # the stepping thread's stack is among them
    assert 'sim_node/core/loop.py' in out, out


def _ignore(call) -> None:
    try:
        call()
    except Exception:  # noqa: B902 (the node went away mid-call, as intended)
        pass


def test_quitting_answers_ok_stops_then_exits_with_status_0(start_node, rclpy_context, watcher):
    """Quitting (SetSimulationState): reset (stop) first, answer, then the process ends."""
    from sim_node.ros.client import SimClient
    from simulation_interfaces.msg import SimulationState
    # A namespace of its own: a node killed earlier may linger in the graph for seconds
    node = start_node(namespace='/quitter')
    client = SimClient(namespace='/quitter', timeout_sec=30)
    client.spawn('crate', uri='box', position=(0.3, 2.0, 1.0))
    wait_for(lambda: (watcher.latest_clock() or 0) > 0.5, timeout=20)
    client.set_state(SimulationState.STATE_QUITTING)  # raises unless the answer is OK
    code = node.proc.wait(5)
    assert code == 0, node.output()
    out = node.output()
    assert 'Traceback' not in out and '[ERROR]' not in out, out
    # stopped before it went: the last /clock is back at the start
    wait_for(lambda: watcher.latest_clock() == 0.0, timeout=2)
    # its services are gone (the client's own clients stay in the graph: count servers)
    wait_for(lambda: client.node.count_services('/quitter/get_simulation_state') == 0,
             timeout=10)
    client.close()


def test_a_second_simulator_in_the_same_namespace_refuses_to_start(start_node, client):
    """Two would answer service calls at random: the second exits 2 with one line saying why."""
    first = start_node()
    client.entities()  # the first is up and answering
    second = start_node()
    assert second.proc.wait(45) == 2
    out = second.output()
    assert 'another simulator already runs' in out and '__ns:=' in out, out
    assert first.proc.poll() is None, first.output()  # the older one stays
    assert 'Traceback' not in out
    third = start_node('allow_second_simulator:=true', 'publish_clock:=false')
    import time
    time.sleep(3.0)
    assert third.proc.poll() is None, third.output()  # allowed: it runs


def test_a_young_node_says_again_every_second_that_it_runs(start_node, watcher):
    """A node that starts beside it hears it even if the latched message missed that node."""
    from std_msgs.msg import String
    heard = []  # a volatile reader: only what is said after it joined
    watcher.node.create_subscription(String, '/_sim_instances', lambda m: heard.append(m.data),
                                     10)
    start_node()
    wait_for(lambda: len(heard) >= 3, timeout=30)
    assert len(set(heard)) == 1, heard


def test_a_killed_test_run_leaves_no_node_running(tmp_path):
    """The nodes a test process started end with it, even when it is killed (SIGKILL)."""
    import os
    import subprocess
    import sys
    import time
    pid_file = tmp_path / 'node.pid'
    script = ('import sys, time; sys.path.insert(0, %r); from conftest import NodeProcess; '
              'p = NodeProcess(); open(%r, "w").write(str(p.proc.pid)); time.sleep(60)'
              % (os.path.dirname(__file__), str(pid_file)))
    runner = subprocess.Popen([sys.executable, '-c', script])
    try:
        wait_for(lambda: pid_file.exists() and pid_file.read_text(), timeout=20)
        node_pid = int(pid_file.read_text())
        time.sleep(1.0)  # the node is up
        runner.kill()
        runner.wait()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and _alive(node_pid):
            time.sleep(0.1)
        assert not _alive(node_pid), 'the node outlived the process that started it'
    finally:
        runner.kill()


def _alive(pid: int) -> bool:
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().split()[2] != 'Z'  # a zombie has ended
    except FileNotFoundError:
        return False
