"""Numerical core of sensor selection: exact criteria, their convex relaxations, certificates.

Everything here works in *units of the measurement noise*: covariances are divided by a reference
variance ``r0`` and each candidate row ``c_i`` by its own noise standard deviation relative to it,
so that the information of candidate ``i`` is ``g_i g_i^T`` with ``g_i = c_i / sigma_i``. Unscaled,
the covariances of a line (~1e-8 m^2) make the conic solvers return infinite bounds.

Criteria are stored as "costs" (smaller is better); maximised criteria store the negated value.
Each criterion offers

- ``exact(layouts)``: the exact integer criterion for a batch of layouts ``(b, k)``;
- ``relaxation(z)``: a cvxpy expression of the convex relaxation in weights ``0 <= z <= 1``;
- ``linearisation(z)``: value and gradient of the relaxation at any ``z`` (for the certificate);
- ``rank_swaps`` / ``rank_additions`` (optional): a cheap surrogate that orders candidate moves so
  that only the promising ones are judged on the (expensive) exact criterion;
- ``bound_swaps`` / ``bound_additions`` (optional, log det): lower bounds on the moves' exact
  costs, so that a search judging every move can skip those that cannot win;
- ``segment`` (optional): the relaxation along a line, for Frank-Wolfe's line search.

Test seam: ``_information``: the sensor information matrices, fed to the batch DARE and compared
with SciPy's solve_discrete_are (tests/test_sensors.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import cvxpy as cp
import numpy as np
import scipy.linalg as sla
import scipy.optimize as sopt

from .._riccati import steady_state_batch

__all__ = [
    "KalmanCriterion",
    "LogDetCriterion",
    "MinEigCriterion",
    "Polytope",
    "linear_extreme",
]

def _information(g: np.ndarray, layouts: np.ndarray) -> np.ndarray:
    """``sum_{i in S} g_i g_i^T`` for each layout: ``(b, n, n)`` from ``g`` (m, n)."""
    rows = g[layouts]  # (b, k, n)
    return np.swapaxes(rows, 1, 2) @ rows


def _correlated_information(c: np.ndarray, r: np.ndarray, layouts: np.ndarray) -> np.ndarray:
    """``C_S^T R_SS^-1 C_S`` for each layout with a full (correlated) noise covariance ``r``."""
    layouts = np.atleast_2d(layouts)
    rows = c[layouts]  # (b, k, n)
    r_ss = r[layouts[:, :, None], layouts[:, None, :]]  # (b, k, k)
    info = np.swapaxes(rows, 1, 2) @ np.linalg.solve(r_ss, rows)
    return (info + np.swapaxes(info, 1, 2)) / 2


@dataclass(frozen=True, eq=False)
class Polytope:
    """The relaxed feasible set: ``0 <= z <= 1``, ``sum z = k`` and the practical constraints.

    ``fixed_one`` / ``fixed_zero`` are required / forbidden candidates; each row of ``cliques``
    lists candidates of which at most one may be chosen (windows shorter than the minimum
    spacing); ``cost`` with ``budget`` bounds ``cost . z``.
    """

    m: int
    k: int
    fixed_one: np.ndarray
    fixed_zero: np.ndarray
    cliques: tuple[np.ndarray, ...] = ()
    cost: np.ndarray | None = None
    budget: float | None = None

    def cvxpy_constraints(self, z: cp.Variable) -> list:
        cons = [z >= 0, z <= 1, cp.sum(z) == self.k]
        if self.fixed_one.size:
            cons.append(z[self.fixed_one] == 1)
        if self.fixed_zero.size:
            cons.append(z[self.fixed_zero] == 0)
        for clique in self.cliques:
            cons.append(cp.sum(z[clique]) <= 1)
        if self.cost is not None and self.budget is not None:
            cons.append(self.cost @ z <= self.budget)
        return cons

    @property
    def simple(self) -> bool:
        return not self.cliques and (self.cost is None or self.budget is None)


def linear_extreme(c: np.ndarray, poly: Polytope) -> tuple[float, np.ndarray | None]:
    """``min c . z`` over the polytope and a minimiser (a sort when simple, HiGHS otherwise).

    Returns ``(-inf, None)`` when the LP fails: the certificate then says nothing rather than
    something false.
    """
    lower = np.zeros(poly.m)
    upper = np.ones(poly.m)
    lower[poly.fixed_one] = 1.0
    upper[poly.fixed_zero] = 0.0
    if poly.simple:
        free = np.flatnonzero(upper > lower)
        rest = poly.k - int(lower.sum())
        chosen = free[np.argsort(c[free], kind="stable")][:rest]
        vertex = lower.copy()
        vertex[chosen] = 1.0
        return float(c @ vertex), vertex
    a_ub, b_ub = [], []
    for clique in poly.cliques:
        row = np.zeros(poly.m)
        row[clique] = 1.0
        a_ub.append(row)
        b_ub.append(1.0)
    if poly.cost is not None and poly.budget is not None:
        a_ub.append(poly.cost)
        b_ub.append(poly.budget)
    res = sopt.linprog(
        c, A_ub=np.array(a_ub), b_ub=np.array(b_ub), A_eq=np.ones((1, poly.m)),
        b_eq=[poly.k], bounds=np.column_stack([lower, upper]), method="highs",
    )
    if res.status != 0:
        return -np.inf, None
    # HiGHS' optimality tolerance (1e-7 on reduced costs) could put the value slightly above the
    # true minimum; step down by that much so the bound stays a bound.
    return float(res.fun) - 1e-7 * (np.abs(c).sum() + 1.0), np.clip(res.x, 0.0, 1.0)


def frank_wolfe_bound(crit, z0: np.ndarray, poly: Polytope, iterations: int = 40,
                      reduced: bool = False) -> tuple[float, np.ndarray]:
    """Best convexity lower bound along Frank-Wolfe iterations from ``z0`` (numpy only).

    Every iterate ``z_t`` gives a valid bound ``f(z_t) + min_z grad f(z_t) . (z - z_t)``; the
    iterations only make it tighter. Used to lift the solver's weights (from a reduced problem)
    to the full relaxation.
    """
    z = np.clip(z0, 0.0, 1.0)
    best = -np.inf
    for _ in range(iterations):
        try:
            value, grad = crit.linearisation(z, reduced)
        except (np.linalg.LinAlgError, ValueError):
            break
        low, vertex = linear_extreme(grad, poly)
        if vertex is None or not np.isfinite(value):
            break
        best = max(best, value + low - float(grad @ z))
        direction = vertex - z
        slope = float(grad @ direction)
        if slope >= -1e-12 * max(abs(value), 1e-300):
            break
        # Golden-section line search on the step (the relaxation is convex along the segment).
        lo, hi = 0.0, 1.0
        ratio = (math.sqrt(5) - 1) / 2
        along = crit.segment(z, direction, reduced) if hasattr(crit, "segment") else (
            lambda step, z=z, direction=direction: _value_or_inf(crit, z + step * direction,
                                                                  reduced))
        for _ in range(12):
            a = hi - ratio * (hi - lo)
            b = lo + ratio * (hi - lo)
            fa = along(a)
            fb = along(b)
            if fa <= fb:
                hi = b
            else:
                lo = a
        z = z + 0.5 * (lo + hi) * direction
    return best, z


def _value_or_inf(crit, z: np.ndarray, reduced: bool) -> float:
    try:
        return crit.linearisation(z, reduced, value_only=True)[0]
    except (np.linalg.LinAlgError, ValueError):
        return np.inf


# ------------------------------------------------------------------------------------ Kalman
@dataclass(eq=False)
class KalmanCriterion:
    """A-optimal: trace of ``H P_post H^T`` for the steady-state posterior covariance (DARE).

    Relaxation, and why it is a lower bound
    ---------------------------------------
    Let ``Phi_S(P) = A (P^-1 + G_S)^-1 A^T + Q`` be the Riccati map of layout ``S`` (``G_S`` its
    information). ``Phi_S`` is monotone in ``P`` (a larger prior gives a larger posterior) and
    antitone in ``G_S``. Start the filters of ``S`` and of *all* candidates from the same ``P_0``;
    by induction ``P_S(t+1) = Phi_S(P_S(t)) >= Phi_S(P_all(t)) >= Phi_all(P_all(t)) =
    P_all(t+1)``, because ``G_all >= G_S``. In the limit the steady-state priors obey
    ``P_S >= P_all_prior = A P_all A^T + Q`` with ``P_all`` the all-candidate posterior. So with the
    fixed prior ``Pbar = A P_all A^T + Q``,
    ``J(S) = tr H (P_S^-1 + G_S)^-1 H^T >= tr H (Pbar^-1 + G_S)^-1 H^T``, and the right side,
    with ``G_S`` replaced by ``sum z_i g_i g_i^T``, is convex in ``z``: its minimum over the relaxed
    weights bounds every integer layout from below. Keeping only the ``r`` largest
    eigen-directions ``U_r`` of ``Pbar`` lowers the prior (``Pbar >= U_r L_r U_r^T``) and hence
    the bound, which keeps it valid while shrinking the SDP from ``n`` to ``r``; Frank-Wolfe steps
    on the full relaxation (numpy) then recover most of what the cut lost.
    """

    a: np.ndarray
    q: np.ndarray
    g: np.ndarray  # (m, n) candidate rows in noise units
    weight: np.ndarray  # (n, n) = H^T H
    relaxation_rank: int
    n_exact: int = 0
    # Correlated noise: (C, R) in noise units. The exact criterion then uses the layout's true
    # information C_S^T R_SS^-1 C_S; ``g`` holds rows c_i / sqrt(lambda_min(R)), whose information
    # dominates it (R_SS >= lambda_min(R) I by interlacing), so the relaxation stays a bound.
    correlated: tuple[np.ndarray, np.ndarray] | None = None
    prior_bound: np.ndarray = field(init=False)
    _reduced: tuple = field(init=False)
    sense: str = "minimize"

    @property
    def n_states(self) -> int:
        return self.a.shape[0]

    def info(self, layouts: np.ndarray) -> np.ndarray:
        """Exact information matrices ``(b, n, n)`` of a batch of layouts."""
        if self.correlated is None:
            return _information(self.g, np.atleast_2d(layouts))
        return _correlated_information(*self.correlated, layouts)

    def __post_init__(self) -> None:
        m, n = self.g.shape
        full = np.arange(m)[None, :]
        _, post_all, ok = steady_state_batch(self.a, self.q, self.info(full))
        if not ok[0]:
            raise FloatingPointError("all candidates together cannot estimate the state")
        pbar = self.a @ post_all[0] @ self.a.T + self.q
        self.prior_bound = (pbar + pbar.T) / 2
        lam, u = np.linalg.eigh(self.prior_bound)
        order = np.argsort(lam)[::-1]
        lam, u = lam[order], u[:, order]
        keep = lam > 1e-12 * max(lam[0], 1e-300)
        keep[self.relaxation_rank:] = False
        lam_r, u_r = lam[keep], u[:, keep]
        # tr H U (L^-1 + U^T G U)^-1 U^T H^T = tr F (..)^-1 F^T with F^T F = U^T H^T H U.
        wr = u_r.T @ self.weight @ u_r
        wl, wv = np.linalg.eigh((wr + wr.T) / 2)
        f = (wv * np.sqrt(np.clip(wl, 0, None))).T
        self._reduced = (1.0 / lam_r, self.g @ u_r, f)

    # exact ----------------------------------------------------------------------------
    def exact(self, layouts: np.ndarray, chunk: int = 64) -> np.ndarray:
        layouts = np.atleast_2d(layouts)
        out = np.empty(len(layouts))
        for start in range(0, len(layouts), chunk):
            part = layouts[start:start + chunk]
            _, post, ok = steady_state_batch(self.a, self.q, self.info(part))
            vals = np.einsum("ij,bji->b", self.weight, np.where(ok[:, None, None], post, 0.0))
            out[start:start + chunk] = np.where(ok, vals, np.inf)
        self.n_exact += len(layouts)
        return out

    def steady(self, layout: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        prior, post, ok = steady_state_batch(
            self.a, self.q, self.info(np.asarray(layout)[None, :]))
        self.n_exact += 1
        return (prior[0], post[0]) if ok[0] else None

    # surrogate --------------------------------------------------------------------------
    def _posterior_for(self, layout: np.ndarray) -> np.ndarray:
        """Posterior of ``layout``; Pbar's one-step posterior if the layout is not detectable."""
        found = self.steady(layout) if len(layout) else None
        prior = self.prior_bound if found is None else found[0]
        gs = self.g[layout]
        info = gs.T @ gs
        post = np.linalg.solve(np.eye(len(prior)) + prior @ info, prior)
        return (post + post.T) / 2

    def rank_additions(self, layout: np.ndarray) -> np.ndarray:
        """Surrogate cost after adding each candidate (one measurement update, prior fixed)."""
        post = self._posterior_for(layout)
        pg = post @ self.g.T  # (n, m)
        gain = np.einsum("im,ij,jm->m", pg, self.weight, pg, optimize=True) / (
            1 + np.einsum("im,mi->m", pg, self.g))
        return np.trace(self.weight @ post) - gain

    def rank_swaps(self, layout: np.ndarray) -> np.ndarray:
        """Surrogate cost ``(k, m)`` after replacing ``layout[p]`` by candidate ``j``."""
        post = self._posterior_for(layout)
        out = np.empty((len(layout), self.g.shape[0]))
        for p, i in enumerate(layout):
            gi = post @ self.g[i]
            denom = 1 - self.g[i] @ gi
            removed = post + np.outer(gi, gi) / max(denom, 1e-12)
            pg = removed @ self.g.T
            gain = np.einsum("im,ij,jm->m", pg, self.weight, pg, optimize=True) / (
                1 + np.einsum("im,mi->m", pg, self.g))
            out[p] = np.trace(self.weight @ removed) - gain
        return out

    # relaxation ---------------------------------------------------------------------------
    relaxation_scale: float = 1.0

    def relaxation(self, z: cp.Variable):
        """``tr F (L^-1 + sum z_i g_i g_i^T)^-1 F^T``, rescaled for the conic solver.

        The matrix is multiplied by ``c`` so that its largest entries are O(1) and the objective
        divided so that it is 1 at ``z = 0`` (prior variances of 1e3..1e7 in noise units made
        Clarabel fail). The value times ``relaxation_scale`` is the relaxed trace. (Whitening by
        the prior is better conditioned still, but doubled Clarabel's time at n = 101.)
        """
        inv_lam, gr, f = self._reduced
        r = len(inv_lam)
        c = 1.0 / max(float(inv_lam.max()), float(np.max(np.sum(gr * gr, axis=1))), 1e-300)
        at_zero = max(float(np.sum(f * f / inv_lam)) / c, 1e-300)
        self.relaxation_scale = c * at_zero
        outer = np.einsum("ia,ib->abi", gr, gr).reshape(r * r, -1) * c
        info = cp.reshape(outer @ z, (r, r), order="C")
        mat = np.diag(c * inv_lam) + (info + info.T) / 2
        return cp.matrix_frac(f.T / np.sqrt(at_zero), mat)

    def _full_form(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not hasattr(self, "_full_cache"):
            lam, u = np.linalg.eigh(self.prior_bound)
            keep = lam > 1e-12 * max(lam.max(), 1e-300)
            u = u[:, keep]
            self._full_cache = (1 / lam[keep], self.g @ u, u.T @ self.weight @ u)
        return self._full_cache

    def linearisation(self, z: np.ndarray, reduced: bool, value_only: bool = False
                      ) -> tuple[float, np.ndarray | None]:
        """Value and gradient of the relaxed cost at ``z`` (full or reduced prior)."""
        if reduced:
            inv_lam, rows, f = self._reduced
            weight = f.T @ f
        else:
            inv_lam, rows, weight = self._full_form()
        mat = np.diag(inv_lam) + rows.T @ (z[:, None] * rows)
        factor = sla.cho_factor((mat + mat.T) / 2)
        value = float(np.trace(sla.cho_solve(factor, weight)))
        if value_only:
            return value, None
        minv_rows = sla.cho_solve(factor, rows.T)  # (r, m)
        grad = -np.einsum("im,ij,jm->m", minv_rows, weight, minv_rows, optimize=True)
        return value, grad


# ------------------------------------------------------------------------------ log det
def _subspace(mats: np.ndarray, rank: int, smallest: bool) -> np.ndarray | None:
    """Orthonormal basis of ``rank`` eigen-directions of ``sum_i W_i`` (None: keep them all)."""
    d = mats.shape[1]
    if d <= rank:
        return None
    total = mats.sum(axis=0)
    _, vec = np.linalg.eigh((total + total.T) / 2)
    return vec[:, :rank] if smallest else vec[:, ::-1][:, :rank]


def _project(mats: np.ndarray, u: np.ndarray | None) -> np.ndarray:
    return mats if u is None else np.einsum("ai,mab,bj->mij", u, mats, u, optimize=True)


def _weighted_sum_expr(mats: np.ndarray, z: cp.Variable):
    d = mats.shape[1]
    flat = mats.reshape(len(mats), d * d).T
    w = cp.reshape(flat @ z, (d, d), order="C")
    return (w + w.T) / 2


@dataclass(eq=False)
class _WeightedSumCriterion:
    """A criterion of ``W(S) = sum_{i in S} W_i`` (maximised, stored negated as a cost).

    Subclasses give ``_cost`` (the cost of a batch of ``W``) and ``_keep_smallest``: which
    eigen-directions of ``sum_i W_i`` the cut relaxation keeps when ``d > relaxation_rank``.
    """

    mats: np.ndarray  # (m, d, d) the W_i
    relaxation_rank: int = 20
    n_exact: int = 0
    sense: str = "maximize"
    relaxation_scale: float = 1.0
    _keep_smallest: ClassVar[bool] = False

    def __post_init__(self) -> None:
        self._reduced_mats = _project(self.mats, _subspace(self.mats, self.relaxation_rank,
                                                           smallest=self._keep_smallest))

    @staticmethod
    def _cost(w: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def exact(self, layouts: np.ndarray, chunk: int = 256) -> np.ndarray:
        layouts = np.atleast_2d(layouts)
        out = np.empty(len(layouts))
        for start in range(0, len(layouts), chunk):
            part = layouts[start:start + chunk]
            # Added one sensor at a time, in the order a sum over the layout's axis adds them
            # (the same values), without gathering a (b, k, d, d) copy first.
            w = self.mats[part[:, 0]]
            for column in range(1, part.shape[1]):
                w += self.mats[part[:, column]]
            out[start:start + chunk] = self._cost(w)
        self.n_exact += len(layouts)
        return out

    def weighted(self, z: np.ndarray, reduced: bool = False) -> np.ndarray:
        """``sum_i z_i W_i``: one matrix-vector product over the flattened ``W_i`` (BLAS; an
        einsum over ``(m, d, d)`` took 55 ms per call at m = 1001, d = 200)."""
        mats = self._reduced_mats if reduced else self.mats
        d = mats.shape[1]
        return (np.asarray(z, dtype=float) @ mats.reshape(len(mats), d * d)).reshape(d, d)

    def traces(self, winv: np.ndarray, reduced: bool = False) -> np.ndarray:
        """``tr(Y W_i)`` for every candidate, for a symmetric ``Y`` (one product)."""
        mats = self._reduced_mats if reduced else self.mats
        return mats.reshape(len(mats), -1) @ winv.reshape(-1)


@dataclass(eq=False)
class LogDetCriterion(_WeightedSumCriterion):
    """D-optimal: ``log det sum_{i in S} W_i`` (Gramian) or ``log det Psi_S^T Psi_S`` (basis).

    ``mats`` holds, per candidate, ``W_i``: the finite-horizon Gramian of candidate ``i`` or the
    outer product of its basis row. The relaxation is the same function of relaxed weights,
    concave, so its maximum bounds every integer layout from above. For ``d`` larger than
    ``relaxation_rank`` the cvxpy problem sees only the leading eigen-directions of
    ``sum_i W_i`` (an ``n x n`` log det cone took minutes at n = 101); that problem only supplies
    the starting weights, and the bound comes from Frank-Wolfe steps on the full relaxation.
    """

    @staticmethod
    def _cost(w: np.ndarray) -> np.ndarray:
        sign, logdet = np.linalg.slogdet(w)
        return np.where(sign > 0, -logdet, np.inf)

    #: Added to the solver's value to give the relaxed cost (see :meth:`relaxation`).
    relaxation_offset: float = 0.0

    def relaxation(self, z: cp.Variable):
        """``-log det sum_i z_i W_i`` on the kept directions, whitened for the conic solver.

        With ``T = sum_i W_i = V L V^T`` (kept directions), the solver sees
        ``W~_i = L^-1/2 V^T W_i V L^-1/2``, whose sum is the identity:
        ``log det sum z_i W_i = log det sum z_i W~_i + log det T``, the same problem shifted by a
        constant (:attr:`relaxation_offset`). Unwhitened, Gramians whose eigenvalues span 1e-30
        to 1e10 made Clarabel fail and SCS run to its iteration limit (63 s on a 20-state
        model of the lab span over 200 steps, 1 s whitened).
        """
        mats = self._reduced_mats
        total = mats.sum(axis=0)
        lam, vec = np.linalg.eigh((total + total.T) / 2)
        if lam[0] > 1e-300 * max(lam[-1], 1e-300):
            whiten = vec / np.sqrt(lam)
            mats = np.einsum("ai,mab,bj->mij", whiten, mats, whiten, optimize=True)
            self.relaxation_offset = -float(np.log(lam).sum())
        else:
            self.relaxation_offset = 0.0
        return -cp.log_det(_weighted_sum_expr(mats, z))

    def linearisation(self, z: np.ndarray, reduced: bool = False, value_only: bool = False
                      ) -> tuple[float, np.ndarray | None]:
        w = self.weighted(z, reduced)
        factor = sla.cho_factor((w + w.T) / 2)
        logdet = 2 * float(np.log(np.diag(factor[0])).sum())
        if value_only:
            return -logdet, None
        winv = sla.cho_solve(factor, np.eye(len(w)))
        return -logdet, -self.traces(winv.T, reduced)

    def segment(self, z: np.ndarray, direction: np.ndarray, reduced: bool):
        """The relaxed cost along ``z + a direction`` as a function of ``a``: ``W(z)`` and
        ``W(direction)`` are summed once, each point is then one Cholesky factorisation (the
        line search of :func:`frank_wolfe_bound` evaluates 24 points per step)."""
        w0, wd = self.weighted(z, reduced), self.weighted(direction, reduced)

        def value(step: float) -> float:
            w = w0 + step * wd
            try:
                factor = sla.cho_factor((w + w.T) / 2)
            except (np.linalg.LinAlgError, ValueError):
                return np.inf
            return -2 * float(np.log(np.diag(factor[0])).sum())

        return value

    # Exact pruning of the integer searches --------------------------------------------------
    #: Rank of every ``W_i`` at most (the Gramian of one row over N steps: min(d, N); a basis
    #: row's outer product: 1); a smaller rank gives a tighter bound.
    term_rank: int | None = None

    def bound_additions(self, layout: np.ndarray) -> np.ndarray:
        """A lower bound on the cost of ``layout + [j]`` for every candidate ``j`` (``-inf``
        where none is known).

        With ``W = W(layout)`` positive definite and ``mu`` the eigenvalues of
        ``W^-1/2 W_j W^-1/2`` (at most ``r`` of them non-zero, ``r`` = :attr:`term_rank`),
        ``log det (W + W_j) = log det W + sum log(1 + mu) <= log det W + r log(1 + tr(W^-1 W_j)
        / r)`` by Jensen's inequality (log is concave). The trace and the log det carry
        round-off margins scaled by ``W``'s condition number, so the bound stays below the
        exact criterion as computed; a ``W`` too ill-conditioned to say anything gives ``-inf``.
        """
        m, d = len(self.mats), self.mats.shape[1]
        layout = np.asarray(layout, dtype=int)
        none = np.full(m, -np.inf)
        if layout.size == 0:
            return none
        w = self.mats[layout].sum(axis=0)
        lam, vec = np.linalg.eigh((w + w.T) / 2)
        if not lam[0] > 0:
            return none
        cond = lam[-1] / lam[0]
        eps = np.finfo(float).eps
        if cond * d * eps > 1e-3:
            return none
        logdet = float(np.log(lam).sum())
        s = self.traces((vec / lam) @ vec.T)
        sizes = np.abs(np.einsum("iaa->i", self.mats))  # tr W_j >= its largest eigenvalue
        # |error of W^-1| <= d eps cond / lambda_min, times tr(W_j): the trace's margin.
        s = np.maximum(s, 0.0) + 10 * d * eps * cond / lam[0] * sizes
        r = d if self.term_rank is None else max(1, min(d, int(self.term_rank)))
        # The exact criterion is a slogdet of W + W_j: a backward error eps |W + W_j| moves its
        # log det by at most d eps (lambda_max + tr W_j) / lambda_min (adding W_j >= 0 does not
        # lower the smallest eigenvalue); 100x that is the margin.
        margin = 100 * d * eps * (lam[-1] + sizes) / lam[0] + 1e-12 * (abs(logdet) + d)
        return -(logdet + r * np.log1p(s / r)) - margin

    def bound_swaps(self, layout: np.ndarray) -> np.ndarray:
        """Lower bounds ``(k, m)`` on the cost after replacing ``layout[p]`` by candidate ``j``
        (:meth:`bound_additions` on the layout without its ``p``-th sensor)."""
        layout = np.asarray(layout, dtype=int)
        return np.array([self.bound_additions(np.delete(layout, p))
                         for p in range(len(layout))]).reshape(len(layout), len(self.mats))


@dataclass(eq=False)
class MinEigCriterion(_WeightedSumCriterion):
    """E-optimal: the smallest eigenvalue of ``sum_{i in S} W_i`` (maximised).

    For ``d`` larger than ``relaxation_rank`` the relaxation keeps the directions ``U`` where
    ``sum_i W_i`` is smallest; by Cauchy interlacing ``lambda_min(U^T W U) >= lambda_min(W)``,
    so the reduced problem still bounds every layout from above.
    """

    _keep_smallest: ClassVar[bool] = True

    @staticmethod
    def _cost(w: np.ndarray) -> np.ndarray:
        return -np.linalg.eigvalsh((w + np.swapaxes(w, 1, 2)) / 2)[:, 0]

    def relaxation(self, z: cp.Variable):
        return -cp.lambda_min(_weighted_sum_expr(self._reduced_mats, z))

    def linearisation(self, z: np.ndarray, reduced: bool = False, value_only: bool = False
                      ) -> tuple[float, np.ndarray]:
        """A linear upper bound ``lambda_min(W(z)) <= tr(Y W(z))`` for a trace-one PSD ``Y``.

        ``Y`` is the normalised projector on the eigenvectors of ``W(z)`` whose eigenvalues lie
        within 1 % of the smallest, so the bound stays valid for every ``z`` and is tight when
        the smallest eigenvalue at the optimum is simple or evenly shared. With ``reduced`` it
        is computed on ``U^T W U``, which bounds ``lambda_min(W)`` too (interlacing).
        """
        mats = self._reduced_mats if reduced else self.mats
        w = np.einsum("i,iab->ab", z, mats)
        lam, v = np.linalg.eigh((w + w.T) / 2)
        close = lam <= lam[0] + 0.01 * max(abs(lam[0]), 1e-300)
        vs = v[:, close]
        y = vs @ vs.T / vs.shape[1]
        grad = np.einsum("ab,iba->i", y, mats)
        return -float(grad @ z), -grad
