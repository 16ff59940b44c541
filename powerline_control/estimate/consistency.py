"""Is the filter honest about its errors: :class:`Consistency`, :func:`filter_consistency`.

The whole-record NEES and NIS against their chi-square bands, and the windowed NIS test that
:meth:`~powerline_control.estimate.KalmanFilter.filter` runs on every record (design.md 4.7):
the window sums, each window's two-sided chi-square test and the run-level count of rejections.
The spectral test of the whitened innovations lives in ``_spectrum.py``; its fields are part of
:class:`Consistency`.
"""

from __future__ import annotations

import numpy as np
import scipy.stats as sstats

from .._validation import (
    check_array,
    check_field_map,
    check_int,
    check_real,
    read_only,
)
from ..errors import (
    InputError,
)
from .result import Consistency, Estimate

__all__ = ["Consistency", "filter_consistency", "windowed_consistency",
           "DEFAULT_CONSISTENCY_WINDOW"]

# Covariance eigenvalues below this fraction of the largest count as zero in the NEES: a
# rank-truncated model claims near-certainty in directions it does not model, and the true error
# there would dominate the statistic.
_NEES_RANK_RTOL = 1e-9
#: Samples per window of the consistency test (design.md 4.7): 0.2 s at 1 kHz, long enough for a
#: tight chi-square band (p = 5 sensors: 1000 degrees of freedom, +-12 % at 1 %), short enough to
#: localise a change of load within a record.
DEFAULT_CONSISTENCY_WINDOW = 200
#: Two-sided level of each window's chi-square test, and of the run-level count of rejections.
_WINDOW_LEVEL = 0.01



def _window_test(sums: np.ndarray, counts: np.ndarray, used: np.ndarray, window: int,
                 dof_fraction: float) -> dict:
    """Windowed NIS fields of :class:`Consistency` from per-window sums of NIS.

    ``sums``: NIS summed over the valid samples of each window; ``counts``: valid samples;
    ``used``: scalar innovations (sensors summed over the window). The sum times
    ``dof_fraction`` is chi-square with ``dof_fraction * used`` degrees of freedom.
    """
    sums, counts, used = (np.asarray(v, dtype=float) for v in (sums, counts, used))
    n_windows = sums.size
    dof = dof_fraction * used
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(counts > 0, sums / np.where(counts > 0, counts, 1.0), np.nan)
        scale = dof_fraction * np.where(counts > 0, counts, np.nan)
        low, high = sstats.chi2.ppf([[_WINDOW_LEVEL / 2], [1 - _WINDOW_LEVEL / 2]],
                                    np.where(dof > 0, dof, np.nan)) / scale
    bounds = np.column_stack([low, high]) if n_windows else np.zeros((0, 2))
    tested = np.zeros(n_windows, dtype=bool)
    tested[1:] = counts[1:] > 0  # the first window holds the transient from the prior
    above = tested & (mean > bounds[:, 1])
    below = tested & (mean < bounds[:, 0])
    n_tested = int(tested.sum())
    allowed = allowed_rejections(n_tested)
    rejected = np.flatnonzero(above | below)
    return {
        "pessimistic": bool(int(below.sum()) > allowed),
        "window": int(window),
        "window_nis": read_only(mean),
        "window_dof": read_only(dof),
        "window_bounds": read_only(bounds),
        "rejected": read_only(rejected),
        "above": read_only(above),
        "tested": read_only(tested),
        "n_tested": n_tested,
        "consistent": bool(int(above.sum()) <= allowed),
        "dof_fraction": float(dof_fraction),
    }


def allowed_rejections(n_tested: int) -> int:
    """How many of ``n_tested`` windows may lie above their bound by chance before the run
    rejects: the 99 % quantile of the binomial law of ``n_tested`` windows each rejecting with
    probability 1 % (the run-level test at 1 %; the same rule for any subset of the windows).

    Examples
    --------
    >>> allowed_rejections(9), allowed_rejections(37), allowed_rejections(0)
    (1, 2, 0)
    """
    return int(sstats.binom.ppf(1 - _WINDOW_LEVEL, n_tested, _WINDOW_LEVEL)) if n_tested else 0


def _window_sums(values: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sums over valid samples, valid counts, starts) of each full window of ``values``."""
    n_windows = values.size // window
    block = values[: n_windows * window].reshape(n_windows, window)
    valid = ~np.isnan(block)
    sums = np.where(valid, block, 0.0).sum(axis=1)
    return sums, valid.sum(axis=1), np.arange(n_windows) * window


def windowed_consistency(windows: np.ndarray, window: int,
                         dof_fraction: float = 1.0) -> Consistency | None:
    """The windowed NIS test of a real-time filter from its closed windows.

    ``windows`` holds one row per consecutive window of ``window`` samples: the NIS summed over
    its valid samples, the valid samples, and the scalar innovations (sensors summed over the
    window), as :attr:`KalmanFilter.consistency_windows` gives them. Windows taken from
    several filters that followed one another (each window from the filter running at its
    end) are tested as one run. None when no window holds a measurement.

    Parameters
    ----------
    windows : array_like, shape (n_windows, 3)
        NIS sum, valid samples and scalar innovations per window.
    window : int
        Samples per window.
    dof_fraction : float
        Degrees of freedom per scalar innovation (1 for the plain NIS).

    Returns
    -------
    Consistency or None

    Examples
    --------
    >>> import numpy as np
    >>> sums = [1000.0, 1010.0, 3000.0]     # 200 samples of 5 sensors each
    >>> c = windowed_consistency(np.array([[s, 200, 1000] for s in sums]), 200)
    >>> c.rejected.tolist(), round(c.mean_nis, 2)     # the first window is never tested
    ([2], 8.35)
    """
    windows = np.asarray(windows, dtype=float).reshape(-1, 3)
    sums, counts, used = windows.T
    if not counts.sum():
        return None
    total, n_valid = float(used.sum()), int(counts.sum())
    bounds = _chi2_band(total, n_valid)
    mean = float(sums.sum() / n_valid)
    return Consistency(
        mean_nis=mean, nis_dof=total / n_valid, nis_bounds=bounds,
        nis_consistent=bool(bounds[0] <= mean <= bounds[1]),
        window_start=read_only(np.arange(sums.size) * window),
        **_window_test(sums, counts, used, window, dof_fraction),
    )


def _chi2_band(total_dof: float, n_samples: int) -> tuple[float, float]:
    low, high = sstats.chi2.ppf([0.025, 0.975], total_dof)
    return float(low / n_samples), float(high / n_samples)


def filter_consistency(
    estimate: Estimate,
    truth: object = None,
    *,
    discard: int = 0,
    field_map: object = None,
    window: int = DEFAULT_CONSISTENCY_WINDOW,
    dof_fraction: float = 1.0,
) -> Consistency:
    """NIS (always) and NEES (with the truth) of a filter run, whole-record and windowed.

    Parameters
    ----------
    estimate : Estimate
        A filter run.
    truth : array_like, optional
        True states ``(n, n_t)``, or the true field ``(n_nodes, n_t)`` when ``estimate.field``
        exists (then ``field_map`` is needed for the full NEES).
    discard : int
        Leading samples left out (the transient from the prior).
    field_map : array_like, optional
        The filter's field map ``(n_nodes, n)``, one column per state, to map the final
        covariance to the field for the NEES.
    window : int
        Samples per window of the windowed test (default 200); windows tile the record from
        ``discard`` on.
    dof_fraction : float
        Share ``0 < f <= 1`` of the nominal chi-square degrees of freedom of each window treated
        as independent (1: white innovations, the textbook test).

    Returns
    -------
    Consistency
        The statistics. NEES uses the final (converged) posterior covariance for every sample
        after ``max(discard, estimate.converged_at)``, with a pseudo-inverse on its range (pinned
        nodes have zero variance) and the rank as degrees of freedom.

    Raises
    ------
    InputError
        If shapes disagree, ``discard`` leaves no samples, ``window`` is not a positive integer
        or ``dof_fraction`` is outside ``(0, 1]``.

    Examples
    --------
    >>> import control as ct
    >>> from powerline_control.estimate import KalmanFilter
    >>> rng = np.random.default_rng(0)
    >>> sys = ct.ss([[0.9]], [[0.0]], [[1.0]], 0, dt=1.0)
    >>> x = np.zeros(2000)
    >>> for k in range(1, 2000):
    ...     x[k] = 0.9 * x[k - 1] + rng.normal()
    >>> est = KalmanFilter(sys, Q=1.0, R=0.25).filter(x[None] + 0.5 * rng.normal(size=(1, 2000)))
    >>> c = filter_consistency(est, x[None], discard=10)
    >>> c.nis_consistent, c.nees_consistent, c.consistent, c.n_tested
    (True, True, True, 8)
    """
    if not isinstance(estimate, Estimate):
        raise InputError(
            f"The 'estimate' parameter must be an Estimate. Got {type(estimate).__name__}."
        )
    n_t = estimate.states.shape[1]
    discard = check_int("discard", discard, low=0, high=n_t - 1)
    # The map is checked when given, whether or not the truth below uses it.
    field_map = check_field_map(field_map, estimate.states.shape[0])
    window = check_int("window", window, low=1)
    dof_fraction = check_real("dof_fraction", dof_fraction, low=0.0, high=1.0)
    nis = estimate.nis[discard:]
    used = estimate.n_used[discard:]
    valid = ~np.isnan(nis)
    if not valid.any():
        raise InputError("No sample after 'discard' has a measurement; NIS is undefined.")
    mean_nis = float(np.mean(nis[valid]))
    total = float(np.sum(used[valid]))
    nis_bounds = _chi2_band(total, int(valid.sum()))
    sums, counts, starts = _window_sums(nis, window)
    used_sums = used[: starts.size * window].reshape(-1, window).sum(axis=1) if starts.size \
        else np.zeros(0)
    result = {
        "mean_nis": mean_nis,
        "nis_dof": float(total / valid.sum()),
        "nis_bounds": nis_bounds,
        "nis_consistent": bool(nis_bounds[0] <= mean_nis <= nis_bounds[1]),
        "window_start": read_only(starts + discard),
        **_window_test(sums, counts, used_sums, window, dof_fraction),
    }
    if truth is None:
        return Consistency(**result)
    true = check_array("truth", truth, ndim=2)
    if estimate.field is not None and true.shape == estimate.field.shape:
        values, variances = estimate.field, estimate.field_variances
        if field_map is None:
            covariance = None
        else:
            covariance = field_map @ estimate.covariance @ field_map.T
    elif true.shape == estimate.states.shape:
        values, variances, covariance = estimate.states, estimate.variances, estimate.covariance
    else:
        raise InputError(
            f"The 'truth' parameter has the wrong shape: expected {estimate.states.shape} "
            f"(states) or the field's shape, but found {true.shape}."
        )
    error = values[:, discard:] - true[:, discard:]
    var = np.asarray(variances)[:, discard:]
    positive = var > 0
    normalised = np.where(positive, error**2 / np.where(positive, var, 1.0), 0.0).mean(axis=1)
    result["normalised_error"] = read_only(normalised)
    if covariance is not None and estimate.converged_at is not None:
        start = max(discard, estimate.converged_at)
        if start < n_t:
            eigenvalues, vectors = np.linalg.eigh((covariance + covariance.T) / 2)
            keep = eigenvalues > eigenvalues.max() * _NEES_RANK_RTOL
            whitened = (vectors[:, keep].T @ (values[:, start:] - true[:, start:])) / np.sqrt(
                eigenvalues[keep]
            )[:, None]
            nees = np.sum(whitened**2, axis=0)
            dof = int(keep.sum())
            bounds = _chi2_band(dof * nees.size, nees.size)
            mean_nees = float(np.mean(nees))
            nees_sums, nees_counts, _ = _window_sums(nees, window)
            nees_windows = _window_test(nees_sums, nees_counts, dof * nees_counts, window, 1.0)
            # Every NEES window is tested (the converged gain already left the transient out).
            nees_mean = nees_windows["window_nis"]
            nees_bounds_w = nees_windows["window_bounds"]
            result.update(
                mean_nees=mean_nees,
                nees_dof=dof,
                nees_bounds=bounds,
                nees_consistent=bool(bounds[0] <= mean_nees <= bounds[1]),
                window_nees=nees_mean,
                nees_rejected=read_only(np.flatnonzero(
                    (nees_mean < nees_bounds_w[:, 0]) | (nees_mean > nees_bounds_w[:, 1]))),
            )
    return Consistency(**result)
