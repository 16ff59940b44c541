"""Optimal sensor placement with a convex relaxation and an optimality certificate.

:func:`select_sensors` chooses ``k`` of the outputs of a discrete ``control.StateSpace`` (the
candidates: every node of an identified model, or positions of an FE model) for one of four
criteria, each relaxed to a convex problem in weights ``0 <= z <= 1, sum z = k`` and solved with
cvxpy:

========================  =========================================================  ==========
criterion                 exact (integer) criterion                                   sense
========================  =========================================================  ==========
``"kalman"``              trace of the steady-state posterior covariance (DARE)       minimise
``"gramian"``             log det of the (finite-horizon) observability Gramian       maximise
``"min-eig"``             smallest eigenvalue of that Gramian                         maximise
``"reconstruction"``      log det ``Psi_S^T Psi_S`` for a POD basis (Joshi & Boyd)    maximise
========================  =========================================================  ==========

The relaxed optimum bounds every integer layout (the certificate); the weights are rounded and
then improved by a swap search judged on the *exact* criterion. When there are few layouts
(``brute_force_limit``) every feasible one is evaluated, and the certificate is the optimum.
For ``"kalman"`` the swaps are ranked by a one-step surrogate and only the most promising are
solved exactly, with a batched doubling Riccati solver (see
:mod:`powerline_control.sensors.criteria`), because a DARE per swap is what makes a naive
search take minutes at ``n = 101``.

Test seam: ``_gramian_work``: which route (plain sum or doubling) sums the per-candidate
Gramians, so that a test of the plain route's blocks knows it runs (tests/test_sensors.py).

Work happens in units of the measurement noise (covariances divided by a reference variance): on
a line the covariances are ~1e-8 m^2 and, unscaled, the conic solvers return infinite bounds.
"""

from __future__ import annotations

import math
import time
import types
from collections.abc import Sequence

import control as ct
import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from .._riccati import gramian_sum
from .._threads import on_one_blas_thread
from .._validation import (
    check_array,
    check_budget,
    check_choice,
    check_discrete_system,
    check_int,
    check_psd,
    check_real,
    check_rng,
    checked_keywords,
    read_only,
)
from ..errors import InputError, SensorSelectionError
from .baselines import _baselines
from .constraints import (
    _build_constraints,
    _check_costs,
    _check_error_weight,
    _check_indices,
    _check_noise,
    _check_noise_ratio,
    _check_positions,
    _check_zones,
    _error_weight,
)
from .criteria import (
    KalmanCriterion,
    LogDetCriterion,
    MinEigCriterion,
)
from .relaxation import _relax
from .results import SensorSelection
from .search import _search_layouts

__all__ = ["select_sensors"]


CRITERIA = ("kalman", "gramian", "min-eig", "reconstruction")


_DEFAULT_BRUTE_FORCE_LIMIT = 100_000


# ----------------------------------------------------------------------------- criteria
def _stationary_covariance(a: np.ndarray, q: np.ndarray, horizon: int) -> np.ndarray:
    """Stationary state covariance (Lyapunov), or after ``horizon`` steps for marginal models.

    The finite sum ``sum_{k<N} A^k Q (A^k)^T`` is computed by doubling (``O(n^3 log N)``).
    """
    if np.max(np.abs(np.linalg.eigvals(a))) < 1 - 1e-9:
        x = sla.solve_discrete_lyapunov(a, q)
    else:  # marginal or unstable: the covariance after `horizon` steps
        block, power = q.copy(), a.copy()
        x, total_power = np.zeros_like(q), np.eye(len(a))
        remaining = horizon
        with np.errstate(all="ignore"):
            while remaining:
                if remaining & 1:
                    x = x + total_power @ block @ total_power.T
                    total_power = power @ total_power
                remaining >>= 1
                if remaining:
                    block = block + power @ block @ power.T
                    power = power @ power
        if not np.all(np.isfinite(x)):
            raise InputError(
                f"The stationary covariance over horizon={horizon} steps overflows: the model "
                "has modes outside the unit circle. Use a shorter 'horizon' or pass basis=."
            )
    return (x + x.T) / 2


def _gramian_work(m: int, n: int, horizon: int) -> tuple[float, bool]:
    """Flops of the per-candidate Gramians and whether doubling beats the plain sum.

    The plain sum propagates the ``m`` rows ``horizon`` steps (``2 m n^2`` each) and adds their
    outer products in blocks of steps, as matrix products (``2 m n^2`` per step again).
    """
    plain = 4.0 * m * n * n * horizon
    doubling = 8.0 * m * n**3 * max(1, math.ceil(math.log2(horizon + 1)))
    return min(plain, doubling), doubling < plain


# The plain Gramian sum adds the outer products of a block of T steps as one batched matrix
# product (m, n, T) @ (m, T, n): T between 8 and 128 (BLAS is 3.5x faster at T = 128 than at 32
# for n = 200), the block at most this many doubles (128 MB; T = 83 at m = 1001, n = 200).
_GRAMIAN_BLOCK_DOUBLES = 2**24


def _gramian_terms(a: np.ndarray, g: np.ndarray, horizon: int) -> np.ndarray:
    """Per-candidate finite-horizon observability Gramians ``sum_t (A^T)^t g_i g_i^T A^t``.

    The plain sum (``O(m n^2 N)``) adds the outer products of blocks of up to 128 steps as
    batched matrix products (one broadcast outer product per step moved ``m n^2`` doubles through
    memory each step: 200 s at m = 1001, n = 200, N = 400, against 8 s); for long horizons the
    binary doubling ``W_2N = W_N + (A^N)^T W_N A^N`` costs ``O(m n^3 log N)`` instead, so
    ``horizon=10**8`` is a second, not an hour. Overflow (an unstable model over a long
    horizon) is refused.
    """
    m, n = g.shape
    _, use_doubling = _gramian_work(m, n, horizon)
    with np.errstate(all="ignore"):
        if not use_doubling:
            mats = np.zeros((m, n, n))
            rows = g.copy()
            size = int(min(horizon, 128, max(8, _GRAMIAN_BLOCK_DOUBLES // (m * n))))
            block = np.empty((m, size, n))
            done = 0
            while done < horizon:
                steps = min(size, horizon - done)
                for t in range(steps):
                    block[:, t] = rows
                    rows = rows @ a
                part = block[:, :steps]
                mats += np.swapaxes(part, 1, 2) @ part
                done += steps
        else:
            mats = gramian_sum(a, g[:, :, None] * g[:, None, :], horizon)
    if not np.all(np.isfinite(mats)) or np.max(np.abs(mats)) > 1e300:
        raise InputError(
            f"The observability Gramians over horizon={horizon} steps overflow: the model has "
            "modes outside the unit circle. Use a shorter 'horizon'."
        )
    return (mats + np.swapaxes(mats, 1, 2)) / 2


def _default_horizon(a: np.ndarray) -> int:
    return 2 * a.shape[0]


def _check_work(criterion: str, n: int, m: int, horizon: int, needs_covariance: bool) -> None:
    """Refuse, before running, a horizon whose Gramian or covariance sums exceed the budget."""
    if criterion in ("gramian", "min-eig"):
        check_budget("The per-candidate observability Gramians", nbytes=24.0 * m * n * n,
                     flops=_gramian_work(m, n, horizon)[0], parameter="horizon", value=horizon,
                     fix="use a shorter horizon or fewer candidates / states")
    if needs_covariance:
        check_budget("The stationary output covariance", nbytes=8.0 * (n * n + m * n),
                     flops=2.0 * n**3 * math.ceil(math.log2(horizon + 1)) + 2.0 * m * m * n,
                     parameter="horizon", value=horizon,
                     fix="use a shorter horizon or fewer candidates / states")


# ------------------------------------------------------------------------------- public API
@checked_keywords
@on_one_blas_thread   # matrices <= ~100 wide: threads only add contention
def select_sensors(
    sys: ct.StateSpace,
    k: int,
    criterion: str = "kalman",
    *,
    Q: object = None,
    R: object = 1.0,
    positions: object = None,
    forbidden: object = None,
    min_spacing: float = 0.0,
    required: Sequence[int] | None = None,
    cost: object = None,
    budget: float | None = None,
    error_weight: object = "states",
    basis: object = None,
    horizon: int | None = None,
    relaxation_rank: int = 20,
    solver: str = "CLARABEL",
    n_random: int = 20,
    brute_force_limit: int = 100_000,
    seed: int | np.random.Generator | None = 0,
) -> SensorSelection:
    """Choose ``k`` sensors among the outputs of ``sys``, with a certificate of optimality.

    Solves the convex relaxation of the criterion in cvxpy, turns its bound into a certificate
    (valid whatever the solver's accuracy, through the convexity inequality and an exact LP),
    rounds the weights to a layout that honours every constraint, and improves it (and the greedy
    layout) by swaps judged on the exact criterion.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete model ``x[t+1] = A x[t] + w``, ``y = C x + v``; its ``m`` outputs are the
        candidate sensors (e.g. ``dmd.to_statespace()`` for every node, or
        ``model.to_statespace(dt=..., n_modes=...)``).
    k : int
        Number of sensors, ``1 <= k <= m``.
    criterion : {"kalman", "gramian", "min-eig", "reconstruction"}
        What to optimise (see the module docstring).
    Q : array_like, optional
        Process-noise covariance ``(n, n)``. Required for ``"kalman"``; for ``"reconstruction"``
        without ``basis`` it defines the POD basis (stationary output covariance).
    R : float or array_like
        Measurement-noise covariance of the candidates, the package's one rule for ``R``: one
        variance for all, one per candidate ``(m,)`` (m^2), or a full ``(m, m)`` symmetric
        matrix (correlated noise: ``"kalman"`` only, which uses each layout's exact information
        ``C_S^T R_SS^-1 C_S``). Positive definite: a zero variance is an ``InputError``, and so
        (for ``"kalman"``) is a variance below ``max|Q| / 1e120``, which the Riccati iteration
        cannot carry in double precision.
    positions : array_like, optional
        Position (m) of each candidate; needed for ``forbidden`` and ``min_spacing`` and used by
        the evenly-spaced baseline.
    forbidden : sequence of (float, float), optional
        Intervals in metres where no sensor may go (near clamps, spacers), ends included.
    min_spacing : float
        Minimum distance (m) between any two sensors.
    required : sequence of int, optional
        Candidates that must be in the layout.
    cost : array_like, optional
        Cost of each candidate, finite and non-negative; with ``budget``, the layout's total
        cost is at most ``budget``.
    budget : float, optional
        Maximum total cost, finite and ``>= 0``. A budget above the total cost of all candidates
        constrains nothing and is capped at that total.
    error_weight : {"states", "outputs"} or array_like
        ``H`` in the Kalman criterion ``tr(H P H^T)``: the states (default: every state
        weighted alike), every candidate output (the displacement field, for FE models whose states
        are modal), or a given ``(q, n)`` matrix. Checked whatever the criterion (only
        ``"kalman"`` reads it here; :func:`sensor_count_study` also weights its simulated error).
    basis : array_like, optional
        ``(m, r)`` basis for ``"reconstruction"`` and QR pivoting (default: the ``k`` leading POD
        modes of the stationary output covariance under ``Q``).
    horizon : int, optional
        Steps of the finite-horizon Gramian (default ``2 n``).
    relaxation_rank : int
        Largest matrix size the cvxpy relaxation sees. "kalman": the prior is cut to its leading
        eigen-directions, which keeps the bound valid (see ``KalmanCriterion``); "min-eig": the
        directions where the Gramian is smallest (valid by interlacing); "gramian" /
        "reconstruction": the leading directions supply starting weights only. In every case
        the reported bound is then tightened on the full relaxation in numpy.
    solver : str
        cvxpy solver tried first, e.g. ``"CLARABEL"`` (default) or ``"SCS"``; both install with
        cvxpy. If it fails (an exception, a non-optimal status, non-finite weights) the other
        installed conic solvers are tried, then the searches run without a relaxation; the
        result's ``certificate`` and ``solver_attempts`` say what happened.
    n_random : int
        Random layouts in the baseline (mean and best); refused when their memory or work
        exceeds the package's budget (docs/conventions.md).
    brute_force_limit : int
        Enumerate every feasible layout when ``C(m, k)`` is at most this (0 disables, unless the
        relaxation fails on every solver: then up to 100,000 layouts are enumerated anyway); the
        result is then proved optimal (``certificate="exhaustive"``, ``gap`` 0).
    seed : int, numpy.random.Generator or None
        Seed of the random baseline.

    Returns
    -------
    SensorSelection
        The layout, its exact objective, the bound, the gap, the weights and the baselines.

    Raises
    ------
    InputError
        Invalid arguments (the message names the parameter).
    SensorSelectionError
        Infeasible constraints (named), or a model that no layout can estimate. A solver
        failure is not an error: see ``certificate``.

    Notes
    -----
    Cost: everything works in the model's ``n`` states and the ``m`` candidates (one Riccati
    solve is ``O(n^3)`` in the information form, the relaxation has ``m`` weights and a
    ``relaxation_rank``-sized cone), so a rank-``r`` DMD model of a 1,000-node span costs what
    ``r`` and ``m`` cost. See ``benchmarks/bench_sensors.py`` for the measured table.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> import powerline_control as plc
    >>> a = np.diag([0.9, 0.5, -0.3])
    >>> c = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
    >>> sys = ct.ss(a, np.zeros((3, 0)), c, np.zeros((4, 0)), 1.0)
    >>> sel = plc.select_sensors(sys, k=2, Q=np.eye(3), R=0.1)
    >>> sel.nodes, sel.gap >= 0, sel.bound <= sel.objective
    ((0, 3), True, True)
    """
    started = time.perf_counter()
    sys = check_discrete_system("sys", sys)
    a = np.asarray(sys.A, dtype=float)
    c = np.asarray(sys.C, dtype=float)
    n, m = a.shape[0], c.shape[0]
    k = check_int("k", k, low=1, high=m)
    criterion = check_choice("criterion", criterion, CRITERIA)
    r, r_full = _check_noise(R, m)
    if r_full is not None and criterion != "kalman":
        raise InputError(
            f"The 'R' parameter is a full matrix with correlated sensor noise; the {criterion!r} "
            "criterion adds up independent sensors, so it needs uncorrelated noise (a scalar or "
            "one variance per candidate). Use criterion='kalman', which handles correlations."
        )
    x = _check_positions(positions, m)
    zones = _check_zones(forbidden)
    min_spacing = check_real("min_spacing", min_spacing, low=0.0, low_inclusive=True)
    req = _check_indices("required", required, m)
    costs = _check_costs(cost, m)
    if budget is not None:
        budget = check_real("budget", budget, low=0.0, low_inclusive=True)
        if costs is None:
            raise InputError("The 'budget' parameter needs 'cost' (one cost per candidate).")
        # A budget at or above the total cost of every candidate constrains nothing: it is
        # capped at that total (1e300 would otherwise reach the LP solver as a bound it cannot
        # scale; the layouts allowed are the same).
        budget = min(budget, float(costs.sum()))
    _check_error_weight(error_weight, c, n)
    relaxation_rank = check_int("relaxation_rank", relaxation_rank, low=1)
    n_random = check_int("n_random", n_random, low=0)
    # The random baseline draws n_random layouts of k and judges each exactly (an (n, n)
    # covariance per layout at least): refuse a count that cannot fit before drawing any.
    check_budget("The random baseline", nbytes=8.0 * n_random * (k + n * n),
                 flops=float(n_random) * n**3, parameter="n_random", value=n_random,
                 fix="use fewer random layouts (n_random=20 is the default)")
    brute_force_limit = check_int("brute_force_limit", brute_force_limit, low=0)
    horizon = _default_horizon(a) if horizon is None else check_int("horizon", horizon, low=1)
    _check_work(criterion, n, m, horizon, Q is not None or basis is not None)
    if not isinstance(solver, str) or solver.upper() not in cp.installed_solvers():
        raise InputError(
            f"The 'solver' parameter must be an installed cvxpy solver, one of "
            f"{cp.installed_solvers()}. Got {solver!r} instead."
        )
    solver = solver.upper()
    rng = check_rng(seed)

    # Units of the measurement noise: covariances / r0, rows scaled by sqrt(r0 / R_i).
    r0 = float(np.exp(np.mean(np.log(r))))
    correlated = None
    if r_full is None:
        g = c * np.sqrt(r0 / r)[:, None]
    else:
        # Relaxation rows with the smallest noise eigenvalue: their information dominates every
        # layout's true one (R_SS >= lambda_min I), so the bound stays valid.
        smallest = float(np.linalg.eigvalsh(r_full).min())
        g = c * np.sqrt(r0 / smallest)
        correlated = (c, r_full / r0)
    q = None
    if Q is not None:
        q_physical = check_psd("Q", Q, n)
        if criterion == "kalman":
            _check_noise_ratio(q_physical, r if r_full is None else smallest)
        q = q_physical / r0
    feas, poly = _build_constraints(m, k, x, zones, min_spacing, req, costs, budget)

    psi = _basis(basis, a, c, q, r, r0, k, horizon, needed=criterion == "reconstruction")
    crit, to_physical, gap_of = _make_criterion(
        criterion, a, q, g, c, psi, error_weight, horizon, relaxation_rank, r0, correlated)

    # Relaxation: the requested solver, then every other installed conic solver; a failure of
    # all of them is not fatal (the exhaustive or swap search below still runs).
    relaxed, weights, relaxed_cost, used_solver, status, bound_cost, certificate, attempts = \
        _relax(crit, poly, m, solver)

    # Every feasible layout, when there are few enough: the exact optimum. Without a relaxation
    # the enumeration runs up to the default limit even when brute_force_limit=0 disabled it.
    limit = brute_force_limit if relaxed else (brute_force_limit or _DEFAULT_BRUTE_FORCE_LIMIT)
    best_layout, best_cost, greedy, brute = _search_layouts(crit, feas, k, weights, limit)
    if not np.isfinite(best_cost):
        raise SensorSelectionError(
            f"No layout of k={k} sensors can estimate the state (the exact {criterion!r} "
            "criterion is infinite): some mode on or outside the unit circle is invisible to "
            "them. Raise k or add candidates."
        )
    if brute is not None:
        # The search saw every feasible layout: best_cost is the optimum itself, a tighter bound
        # than any relaxation.
        bound_cost, certificate = best_cost, "exhaustive"
    if isinstance(crit, KalmanCriterion):
        bound_cost = max(bound_cost, 0.0)  # the trace of a covariance is never negative
    bound_cost = min(bound_cost, best_cost)  # guard against round-off above the optimum

    baselines = _baselines(crit, feas, k, greedy, psi, x, rng, n_random, brute, to_physical)
    objective = to_physical(best_cost)
    bound = to_physical(bound_cost)
    nodes = tuple(sorted(int(i) for i in best_layout))
    gap = gap_of(objective, bound) if np.isfinite(bound) else 1.0
    return SensorSelection(
        nodes=nodes,
        positions=None if x is None else tuple(float(x[i]) for i in nodes),
        objective=objective,
        bound=bound,
        gap=float(gap),
        weights=read_only(weights),
        criterion=criterion,
        sense=crit.sense,
        k=k,
        baselines=types.MappingProxyType(baselines),
        relaxation_value=to_physical(relaxed_cost),
        solver=used_solver,
        solver_status=status,
        certificate=certificate,
        solver_attempts=tuple(attempts),
        n_exact_evaluations=crit.n_exact,
        runtime=time.perf_counter() - started,
    )


def _basis(basis, a, c, q, r, r0, k, horizon, needed) -> np.ndarray | None:
    m = c.shape[0]
    if basis is not None:
        psi = check_array("basis", basis, ndim=2)
        if psi.shape[0] != m:
            raise InputError(
                f"The 'basis' parameter must have one row per candidate: expected ({m}, r) but "
                f"found {psi.shape}."
            )
    elif q is not None:
        cov = c @ _stationary_covariance(a, q, horizon) @ c.T
        lam, vec = np.linalg.eigh((cov + cov.T) / 2)
        psi = vec[:, ::-1][:, : min(k, m)]
    elif needed:
        raise InputError(
            "The 'reconstruction' criterion needs a basis: pass basis= (m, r) or Q= (the POD "
            "basis is then taken from the stationary output covariance)."
        )
    else:
        return None
    if needed and psi.shape[1] > k:
        raise InputError(
            f"The 'basis' parameter has {psi.shape[1]} columns, more than k={k}: log det "
            "Psi_S^T Psi_S is then singular for every layout. Use at most k basis vectors."
        )
    return psi * np.sqrt(r0 / r)[:, None]


def _make_criterion(criterion, a, q, g, c, psi, error_weight, horizon, relaxation_rank, r0,
                    correlated=None):
    """The criterion object, its cost-to-physical map and its gap formula."""
    n = a.shape[0]
    if criterion == "kalman":
        if q is None:
            raise InputError(
                "The 'kalman' criterion needs the process-noise covariance Q (n, n), e.g. "
                "dmd.residual_covariance for an identified model."
            )
        weight = _error_weight(error_weight, c, n)
        try:
            crit = KalmanCriterion(a, q, g, weight, relaxation_rank, correlated=correlated)
        except FloatingPointError as exc:
            raise SensorSelectionError(
                "Even all candidates together cannot estimate the state (the Riccati iteration "
                "diverges): a mode on or outside the unit circle is unobservable from every "
                "output. Check the model (e.g. stabilise the identified A) or add candidates."
            ) from exc

        def gap_of(obj: float, bound: float) -> float:
            return max(0.0, (obj - bound) / obj) if obj > 0 else 0.0

        return crit, (lambda cost: cost * r0), gap_of
    mats = psi[:, :, None] * psi[:, None, :] if criterion == "reconstruction" else \
        _gramian_terms(a, g, horizon)
    d = mats.shape[1]
    scale = float(np.trace(mats.sum(axis=0))) / (d * len(mats)) or 1.0
    mats = mats / scale
    # Gramians were built from rows in noise units (c_i sqrt(r0 / R_i)); physical ones carry 1/r0.
    unit = 1.0 if criterion == "reconstruction" else 1.0 / r0
    if criterion == "min-eig":
        crit = MinEigCriterion(mats, relaxation_rank)

        def gap_of(obj: float, bound: float) -> float:
            return max(0.0, (bound - obj) / bound) if bound > 0 else 0.0

        return crit, (lambda cost: -cost * scale * unit), gap_of
    # Each W_i has rank <= 1 (a basis row's outer product) or <= min(n, horizon) (a Gramian over
    # `horizon` steps): the exact searches' bounds are tighter for it.
    crit = LogDetCriterion(mats, relaxation_rank,
                           term_rank=1 if criterion == "reconstruction" else min(d, horizon))

    def gap_of(obj: float, bound: float) -> float:
        return max(0.0, 1.0 - math.exp(-(bound - obj) / d))

    return crit, (lambda cost: -cost + d * math.log(scale * unit)), gap_of
