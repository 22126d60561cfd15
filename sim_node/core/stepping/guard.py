"""
The divergence guard.

MuJoCo's own checks after every batch, and the replay that finds the exact bad step.

MuJoCo's whole-world auto-reset on NaN is disabled by the world; divergence is reported
instead (dm_control's ``check_invalid_state``).
"""

import logging
from typing import Callable, Optional

import mujoco
import numpy as np

from ..base.checks import MAX_ABS_VALUE
from ..compiled.index import STATE_SPEC

log = logging.getLogger(__name__)

_MUJOCO_LOG = logging.getLogger('sim_node.mujoco')


def _log_mujoco_warning(message: str) -> None:
    if message.startswith('Attach conflict'):
        # A spawned model's own <option>/<size>/<visual> differ from the world's, which are
        # kept (the documented rule): information, not a fault.
        _MUJOCO_LOG.info('MuJoCo: %s (the world keeps its own settings)', message)
    else:
        _MUJOCO_LOG.warning('MuJoCo: %s', message)


#: MuJoCo releases with a known fault in what this simulator relies on: release -> the fault.
#: ros_env/requirements.txt excludes them; a ROS machine's pip (rosdep's python3-mujoco-pip
#: key) may still bring one, so the first world made says so.
FAULTY_RELEASES = {
    '4.0.0': ('its sparse Cholesky factorization gives the Newton solver a wrong Hessian '
              'factor when the constraint Jacobian is sparse (slow convergence, wrong '
              'accelerations, divergence: MuJoCo issue 3767); pip install '
              '"mujoco-core>=4.0.1" glfw (the mujoco 4.0.0 metapackage pins the faulty core: '
              'uninstall it first)'),
}


def release_warning(version: str) -> str:
    """Return what is wrong with MuJoCo release `version` and what to do, or ''."""
    fault = FAULTY_RELEASES.get(version)
    return f'MuJoCo {version} is known to be faulty: {fault}' if fault else ''


def route_mujoco_warnings() -> None:
    """
    Send MuJoCo's warning text to logging instead of stderr and a MUJOCO_LOG.TXT.

    The node forwards it to the ROS log. Nothing changes if the application has installed a
    MuJoCo warning handler of its own (the handler is process-wide). The first call also says,
    once, if the MuJoCo in use is a release of :data:`FAULTY_RELEASES`.
    """
    global _release_checked
    if not _release_checked:
        _release_checked = True
        note = release_warning(mujoco.mj_versionString())
        if note:
            _MUJOCO_LOG.warning(note)
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_log_mujoco_warning)


_release_checked = False


_BAD_WARNINGS = [int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQVEL),
                 int(mujoco.mjtWarning.mjWARN_BADQACC)]


def clean(state: np.ndarray) -> bool:
    """Return True if a state vector has nothing MuJoCo would call divergent."""
    return bool(np.all(np.isfinite(state)) and np.max(np.abs(state), initial=0) < MAX_ABS_VALUE)


def _within(values: np.ndarray) -> bool:
    """Say whether none of `values` is bad for MuJoCo (mju_isBad): NaN or beyond +-1e10."""
    return not values.size or bool(-MAX_ABS_VALUE <= values.min() and
                                   values.max() <= MAX_ABS_VALUE)


class DivergenceGuard:
    """
    Watches one MjData's warning counters.

    A counter may be set back to 1 by a reset, so changes are detected by comparison with the last
    seen values, not by "greater than".
    """

    def bind(self, data: mujoco.MjData) -> None:
        """Watch `data` (a new one after every recompile), taking its counters as seen."""
        self._view = data.warning.number
        self.note()

    def note(self) -> None:
        """Take the current counters as seen (new ones are what :meth:`diverged` looks for)."""
        self._seen = self._view.copy()
        self._seen_bytes = self._seen.tobytes()

    def diverged(self, model: mujoco.MjModel, data: mujoco.MjData, quiet: bool = False) -> bool:
        """
        Return True if MuJoCo calls the state bad (NaN, inf or beyond 1e10 in qpos, qvel or qacc).

        Logs other new warnings. Runs after every batch: two C calls and one comparison; with
        `quiet`, numpy instead of the C calls while the state is clean (a few microseconds more,
        but no release of the GIL: see :func:`sim_node.core.compiled.state.state_copier`).
        """
        # mj_step checks qpos and qvel only at the start of the next step; the integrator may
        # have just carried a bad acceleration into them. Check them now, as MuJoCo would.
        if not (quiet and _within(data.qpos) and _within(data.qvel)):
            mujoco.mj_checkPos(model, data)  # sets the warnings MuJoCo's own check would
            mujoco.mj_checkVel(model, data)
        if self._view.tobytes() == self._seen_bytes:
            return False
        changed = self._view != self._seen
        if changed[_BAD_WARNINGS].any():
            return True
        for i in np.nonzero(changed)[0]:
            log.warning('MuJoCo warning %s (info %d)', mujoco.mjtWarning(i).name,
                        data.warning[i].lastinfo)
        self.note()
        return False

    def new_warnings(self, data: mujoco.MjData) -> dict:
        """{warning name: lastinfo} for the counters that changed since last seen."""
        return {mujoco.mjtWarning(i).name: int(data.warning[i].lastinfo)
                for i in np.nonzero(self._view != self._seen)[0]}

    def locate(self, model: mujoco.MjModel, data: mujoco.MjData, before: np.ndarray, n: int,
               ctrl: Optional[np.ndarray], before_step: Optional[Callable[[], None]]) -> tuple:
        """
        Replay a batch that diverged one step at a time from `before`.

        :param ctrl: the batch's controls, if `before` does not hold them yet.
        :param before_step: per-step control to run before each replayed step, if any.
        :returns: (k, state before the bad step, report); the bad step is the batch's k+1-th.
            `data` is left at the bad state.
        """
        mujoco.mj_setState(model, data, before, STATE_SPEC)
        if ctrl is not None:
            data.ctrl[:] = ctrl
        mujoco.mj_forward(model, data)
        self.note()
        good = np.empty_like(before)
        for k in range(n):
            mujoco.mj_getState(model, data, good, STATE_SPEC)
            if before_step is not None:
                before_step()
            mujoco.mj_step(model, data)
            if self.diverged(model, data) or k == n - 1:
                break
        report = {'time': float(data.time), 'warnings': self.new_warnings(data),
                  'nonfinite_qpos': int(np.count_nonzero(~np.isfinite(data.qpos))),
                  'nonfinite_qvel': int(np.count_nonzero(~np.isfinite(data.qvel)))}
        return k, good, report
