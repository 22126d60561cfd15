"""The installed executable starts, publishes /clock, and stops cleanly on SIGINT."""

from conftest import wait_for


def test_node_publishes_clock_and_exits_cleanly_on_sigint(start_node, watcher):
    node = start_node()
    first = wait_for(watcher.latest_clock, timeout=20)
    later = wait_for(lambda: (watcher.latest_clock() or 0) > first + 0.2 and
                     watcher.latest_clock(), timeout=10)
    assert later > first
    code, seconds = node.interrupt()
    assert code == 0, node.output()
    assert seconds < 2.0, f'took {seconds:.2f} s to stop'


def test_bad_scene_parameter_exits_with_a_message(start_node):
    node = start_node('scene:=no_such_scene')
    code = node.proc.wait(20)
    assert code != 0
    assert 'no scene' in node.output() and 'default' in node.output()


def test_sigterm_ends_a_busy_node_cleanly_within_two_seconds(start_node, watcher):
    import signal
    import time
    for _ in range(3):
        node = start_node('real_time_factor:=0')
        wait_for(watcher.latest_clock, timeout=20)
        t0 = time.monotonic()
        node.proc.send_signal(signal.SIGTERM)
        code = node.proc.wait(10)
        assert code == 0 and time.monotonic() - t0 < 2.0, node.output()
        assert 'Traceback' not in node.output()
        watcher.clock.clear()
