"""The one home of the filter Riccati equation: single and batched solvers, one acceptance rule.

Every steady-state Kalman quantity of the package (``steady_state_covariance``, the steady-state
:class:`~powerline_control.estimate.KalmanFilter`, the exact ``"kalman"`` criterion of sensor
selection and the simulation of ``sensor_count_study``) comes from here, so they agree.

The equation, for the *predicted* covariance ``P`` of ``x[k+1] = A x + w``, ``y = C x + v``::

    P = A (P^-1 + G)^-1 A^T + Q,        G = C^T R^-1 C   (the information of the sensors)

depends on the sensors only through the ``n x n`` information ``G``: with ``r`` model states and
``p`` outputs the work is ``O(r^3)`` per iteration plus ``O(p r^2)`` once to form ``G`` (the
information, or Woodbury, form), never ``O(p^3)``.

Solvers, in order:

1. structure-preserving doubling (Chu, Fan, Lin & Wang, 2004): quadratic convergence, about 20
   ``O(r^3)`` steps even for modes with ``|lambda| = 0.9999``, batched over many layouts;
2. SciPy's QZ (``scipy.linalg.solve_discrete_are``) on the information form, as the fallback.

One acceptance rule for every solution, whichever solver produced it: finite, a small relative
residual of the Riccati equation (:data:`RESIDUAL_RTOL`) *and* stabilising (the closed-loop
predictor ``A (I + P G)^-1`` has spectral radius below 1). An undetectable marginal mode makes
the doubling iterates grow while the relative residual can still look small; only the
stabilising test catches it.

Public names here (``solve_filter_dare``, ...) may be imported by any module of the package:
``_riccati`` is the one private module shared across module boundaries.

Test seam: ``_doubling``: tests make the doubling iteration fail to check that the failure is
reported, not returned as NaN (tests/test_observability.py).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .errors import EstimationError

__all__ = [
    "RESIDUAL_RTOL",
    "gramian_sum",
    "information_matrix",
    "solve_filter_dare",
    "steady_state_batch",
    "accept_solutions",
    "posterior_from_predicted",
    "filter_gain",
    "undetectable_modes",
    "describe_modes",
    "field_variances",
]

# Relative residual ||A P+ A^T + Q - P|| / max(||P||, ||Q||) a solution may have. Backward-stable
# solvers reach 1e-13..1e-10 on the package's models (identified 101-state DMD models included);
# 1e-7 leaves room for ill-conditioned identified models while refusing a non-solution.
RESIDUAL_RTOL = 1e-7
# A closed loop with spectral radius at or above this is not stabilising: the margin keeps an
# unseen mode exactly on the unit circle (radius 1 - 1e-15 in floating point) out.
_STABLE_RADIUS = 1.0 - 1e-10
_MAX_DOUBLINGS = 64
_DOUBLING_RTOL = 1e-13
# Iterates beyond this are divergence (an undetectable mode), long before floating overflow.
_BLOW_UP = 1e150


def information_matrix(c: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``C^T R^-1 C`` for a positive definite ``R`` (``(p,)`` variances or ``(p, p)``).

    Examples
    --------
    >>> information_matrix(np.array([[1.0, 0.0], [1.0, 1.0]]), np.array([1.0, 4.0]))
    array([[1.25, 0.25],
           [0.25, 0.25]])
    """
    if r.ndim == 1:
        rows = c / np.sqrt(r)[:, None]
    elif np.count_nonzero(r - np.diag(np.diag(r))) == 0:
        rows = c / np.sqrt(np.diag(r))[:, None]
    else:
        factor = np.linalg.cholesky((r + r.T) / 2)
        rows = sla.solve_triangular(factor, c, lower=True)
    g = rows.T @ rows
    return (g + g.T) / 2


def _doubling(a: np.ndarray, q: np.ndarray, info: np.ndarray) -> np.ndarray:
    """Doubling iterates for a batch ``info`` ``(b, n, n)``; NaN where they diverged."""
    b, n, _ = info.shape
    eye = np.eye(n)
    a_k = np.broadcast_to(a.T, (b, n, n)).copy()
    g_k = info.copy()
    h_k = np.broadcast_to(q, (b, n, n)).copy()
    active = np.ones(b, dtype=bool)
    for _ in range(_MAX_DOUBLINGS):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        A, G, H = a_k[idx], g_k[idx], h_k[idx]
        W = eye + G @ H
        with np.errstate(all="ignore"):
            try:
                S = np.linalg.solve(W, np.concatenate([A, G], axis=2))
            except np.linalg.LinAlgError:
                S = np.full((idx.size, n, 2 * n), np.nan)
            WA, WG = S[:, :, :n], S[:, :, n:]
            At = np.swapaxes(A, 1, 2)
            H_new = H + At @ H @ WA
            H_new = (H_new + np.swapaxes(H_new, 1, 2)) / 2
            G_new = G + A @ WG @ At
            G_new = (G_new + np.swapaxes(G_new, 1, 2)) / 2
            A_new = A @ WA
            change = np.abs(H_new - H).max(axis=(1, 2))
            size = np.abs(H_new).max(axis=(1, 2))
        finite = np.isfinite(size) & np.isfinite(change)
        a_k[idx], g_k[idx], h_k[idx] = A_new, G_new, H_new
        done = finite & (change <= _DOUBLING_RTOL * np.maximum(size, 1e-300))
        blown = ~finite | (size > _BLOW_UP)
        h_k[idx[blown]] = np.nan
        active[idx[done | blown]] = False
    return h_k


def accept_solutions(
    a: np.ndarray, q: np.ndarray, info: np.ndarray, prior: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The acceptance rule: ``(ok, posterior)`` for candidate solutions ``prior`` ``(b, n, n)``.

    ``ok[i]`` is True when ``prior[i]`` is finite, satisfies the Riccati equation to
    :data:`RESIDUAL_RTOL` and is stabilising; ``posterior`` is ``(P^-1 + G)^-1 = (I + P G)^-1 P``
    (NaN where not ok).

    Examples
    --------
    >>> a, q, g = np.array([[1.0]]), np.array([[1.0]]), np.array([[[1.0]]])
    >>> ok, post = accept_solutions(a, q, g, np.array([[[(1 + 5**0.5) / 2]]]))
    >>> bool(ok[0]), round(float(post[0, 0, 0]), 6)
    (True, 0.618034)
    """
    b, n, _ = prior.shape
    eye = np.eye(n)
    ok = np.all(np.isfinite(prior), axis=(1, 2))
    post = np.full_like(prior, np.nan)
    if not ok.any():
        return ok, post
    idx = np.flatnonzero(ok)
    p, g = prior[idx], info[idx]
    with np.errstate(all="ignore"):
        try:
            inv_factor = np.linalg.solve(eye + p @ g, np.broadcast_to(eye, p.shape))
        except np.linalg.LinAlgError:
            ok[idx] = False
            return ok, post
        pst = inv_factor @ p
        pst = (pst + np.swapaxes(pst, 1, 2)) / 2
        residual = a @ pst @ a.T + q - p
        scale = np.maximum(np.abs(p).max(axis=(1, 2)), np.abs(q).max())
        small = np.abs(residual).max(axis=(1, 2)) <= RESIDUAL_RTOL * np.maximum(scale, 1e-300)
        closed = a @ inv_factor  # predictor closed loop A (I - K C) = A (I + P G)^-1
        radius = np.abs(np.linalg.eigvals(closed)).max(axis=1)
    good = small & (radius < _STABLE_RADIUS) & np.all(np.isfinite(pst), axis=(1, 2))
    ok[idx] = good
    post[idx[good]] = pst[good]
    return ok, post


def steady_state_batch(
    a: np.ndarray, q: np.ndarray, info: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steady-state predicted and posterior covariances of many sensor layouts at once.

    Parameters
    ----------
    a : numpy.ndarray
        ``(n, n)`` transition matrix.
    q : numpy.ndarray
        ``(n, n)`` process-noise covariance.
    info : numpy.ndarray
        ``(b, n, n)`` information matrices ``G = C_S^T R_S^-1 C_S`` of the layouts.

    Returns
    -------
    prior, posterior : numpy.ndarray
        ``(b, n, n)`` each; NaN for layouts without an accepted solution (see
        :func:`accept_solutions`: typically a mode on or outside the unit circle the layout does
        not see).
    ok : numpy.ndarray
        ``(b,)`` bool, True where the solution was accepted.

    Examples
    --------
    >>> prior, post, ok = steady_state_batch(np.eye(1), np.eye(1), np.ones((1, 1, 1)))
    >>> round(float(post[0, 0, 0]), 6), bool(ok[0])   # random walk: (sqrt(5) - 1) / 2
    (0.618034, True)
    """
    prior = _doubling(a, q, info)
    ok, post = accept_solutions(a, q, info, prior)
    prior[~ok] = np.nan
    return prior, post, ok


def undetectable_modes(a: np.ndarray, c: np.ndarray, *, rtol: float = 1e-9) -> np.ndarray:
    """Eigenvalues on or outside the unit circle whose modes the outputs ``C`` do not see.

    The PBH eigenvector test: a mode with right eigenvector ``v`` is unseen when
    ``||C v|| <= rtol ||C|| ||v||``. These are the modes for which no stabilising Riccati
    solution exists and whose estimation error grows without bound when the noise excites them.

    Examples
    --------
    >>> undetectable_modes(np.diag([1.0, 0.5]), np.array([[0.0, 1.0]]))
    array([1.+0.j])
    """
    eigenvalues, vectors = np.linalg.eig(a)
    marginal = np.abs(eigenvalues) >= _STABLE_RADIUS
    if not marginal.any():
        return np.zeros(0, dtype=complex)
    seen = np.linalg.norm(c @ vectors[:, marginal], axis=0)
    scale = max(float(np.linalg.norm(c, 2)), 1e-300)
    unseen = seen <= rtol * scale * np.linalg.norm(vectors[:, marginal], axis=0)
    return eigenvalues[marginal][unseen].astype(complex)


def describe_modes(modes: np.ndarray) -> str:
    """Short text listing eigenvalues (at most six) for error messages.

    Examples
    --------
    >>> describe_modes(np.array([1.0 + 0.0j]))
    '[1+0j]'
    """
    shown = ", ".join(f"{complex(m):.6g}" for m in modes[:6])
    return f"[{shown}{', ...' if modes.size > 6 else ''}]"


def _qz_solution(a: np.ndarray, q: np.ndarray, info: np.ndarray) -> np.ndarray:
    """SciPy's QZ DARE on the information form (``G = L L^T`` with ``L`` at most ``n`` wide)."""
    lam, vec = np.linalg.eigh(info)
    keep = lam > 1e-14 * max(float(lam.max()), 1e-300)
    if not keep.any():
        raise np.linalg.LinAlgError("no information: the sensors see nothing")
    factor = vec[:, keep] * np.sqrt(lam[keep])
    return sla.solve_discrete_are(a.T, factor, q, np.eye(int(keep.sum())))


def solve_filter_dare(
    a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray
) -> np.ndarray:
    """Stabilising solution ``P`` (predicted covariance) of the filter Riccati equation.

    Doubling first, SciPy's QZ as the fallback; a solution is returned only if it passes the one
    acceptance rule (finite, small residual, stabilising closed loop).

    Parameters
    ----------
    a : numpy.ndarray
        ``(n, n)`` transition matrix.
    c : numpy.ndarray
        ``(p, n)`` output matrix of the sensors used.
    q : numpy.ndarray
        ``(n, n)`` process-noise covariance (symmetric positive semidefinite).
    r : numpy.ndarray
        Measurement-noise covariance of those sensors, ``(p,)`` variances or ``(p, p)``,
        positive definite.

    Returns
    -------
    numpy.ndarray
        Symmetric ``(n, n)`` predicted covariance ``P[k|k-1]``.

    Raises
    ------
    EstimationError
        If ``R`` is not positive definite, or no stabilising solution exists (the message names
        the modes on or outside the unit circle that the sensors cannot see, when there are).

    Examples
    --------
    >>> P = solve_filter_dare(np.eye(1), np.eye(1), np.eye(1), np.ones(1))
    >>> round(float(P[0, 0]), 6)   # random walk measured directly: (1 + sqrt(5)) / 2
    1.618034
    """
    a = np.asarray(a, dtype=float)
    c = np.asarray(c, dtype=float)
    q = np.asarray(q, dtype=float)
    r = np.asarray(r, dtype=float)
    try:
        info = information_matrix(c, r)
    except np.linalg.LinAlgError as exc:
        raise EstimationError(
            "The measurement-noise covariance R of the chosen sensors is not positive definite; "
            "the Riccati equation needs it. Give every sensor a positive noise variance."
        ) from exc
    if r.ndim == 1 and np.any(r <= 0):
        raise EstimationError(
            "The measurement-noise covariance R of the chosen sensors is not positive definite; "
            "the Riccati equation needs it. Give every sensor a positive noise variance."
        )
    q = (q + q.T) / 2
    prior, _, ok = steady_state_batch(a, q, info[None])
    if ok[0]:
        return prior[0]
    # Fallback: QZ, judged by the same rule.
    reason = "doubling did not converge to a stabilising solution"
    try:
        with np.errstate(all="ignore"):
            candidate = _qz_solution(a, q, info)
        candidate = (candidate + candidate.T) / 2
        ok, _ = accept_solutions(a, q, info[None], candidate[None])
        if ok[0]:
            return candidate
        reason += "; SciPy's QZ returned a solution that is not stabilising"
    except (np.linalg.LinAlgError, ValueError) as exc:
        reason += f"; SciPy's QZ failed too ({exc})"
    unseen = undetectable_modes(a, c)
    if unseen.size:
        raise EstimationError(
            "The Kalman Riccati equation has no stabilising solution for this sensor set: the "
            f"modes with eigenvalues {describe_modes(unseen)} lie on or outside the unit circle "
            "and are not detectable from the chosen outputs (their error would grow without "
            f"bound). Add a sensor that sees them or stabilise the model ({reason})."
        )
    raise EstimationError(
        "The Kalman Riccati equation has no stabilising solution for this sensor set (some mode "
        "on or outside the unit circle is barely detectable from the chosen outputs, or the "
        f"problem is too ill-conditioned): {reason}."
    )


def posterior_from_predicted(
    predicted: np.ndarray, c: np.ndarray, r: np.ndarray
) -> np.ndarray:
    """Posterior ``P - P C^T S^-1 C P`` (``p <= n``) or ``(I + P G)^-1 P`` (``p > n``).

    Both are the same matrix; the information form costs ``O(n^3 + p n^2)`` instead of
    ``O(p^3)`` when there are more outputs than states.

    Examples
    --------
    >>> post = posterior_from_predicted(np.array([[2.0]]), np.eye(1), np.ones(1))
    >>> round(float(post[0, 0]), 12)   # 2 * 1 / (2 + 1)
    0.666666666667
    """
    n, p = predicted.shape[0], c.shape[0]
    if p > n:
        info = information_matrix(c, r)
        post = np.linalg.solve(np.eye(n) + predicted @ info, predicted)
    else:
        rm = np.diag(r) if r.ndim == 1 else r
        pct = predicted @ c.T
        innovation = c @ pct + rm
        factor = sla.cho_factor((innovation + innovation.T) / 2)
        post = predicted - pct @ sla.cho_solve(factor, pct.T)
    return (post + post.T) / 2


def filter_gain(
    predicted: np.ndarray, c: np.ndarray, r: np.ndarray, posterior: np.ndarray | None = None
) -> np.ndarray:
    """Filter-form gain ``K = P C^T S^-1``, or ``P+ C^T R^-1`` (Woodbury) when ``p > n``.

    Examples
    --------
    >>> filter_gain(np.array([[2.0]]), np.eye(1), np.ones(1))
    array([[0.66666667]])
    """
    n, p = predicted.shape[0], c.shape[0]
    if p > n:
        post = posterior_from_predicted(predicted, c, r) if posterior is None else posterior
        if r.ndim == 1:
            return (post @ c.T) / r[None, :]
        return sla.cho_solve(sla.cho_factor((r + r.T) / 2), c @ post).T
    rm = np.diag(r) if r.ndim == 1 else r
    s = c @ predicted @ c.T + rm
    return sla.cho_solve(sla.cho_factor((s + s.T) / 2), c @ predicted).T


def field_variances(covariance: np.ndarray, field_map: np.ndarray | None) -> np.ndarray:
    """Diagonal of ``M P M^T`` without forming the full product (``diag(P)`` without a map).

    Examples
    --------
    >>> field_variances(np.diag([1.0, 4.0]), np.array([[1.0, 1.0]]))
    array([5.])
    """
    if field_map is None:
        return np.clip(np.diag(covariance).copy(), 0.0, None)
    return np.clip(np.sum((field_map @ covariance) * field_map, axis=1), 0.0, None)


def gramian_sum(a: np.ndarray, block: np.ndarray, horizon: int) -> np.ndarray:
    """``sum_{t<horizon} (A^T)^t W A^t`` by binary doubling: ``O(n^3 log N)``, not ``O(n^2 N)``.

    ``block`` is W, one ``(n, n)`` matrix or a batch ``(m, n, n)`` (one per sensor candidate).
    Uses ``W_2m = W_m + (A^m)^T W_m A^m``; overflow (an unstable model over a long horizon) is
    left for the caller to detect, as non-finite or huge entries, and to report in its own terms.
    """
    block = np.array(block, dtype=float)
    power = np.array(a, dtype=float)
    total = np.zeros_like(block)
    total_power = np.eye(power.shape[0])  # A^(length accumulated so far)
    remaining = horizon
    with np.errstate(all="ignore"):  # overflow is the caller's to check
        while remaining:
            if remaining & 1:
                # Append the block after what has been accumulated: W += (A^s)^T W_m A^s.
                total += total_power.T @ block @ total_power
                total_power = power @ total_power
            remaining >>= 1
            if remaining:
                block = block + power.T @ block @ power
                power = power @ power
    return total
