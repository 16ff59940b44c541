"""The integer searches of sensor selection, each judged on the exact criterion.

Rounding of the relaxed weights, the greedy layout, the swap search that improves either (for
``"kalman"`` a surrogate ranks the swaps and only the most promising are solved exactly; for the
log det criteria every move is judged, in order of a lower bound on its cost, and the moves whose
bound exceeds the best cost found are skipped: the same move, fewer exact evaluations) and the
enumeration of every feasible layout when there are few.

Test seam: ``_pruned_argmin``: the bound-pruned choice of a move, compared with the argmin over
every move's exact cost (tests/test_sensors.py).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from ..errors import SensorSelectionError
from .constraints import _Feasibility


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
        if not ranked and hasattr(crit, "bound_swaps"):
            # Every move judged, but only those whose lower bound could beat the best found:
            # the same move as the full evaluation, at a fraction of the exact evaluations.
            bounds = crit.bound_swaps(np.array(layout))[moves[:, 0], moves[:, 1]]

            def build(part, layout=layout):
                cands = np.tile(np.array(layout), (len(part), 1))
                cands[np.arange(len(part)), part[:, 0]] = part[:, 1]
                return cands

            best, value = _pruned_argmin(crit, moves, bounds, build, cost)
            if best is None or not _improves(value, cost):
                break
            layout, cost = build(moves[best:best + 1])[0].tolist(), value
            continue
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


def _pruned_argmin(crit, moves: np.ndarray, bounds: np.ndarray, build, ceiling: float,
                   chunk: int = 32) -> tuple[int | None, float]:
    """The first move of least exact cost, judging moves in order of their lower bounds.

    Returns ``(index into moves, its cost)``, as ``argmin`` over every move's exact cost would
    (ties to the earliest move), or ``(None, inf)`` when no move's bound is below ``ceiling``
    (then none can improve on it). Moves are judged a chunk at a time, lowest bound first, and
    the rest skipped once the next bound exceeds the best cost found (their costs are higher)
    or reaches ``ceiling`` (none of them improves on it).
    """
    order = np.argsort(bounds, kind="stable")
    best, best_value = None, np.inf
    for start in range(0, len(order), chunk):
        part = order[start:start + chunk]
        if bounds[part[0]] > best_value or bounds[part[0]] >= ceiling:
            break
        values = crit.exact(build(moves[part]))
        for index, value in zip(part.tolist(), values.tolist(), strict=True):
            if best is None or value < best_value or (value == best_value and index < best):
                best, best_value = index, value
    return best, best_value


def _greedy(crit, feas: _Feasibility, k: int, chunk: int = 4) -> list[int] | None:
    """Add the sensor that most improves the exact criterion (surrogate-ranked when large)."""
    layout = feas.required.tolist()
    while len(layout) < k:
        adds = feas.additions(layout)
        if len(adds) == 0:
            return None
        if hasattr(crit, "bound_additions"):
            # The same addition as judging all of them exactly, pruned by lower bounds.
            bounds = crit.bound_additions(np.array(layout, dtype=int))[adds]
            found, _ = _pruned_argmin(
                crit, adds, bounds,
                lambda part, layout=layout: np.array([layout + [int(j)] for j in part]), np.inf)
            if found is not None:
                layout.append(int(adds[found]))
                continue
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


def _search_layouts(crit, feas: _Feasibility, k: int, weights: np.ndarray, limit: int):
    """The best layout found and its exact cost, with the greedy layout and the enumeration.

    Returns ``(layout, cost, greedy, brute)``: ``greedy`` is None when the greedy step
    stalled, ``brute`` the enumerated optimum ``(layout, cost)`` or None when ``limit`` is 0 or
    there are more than ``limit`` feasible layouts.
    """
    # Integer layouts: rounding and greedy, each improved by exact swaps; the better wins.
    starts = []
    rounded = _round(weights, feas, k)
    if rounded is not None:
        starts.append(rounded)
    greedy = _greedy(crit, feas, k)
    if greedy is not None:
        starts.append(greedy)
    # Every feasible layout, when there are few enough (limit): the exact optimum.
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
    return best_layout, best_cost, greedy, brute
