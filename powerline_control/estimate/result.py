"""What a filter run returns, how close it came and how fast it recovers: :class:`Estimate`,
:class:`Consistency`, :class:`Accuracy`, :class:`Recovery`.

:class:`Estimate` holds the filtered states, their variances and the innovations of one
:meth:`~powerline_control.estimate.KalmanFilter.filter` run, with its windowed NIS test as a
:class:`Consistency` (the test itself is :mod:`~powerline_control.estimate.consistency`'s);
:func:`estimation_accuracy` compares an estimate with the true signal (RMS errors relative to the
RMS displacement, over all signals and over the unmeasured ones) and returns an :class:`Accuracy`.

How long a filter takes to recover after a sudden change (the paper's open question: the delay
with which the filter recovers after a change in the dynamics, a wind step, a tension step) is
:func:`recovery_time`: the time from the change until the windowed NIS test accepts ``hold``
windows in a row, and, given the truth, until the field error stays within ``factor`` times its
steady value for ``hold`` windows; :meth:`Estimate.recovery` is the same on a filter's result.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._results import Result
from .._validation import (
    check_array,
    check_forwarded_options,
    check_indices,
    check_int,
    check_real,
    checked_keywords,
    read_only,
)
from ..errors import (
    InputError,
)

__all__ = ["Estimate", "Consistency", "Accuracy", "estimation_accuracy", "Recovery",
           "recovery_time"]


@dataclass(frozen=True, eq=False)
class Estimate(Result):
    """Result of :meth:`KalmanFilter.filter`: filtered states and their uncertainty.

    Attributes
    ----------
    states : numpy.ndarray
        Posterior (filtered) state estimates ``x[k|k]``, shape ``(n, n_t)``.
    variances : numpy.ndarray
        Diagonal of the posterior covariance ``P[k|k]``, shape ``(n, n_t)`` (a read-only
        broadcast view when the covariance is constant over the whole record).
    innovations : numpy.ndarray
        Measurement residuals ``y[k] - C x[k|k-1] - D u[k]``, shape ``(p, n_t)``; NaN where the
        measurement was missing.
    nis : numpy.ndarray
        Normalised innovation squared ``e^T S^-1 e`` per sample, ``(n_t,)``; NaN for all-missing
        samples. For a consistent filter it is chi-square with ``n_used[k]`` degrees of freedom.
    n_used : numpy.ndarray
        Number of sensors used in each update, ``(n_t,)`` (``p`` without dropouts).
    covariance : numpy.ndarray
        Posterior covariance after the last sample, ``(n, n)``.
    gain : numpy.ndarray
        Filter-form gain ``(n, p)`` of the last update that used every sensor (the steady-state
        gain once converged).
    converged_at : int or None
        First sample from which the gain was frozen (the change of the covariance and of the
        gain stayed below ``gain_rtol``); ``0`` in steady-state mode, ``None`` if it never
        converged (always ``None`` when ``undetectable_modes`` is not empty).
    dt : float or None
        Sample time of the model (``None`` when the model's timebase is unspecified).
    field : numpy.ndarray or None
        Full field ``field_map @ states``, ``(n_nodes, n_t)``, when the filter has a field map.
    field_variances : numpy.ndarray or None
        Posterior variance of each field value, ``(n_nodes, n_t)``, when the filter has a field map.
    field_growth : numpy.ndarray or None
        With a filter whose spectral reference follows the field (``spectral_field_reference``
        and a consistency window): the factor ``(n_t,)`` on the innovation covariance of each
        consistency window (``S_k = S g``, ``estimate._spectrum.nis_growth``) and, with a field
        map, on ``field_variances`` (model-error terms included): an identified model's error
        grows at nodes no sensor sees as it does at the sensors; 1 in the windows that end
        before the gain converges (as ``step`` gives them). ``None`` otherwise, or when the
        gain never converges.
    undetectable_modes : tuple of complex
        Eigenvalues on or outside the unit circle that the sensors cannot see (empty when the
        model is detectable). Their variance grows without bound and is reported as it grows.
    process_noise_scale : numpy.ndarray or None
        With a filter's ``adapt_horizon``: the scale ``q_k`` on ``Q`` after each sample
        ``(n_t,)`` (the covariance matching of ``estimate._adaptive``), else ``None``.
    consistency : Consistency or None
        The windowed NIS test of this run (:func:`filter_consistency` with the filter's
        ``consistency_window`` and ``nis_dof_fraction``); ``None`` when the filter's window is
        ``None`` or no sample had a measurement. When it rejects, ``filter`` has warned
        :class:`~powerline_control.errors.EstimatorInconsistentWarning`.

    All arrays are read-only.

    Examples
    --------
    >>> import control as ct
    >>> from powerline_control.estimate import KalmanFilter
    >>> sys = ct.ss([[0.9]], [[0.0]], [[1.0]], 0, dt=0.01)
    >>> est = KalmanFilter(sys, Q=1.0, R=1.0, field_map=[[1.0], [2.0]]).filter(np.ones((1, 3)))
    >>> est.states.shape, est.field.shape, est.t.round(2).tolist()
    ((1, 3), (2, 3), [0.0, 0.01, 0.02])
    """

    states: np.ndarray
    variances: np.ndarray
    innovations: np.ndarray
    nis: np.ndarray
    n_used: np.ndarray
    covariance: np.ndarray
    gain: np.ndarray
    converged_at: int | None
    dt: float | None
    field: np.ndarray | None = None
    field_variances: np.ndarray | None = None
    field_growth: np.ndarray | None = None
    undetectable_modes: tuple[complex, ...] = ()
    consistency: Consistency | None = None
    process_noise_scale: np.ndarray | None = None

    def __post_init__(self) -> None:
        _freeze_arrays(self)

    def recovery(self, change_at: int, truth: object = None, rows: object = None,
                 **options: object) -> Recovery:
        """Time to recover after a sudden change at sample ``change_at``:
        :func:`~powerline_control.estimate.recovery_time` of this estimate (same arguments).

        Examples
        --------
        >>> import control as ct
        >>> from powerline_control.estimate import KalmanFilter
        >>> sys = ct.ss([[0.9]], [[0.0]], [[1.0]], 0, dt=0.01)
        >>> y = np.random.default_rng(0).normal(size=(1, 2000))
        >>> KalmanFilter(sys, Q=0.01, R=1.0).filter(y).recovery(1000).nis_samples
        0
        """
        options = check_forwarded_options(Estimate.recovery, options, recovery_time,
                                          set_here=("estimate",), why="this estimate")
        return recovery_time(self, change_at, truth, rows, **options)

    @property
    def t(self) -> np.ndarray:
        """Sample times ``k * dt`` in seconds, ``(n_t,)`` (sample indices without a timebase)."""
        step = 1.0 if self.dt is None else self.dt
        return np.arange(self.states.shape[1]) * step


def _freeze_arrays(result: object) -> None:
    """Mark every ndarray field of a result read-only (no copy: the result owns them)."""
    for value in vars(result).values():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)



@dataclass(frozen=True, eq=False)
class Consistency(Result):
    """NEES / NIS statistics: is the filter's covariance honest about its errors?

    Two views of the same question (design.md 4.7). The whole-record means (``mean_nis``,
    ``mean_nees``) with their 95 % bands; and the *windowed* test that
    :meth:`KalmanFilter.filter` runs on every record: the NIS averaged over consecutive windows
    of ``window`` samples, each compared with its two-sided 1 % chi-square bounds. The run is
    ``consistent`` unless more windows reject than chance allows at 1 % (a binomial bound on
    the count, so that a long record of an honest filter does not warn merely because it has
    many windows).

    Attributes
    ----------
    mean_nis : float
        Mean normalised innovation squared over the samples used.
    nis_dof : float
        Mean number of sensors per update (the expected value of ``mean_nis``).
    nis_bounds : tuple of float
        Two-sided 95 % chi-square band of ``mean_nis`` for a consistent filter (valid since the
        innovations of an optimal filter are white).
    nis_consistent : bool
        ``mean_nis`` inside ``nis_bounds``.
    mean_nees : float or None
        Mean normalised estimation error squared ``e^T P^-1 e`` (needs the truth and a
        converged gain), ``None`` otherwise.
    nees_dof : int or None
        Its expected value: the rank of the covariance used.
    nees_bounds : tuple of float or None
        95 % chi-square band of ``mean_nees`` treating samples as independent; estimation errors
        are correlated in time, so read it as a guide rather than a test.
    nees_consistent : bool or None
        ``mean_nees`` inside ``nees_bounds``.
    normalised_error : numpy.ndarray or None
        Per-signal mean of ``error^2 / variance`` ``(n_signals,)`` (1 for an honest variance).
    window : int
        Samples per window of the windowed test.
    window_start : numpy.ndarray
        First sample of each full window, ``(n_windows,)`` (a trailing partial window is left
        out).
    window_nis : numpy.ndarray
        The statistic: mean NIS of each window, ``(n_windows,)`` (NaN for a window without a
        measurement).
    window_dof : numpy.ndarray
        Degrees of freedom of each window's chi-square law: ``dof_fraction`` times the number
        of scalar innovations in it (``window * p`` without dropouts). The window's sum of NIS
        times ``dof_fraction`` is chi-square with this many degrees of freedom.
    window_bounds : numpy.ndarray
        Two-sided 1 % bounds of each window's mean NIS, ``(n_windows, 2)``.
    rejected : numpy.ndarray
        Indices of the tested windows whose mean NIS lies outside its bounds (int).
    above : numpy.ndarray
        Which windows were rejected *above* their bounds (larger innovations than the model
        predicts), ``(n_windows,)`` bool; the rest of ``rejected`` lies below.
    tested : numpy.ndarray
        Which windows were tested, ``(n_windows,)`` bool (see ``n_tested``).
    n_tested : int
        Windows tested: every full window after the first (which holds the filter's transient
        from its prior) that has a measurement.
    consistent : bool
        False when the number of windows rejected *above* their bounds (innovations larger than
        the filter's covariance says: an overconfident estimate) exceeds the 99 % quantile of a
        binomial law with ``n_tested`` trials of probability 1 % (the run-level test at 1 %), or
        when the spectral test rejects; True when no window could be tested. Windows below
        their bounds make the run ``pessimistic`` instead.
    pessimistic : bool
        As many windows rejected *below* their bounds: the innovations are smaller than the
        filter's covariance says (a reported sigma larger than the error, the safe side; typical
        of a record still ringing up from rest, whose model error grows with the field). Not a
        reason to warn: a load the model does not know raises the innovations at some
        frequency, which the spectral test sees even when the total NIS falls.
    dof_fraction : float
        Share of the nominal degrees of freedom treated as independent (1 for the white
        innovations of an exact model; below 1 when a design measured on held-out data that its
        innovations carry fewer independent samples, see
        :func:`~powerline_control.recipe.design_estimator`).
    window_nees : numpy.ndarray or None
        Mean NEES of each window (with the truth, from the converged gain on), else ``None``.
    nees_rejected : numpy.ndarray or None
        Indices into ``window_nees`` of windows outside their 1 % chi-square bounds (estimation
        errors are correlated in time: a guide, as ``nees_bounds``).
    spectral_frequencies : numpy.ndarray or None
        Frequencies (Hz; cycles per sample without ``dt``) of the spectral test's bins, when the
        filter carries a ``spectral_reference`` (every filter
        :func:`~powerline_control.recipe.design_estimator` builds from a broadband record).
    spectral_ratio : numpy.ndarray or None
        The record's whitened innovation power in each bin over the reference's (1: like the
        held-out part of the training record; far above 1: power the model does not predict,
        a load that drives modes the training never saw). With the filter's
        ``spectral_field_reference`` the reference has followed the record's field where the
        training saw one (``estimate._spectrum.following_reference``).
    spectral_threshold : float or None
        The ratio above which a bin is rejected: the larger of a fixed factor (two matched
        records of an identified model differ by more than sampling) and the F quantile at 1 %
        with a Bonferroni correction over the bins.
    spectral_rejected : numpy.ndarray or None
        Indices of the rejected bins.
    spectral_consistent : bool or None
        No bin rejected (``None``: no spectral test). ``consistent`` is False when either the
        windowed NIS test or the spectral test rejects.

    Examples
    --------
    See :func:`filter_consistency`, which builds it:

    >>> import control as ct
    >>> from powerline_control.estimate import KalmanFilter, filter_consistency
    >>> sys = ct.ss([[0.5]], [[0.0]], [[1.0]], 0, dt=1.0)
    >>> est = KalmanFilter(sys, Q=1.0, R=1.0).filter(np.array([[1.0, -1.0, 0.5]]))
    >>> filter_consistency(est).nis_dof
    1.0
    """

    mean_nis: float
    nis_dof: float
    nis_bounds: tuple[float, float]
    nis_consistent: bool
    mean_nees: float | None = None
    nees_dof: int | None = None
    nees_bounds: tuple[float, float] | None = None
    nees_consistent: bool | None = None
    normalised_error: np.ndarray | None = None
    window: int = 0
    window_start: np.ndarray = dataclasses.field(
        default_factory=lambda: read_only(np.zeros(0, int)))
    window_nis: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0)))
    window_dof: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0)))
    window_bounds: np.ndarray = dataclasses.field(
        default_factory=lambda: read_only(np.zeros((0, 2))))
    rejected: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0, int)))
    above: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0, bool)))
    tested: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0, bool)))
    n_tested: int = 0
    consistent: bool = True
    pessimistic: bool = False
    dof_fraction: float = 1.0
    window_nees: np.ndarray | None = None
    nees_rejected: np.ndarray | None = None
    spectral_frequencies: np.ndarray | None = None
    spectral_ratio: np.ndarray | None = None
    spectral_threshold: float | None = None
    spectral_rejected: np.ndarray | None = None
    spectral_consistent: bool | None = None

    def __post_init__(self) -> None:
        _freeze_arrays(self)

    @property
    def message(self) -> str:
        """One sentence: what the windowed test found, for a warning or a report."""
        if not self.n_tested:
            return (f"No window of {self.window} samples could be tested (the record is shorter "
                    "than two windows): the filter's consistency is unknown.")
        tested = self.window_nis[1:][np.isfinite(self.window_nis[1:])]
        expected = self.window_dof[1:] / self.dof_fraction / self.window
        ratio = float(np.nanmedian(self.window_nis[1:] / np.where(expected > 0, expected, np.nan)))
        verdict = ("consistent" if self.consistent else
                   "INCONSISTENT: the model does not fit this record")
        if self.consistent and self.pessimistic:
            verdict += " (pessimistic: the innovations are smaller than the covariance says)"
        spectral = ""
        if self.spectral_consistent is not None:
            worst = int(np.nanargmax(np.where(np.arange(self.spectral_ratio.size) > 0,
                                              self.spectral_ratio, np.nan)))
            spectral = (" Innovation spectrum against the training's: "
                        f"{self.spectral_rejected.size} of {self.spectral_ratio.size - 1} bins "
                        f"above {self.spectral_threshold:.3g} times the reference (largest "
                        f"{self.spectral_ratio[worst]:.3g} at "
                        f"{self.spectral_frequencies[worst]:.4g} Hz).")
        return (f"Windowed NIS test ({self.window} samples per window, 1 % two-sided chi-square "
                f"bounds): {self.rejected.size} of {self.n_tested} windows rejected, mean NIS "
                f"{float(np.mean(tested)):.3g} per sample against {float(np.mean(expected)):.3g}"
                f" expected (median ratio {ratio:.3g}).{spectral} Verdict: {verdict}.")


@dataclass(frozen=True, eq=False)
class Accuracy(Result):
    """RMS estimation errors, relative to the RMS of the true signal.

    Attributes
    ----------
    relative_rms_error : float
        ``rms(estimate - truth) / rms(truth)`` over all signals and samples used.
    relative_rms_error_unmeasured : float or None
        The same over the unmeasured signals only, still relative to the RMS of *all* true signals
        (the RMS displacement of the span); ``None`` when every signal is measured.
    relative_rms_error_unmeasured_own : float or None
        Unmeasured error relative to the RMS of the unmeasured true signals themselves.
    rms_truth : float
        RMS of the true signals (e.g. the RMS displacement, metres).
    per_signal_rms_error : numpy.ndarray
        RMS error of each signal ``(n_signals,)`` in the signals' units.
    n_samples : int
        Number of samples used (after ``discard``).

    Examples
    --------
    >>> acc = estimation_accuracy(np.array([[1.1, -0.9]]), np.array([[1.0, -1.0]]))
    >>> round(acc.relative_rms_error, 3), acc.n_samples
    (0.1, 2)
    """

    relative_rms_error: float
    relative_rms_error_unmeasured: float | None
    relative_rms_error_unmeasured_own: float | None
    rms_truth: float
    per_signal_rms_error: np.ndarray
    n_samples: int


@checked_keywords
def estimation_accuracy(
    estimate: Estimate | object,
    truth: object,
    measured: Sequence[int] | None = None,
    *,
    discard: int = 0,
) -> Accuracy:
    """RMS error of an estimate against the truth, for all signals and for the unmeasured ones.

    Parameters
    ----------
    estimate : Estimate or array_like
        An :class:`Estimate` (its ``field`` when it has one, else its ``states``) or an
        ``(n_signals, n_t)`` array.
    truth : array_like
        True signals ``(n_signals, n_t)``, e.g. ``snap.true_displacement`` of an independent
        simulation.
    measured : sequence of int, optional
        Rows of ``truth`` that were measured; the others are "unmeasured".
    discard : int
        Leading samples left out (the filter's transient from its prior).

    Returns
    -------
    Accuracy
        The errors.

    Raises
    ------
    InputError
        If shapes disagree, ``measured`` is out of range or ``discard`` leaves no samples.

    Examples
    --------
    >>> truth = np.array([[1.0, -1.0], [2.0, -2.0]])
    >>> acc = estimation_accuracy(truth + 0.1, truth, measured=[0])
    >>> round(acc.relative_rms_error, 4), round(acc.relative_rms_error_unmeasured, 4)
    (0.0632, 0.0632)
    """
    if isinstance(estimate, Estimate):
        values = estimate.field if estimate.field is not None else estimate.states
    else:
        values = check_array("estimate", estimate, ndim=2)
    true = check_array("truth", truth, ndim=2)
    if true.shape != values.shape:
        raise InputError(
            f"The 'truth' parameter has the wrong shape: expected {values.shape} (as the "
            f"estimate) but found {true.shape}."
        )
    discard = check_int("discard", discard, low=0, high=true.shape[1] - 1)
    error = values[:, discard:] - true[:, discard:]
    true = true[:, discard:]
    rms_truth = float(np.sqrt(np.mean(true**2)))
    if rms_truth == 0:
        raise InputError("The 'truth' parameter is identically zero; no relative error exists.")
    per_signal = np.sqrt(np.mean(error**2, axis=1))
    unmeasured_error = unmeasured_own = None
    if measured is not None:
        rows = np.zeros(true.shape[0], dtype=bool)
        # Integer row indices only: measured=[0.7] used to be read as row 0.
        index = check_indices("measured", measured, true.shape[0], allow_empty=True)
        rows[index] = True
        if (~rows).any():
            err_u = float(np.sqrt(np.mean(error[~rows] ** 2)))
            unmeasured_error = err_u / rms_truth
            own = float(np.sqrt(np.mean(true[~rows] ** 2)))
            unmeasured_own = err_u / own if own > 0 else float("inf")
    return Accuracy(
        relative_rms_error=float(np.sqrt(np.mean(error**2))) / rms_truth,
        relative_rms_error_unmeasured=unmeasured_error,
        relative_rms_error_unmeasured_own=unmeasured_own,
        rms_truth=rms_truth,
        per_signal_rms_error=read_only(per_signal),
        n_samples=int(true.shape[1]),
    )


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
