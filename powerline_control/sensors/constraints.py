"""Argument checks and the feasible layouts of a sensor selection.

The validation of ``select_sensors``' noise, costs, positions, indices and zones, and the
constraints every layout must honour (forbidden zones, minimum spacing, required sensors, a cost
budget) in two forms: an integer feasibility test for the searches (:class:`_Feasibility`) and
the relaxed polytope for the convex relaxation (``criteria.Polytope``).
"""

from __future__ import annotations

import itertools
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._validation import (
    check_array,
    check_choice,
    check_covariance,
    check_indices,
)
from ..errors import InputError, SensorSelectionError
from .criteria import (
    Polytope,
)


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
    _error_rows(error_weight, c, n)


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
@dataclass(frozen=True, eq=False)
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


def _error_weight(error_weight: object, c: np.ndarray, n: int) -> np.ndarray:
    """The weight ``H^T H`` of the posterior trace, ``(n, n)``."""
    h = _error_rows(error_weight, c, n)
    return h.T @ h


def _error_rows(error_weight: object, c: np.ndarray, n: int) -> np.ndarray:
    """The checked rows ``H`` whose error is weighed: identity, ``C`` or a ``(q, n)`` matrix."""
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
    return h
