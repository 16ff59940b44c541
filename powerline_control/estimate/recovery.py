"""How long a filter takes to recover after a sudden change: :class:`Recovery`,
:func:`recovery_time`.

The paper's open question (the delay with which the filter recovers after a change in the
dynamics: a wind step, a tension step) as a number: the time from the change until the windowed
NIS test of :class:`~powerline_control.estimate.Consistency` accepts ``hold`` windows in a row,
and, given the truth, until the field error stays within ``factor`` times its steady value for
``hold`` windows. :meth:`Estimate.recovery <powerline_control.estimate.Estimate.recovery>` is
the same on a filter's result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validation import check_array, check_indices, check_int, check_real
from ..errors import InputError
from .result import Estimate

__all__ = ["Recovery", "recovery_time"]


@dataclass(frozen=True)
class Recovery:
    """Recovery after a change at sample ``change_at`` (see :func:`recovery_time`).

    Attributes
    ----------
    change_at : int
        Sample of the change.
    nis_samples : int or None
        Samples from the change to the first sample of the first run of ``hold`` consecutive
        windows the windowed NIS test accepts (0: no window after the change rejected);
        ``None`` when the test never accepts ``hold`` windows in a row again.
    error_samples : int or None
        Samples from the change until the field error (RMS over ``rows`` per window) stays
        within ``factor`` times ``steady_error`` for ``hold`` windows; ``None`` without the
        truth, or when it never does.
    steady_error : float or None
        The error's steady value after the change (m; given, or the median window error over
        the last quarter of the windows after the change).
    window : int
        Samples per window (the consistency test's).
    dt : float or None
        Sample time, s (``None``: times are in samples).

    Examples
    --------
    >>> rec = Recovery(change_at=1000, nis_samples=400, error_samples=None, steady_error=None,
    ...                window=200, dt=1e-3)
    >>> rec.nis_time, rec.error_time, rec.time
    (0.4, nan, 0.4)
    """

    change_at: int
    nis_samples: int | None
    error_samples: int | None
    steady_error: float | None
    window: int
    dt: float | None

    def _seconds(self, samples: int | None) -> float:
        if samples is None:
            return math.inf
        return samples * (1.0 if self.dt is None else self.dt)

    @property
    def nis_time(self) -> float:
        """Seconds until the windowed NIS is back within its bounds (``inf``: never)."""
        return self._seconds(self.nis_samples)

    @property
    def error_time(self) -> float:
        """Seconds until the field error is within ``factor`` of its steady value (``inf``:
        never; NaN without the truth)."""
        return math.nan if self.steady_error is None else self._seconds(self.error_samples)

    @property
    def time(self) -> float:
        """The recovery time: the later of :attr:`nis_time` and :attr:`error_time` (the NIS
        alone without the truth)."""
        return self.nis_time if math.isnan(self.error_time) else max(self.nis_time,
                                                                      self.error_time)


def _first_run(ok: np.ndarray, hold: int) -> int | None:
    """Index of the first window that starts ``hold`` accepted windows in a row (or all the
    remaining ones, at least one, when fewer than ``hold`` are left); None if there is none."""
    n = ok.size
    for i in range(n):
        end = min(i + hold, n)
        if ok[i:end].all():
            return i
    return None


def recovery_time(estimate: Estimate, change_at: int, truth: object = None,
                  rows: object = None, *, hold: int = 3, factor: float = 1.5,
                  steady_error: float | None = None) -> Recovery:
    """Time for a filter to recover after a sudden change at sample ``change_at``.

    The windows are those of ``estimate.consistency`` (the filter's windowed NIS test) that end
    after the change. NIS recovery: the first of them that starts ``hold`` windows in a row
    within their 1 % bounds (a window straddling the change counts from the change). Error
    recovery (with ``truth``): the same with "the RMS error over ``rows`` within ``factor``
    times ``steady_error``".

    Parameters
    ----------
    estimate : Estimate
        A :meth:`KalmanFilter.filter` result with its consistency test (a filter with a
        ``consistency_window``).
    change_at : int
        Sample at which the change happens, ``1 <= change_at < n_t``.
    truth : array_like, optional
        ``(len(rows), n_t)`` true values of ``rows`` of the estimate's field (its states
        without a field map), e.g. the unmeasured nodes of a simulation's noise-free field.
    rows : sequence of int, optional
        Rows of the field the truth holds (default every row).
    hold : int
        Consecutive windows that must pass (``>= 1``, default 3).
    factor : float
        Allowed error over its steady value (``>= 1``, default 1.5).
    steady_error : float, optional
        The steady RMS error after the change (m); default the median window error over the
        last quarter of the windows after the change.

    Returns
    -------
    Recovery
        Samples and seconds to recover.

    Raises
    ------
    InputError
        If the estimate has no consistency test, ``change_at`` is outside the record, ``hold``
        or ``factor`` is out of range, or ``truth`` does not match ``rows``.

    Examples
    --------
    A random walk whose process noise jumps 100-fold at sample 3000, filtered with Q adapted
    over 500 samples:

    >>> import control as ct
    >>> import numpy as np
    >>> import powerline_control as plc
    >>> rng = np.random.default_rng(0)
    >>> w = rng.normal(size=6000) * np.where(np.arange(6000) < 3000, 0.1, 1.0)
    >>> y = (np.cumsum(w) + rng.normal(size=6000))[None, :]
    >>> sys = ct.ss([[1.0]], [[0.0]], [[1.0]], 0, dt=1e-3)
    >>> kf = plc.KalmanFilter(sys, Q=0.01, R=1.0, adapt_horizon=500)
    >>> rec = recovery_time(kf.filter(y), 3000)
    >>> 0 < rec.nis_time < 1.0     # s: the NIS is back within its bounds within 2 horizons
    True
    """
    if not isinstance(estimate, Estimate):
        raise InputError("The 'estimate' parameter must be an Estimate (KalmanFilter.filter's "
                         f"result). Got {type(estimate).__name__}.")
    c = estimate.consistency
    if c is None or c.window_start.size == 0:
        raise InputError("The 'estimate' parameter has no windowed NIS test (a filter with "
                         "consistency_window=None, or a record shorter than one window): "
                         "recovery is measured on its windows.")
    n_t = estimate.states.shape[1]
    change_at = check_int("change_at", change_at, low=1, high=n_t - 1)
    hold = check_int("hold", hold, low=1)
    factor = check_real("factor", factor, low=1.0, low_inclusive=True)
    window = c.window
    after = np.flatnonzero(c.window_start + window > change_at)
    if after.size == 0:
        raise InputError(f"The 'change_at' parameter ({change_at}) leaves no full window of "
                         f"{window} samples after it in the record of {n_t} samples.")
    starts = np.maximum(c.window_start[after], change_at)
    rejected = np.zeros(c.window_start.size, dtype=bool)
    rejected[c.rejected] = True
    nis_ok = c.tested[after] & ~rejected[after]
    first = _first_run(nis_ok, hold)
    nis_samples = None if first is None else int(starts[first] - change_at)
    error_samples, steady = None, None
    if truth is not None:
        values = estimate.field if estimate.field is not None else estimate.states
        index = (np.arange(values.shape[0]) if rows is None
                 else check_indices("rows", rows, values.shape[0]))
        true = check_array("truth", truth, shape=(index.size, n_t))
        error2 = np.mean((values[index] - true) ** 2, axis=0)
        errors = np.array([math.sqrt(float(np.mean(error2[s: s + window])))
                           for s in c.window_start[after]])
        if steady_error is None:
            steady = float(np.median(errors[-max(1, errors.size // 4):]))
        else:
            steady = check_real("steady_error", steady_error, low=0.0)
        first = _first_run(errors <= factor * steady, hold)
        error_samples = None if first is None else int(starts[first] - change_at)
    return Recovery(change_at=change_at, nis_samples=nis_samples, error_samples=error_samples,
                    steady_error=steady, window=window, dt=estimate.dt)
