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
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ._validation import (
    check_array,
    check_budget,
    check_choice,
    check_indices,
    check_int,
    check_real,
    read_only,
)
from .errors import EstimationError, IdentificationError, IllConditionedWarning, InputError
from .estimate import KalmanFilter
from .identify import DMDModel, fit_dmd
from .sensors import select_sensors

__all__ = ["AlphaSweep", "EstimatorDesign", "design_estimator"]

#: Default number of stacked snapshots (the model state spans delays * dt of history).
DEFAULT_DELAYS = 8
#: Default POD rank of the delay-embedded model.
DEFAULT_RANK = 30
#: Largest number of spatial POD coordinates kept before delay embedding.
DEFAULT_SPATIAL_RANK = 24
#: Relative alphas of the held-out sweep (0 first: exact on clean data, no damping bias).
_DEFAULT_ALPHAS = np.array([0.0, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2])
#: Process-noise floor of the filter, as a fraction of the data's mean square (see _steady_filter).
_Q_FLOOR_FRACTION = 1e-10
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
        Relative Tikhonov alphas tried.
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
            noise_std = check_real("noise_std", noise_std, low=0.0)
            if noise_std != self.noise_std:
                kf = _steady_filter(self.model, self.sensors, noise_std, self.q_floor)
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
        lines = [
            f"Estimator for {m.n_nodes} nodes from {self.sensors.size} sensors "
            f"(nodes {self.sensors.tolist()}).",
            f"Model: time-delay DMD, {m.delays} delays ({m.delays * m.dt * 1e3:.3g} ms of "
            f"history), {m.n_states} POD coordinates of {self.spatial_rank} spatial ones, "
            f"trained on {self.n_train} samples at dt = {m.dt:g} s.",
            f"Tikhonov alpha {m.alpha_relative:.3g} relative ({m.alpha:.3g} absolute), chosen "
            f"by the estimator's error at unmeasured nodes on held-out data "
            f"({100 * float(np.nanmin(self.alpha_sweep.held_out_error)):.3g} %); "
            + report.message,
            f"Sensor noise std {self.noise_std:.3g} m ({self.noise_source}).",
        ]
        if self.n_stabilised:
            lines.insert(3, f"{self.n_stabilised} eigenvalue(s) of the least-squares fit lay just "
                            "outside the unit circle and were pulled to radius 1 - 1e-6.")
        if self.sensor_selection is not None:
            sel = self.sensor_selection
            lines.append(
                f"Sensors chosen by the {sel.criterion} criterion ({sel.certificate} "
                f"certificate, gap {100 * sel.gap:.2g} %)."
            )
        field_std = np.sqrt(np.maximum(
            np.einsum("ij,jk,ik->i", m.field_map, self.filter.steady_covariance, m.field_map),
            0.0))
        lines.append(
            f"Predicted steady-state RMS field error {float(np.sqrt(np.mean(field_std**2))):.3g}"
            " m (from the model's own Riccati solution; check it on held-out data)."
        )
        return "\n".join(lines)


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
    except (EstimationError, IdentificationError, InputError, np.linalg.LinAlgError):
        return math.inf
    unmeasured = np.setdiff1d(candidates, layout)
    skip = min(held.shape[1] // 4, 10 * delays + 100)  # the filter's start-up transient
    truth = held[unmeasured, skip:]
    mse = float(np.mean((field[unmeasured, skip:] - truth) ** 2)) - data_noise**2
    power = float(np.mean(truth**2)) - data_noise**2
    if not math.isfinite(mse) or power <= 0:
        return math.inf
    return math.sqrt(max(mse, 0.0) / power)


def _steady_filter(model: DMDModel, sensors: np.ndarray, noise_std: float,
                   q_floor: float) -> KalmanFilter:
    """Steady-state filter on the measured rows, Q = residual covariance + floor, R = noise^2.

    The floor (1e-10 of the data's mean square per coordinate, far below any noisy record's
    residual) keeps the Riccati equation solvable on noise-free data, whose residual covariance
    is round-off: undamped modes without process noise have no stabilising solution.
    """
    q = np.array(model.residual_covariance)
    q[np.diag_indices_from(q)] += q_floor
    return KalmanFilter(
        model.to_statespace(measured=sensors.tolist()),
        Q=q,
        R=noise_std**2,
        steady_state=True,
        field_map=model.field_map,
    )


def _snapshot_matrix(snapshots: object, dt: object) -> tuple[np.ndarray, float, float, object]:
    """(X, dt, noise_std or nan, positions or None) from Snapshots or an array."""
    if hasattr(snapshots, "displacement") and hasattr(snapshots, "dt"):
        X = check_array("snapshots.displacement", snapshots.displacement, ndim=2)
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
    X = check_array("snapshots", snapshots, ndim=2)
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
    grid = np.linspace(lo, hi, 4001)
    density = np.sqrt(np.maximum((hi - grid) * (grid - lo), 0.0)) / (2 * math.pi * beta * grid)
    cdf = np.cumsum(density)
    cdf /= cdf[-1]
    return float(np.interp(0.5, cdf, grid))


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
    return dataclasses.replace(
        model,
        n_nodes=n,
        field_map=read_only(spatial @ model.field_map),
        basis=read_only(basis),
    )


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
        estimator has the smallest error at unmeasured nodes on the held-out data wins.
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
    if noise_std is not None:
        noise_std = check_real("noise_std", noise_std, low=0.0)
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

    # 1. Spatial POD: the coordinates above round-off (at most spatial_rank).
    spatial, s = _spatial_basis(X, min(spatial_rank, n_nodes))
    sigma_est, _ = _noise_floor(s, X.shape)
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
    if given is not None:
        chosen, selection = given, None
    else:
        if positions is None:
            positions = snap_positions
        cand_positions = None
        if positions is not None:
            positions = check_array("positions", positions, shape=(n_nodes,))
            cand_positions = positions[candidates]
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
        chosen = np.sort(candidates[list(selection.nodes)])

    kf = _steady_filter(model, chosen, noise, q_floor)
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
    )
