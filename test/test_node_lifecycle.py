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
