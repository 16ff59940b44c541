"""Fitting: :func:`fit_dmd`, from snapshots to a :class:`~powerline_control.identify.DMDModel`.

The snapshots are checked, delay-embedded (a Hankel stack), projected on a POD basis when a rank
is asked for, and posed as one regression ``target ~ coef @ regressor`` (:class:`_Problem`);
the ridge solve of that regression is :mod:`._ridge`'s, and :func:`_fit_problem` assembles the
frozen model from it (with the exact shift rows of a delay embedding).  The checks, the embedding
and the problem are shared with the alpha sweep and the online fit.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .._validation import (
    check_array,
    check_budget,
    check_choice,
    check_int,
    check_real,
    check_snapshot_matrix,
    checked_keywords,
    read_only,
)
from ..errors import IdentificationError, IllConditionedWarning, InputError
from ._ridge import _covariance, _numerical_rank, _residual_covariance_from_gram, _ridge
from .model import DMDModel

#: alpha = 0 and a kept singular value below this fraction of the largest: the fit inverts noise
#: or round-off, and fit_dmd says so.
_ILL_CONDITIONED_RATIO = 1e-8
#: The Gram-eigh + Rayleigh-Ritz route for a rank-r POD basis is used when s_r >= this * s_max
#: (subspace-iteration steps recover the accuracy the Gram matrix loses above that).
_GRAM_RANK_RATIO = 1e-6
#: Models with at most this many regressors (states + inputs) keep their Gram matrix for
#: DMDModel.damping_report (2 MB at the limit).
_KEEP_GRAM_LIMIT = 500


def _hankel(X: np.ndarray, delays: int) -> np.ndarray:
    """Columns ``[x_k; x_{k-1}; ...; x_{k-d+1}]`` for ``k = d-1 .. N-1``."""
    if delays == 1:
        return X  # no copy: callers only read it
    n_samples = X.shape[1]
    return np.vstack([X[:, delays - 1 - i : n_samples - i] for i in range(delays)])



def _largest_singular_value(M: np.ndarray, gram: np.ndarray | None = None) -> float:
    """Largest singular value, from the smaller Gram matrix (``gram`` if already computed).

    The top eigenvalue of a Gram matrix is accurate to relative round-off, and it costs far less
    than an SVD: a partial symmetric eigensolver for small Gram matrices, Lanczos for large
    ones.  Lanczos starts from a pseudo-random vector with a fixed seed (reproducible, and never
    orthogonal to the top eigenvector by a symmetry of the data, as a vector of ones is to an
    antisymmetric mode).
    """
    if M.size == 0:
        return 0.0
    if gram is None:
        gram = M @ M.T if M.shape[0] <= M.shape[1] else M.T @ M
    k = gram.shape[0]
    if k <= 500:
        try:
            top = sla.eigvalsh(gram, subset_by_index=[k - 1, k - 1])[0]
        except np.linalg.LinAlgError:  # syevr can fail on a tight cluster (G = c I)
            top = np.linalg.eigvalsh(gram)[-1]
    else:
        from scipy.sparse.linalg import eigsh

        start = np.random.default_rng(0).standard_normal(k)
        top = eigsh(gram, k=1, which="LA", v0=start, tol=0, return_eigenvectors=False)[0]
    return math.sqrt(max(float(top), 0.0))



@dataclass(frozen=True, eq=False)
class _Problem:
    """A prepared regression ``target ~ coef @ regressor`` in model coordinates."""

    target: np.ndarray  # (n_out, n_pairs): next states (first block only when `structured`)
    regressor: np.ndarray  # (n_states + n_inputs, n_pairs)
    n_states: int
    n_inputs: int
    n_nodes: int
    delays: int
    basis: np.ndarray | None
    s_max: float  # largest singular value of the state data, for relative alpha
    structured: bool  # True: delays without rank; only the first block row is fitted


def _prepare(
    X: np.ndarray, delays: int, rank: int | None, inputs: np.ndarray | None
) -> _Problem:
    """Embed the snapshots (and project them on the POD basis) into a regression problem."""
    n_nodes = X.shape[0]
    Z = _hankel(X, delays)
    Z0, Z1 = Z[:, :-1], Z[:, 1:]
    U0 = None if inputs is None else inputs[:, delays - 1 : delays - 1 + Z0.shape[1]]
    if rank is None:
        target = Z1[:n_nodes] if delays > 1 else Z1
        regressor = Z0 if U0 is None else np.vstack([Z0, U0])
        problem = _Problem(
            target, regressor, Z0.shape[0], 0 if U0 is None else U0.shape[0], n_nodes, delays,
            None, float("nan"), delays > 1,
        )
        return problem
    basis, s_max = _pod_basis(Z0, rank)
    A0, A1 = basis.T @ Z0, basis.T @ Z1
    regressor = A0 if U0 is None else np.vstack([A0, U0])
    problem = _Problem(
        A1, regressor, rank, 0 if U0 is None else U0.shape[0], n_nodes, delays, basis, s_max,
        False,
    )
    return problem



def _pod_basis(Z0: np.ndarray, rank: int) -> tuple[np.ndarray, float]:
    """Leading ``rank`` left singular vectors of ``Z0`` and its largest singular value.

    For ``rank`` well below the number of rows, a partial eigensolver of the Gram matrix gives an
    approximate subspace; two subspace-iteration steps on the data itself and a Rayleigh-Ritz SVD
    of the small projection ``Q^T Z0`` then give singular values and vectors without the
    squared condition number of the Gram matrix.  Otherwise (or when the spectrum falls below
    what that can resolve) a full thin SVD.
    """
    n_rows, n_cols = Z0.shape
    if n_rows <= n_cols and n_rows > 4 * rank:
        gram = Z0 @ Z0.T
        _, approx = sla.eigh(gram, subset_by_index=[n_rows - rank, n_rows - 1])
        Q = approx
        for _ in range(2):  # each step shrinks the error by (s_{r+1} / s_r)^2
            Q, _ = np.linalg.qr(Z0 @ (Z0.T @ Q))
        U_small, s, _ = sla.svd(Q.T @ Z0, full_matrices=False, lapack_driver="gesdd")
        if s[0] > 0 and s[-1] >= _GRAM_RANK_RATIO * s[0]:
            return _sign_fixed(Q @ U_small), float(s[0])
    U, s, _ = sla.svd(Z0, full_matrices=False, lapack_driver="gesdd")
    data_rank = _numerical_rank(s, Z0.shape)
    if rank > data_rank:
        raise InputError(
            f"The 'rank' parameter must not exceed the numerical rank of the data "
            f"({data_rank}). Got {rank} instead; pass rank <= {data_rank} or rank=None."
        )
    return _sign_fixed(U[:, :rank]), float(s[0])


def _sign_fixed(U: np.ndarray) -> np.ndarray:
    """Make the largest entry of each basis vector positive, so results are reproducible."""
    signs = np.sign(U[np.argmax(np.abs(U), axis=0), np.arange(U.shape[1])])
    return U * np.where(signs == 0, 1.0, signs)



def _assemble(problem: _Problem, coef: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Split the coefficients into A and B (adding the exact shift rows when structured)."""
    n, m = problem.n_states, problem.n_inputs
    top_A, top_B = coef[:, :n], coef[:, n:]
    if not problem.structured:
        return top_A, (top_B if m else None)
    A = np.zeros((n, n))
    A[: problem.n_nodes] = top_A
    block = problem.n_nodes * (problem.delays - 1)
    A[problem.n_nodes :, :block] = np.eye(block)
    B = None
    if m:
        B = np.zeros((n, m))
        B[: problem.n_nodes] = top_B
    return A, B



def _fit_problem(
    problem: _Problem,
    alpha: float,
    dt: float,
    *,
    warn: bool = True,
    svd: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    gram: np.ndarray | None = None,
) -> DMDModel:
    n_reg, n_pairs = problem.regressor.shape
    kept_gram = None
    if alpha > 0 and n_reg <= _KEEP_GRAM_LIMIT and gram is not None:
        kept_gram = gram.copy()  # the Cholesky route overwrites it
    solution = _ridge(problem.target, problem.regressor, alpha, gram=gram, svd=svd)
    coef, kept_ratio, covariance = solution.coef, solution.kept_ratio, None
    if solution.scatter is not None:
        covariance = _residual_covariance_from_gram(
            coef, alpha, solution.scatter, problem.n_states, n_pairs
        )
    elif alpha > 0 and n_reg <= _KEEP_GRAM_LIMIT and kept_gram is None:
        U, sv = solution.svd[2], solution.svd[1]
        kept_gram = (U * sv**2) @ U.T
    if (
        warn
        and alpha == 0
        and kept_ratio is not None
        and kept_ratio < _ILL_CONDITIONED_RATIO
    ):
        warnings.warn(
            f"Plain DMD (alpha=0) inverts singular values down to {kept_ratio:.2g} of the largest: "
            "the operator fits noise or round-off and is likely unstable. Use alpha > 0 "
            "(e.g. alpha_mode='relative', alpha=1e-8..1e-4; see select_alpha) or rank=...",
            IllConditionedWarning,
            stacklevel=3,
        )
    A, B = _assemble(problem, coef)
    if covariance is None:  # the residual pass: exact whatever the cancellation
        residual = problem.target - coef @ problem.regressor
        covariance = _covariance(residual @ residual.T, problem.n_states, n_pairs)
    n_states, n_nodes = problem.n_states, problem.n_nodes
    if problem.basis is None:
        field_map = np.eye(n_nodes, n_states)
    else:
        field_map = problem.basis[:n_nodes]
    s_max = problem.s_max
    return DMDModel(
        A=read_only(A),
        B=None if B is None else read_only(B),
        dt=dt,
        alpha=alpha,
        alpha_relative=alpha / s_max**2 if s_max**2 > 0 else 0.0,  # squares can underflow
        delays=problem.delays,
        rank=None if problem.basis is None else n_states,
        n_nodes=n_nodes,
        field_map=read_only(field_map),
        basis=None if problem.basis is None else read_only(problem.basis),
        residual_covariance=covariance,
        n_pairs=n_pairs,
        initial_state=read_only(problem.regressor[:n_states, 0].copy()),
        regressor_gram=None if kept_gram is None else read_only(kept_gram),
    )



def _check_snapshots(X: object) -> np.ndarray:
    # Refuses complex (the imaginary part would be lost), boolean (a mask) and transposed data.
    return check_snapshot_matrix("X", X)


def _check_inputs(inputs: object, n_samples: int) -> np.ndarray | None:
    if inputs is None:
        return None
    u = check_array("inputs", inputs, ndim=(1, 2))
    u = u[None, :] if u.ndim == 1 else u
    if u.shape[1] not in (n_samples, n_samples - 1):
        raise InputError(
            f"The 'inputs' parameter must have one column per snapshot ({n_samples}) or per "
            f"snapshot pair ({n_samples - 1}); u[:, k] drives x_k -> x_(k+1). Got shape "
            f"{u.shape} instead."
        )
    return u


#: Largest data magnitude: Gram matrices sum its squares, which beyond ~1e154 overflow to inf.
#: (Tiny data are accepted: their squares underflow to zero, which the fit copes with.)
_SCALE_LIMIT = 1e150


def _check_scale(name: str, values: np.ndarray) -> None:
    """Refuse data whose squares overflow (max/min: no temporary array)."""
    if values.size == 0:
        return
    peak = max(abs(float(values.max())), abs(float(values.min())))
    if peak > _SCALE_LIMIT:
        raise InputError(
            f"The {name!r} parameter has largest magnitude {peak:.3g}, above {_SCALE_LIMIT:g}: "
            "its squares overflow in floating point. Rescale it (e.g. to km or Mm)."
        )


def _check_common(
    X: object, dt: object, delays: object, rank: object, inputs: object
) -> tuple[np.ndarray, float, int, int | None, np.ndarray | None]:
    X = _check_snapshots(X)
    _check_scale("X", X)
    dt = check_real("dt", dt, low=0.0)
    n_samples = X.shape[1]
    delays = check_int("delays", delays, low=1, high=max(1, n_samples - 2))
    if rank is not None:
        rank = check_int("rank", rank, low=1, high=X.shape[0] * delays)
    rows = X.shape[0] * delays
    # The delay-embedded data (a copy, plus shifted views and a projection) and the Gram matrix
    # of its rows: estimated before anything is allocated.
    check_budget(
        "The DMD fit", nbytes=8.0 * (2 * rows * n_samples + rows**2),
        flops=2.0 * rows**2 * n_samples, parameter="delays", value=delays,
        fix=(f"use fewer delays or nodes ({X.shape[0]} nodes x {delays} delays = {rows} rows; "
             "design_estimator first projects the nodes on a few spatial POD modes), or a "
             "shorter record"),
    )
    u = _check_inputs(inputs, n_samples)
    if u is not None:
        _check_scale("inputs", u)
    return X, dt, delays, rank, u


def _refuse_all_zero(X: np.ndarray) -> None:
    if not np.any(X):
        raise IdentificationError(
            "The 'X' parameter is all zeros: there are no dynamics to identify."
        )


def _absolute_alpha(
    alpha: float, alpha_mode: str, problem: _Problem, gram: np.ndarray | None = None
) -> tuple[float, _Problem]:
    """Absolute alpha, computing the largest singular value of the state data when needed.

    ``gram`` is ``regressor @ regressor.T`` when already computed (its leading block is the
    Gram matrix of the state data).
    """
    if math.isnan(problem.s_max):
        n = problem.n_states
        block = None if gram is None else gram[:n, :n]
        s_max = _largest_singular_value(problem.regressor[:n], block)
        problem = dataclasses.replace(problem, s_max=s_max)
    if alpha_mode == "relative":
        return alpha * problem.s_max**2, problem
    return alpha, problem



@checked_keywords
def fit_dmd(
    X: np.ndarray,
    dt: float,
    alpha: float = 0.0,
    delays: int = 1,
    rank: int | None = None,
    inputs: np.ndarray | None = None,
    alpha_mode: str = "absolute",
) -> DMDModel:
    """Identify ``z_{k+1} = A z_k (+ B u_k)`` from snapshots by (Tikhonov-regularised) DMD.

    With ``alpha = 0`` this is exact DMD, ``A = X' X^+`` (the paper's eq. 11, minimum-norm least
    squares with the usual numerical-rank cut); with ``alpha > 0`` it is
    ``A = X' X^T (X X^T + alpha I)^{-1}`` (eq. 14).  Both are computed through an SVD or a
    Cholesky solve, never an explicit inverse.  Identically zero rows (pinned supports) are
    handled: they give zero rows and columns of ``A``.

    Parameters
    ----------
    X : array_like, shape (n_nodes, n_samples)
        Snapshots, one column per sample (the paper's and python-control's layout).
    dt : float
        Sample time in seconds (> 0).
    alpha : float, default 0.0
        Tikhonov parameter (>= 0), interpreted according to ``alpha_mode``.
    delays : int, default 1
        Number of stacked snapshots ``d``; the state is ``[x_k; ...; x_{k-d+1}]``.  A line is
        second order, so ``d >= 2`` is needed for an exact linear model of displacements.
    rank : int, optional
        Keep this many POD coordinates of the (delayed) data as the state; must not exceed the
        numerical rank of the data.  ``None``: no truncation.
    inputs : array_like, shape (n_inputs, n_samples) or (n_inputs, n_samples - 1), optional
        Known inputs (DMD with control); ``inputs[:, k]`` drives ``x_k -> x_{k+1}``.  A 1-d
        array is one input.
    alpha_mode : {"absolute", "relative"}, default "absolute"
        "absolute": ``alpha`` as in eq. 14 (not scale-invariant: data scaled by c needs
        ``alpha c**2``).  "relative": ``alpha`` times the largest squared singular value of the
        (delayed) state data, which transfers between spans and units.

    Returns
    -------
    DMDModel
        The identified model.

    Raises
    ------
    InputError
        Non-finite data, ``dt <= 0``, ``alpha < 0``, a bad ``delays``/``rank``, a rank above the
        data rank, inputs of the wrong length, or (with ``alpha = 0`` and no rank) fewer snapshot
        pairs than states.
    IdentificationError
        The data are all zero.

    Warns
    -----
    IllConditionedWarning
        ``alpha = 0`` and the fit inverts singular values below 1e-8 of the largest.

    Examples
    --------
    Two damped oscillation modes sampled at 100 Hz; two delays make the model exact:

    >>> import numpy as np, powerline_control as plc
    >>> t = np.arange(400) * 0.01
    >>> X = np.vstack([np.exp(-0.5 * t) * np.cos(2 * np.pi * 3 * t),
    ...                np.exp(-0.2 * t) * np.sin(2 * np.pi * 7 * t)])
    >>> dmd = plc.fit_dmd(X, dt=0.01, delays=2)
    >>> np.round(np.sort(dmd.damped_frequencies)[::2], 6)
    array([3., 7.])
    >>> dmd.is_stable, dmd.A.shape
    (True, (4, 4))
    """
    X, dt, delays, rank, u = _check_common(X, dt, delays, rank, inputs)
    alpha = check_real("alpha", alpha, low=0.0, low_inclusive=True)
    alpha_mode = check_choice("alpha_mode", alpha_mode, ("absolute", "relative"))
    n_pairs = X.shape[1] - delays
    n_states = X.shape[0] * delays
    n_reg = n_states + (0 if u is None else u.shape[0])
    # The Gram matrix serves the relative-alpha scale and the Cholesky route (computed once),
    # and its trace tells whether the data are all zero without another pass over them.
    with_gram = alpha > 0 and n_reg <= n_pairs
    if not (with_gram and rank is None):
        _refuse_all_zero(X)
    if alpha == 0 and rank is None and n_pairs < n_reg:
        raise InputError(
            f"Plain DMD (alpha=0, rank=None) needs at least as many snapshot pairs as states "
            f"(+ inputs): got {n_pairs} pairs for {n_states} states. Pass alpha > 0 "
            "(e.g. alpha_mode='relative', alpha=1e-6), a rank, or more samples."
        )
    problem = _prepare(X, delays, rank, u)
    gram = problem.regressor @ problem.regressor.T if with_gram else None
    if gram is not None and rank is None and not gram.diagonal()[:n_states].sum() > 0:
        # the state rows cover every sample but the last; squares can underflow: ask the data
        _refuse_all_zero(X)
    alpha, problem = _absolute_alpha(alpha, alpha_mode, problem, gram)
    return _fit_problem(problem, alpha, dt, gram=gram)
