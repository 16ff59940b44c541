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
   taken from :class:`~powerline_control.simulation.Snapshots`, or estimated from the data).

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

import numpy as np

from .._constants import NOISE_FLOOR_FRACTION
from .._spectral import line_occupancy
from .._validation import (
    check_array,
    check_choice,
    check_indices,
    check_int,
    check_real,
    checked_keywords,
    read_only,
    warn_if_saturated,
)
from ..errors import (
    ExcitationWarning,
    IdentificationError,
    InputError,
    ModelErrorRecordsWarning,
    SaturationWarning,
)
from .defaults import (
    _MOTIONLESS_FRACTION,
    _NARROWBAND_OCCUPANCY,
    _Q_FLOOR_FRACTION,
    _ROUND_OFF_FRACTION,
    DEFAULT_DELAYS,
    DEFAULT_PROCESS_NOISE,
    DEFAULT_RANK,
    DEFAULT_SPATIAL_RANK,
    DEFAULT_TRAIN_FRACTION,
    check_record_work,
    parts_too_short,
    record_parts,
)
from .dmd import _dmd_design
from .modal import _completed_basis, _modal_design, _smooth_basis
from .physics import _check_nominal, _choose
from .record import (
    _check_noise_std,
    _noise_floor,
    _other_records,
    _Record,
    _snapshot_matrix,
    _spatial_basis,
)
from .results import EstimatorDesign, ExcitationReport

__all__ = ["design_estimator"]


@checked_keywords
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
    train_fraction: float = DEFAULT_TRAIN_FRACTION,
    seed: int | np.random.Generator | None = None,
    method: str = "auto",
    process_noise: float = DEFAULT_PROCESS_NOISE,
    warn_inconsistent: bool = False,
    model_error_records: object = None,
    adapt_horizon: int | None = None,
    nominal: object = None,
    bc: object = None,
) -> EstimatorDesign:
    """Identify a reduced model, select sensors and build the Kalman filter, in one call.

    Parameters
    ----------
    snapshots : Snapshots or array_like, shape (n_nodes, n_samples)
        Training record of every node (e.g. :func:`~powerline_control.simulation.simulate`'s
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
    method : {"auto", "dmd", "modal", "physics"}, default "auto"
        "dmd": time-delay DMD (steps 1-4 above). "modal": one undamped oscillator per spectral
        line of the record (frequency and spatial shape found above the noise, in the data's POD
        directions completed with smooth fields over ``positions``); ``delays``, ``rank`` and
        ``alphas`` are then not used. "auto": "modal" when the record is narrowband (its
        spectral lines explain it down to the noise: a harmonic load), else "dmd". A narrowband
        record warns :class:`~powerline_control.errors.ExcitationWarning` (see
        :attr:`EstimatorDesign.excitation`). "physics": the calibrated span's modes
        (``nominal`` required).
    process_noise : float, default 1
        Modal model only: process-noise variance per step and line coordinate, in units of the
        sensor noise variance (the unknown load of a new run, tracked from the sensors).
    warn_inconsistent : bool, default False
        Build the filter with ``warn_inconsistent=True``: its ``filter`` then warns
        :class:`~powerline_control.errors.EstimatorInconsistentWarning` when a record fails the
        windowed NIS test (``Estimate.consistency`` reports the test either way).
    model_error_records : Snapshots or sequence of Snapshots, optional
        Records of every node under other load histories (new random loads, another run), at
        the same node positions and sample time, **with the training record's sensor noise**
        (the same sensors: the level subtracts each record's noise variance from its error, so
        a record noisier or cleaner than its stated or estimated noise std biases the level).
        The level of the model-error terms (:attr:`EstimatorDesign.field_variance_scale` and
        ``field_relative_variance``) is then measured on them, pooled, with the final filter,
        instead of on the held-out part of the record: that part continues the training
        record's load histories, and on a line that rings longer than the record it understates
        the error on new ones (Drake 300 m, 24 sensors: reported over actual sigma 0.60-0.72 on
        five new runs; 0.87-1.04 with two such records, ``docs/estimation.md``). Each record's
        sensor noise std is its own positive ``noise_std``, else estimated from its singular
        values (a Snapshots' ``noise_std`` of 0 means unknown, for these records as for
        ``snapshots``; only the ``noise_std`` parameter of 0 means noise-free). The DMD model
        only: the modal model of a narrowband record has no model-error terms, so
        ``method="modal"`` with records raises :class:`~powerline_control.errors.InputError`
        and ``method="auto"`` choosing the modal model warns
        :class:`~powerline_control.errors.ModelErrorRecordsWarning` (the records are then not
        used).

    adapt_horizon : int, optional
        Build the filter with process noise that follows the record
        (:class:`~powerline_control.estimate.KalmanFilter`'s ``adapt_horizon``, samples): a
        time-varying filter from the stationary covariance whose scale on ``Q`` is matched to
        the innovations over this horizon, ``R`` the sensor noise; the model-error terms are
        fitted with it. Default ``None``: the steady filter with ``Q`` and ``R`` matched once
        on the held-out part (``docs/validation/adaptive_noise.md`` compares the two).
    nominal : Span or LineModel, optional
        The span as told (catalogue conductor, length, supports, stringing tension): adds the
        physics candidate, the nominal span calibrated from the training part of the record
        (:func:`~powerline_control.identify.calibrate_span` at up to 16 evenly spread moving
        nodes) and written as its modes near the record's spectral lines
        (:func:`~powerline_control.identify.span_model`), which carry the standing wave between
        the sensors. With ``method="auto"`` it replaces the DMD or oscillator model when its
        estimator's error at the unmeasured nodes of the held-out part is smaller (the same
        score as the alpha sweep's; ``excitation.method`` is then "physics"); the final
        model is calibrated on the whole record. Needs the node positions (Snapshots' ``x`` or
        ``positions``).
    bc : str or (str, str), optional
        Supports of a nominal Span (default "pinned"); a LineModel carries its own.

    Returns
    -------
    EstimatorDesign
        Model, sensors, filter, and the intermediate results.

    Raises
    ------
    InputError
        Bad arguments (named), a record too short for ``delays`` and ``horizon``, a
        ``model_error_records`` record of other node positions or sample time,
        ``model_error_records`` with ``method="modal"``, or a problem over the memory budget.
    IdentificationError
        No dynamics in the data.

    Warns
    -----
    SaturationWarning
        A node of the training record is clipped (many samples exactly at its largest or
        smallest value: a sensor at its range), see
        ``_validation.warn_if_saturated``.
    ExcitationWarning
        The record is narrowband (not persistently exciting): the design knows only the modes
        among its spectral lines.
    ModelErrorRecordsWarning
        ``model_error_records`` that cannot be used as given: a record whose sensor noise std
        (given or estimated) differs from the training record's by more than 1.5x; records
        dropped because ``method="auto"`` chose the modal model or no moving node is left
        unmeasured; records on which the estimate's error at the unmeasured nodes is no larger
        than their noise (the model-error terms are then set to their floor).

    Examples
    --------
    A lab span under two broadband loads; the level of the model-error terms from a record of
    other load histories with the same sensor noise:

    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    >>> def loads(seed):
    ...     return [plc.RandomForce(1.0, 0.9, 80.0, seed=seed),
    ...             plc.RandomForce(1.0, 2.6, 80.0, seed=seed + 1)]
    >>> rec = plc.simulate(model, loads(3), 3.0, 1e-3, noise_fraction=0.01, seed=0)
    >>> other = plc.simulate(model, loads(23), 2.0, 1e-3, noise_std=rec.noise_std, seed=7)
    >>> design = plc.design_estimator(rec, n_sensors=3, seed=0, delays=4, rank=12,
    ...                               model_error_records=other)
    >>> design.sensors.size, design.n_model_error_records
    (3, 1)

    See also :class:`EstimatorDesign`.
    """
    rec = _prepare(snapshots, n_sensors, dt=dt, delays=delays, rank=rank,
                   spatial_rank=spatial_rank, noise_std=noise_std, sensors=sensors,
                   positions=positions, forbidden=forbidden, criterion=criterion,
                   train_fraction=train_fraction, seed=seed, method=method,
                   process_noise=process_noise, warn_inconsistent=warn_inconsistent,
                   model_error_records=model_error_records, adapt_horizon=adapt_horizon)
    told = _check_nominal(nominal, bc)
    # The supports of the line trained on, for the checks of those who use the design
    # (estimate_clamp_strain needs a clamp): the record's own, else the nominal span's.
    supports = getattr(snapshots, "supports", None)
    if supports is None and told is not None:
        supports = tuple(told[1])
    if rec.method == "physics":
        if told is None:
            raise InputError("The 'method' parameter is 'physics', which calibrates the span "
                             "as told: give 'nominal' (a Span with bc=, or a LineModel). Got "
                             "nominal=None.")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SaturationWarning)
            return _with_supports(_choose(None, rec, *told), supports)
    # A narrowband record gets one oscillator per spectral line, unless ("auto") its lines
    # leave more than noise unexplained; every other record gets a time-delay DMD model.
    # A clipped node was named above: the held-out filter runs on its rows do not repeat it.
    # With a nominal span, the physics candidate then replaces it if it scores better on the
    # held-out part (the narrowband warning waits for that choice).
    design = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SaturationWarning)
        if told is not None:
            warnings.simplefilter("ignore", ExcitationWarning)
        if rec.method == "modal" or (rec.method == "auto"
                                     and rec.excitation.occupancy < _NARROWBAND_OCCUPANCY):
            design = _modal_design(rec)
            if design is not None and rec.others:
                warnings.warn(
                    f"The 'model_error_records' parameter ({len(rec.others)} record(s)) was "
                    "not used: method='auto' chose the modal model for this narrowband "
                    "record, which has no model-error terms. Pass method='dmd' to set their "
                    "level from the records.", ModelErrorRecordsWarning, stacklevel=2)
        if design is None:
            design = _dmd_design(rec, alphas)
        if told is None:
            return _with_supports(design, supports)
        design = _choose(design, rec, *told) if rec.method == "auto" else design
    if design.excitation.narrowband:
        warnings.warn(design.excitation.message, ExcitationWarning, stacklevel=2)
    return _with_supports(design, supports)


def _with_supports(design: EstimatorDesign, supports: object) -> EstimatorDesign:
    """``design`` with the supports of the line it was trained on (None: not known)."""
    if supports is None:
        return design
    return dataclasses.replace(design, supports=(str(supports[0]), str(supports[1])))


#: A model-error record whose sensor noise std differs from the training record's by more than
#: this factor (either way) warns: the level subtracts the record's noise variance.
_NOISE_MISMATCH = 1.5


def _warn_noise_mismatch(others_noise, data_noise: float, source: str) -> None:
    """Warn :class:`ModelErrorRecordsWarning` for each ``model_error_records`` record whose noise
    std is not within ``_NOISE_MISMATCH`` of the training record's ``data_noise``."""
    for i, sigma in enumerate(others_noise):
        low, high = sorted((sigma, data_noise))
        if high > _NOISE_MISMATCH * low:
            warnings.warn(
                f"The 'model_error_records' parameter's record {i} has sensor noise std "
                f"{sigma:.3g} m (its own or estimated), the training record {data_noise:.3g} m "
                f"({source}): more than {_NOISE_MISMATCH:g}x apart. The records must carry the "
                "training record's sensor noise (the same sensors) for their level to hold; give "
                "records of the same sensors, or set their noise_std to the noise they carry.",
                ModelErrorRecordsWarning, stacklevel=4)


def _prepare(snapshots, n_sensors, *, dt, delays, rank, spatial_rank, noise_std, sensors,
             positions, forbidden, criterion, train_fraction, seed, method, process_noise,
             warn_inconsistent, model_error_records, adapt_horizon=None) -> _Record:
    """Check the arguments and read the record: steps 1-3 of the recipe, shared by both
    families (spatial POD, noise level, candidates and provisional layout, line basis)."""
    X, dt, snap_noise, snap_positions = _snapshot_matrix(snapshots, dt)
    n_nodes, n_samples = X.shape
    n_sensors = check_int("n_sensors", n_sensors, low=1, high=n_nodes)
    delays = check_int("delays", delays, low=1)
    spatial_rank = check_int("spatial_rank", spatial_rank, low=1)
    rank = check_int("rank", rank, low=1, high=spatial_rank * delays)
    criterion = check_choice("criterion", criterion, ("kalman", "gramian", "min-eig",
                                                      "reconstruction"))
    train_fraction = check_real("train_fraction", train_fraction, low=0.0, high=1.0,
                                high_inclusive=False)
    n_fit = record_parts(n_samples, train_fraction)[0]
    if parts_too_short(n_samples, delays, train_fraction):   # before any delay embedding
        raise InputError(
            f"The record of {n_samples} samples is too short for delays={delays} with "
            f"train_fraction={train_fraction}: its training and held-out parts ({n_fit} and "
            f"{n_samples - n_fit} samples) need at least {4 * delays} each. Give a longer "
            "record (a few periods of the lowest mode of interest) or fewer 'delays'."
        )
    method = check_choice("method", method, ("auto", "dmd", "modal", "physics"))
    process_noise = check_real("process_noise", process_noise, low=0.0, high=1e6)
    if adapt_horizon is not None:   # the filter's own check, before the alpha sweep
        adapt_horizon = check_int("adapt_horizon", adapt_horizon, low=2)
    if not isinstance(warn_inconsistent, bool):
        raise InputError("The 'warn_inconsistent' parameter must be True or False. Got "
                         f"{warn_inconsistent!r}.")
    if positions is None:
        positions = snap_positions
    if positions is not None:
        positions = check_array("positions", positions, shape=(n_nodes,))
    if noise_std is not None:
        noise_std = _check_noise_std(noise_std, float(np.sqrt(np.mean(X**2))))
    others, others_noise = _other_records(model_error_records, "model_error_records", positions,
                                          n_nodes, dt)
    if others and method == "modal":
        raise InputError(
            f"The 'model_error_records' parameter sets the level of the DMD model's model-error "
            f"terms, which the modal model has none of. Got {len(others)} record(s) with "
            "method='modal'; leave them out, or use method='dmd' (or 'auto')."
        )
    check_record_work(n_nodes, n_samples, parameter="snapshots", value=f"shape {X.shape}",
                      fix="use fewer nodes or a shorter record", spatial_rank=spatial_rank,
                      delays=delays)
    if not np.any(X):
        raise IdentificationError(
            "The 'snapshots' are all zeros: there are no dynamics to identify."
        )
    if not np.any(X != X[:, :1]):
        raise IdentificationError(
            "The 'snapshots' are constant in time (every node keeps its first value): there are "
            "no dynamics to identify. Give a record of the vibrating span."
        )
    # A node that keeps one non-zero value (a stuck sensor at an offset) reads nothing of the
    # line, yet its offset would enter the basis and the model as a mode of its own.
    stuck = np.flatnonzero(np.all(X == X[:, :1], axis=1) & (X[:, 0] != 0))
    if stuck.size:
        raise InputError(
            f"The 'snapshots' parameter: node(s) {stuck.tolist()} keep one non-zero value in "
            f"every sample (node {stuck[0]}: {X[stuck[0], 0]:.6g} m), a stuck or disconnected "
            "sensor that carries no information about the span. Drop those rows (with their "
            "'positions'), or set them to 0 where the line cannot move (a support)."
        )
    # A clipped node (a sensor at its range) would teach the model flat tops: warn, named.
    warn_if_saturated("The 'snapshots' parameter", X, [
        f"node {i}" + ("" if positions is None else f" (x = {positions[i]:.6g} m)")
        for i in range(n_nodes)], stacklevel=3)

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
    noise = max(noise, NOISE_FLOOR_FRACTION * rms)
    _warn_noise_mismatch(others_noise, data_noise, source)

    # 3. Candidates: every node that moves; a provisional layout for the alpha sweep.
    # Motionless: below the RMS floor, or reading nothing but the noise (a support of a noisy
    # record: its mean square within 5 standard errors of the noise variance).
    node_rms = np.sqrt(np.mean(X**2, axis=1))
    noise_only = node_rms**2 <= data_noise**2 * (1 + 5 * math.sqrt(2.0 / n_samples))
    candidates = np.flatnonzero(node_rms > _MOTIONLESS_FRACTION * node_rms.max())
    if sensors is not None:
        given = np.sort(check_indices("sensors", sensors, n_nodes))
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
        # (a record all noise to its own estimate says nothing of its supports: then only the
        # RMS floor counts)
        usable = int(np.count_nonzero(~noise_only[candidates])) or candidates.size
        if usable < n_sensors:
            raise InputError(
                f"The 'n_sensors' parameter ({n_sensors}) exceeds the {usable} nodes that move "
                "in the training record (supports and nodes that read only noise do not count): "
                f"choose n_sensors <= {usable}."
            )
        provisional = candidates[np.linspace(0, candidates.size - 1, n_sensors + 2)
                                 .round().astype(int)[1:-1]]
        provisional = np.unique(provisional)

    # 3b. The basis the spectral lines are sought in, and how much of the spectrum rises above
    # the noise there: what tells a narrowband record (see design_estimator).
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
    return _Record(
        X=X, dt=dt, n_sensors=n_sensors, delays=delays, rank=rank, criterion=criterion,
        n_fit=n_fit, method=method, process_noise=process_noise,
        warn_inconsistent=warn_inconsistent, positions=positions, forbidden=forbidden,
        seed=seed, spatial=spatial, k=k, coords=coords, source=source, noise=noise,
        data_noise=data_noise, q_floor=q_floor, candidates=candidates, given=given,
        provisional=provisional, node_x=node_x, moving=moving, line_basis=line_basis,
        line_coords=line_coords, excitation=excitation, others=tuple(others),
        others_noise=tuple(others_noise), adapt_horizon=adapt_horizon)
