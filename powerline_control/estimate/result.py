"""What a filter run returns and how close it came: :class:`Estimate`, :class:`Accuracy`.

:class:`Estimate` holds the filtered states, their variances and the innovations of one
:meth:`~powerline_control.estimate.KalmanFilter.filter` run; :func:`estimation_accuracy` compares
an estimate with the true signal (RMS errors relative to the RMS displacement, over all signals
and over the unmeasured ones) and returns an :class:`Accuracy`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._validation import (
    check_array,
    check_indices,
    check_int,
    read_only,
)
from ..errors import (
    InputError,
)

if TYPE_CHECKING:  # annotations only: consistency.py and recovery.py import this module
    from .consistency import Consistency
    from .recovery import Recovery

__all__ = ["Estimate", "Accuracy", "estimation_accuracy"]


@dataclass(frozen=True)
class Estimate:
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
        from .recovery import recovery_time  # recovery.py imports this module

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



@dataclass(frozen=True)
class Accuracy:
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

