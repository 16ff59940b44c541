"""What :func:`~powerline_control.recipe.design_estimator` returns and reports.

:class:`EstimatorDesign` (the model, the sensors, the filter and every intermediate result),
:class:`AlphaSweep` (how alpha was chosen on held-out data) and :class:`ExcitationReport` (what
the record excites above its noise, and whether it is narrowband). Records only: nothing here
fits a model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._results import Result
from .._validation import (
    check_array,
    check_indices,
    read_only,
)
from ..errors import (
    InputError,
)
from ..estimate import KalmanFilter
from ..identify import DMDModel, OscillatorModel, SpanModel
from .coverage import Coverage
from .defaults import _NARROWBAND_OCCUPANCY, _Q_FLOOR_FRACTION
from .record import _check_noise_std
from .sensing import _steady_filter


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
class EstimatorDesign(Result):
    """An identified model, a sensor layout and the Kalman filter on those sensors.

    Build it with :func:`design_estimator`.

    Attributes
    ----------
    model : DMDModel
        The identified reduced model (state: POD coordinates of the delay window), or for a
        narrowband record an :class:`~powerline_control.identify.OscillatorModel` (one
        undamped oscillator per spectral line; a DMDModel subclass).
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
    field_variance_scale, field_relative_variance : float
        The model error at nodes no sensor sees, which the innovations (and
        ``covariance_scale``) cannot show: the filter reports at each node
        ``field_variance_scale`` times its Riccati variance plus ``field_relative_variance``
        times the running mean square of its estimate there (the filter's parameters of the
        same names), their shape fitted on the whole training record at the unmeasured moving
        nodes, their level on the held-out part or on ``model_error_records`` (the scale
        clipped to 0.01-100). 1 and 0 when not fitted (the modal model, short records). With a
        spectral field reference the filter scales both terms by its windowed test's factor on
        ``S`` (``Estimate.field_growth``), and they are fitted with it.
    innovation_growth : tuple of float or None
        The filter's ``innovation_growth``: the running mean square at the sensors of the
        held-out part where ``covariance_scale`` was matched, and the model error's share of
        ``S`` there; once a record's field at the sensors rises above that level, the
        consistency test's ``S`` grows with it (an identified model's one-step error is a share
        of the field). ``None`` when not measured (the modal model, short records). Not used
        by a filter with a ``spectral_field_reference``, whose windowed test follows the field
        per frequency instead.
    n_model_error_records : int
        How many records of other load histories (``design_estimator``'s
        ``model_error_records``) set the level of ``field_variance_scale`` and
        ``field_relative_variance``; 0 when the held-out part of the training record set it
        (or nothing was fitted).
    supports : (str, str) or None
        The supports, left and right, of the line the design was trained on: the training
        Snapshots' (``Snapshots.supports``), else the nominal span's (``design_estimator``'s
        ``nominal``/``bc``); None when the record does not say (a measured array).

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
    field_relative_variance: float = 0.0
    innovation_growth: tuple[float, float] | None = None
    n_model_error_records: int = 0
    supports: tuple[str, str] | None = None

    @property
    def alpha_curve(self) -> AlphaSweep:
        """The same as :attr:`alpha_sweep` (the name of the first version of the recipe)."""
        return self.alpha_sweep

    @property
    def noise_origin(self) -> str:
        """Where :attr:`noise_std` came from, in words (:attr:`noise_source` is its code)."""
        return {"given": "given to the recipe (noise_std): the training record's sensor noise",
                "snapshots": "the training Snapshots' own sensor noise (noise_std)",
                "estimated": "estimated from the record's singular values (Gavish-Donoho noise "
                             "floor)"}.get(self.noise_source, self.noise_source)

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
        return read_only(self.filter_on(self.sensors, noise_std=noise_std).filter(y).field)

    def filter_on(self, sensors: object, *, noise_std: float | None = None) -> KalmanFilter:
        """The design's steady-state filter on other sensors (or with another sensor noise).

        Built as the recipe builds :attr:`filter`: the same model, process-noise floor,
        covariance scale, NIS degrees-of-freedom share and model-error terms
        (:attr:`field_variance_scale`, :attr:`field_relative_variance`), so that another layout
        is judged with the same model and reports its sigma the same way. Only the measured
        rows (and ``R`` with ``noise_std``) differ; the spectral test's reference, measured on
        the design's own sensors and noise, is left out.

        Parameters
        ----------
        sensors : sequence of int
            Measured node indices (distinct, in ``0..n_nodes - 1``), one filter output each, in
            the order given.
        noise_std : float, optional
            Sensor noise standard deviation, m (default the design's :attr:`noise_std`).

        Returns
        -------
        KalmanFilter
            :attr:`filter` itself when ``sensors`` and ``noise_std`` are the design's.

        Raises
        ------
        InputError
            If ``sensors`` is not a list of distinct node indices or ``noise_std`` is not a
            positive finite number.

        Examples
        --------
        >>> import powerline_control as plc
        >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
        >>> snap = plc.simulate(model, plc.RandomForce(1.0, 0.5, 80.0, seed=1), 2.0, 1e-3,
        ...                     noise_fraction=0.01, seed=0)
        >>> design = plc.design_estimator(snap, n_sensors=3, delays=4, rank=12, seed=0)
        >>> kf = design.filter_on([4, 10, 16])
        >>> kf.n_outputs, kf.field_variance_scale == design.field_variance_scale
        (3, True)
        """
        nodes = check_indices("sensors", sensors, self.model.n_nodes)
        noise = self.noise_std
        if noise_std is not None:
            rms = math.sqrt(self.q_floor / _Q_FLOOR_FRACTION) if self.q_floor > 0 else math.nan
            noise = _check_noise_std(noise_std, rms)
        if np.array_equal(nodes, self.sensors) and noise == self.noise_std:
            return self.filter
        return _steady_filter(self.model, nodes, noise, self.q_floor, self.covariance_scale,
                              self.nis_dof_fraction, self.filter.warn_inconsistent,
                              field_scale=self.field_variance_scale,
                              field_relative=self.field_relative_variance,
                              innovation_growth=self.innovation_growth,
                              adapt_horizon=self.filter.adapt_horizon)

    def _sigma_line(self) -> str:
        """The summary's line on the sigma the filter reports: what it is and its RMS."""
        kf = self.filter
        if self.coverage is not None:
            # Coverage.node_sigma: the RMS over the training record of the sigma the filter
            # reports (Estimate.field_variances), model-error terms included.
            sigma = np.asarray(self.coverage.node_sigma)
            where = "the nodes and the training record"
        else:
            m = self.model
            sigma = np.sqrt(np.maximum(kf.field_variance_scale * np.einsum(
                "ij,jk,ik->i", m.field_map, kf.steady_covariance, m.field_map), 0.0))
            where = "the nodes, in steady state"
        terms = "its Riccati variance"
        if kf.field_variance_scale != 1.0:
            terms = f"{kf.field_variance_scale:.3g} x its Riccati variance"
        if kf.field_relative_variance > 0:
            terms += (f" + {kf.field_relative_variance:.3g} x the running mean square of the "
                      "estimate")
        return (f"Reported field sigma: RMS {float(np.sqrt(np.mean(sigma**2))):.3g} m over "
                f"{where} (the filter's Estimate.field_variances: {terms}; check it on "
                "held-out data).")

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
        if isinstance(m, SpanModel):
            lines = [
                head,
                f"Model: {m.describe()}: the span calibrated from the training record, one "
                f"lightly damped oscillator per mode (damping ratio {m.damping_ratio:g}; "
                f"{2 * m.n_lines} states), trained on {self.n_train} samples at "
                f"dt = {m.dt:g} s; no alpha.",
                self.excitation.message,
                f"Sensor noise std {self.noise_std:.3g} m ({self.noise_source}).",
            ]
        elif isinstance(m, OscillatorModel):
            # The model's type says what it is (its alpha and delays are not a DMD fit's).
            lines = [
                head,
                f"Model: {m.describe()}, one undamped oscillator per spectral line of the "
                f"record ({m.n_lines} lines, {2 * m.n_lines} states) and {m.n_unseen} white "
                f"states for smooth directions the record never excited; shapes in "
                f"{self.spatial_rank} spatial directions (POD completed with smooth fields), "
                f"trained on {self.n_train} samples at dt = {m.dt:g} s; no alpha.",
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
        lines.append(self._sigma_line())
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
                f"{self.held_out_sigma_ratio:.3g} x the actual error (before the model-error "
                "terms)."
            )
        if self.field_variance_scale != 1.0 or self.field_relative_variance != 0.0:
            level = (f"its level on {self.n_model_error_records} record(s) of other load histories"
                     if self.n_model_error_records else
                     "its level on the held-out part, which continues the training loads")
            lines.append(
                f"Model error at unmeasured nodes (shape fitted on the training record, {level}):"
                f" variances scaled by {self.field_variance_scale:.3g} plus "
                f"{self.field_relative_variance:.3g} x the running mean square of the estimate "
                "(Estimate.field_variances)."
            )
        if self.filter.spectral_field_reference is not None:
            lines.append("The windowed NIS test's innovation covariance follows the field per "
                         "frequency, as the spectral reference does (estimate._spectrum."
                         "nis_growth), and the field variances grow by the same factor "
                         "(Estimate.field_growth).")
        elif self.innovation_growth is not None:
            lines.append(
                f"The consistency test's innovation covariance grows with the field above the "
                f"held-out level ({self.innovation_growth[0]:.3g} m^2 at the sensors; model error "
                f"{100 * self.innovation_growth[1]:.3g} % of S there)."
            )
        if self.filter.spectral_reference is not None:
            lines.append("Every record's innovation spectrum is compared with the held-out one "
                         + ("(following the field where the training saw one) "
                            if self.filter.spectral_field_reference is not None else "")
                         + "(Consistency.spectral_ratio).")
        if self.coverage is not None and math.isfinite(self.coverage.band[0]):
            lines.append(
                f"Training band at the sensors {self.coverage.band[0]:.4g}-"
                f"{self.coverage.band[1]:.4g} Hz (coverage.check(record) warns on power outside)."
            )
        return "\n".join(lines)


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
        The model built: "modal" (one oscillator per line), "dmd" (time-delay DMD) or
        "physics" (the modes of the span calibrated from the record).

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
        if self.method == "physics":
            kind = "Narrowband" if self.narrowband else "Broadband"
            return (f"{kind} record ({self.n_lines} spectral lines above the noise): the modes "
                    "of the span calibrated from it, near those lines (physics model), chosen "
                    "on the held-out part.")
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
