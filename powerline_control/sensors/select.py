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
:mod:`powerline_control._sensor_criteria`), because a DARE per swap is what makes a naive
search take minutes at ``n = 101``.

Work happens in units of the measurement noise (covariances divided by a reference variance): on
a line the covariances are ~1e-8 m^2 and, unscaled, the conic solvers return infinite bounds.
"""

from __future__ import annotations

import itertools
import math
import numbers
import time
import types
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import control as ct
import cvxpy as cp
import numpy as np
import scipy.linalg as sla
from threadpoolctl import threadpool_limits

from ._riccati import gramian_sum, solve_filter_dare
from ._sensor_criteria import (
    KalmanCriterion,
    LogDetCriterion,
    MinEigCriterion,
    Polytope,
    frank_wolfe_bound,
    linear_extreme,
)
from ._validation import (
    check_array,
    check_budget,
    check_choice,
    check_covariance,
    check_discrete_system,
    check_indices,
    check_int,
    check_psd,
    check_real,
    check_rng,
    read_only,
)
from .errors import EstimationError, InputError, SensorSelectionError

__all__ = ["select_sensors", "SensorSelection", "Baseline", "sensor_count_study",
           "SensorCountStudy"]

def _small_matrix_blas():
    """One BLAS thread: the matrices here are <= ~100 wide, where threads only add contention.

    Measured on a loaded 2-core machine: a 101 x 101 Cholesky solve took 36 ms with two
    OpenBLAS threads and well under 1 ms with one.
    """
    return threadpool_limits(limits=1, user_api="blas")


CRITERIA = ("kalman", "gramian", "min-eig", "reconstruction")
_SOLVER_OK = ("optimal", "optimal_inaccurate")


# ----------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class Baseline:
    """One comparison layout.

    Attributes
    ----------
    name : str
        ``"first-k"``, ``"evenly-spaced"``, ``"greedy"``, ``"qr-pivoting"``, ``"random-mean"``,
        ``"random-best"`` or ``"brute-force"``.
    nodes : tuple of int or None
        Candidate indices (None for the random mean).
    objective : float
        Exact criterion of the layout (``inf`` / ``-inf`` if the layout cannot estimate the state).

    Examples
    --------
    >>> Baseline("first-k", (0, 1, 2), 1.5e-6).nodes
    (0, 1, 2)
    """

    name: str
    nodes: tuple[int, ...] | None
    objective: float


@dataclass(frozen=True)
class SensorSelection:
    """Result of :func:`select_sensors`.

    Attributes
    ----------
    nodes : tuple of int
        Chosen candidate indices (outputs of ``sys``), ascending.
    positions : tuple of float or None
        Their positions in metres, when known.
    objective : float
        Exact criterion of ``nodes`` in physical units: for ``"kalman"`` the trace of the
        steady-state posterior covariance of the weighted states (m^2 for displacements), for
        ``"gramian"`` / ``"reconstruction"`` a log determinant, for ``"min-eig"`` an eigenvalue.
    bound : float
        Certificate: no layout satisfying the constraints does better than this (a lower bound
        for a minimised criterion, an upper bound for a maximised one). Equal to ``objective``
        when ``certificate`` is ``"exhaustive"``.
    gap : float
        Relative distance to the bound, >= 0, an upper bound on the distance to the best layout:
        ``(objective - bound) / objective`` for ``"kalman"``; ``(bound - objective) / bound`` for
        ``"min-eig"``; ``1 - exp(-(bound - objective) / d)`` for the log determinants (the gap in
        the geometric-mean eigenvalue ``det^(1/d)``, ``d`` the matrix size). 0 when
        ``certificate`` is ``"exhaustive"`` (the layout is proved optimal).
    weights : numpy.ndarray
        Relaxed weights ``z`` (read-only), one per candidate.
    criterion : str
        The criterion optimised.
    sense : str
        ``"minimize"`` or ``"maximize"``.
    k : int
        Number of sensors.
    baselines : Mapping[str, Baseline]
        Comparison layouts (they ignore the practical constraints: they are the obvious layouts
        a report compares against). ``"brute-force"`` (present when ``C(m, k)`` is small enough)
        does honour the constraints and is the true optimum.
    relaxation_value : float
        Optimal value of the relaxation as reported by the solver (physical units); NaN when
        every solver failed.
    solver : str
        cvxpy solver whose relaxation was used (``"none"`` when every installed conic solver
        failed on it).
    solver_status : str
        Its status (``"failed"`` when none succeeded).
    certificate : str
        What backs ``bound``, always checked rather than trusted:

        * ``"exhaustive"``: every feasible layout was evaluated on the exact criterion, so
          ``nodes`` is the optimum, ``bound`` equals ``objective`` and ``gap`` is 0. Used when
          ``C(m, k)`` is within ``brute_force_limit``, and also, when the relaxation failed on
          every solver and ``brute_force_limit=0``, within the default limit (100,000);
        * ``"convexity"``: the bound comes from the convexity inequality at the relaxed weights
          (the solver's, or a feasible point when every solver failed) with an exact linear
          program, valid whatever the solver's accuracy;
        * ``"solver"``: the solver's optimal value (valid up to its tolerance);
        * ``"none: heuristic"``: no bound could be computed; ``bound`` is the trivial one
          (0 for ``"kalman"``, ``inf`` for a maximised criterion) and ``gap`` is 1. The layout
          comes from greedy and swap searches on the exact criterion.
    n_exact_evaluations : int
        Exact criterion evaluations used (Riccati solves for ``"kalman"``).
    runtime : float
        Wall-clock seconds.
    solver_attempts : tuple of str
        What each solver tried did, in order (e.g. ``("CLARABEL: failed (...)", "SCS:
        optimal")``): the requested solver first, then the other installed conic solvers.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> import powerline_control as plc
    >>> sys = ct.ss(np.diag([0.9, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0)
    >>> sel = plc.select_sensors(sys, k=1, Q=np.eye(2), R=0.1)
    >>> sel.nodes, sel.criterion, sel.sense, sorted(sel.baselines)[:2]
    ((0,), 'kalman', 'minimize', ['brute-force', 'evenly-spaced'])
    """

    nodes: tuple[int, ...]
    positions: tuple[float, ...] | None
    objective: float
    bound: float
    gap: float
    weights: np.ndarray
    criterion: str
    sense: str
    k: int
    baselines: Mapping[str, Baseline]
    relaxation_value: float
    solver: str
    solver_status: str
    certificate: str
    n_exact_evaluations: int
    runtime: float
    solver_attempts: tuple[str, ...] = ()

    def summary(self) -> str:
        """A short markdown report: the layout, its certificate and the baselines.

        Returns
        -------
        str
            Markdown text.
        """
        better = "lower" if self.sense == "minimize" else "higher"
        pct = f"{100 * self.gap:.3g} %"
        # What the gap guarantees (see the ``gap`` attribute): a relative distance to the optimum.
        if self.certificate == "exhaustive":
            claim = ("proved optimal by exhaustive search over every feasible layout, within 0 % "
                     "of the best possible layout")
        elif self.certificate == _HEURISTIC:
            claim = ("not certified: no solver could bound the optimum, the layout comes from "
                     "greedy and swap searches on the exact criterion")
        elif self.sense == "minimize":
            claim = (f"certified: the best possible layout's objective lies within {pct} below "
                     "this one's")
        else:
            quantity = "objective" if self.criterion == "min-eig" else "det^(1/d)"
            claim = (f"certified: this layout's {quantity} lies within {pct} below the best "
                     "possible layout's")
        lines = [
            f"criterion {self.criterion!r} ({better} is better), k = {self.k}",
            f"nodes {list(self.nodes)}: objective {self.objective:.6g}, bound {self.bound:.6g}, "
            f"gap {pct}: {claim}",
            "",
            "| layout | objective |",
            "|---|---|",
        ]
        lines += [f"| {b.name} | {b.objective:.6g} |" for b in self.baselines.values()]
        return "\n".join(lines)


@dataclass(frozen=True)
class SensorCountStudy:
    """Result of :func:`sensor_count_study`: the criterion and the RMS error against ``k``.

    Attributes
    ----------
    k : tuple of int
        Sensor counts studied.
    objective : numpy.ndarray
        Exact steady-state posterior trace of the optimised layout for each ``k``.
    rms_error : numpy.ndarray
        ``sqrt(objective / q)``: the predicted RMS estimation error per weighted state.
    simulated_rms_error : numpy.ndarray
        The RMS error of a steady-state Kalman filter on a seeded simulation of the model.
    layouts : tuple of tuple of int
        The optimised layout for each ``k``.
    target_error : float or None
        The RMS error asked for.
    smallest_k : int or None
        Smallest ``k`` whose predicted RMS error is at most ``target_error`` (None if none).

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> import powerline_control as plc
    >>> sys = ct.ss(np.diag([0.9, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0)
    >>> study = plc.sensor_count_study(sys, [1, 2], Q=np.eye(2), R=0.1, target_error=1.0,
    ...                                n_steps=50)
    >>> study.smallest_k, study.layouts
    (1, ((0,), (0, 1)))
    """

    k: tuple[int, ...]
    objective: np.ndarray
    rms_error: np.ndarray
    simulated_rms_error: np.ndarray
    layouts: tuple[tuple[int, ...], ...]
    target_error: float | None
    smallest_k: int | None


# -------------------------------------------------------------------------------- validation
def _check_noise(R: object, m: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The package's one rule for R (scalar, per-candidate variances or a full ``(m, m)``
    matrix, positive definite); returns the variances and the full matrix when correlated."""
    full = check_covariance("R", R, m, definite=True)
    variances = np.diag(full).copy()
    correlated = np.any(full - np.diag(variances))
    return variances, (full if correlated else None)


def _check_costs(cost: object, m: int) -> np.ndarray | None:
    """``None`` or one finite, non-negative cost per candidate (a negative cost would buy budget
    for the other sensors: the budget would mean nothing)."""
    if cost is None:
        return None
    costs = check_array("cost", cost, shape=(m,))
    if np.any(costs < 0):
        raise InputError(
            f"The 'cost' parameter must hold non-negative costs (one per candidate); a negative "
            f"cost makes the budget meaningless. Got {int(np.count_nonzero(costs < 0))} negative "
            f"value(s), the smallest {float(costs.min()):.6g}."
        )
    return costs


# Q/R (process over measurement noise) that the Riccati iteration, which works in units of the
# measurement noise and squares them, still carries in double precision with a wide margin (it
# overflows near 1e150 on small models).
_MAX_NOISE_RATIO = 1e120


def _check_noise_ratio(q: np.ndarray, r: np.ndarray | float) -> None:
    """Refuse an ``R`` so small against ``Q`` that the Kalman criterion would overflow."""
    smallest = float(np.min(r))
    ratio = float(np.max(np.abs(q))) / smallest
    if ratio > _MAX_NOISE_RATIO:
        raise InputError(
            f"The 'R' parameter is too small for the Riccati equation: its smallest variance "
            f"{smallest:.3g} against the largest entry {float(np.max(np.abs(q))):.3g} of Q is a "
            f"ratio of {ratio:.3g}, over the {_MAX_NOISE_RATIO:.0e} that double precision "
            "carries through the iteration. Give the sensors' real noise variance (R must be "
            f"at least max|Q| / {_MAX_NOISE_RATIO:.0e})."
        )


def _check_error_weight(error_weight: object, c: np.ndarray, n: int) -> None:
    """``error_weight`` is checked for every criterion (``sensor_count_study`` uses it for its
    simulated error whatever the criterion), not only where ``"kalman"`` reads it."""
    _error_weight(error_weight, c, n)


def _check_positions(positions: object, m: int) -> np.ndarray | None:
    if positions is None:
        return None
    x = check_array("positions", positions, ndim=1)
    if x.shape != (m,):
        raise InputError(
            f"The 'positions' parameter must give one position (m) per candidate output, shape "
            f"({m},). Got shape {x.shape} instead."
        )
    return x


def _check_indices(name: str, value: object, m: int) -> np.ndarray:
    if value is None:
        return np.zeros(0, dtype=int)
    return check_indices(name, value, m, allow_empty=True)


def _check_zones(forbidden: object) -> list[tuple[float, float]]:
    if forbidden is None:
        return []
    try:
        zones = [(float(lo), float(hi)) for lo, hi in forbidden]  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise InputError(
            "The 'forbidden' parameter must be a sequence of (start, end) intervals in metres, "
            f"e.g. [(0.0, 0.2), (3.4, 3.66)]. Got {forbidden!r} instead."
        ) from exc
    for lo, hi in zones:
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise InputError(
                f"The 'forbidden' parameter has an interval ({lo}, {hi}); each must be finite "
                "with start <= end."
            )
    return zones


# ---------------------------------------------------------------------------- feasibility
@dataclass(frozen=True)
class _Feasibility:
    """Integer feasibility of layouts: allowed candidates, spacing conflicts, budget."""

    allowed: np.ndarray  # (m,) bool
    required: np.ndarray
    conflict: np.ndarray | None  # (m, m) bool or None
    cost: np.ndarray | None
    budget: float | None

    def compatible(self, layout: Sequence[int], j: int) -> bool:
        if not self.allowed[j] or j in layout:
            return False
        if self.conflict is not None and np.any(self.conflict[j, list(layout)]):
            return False
        return True

    def within_budget(self, layout: Sequence[int]) -> bool:
        if self.cost is None or self.budget is None:
            return True
        return float(self.cost[list(layout)].sum()) <= self.budget * (1 + 1e-12)

    def is_feasible(self, layout: Sequence[int]) -> bool:
        layout = list(layout)
        if len(set(layout)) != len(layout) or not np.all(self.allowed[layout]):
            return False
        if not set(self.required.tolist()) <= set(layout):
            return False
        if self.conflict is not None and np.any(self.conflict[np.ix_(layout, layout)]):
            return False
        return self.within_budget(layout)

    def swaps(self, layout: list[int]) -> np.ndarray:
        """Feasible moves ``(p, j)``: replace ``layout[p]`` by candidate ``j``."""
        moves = []
        req = set(self.required.tolist())
        for p, i in enumerate(layout):
            if i in req:
                continue
            rest = layout[:p] + layout[p + 1:]
            for j in np.flatnonzero(self.allowed):
                if j in layout:
                    continue
                if self.conflict is not None and np.any(self.conflict[j, rest]):
                    continue
                if not self.within_budget(rest + [int(j)]):
                    continue
                moves.append((p, int(j)))
        return np.array(moves, dtype=int).reshape(-1, 2)

    def additions(self, layout: list[int]) -> np.ndarray:
        return np.array([j for j in range(len(self.allowed))
                         if self.compatible(layout, j) and self.within_budget(layout + [j])],
                        dtype=int)


def _build_constraints(
    m: int, k: int, x: np.ndarray | None, zones: list[tuple[float, float]],
    min_spacing: float, required: np.ndarray, cost: np.ndarray | None, budget: float | None,
) -> tuple[_Feasibility, Polytope]:
    """Check that the constraints admit a layout and return them in integer and relaxed form."""
    needs_positions = [name for name, used in (("forbidden", bool(zones)),
                                               ("min_spacing", min_spacing > 0)) if used]
    if needs_positions and x is None:
        raise InputError(
            f"The {needs_positions[0]!r} constraint is in metres, so the candidate positions are "
            "needed: pass positions= (e.g. model.node_positions for every node)."
        )
    allowed = np.ones(m, dtype=bool)
    for lo, hi in zones:
        allowed &= ~((x >= lo) & (x <= hi))
    if k > m:
        raise SensorSelectionError(f"k={k} exceeds the number of candidate outputs ({m}).")
    blocked = required[~allowed[required]]
    if blocked.size:
        raise SensorSelectionError(
            f"Required candidates {blocked.tolist()} (at {x[blocked].tolist()} m) lie inside the "
            f"forbidden zones {zones}: remove them from 'required' or shrink the zones."
        )
    if required.size > k:
        raise SensorSelectionError(
            f"{required.size} required candidates do not fit in k={k} sensors; raise k."
        )
    n_allowed = int(allowed.sum())
    if k > n_allowed:
        raise SensorSelectionError(
            f"k={k} exceeds the {n_allowed} candidates left after the forbidden zones {zones} "
            f"removed {m - n_allowed} of {m}; lower k or shrink the zones."
        )
    conflict = None
    cliques: list[np.ndarray] = []
    if min_spacing > 0:
        conflict = np.abs(x[:, None] - x[None, :]) < min_spacing
        np.fill_diagonal(conflict, False)
        bad = [(int(a), int(b)) for a, b in itertools.combinations(required, 2) if conflict[a, b]]
        if bad:
            raise SensorSelectionError(
                f"Required candidates {bad[0]} are closer than min_spacing={min_spacing} m."
            )
        # Largest layout: required ones plus an interval-scheduling greedy on the compatible rest
        # (leftmost first is optimal for points on a line).
        free = allowed.copy()
        free[required] = False
        if required.size:
            free &= ~np.any(conflict[:, required], axis=1)
        chosen_x: list[float] = []
        for j in np.flatnonzero(free)[np.argsort(x[free], kind="stable")]:
            if not chosen_x or x[j] - chosen_x[-1] >= min_spacing:
                chosen_x.append(float(x[j]))
        most = required.size + len(chosen_x)
        if most < k:
            raise SensorSelectionError(
                f"min_spacing={min_spacing} m leaves room for at most {most} sensors among the "
                f"{n_allowed} allowed candidates (k={k} requested); lower min_spacing or k."
            )
        order = np.argsort(x, kind="stable")
        xs = x[order]
        seen: set[tuple[int, ...]] = set()
        for a in range(m):
            end = np.searchsorted(xs, xs[a] + min_spacing, side="left")
            window = tuple(order[a:end][allowed[order[a:end]]].tolist())
            if len(window) > 1 and window not in seen:
                seen.add(window)
                cliques.append(np.array(window))
    if cost is not None and budget is not None:
        free = np.flatnonzero(allowed & ~np.isin(np.arange(m), required))
        cheapest = float(cost[required].sum() + np.sort(cost[free])[: k - required.size].sum())
        if cheapest > budget:
            raise SensorSelectionError(
                f"budget={budget} is below {cheapest:.6g}, the cost of the cheapest {k} allowed "
                "sensors (required ones included); raise the budget or lower k."
            )
    feas = _Feasibility(allowed, required, conflict, cost, budget)
    poly = Polytope(m, k, required, np.flatnonzero(~allowed), tuple(cliques), cost, budget)
    return feas, poly


# ----------------------------------------------------------------------------- the search
def _best_of(crit, candidates: list[list[int]]) -> tuple[int, np.ndarray]:
    values = crit.exact(np.array(candidates, dtype=int))
    return int(np.argmin(values)), values


def _improves(new: float, old: float) -> bool:
    return new < old - 1e-10 * max(abs(old), 1e-300)


# Exact evaluations of a whole neighbourhood are allowed while (moves x n^3) stays below this:
# every swap of a 21-state model (a true swap-local optimum), a surrogate-ranked shortlist at 101
# and for reduced models with many candidates (at 2e7 the greedy step of a rank-20 model with
# 1,001 candidates solved 1,001 Riccati equations per sensor: 7 of its 20 s).
_EXHAUSTIVE_WORK = 2e6


def _exhaustive(crit, n_moves: int) -> bool:
    size = getattr(crit, "n_states", 0)
    return not hasattr(crit, "rank_swaps") or n_moves * size**3 <= _EXHAUSTIVE_WORK


def _swap_search(crit, feas: _Feasibility, layout: list[int], cost: float,
                 chunk: int = 8, max_chunks: int = 2,
                 max_rounds: int = 500) -> tuple[list[int], float]:
    """Best-improvement swaps on the exact criterion until no swap improves it.

    Small neighbourhoods are evaluated exactly in full (a true swap-local optimum); large ones
    are ordered by the criterion's surrogate and only the ``chunk * max_chunks`` most promising
    are judged exactly, a chunk at a time.
    """
    layout = list(layout)
    for _ in range(max_rounds):
        moves = feas.swaps(layout)
        if len(moves) == 0:
            break
        ranked = not _exhaustive(crit, len(moves))
        if ranked:
            scores = crit.rank_swaps(np.array(layout))[moves[:, 0], moves[:, 1]]
            moves = moves[np.argsort(scores, kind="stable")][: chunk * max_chunks]
            size = chunk
        else:
            size = len(moves)
        improved = False
        for start in range(0, len(moves), size):
            part = moves[start:start + size]
            cands = np.tile(np.array(layout), (len(part), 1))
            cands[np.arange(len(part)), part[:, 0]] = part[:, 1]
            values = crit.exact(cands)
            best = int(np.argmin(values))
            if _improves(values[best], cost):
                layout, cost, improved = cands[best].tolist(), float(values[best]), True
                break
        if not improved:
            break
    return layout, cost


def _greedy(crit, feas: _Feasibility, k: int, chunk: int = 4) -> list[int] | None:
    """Add the sensor that most improves the exact criterion (surrogate-ranked when large)."""
    layout = feas.required.tolist()
    while len(layout) < k:
        adds = feas.additions(layout)
        if len(adds) == 0:
            return None
        scores = crit.rank_additions(np.array(layout, dtype=int)) if hasattr(
            crit, "rank_additions") else None
        if scores is not None and not _exhaustive(crit, len(adds)):
            adds = adds[np.argsort(scores[adds], kind="stable")][:chunk]
        values = crit.exact(np.array([layout + [int(j)] for j in adds]))
        if np.all(~np.isfinite(values)) and scores is not None:
            best = int(adds[np.argmin(scores[adds])])  # not yet detectable: follow the surrogate
        else:
            best = int(adds[np.argmin(values)])
        layout.append(best)
    return layout


def _round(weights: np.ndarray, feas: _Feasibility, k: int) -> list[int] | None:
    """Largest weights first, skipping candidates that would break a constraint."""
    layout = feas.required.tolist()
    for j in np.argsort(-weights, kind="stable"):
        if len(layout) == k:
            break
        if feas.compatible(layout, int(j)) and feas.within_budget(layout + [int(j)]):
            layout.append(int(j))
    return layout if len(layout) == k else None


def _brute_force(crit, feas: _Feasibility, k: int, limit: int) -> tuple[list[int], float] | None:
    req = feas.required.tolist()
    free = [int(j) for j in np.flatnonzero(feas.allowed) if j not in req]
    if math.comb(len(free), k - len(req)) > limit:
        return None
    combos = [req + list(c) for c in itertools.combinations(free, k - len(req))]
    combos = [c for c in combos if feas.is_feasible(c)]
    if not combos:
        return None
    values = crit.exact(np.array(combos, dtype=int))
    best = int(np.argmin(values))
    return combos[best], float(values[best])


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
    """Flops of the per-candidate Gramians and whether doubling beats the plain sum."""
    plain = 2.0 * m * n * n * horizon
    doubling = 8.0 * m * n**3 * max(1, math.ceil(math.log2(horizon + 1)))
    return min(plain, doubling), doubling < plain


def _gramian_terms(a: np.ndarray, g: np.ndarray, horizon: int) -> np.ndarray:
    """Per-candidate finite-horizon observability Gramians ``sum_t (A^T)^t g_i g_i^T A^t``.

    The plain sum costs ``O(m n^2 N)``; for long horizons the binary doubling
    ``W_2N = W_N + (A^N)^T W_N A^N`` costs ``O(m n^3 log N)`` instead, so ``horizon=10**8`` is
    a second, not an hour. Overflow (an unstable model over a long horizon) is refused.
    """
    m, n = g.shape
    _, use_doubling = _gramian_work(m, n, horizon)
    with np.errstate(all="ignore"):
        if not use_doubling:
            mats = np.zeros((m, n, n))
            rows = g.copy()
            for _ in range(horizon):
                mats += rows[:, :, None] * rows[:, None, :]
                rows = rows @ a
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


_HEURISTIC = "none: heuristic"
_DEFAULT_BRUTE_FORCE_LIMIT = 100_000
# Conic solvers that handle the semidefinite / exponential cones of the relaxations, in the order
# they are tried after the requested one (only installed ones are used).
_CONIC_SOLVERS = ("CLARABEL", "SCS", "MOSEK", "CVXOPT", "COPT")


def _solve_relaxation(crit, poly: Polytope, m: int, requested: str):
    """Solve the relaxation with ``requested``, then the other installed conic solvers.

    Returns ``((weights, relaxed_cost, solver, status), attempts)`` for the first solver that
    reports an optimal (possibly inaccurate) status with finite weights, ``(None, attempts)``
    when all fail; ``attempts`` lists what each solver did. (The certificate never trusts the
    solver's accuracy: it is recomputed from its weights by convexity.)
    """
    installed = set(cp.installed_solvers())
    order = [requested] + [s for s in _CONIC_SOLVERS if s in installed and s != requested]
    attempts: list[str] = []
    for name in order:
        z = cp.Variable(m)
        problem = cp.Problem(cp.Minimize(crit.relaxation(z)), poly.cvxpy_constraints(z))
        try:
            with warnings.catch_warnings():
                # cvxpy warns "Solution may be inaccurate"; the status says so and the
                # certificate does not rely on the solver's accuracy.
                warnings.simplefilter("ignore", UserWarning)
                problem.solve(solver=name)
        except (cp.error.SolverError, cp.error.DCPError, ValueError, ArithmeticError) as exc:
            attempts.append(f"{name}: failed ({type(exc).__name__}: {str(exc)[:120]})")
            continue
        value = None if z.value is None else np.asarray(z.value, dtype=float)
        if problem.status not in _SOLVER_OK or value is None or not np.all(np.isfinite(value)) \
                or problem.value is None or not np.isfinite(problem.value):
            attempts.append(f"{name}: status {problem.status!r}")
            continue
        attempts.append(f"{name}: {problem.status}")
        weights = np.clip(value, 0.0, 1.0)
        relaxed_cost = float(problem.value) * crit.relaxation_scale
        return (weights, relaxed_cost, name, str(problem.status)), attempts
    return None, attempts


def _feasible_weights(poly: Polytope) -> np.ndarray:
    """A point of the relaxed polytope without a conic solver (an LP vertex, or uniform)."""
    _, vertex = linear_extreme(np.zeros(poly.m), poly)
    if vertex is not None:
        return vertex
    weights = np.full(poly.m, poly.k / poly.m)  # pragma: no cover - the constraints were checked
    return weights


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
        ``H`` in the Kalman criterion ``tr(H P H^T)``: the states (default, the issue's
        criterion), every candidate output (the displacement field, for FE models whose states
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
    with _small_matrix_blas():
        return _select_sensors(**locals())


def _select_sensors(sys, k, criterion, *, Q, R, positions, forbidden, min_spacing, required, cost,
                    budget, error_weight, basis, horizon, relaxation_rank, solver, n_random,
                    brute_force_limit, seed) -> SensorSelection:
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
    relaxed, attempts = _solve_relaxation(crit, poly, m, solver)
    if relaxed is not None:
        weights, relaxed_cost, used_solver, status = relaxed
        bound_cost, certificate = _certificate(crit, weights, poly, relaxed_cost)
    else:
        used_solver, status = "none", "failed"
        weights = _feasible_weights(poly)
        relaxed_cost = float("nan")
        # The convexity bound needs no solver: Frank-Wolfe from any feasible weights.
        bound_cost, certificate = _certificate(crit, weights, poly, -np.inf)
        if certificate != "convexity":
            bound_cost, certificate = -np.inf, _HEURISTIC

    # Integer layouts: rounding and greedy, each improved by exact swaps; the better wins.
    starts = []
    rounded = _round(weights, feas, k)
    if rounded is not None:
        starts.append(rounded)
    greedy = _greedy(crit, feas, k)
    if greedy is not None:
        starts.append(greedy)
    # Every feasible layout, when there are few enough: the exact optimum. Without a relaxation
    # the enumeration runs up to the default limit even when brute_force_limit=0 disabled it.
    limit = brute_force_limit if relaxed is not None else (brute_force_limit
                                                           or _DEFAULT_BRUTE_FORCE_LIMIT)
    brute = _brute_force(crit, feas, k, limit) if limit else None
    if not starts and brute is not None:  # rounding and greedy can stall where a layout exists
        starts.append(brute[0])
    if not starts:
        raise SensorSelectionError(
            "No layout honouring the constraints could be built from the relaxed weights; "
            "loosen min_spacing or budget."
        )
    best_layout, best_cost = None, np.inf
    for start in starts:
        start_cost = float(crit.exact(np.array([start]))[0])
        layout, value = _swap_search(crit, feas, start, start_cost)
        if best_layout is None or value < best_cost:
            best_layout, best_cost = layout, value
    if brute is not None and brute[1] < best_cost:
        best_layout, best_cost = brute
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
    crit = LogDetCriterion(mats, relaxation_rank)

    def gap_of(obj: float, bound: float) -> float:
        return max(0.0, 1.0 - math.exp(-(bound - obj) / d))

    return crit, (lambda cost: -cost + d * math.log(scale * unit)), gap_of


def _error_weight(error_weight: object, c: np.ndarray, n: int) -> np.ndarray:
    if isinstance(error_weight, str):
        choice = check_choice("error_weight", error_weight, ("states", "outputs"))
        h = np.eye(n) if choice == "states" else c
    else:
        if error_weight is None or isinstance(error_weight, numbers.Number):
            raise InputError(
                f"The 'error_weight' parameter must be 'states', 'outputs' or a (q, {n}) "
                f"matrix. Got {error_weight!r} instead."
            )
        h = check_array("error_weight", error_weight, ndim=2)
        if h.shape[1] != n:
            raise InputError(
                f"The 'error_weight' parameter must be a (q, {n}) matrix. Got {h.shape}."
            )
    return h.T @ h


def _certificate(crit, weights: np.ndarray, poly: Polytope, solver_value: float
                 ) -> tuple[float, str]:
    """Lower bound on the cost of every feasible layout, from convexity at ``weights``.

    For a convex cost ``f``, ``f(z) >= f(w) + grad f(w) . (z - w)`` for every ``z``; its minimum
    over the relaxed polytope (an exact LP) bounds the relaxation, and hence every integer
    layout, from below, however inaccurate the solver's ``w``. For ``"kalman"`` the solver saw a
    reduced prior; Frank-Wolfe steps on the full relaxation tighten the bound from there.
    """
    bounds = []
    if isinstance(crit, MinEigCriterion):
        for reduced in (False, True):  # both bound lambda_min (the reduced one by interlacing)
            value, grad = crit.linearisation(weights, reduced)
            low, _ = linear_extreme(grad, poly)
            bounds.append(value + low - float(grad @ weights))
    else:
        for reduced in (True, False) if isinstance(crit, KalmanCriterion) else (False,):
            iterations = 1 if reduced else 40
            bound, _ = frank_wolfe_bound(crit, weights, poly, iterations, reduced)
            bounds.append(bound)
    bounds = [b for b in bounds if np.isfinite(b)]
    if bounds:
        best = max(bounds)
        if isinstance(crit, KalmanCriterion):
            best = max(best, 0.0)  # the trace of a covariance is never negative
        return best, "convexity"
    return solver_value, "solver"


def _baselines(crit, feas: _Feasibility, k: int, greedy: list[int] | None,
               psi: np.ndarray | None, x: np.ndarray | None, rng: np.random.Generator,
               n_random: int, brute: tuple[list[int], float] | None, to_physical
               ) -> dict[str, Baseline]:
    """The obvious layouts a report compares against, judged on the exact criterion."""
    m = len(feas.allowed)
    layouts: dict[str, list[int]] = {"first-k": list(range(k))}
    if x is not None:
        targets = np.linspace(x.min(), x.max(), k + 2)[1:-1]
        even: list[int] = []
        for t in targets:
            for j in np.argsort(np.abs(x - t), kind="stable"):
                if int(j) not in even:
                    even.append(int(j))
                    break
        layouts["evenly-spaced"] = even
    else:
        layouts["evenly-spaced"] = np.unique(np.round(np.linspace(0, m - 1, k + 2)[1:-1])
                                             ).astype(int).tolist()
    if greedy is not None:
        layouts["greedy"] = greedy
    if psi is not None:
        # QR column pivoting on Psi^T (the method of PySensors' SSPOR): rows maximising |det|.
        _, _, piv = sla.qr(psi.T, pivoting=True, mode="economic")
        qr_layout = piv[: min(k, len(piv))].tolist()
        for j in range(m):  # k larger than the basis: fill in candidate order
            if len(qr_layout) == k:
                break
            if j not in qr_layout:
                qr_layout.append(j)
        layouts["qr-pivoting"] = qr_layout
    out: dict[str, Baseline] = {}
    named = [v for v in layouts.values() if len(set(v)) == k]
    values = crit.exact(np.array(named, dtype=int))
    for (name, layout), value in zip(
        [(nm, v) for nm, v in layouts.items() if len(set(v)) == k], values, strict=True):
        out[name] = Baseline(name, tuple(sorted(int(i) for i in layout)), to_physical(value))
    if n_random:
        rand = np.array([rng.choice(m, size=k, replace=False) for _ in range(n_random)])
        values = crit.exact(rand)
        physical = np.array([to_physical(v) for v in values])
        finite = physical[np.isfinite(physical)]
        mean = float(finite.mean()) if finite.size == len(physical) else to_physical(np.inf)
        out["random-mean"] = Baseline("random-mean", None, mean)
        best = int(np.argmin(values))
        out["random-best"] = Baseline("random-best", tuple(sorted(rand[best].tolist())),
                                      to_physical(values[best]))
    if brute is not None:
        out["brute-force"] = Baseline("brute-force", tuple(sorted(brute[0])),
                                      to_physical(brute[1]))
    return out


def _error_rows(error_weight: object, c: np.ndarray, n: int) -> np.ndarray:
    if isinstance(error_weight, str):
        return np.eye(n) if error_weight == "states" else c
    return np.asarray(error_weight, dtype=float)


def _simulated_rms(a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray, h: np.ndarray,
                   layout: Sequence[int], n_steps: int, rng: np.random.Generator) -> float:
    """RMS of ``H (x - x_hat)`` for a steady-state Kalman filter on a simulated trajectory.

    ``r`` is the candidates' noise covariance, ``(m,)`` variances or a full ``(m, m)`` matrix.
    """
    index = list(layout)
    cs = c[index]
    r_s = np.diag(r[index]) if r.ndim == 1 else r[np.ix_(index, index)]
    try:  # the package's one Riccati solver (doubling, QZ fallback, stabilising only)
        prior = solve_filter_dare(a, cs, q, r_s)
    except EstimationError as exc:
        raise SensorSelectionError(
            f"The steady-state Kalman filter of the layout {index} that checks the "
            f"predicted RMS error could not be computed: {exc}"
        ) from exc
    # solve_filter_dare returns only stabilising solutions: the filter below is stable.
    gain = np.linalg.solve(cs @ prior @ cs.T + r_s, cs @ prior).T
    noise_factor = np.linalg.cholesky(r_s)
    lam, vec = np.linalg.eigh((q + q.T) / 2)
    q_half = vec * np.sqrt(np.clip(lam, 0, None))
    lam, vec = np.linalg.eigh((prior + prior.T) / 2)
    x = vec @ (np.sqrt(np.clip(lam, 0, None)) * rng.standard_normal(len(a)))
    x_pred = np.zeros(len(a))  # the error starts with the steady-state prior covariance
    total = 0.0
    for _ in range(n_steps):
        y = cs @ x + noise_factor @ rng.standard_normal(len(index))
        x_post = x_pred + gain @ (y - cs @ x_pred)
        err = h @ (x - x_post)
        total += float(err @ err)
        x_pred = a @ x_post
        x = a @ x + q_half @ rng.standard_normal(len(a))
    return math.sqrt(total / (n_steps * h.shape[0]))


def sensor_count_study(
    sys: ct.StateSpace,
    k_values: Sequence[int],
    *,
    Q: object,
    R: object = 1.0,
    target_error: float | None = None,
    n_steps: int = 2000,
    seed: int | np.random.Generator | None = 0,
    **options: object,
) -> SensorCountStudy:
    """How many sensors: the optimised Kalman criterion and the simulated RMS error against k.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete model whose outputs are the candidates (as in :func:`select_sensors`).
    k_values : sequence of int
        Sensor counts to study, ascending.
    Q : array_like
        Process-noise covariance ``(n, n)``.
    R : float or array_like
        Measurement-noise covariance of the candidates (scalar, per-candidate variances or a
        full matrix; see :func:`select_sensors`).
    target_error : float, optional
        RMS estimation error (per weighted state) to reach; sets ``smallest_k``.
    n_steps : int
        Length of the simulation that checks each predicted RMS error; refused when the
        simulations exceed the package's work budget (docs/conventions.md).
    seed : int, numpy.random.Generator or None
        Seed of the simulation.
    **options
        Passed to :func:`select_sensors` (constraints, ``error_weight``, ``solver``, ...).

    Returns
    -------
    SensorCountStudy
        Per ``k``: the exact criterion, the predicted and simulated RMS errors, the layout, and
        the smallest ``k`` reaching ``target_error``.

    Raises
    ------
    InputError
        Invalid arguments.
    SensorSelectionError
        As :func:`select_sensors`.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> import powerline_control as plc
    >>> sys = ct.ss(np.diag([0.9, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0)
    >>> study = plc.sensor_count_study(sys, [1, 2], Q=np.eye(2), R=0.1, n_steps=200)
    >>> study.k, bool(study.rms_error[1] < study.rms_error[0])
    ((1, 2), True)
    """
    sys = check_discrete_system("sys", sys)
    if isinstance(k_values, str) or not isinstance(k_values, Sequence | np.ndarray):
        raise InputError(
            "The 'k_values' parameter must be a sequence of sensor counts, e.g. [1, 2, 3]. "
            f"Got {k_values!r} of type {type(k_values).__name__}."
        )
    items = np.ravel(k_values).tolist() if isinstance(k_values, np.ndarray) else list(k_values)
    ks = [check_int("k_values", k, low=1) for k in items]
    if not ks or sorted(set(ks)) != ks:
        raise InputError(
            f"The 'k_values' parameter must be a non-empty ascending sequence of distinct "
            f"integers. Got {list(k_values)!r} instead."
        )
    if target_error is not None:
        target_error = check_real("target_error", target_error, low=0.0)
    n_steps = check_int("n_steps", n_steps, low=1)
    rng = check_rng(seed)
    a = np.asarray(sys.A, dtype=float)
    c = np.asarray(sys.C, dtype=float)
    q = check_psd("Q", Q, a.shape[0])
    variances, r_full = _check_noise(R, c.shape[0])
    r = variances if r_full is None else r_full
    _check_error_weight(options.get("error_weight", "states"), c, a.shape[0])
    h = _error_rows(options.get("error_weight", "states"), c, a.shape[0])
    n = a.shape[0]
    # Each simulated step is a handful of small matrix products plus about ten NumPy calls,
    # whose overhead (~1 us each) is the time of ~1e3 floating-point operations: counted as
    # 1e4 per step, so that the work budget (1e12, minutes) bounds the loop's wall time too.
    per_step = 6.0 * n * n + 4.0 * max(ks) * n + 2.0 * h.shape[0] * n + 1e4
    check_budget("The simulations that check the predicted errors",
                 flops=float(n_steps) * len(ks) * per_step, parameter="n_steps", value=n_steps,
                 fix="simulate fewer steps (n_steps=2000 is the default)")
    options = {"n_random": 0, "brute_force_limit": 0, **options}
    objective, rms, simulated, layouts = [], [], [], []
    for k in ks:
        sel = select_sensors(sys, k, "kalman", Q=Q, R=R, **options)  # type: ignore[arg-type]
        objective.append(sel.objective)
        rms.append(math.sqrt(sel.objective / h.shape[0]))
        simulated.append(_simulated_rms(a, c, q, r, h, sel.nodes, n_steps, rng))
        layouts.append(sel.nodes)
    reached = [k for k, e in zip(ks, rms, strict=True) if target_error is not None
               and e <= target_error]
    return SensorCountStudy(
        k=tuple(ks),
        objective=read_only(np.array(objective)),
        rms_error=read_only(np.array(rms)),
        simulated_rms_error=read_only(np.array(simulated)),
        layouts=tuple(layouts),
        target_error=target_error,
        smallest_k=reached[0] if reached else None,
    )
