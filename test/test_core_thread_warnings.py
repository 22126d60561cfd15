"""
Warnings caught on the thread that raised them (`sim_node.core.base.thread_warnings`).

What went wrong: a spawn's compile caught its warnings with ``warnings.catch_warnings`` while a
service's thread was told its reply could not be sent; the compile took that warning too, and
the reply was never sent again (test_node_replies.py, under lossy discovery).
"""

import threading
import warnings

import mujoco
import pytest

from sim_node.core.base import thread_warnings


def test_a_warning_of_another_thread_is_not_caught_here_but_by_its_own_thread():
    other_heard = []

    def other():
        with thread_warnings.caught('failed to send response') as heard:
            warnings.warn('failed to send response (timeout)', RuntimeWarning)
        other_heard.extend(heard)
    with thread_warnings.caught('failed to send response', 'Attach conflict') as here:
        t = threading.Thread(target=other)
        t.start()
        t.join(5)
    assert here == [] and other_heard == ['failed to send response (timeout)']


def test_another_threads_warning_is_not_caught_here_even_when_its_text_is_asked_for():
    """Two spawns compiling at once: each hears its own conflicts, not the other's."""
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter('always')

        def other():
            warnings.warn('Attach conflict of the other spawn', UserWarning)
        with thread_warnings.caught('Attach conflict') as here:
            t = threading.Thread(target=other)
            t.start()
            t.join(5)
    assert here == []
    assert [str(w.message) for w in shown] == ['Attach conflict of the other spawn']


def test_what_is_not_asked_for_is_shown_as_before_and_asked_for_comes_every_time():
    with warnings.catch_warnings(record=True) as shown:  # the test's own view of the display
        warnings.simplefilter('default')
        for _ in range(3):
            with thread_warnings.caught('Attach conflict') as heard:
                warnings.warn('Attach conflict on attach: timestep', UserWarning)
                warnings.warn('something else', UserWarning)
            assert heard == ['Attach conflict on attach: timestep']  # each time, not once
    assert [str(w.message) for w in shown] == ['something else']  # shown (once: the default)


def test_a_warning_raised_by_another_thread_during_a_compile_stays_that_threads():
    """The attach conflict is caught by the compiling thread; the other thread's is not."""
    parent = mujoco.MjSpec.from_string('<mujoco><option timestep="0.002"/><worldbody/></mujoco>')
    child = mujoco.MjSpec.from_string(
        '<mujoco><option timestep="0.01"/><worldbody><body name="b"><geom size="0.1"/></body>'
        '</worldbody></mujoco>')
    other_heard = []

    def other():
        with thread_warnings.caught('failed to send response') as heard:
            warnings.warn('failed to send response (timeout)', RuntimeWarning)
        other_heard.extend(heard)
    with thread_warnings.caught('Attach conflict') as conflicts:
        parent.attach(child, prefix='c/', frame=parent.worldbody.add_frame())
        parent.compile()  # where MuJoCo says it
        t = threading.Thread(target=other)
        t.start()
        t.join(5)
    assert len(conflicts) == 1 and 'timestep' in conflicts[0]
    assert other_heard == ['failed to send response (timeout)']


def test_nothing_named_is_refused():
    with pytest.raises(ValueError, match='prefix'):
        with thread_warnings.caught():
            pass
