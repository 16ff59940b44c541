"""The training record as the recipe reads it: the snapshot matrix, its noise and its POD.

The snapshot matrix and sample time from Snapshots or an array, the check of a given sensor
noise, the noise floor of the singular values (Gavish-Donoho, with the Marchenko-Pastur median)
and the leading spatial POD modes through the node-by-node Gram matrix.

Test seam: ``_marchenko_pastur_median`` and ``_noise_floor``: checked against quadrature of the
Marchenko-Pastur density and against white noise of known std (tests/test_recipe.py);
``_other_records`` and ``_snapshot_matrix``: the one rule for a record's ``noise_std`` of 0
(unknown, estimated) against a simulated noise of known std
(tests/test_estimator_calibration.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .._validation import (
    check_real,
    check_snapshot_matrix,
)
from ..errors import (
    InputError,
)
from .defaults import _NOISE_STD_MAX, _NOISE_TO_RMS_MAX


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
    """(X, dt, noise_std or nan, positions or None) from Snapshots or an array. A Snapshots'
    ``noise_std`` of 0 (or NaN) reads as unknown (nan): the one rule for every record's own
    noise std (also :func:`_other_records`); only a ``noise_std`` parameter of 0 means
    noise-free."""
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


def _record_noise_std(X: np.ndarray) -> float:
    """The sensor noise std of a record of every node ``(n_nodes, n_samples)``, from the noise
    floor of its singular values (:func:`_noise_floor`), as the recipe estimates a training
    record's when none is given."""
    _, s = _spatial_basis(X, 1)
    return _noise_floor(s, X.shape)[0]


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


def _other_records(records, name: str, positions, n_nodes: int, dt: float, *, noise_std=None,
                   noise_name: str | None = None) -> tuple[list[np.ndarray], list[float]]:
    """(displacement, noise std) of each record of every node under other load histories passed
    as the parameter ``name`` (``[], []`` for None), checked against the main record's nodes
    (their positions when both records carry them) and sample time. The noise std is
    ``noise_std`` (the parameter ``noise_name``: one for all or one per record) when given (0
    then means noise-free), else each record's own positive ``noise_std``, else estimated from
    its singular values: a record's own ``noise_std`` of 0 (or NaN) means unknown, as it does
    for the training record (:func:`_snapshot_matrix`)."""
    if records is None:
        if noise_std is not None:
            raise InputError(f"The '{noise_name}' parameter needs '{name}' records. Got "
                             f"{noise_std!r} with {name}=None.")
        return [], []
    given = records
    records = [records] if hasattr(records, "displacement") else records
    if isinstance(records, str) or not isinstance(records, Sequence) or not records:
        raise InputError(f"The '{name}' parameter must be None, a Snapshots record or a "
                         f"non-empty sequence of them. Got {type(given).__name__}.")
    levels = _noise_levels(noise_std, noise_name, len(records))
    out, sigmas = [], []
    for i, rec in enumerate(records):
        try:
            x, rec_dt = np.asarray(rec.displacement, dtype=float), float(rec.dt)
        except AttributeError:
            raise InputError(f"The '{name}' parameter's record {i} must be a Snapshots record "
                             f"(with .displacement and .dt). Got {type(rec).__name__}.") from None
        if x.ndim != 2 or x.shape[0] != n_nodes or x.shape[1] < 400 or not np.all(
                np.isfinite(x)) or not math.isclose(rec_dt, dt, rel_tol=1e-9):
            raise InputError(f"The '{name}' parameter's record {i} must hold the same {n_nodes} "
                             f"nodes at the same dt={dt:g} s, finite, over at least 400 samples. "
                             f"Got shape {x.shape}, dt={rec_dt:g} s.")
        _check_positions(name, i, getattr(rec, "x", None), positions)
        if levels is not None:
            sigmas.append(levels[i])
        else:
            own = float(getattr(rec, "noise_std", math.nan))
            sigmas.append(own if math.isfinite(own) and own > 0 else _record_noise_std(x))
        out.append(x)
    return out, sigmas


def _noise_levels(noise_std, name: str | None, n_records: int) -> list[float] | None:
    """``noise_std`` (the parameter ``name``) as one non-negative float per record (None: not
    given)."""
    if noise_std is None:
        return None
    values = np.atleast_1d(np.asarray(noise_std, dtype=object))
    if values.ndim != 1 or values.size not in (1, n_records):
        raise InputError(f"The '{name}' parameter must be one number or one per record "
                         f"({n_records}). Got {noise_std!r}.")
    levels = [check_real(name, v, low=0.0, low_inclusive=True) for v in values]
    return levels * n_records if len(levels) == 1 else levels


#: Node positions of another record must equal the main record's within this distance (m): the
#: same mesh written twice agrees to round-off, a different mesh differs by centimetres.
_POSITION_TOLERANCE = 1e-6


def _check_positions(name: str, i: int, x, reference) -> None:
    """Record ``i`` of the parameter ``name``: its node positions ``x`` against the main
    record's (when both are known)."""
    if x is None or reference is None:
        return
    x, reference = np.asarray(x, dtype=float), np.asarray(reference, dtype=float)
    if x.shape != reference.shape:
        raise InputError(f"The '{name}' parameter's record {i} must be a record of the "
                         f"{reference.size} node positions of 'snapshots'. Got {x.size} positions.")
    off = np.abs(x - reference)
    if not np.all(off <= _POSITION_TOLERANCE):
        j = int(np.argmax(off))
        raise InputError(f"The '{name}' parameter's record {i} must be a record of the node "
                         f"positions of 'snapshots' (within {_POSITION_TOLERANCE:g} m; the "
                         f"design's sensors are its nodes). Got node {j} at {x[j]:.9g} m "
                         f"against {reference[j]:.9g} m in 'snapshots'.")


@dataclass(frozen=True, eq=False)
class _Record:
    """The checked arguments and the record's shared reading, handed to either model family."""

    X: np.ndarray
    dt: float
    n_sensors: int
    delays: int
    rank: int
    criterion: str
    n_fit: int                 # samples of the training part ('train_fraction'; the rest held out)
    method: str
    process_noise: float
    warn_inconsistent: bool
    positions: np.ndarray | None
    forbidden: object
    seed: object
    #: spatial POD modes kept (``k`` columns) and the record's coordinates on them
    spatial: np.ndarray
    k: int
    coords: np.ndarray
    #: where the sensor noise came from, the filter's noise and what the data actually carry
    source: str
    noise: float
    data_noise: float
    q_floor: float
    #: the moving nodes, the given sensors (or None) and the layout of the alpha sweep
    candidates: np.ndarray
    given: np.ndarray | None
    provisional: np.ndarray
    #: node positions (or indices), the moving mask, and the basis the lines are sought in
    node_x: np.ndarray
    moving: np.ndarray
    line_basis: np.ndarray
    line_coords: np.ndarray
    excitation: object
    #: records of every node under other load histories, and their sensor noise std
    others: tuple = ()
    others_noise: tuple = ()
    #: the filter's adapt_horizon (None: Q as matched on the held-out part)
    adapt_horizon: int | None = None

    @property
    def n_samples(self) -> int:
        return self.X.shape[1]
