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


def test_sigterm_during_a_long_spawn_ends_the_node_within_two_seconds(start_node, client,
                                                                      tmp_path):
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
    t0 = time.monotonic()
    node.proc.send_signal(signal.SIGTERM)
    code = node.proc.wait(10)
    assert code == 0 and time.monotonic() - t0 < 2.0, node.output()
    assert 'Traceback' not in node.output()


def _ignore(call) -> None:
    try:
        call()
    except Exception:  # noqa: B902 (the node went away mid-call, as intended)
        pass
