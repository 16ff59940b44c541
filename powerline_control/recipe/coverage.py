"""The field of view of an estimator design: its band, its modes and its per-node sigma.

:func:`~powerline_control.recipe.design_estimator` measures, on its training
record, the spectrum at the chosen sensors (Welch, Hann segments of ``COVERAGE_SEGMENT``
samples, half overlap); the bins holding power above ``COVERED_FACTOR`` times the sensors' noise
are the band the training covered. :meth:`Coverage.check` measures a new record the same way and
warns when more than ``OUTSIDE_LIMIT`` of its power above the noise lies in bins the training
left at the noise floor: the model has never seen that part of the response, and nothing it
estimates there can be trusted.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .._results import Result
from .._validation import check_array, read_only
from ..errors import EstimatorInconsistentWarning, InputError, SaturationWarning
from ..estimate import DEFAULT_CONSISTENCY_WINDOW

__all__ = ["Coverage", "build_coverage"]

#: Samples per Welch segment of the coverage spectra (the spectral test's resolution).
COVERAGE_SEGMENT = 256
#: A bin is covered when the training's mean power at the sensors exceeds the noise by this
#: factor (a broadband training load stands 10^2 to 10^6 above the noise inside its band).
COVERED_FACTOR = 10.0
#: A record warns when more than this share of its power above the noise lies outside the band.
OUTSIDE_LIMIT = 0.05


def sensor_psd(y: np.ndarray, segment: int = COVERAGE_SEGMENT) -> np.ndarray:
    """Mean power per bin over the rows of ``y`` (white noise of variance s^2 reads s^2).

    Segments holding NaN are left out; NaN bins when no full segment remains.
    """
    y = np.asarray(y, dtype=float)
    hop = segment // 2
    starts = np.arange(0, y.shape[1] - segment + 1, hop)
    bad = np.isnan(y).any(axis=0)
    if bad.any() and starts.size:
        counts = np.concatenate([[0], np.cumsum(bad)])
        starts = starts[counts[starts + segment] == counts[starts]]
    if not starts.size:
        return np.full(segment // 2 + 1, np.nan)
    taper = np.hanning(segment + 2)[1:-1]
    blocks = np.where(np.isnan(y), 0.0, y)[:, starts[:, None] + np.arange(segment)[None, :]]
    blocks = (blocks - blocks.mean(axis=-1, keepdims=True)) * taper
    return (np.abs(np.fft.rfft(blocks, axis=-1)) ** 2).mean(axis=(0, 1)) / float(np.sum(taper**2))


@dataclass(frozen=True, eq=False)
class Coverage(Result):
    """What an estimator design can estimate: the training band, the model's modes, node sigma.

    Built by :func:`~powerline_control.recipe.design_estimator` (``EstimatorDesign.coverage``).

    Attributes
    ----------
    band : tuple of float
        Lowest and highest frequency (Hz) of the bins the training record covered at the
        sensors (see ``covered``); ``(nan, nan)`` when none was.
    frequencies : numpy.ndarray
        Bin frequencies of the spectra, Hz, ``(n_bins,)``.
    training_power : numpy.ndarray
        Training record's power per bin at the sensors, averaged over them, m^2 ``(n_bins,)``
        (white noise of variance ``s^2`` reads ``s^2`` in every bin).
    noise_power : float
        The sensors' noise variance, m^2: the floor of ``training_power``.
    covered : numpy.ndarray
        Bins whose training power exceeds ``COVERED_FACTOR`` (10) times ``noise_power`` (bool).
    mode_frequencies : numpy.ndarray
        Frequencies of the model's modes (one per conjugate pair), Hz, ascending.
    mode_observability : numpy.ndarray
        Per mode, the share of its field shape's norm that lies at the sensors
        (``||phi[sensors]|| / ||phi||``; 0: the sensors cannot see it).
    node_sigma : numpy.ndarray
        Standard deviation the filter reports at every node, m ``(n_nodes,)``: its steady
        Riccati part and, with ``field_relative_variance``, the share of the field, as an RMS
        over the training record (after the first consistency window): what it reports on a
        record like that one.
    n_sensors : int or None
        The design's sensor count: a record to judge has one row per sensor (None: unchecked).

    Examples
    --------
    >>> import warnings
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    >>> snap = plc.simulate(model, plc.RandomForce(1.0, 0.5, 60.0, seed=1), 2.0, 1e-3,
    ...                     noise_fraction=0.01, seed=0)
    >>> design = plc.design_estimator(snap, n_sensors=3, delays=4, rank=12, seed=0)
    >>> cov = design.coverage
    >>> bool(cov.band[1] < 200.0), cov.node_sigma.shape
    (True, (21,))
    >>> high = plc.simulate(model, plc.HarmonicForce(1.0, 150.0, 1.3), 1.0, 1e-3,
    ...                     noise_std=design.noise_std, seed=2)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     share = cov.check(high.displacement[design.sensors])
    >>> bool(share > 0.5), caught[0].category.__name__
    (True, 'EstimatorInconsistentWarning')
    """

    band: tuple[float, float]
    frequencies: np.ndarray
    training_power: np.ndarray
    noise_power: float
    covered: np.ndarray
    mode_frequencies: np.ndarray
    mode_observability: np.ndarray
    node_sigma: np.ndarray
    n_sensors: int | None = None

    def outside_share(self, measurements: object) -> float:
        """Share of a record's power above the sensor noise that lies outside the band.

        Parameters
        ----------
        measurements : array_like, shape (n_sensors, n_t)
            The design's sensors (in its order), m; NaN = missing.

        Returns
        -------
        float
            0 when the record holds power only where the training did; 1 when all of it lies
            where the training record held only noise; NaN when the record is shorter than one
            segment (256 samples) or holds nothing above the noise.

        Raises
        ------
        InputError
            Not a 2-D real array, infinite values, or not one row per sensor.

        Examples
        --------
        See :class:`Coverage`.
        """
        y = check_array("measurements", measurements, ndim=2, allow_nan=True)
        if self.n_sensors is not None and y.shape[0] != self.n_sensors:
            raise InputError(
                f"The 'measurements' parameter must hold one row per sensor of the design "
                f"({self.n_sensors}, in its order: y[design.sensors]). Got {y.shape[0]} rows "
                f"(shape {y.shape}); a (n_t, n_sensors) record needs transposing (.T).")
        power = sensor_psd(y, 2 * (self.frequencies.size - 1))
        if not np.all(np.isfinite(power)):
            return float("nan")
        # Only bins significantly above the noise count (the noise itself is everywhere).
        excess = np.where(power > 2.0 * self.noise_power, power - self.noise_power, 0.0)
        excess[0] = 0.0  # an offset is not a mode
        total = float(excess.sum())
        if total <= 0:
            return float("nan")
        return float(excess[~self.covered].sum() / total)

    def check(self, measurements: object, *, warn: bool = True) -> float:
        """:meth:`outside_share`, warning when it exceeds 5 %.

        Parameters
        ----------
        measurements : array_like, shape (n_sensors, n_t)
            The design's sensors (in its order), m; NaN = missing.
        warn : bool, default True
            Warn :class:`~powerline_control.errors.EstimatorInconsistentWarning` when more than
            5 % of the record's power above the noise lies outside the training band.

        Returns
        -------
        float
            The share (see :meth:`outside_share`).

        Raises
        ------
        InputError
            Bad ``measurements`` or a ``warn`` that is not a bool.

        Examples
        --------
        See :class:`Coverage`.
        """
        if not isinstance(warn, bool):
            raise InputError(f"The 'warn' parameter must be True or False. Got {warn!r}.")
        share = self.outside_share(measurements)
        if warn and share > OUTSIDE_LIMIT:
            y = np.asarray(measurements, dtype=float)
            power = sensor_psd(y, 2 * (self.frequencies.size - 1))
            outside = (~self.covered) & (power > 2.0 * self.noise_power)
            outside[0] = False
            top = self.frequencies[outside][np.argsort(power[outside])[::-1][:3]]
            warnings.warn(
                f"{100 * share:.3g} % of this record's power above the sensor noise lies outside "
                f"the band the training record covered ({self.band[0]:.4g}-{self.band[1]:.4g} "
                f"Hz; strongest outside at {', '.join(f'{f:.4g}' for f in top)} Hz): the model "
                "has never seen that response and its estimate there has no meaning. Retrain on "
                "a record with this excitation.",
                EstimatorInconsistentWarning,
                stacklevel=2,
            )
        return share


def build_coverage(train_sensors: np.ndarray, dt: float, noise_std: float, model, kf,
                   sensors: np.ndarray) -> Coverage:
    """The :class:`Coverage` of a design from its training record at the sensors."""
    power = sensor_psd(train_sensors)
    freqs = np.fft.rfftfreq(2 * (power.size - 1), dt)
    noise_power = float(noise_std) ** 2
    covered = np.isfinite(power) & (power > COVERED_FACTOR * noise_power)
    covered[0] = False
    band = ((float(freqs[covered].min()), float(freqs[covered].max())) if covered.any()
            else (float("nan"), float("nan")))
    eigenvalues, vectors = np.linalg.eig(np.asarray(model.A))
    keep = eigenvalues.imag >= 0
    eigenvalues, vectors = eigenvalues[keep], vectors[:, keep]
    field = np.asarray(model.field_map) @ vectors
    norms = np.linalg.norm(field, axis=0)
    seen = np.linalg.norm(field[sensors], axis=0) / np.where(norms > 0, norms, 1.0)
    mode_f = np.abs(np.angle(eigenvalues)) / (2 * np.pi * dt)
    order = np.argsort(mode_f)
    p = np.asarray(kf.steady_covariance)
    m = np.asarray(model.field_map)
    variance = kf.field_variance_scale * np.einsum("ij,jk,ik->i", m, p, m)
    if kf.field_relative_variance > 0:  # plus the share of the training field it reports
        with warnings.catch_warnings():
            # The training record was checked (and warned about) once already.
            warnings.simplefilter("ignore", EstimatorInconsistentWarning)
            warnings.simplefilter("ignore", SaturationWarning)
            reported = kf.filter(train_sensors).field_variances
        start = DEFAULT_CONSISTENCY_WINDOW if reported.shape[1] > DEFAULT_CONSISTENCY_WINDOW else 0
        variance = np.mean(reported[:, start:], axis=1)
    sigma = np.sqrt(np.maximum(variance, 0.0))
    return Coverage(band=band, frequencies=read_only(freqs), training_power=read_only(power),
                    noise_power=noise_power, covered=read_only(covered),
                    mode_frequencies=read_only(mode_f[order]),
                    mode_observability=read_only(seen[order]), node_sigma=read_only(sigma),
                    n_sensors=int(len(sensors)))
