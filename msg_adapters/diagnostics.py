"""The session's state and the loop's rate as diagnostic_msgs/DiagnosticArray, for /diagnostics."""

from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sim_node.core.base.records import LoopStatus

from .convert import stamp


def diagnostics(status: LoopStatus, name: str, state: str, reason: str = '',
                divergence: Optional[dict] = None,
                extra: Optional[dict] = None) -> DiagnosticArray:
    """
    Return one status named `name`, with the culprit entity of a divergence as a value.

    `state` (``'playing'``, ``'paused'``, ``'stopped'``), `reason` and `divergence` are the
    session's (its state event); `status` is the loop's (step, time, the factors, lag).
    OK; WARN when lagging, or after a divergence handled by playing on; ERROR when paused or
    stopped by a divergence or a failure. `extra`: more values, after the loop's (the mesh
    cache's size).
    """
    level, message = DiagnosticStatus.OK, state
    if status.lag and state == 'playing':
        level, message = DiagnosticStatus.WARN, status.lag
    div = divergence
    if div is not None:
        handled = div.get('action') in ('remove', 'reset') and state == 'playing'
        level = DiagnosticStatus.WARN if handled else DiagnosticStatus.ERROR
        message = reason or 'the physics diverged'
    elif state == 'stopped' and reason:
        level, message = DiagnosticStatus.ERROR, reason
    values = {'state': state, 'step': status.step, 'time': f'{status.time:.6f}',
              'real_time_factor': status.real_time_factor,
              'achieved_real_time_factor': f'{status.achieved_real_time_factor:.3f}'}
    values.update(extra or {})
    if div is not None:
        values.update({'divergence_' + k: div.get(k, '') for k in (
            'entity', 'body', 'step', 'time', 'warnings', 'action')})
    msg = DiagnosticArray()
    msg.header.stamp = stamp(status.time)
    msg.status = [DiagnosticStatus(level=level, name=name, message=message[:1000],
                                   hardware_id='mujoco',
                                   values=[KeyValue(key=k, value=str(v))
                                           for k, v in values.items()])]
    return msg


def refused_command(why: str, names: list, name: str, what: str = 'joint command',
                    verdict: str = 'refused') -> DiagnosticStatus:
    """Return a WARN status for a refused (or `verdict`) command or goal: why, and the names."""
    return DiagnosticStatus(level=DiagnosticStatus.WARN, name=name, hardware_id='mujoco',
                            message=f'{what} {verdict}: {why}'[:1000],
                            values=[KeyValue(key='names', value=', '.join(names)[:1000])])
