"""The time-delay DMD family of the recipe: spatial POD, delay DMD and alpha on held-out data.

Fits a time-delay DMD model on the record's spatial POD coordinates, choosing its Tikhonov alpha
by the error of the resulting estimator at the nodes it does not measure on held-out data, lifts
it back to the nodes, pulls unstable eigenvalues inside the unit circle, and calibrates the
filter's covariance on the held-out part and its field variance (the model error at unmeasured
nodes) on the whole record.

Test seam: ``_sweep_model``: made to fail in tests/test_estimator_calibration.py, to show that
records of other load histories still set the model-error level when the partial model cannot
be built (a fault no public input produces reliably).
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import control as ct
import numpy as np
import scipy.linalg as sla
import scipy.optimize as sopt
import scipy.stats as sstats

from .._validation import (
    check_array,
    read_only,
)
from ..errors import (
    EstimationError,
    IdentificationError,
    IllConditionedWarning,
    InputError,
    ModelErrorRecordsWarning,
)
from ..estimate import (
    DEFAULT_CONSISTENCY_WINDOW,
    measurement_psd,
    running_mean_square,
    sensor_mean_square,
    whitened_psd,
    whitening_factor,
)
from ..identify import DMDModel, fit_dmd
from .coverage import build_coverage
from .defaults import (
    _ALPHA_CAP,
    _ALPHA_WIDEN,
    _DEFAULT_ALPHAS,
    _FIELD_SCALE_MAX,
    _FIELD_SCALE_MIN,
    _STABLE_RADIUS,
)
from .record import _Record
from .results import AlphaSweep, EstimatorDesign
from .sensing import _choose_sensors, _steady_filter

# What a model of the sweep (or its filter) raises when it cannot be built: that alpha, or that
# calibration, is then skipped rather than the whole design failing.
_MODEL_FAILURES = (EstimationError, IdentificationError, InputError, np.linalg.LinAlgError,
                   ct.ControlDimension)


def _stabilise(model: DMDModel) -> DMDModel:
    """Pull eigenvalues outside the unit circle to radius ``_STABLE_RADIUS``, nothing else.

    A finite noisy record cannot tell an undamped mode (or a slow drift) from one that grows by
    1e-4 per sample; least squares lands on either side.  The filter does not care, but an
    unstable model is refused by python-control's Riccati solvers and grows in free runs, so the
    few eigenvalues outside are moved radially onto the circle of radius 1 - 1e-6 (frequency
    and mode shape kept; the held-out sweep scores the model after this step).
    """
    if model.is_stable:
        return model
    values, vectors = sla.eig(model.A)
    magnitude = np.abs(values)
    scale = np.where(magnitude > _STABLE_RADIUS, _STABLE_RADIUS / magnitude, 1.0)
    A = vectors @ np.diag(values * scale) @ sla.inv(vectors)
    if np.abs(A.imag).max() > 1e-8 * max(np.abs(A.real).max(), 1e-300):
        raise IdentificationError(  # pragma: no cover - conjugate pairs scale alike
            "internal: stabilising the identified model broke its conjugate symmetry")
    return dataclasses.replace(model, A=read_only(A.real.copy()), regressor_gram=None)


def _sweep_model(train: np.ndarray, spatial: np.ndarray, dt: float, alpha: float, delays: int,
                 rank: int) -> DMDModel:
    """The model of one alpha of the sweep: delay DMD of the training coordinates, lifted to
    the nodes and stabilised."""
    with warnings.catch_warnings():
        # Expected along the sweep: plain DMD (alpha = 0) may be ill-conditioned.
        warnings.simplefilter("ignore", IllConditionedWarning)
        reduced = fit_dmd(train, dt, alpha=alpha, alpha_mode="relative", delays=delays,
                          rank=min(rank, train.shape[0] * delays))
    return _stabilise(_lift(reduced, spatial))


def _held_out_error(train: np.ndarray, held: np.ndarray, spatial: np.ndarray, dt: float,
                    alpha: float, delays: int, rank: int, layout: np.ndarray,
                    candidates: np.ndarray, noise: float, data_noise: float,
                    q_floor: float) -> float:
    """Relative RMS error of the estimator at unmeasured nodes on held-out data (inf: unusable).

    The held-out truth is itself noisy; its white noise adds ``data_noise**2`` to the mean
    square error at every unmeasured node (the filter never sees those nodes), so it is
    subtracted.  ``noise`` is the filter's R (floored for noise-free data).
    """
    try:
        model = _sweep_model(train, spatial, dt, alpha, delays, rank)
    except _MODEL_FAILURES:
        return math.inf
    return _unmeasured_score(model, held, layout, candidates, noise, data_noise, q_floor, delays)


def _unmeasured_score(model, held: np.ndarray, layout: np.ndarray, candidates: np.ndarray,
                      noise: float, data_noise: float, q_floor: float, delays: int) -> float:
    """The held-out score of one model (inf: its filter fails): the steady filter on the
    ``layout`` rows of ``held``, its relative RMS error at the other moving nodes with the
    noise of the held-out truth removed (:func:`_held_out_error`). The one rule every candidate
    of the recipe is compared by (the DMD alphas, the oscillator and the physics models)."""
    try:
        field = _steady_filter(model, layout, noise, q_floor).filter(held[layout]).field
    except _MODEL_FAILURES:
        return math.inf
    unmeasured = np.setdiff1d(candidates, layout)
    if unmeasured.size == 0:  # every moving node measured: score the filtered measured nodes
        unmeasured = layout
    skip = min(held.shape[1] // 4, 10 * delays + 100)  # the filter's start-up transient
    truth = held[unmeasured, skip:]
    mse = float(np.mean((field[unmeasured, skip:] - truth) ** 2)) - data_noise**2
    power = float(np.mean(truth**2)) - data_noise**2
    if not math.isfinite(mse) or power <= 0:
        return math.inf
    return math.sqrt(max(mse, 0.0) / power)


def _calibration(model, held: np.ndarray, sensors: np.ndarray, noise: float,
                 q_floor: float, candidates: np.ndarray | None = None, data_noise: float = 0.0
                 ) -> tuple[float, float, tuple[np.ndarray, int] | None, float, tuple | None]:
    """(covariance scale, NIS dof fraction, spectral reference, held-out sigma ratio, growth)
    of ``model``, the model fitted on the training part (None: it could not be fitted).

    The last is the reported over the actual RMS error at the unmeasured moving nodes of the
    held-out part (the sensor noise variance removed from the actual one), after the scale;
    NaN when not measured.

    Covariance matching (Mehra 1972, with one common factor): the model fitted on the training
    part filters the held-out part from the final sensors, and Q and R are scaled by the mean
    NIS over its nominal value there, so that a record like the training one is consistent on
    average. An identified model's innovations are not white, so the NIS averaged over a window
    varies more than chi-square with ``window * p`` degrees of freedom says; the share of those
    degrees of freedom that matches the spread of the held-out windows (Satterthwaite's
    moment match, from the upper 95 % confidence bound of that spread, since the held-out part
    gives only a few windows) is what the consistency test then uses. With one or two held-out
    windows after the first (a short record, such as the closed loop's 2 s calibration) only
    the scale is matched (the rest at its default: measured on the main job, the unmatched S
    was 15 % too large there, and 5 of its 9 calibration windows fell below their bound);
    with none, (1, 1).

    ``growth`` is the filter's ``innovation_growth``: the running mean square of the estimate
    at the sensors over those windows (the level the scale was matched at) and the model
    error's share of the scaled ``S`` there (one minus the sensor noise's share,
    ``noise^2 tr(S^-1) / p``). An identified model's one-step error grows with the field: on
    the steady runs of the detection family (``tests/estimator_family.py``, a matched load
    3x as long as the test runs) the window NIS per sensor rose affinely with the field's mean
    square at the sensors (R^2 0.6-0.97 on the real spans), to 1.5-5 by the end of a 22 s
    run, and 5 of the 7 steady tune runs that warned did so on the windowed NIS. ``None``
    when the held-out field is zero.
    """
    window = DEFAULT_CONSISTENCY_WINDOW
    failed = 1.0, 1.0, None, math.nan, None
    if model is None:
        return failed
    try:
        kf = _steady_filter(model, sensors, noise, q_floor)
        held_est = kf.filter(held[sensors])
        nis = held_est.nis
    except _MODEL_FAILURES:
        return failed
    n_windows = nis.size // window
    if n_windows < 2 or not np.all(np.isfinite(nis)):
        return failed
    means = nis[window: n_windows * window].reshape(-1, window).mean(axis=1) / sensors.size
    scale = float(np.mean(means))
    if not scale > 0:
        return failed
    if means.size < 3:   # the scale only: no spread, growth or spectrum from one or two windows
        return scale, 1.0, None, math.nan, None
    # The level of the field at the sensors that scale was matched at, and the model error's
    # share of S there (the rest is the sensor noise, whose share of the scaled S is known).
    level = float(np.mean(
        sensor_mean_square(held_est.field[sensors], window)[window: n_windows * window]))
    noise_share = noise**2 * float(np.trace(np.linalg.inv(kf.innovation_covariance))) / (
        scale * sensors.size)
    growth = (level, float(np.clip(1.0 - noise_share, 0.0, 1.0))) if level > 0 else None
    ratios = means / scale
    spread = float(np.var(ratios, ddof=1)) * (ratios.size - 1) / float(
        sstats.chi2.ppf(0.05, ratios.size - 1))
    nominal = 2.0 / (window * sensors.size)  # variance of a window's mean NIS / p, chi-square
    fraction = 1.0 if spread <= nominal else nominal / spread
    # The spectral test's reference: the held-out innovations whitened by the scaled S, and
    # the held-out measurements whitened alike with the noise's share of them (white noise
    # whitened by S: noise_share in every bin), which the reference follows.
    factor = whitening_factor(scale * np.asarray(kf.innovation_covariance))
    psd, count = whitened_psd(held_est.innovations, factor, discard=window)
    field = measurement_psd(held[sensors], factor, discard=window)
    reference = ((psd, count, field, noise_share)
                 if count and np.all(np.isfinite(psd)) and np.all(np.isfinite(field)) else None)
    ratio = math.nan
    if candidates is not None:
        unmeasured = np.setdiff1d(candidates, sensors)
        if unmeasured.size and held_est.field is not None:
            error2 = float(np.mean((held_est.field[unmeasured, window:]
                                    - held[unmeasured, window:]) ** 2)) - data_noise**2
            reported2 = scale * float(np.mean(held_est.field_variances[unmeasured, window:]))
            if error2 > 0:
                ratio = math.sqrt(reported2 / error2)
    return scale, float(fraction), reference, ratio, growth


def _unmeasured_error(kf, X: np.ndarray, unmeasured: np.ndarray, sensors: np.ndarray,
                      data_noise: float):
    """(actual error variance, reported Riccati variance, running mean square of the estimate)
    of ``kf`` filtering the record ``X``, averaged over ``unmeasured``: three arrays over time
    (NaN where the record has a gap). With a spectral field reference the filter scales the
    variances it reports by the factor its windowed test puts on ``S``
    (``Estimate.field_growth``): the reported variance holds it, and the running mean square
    is multiplied by it, as the filter does to its ``field_relative_variance`` term."""
    est = kf.filter(X[sensors])
    field = est.field[unmeasured]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN samples of a gapped record
        error2 = np.nanmean((field - X[unmeasured]) ** 2, axis=0) - data_noise**2
    reported = np.mean(est.field_variances[unmeasured], axis=0) / kf.field_variance_scale
    power = np.mean(running_mean_square(field, DEFAULT_CONSISTENCY_WINDOW), axis=0)
    if est.field_growth is not None:
        power = power * est.field_growth
    return error2, reported, power


def _field_error_model(X: np.ndarray, kf, partial_kf, n_fit: int, candidates: np.ndarray,
                       sensors: np.ndarray, data_noise: float, others=(), others_noise=()
                       ) -> tuple[float, float, int]:
    """(field variance scale, relative field variance, records of ``others`` that set the
    level) of the shipped filter: its shape fitted on the whole record, its level on the
    held-out part, or on ``others`` (records of other load histories, sensor noise std
    ``others_noise``) when there are any; (1, 0, 0) when there is nothing to fit.

    ``kf`` is the filter that ships without its field terms (the model refitted on the whole
    record, its final sensors and covariance scale) and ``partial_kf`` the same filter on the
    model fitted on the first ``n_fit`` samples. The error at the unmeasured moving nodes,
    averaged over them, is modelled as ``a * v + b * m(t)``: ``v`` the variance the filter
    reports there (its Riccati solution) and ``m(t)`` the running mean square of the estimate
    there (:func:`~powerline_control.estimate.running_mean_square`, the filter's own
    definition), both times the factor the filters (with the shipped spectral reference) put on
    their field variances (``Estimate.field_growth``: the per-frequency growth of the windowed
    test's ``S``, near 1 on the record itself). ``kf`` filtering the whole record gives ``a``
    and ``b`` by non-negative least
    squares (the first consistency window, the start-up, left out); ``partial_kf`` filtering the
    whole record then gives, on the held-out samples it was not fitted on, the ratio of the
    actual error variance to ``a * v + b * m(t)``, which multiplies both: what a model makes of
    data it has not seen, which its own record understates. ``a`` becomes the filter's
    ``field_variance_scale`` (clipped to ``_FIELD_SCALE_MIN``-``_FIELD_SCALE_MAX``), ``b`` its
    ``field_relative_variance``.

    Why (measured on the 24 tune designs of ``tests/estimator_family.py``, reported over actual
    sigma at unmeasured nodes, median and range): an identified real-span model is wrong by
    20-60 % of the field, so its error grows as the line rings up (2-4x in variance over a 7 s
    run from rest). A constant scale learned on the held-out tail (the previous rule) matched
    steady records (0.84, 0.59-1.24) and over-reported new runs from rest (1.46, 0.98-2.92); a
    constant fitted on the whole record did the reverse (1.02 from rest, 0.57 in steady
    state). ``a * v + b * m(t)`` fitted on the whole record follows both (0.99, 0.60-1.55 from
    rest; 0.86, 0.60-1.32 steady) but trusts the record the model was fitted on (held-out
    factors 1.0-2.4); with the held-out level 1.09 (0.69-2.10) and 0.97 (0.61-1.66). The
    held-out tail alone holds too little ring-up to separate ``a`` from ``b`` (0.50-2.45 from
    rest).

    With ``others`` the level is instead the actual over the predicted error variance of ``kf``
    itself on them, pooled over their samples (the first window of each left out): the
    held-out part continues the load histories the model was fitted on, and a line that rings
    longer than the record keeps their modal amplitudes into it, so it understates the error on
    a new load history (Drake 300 m clamped, 24 sensors, broadband: reported over actual sigma
    0.60-0.72 on five new runs with the held-out level, 0.87-1.04 with the level of two other
    runs; ``docs/estimation.md``).
    """
    unmeasured = np.setdiff1d(candidates, sensors)
    window = DEFAULT_CONSISTENCY_WINDOW
    if others:
        return _records_error_model(X, kf, unmeasured, sensors, data_noise, others,
                                    others_noise)
    if (unmeasured.size == 0 or partial_kf is None or n_fit <= window
            or X.shape[1] - n_fit <= window):
        return 1.0, 0.0, 0
    try:
        coef = _error_shape(kf, X, unmeasured, sensors, data_noise)
        level_runs = [(_unmeasured_error(partial_kf, X, unmeasured, sensors, data_noise), n_fit)]
    except (EstimationError, np.linalg.LinAlgError):  # pragma: no cover - the design's filter
        return 1.0, 0.0, 0
    if coef is None:
        return 1.0, 0.0, 0
    predicted, actual = _pooled_level(coef, level_runs)
    if not (predicted > 0 and actual > 0):
        return 1.0, 0.0, 0
    level = actual / predicted
    return (float(np.clip(level * coef[0], _FIELD_SCALE_MIN, _FIELD_SCALE_MAX)),
            float(level * coef[1]), 0)


def _error_shape(kf, X: np.ndarray, unmeasured: np.ndarray, sensors: np.ndarray,
                 data_noise: float) -> np.ndarray | None:
    """``(a, b)`` of the error model ``a * v + b * m(t)`` fitted by NNLS on ``kf`` filtering
    the whole record ``X`` (see :func:`_field_error_model`); None when the record cannot fit
    it (no reported variance, too few samples after the first window)."""
    window = DEFAULT_CONSISTENCY_WINDOW
    error2, reported, power = _unmeasured_error(kf, X, unmeasured, sensors, data_noise)
    kept = np.isfinite(error2) & np.isfinite(power)
    kept[:window] = False
    if not (np.all(reported > 0) and np.count_nonzero(kept) > window):
        return None
    # Columns scaled to unit RMS so that NNLS is not steered by their units.
    columns = np.column_stack([reported[kept], power[kept]])
    norms = np.sqrt(np.mean(columns**2, axis=0))
    norms[norms == 0] = 1.0
    return sopt.nnls(columns / norms, error2[kept])[0] / norms


def _pooled_level(coef: np.ndarray, level_runs) -> tuple[float, float]:
    """(predicted, actual) error variance summed over the samples of ``level_runs`` (each the
    :func:`_unmeasured_error` of a run and the first sample that counts)."""
    predicted = actual = 0.0
    for (run2, run_reported, run_power), start in level_runs:
        used = np.isfinite(run2) & np.isfinite(run_power)
        used[:start] = False
        predicted += float(np.sum(coef[0] * run_reported[used] + coef[1] * run_power[used]))
        actual += float(np.sum(run2[used]))
    return predicted, actual


def _records_error_model(X: np.ndarray, kf, unmeasured: np.ndarray, sensors: np.ndarray,
                         data_noise: float, others, others_noise) -> tuple[float, float, int]:
    """:func:`_field_error_model` with ``model_error_records``: the level from ``kf`` on the
    records alone (no model of part of the record, no held-out part needed). The shape is
    fitted on the training record; where it cannot be (or is zero) the reported variance alone
    (``a = 1, b = 0``) takes the level. Where the records give no level, warns
    :class:`~powerline_control.errors.ModelErrorRecordsWarning` (naming why and what would
    work) and reports (1, 0, 0): no unmeasured moving node, or the filter fails. Records whose
    error at the unmeasured nodes is no larger than their sensor noise measure a model error
    below it: the terms are then set to their floor (scale ``_FIELD_SCALE_MIN``, relative 0),
    with a warning, since a record noise std set too high reads the same."""
    window = DEFAULT_CONSISTENCY_WINDOW
    name = "The 'model_error_records' parameter"
    if unmeasured.size == 0:
        warnings.warn(f"{name} was not used: every moving node of the training record is a "
                      f"sensor ({sensors.size}), so there is no unmeasured node to measure the "
                      "model error at. Choose fewer sensors to use the records.",
                      ModelErrorRecordsWarning, stacklevel=5)
        return 1.0, 0.0, 0
    try:
        coef = _error_shape(kf, X, unmeasured, sensors, data_noise)
        level_runs = [(_unmeasured_error(kf, other, unmeasured, sensors, sigma), window)
                      for other, sigma in zip(others, others_noise, strict=True)]
    except (EstimationError, np.linalg.LinAlgError) as exc:  # pragma: no cover
        warnings.warn(f"{name} was not used: the designed filter failed on them ({exc}). "
                      "Give records of the same line and sensors without gaps.",
                      ModelErrorRecordsWarning, stacklevel=5)
        return 1.0, 0.0, 0
    if coef is None or not np.any(coef > 0):
        coef = np.array([1.0, 0.0])
    predicted, actual = _pooled_level(coef, level_runs)
    if not predicted > 0:  # pragma: no cover - a steady filter reports a positive variance
        warnings.warn(f"{name} was not used: the filter reports no error variance at the "
                      "unmeasured nodes on them.", ModelErrorRecordsWarning, stacklevel=5)
        return 1.0, 0.0, 0
    if not actual > 0:
        n_used = sum(int(np.count_nonzero(np.isfinite(r[0][window:]))) for r, _ in level_runs)
        warnings.warn(
            f"{name}: on its {len(others)} record(s) the error of the estimate at the "
            f"unmeasured nodes is no larger than their sensor noise (mean error variance minus "
            f"noise variance {actual / max(n_used, 1):.3g} m^2, noise std "
            f"{', '.join(f'{s:.3g}' for s in others_noise)} m): the model error is below the "
            "noise there, and the model-error terms are set to their floor. If the records' "
            "noise_std overstates their noise, give the true one; records of broader loads "
            "measure more error.", ModelErrorRecordsWarning, stacklevel=5)
        return _FIELD_SCALE_MIN, 0.0, len(others)
    level = actual / predicted
    return (float(np.clip(level * coef[0], _FIELD_SCALE_MIN, _FIELD_SCALE_MAX)),
            float(level * coef[1]), len(others))


def _delay_rank(coords: np.ndarray, delays: int) -> int:
    """Directions of the delay-embedded coordinates above 1e-6 of the largest singular value."""
    k, n = coords.shape
    rows = np.vstack([coords[:, delays - 1 - i: n - i - 1] for i in range(delays)])
    eig = sla.eigvalsh(rows @ rows.T)
    return int(np.count_nonzero(eig > 1e-12 * eig[-1])) if eig[-1] > 0 else 0


def _lift(model: DMDModel, spatial: np.ndarray) -> DMDModel:
    """The model fitted on spatial coordinates, re-expressed on the nodes (exactly)."""
    n, k = spatial.shape
    d, r = model.delays, model.n_states
    if model.basis is None:
        raise IdentificationError("internal: the recipe always fits with a rank")
    basis = np.einsum("nk,dkr->dnr", spatial, model.basis.reshape(d, k, r)).reshape(d * n, r)
    # The field map is the current snapshot's block of the basis; taking those very rows (not
    # spatial @ field_map, equal only to round-off) keeps save_model / load_model bit-exact.
    return dataclasses.replace(
        model,
        n_nodes=n,
        field_map=read_only(basis[:n].copy()),
        basis=read_only(basis),
    )


def _dmd_design(rec: _Record, alphas) -> EstimatorDesign:
    """The time-delay DMD design: alpha from held-out data, sensors, calibrated filter."""
    X, dt, delays = rec.X, rec.dt, rec.delays
    coords, spatial, noise, q_floor = rec.coords, rec.spatial, rec.noise, rec.q_floor
    # 4. Alpha from held-out data: the error of the estimator itself at unmeasured nodes.
    grid = _DEFAULT_ALPHAS if alphas is None else check_array("alphas", alphas, ndim=1)
    if grid.size == 0 or np.any(grid < 0):
        raise InputError(f"The 'alphas' parameter must be a non-empty list of values >= 0. "
                         f"Got {alphas!r}.")
    n_fit = rec.n_fit
    # The rank cannot exceed what the (training part of the) delay embedding holds above
    # round-off: a clean harmonic record has two directions per sinusoid.
    rank = max(1, min(rec.rank, _delay_rank(coords[:, :n_fit], delays)))
    errors = np.array([
        _held_out_error(coords[:, :n_fit], X[:, n_fit:], spatial, dt, float(a), delays, rank,
                        rec.provisional, rec.candidates, noise, rec.data_noise, q_floor)
        for a in grid
    ])
    # A best alpha at the top of the sweep says the held-out error may still be falling there:
    # widen by factors of 100 until the minimum is inside the sweep, up to relative alpha 1
    # (beyond which Tikhonov damping outweighs every direction of the data).
    grid = np.array(grid, dtype=float)
    while (np.isfinite(errors).any() and grid[-1] > 0 and grid[-1] < _ALPHA_CAP
           and int(np.nanargmin(np.where(np.isfinite(errors), errors, np.nan))) == grid.size - 1):
        wider = min(grid[-1] * _ALPHA_WIDEN, _ALPHA_CAP)
        grid = np.append(grid, wider)
        errors = np.append(errors, _held_out_error(
            coords[:, :n_fit], X[:, n_fit:], spatial, dt, wider, delays, rank, rec.provisional,
            rec.candidates, noise, rec.data_noise, q_floor))
    if not np.isfinite(errors).any():
        raise IdentificationError(
            "No alpha of the sweep gives a usable estimator on the held-out data (every model "
            "was unstable or its filter failed). Try larger alphas, fewer delays or a lower rank."
        )
    alpha = float(grid[int(np.nanargmin(np.where(np.isfinite(errors), errors, np.nan)))])
    sweep = AlphaSweep(alphas=read_only(np.array(grid, dtype=float)),
                       held_out_error=read_only(errors), layout=read_only(rec.provisional),
                       n_fit=n_fit)
    reduced = fit_dmd(coords, dt, alpha=alpha, alpha_mode="relative", delays=delays, rank=rank)
    lifted = _lift(reduced, spatial)
    model = _stabilise(lifted)

    # 5. Sensors on the final model.
    chosen, selection = _choose_sensors(model, rec.given, rec.candidates, rec.n_sensors,
                                        rec.criterion, noise, rec.positions, rec.forbidden,
                                        rec.seed)

    # The model of the training part at the chosen alpha: fitted once, for the covariance
    # matching on the held-out part and the level of the model-error terms below.
    try:
        partial_model = _sweep_model(coords[:, :n_fit], spatial, dt, alpha, delays, rank)
    except _MODEL_FAILURES:
        partial_model = None
    return _calibrated_design(rec, model, partial_model, chosen, selection, sweep,
                              spatial_rank=rec.k, n_stabilised=lifted.n_unstable,
                              excitation=rec.excitation)


def _calibrated_design(rec: _Record, model, partial_model, chosen: np.ndarray, selection,
                       sweep: AlphaSweep, *, spatial_rank: int, n_stabilised: int,
                       excitation) -> EstimatorDesign:
    """The design of ``model`` on the ``chosen`` sensors, its filter's covariance matched on the
    held-out part with ``partial_model`` (the same model from the training part alone; None:
    not measured) and its model-error terms fitted (:func:`_field_error_model`). Shared by the
    DMD and the physics families."""
    X, dt, n_fit, noise, q_floor = rec.X, rec.dt, rec.n_fit, rec.noise, rec.q_floor
    scale, fraction, reference, sigma_ratio, growth = _calibration(
        partial_model, X[:, n_fit:], chosen, noise, q_floor, rec.candidates, rec.data_noise)
    # Model error at the unmeasured nodes, which the innovations cannot show: fitted on the
    # shipped filter's own record, a scale of its variance and a share of the field. The
    # filters it is fitted with have the shipped spectral reference, so that their reported
    # variances follow the field as the shipped filter's do (Estimate.field_growth).
    field_scale, field_relative, level_records = 1.0, 0.0, 0
    try:
        partial = None if partial_model is None else _steady_filter(
            partial_model, chosen, noise, q_floor, scale, reference=reference,
            adapt_horizon=rec.adapt_horizon)
    except _MODEL_FAILURES:
        partial = None
    if partial is not None or rec.others:  # the records' level needs no partial filter
        field_scale, field_relative, level_records = _field_error_model(
            X, _steady_filter(model, chosen, noise, q_floor, scale, reference=reference,
                              adapt_horizon=rec.adapt_horizon),
            partial, n_fit, rec.candidates, chosen, rec.data_noise, rec.others,
            rec.others_noise)
    kf = _steady_filter(model, chosen, noise, q_floor, scale, fraction, rec.warn_inconsistent,
                        reference, field_scale, field_relative, growth, rec.adapt_horizon)
    return EstimatorDesign(
        model=model,
        sensors=read_only(chosen),
        filter=kf,
        noise_std=float(noise),
        noise_source=rec.source,
        alpha_sweep=sweep,
        spatial_rank=spatial_rank,
        sensor_selection=selection,
        n_train=rec.n_samples,
        n_stabilised=n_stabilised,
        q_floor=q_floor,
        excitation=excitation,
        covariance_scale=scale,
        nis_dof_fraction=fraction,
        coverage=build_coverage(X[chosen], dt, rec.data_noise, model, kf, chosen),
        held_out_sigma_ratio=sigma_ratio,
        field_variance_scale=field_scale,
        field_relative_variance=field_relative,
        innovation_growth=growth,
        n_model_error_records=level_records,
    )
