"""The convex relaxation of sensor selection and its optimality certificate.

The relaxation is solved with the requested cvxpy solver, then the other installed conic solvers;
the certificate is recomputed from the solver's weights by convexity and an exact LP, so it holds
whatever the solver's accuracy.
"""

from __future__ import annotations

import warnings

import cvxpy as cp
import numpy as np

from .criteria import (
    KalmanCriterion,
    MinEigCriterion,
    Polytope,
    frank_wolfe_bound,
    linear_extreme,
)

_HEURISTIC = "none: heuristic"
_SOLVER_OK = ("optimal", "optimal_inaccurate")
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
        relaxed_cost = float(problem.value) * crit.relaxation_scale + getattr(
            crit, "relaxation_offset", 0.0)
        return (weights, relaxed_cost, name, str(problem.status)), attempts
    return None, attempts


def _feasible_weights(poly: Polytope) -> np.ndarray:
    """A point of the relaxed polytope without a conic solver (an LP vertex, or uniform)."""
    _, vertex = linear_extreme(np.zeros(poly.m), poly)
    if vertex is not None:
        return vertex
    weights = np.full(poly.m, poly.k / poly.m)  # pragma: no cover - the constraints were checked
    return weights


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


def _relax(crit, poly: Polytope, m: int, solver: str):
    """The relaxed weights and the bound they certify, with what each solver did.

    Returns ``(relaxed, weights, relaxed_cost, solver, status, bound_cost, certificate,
    attempts)``; ``relaxed`` is False when every solver failed: the weights are then a feasible
    point and the bound is the solver-free convexity bound from it (or none, heuristic).
    """
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
    return (relaxed is not None, weights, relaxed_cost, used_solver, status, bound_cost,
            certificate, attempts)
