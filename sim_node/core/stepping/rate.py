"""
The real-time factor a stepping loop achieves, measured over windows of wall time.

:class:`RateWindow` is told of each batch; over every :data:`RATE_WINDOW_SEC` it computes the
achieved factor and, when it falls below :data:`LAG_FRACTION` of the requested one, says so once
(a log line and the loop's status) instead of lagging silently. Only the loop's thread uses it.
"""

import logging
from typing import Optional

log = logging.getLogger(__name__)

RATE_WINDOW_SEC = 2.0
LAG_FRACTION = 0.95
ERR_LAG = ('the simulation cannot keep real_time_factor {rtf:g}: achieved {achieved:.3g} over '
           'the last {window:g} s (its last batch took {ms:.2f} ms of wall time per {dt:g} s '
           'step, waits for the world lock included)')


class RateWindow:
    """The achieved real-time factor and the lag message, if the loop lags."""

    def __init__(self):
        self._start: Optional[float] = None  # wall time the window began
        self._steps = 0
        self._rtf = 0.0  # the factor asked for during this window
        self.achieved = 0.0
        self.lag_message = ''

    def restart(self) -> None:
        """Begin a new window at the next batch (after a pause: a pause is not lag)."""
        self._start = None

    def batch(self, now: float, n: int, rtf: float, timestep: float,
              wall_per_step: float) -> None:
        """Count a batch of `n` steps that ended at wall time `now` under factor `rtf`."""
        if self._start is None or rtf != self._rtf:
            self._start, self._steps, self._rtf = now, 0, rtf
            return
        self._steps += n
        span = now - self._start
        if span < RATE_WINDOW_SEC:
            return
        self.achieved = self._steps * timestep / span
        self._start, self._steps = now, 0
        if rtf > 0 and self.achieved < LAG_FRACTION * rtf:
            if not self.lag_message:
                self.lag_message = ERR_LAG.format(rtf=rtf, achieved=self.achieved,
                                                  window=RATE_WINDOW_SEC,
                                                  ms=wall_per_step * 1e3, dt=timestep)
                log.warning(self.lag_message)
        else:
            self.lag_message = ''
