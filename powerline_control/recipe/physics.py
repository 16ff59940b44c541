"""The physics family of the recipe: the nominal span, calibrated from the record, as a model.

Given the nominal span (catalogue conductor, length, supports, stringing tension: what the field
engineer is told), the record's tension and bending stiffness come from
:func:`~powerline_control.identify.calibrate_span` and the model is the calibrated span's modes
near the record's spectral lines (:func:`~powerline_control.identify.span_model`). Like the DMD
alphas, its two settings (modes kept beside each line, process noise) are chosen by the
estimator's error at the unmeasured nodes on the held-out part of the record, with the model
calibrated on the training part alone; the recipe then keeps whichever family scores best
there (:func:`_choose`), by the one rule ``dmd._unmeasured_score``.

The calibration reads the record at up to :data:`_CALIBRATION_CHANNELS` moving nodes spread
evenly over the span (what a few field sensors give), in a band around the record's dominant
frequency; nothing of a simulation's truth enters.

Test seam: ``_scoring_layout``: checked on a standing wave whose vibration nodes the evenly
spread layout falls on (tests/test_recipe_physics.py).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np

from .._spectral import dominant_frequency, fit_phasors
from .._validation import read_only
from ..errors import CalibrationWarning, InputError
from ..fem import LineModel
from ..fem.mesh import parse_bc
from ..identify import OscillatorModel, calibrate_span, span_model
from ..identify.span_model import MESH_MARGIN, MESH_TOLERANCE
from ..line import Span
from .dmd import _MODEL_FAILURES, _calibrated_design, _held_out_error, _unmeasured_score
from .record import _Record
from .results import AlphaSweep, EstimatorDesign, ExcitationReport
from .sensing import _choose_sensors

#: Most channels of the record the calibration reads (evenly spread over the moving nodes): a
#: standing wave's wavelength is told by a handful of channels; more cost time, not accuracy.
_CALIBRATION_CHANNELS = 16
#: The calibration reads lines within this factor of the record's dominant frequency.
_CALIBRATION_BAND = 1.3
#: Settings tried on the held-out part: modes on each side of each line, and process noise per
#: step and mode in sensor-noise variances. The load is the lift in lock-in at the record's
#: dominant tone (``span_model``'s ``lock_in``): with each mode driven alone instead, more than
#: two modes a side let five sensors mistake one combination of modes for another (measured on
#: Oxlip 220 m and Condor 180 m: 13-29 % off at the unmeasured nodes with four a side; with the
#: lock-in load 1-6 %), and two a side miss the standing wave of a tone between modes.
_MODES_PER_SIDE = (2, 4, 6)
_PROCESS_NOISE = (1.0, 100.0)
#: A record is one tone (aeolian lock-in, a standing wave) when one sinusoid explains this share
#: of the power of its held-out part at the calibration channels.
_ONE_TONE_SHARE = 0.9
#: On a one-tone record the held-out part continues the training tone: it cannot show how a
#: model follows the tone as the wind moves it, and a data-driven model that learned the tone's
#: shape wins there (DMD 0.1-0.6 % on Oxlip 220 m and Condor 180 m in lock-in) while it fails at
#: the same wind 1 % faster (5-26 %: the standing wave's wavelength moved; the physics model:
#: 0.8-6.3 % held out, 1-6.7 % on the faster wind, docs/validation/physics_candidate.md). The
#: physics model is then chosen unless its held-out error exceeds this: a model that misses a
#: tenth of the tone it was calibrated on holds the wrong span (a wrong mode, a nominal far
#: off), and the data-driven one is kept.
_ONE_TONE_ACCEPT = 0.10
#: A provisional layout whose sensors read under this share of the moving nodes' mean square is
#: blind to the record's field (``_scoring_layout``).
_BLIND_LAYOUT = 0.1


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class _Channels:
    """Channels of the training record as :func:`calibrate_span` reads a Record."""

    t: np.ndarray           # (n_t,) sample times, s
    positions: np.ndarray   # (p,) node positions, m
    values: np.ndarray      # (p, n_t) displacements, m
    dt: float               # sample interval, s


def _check_nominal(nominal: object, bc: object) -> tuple[Span, tuple] | None:
    """(span, supports) of the ``nominal`` parameter (a Span with ``bc``, or a LineModel's),
    or None when no nominal is given."""
    if nominal is None:
        if bc is not None:
            raise InputError(f"The 'bc' parameter is the nominal span's supports; it needs "
                             f"'nominal'. Got bc={bc!r} with nominal=None.")
        return None
    if isinstance(nominal, LineModel):
        if bc is not None:
            raise InputError("The 'bc' parameter is for a nominal Span; a nominal LineModel has "
                             f"its supports {nominal.bc}. Got bc={bc!r}.")
        return nominal.span, tuple(nominal.bc)
    if isinstance(nominal, Span):
        return nominal, tuple(parse_bc("pinned" if bc is None else bc))
    raise InputError("The 'nominal' parameter must be None, a Span (with bc=) or a LineModel: "
                     f"the span as told, whose tension the record calibrates. Got "
                     f"{type(nominal).__name__}.")


def _channels(rec: _Record, span: Span) -> np.ndarray:
    """Up to :data:`_CALIBRATION_CHANNELS` moving nodes inside the span, evenly spread."""
    count = min(_CALIBRATION_CHANNELS, rec.candidates.size)
    channels = np.unique(rec.candidates[np.linspace(0, rec.candidates.size - 1, count).round()
                                        .astype(int)])
    x = rec.positions[channels]
    return channels[(x > 0) & (x < span.length)]


def _one_tone_share(rec: _Record, span: Span) -> float:
    """Share of the held-out part's power at the calibration channels that its dominant
    sinusoid explains (1: a pure standing wave)."""
    held = rec.X[_channels(rec, span), rec.n_fit:]
    held = held - held.mean(axis=1, keepdims=True)
    power = float(np.sum(held**2))
    if not power > 0:
        return 0.0
    f = dominant_frequency(held, rec.dt)
    phasors = fit_phasors(held, rec.dt * np.arange(held.shape[1]), f)
    return float(0.5 * held.shape[1] * np.sum(np.abs(phasors) ** 2) / power)


def _calibrate(rec: _Record, n: int, span: Span, bc: tuple):
    """(:func:`calibrate_span` of the record's first ``n`` samples at evenly spread moving
    nodes, on a nominal mesh accurate around the record's dominant frequency; that frequency,
    Hz)."""
    channels = _channels(rec, span)
    x = rec.positions[channels]
    values = rec.X[channels, :n]
    peak = dominant_frequency(values, rec.dt)
    top = min(_CALIBRATION_BAND * peak, 0.4 / rec.dt)
    nominal = LineModel(span, None, bc=bc, max_frequency=MESH_MARGIN * top,
                        frequency_tolerance=MESH_TOLERANCE)
    record = _Channels(t=rec.dt * np.arange(n), positions=x, values=values, dt=rec.dt)
    with warnings.catch_warnings():
        # One line only, or an ambiguous posterior: the held-out score judges the model.
        warnings.simplefilter("ignore", CalibrationWarning)
        return calibrate_span(record, nominal, band=(peak / _CALIBRATION_BAND, top)), peak


def _models(rec: _Record, calibration, n_pairs: int, tone: float):
    """The physics models of every setting: ((modes per side, process noise), model)."""
    for side in _MODES_PER_SIDE:
        for q in _PROCESS_NOISE:
            yield (side, q), span_model(calibration, rec.positions, rec.dt, n_pairs=n_pairs,
                                        process_noise=q * rec.noise**2, modes_per_side=side,
                                        lock_in=tone)


def _score(rec: _Record, model, part: slice | None = None) -> float:
    """The model's estimator scored on ``part`` of the record (default: the held-out part)."""
    part = slice(rec.n_fit, None) if part is None else part
    return _unmeasured_score(model, rec.X[:, part], rec.provisional, rec.candidates,
                             rec.noise, rec.data_noise, rec.q_floor, rec.delays)


def _physics_candidate(rec: _Record, span: Span, bc: tuple):
    """(held-out error, settings, the training part's calibration) of the best physics model,
    or None when the training part cannot be calibrated."""
    try:
        partial_cal, tone = _calibrate(rec, rec.n_fit, span, bc)
    except _MODEL_FAILURES:
        return None
    best = (math.inf, None)
    for settings, model in _models(rec, partial_cal, rec.n_fit - 1, tone):
        error = _score(rec, model)
        if error < best[0]:
            best = (error, settings)
    return best[0], best[1], partial_cal, tone


def _scoring_layout(X: np.ndarray, layout: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """The provisional ``layout`` (rows of the record ``X``), or, where its sensors read under
    :data:`_BLIND_LAYOUT` of the moving nodes' (``candidates``, ascending) mean square (on the
    standing wave's vibration nodes: five nodes evenly spread over a pinned span lie near
    multiples of L / 6, the nodes of every sixth mode), each sensor moved to the node of largest
    mean square within a quarter of the layout's spacing."""
    power = np.mean(X**2, axis=1)
    if np.mean(power[layout]) >= _BLIND_LAYOUT * np.mean(power[candidates]):
        return layout
    reach = max(1, candidates.size // (4 * (layout.size + 1)))
    where = np.searchsorted(candidates, layout)
    moved = [int(candidates[lo + np.argmax(power[candidates[lo:hi]])])
             for lo, hi in ((max(0, w - reach), min(candidates.size, w + reach + 1))
                            for w in where)]
    return np.unique(moved)


def _held_out_of(design: EstimatorDesign, rec: _Record, layout: np.ndarray) -> float:
    """The held-out score of another family's design on ``layout``: the DMD sweep's best (its
    alpha refitted on the training part when ``layout`` is not the sweep's), or the oscillator
    model's on the same part (its lines came from the whole record, which favours it)."""
    if isinstance(design.model, OscillatorModel):
        return _score(rec, design.model)
    if not np.array_equal(layout, design.alpha_sweep.layout):
        return _held_out_error(rec.coords[:, :rec.n_fit], rec.X[:, rec.n_fit:], rec.spatial,
                               rec.dt, design.model.alpha_relative, rec.delays,
                               int(design.model.rank), layout, rec.candidates, rec.noise,
                               rec.data_noise, rec.q_floor)
    errors = np.asarray(design.alpha_sweep.held_out_error, dtype=float)
    return float(np.nanmin(np.where(np.isfinite(errors), errors, np.nan))) \
        if np.isfinite(errors).any() else math.inf


def _choose(design: EstimatorDesign | None, rec: _Record, span: Span, bc: tuple
            ) -> EstimatorDesign:
    """The physics design when it beats ``design`` on the held-out part (or ``design`` is None:
    method="physics"), else ``design``."""
    if rec.positions is None:
        raise InputError("The 'nominal' parameter needs the node positions (m) of the record: "
                         "give 'positions', or Snapshots (with x).")
    if rec.given is None:
        rec = replace(rec, provisional=_scoring_layout(rec.X, rec.provisional, rec.candidates))
    other = math.inf if design is None else _held_out_of(design, rec, rec.provisional)
    found = _physics_candidate(rec, span, bc)
    if found is not None and _one_tone_share(rec, span) >= _ONE_TONE_SHARE:
        other = max(other, _ONE_TONE_ACCEPT)   # see _ONE_TONE_ACCEPT
    if found is None or found[1] is None or (design is not None and not found[0] < other):
        if design is None:
            raise InputError(
                "The 'method' parameter is 'physics' but the record does not calibrate the "
                f"nominal span ({span.length:g} m, {span.tension:.6g} N): no spectral line it "
                "explains. Use method='auto'.")
        return design
    error, (side, q), partial_cal, partial_tone = found
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CalibrationWarning)
        try:
            calibration, tone = _calibrate(rec, rec.n_samples, span, bc)
        except _MODEL_FAILURES:
            calibration, tone = partial_cal, partial_tone
    model = span_model(calibration, rec.positions, rec.dt, n_pairs=rec.n_samples - 1,
                       process_noise=q * rec.noise**2, modes_per_side=side, lock_in=tone)
    partial = span_model(partial_cal, rec.positions, rec.dt, n_pairs=rec.n_fit - 1,
                         process_noise=q * rec.noise**2, modes_per_side=side,
                         lock_in=partial_tone)
    chosen, selection = _choose_sensors(model, rec.given, rec.candidates, rec.n_sensors,
                                        rec.criterion, rec.noise, rec.positions, rec.forbidden,
                                        rec.seed)
    base = rec.excitation if design is None else design.excitation
    excitation = ExcitationReport(narrowband=base.narrowband, occupancy=base.occupancy,
                                  frequencies=read_only(np.array(calibration.line_frequencies)),
                                  residual_ratio=base.residual_ratio, method="physics")
    sweep = AlphaSweep(alphas=read_only(np.zeros(0)),
                       held_out_error=read_only(np.array([error])),
                       layout=read_only(rec.provisional), n_fit=rec.n_fit)
    return _calibrated_design(rec, model, partial, chosen, selection, sweep,
                              spatial_rank=model.n_lines, n_stabilised=0, excitation=excitation)
