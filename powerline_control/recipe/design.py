"""One estimator recipe: identify a reduced model, choose the sensors, build the Kalman filter.

:func:`design_estimator` turns a training record of nodal displacements into a ready
:class:`EstimatorDesign`.  Every decision the package's users used to make by hand lives here,
with defaults measured to generalise (``docs/identification.md``, "The estimator recipe"):

1. **Spatial reduction.**  The snapshots are projected on their leading spatial POD modes
   (at most ``spatial_rank``),
   so that nothing later costs more than ``O(n_nodes)`` per sample: the ``n`` nodes enter only
   through output maps (``DMDModel.field_map``).
2. **Time-delay DMD with rank truncation** (``delays``, ``rank``) on those coordinates, with the
   Tikhonov ``alpha`` chosen on held-out data by what matters here: the error of the resulting
   estimator at the nodes it does not measure (alpha = 0 is on the grid).
3. **Sensors** by :func:`~powerline_control.sensors.select_sensors` on the identified model's
   node outputs (Kalman criterion, supports and other motionless nodes excluded).
4. **Filter**: a steady-state :class:`~powerline_control.estimate.KalmanFilter` on the measured
   rows only, ``Q`` = the model's residual covariance, ``R`` = the sensor noise variance (given,
   taken from :class:`~powerline_control.simulate.Snapshots`, or estimated from the data).

A *narrowband* record (a harmonic load alone: the forced response plus the free transients of an
undamped span, a sum of spectral lines down to the noise) replaces step 2: its lines are found in
the data's POD directions completed with smooth fields over the node positions, and the model is
one undamped oscillator per line with process noise (:class:`ExcitationReport`; it warns
:class:`~powerline_control.errors.ExcitationWarning`, since such a record cannot teach the modes it
does not excite). A DMD model of such a record learns the forced mode and little else.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import control as ct
import numpy as np
import scipy.linalg as sla
import scipy.stats as sstats

from ._estimate_spectrum import whitened_psd, whitening_factor
from ._recipe_coverage import Coverage, build_coverage
from ._spectral import extract_lines, line_occupancy, line_power
from ._validation import (
    check_array,
    check_budget,
    check_choice,
    check_indices,
    check_int,
    check_real,
    check_snapshot_matrix,
    read_only,
)
from .errors import (
    EstimationError,
    ExcitationWarning,
    IdentificationError,
    IllConditionedWarning,
    InputError,
)
from .estimate import DEFAULT_CONSISTENCY_WINDOW, KalmanFilter
from .identify import DMDModel, fit_dmd
from .sensors import select_sensors

__all__ = ["AlphaSweep", "EstimatorDesign", "ExcitationReport", "design_estimator"]

# tests/test_recipe.py reaches the line extraction under its recipe-private name.
_extract_lines = extract_lines

#: Default number of stacked snapshots (the model state spans delays * dt of history).
DEFAULT_DELAYS = 8
#: Default POD rank of the delay-embedded model.
DEFAULT_RANK = 30
#: Largest number of spatial POD coordinates kept before delay embedding.
DEFAULT_SPATIAL_RANK = 24
#: Modal model: process noise per step and line coordinate, in sensor-noise variances.
DEFAULT_PROCESS_NOISE = 1.0
#: A record is narrowband when fewer than this fraction of its frequency bins rise above the
#: noise (spectral lines occupy a few bins each; broadband excitation tens of %).
_NARROWBAND_OCCUPANCY = 0.05
#: ... and when removing its lines leaves at most this multiple of the noise variance.
_NARROWBAND_RESIDUAL = 1.5
#: Most spectral lines extracted (each costs a few DTFTs of the record).
_MAX_LINES = 60
#: Modal model: smooth directions outside the lines' shapes, appended as white states with this
#: many sensor-noise variances (what a narrowband record never showed, fitted to each sample).
_UNSEEN_COUNT = 8
_UNSEEN_NOISE = 100.0
#: Relative alphas of the held-out sweep (0 first: exact on clean data, no damping bias).
_DEFAULT_ALPHAS = np.array([0.0, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2])
#: Factor between the alphas appended when the best one sits at the top of the sweep, and the
#: largest relative alpha the widening reaches.
_ALPHA_WIDEN = 100.0
_ALPHA_CAP = 1.0
#: Process-noise floor of the filter, as a fraction of the data's mean square (see _steady_filter).
_Q_FLOOR_FRACTION = 1e-10
# A sensor noise a million times the record's RMS carries no information, and its square (R)
# would overflow long before the bound (noise_std=1e300 raised a raw OverflowError).
_NOISE_TO_RMS_MAX = 1e6
_NOISE_STD_MAX = 1e100  # without a record's RMS to compare with: R = noise_std**2 stays finite
#: Radius that eigenvalues outside the unit circle are pulled to (see _stabilise).
_STABLE_RADIUS = 1.0 - 1e-6
#: Spatial POD coordinates below this fraction of the largest singular value are round-off.
_ROUND_OFF_FRACTION = 1e-7
#: Nodes whose training RMS is below this fraction of the largest never move (supports).
_MOTIONLESS_FRACTION = 1e-6


@dataclass(frozen=True, eq=False)
class AlphaSweep:
    """How :func:`design_estimator` chose alpha: the estimator's own held-out error per alpha.

    Attributes
    ----------
    alphas : ndarray
        Relative Tikhonov alphas tried (the given or default grid, then any widening above it).
    held_out_error : ndarray
        Relative RMS error at the unmeasured moving nodes on the held-out part of the record,
        noise-corrected, with the provisional ``layout`` (``inf``: unstable model or failed filter).
    layout : ndarray of int
        Provisional sensors used for the sweep (evenly spread over the moving nodes, or the
        given sensors).
    n_fit : int
        Samples that trained each model of the sweep; the rest were held out.
    alpha_mode : str
        Always "relative" (alphas are fractions of the largest squared singular value).

    Examples
    --------
    See :class:`EstimatorDesign`.
    """

    alphas: np.ndarray
    held_out_error: np.ndarray
    layout: np.ndarray
    n_fit: int
    alpha_mode: str = "relative"


@dataclass(frozen=True, eq=False)
class EstimatorDesign:
    """An identified model, a sensor layout and the Kalman filter on those sensors.

    Build it with :func:`design_estimator`.

    Attributes
    ----------
    model : DMDModel
        The identified reduced model (state: POD coordinates of the delay window).
    sensors : ndarray of int
        Measured node indices (rows of the training snapshots), ascending; read-only.
    filter : KalmanFilter
        Steady-state filter on the measured rows only (``C = model.field_map[sensors]``).
    noise_std : float
        Sensor noise standard deviation used for ``R``, m.
    noise_source : str
        Where ``noise_std`` came from: "given", "snapshots" or "estimated".
    alpha_sweep : AlphaSweep
        The held-out sweep that chose ``model.alpha``.
    spatial_rank : int
        Spatial POD coordinates kept before delay embedding.
    sensor_selection : SensorSelection or None
        The sensor optimisation result (``None`` when ``sensors`` were given).
    n_train : int
        Samples used for the final fit.
    n_stabilised : int
        Eigenvalues of the least-squares fit that lay outside the unit circle and were pulled
        radially to 1 - 1e-6 (0 for a stable fit).
    q_floor : float
        Variance (m^2) added to every diagonal entry of the filter's ``Q`` (1e-10 of the data's
        mean square): it keeps the Riccati equation solvable on noise-free data.
    excitation : ExcitationReport or None
        What the record excites above its noise (narrowband or broadband, its spectral lines)
        and which model was built ("modal" or "dmd").
    covariance_scale : float
        Common factor of the filter's ``Q`` and ``R`` found by covariance matching on the
        held-out part of the record (the model fitted on the rest, filtered from the final
        sensors: mean NIS over its nominal value); it scales the reported covariance and leaves
        the estimate unchanged. 1 for the modal model and for records too short to measure it.
    nis_dof_fraction : float
        Share of each consistency window's chi-square degrees of freedom that the held-out
        windows' spread supports (the filter's ``nis_dof_fraction``; 1 when not measured).
    coverage : Coverage or None
        The field of view: the band the training record covered at the sensors, the model's
        modes with the share of each that the sensors see, the filter's steady sigma at every
        node; ``coverage.check(measurements)`` warns when a record's power lies outside the
        band (``None`` for designs built by hand).
    held_out_sigma_ratio : float
        On the held-out part of the record (the model fitted on the rest, filtered from the
        final sensors, after ``covariance_scale``): the reported over the actual RMS error at
        the unmeasured moving nodes, the sensor noise removed from the actual one. Near 1: the
        reported sigma is honest on data like the training record; NaN when not measured (the
        modal model, short records), measured before ``field_variance_scale``.
    field_variance_scale : float
        Factor on the field variances the filter reports, ``held_out_sigma_ratio ** -2``
        (clipped to 0.01-100; 1 when not measured): the model error at nodes no sensor sees,
        which the innovations (and ``covariance_scale``) cannot show.

    Examples
    --------
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    >>> snap = plc.simulate(model, plc.RandomForce(1.0, 0.5, 80.0, seed=1), 2.0, 1e-3,
    ...                     noise_fraction=0.01, seed=0)
    >>> design = plc.design_estimator(snap, n_sensors=3, delays=4, rank=12, seed=0)
    >>> design.sensors.shape, design.estimate_field(snap.displacement[design.sensors]).shape
    ((3,), (21, 2001))
    """

    model: DMDModel
    sensors: np.ndarray
    filter: KalmanFilter
    noise_std: float
    noise_source: str
    alpha_sweep: AlphaSweep
    spatial_rank: int
    sensor_selection: object
    n_train: int
    n_stabilised: int = 0
    q_floor: float = 0.0
    excitation: ExcitationReport | None = None
    covariance_scale: float = 1.0
    nis_dof_fraction: float = 1.0
    coverage: Coverage | None = None
    held_out_sigma_ratio: float = math.nan
    field_variance_scale: float = 1.0

    @property
    def alpha_curve(self) -> AlphaSweep:
        """The same as :attr:`alpha_sweep` (the name of the first version of the recipe)."""
        return self.alpha_sweep

    @property
    def n_nodes(self) -> int:
        """Number of nodes of the field the filter reconstructs."""
        return self.model.n_nodes

    def estimate_field(self, measurements: object, *, noise_std: float | None = None
                       ) -> np.ndarray:
        """Filter a record of the sensors and return the whole field.

        Parameters
        ----------
        measurements : array_like, shape (n_sensors, n_t)
            Displacements measured at :attr:`sensors` (in that order), m; NaN = missing.
        noise_std : float, optional
            Sensor noise standard deviation of this record, m, when it differs from the
            design's :attr:`noise_std` (e.g. other sensors); a filter with that ``R`` is used.

        Returns
        -------
        ndarray, shape (n_nodes, n_t)
            Estimated displacement of every node, m (read-only).

        Raises
        ------
        InputError
            Wrong shape or infinite values.

        Examples
        --------
        See :class:`EstimatorDesign`.
        """
        y = check_array("measurements", measurements, ndim=(1, 2), allow_nan=True)
        y = y[None, :] if y.ndim == 1 else y
        if y.shape[0] != self.sensors.size:
            raise InputError(
                f"The 'measurements' parameter must have one row per sensor ({self.sensors.size}:"
                f" nodes {self.sensors.tolist()}), time along columns. Got shape {y.shape}."
            )
        kf = self.filter
        if noise_std is not None:
            rms = math.sqrt(self.q_floor / _Q_FLOOR_FRACTION) if self.q_floor > 0 else math.nan
            noise_std = _check_noise_std(noise_std, rms)
            if noise_std != self.noise_std:
                kf = _steady_filter(self.model, self.sensors, noise_std, self.q_floor,
                                    self.covariance_scale, self.nis_dof_fraction,
                                    self.filter.warn_inconsistent,
                                    field_scale=self.field_variance_scale)
        return read_only(kf.filter(y).field)

    def summary(self) -> str:
        """A few lines in words: model, alpha, sensors and the filter's predicted accuracy.

        Returns
        -------
        str
            Plain text, one item per line.

        Examples
        --------
        See :class:`EstimatorDesign`.
        """
        m = self.model
        report = m.stability_report(warn=False)
        head = (f"Estimator for {m.n_nodes} nodes from {self.sensors.size} sensors "
                f"(nodes {self.sensors.tolist()}).")
        if self.excitation is not None and self.excitation.method == "modal":
            lines = [
                head,
                f"Model: one undamped oscillator per spectral line of the record "
                f"({self.excitation.n_lines} lines, {2 * self.excitation.n_lines} states) and "
                f"{m.n_states - 2 * self.excitation.n_lines} white states for smooth directions "
                f"the record never excited; shapes in {self.spatial_rank} spatial directions "
                f"(POD completed with smooth fields), trained on {self.n_train} samples at "
                f"dt = {m.dt:g} s; no alpha.",
                self.excitation.message,
                f"Sensor noise std {self.noise_std:.3g} m ({self.noise_source}).",
            ]
        else:
            lines = [
                head,
                f"Model: time-delay DMD, {m.delays} delays ({m.delays * m.dt * 1e3:.3g} ms of "
                f"history), {m.n_states} POD coordinates of {self.spatial_rank} spatial ones, "
                f"trained on {self.n_train} samples at dt = {m.dt:g} s.",
                f"Tikhonov alpha {m.alpha_relative:.3g} relative ({m.alpha:.3g} absolute), "
                f"chosen by the estimator's error at unmeasured nodes on held-out data "
                f"({100 * float(np.nanmin(self.alpha_sweep.held_out_error)):.3g} %); "
                + report.message,
                f"Sensor noise std {self.noise_std:.3g} m ({self.noise_source}).",
            ]
            if self.excitation is not None:
                lines.insert(3, self.excitation.message)
        if self.n_stabilised:
            lines.insert(3, f"{self.n_stabilised} eigenvalue(s) of the least-squares fit lay just "
                            "outside the unit circle and were pulled to radius 1 - 1e-6.")
        if self.sensor_selection is not None:
            sel = self.sensor_selection
            lines.append(
                f"Sensors chosen by the {sel.criterion} criterion ({sel.certificate} "
                f"certificate, gap {100 * sel.gap:.2g} %)."
            )
        field_std = np.sqrt(np.maximum(self.field_variance_scale * np.einsum(
            "ij,jk,ik->i", m.field_map, self.filter.steady_covariance, m.field_map), 0.0))
        lines.append(
            f"Predicted steady-state RMS field error {float(np.sqrt(np.mean(field_std**2))):.3g}"
            " m (from the model's own Riccati solution; check it on held-out data)."
        )
        if self.covariance_scale != 1.0 or self.nis_dof_fraction != 1.0:
            lines.append(
                f"Q and R scaled by {self.covariance_scale:.3g} so that the held-out NIS is "
                f"nominal (covariance matching); every record is checked by a windowed NIS "
                f"test on {self.nis_dof_fraction:.3g} of the chi-square degrees of freedom "
                "(Estimate.consistency)."
            )
        if math.isfinite(self.held_out_sigma_ratio):
            lines.append(
                f"On the held-out part the reported sigma at unmeasured nodes was "
                f"{self.held_out_sigma_ratio:.3g} x the actual error: field variances scaled by "
                f"{self.field_variance_scale:.3g}."
            )
        if self.filter.spectral_reference is not None:
            lines.append("Every record's innovation spectrum is compared with the held-out one "
                         "(Consistency.spectral_ratio).")
        if self.coverage is not None and math.isfinite(self.coverage.band[0]):
            lines.append(
                f"Training band at the sensors {self.coverage.band[0]:.4g}-"
                f"{self.coverage.band[1]:.4g} Hz (coverage.check(record) warns on power outside)."
            )
        return "\n".join(lines)


# Bounds of the field-variance scale learned on held-out data (a factor 10 on the sigma).
_FIELD_SCALE_MIN, _FIELD_SCALE_MAX = 1e-2, 1e2


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
        with warnings.catch_warnings():
            # Expected along the sweep: plain DMD (alpha = 0) may be ill-conditioned.
            warnings.simplefilter("ignore", IllConditionedWarning)
            reduced = fit_dmd(train, dt, alpha=alpha, alpha_mode="relative", delays=delays,
                              rank=min(rank, train.shape[0] * delays))
        model = _stabilise(_lift(reduced, spatial))
        field = _steady_filter(model, layout, noise, q_floor).filter(held[layout]).field
    except (EstimationError, IdentificationError, InputError, np.linalg.LinAlgError,
            ct.ControlDimension):
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


def _steady_filter(model: DMDModel, sensors: np.ndarray, noise_std: float,
                   q_floor: float, scale: float = 1.0, dof_fraction: float = 1.0,
                   warn: bool = False,
                   reference: tuple[np.ndarray, int] | None = None,
                   field_scale: float = 1.0) -> KalmanFilter:
    """Steady-state filter on the measured rows, Q = residual covariance + floor, R = noise^2,
    both times ``scale`` (the covariance matching of :func:`_calibration`).

    The floor (1e-10 of the data's mean square per coordinate, far below any noisy record's
    residual) keeps the Riccati equation solvable on noise-free data, whose residual covariance
    is round-off: undamped modes without process noise have no stabilising solution. A common
    scale of Q and R scales the Riccati solution alike and leaves the gain, hence the estimate,
    unchanged: only the reported covariance (and the NIS) changes.
    """
    q = np.array(model.residual_covariance)
    q[np.diag_indices_from(q)] += q_floor
    return KalmanFilter(
        model.to_statespace(measured=sensors.tolist()),
        Q=scale * q,
        R=scale * noise_std**2,
        steady_state=True,
        field_map=model.field_map,
        nis_dof_fraction=dof_fraction,
        warn_inconsistent=warn,
        spectral_reference=None if reference is None else reference[0],
        spectral_reference_count=1 if reference is None else reference[1],
        field_variance_scale=field_scale,
    )


def _calibration(train: np.ndarray, held: np.ndarray, spatial: np.ndarray, dt: float,
                 alpha: float, delays: int, rank: int, sensors: np.ndarray, noise: float,
                 q_floor: float, candidates: np.ndarray | None = None, data_noise: float = 0.0
                 ) -> tuple[float, float, tuple[np.ndarray, int] | None, float]:
    """(covariance scale, NIS dof fraction, spectral reference, held-out sigma ratio).

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
    gives only a few windows) is what the consistency test then uses. (1, 1) when the held-out
    part holds fewer than three windows after the first (no spread to measure).
    """
    window = DEFAULT_CONSISTENCY_WINDOW
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IllConditionedWarning)
            reduced = fit_dmd(train, dt, alpha=alpha, alpha_mode="relative", delays=delays,
                              rank=min(rank, train.shape[0] * delays))
        model = _stabilise(_lift(reduced, spatial))
        kf = _steady_filter(model, sensors, noise, q_floor)
        held_est = kf.filter(held[sensors])
        nis = held_est.nis
    except (EstimationError, IdentificationError, InputError, np.linalg.LinAlgError,
            ct.ControlDimension):
        return 1.0, 1.0, None, math.nan
    n_windows = nis.size // window
    if n_windows < 4 or not np.all(np.isfinite(nis)):
        return 1.0, 1.0, None, math.nan
    means = nis[window: n_windows * window].reshape(-1, window).mean(axis=1) / sensors.size
    scale = float(np.mean(means))
    if not scale > 0:
        return 1.0, 1.0, None, math.nan
    ratios = means / scale
    spread = float(np.var(ratios, ddof=1)) * (ratios.size - 1) / float(
        sstats.chi2.ppf(0.05, ratios.size - 1))
    nominal = 2.0 / (window * sensors.size)  # variance of a window's mean NIS / p, chi-square
    fraction = 1.0 if spread <= nominal else nominal / spread
    # The spectral test's reference: the held-out innovations whitened by the scaled S.
    factor = whitening_factor(scale * np.asarray(kf.innovation_covariance))
    psd, count = whitened_psd(held_est.innovations, factor, discard=window)
    reference = (psd, count) if count and np.all(np.isfinite(psd)) else None
    ratio = math.nan
    if candidates is not None:
        unmeasured = np.setdiff1d(candidates, sensors)
        if unmeasured.size and held_est.field is not None:
            error2 = float(np.mean((held_est.field[unmeasured, window:]
                                    - held[unmeasured, window:]) ** 2)) - data_noise**2
            reported2 = scale * float(np.mean(held_est.field_variances[unmeasured, window:]))
            if error2 > 0:
                ratio = math.sqrt(reported2 / error2)
    return scale, float(fraction), reference, ratio


def _check_noise_std(noise_std: object, rms: float) -> float:
    """A positive sensor noise std, at most ``_NOISE_TO_RMS_MAX`` times the data's RMS."""
    noise_std = check_real("noise_std", noise_std, low=0.0)
    if rms > 0 and noise_std > _NOISE_TO_RMS_MAX * rms:
        raise InputError(
            f"The 'noise_std' parameter must be <= {_NOISE_TO_RMS_MAX * rms:.3g} m "
            f"({_NOISE_TO_RMS_MAX:g} times the training record's RMS {rms:.3g} m: a larger noise "
            f"carries no information). Got {noise_std!r}."
        )
    if not rms > 0 and noise_std > _NOISE_STD_MAX:
        raise InputError(
            f"The 'noise_std' parameter must be <= {_NOISE_STD_MAX:g} m (its square is the "
            f"filter's R). Got {noise_std!r}."
        )
    return noise_std


def _snapshot_matrix(snapshots: object, dt: object) -> tuple[np.ndarray, float, float, object]:
    """(X, dt, noise_std or nan, positions or None) from Snapshots or an array."""
    if hasattr(snapshots, "displacement") and hasattr(snapshots, "dt"):
        X = check_snapshot_matrix("snapshots.displacement", snapshots.displacement)
        given_dt = float(snapshots.dt)
        if dt is not None and check_real("dt", dt, low=0.0) != given_dt:
            raise InputError(
                f"The 'dt' parameter ({dt!r}) contradicts the snapshots' own dt ({given_dt!r}); "
                "leave it out for Snapshots."
            )
        noise = float(getattr(snapshots, "noise_std", math.nan))
        positions = getattr(snapshots, "x", None)
        return X, given_dt, (noise if noise > 0 else math.nan), positions
    if dt is None:
        raise InputError(
            "The 'dt' parameter is required when 'snapshots' is an array (n_nodes, n_samples)."
        )
    X = check_snapshot_matrix("snapshots", snapshots)
    return X, check_real("dt", dt, low=0.0), math.nan, None


def _noise_floor(s: np.ndarray, shape: tuple[int, int]) -> tuple[float, float]:
    """(noise std, singular-value threshold) from the bulk of the singular values.

    White noise of std ``sigma`` on an ``n x N`` matrix has singular values spread around
    ``sigma sqrt(N)`` (Marchenko-Pastur); the median of the spectrum estimates that bulk when the
    signal occupies fewer than half of the directions, and Gavish & Donoho's (2014) optimal hard
    threshold ``omega(beta) * median`` separates signal from noise.
    """
    n, N = min(shape), max(shape)
    beta = n / N
    mp_median = _marchenko_pastur_median(beta)
    median = float(np.median(s))
    sigma = median / math.sqrt(N * mp_median)
    omega = 0.56 * beta**3 - 0.95 * beta**2 + 1.82 * beta + 1.43
    return sigma, omega * median


def _marchenko_pastur_median(beta: float) -> float:
    """Median of the Marchenko-Pastur law with ratio ``beta`` (unit variance), by bisection."""
    lo, hi = (1 - math.sqrt(beta)) ** 2, (1 + math.sqrt(beta)) ** 2
    if beta <= 1e-9:
        return 1.0
    # x = centre - half cos(theta) takes the square-root edges (and, at beta = 1, the 1 / x pole
    # at x = 0) out of the integrand: half^2 sin^2(theta) / (2 pi beta x) is smooth in theta.
    # Midpoint rule, so that x = 0 itself is never evaluated.
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    edges = np.linspace(0.0, math.pi, 4001)
    mid = (edges[1:] + edges[:-1]) / 2
    weight = half**2 * np.sin(mid) ** 2 / (2 * math.pi * beta * (centre - half * np.cos(mid)))
    cdf = np.cumsum(weight)
    cdf /= cdf[-1]
    return float(np.interp(0.5, cdf, centre - half * np.cos(edges[1:])))


def _spatial_basis(X: np.ndarray, max_rank: int) -> tuple[np.ndarray, np.ndarray]:
    """Leading left singular vectors and all singular values of X (via the n x n Gram matrix)."""
    n, N = X.shape
    if n <= N:
        gram = X @ X.T
        w, V = sla.eigh(gram)
        order = np.argsort(w)[::-1]
        s = np.sqrt(np.maximum(w[order], 0.0))
        return V[:, order[:max_rank]], s
    U, s, _ = sla.svd(X, full_matrices=False)
    return U[:, :max_rank], s


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


# ------------------------------------------------------------------ narrowband records
@dataclass(frozen=True, eq=False)
class ExcitationReport:
    """What the training record excites above its noise, as :func:`design_estimator` saw it.

    A record is *narrowband* when, in the spatial coordinates, a few spectral lines hold all its
    power above the sensor noise (a harmonic load with the free start-up transients of an
    undamped span); it is then not persistently exciting: only the modes among those lines can
    be identified, and loads that excite other modes are beyond any model of it.

    Attributes
    ----------
    narrowband : bool
        True when spectral lines explain the record down to the noise (see ``occupancy``).
    occupancy : float
        Fraction of the frequency bins (0 to Nyquist) whose summed power over the spatial
        coordinates exceeds the level white noise reaches in 0.1 % of bins: a few % for lines,
        tens of % for broadband excitation.
    frequencies : ndarray
        Frequencies (Hz, ascending) of the spectral lines found above the noise (narrowband
        records only; empty otherwise): the forcing and the modes the record excites.
    residual_ratio : float
        Mean square left after removing those lines, over the noise variance (about 1 when the
        lines explain everything; NaN for broadband records).
    method : str
        The model built: "modal" (one oscillator per line) or "dmd" (time-delay DMD).

    Examples
    --------
    A harmonic load alone: the record holds the load's line and the span's start-up modes.

    >>> import warnings, powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    >>> snap = plc.simulate(model, plc.HarmonicForce(1.0, 18.3, 1.6), 4.0, 1e-3,
    ...                     noise_fraction=0.01, seed=3)
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", plc.ExcitationWarning)  # it is narrowband
    ...     design = plc.design_estimator(snap, n_sensors=3, seed=0)
    >>> report = design.excitation
    >>> report.narrowband, report.method, bool(abs(report.frequencies - 18.3).min() < 0.01)
    (True, 'modal', True)
    """

    narrowband: bool
    occupancy: float
    frequencies: np.ndarray
    residual_ratio: float
    method: str

    @property
    def n_lines(self) -> int:
        """Number of spectral lines found (forcing and excited modes)."""
        return int(self.frequencies.size)

    @property
    def message(self) -> str:
        """One sentence: what the record excites and what a model of it can know."""
        if not self.narrowband and self.method == "modal":  # asked for: method="modal"
            return (f"Record not narrowband ({self.n_lines} spectral lines leave "
                    f"{self.residual_ratio:.3g} x the noise variance; "
                    f"{100 * self.occupancy:.2g} % of the frequency bins above the noise): one "
                    "oscillator per line as asked (method='modal'); what the lines leave out is "
                    "not modelled.")
        if not self.narrowband and self.occupancy >= _NARROWBAND_OCCUPANCY:
            return (f"Broadband record ({100 * self.occupancy:.2g} % of the frequency bins above "
                    "the noise): time-delay DMD model.")
        if not self.narrowband:  # few bins, but its spectral lines do not explain it
            return (f"Not a line spectrum: {100 * self.occupancy:.2g} % of the frequency bins "
                    "above the noise, but its spectral lines leave much more than the noise: "
                    "time-delay DMD model.")
        f = self.frequencies
        listed = ", ".join(f"{v:.4g}" for v in f[:12]) + (", ..." if f.size > 12 else "")
        return (f"Narrowband record: {f.size} spectral lines above the noise ({listed} Hz; "
                f"{100 * self.occupancy:.2g} % of the frequency bins), which leave "
                f"{self.residual_ratio:.3g} x the noise variance: one oscillator per line. It is "
                "not persistently exciting: a load that excites modes other than these (e.g. "
                f"broadband, or above {f.max():.4g} Hz) is beyond what this record can teach; "
                "train on a record with broadband excitation (e.g. a RandomForce alongside the "
                "harmonic load) for such loads.")


def _smooth_basis(positions: np.ndarray, moving: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` smoothest unit fields over the moving nodes (zero on the others).

    Eigenvectors of the lumped-mass second-difference operator along the node positions, with
    the motionless nodes as fixed ends and free ends where the line stops (a string's modes:
    sines on a uniform pinned mesh). They carry no information from the data: they complete
    its POD with the smooth directions a record excites too weakly to show above its noise.
    """
    order = np.argsort(positions, kind="stable")
    x = np.asarray(positions, dtype=float)[order]
    if x.size < 2 or not np.all(np.diff(x) > 0):
        x = np.arange(x.size, dtype=float)          # repeated positions: the node order
    idx = np.flatnonzero(moving[order])
    count = min(count, idx.size)
    if count == 0:
        return np.zeros((x.size, 0))
    if idx.size == 1:  # one moving node (also a one-node record: no element lengths)
        fields = np.zeros((x.size, 1))
        fields[order[idx]] = 1.0
        return fields
    inv_h = 1.0 / np.diff(x)                        # 1 / element length, between node j, j+1
    left = np.where(idx > 0, inv_h[np.maximum(idx - 1, 0)], 0.0)
    right = np.where(idx < x.size - 1, inv_h[np.minimum(idx, x.size - 2)], 0.0)
    with np.errstate(divide="ignore"):
        mass = 0.5 * (np.where(left > 0, 1.0 / left, 0.0) + np.where(right > 0, 1.0 / right, 0.0))
    scale = 1.0 / np.sqrt(mass)
    diag = (left + right) * scale**2
    adjacent = np.diff(idx) == 1                    # both neighbours move: coupled
    off = np.where(adjacent, -inv_h[idx[:-1]], 0.0) * scale[:-1] * scale[1:]
    _, vectors = sla.eigh_tridiagonal(diag, off, select="i", select_range=(0, count - 1))
    fields = np.zeros((x.size, vectors.shape[1]))
    fields[order[idx]] = vectors * scale[:, None]
    return fields / np.linalg.norm(fields, axis=0)


def _completed_basis(pod: np.ndarray, smooth: np.ndarray, size: int) -> np.ndarray:
    """The POD directions, then smooth directions orthogonal to them, ``size`` in all."""
    rest = smooth - pod @ (pod.T @ smooth)
    q, r = sla.qr(rest, mode="economic")
    independent = np.abs(np.diag(r)) > 1e-3  # what the POD directions do not already span
    return np.hstack([pod, q[:, independent]])[:, :size]


def _modal_model(frequencies: np.ndarray, shapes: np.ndarray, dt: float, n_pairs: int,
                 process_noise: float, unseen: np.ndarray | None = None,
                 unseen_noise: float = 0.0) -> DMDModel:
    """One undamped oscillator per line, as a two-delay model of the line's coordinates.

    State ``[b_k; b_{k-1}]`` with ``b = Qᵀ x`` the coordinates of the field on the
    orthonormalised line shapes ``Q``; each line's amplitude obeys
    ``a_{k+1} = 2 rho cos(omega dt) a_k - rho^2 a_{k-1}`` (rho = 1 - 1e-6). Process noise
    ``process_noise`` (m^2 per step) enters every current coordinate alike: the unknown load of
    a new run, which the filter then tracks from the sensors.
    """
    n, r = shapes.shape
    q, upper = sla.qr(shapes, mode="economic")
    rho = _STABLE_RADIUS
    c1 = 2 * rho * np.cos(2 * np.pi * frequencies * dt)
    inv = sla.solve_triangular(upper, np.eye(r))
    a11 = upper @ (c1[:, None] * inv)
    a12 = -(rho**2) * np.eye(r)
    A = np.block([[a11, a12], [np.eye(r), np.zeros((r, r))]])
    u = 0 if unseen is None else unseen.shape[1]
    A = np.block([[A, np.zeros((2 * r, u))], [np.zeros((u, 2 * r + u))]])
    basis = np.zeros((2 * n, 2 * r + u))
    basis[:n, :r] = q
    basis[n:, r:2 * r] = q
    field_map = np.hstack([q, np.zeros((n, r))] + ([unseen] if u else []))
    if u:
        basis[:n, 2 * r:] = unseen
    cov = np.zeros((2 * r + u, 2 * r + u))
    cov[:r, :r] = process_noise * np.eye(r)
    cov[2 * r:, 2 * r:] = unseen_noise * np.eye(u)
    return DMDModel(
        A=read_only(A), B=None, dt=dt, alpha=0.0, alpha_relative=0.0, delays=2,
        rank=2 * r + u, n_nodes=n, field_map=read_only(field_map), basis=read_only(basis),
        residual_covariance=read_only(cov), n_pairs=n_pairs,
        initial_state=read_only(np.zeros(2 * r + u)),
    )


def _unseen_directions(fields: np.ndarray, smooth: np.ndarray) -> np.ndarray:
    """Up to ``_UNSEEN_COUNT`` smooth directions that the line shapes leave out (orthonormal)."""
    q, _ = np.linalg.qr(fields)
    rest = smooth - q @ (q.T @ smooth)
    basis, upper = sla.qr(rest, mode="economic")
    new = np.abs(np.diag(upper)) > 0.3     # mostly outside the lines' span
    return basis[:, new][:, :_UNSEEN_COUNT]


def _independent_lines(frequencies: np.ndarray, shapes: np.ndarray, spatial: np.ndarray,
                       strength: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Drop lines whose field shape the others already span (their oscillator is unobservable
    apart from its twin and makes the filter's Riccati equation singular).

    The strongest lines (``strength``, e.g. their power) are kept first: with one node every
    shape is the same, and the line kept must be the record's, not a weak neighbour of it.
    The kept lines stay in the given (ascending frequency) order.
    """
    fields = spatial @ shapes
    keep: list[int] = []
    order = (range(fields.shape[1]) if strength is None
             else np.argsort(-np.asarray(strength), kind="stable"))
    for j in order:
        if keep:
            q, _ = np.linalg.qr(fields[:, keep])
            distance = float(np.linalg.norm(fields[:, j] - q @ (q.T @ fields[:, j])))
        else:
            distance = float(np.linalg.norm(fields[:, j]))
        if distance > 1e-6:   # unit columns: 1e-6 is round-off of a repeated shape
            keep.append(int(j))
    keep.sort()
    return frequencies[keep], fields[:, keep]


def design_estimator(
    snapshots: object,
    n_sensors: int = 5,
    *,
    dt: float | None = None,
    delays: int = DEFAULT_DELAYS,
    rank: int = DEFAULT_RANK,
    spatial_rank: int = DEFAULT_SPATIAL_RANK,
    alphas: Sequence[float] | np.ndarray | None = None,
    noise_std: float | None = None,
    sensors: Sequence[int] | np.ndarray | None = None,
    positions: object = None,
    forbidden: object = None,
    criterion: str = "kalman",
    train_fraction: float = 0.7,
    seed: int | np.random.Generator | None = None,
    method: str = "auto",
    process_noise: float = DEFAULT_PROCESS_NOISE,
    warn_inconsistent: bool = False,
) -> EstimatorDesign:
    """Identify a reduced model, select sensors and build the Kalman filter, in one call.

    Parameters
    ----------
    snapshots : Snapshots or array_like, shape (n_nodes, n_samples)
        Training record of every node (e.g. :func:`~powerline_control.simulate.simulate`'s
        result, or measured displacements with ``dt``).
    n_sensors : int, default 5
        Number of sensors to choose (ignored when ``sensors`` is given).
    dt : float, optional
        Sample time in seconds; required for an array, taken from Snapshots otherwise.
    delays : int, default 8
        Stacked snapshots of the model state.
    rank : int, default 30
        POD coordinates of the delay-embedded model (the filter's state size).
    spatial_rank : int, default 24
        At most this many spatial POD coordinates (fewer when the data's noise floor says so)
        are kept before the delay embedding; cost grows with it, not with ``n_nodes``.
    alphas : sequence of float, optional
        Relative Tikhonov alphas to try (default: 0 and 1e-10, 1e-8, ..., 1e-2); the one whose
        estimator has the smallest error at unmeasured nodes on the held-out data wins. When the
        best is the largest, the sweep widens by factors of 100 (up to relative alpha 1) until
        its minimum lies inside (``alpha_sweep.alphas`` lists every alpha tried).
    noise_std : float, optional
        Sensor noise standard deviation, m.  Default: from Snapshots, else estimated from the
        noise floor of the data's singular values.
    sensors : sequence of int, optional
        Use these nodes instead of optimising the layout.
    positions : array_like, optional
        Node positions (m), for ``forbidden``; default the Snapshots' ``x``.
    forbidden : sequence of (float, float), optional
        Intervals (m) where no sensor may go.
    criterion : str, default "kalman"
        Sensor-selection criterion (see :func:`~powerline_control.sensors.select_sensors`).
    train_fraction : float, default 0.7
        Fraction of the record that trains the models of the alpha sweep; the rest is held out
        (filtered from the provisional layout, scored at every other moving node).  The final
        model is fitted on the whole record.
    seed : int, Generator or None
        Seed of the sensor selection's random baseline.
    method : {"auto", "dmd", "modal"}, default "auto"
        "dmd": time-delay DMD (steps 1-4 above). "modal": one undamped oscillator per spectral
        line of the record (frequency and spatial shape found above the noise, in the data's POD
        directions completed with smooth fields over ``positions``); ``delays``, ``rank`` and
        ``alphas`` are then not used. "auto": "modal" when the record is narrowband (its
        spectral lines explain it down to the noise: a harmonic load), else "dmd". A narrowband
        record warns :class:`~powerline_control.errors.ExcitationWarning` (see
        :attr:`EstimatorDesign.excitation`).
    process_noise : float, default 1
        Modal model only: process-noise variance per step and line coordinate, in units of the
        sensor noise variance (the unknown load of a new run, tracked from the sensors).
    warn_inconsistent : bool, default False
        Build the filter with ``warn_inconsistent=True``: its ``filter`` then warns
        :class:`~powerline_control.errors.EstimatorInconsistentWarning` when a record fails the
        windowed NIS test (``Estimate.consistency`` reports the test either way).

    Returns
    -------
    EstimatorDesign
        Model, sensors, filter, and the intermediate results.

    Raises
    ------
    InputError
        Bad arguments (named), a record too short for ``delays`` and ``horizon``, or a problem
        over the memory budget.
    IdentificationError
        No dynamics in the data.

    Warns
    -----
    ExcitationWarning
        The record is narrowband (not persistently exciting): the design knows only the modes
        among its spectral lines.

    Examples
    --------
    See :class:`EstimatorDesign`.
    """
    X, dt, snap_noise, snap_positions = _snapshot_matrix(snapshots, dt)
    n_nodes, n_samples = X.shape
    n_sensors = check_int("n_sensors", n_sensors, low=1, high=n_nodes)
    delays = check_int("delays", delays, low=1, high=max(1, n_samples // 4))
    spatial_rank = check_int("spatial_rank", spatial_rank, low=1)
    rank = check_int("rank", rank, low=1, high=spatial_rank * delays)
    criterion = check_choice("criterion", criterion, ("kalman", "gramian", "min-eig",
                                                      "reconstruction"))
    train_fraction = check_real("train_fraction", train_fraction, low=0.0, high=1.0,
                                high_inclusive=False)
    method = check_choice("method", method, ("auto", "dmd", "modal"))
    process_noise = check_real("process_noise", process_noise, low=0.0, high=1e6)
    if not isinstance(warn_inconsistent, bool):
        raise InputError("The 'warn_inconsistent' parameter must be True or False. Got "
                         f"{warn_inconsistent!r}.")
    if positions is None:
        positions = snap_positions
    if positions is not None:
        positions = check_array("positions", positions, shape=(n_nodes,))
    if noise_std is not None:
        noise_std = _check_noise_std(noise_std, float(np.sqrt(np.mean(X**2))))
    check_budget(
        "design_estimator's spatial Gram matrix and projection",
        nbytes=8.0 * (min(n_nodes, n_samples) ** 2 + 3 * spatial_rank * delays * n_samples),
        flops=2.0 * n_nodes * n_nodes * n_samples,
        parameter="snapshots", value=f"shape {X.shape}",
        fix="use fewer nodes or a shorter record",
    )
    if not np.any(X):
        raise IdentificationError(
            "The 'snapshots' are all zeros: there are no dynamics to identify."
        )
    if not np.any(X != X[:, :1]):
        raise IdentificationError(
            "The 'snapshots' are constant in time (every node keeps its first value): there are "
            "no dynamics to identify. Give a record of the vibrating span."
        )

    # 1. Spatial POD: the coordinates above round-off (at most spatial_rank).
    spatial, s = _spatial_basis(X, min(spatial_rank, n_nodes))
    sigma_est, gd_threshold = _noise_floor(s, X.shape)
    above = int(np.count_nonzero(s > _ROUND_OFF_FRACTION * s[0]))
    k = max(1, min(spatial_rank, above, n_nodes))
    k = min(max(k, math.ceil(rank / delays)), spatial.shape[1])  # enough for the rank
    spatial = spatial[:, :k]
    rank = min(rank, k * delays)
    coords = spatial.T @ X

    # 2. Noise level (R of the filter, and the held-out score's noise correction).
    if noise_std is not None:
        source, noise = "given", noise_std
    elif math.isfinite(snap_noise):
        source, noise = "snapshots", snap_noise
    else:
        source, noise = "estimated", sigma_est
    rms = float(np.sqrt(np.mean(X**2)))
    data_noise = noise  # what the held-out measurements actually carry
    q_floor = _Q_FLOOR_FRACTION * rms**2
    noise = max(noise, 1e-4 * rms)  # noise-free data still needs a well-posed Riccati equation

    # 3. Candidates: every node that moves; a provisional layout for the alpha sweep.
    node_rms = np.sqrt(np.mean(X**2, axis=1))
    candidates = np.flatnonzero(node_rms > _MOTIONLESS_FRACTION * node_rms.max())
    if sensors is not None:
        given = np.sort(check_indices("sensors", sensors, n_nodes))
        # Motionless: below the RMS floor, or reading nothing but the noise (a support of a
        # noisy record: its mean square within 5 standard errors of the noise variance).
        noise_only = node_rms**2 <= data_noise**2 * (1 + 5 * math.sqrt(2.0 / n_samples))
        still = np.union1d(np.setdiff1d(given, candidates), given[noise_only[given]])
        if still.size:
            raise InputError(
                f"The 'sensors' parameter holds nodes that do not move in the training record "
                f"({still.tolist()}: supports, or nodes whose RMS is below "
                f"{_MOTIONLESS_FRACTION:g} of the largest or no more than the noise); a sensor "
                "there reads only noise. "
                f"Got {np.asarray(sensors).tolist()}; choose among the moving nodes "
                f"{candidates[0]}..{candidates[-1]}."
            )
        provisional = given
    else:
        given = None
        if candidates.size < n_sensors:
            raise InputError(
                f"The 'n_sensors' parameter ({n_sensors}) exceeds the {candidates.size} nodes "
                "that move in the training record."
            )
        provisional = candidates[np.linspace(0, candidates.size - 1, n_sensors + 2)
                                 .round().astype(int)[1:-1]]
        provisional = np.unique(provisional)

    # 3b. Narrowband record? Then one oscillator per spectral line (the DMD model of such a
    # record knows its forced mode and learns nothing of the modes a new load excites).
    moving = np.zeros(n_nodes, dtype=bool)
    moving[candidates] = True
    node_x = np.arange(n_nodes, dtype=float) if positions is None else positions
    n_signal = max(1, min(k, int(np.count_nonzero(s > gd_threshold))))
    line_basis = _completed_basis(spatial[:, :n_signal],
                                  _smooth_basis(node_x, moving, k + n_signal), k)
    line_coords = line_basis.T @ X
    occupancy = line_occupancy(line_coords, noise)
    excitation = ExcitationReport(narrowband=False, occupancy=occupancy,
                                  frequencies=read_only(np.zeros(0)), residual_ratio=math.nan,
                                  method="dmd")
    if method == "modal" or (method == "auto" and occupancy < _NARROWBAND_OCCUPANCY):
        freqs, shapes, residual = extract_lines(line_coords, dt, min(2 * k, _MAX_LINES))
        ratio = float(np.mean(residual**2)) / noise**2
        if method == "modal" and not freqs.size:
            raise IdentificationError(
                "The 'method' parameter is 'modal' but the record holds no spectral line above "
                f"its noise (std {noise:.3g} m): there is no oscillator to build. Use "
                "method='dmd' or 'auto'."
            )
        if freqs.size and (method == "modal" or ratio < _NARROWBAND_RESIDUAL):
            power = np.array([line_power(line_coords, f, dt) for f in freqs])
            freqs, fields = _independent_lines(freqs, shapes, line_basis, power)
            excitation = ExcitationReport(narrowband=ratio < _NARROWBAND_RESIDUAL,
                                          occupancy=occupancy, frequencies=read_only(freqs),
                                          residual_ratio=ratio, method="modal")
            lines_only = _modal_model(freqs, fields, dt, n_samples - 2, process_noise * noise**2)
            if excitation.narrowband:
                warnings.warn(excitation.message, ExcitationWarning, stacklevel=2)
            # Sensors for what the record showed (the white unseen states below would pull them
            # toward fitting directions with no dynamics).
            chosen, selection = _choose_sensors(lines_only, given, candidates, n_sensors,
                                                criterion, noise, positions, forbidden, seed)
            unseen = _unseen_directions(fields, _smooth_basis(node_x, moving,
                                                              fields.shape[1] + _UNSEEN_COUNT))
            model = _modal_model(freqs, fields, dt, n_samples - 2, process_noise * noise**2,
                                 unseen, _UNSEEN_NOISE * noise**2)
            kf = _steady_filter(model, chosen, noise, q_floor, warn=warn_inconsistent)
            return EstimatorDesign(
                model=model, sensors=read_only(chosen),
                filter=kf,
                coverage=build_coverage(X[chosen], dt, data_noise, model, kf, chosen),
                noise_std=float(noise),
                noise_source=source,
                alpha_sweep=AlphaSweep(alphas=read_only(np.zeros(0)),
                                       held_out_error=read_only(np.zeros(0)),
                                       layout=read_only(provisional), n_fit=0),
                spatial_rank=line_basis.shape[1], sensor_selection=selection,
                n_train=n_samples, n_stabilised=0, q_floor=q_floor, excitation=excitation)

    # 4. Alpha from held-out data: the error of the estimator itself at unmeasured nodes.
    grid = _DEFAULT_ALPHAS if alphas is None else check_array("alphas", alphas, ndim=1)
    if grid.size == 0 or np.any(grid < 0):
        raise InputError(f"The 'alphas' parameter must be a non-empty list of values >= 0. "
                         f"Got {alphas!r}.")
    n_fit = int(round(train_fraction * n_samples))
    # The rank cannot exceed what the (training part of the) delay embedding holds above
    # round-off: a clean harmonic record has two directions per sinusoid.
    rank = max(1, min(rank, _delay_rank(coords[:, :n_fit], delays)))
    if n_fit < 4 * delays or n_samples - n_fit < 4 * delays:
        raise InputError(
            f"The record of {n_samples} samples is too short for delays={delays} with "
            f"train_fraction={train_fraction}: both parts need at least {4 * delays} samples."
        )
    errors = np.array([
        _held_out_error(coords[:, :n_fit], X[:, n_fit:], spatial, dt, float(a), delays, rank,
                        provisional, candidates, noise, data_noise, q_floor)
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
            coords[:, :n_fit], X[:, n_fit:], spatial, dt, wider, delays, rank, provisional,
            candidates, noise, data_noise, q_floor))
    if not np.isfinite(errors).any():
        raise IdentificationError(
            "No alpha of the sweep gives a usable estimator on the held-out data (every model "
            "was unstable or its filter failed). Try larger alphas, fewer delays or a lower rank."
        )
    alpha = float(grid[int(np.nanargmin(np.where(np.isfinite(errors), errors, np.nan)))])
    sweep = AlphaSweep(alphas=read_only(np.array(grid, dtype=float)),
                       held_out_error=read_only(errors), layout=read_only(provisional),
                       n_fit=n_fit)
    reduced = fit_dmd(coords, dt, alpha=alpha, alpha_mode="relative", delays=delays, rank=rank)
    lifted = _lift(reduced, spatial)
    model = _stabilise(lifted)

    # 5. Sensors on the final model.
    chosen, selection = _choose_sensors(model, given, candidates, n_sensors, criterion, noise,
                                        positions, forbidden, seed)

    scale, fraction, reference, sigma_ratio = _calibration(
        coords[:, :n_fit], X[:, n_fit:], spatial, dt, alpha, delays, rank, chosen, noise,
        q_floor, candidates, data_noise)
    # Model error at the unmeasured nodes, which the innovations cannot show: the reported
    # field variance matched to the held-out error there (within a factor 10 either way).
    field_scale = (1.0 if not math.isfinite(sigma_ratio)
                   else float(np.clip(sigma_ratio**-2, _FIELD_SCALE_MIN, _FIELD_SCALE_MAX)))
    kf = _steady_filter(model, chosen, noise, q_floor, scale, fraction, warn_inconsistent,
                        reference, field_scale)
    return EstimatorDesign(
        model=model,
        sensors=read_only(chosen),
        filter=kf,
        noise_std=float(noise),
        noise_source=source,
        alpha_sweep=sweep,
        spatial_rank=k,
        sensor_selection=selection,
        n_train=n_samples,
        n_stabilised=lifted.n_unstable,
        q_floor=q_floor,
        excitation=excitation,
        covariance_scale=scale,
        nis_dof_fraction=fraction,
        coverage=build_coverage(X[chosen], dt, data_noise, model, kf, chosen),
        held_out_sigma_ratio=sigma_ratio,
        field_variance_scale=field_scale,
    )


def _choose_sensors(model: DMDModel, given, candidates: np.ndarray, n_sensors: int,
                    criterion: str, noise: float, positions, forbidden, seed):
    """The given sensors, or the optimised layout over the moving nodes (and its result)."""
    if given is not None:
        return given, None
    cand_positions = None if positions is None else positions[candidates]
    selection = select_sensors(
        model.to_statespace(measured=candidates.tolist()),
        k=n_sensors,
        criterion=criterion,
        Q=model.residual_covariance,
        R=noise**2,
        positions=cand_positions,
        forbidden=forbidden,
        seed=0 if seed is None else seed,
    )
    return np.sort(candidates[list(selection.nodes)]), selection
