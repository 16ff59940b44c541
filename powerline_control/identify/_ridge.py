"""The ridge solve of every DMD fit, by one of three named routes, and its residual covariance.

``coef = Y R^T (R R^T + alpha I)^{-1}`` is solved by :func:`_ridge`, which picks the route the
way scikit-learn's ``Ridge(solver="auto")`` picks a solver: :func:`_solve_cholesky` (normal
equations, when a Gram matrix is at hand and alpha keeps its round-off below ~1e-10),
otherwise the SVD of the regressor, :func:`_solve_svd` for alpha > 0 and :func:`_solve_pinv`
(the pseudo-inverse with the numerical-rank cut, the paper's eq. 11) for alpha = 0.  The
Cholesky route also gives the one-step residual covariance from Gram matrices, without another
pass over the data (:func:`_residual_covariance_from_gram`); :func:`_covariance` is the
residual pass used otherwise.

Test seam: ``_residual_covariance_from_gram`` and ``_SCATTER_BLOCK``: tests check that the Cholesky
route takes the Gram shortcut and that the result does not depend on the block size
(tests/test_identify.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.linalg.blas import dsyr as _syr
from scipy.linalg.lapack import dpotrf as _potrf
from scipy.linalg.lapack import dpotrs as _potrs

from .._validation import read_only

#: The Gram/Cholesky route loses about eps * (1 + s_max**2 / alpha) relative accuracy; it is used
#: only when that is below ~1e-10, i.e. alpha >= 1e-6 * trace(G) >= 1e-6 * s_max**2.
_GRAM_ALPHA_FRACTION = 1e-6


@dataclass(frozen=True, eq=False)
class _Solution:
    """One ridge solve: the coefficients and what the route leaves for the rest of the fit."""

    coef: np.ndarray  # (n_out, n_regressors)
    kept_ratio: float | None  # alpha = 0: smallest kept singular value / largest
    scatter: _GramScatter | None  # Cholesky route: the Gram parts of the residual covariance
    svd: tuple[np.ndarray, np.ndarray, np.ndarray] | None  # SVD routes: (target @ V, s, U)


def _ridge(
    target: np.ndarray,
    regressor: np.ndarray,
    alpha: float,
    *,
    gram: np.ndarray | None = None,
    svd: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> _Solution:
    """``coef = target R^T (R R^T + alpha I)^{-1}`` by the accurate, cheapest route.

    ``gram`` is ``R R^T`` when already computed (the Cholesky route overwrites it); ``svd`` a
    precomputed ``(target @ V, s, U)`` of ``R = U diag(s) V^T`` (for alpha curves), which
    selects the SVD routes.
    """
    if svd is None:
        cholesky = _solve_cholesky(target, regressor, alpha, gram)
        if cholesky is not None:
            return cholesky
        svd = _ridge_svd(target, regressor)
    if alpha > 0:
        return _solve_svd(svd, alpha)
    return _solve_pinv(svd, regressor.shape)


def _numerical_rank(s: np.ndarray, shape: tuple[int, int]) -> int:
    if s.size == 0 or s[0] == 0:
        return 0
    tol = s[0] * max(shape) * np.finfo(float).eps
    return int(np.count_nonzero(s > tol))


def _solve_cholesky(
    target: np.ndarray, regressor: np.ndarray, alpha: float, gram: np.ndarray | None
) -> _Solution | None:
    """Cholesky route of :func:`_ridge`, or None when it would not be accurate.

    Solving ``(G + alpha I) coef^T = C`` (``G = R R^T``, ``C = R Y^T``) loses about
    ``eps (1 + s_max^2 / alpha)``; it is taken only when that is below ~1e-10 (and when
    ``R R^T`` is the smaller Gram matrix).  ``gram`` (``R R^T``, C-ordered) is overwritten by
    the factor.  Everything is laid out for LAPACK without transposed copies: a symmetric
    C-ordered matrix is itself in Fortran order, and ``Y R^T`` (C-ordered) is ``C`` in Fortran
    order, so ``potrs`` returns ``coef^T`` in Fortran order, i.e. ``coef`` in C order.
    """
    n_reg, n_pairs = regressor.shape
    if gram is None or alpha <= 0 or n_reg > n_pairs:
        return None
    diagonal = gram.diagonal().copy()
    if alpha < _GRAM_ALPHA_FRACTION * diagonal.sum():
        return None
    gram = np.ascontiguousarray(gram)  # (it is: fit_dmd's syrk) the flat view below needs it
    cross_t = target @ regressor.T  # C^T, C-ordered: C in Fortran order
    flat_diagonal = gram.reshape(-1)[:: n_reg + 1]  # a view (gram is C-contiguous)
    flat_diagonal += alpha
    # Fortran 'lower' is C-order 'upper': the factor fills gram's upper triangle and leaves
    # G in its strict lower one (read back by _GramScatter).
    factor, info = _potrf(gram.T, lower=1, overwrite_a=1, clean=0)
    if info != 0:  # not positive definite in floating point (cannot happen for alpha > 0
        return None  # above the threshold, but the SVD route is the safe answer)
    coef_t, info = _potrs(factor, cross_t.T, lower=1, overwrite_b=0)
    if info != 0:  # pragma: no cover - potrs fails only on bad arguments
        return None
    k = target.shape[0]
    scatter = _GramScatter(gram, diagonal, cross_t, regressor[:k, 0].copy(), target[:, -1].copy())
    return _Solution(coef_t.T, None, scatter, None)



@dataclass(frozen=True, eq=False)
class _GramScatter:
    """What :func:`_residual_covariance_from_gram` needs to form ``E E^T`` without a data pass.

    ``gram`` holds ``G = R R^T`` in its strict lower triangle (the Cholesky factor of
    ``G + alpha I`` is in the upper one) and ``diagonal`` its diagonal.  The target is the
    regressor's state rows shifted by one sample, so ``Y Y^T = G[:k, :k] - r_0 r_0^T +
    y_N y_N^T``.  ``cross_t`` is ``C^T = Y R^T`` (overwritten by the scatter computation).
    """

    gram: np.ndarray
    diagonal: np.ndarray
    cross_t: np.ndarray
    first: np.ndarray
    last: np.ndarray

    def target_trace(self) -> float:
        k = self.first.size
        return float(self.diagonal[:k].sum() - self.first @ self.first + self.last @ self.last)


#: Block rows of the lower-triangle product in _residual_covariance_from_gram: the blocks above
#: the diagonal cost (1 + block / k) / 2 of the full product.
_SCATTER_BLOCK = 256


def _residual_covariance_from_gram(
    coef: np.ndarray, alpha: float, parts: _GramScatter, n_states: int, n_pairs: int
) -> np.ndarray | None:
    """``E E^T / n_pairs`` (``E = Y - coef R``) from Gram matrices, or None when cancellation bites.

    With the normal equations ``coef (G + alpha I) = C^T``,
    ``E E^T = Y Y^T - 2 coef C + coef G coef^T = Y Y^T - coef D`` with
    ``D = C + alpha coef^T`` (``coef G coef^T = coef C - alpha coef coef^T``).  ``coef D`` is
    symmetric, so only its lower triangle is formed, by block rows: about ``k^3`` flops
    (half a product) and no pass over the data.  The difference of large terms is accurate to
    about ``eps ||Y||^2``, so the result is used only when the residual is at least 1e-8 of the
    data (checked on the trace, in O(k^2), before the product is formed).  Returns the
    symmetric ``(n_states, n_states)`` covariance (zero outside the leading ``k x k`` block).
    """
    k = coef.shape[0]
    d_t = parts.cross_t
    d_t += alpha * coef  # D^T = C^T + alpha coef, in place
    total = parts.target_trace()
    trace = total - _dot(coef, d_t)  # trace(coef D) = sum(coef * D^T)
    if not trace >= 1e-8 * total:
        return None
    scatter = np.zeros((k, k))  # contiguous: BLAS updates it in place
    for start in range(0, k, _SCATTER_BLOCK):
        stop = min(start + _SCATTER_BLOCK, k)
        np.matmul(coef[start:stop], d_t[:stop].T, out=scatter[start:stop, :stop])
    gram = parts.gram
    # G's diagonal back over the factor's (no longer needed): gram's lower triangle is G's
    gram.reshape(-1)[:: gram.shape[0] + 1] = parts.diagonal
    np.subtract(gram[:k, :k], scatter, out=scatter)  # lower triangle: G - coef D
    # rank-one corrections of Y Y^T, on the lower triangle only (Fortran 'upper' of the
    # transposed view, updated in place; the returned array is used in case BLAS copied)
    updated = _syr(-1.0, parts.first, lower=0, a=scatter.T, overwrite_a=1)
    scatter = _syr(1.0, parts.last, lower=0, a=updated, overwrite_a=1).T
    _mirror_lower(scatter)
    scatter *= 1.0 / n_pairs
    if n_states == k:
        return read_only(scatter)
    Q = np.zeros((n_states, n_states))
    Q[:k, :k] = scatter
    return read_only(Q)


def _mirror_lower(M: np.ndarray) -> None:
    """Copy the lower triangle of the square ``M`` onto its upper one, in place, by blocks."""
    k = M.shape[0]
    for start in range(0, k, _SCATTER_BLOCK):
        stop = min(start + _SCATTER_BLOCK, k)
        M[:start, start:stop] = M[start:stop, :start].T
        block = M[start:stop, start:stop]
        # only upper entries are written, from lower ones, so the overlap is harmless
        np.copyto(block, block.T, where=np.tri(stop - start, k=-1, dtype=bool).T)


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """``sum(a * b)`` of two arrays of the same shape (no temporaries when C-contiguous)."""
    return float(np.vdot(a, b))



def _solve_svd(svd: tuple[np.ndarray, np.ndarray, np.ndarray], alpha: float) -> _Solution:
    """SVD route of :func:`_ridge` for alpha > 0: each singular value ``s`` becomes
    ``s / (s^2 + alpha)``."""
    target_V, s, U = svd
    keep = s > 0
    gain = s[keep] / (s[keep] ** 2 + alpha)
    coef = (target_V[:, keep] * gain) @ U[:, keep].T
    return _Solution(coef, None, None, svd)


def _solve_pinv(
    svd: tuple[np.ndarray, np.ndarray, np.ndarray], shape: tuple[int, int]
) -> _Solution:
    """SVD route of :func:`_ridge` for alpha = 0: the pseudo-inverse of the regressor (of
    ``shape``) above its numerical rank; ``kept_ratio`` is the smallest kept singular value as a
    fraction of the largest."""
    target_V, s, U = svd
    keep = np.zeros(s.shape, dtype=bool)
    keep[: _numerical_rank(s, shape)] = True
    gain = 1.0 / s[keep]
    ratio = float(s[keep][-1] / s[0]) if keep.any() else None
    coef = (target_V[:, keep] * gain) @ U[:, keep].T
    return _Solution(coef, ratio, None, svd)


def _ridge_svd(
    target: np.ndarray, regressor: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    U, s, Vt = sla.svd(regressor, full_matrices=False, lapack_driver="gesdd")
    return target @ Vt.T, s, U



def _covariance(scatter: np.ndarray, n_states: int, n_pairs: int) -> np.ndarray:
    """``scatter / n_pairs`` in the leading block of a symmetric (n_states, n_states) matrix."""
    Q = np.zeros((n_states, n_states))
    k = scatter.shape[0]
    Q[:k, :k] = scatter / n_pairs
    return read_only((Q + Q.T) / 2)

