"""The modal family of the recipe, for narrowband records: one oscillator per spectral line.

The record's lines are found in its POD directions completed with the smoothest fields over the
moving nodes; each independent line becomes one undamped oscillator with process noise, and the
smooth directions the lines leave out become white states, so that a new load is still tracked.

Test seam: ``_smooth_basis``, ``_extract_lines`` and ``_modal_model``: checked against closed forms
(the discrete sine basis, lines at their frequencies within the Cramer-Rao bound) and against a
model built by hand (tests/test_recipe.py, tests/test_oscillator_model.py).
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

from .._spectral import extract_lines, line_power
from .._validation import (
    read_only,
)
from ..errors import (
    ExcitationWarning,
    IdentificationError,
)
from ..identify import OscillatorModel
from .coverage import build_coverage
from .defaults import _MAX_LINES, _NARROWBAND_RESIDUAL, _STABLE_RADIUS, _UNSEEN_COUNT, _UNSEEN_NOISE
from .record import _Record
from .results import AlphaSweep, EstimatorDesign, ExcitationReport
from .sensing import _choose_sensors, _steady_filter

# tests/test_recipe.py reaches the line extraction under its recipe-private name.
_extract_lines = extract_lines


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
                 unseen_noise: float = 0.0) -> OscillatorModel:
    """One undamped oscillator per line (:class:`~powerline_control.identify.OscillatorModel`).

    Each line's amplitude obeys ``a_{k+1} = 2 rho cos(omega dt) a_k - rho^2 a_{k-1}`` with the
    recipe's radius (rho = 1 - 1e-6). Process noise ``process_noise`` (m^2 per step) enters every
    current coordinate alike: the unknown load of a new run, which the filter then tracks from
    the sensors.
    """
    return OscillatorModel.from_lines(frequencies, shapes, dt, n_pairs=n_pairs,
                                      process_noise=process_noise, unseen=unseen,
                                      unseen_noise=unseen_noise, radius=_STABLE_RADIUS)


def _unseen_directions(fields: np.ndarray, smooth: np.ndarray) -> np.ndarray:
    """Up to ``_UNSEEN_COUNT`` smooth directions that the line shapes leave out (orthonormal)."""
    q, _ = np.linalg.qr(fields)
    rest = smooth - q @ (q.T @ smooth)
    basis, upper = sla.qr(rest, mode="economic")
    new = np.abs(np.diag(upper)) > 0.3     # mostly outside the lines' span
    # A column of ``rest`` that the lines' span nearly held leaves QR an arbitrary direction,
    # and the later columns lean on it: project the lines' span out of the kept ones once more.
    kept = basis[:, new][:, :_UNSEEN_COUNT]
    return np.linalg.qr(kept - q @ (q.T @ kept))[0]


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


def _modal_design(rec: _Record) -> EstimatorDesign | None:
    """The modal design of a narrowband record, or None when its lines do not explain it.

    One oscillator per spectral line (the DMD model of such a record knows its forced mode and
    learns nothing of the modes a new load excites). None when the record holds no line, or
    (``method="auto"``) when removing its lines leaves more than noise: the DMD family then runs.
    """
    noise, dt, k, n_samples = rec.noise, rec.dt, rec.k, rec.n_samples
    freqs, shapes, residual = extract_lines(rec.line_coords, dt, min(2 * k, _MAX_LINES))
    ratio = float(np.mean(residual**2)) / noise**2
    if rec.method == "modal" and not freqs.size:
        raise IdentificationError(
            "The 'method' parameter is 'modal' but the record holds no spectral line above "
            f"its noise (std {noise:.3g} m): there is no oscillator to build. Use "
            "method='dmd' or 'auto'."
        )
    if not (freqs.size and (rec.method == "modal" or ratio < _NARROWBAND_RESIDUAL)):
        return None
    power = np.array([line_power(rec.line_coords, f, dt) for f in freqs])
    freqs, fields = _independent_lines(freqs, shapes, rec.line_basis, power)
    excitation = ExcitationReport(narrowband=ratio < _NARROWBAND_RESIDUAL,
                                  occupancy=rec.excitation.occupancy,
                                  frequencies=read_only(freqs),
                                  residual_ratio=ratio, method="modal")
    process = rec.process_noise * noise**2
    lines_only = _modal_model(freqs, fields, dt, n_samples - 2, process)
    if excitation.narrowband:
        # stacklevel 3: the caller of design_estimator, which called this builder
        warnings.warn(excitation.message, ExcitationWarning, stacklevel=3)
    # Sensors for what the record showed (the white unseen states below would pull them
    # toward fitting directions with no dynamics).
    chosen, selection = _choose_sensors(lines_only, rec.given, rec.candidates, rec.n_sensors,
                                        rec.criterion, noise, rec.positions, rec.forbidden,
                                        rec.seed)
    unseen = _unseen_directions(fields, _smooth_basis(rec.node_x, rec.moving,
                                                      fields.shape[1] + _UNSEEN_COUNT))
    model = _modal_model(freqs, fields, dt, n_samples - 2, process,
                         unseen, _UNSEEN_NOISE * noise**2)
    kf = _steady_filter(model, chosen, noise, rec.q_floor, warn=rec.warn_inconsistent,
                        adapt_horizon=rec.adapt_horizon)
    return EstimatorDesign(
        model=model, sensors=read_only(chosen),
        filter=kf,
        coverage=build_coverage(rec.X[chosen], dt, rec.data_noise, model, kf, chosen),
        noise_std=float(noise),
        noise_source=rec.source,
        alpha_sweep=AlphaSweep(alphas=read_only(np.zeros(0)),
                               held_out_error=read_only(np.zeros(0)),
                               layout=read_only(rec.provisional), n_fit=0),
        spatial_rank=rec.line_basis.shape[1], sensor_selection=selection,
        n_train=n_samples, n_stabilised=0, q_floor=rec.q_floor, excitation=excitation)
