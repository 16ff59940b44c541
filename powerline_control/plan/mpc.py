"""Receding-horizon (MPC) motion planning toward a target that moves when the wind changes.

:class:`MotionPlanner` re-plans every control period over a horizon that ends at rest inside the
free interval, warm-started from the closed-form move or its previous solution, within an
iteration limit (and a time budget when the user sets one); when a solve fails it brakes to a
safe stop and says so in its :class:`MPCStep`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .._validation import check_array, check_budget, check_choice, check_int, check_real
from ..errors import InputError
from .closed_form import Trajectory, _sample_pieces, _time_optimal_pieces
from .free_space import (
    _GEOMETRY_TOL,
    _check_position,
    _check_span_length,
    _check_start_free,
    _free_interval,
    _push_out_of_obstacles,
    check_obstacles,
)
from .limits import RobotLimits, _check_limits
from .nlp import (
    _FAR,
    _IPOPT_QUIET,
    _acceleration_energy,
    _add_dynamics_and_limits,
    _new_program,
    _position_points,
    _Program,
    _Scale,
    _set_limits,
    _solve,
    _trajectory_from,
)

# A receding-horizon state whose speed (or acceleration) exceeds its limit by at most this
# fraction is clipped to the limit (tracking and integration errors), not reported as infeasible.
_STATE_CLIP_RTOL = 1e-3
# Tolerance on a given state's position (m): IPOPT meets constraints to about 1e-8.
_STATE_TOL = 1e-6
# Soft margin of receding-horizon plans from the position bounds, as a fraction of the planner's
# tolerance, and the weight of its violation (an exact penalty: larger than any multiplier).
_MARGIN_FRACTION = 0.1
_SLACK_WEIGHT = 1e3


def _track_program(
    n: int, order: int, time_budget: float | None, max_iter: int, warm: bool
) -> _Program:
    """Receding-horizon tracking: fixed step, approach the target, end the horizon at rest."""
    opti, states, inputs, params = _new_program(n, order)
    params["target"] = opti.parameter()
    params["dt"] = opti.parameter()
    params["scale"] = opti.parameter()
    params["rho"] = opti.parameter()
    params["tolerance"] = opti.parameter()
    params["margin"] = opti.parameter()
    h = params["dt"]
    _add_dynamics_and_limits(opti, states, inputs, h, params, order)
    opti.subject_to(states[:, 0] == params["start"])
    # Ending the horizon at rest is what makes braking always possible (recursive feasibility).
    opti.subject_to(states[1, -1] == 0)
    if order == 3:
        opti.subject_to(states[2, -1] == 0)
    error = (states[0, 1:] - params["target"]) / params["scale"]
    effort = _acceleration_energy(states, inputs, h, order) / (params["a_max"] ** 2 * n * h)
    # Pseudo-Huber distance (L1 beyond ~1 mm): unlike a squared error it gives no incentive to
    # rush at the target and overshoot it.
    soft = params["tolerance"] / params["scale"]
    # Plans keep a small margin from the position bounds as a *soft* constraint (exact L1
    # penalty on one slack), on top of the hard bounds.  Without it, plans that brake as late as
    # possible leave the next state exactly on the edge of the feasible set, and a 1e-8 deviation
    # of the real state makes IPOPT report an infeasible problem.
    slack = opti.variable()
    opti.subject_to(slack >= 0)
    margin = params["margin"]
    for point in _position_points(states, h, order):
        opti.subject_to(point >= params["low"] + margin - slack)
        opti.subject_to(point <= params["high"] - margin + slack)
    opti.minimize(
        ca.sum2(ca.sqrt(error**2 + soft**2) - soft) / n
        + params["rho"] * effort
        + _SLACK_WEIGHT * slack / params["scale"]
    )
    # Adaptive barrier updates: measured 9 instead of 13 iterations cold, and 4 instead of 10
    # warm, along the benchmark's closed loop.
    # An iteration limit, never a clock, unless the user asks for one: a result must not depend
    # on how busy the machine is.
    options = {**_IPOPT_QUIET, "ipopt.max_iter": max_iter, "ipopt.mu_strategy": "adaptive"}
    if time_budget is not None:
        options["ipopt.max_wall_time"] = time_budget
    if warm:
        # Start from the shifted previous solution and its multipliers, close to the boundary.
        options.update(
            {
                "ipopt.warm_start_init_point": "yes",
                "ipopt.warm_start_bound_push": 1e-6,
                "ipopt.warm_start_mult_bound_push": 1e-6,
                "ipopt.mu_init": 1e-4,
            }
        )
    opti.solver("ipopt", options)
    duration = ca.MX(n) * h
    return _Program(opti, order, n, states, inputs, duration, params)


@dataclass(frozen=True, eq=False)
class MPCStep:
    """The outcome of one receding-horizon step.

    Attributes
    ----------
    acceleration : float
        Acceleration to apply at the start of the next control period, m/s^2 (constant over the
        period without a jerk limit).
    jerk : float or None
        Jerk to apply over the next period, m/s^3, with a jerk limit; None otherwise.
    next_state : tuple of float
        Predicted (position, velocity[, acceleration]) after one control period under the command,
        integrated exactly.
    status : str
        ``"optimal"`` (a solve succeeded), ``"at_target"`` (at rest at the target: hold, no solve)
        or ``"safe_stop"`` (the solve failed, reached its iteration limit or the time budget the
        user set: braking to rest instead).
    fallback : bool
        True when the command is the safe-stop fallback rather than an optimal plan.
    target : float
        The target actually tracked: the requested one, moved to the nearest reachable position
        when it lies in an obstacle or beyond one.
    target_clamped : bool
        True when ``target`` differs from the requested target.
    plan : Trajectory or None
        The horizon plan when a solve succeeded.
    solve_time : float
        Wall-clock time of the step, s (information only: no result depends on it unless a
        ``time_budget`` was set).
    within_budget : bool
        Whether ``solve_time`` stayed within the planner's ``time_budget`` (True without one).
    iterations : int
        IPOPT iterations (0 without a solve).
    message : str
        Human-readable account of the step (the solver status on a fallback).
    guess : str
        Initial guess of the solve: ``"closed_form"`` (the time-optimal move from the current
        state), ``"previous"`` (the previous plan shifted by one period) or ``"none"``.

    Examples
    --------
    >>> planner = MotionPlanner(RobotLimits(v_max=0.5, a_max=1.0), dt=0.05)
    >>> step = planner.step((0.0, 0.0), target=1.0)
    >>> step.status, step.fallback, [round(v, 5) for v in step.next_state]
    ('optimal', False, [0.00125, 0.05])
    """

    acceleration: float
    jerk: float | None
    next_state: tuple[float, ...]
    status: str
    fallback: bool
    target: float
    target_clamped: bool
    plan: Trajectory | None
    solve_time: float
    within_budget: bool
    iterations: int
    message: str
    guess: str = "none"


class MotionPlanner:
    """Receding-horizon (MPC) motion planner that follows a moving antinode.

    Each :meth:`step` solves, from the robot's current state, a plan over ``horizon`` control
    periods that approaches the target as fast as the limits allow (least distance to the
    target, lightly penalised acceleration) and ends the horizon at rest inside the free interval;
    the first period of that plan is the command.  Because every plan can stop, braking is always
    possible: when a solve fails (or reaches its iteration limit, or a time budget the user set),
    the step brakes to rest at ``a_max`` (the *safe stop*) and reports ``status="safe_stop"``.

    Each solve starts from the closed-form time-optimal move from the current state to the
    target (bang-coast-bang; the S-curve from rest with a jerk limit), sampled on the horizon:
    close to the tracking optimum and valid at once when the target jumps, which a shifted
    previous plan is not (``warm_start="previous"`` keeps that older scheme, with the previous
    multipliers).  Results depend only on the inputs: IPOPT stops on an iteration limit, and
    a wall-clock budget applies only when ``time_budget`` is given.

    Parameters
    ----------
    limits : RobotLimits
        Robot limits and length.
    dt : float
        Control period, s (> 0); also the step of the horizon plans.
    horizon : int
        Number of control periods in a plan (>= 2).  ``horizon * dt`` must exceed the braking time
        ``v_max / a_max`` (plus ``a_max / j_max`` with a jerk limit).
    span_length : float or None
        Span length, m (hard limits for the robot's body), or None.
    obstacles : sequence of (left, right)
        Intervals, m, the robot may neither enter nor cross.
    time_budget : float or None
        Wall-clock time allowed per solve, s (IPOPT is stopped after it), or None (default): no
        clock, only ``max_iter``.  With a budget the results depend on the machine's load.
    effort_weight : float
        Weight of the (normalised) squared acceleration against the (normalised) squared
        distance to the target (>= 0); small values give nearly time-optimal motion.
    tolerance : float
        Position (m) and speed (m/s) within which the robot counts as at rest at the target.
    max_iter : int
        IPOPT iterations allowed per solve (>= 1); a solve that needs more brakes instead.
    warm_start : {"closed_form", "previous", "none"}
        Initial guess of each solve (see above).
    memory_budget : float or None
        Bytes the two horizon programs may take (about 16 KB per horizon step), or None for the
        package default (4 GiB, or the environment variable POWERLINE_CONTROL_MEMORY_BUDGET).

    Raises
    ------
    InputError
        If an argument has no meaning or the horizon is too short to brake from ``v_max``.

    Examples
    --------
    >>> planner = MotionPlanner(RobotLimits(v_max=0.5, a_max=1.0), dt=0.05, span_length=3.66)
    >>> step = planner.step((0.5, 0.0), target=2.0)
    >>> step.status, round(step.acceleration, 3), step.guess
    ('optimal', 1.0, 'closed_form')
    """

    def __init__(
        self,
        limits: RobotLimits,
        *,
        dt: float = 0.05,
        horizon: int = 40,
        span_length: float | None = None,
        obstacles: Sequence[tuple[float, float]] = (),
        time_budget: float | None = None,
        effort_weight: float = 1e-3,
        tolerance: float = 1e-3,
        max_iter: int = 200,
        warm_start: str = "closed_form",
        memory_budget: float | None = None,
    ) -> None:
        _check_limits(limits)
        self.limits = limits
        self.dt = check_real("dt", dt, low=0.0)
        self.horizon = check_int("horizon", horizon, low=2)
        braking_time = limits.v_max / limits.a_max
        if limits.j_max is not None:
            braking_time += limits.a_max / limits.j_max
        if self.horizon * self.dt <= braking_time:
            raise InputError(
                f"The 'horizon' parameter must make horizon * dt exceed the braking time "
                f"{braking_time:g} s (v_max / a_max{' + a_max / j_max' if limits.j_max else ''}) "
                f"so that every plan can stop. Got horizon={self.horizon}, dt={self.dt:g} s."
            )
        if span_length is not None:
            span_length = _check_span_length(span_length, limits)
        self.span_length = span_length
        self.obstacles = tuple(check_obstacles(obstacles, span_length))
        self.time_budget = (
            None if time_budget is None else check_real("time_budget", time_budget, low=0.0)
        )
        self.effort_weight = check_real(
            "effort_weight", effort_weight, low=0.0, low_inclusive=True
        )
        self.tolerance = check_real("tolerance", tolerance, low=0.0)
        self.max_iter = check_int("max_iter", max_iter, low=1)
        self.warm_start = check_choice(
            "warm_start", warm_start, ("closed_form", "previous", "none")
        )
        if memory_budget is not None:
            memory_budget = check_real("memory_budget", memory_budget, low=0.0)
        self._scale = _Scale.of(limits)
        order = limits.order
        # CasADi's two programs take ~16 KB per horizon step (measured: 31 MB at horizon 2000):
        # refuse before building them (horizon=10**7 ended in std::bad_alloc).
        check_budget("MotionPlanner's two horizon programs", nbytes=16e3 * self.horizon,
                     parameter="horizon", value=self.horizon,
                     fix="use a shorter horizon (a few braking times: horizon * dt of seconds)",
                     memory_budget=memory_budget)
        self._cold = _track_program(self.horizon, order, self.time_budget, self.max_iter, False)
        self._warm = _track_program(self.horizon, order, self.time_budget, self.max_iter, True)
        self._previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.n_fallbacks = 0
        self.n_steps = 0

    def reset(self) -> None:
        """Forget the previous solution: the next step is solved cold."""
        self._previous = None

    def step(self, state: Sequence[float], target: float) -> MPCStep:
        """Re-plan from ``state`` toward ``target`` and return the command for the next period.

        Parameters
        ----------
        state : sequence of float
            ``(position, velocity)`` of the robot's centre, plus ``acceleration`` with a jerk
            limit; m, m/s, m/s^2.
        target : float
            Where the robot should go (e.g. the nearest antinode), m.

        Returns
        -------
        MPCStep
            Command, predicted next state, status (``"optimal"``, ``"at_target"`` or
            ``"safe_stop"``) and timing.

        Raises
        ------
        InputError
            If the state has the wrong length, is not finite, or puts the robot outside the span
            or in an obstacle, or the target lies outside the span or is not finite.

        Examples
        --------
        >>> planner = MotionPlanner(RobotLimits(v_max=0.5, a_max=1.0), span_length=3.66)
        >>> planner.step((1.0, 0.0), target=1.0).status
        'at_target'
        """
        started = time.perf_counter()
        order = self.limits.order
        state_array = check_array("state", state, shape=(order,))
        position, velocity = float(state_array[0]), float(state_array[1])
        acceleration = float(state_array[2]) if order == 3 else 0.0
        position = _check_position("state[0]", position, self.span_length)
        target = _check_position("target", target, self.span_length)
        obstacles = list(self.obstacles)
        # A measured (or previously planned) state may sit a hair outside the free interval or
        # above v_max after tracking errors: accept it within _STATE_TOL (_STATE_CLIP_RTOL) and
        # hand the solver the nearest admissible state.
        _check_start_free(position, self.limits.length, self.span_length, obstacles, _STATE_TOL)
        low, high, _, _ = _free_interval(position, self.limits.length, self.span_length, obstacles)
        state_array = state_array.copy()
        state_array[0] = min(max(position, low), high)
        if abs(velocity) <= self.limits.v_max * (1 + _STATE_CLIP_RTOL):
            state_array[1] = min(max(velocity, -self.limits.v_max), self.limits.v_max)
        if order == 3 and abs(acceleration) <= self.limits.a_max * (1 + _STATE_CLIP_RTOL):
            state_array[2] = min(max(acceleration, -self.limits.a_max), self.limits.a_max)
        tracked = min(max(target, low), high)
        tracked = _push_out_of_obstacles(tracked, position, self.limits.length, obstacles)
        clamped = abs(tracked - target) > _GEOMETRY_TOL
        self.n_steps += 1

        if (
            abs(position - tracked) <= self.tolerance
            and abs(velocity) <= self.tolerance
            and abs(acceleration) <= self.tolerance * self.limits.a_max
        ):
            self._previous = None
            return self._hold(state_array, tracked, clamped, started)

        use_previous = self.warm_start == "previous" and self._previous is not None
        program = self._warm if self._previous is not None and self.warm_start != "none" \
            else self._cold
        scale = self._scale
        with program.lock:
            opti, params = program.opti, program.params
            _set_limits(program, self.limits, low, high, scale)
            opti.set_value(params["start"], scale.state(state_array))
            opti.set_value(params["target"], scale.position(tracked))
            opti.set_value(params["dt"], self.dt / scale.time)
            normaliser = max(self.limits.v_max * self.dt * self.horizon, self.tolerance)
            opti.set_value(params["scale"], normaliser / scale.length)
            opti.set_value(params["rho"], self.effort_weight)
            opti.set_value(params["tolerance"], self.tolerance / scale.length)
            opti.set_value(params["margin"], _MARGIN_FRACTION * self.tolerance / scale.length)
            guess = self._set_guess(program, state_array, tracked, use_previous, (low, high))
            solution, stats, _ = _solve(program)
            if solution is not None:
                plan = _trajectory_from(
                    program, solution, stats, 0.0, "track", self.limits, (low, high), scale
                )
                inputs = plan.acceleration[:-1] if order == 2 else plan.jerk
                lam_g = np.atleast_1d(solution.value(opti.lam_g))
                self._previous = (_plan_states(plan, order), inputs, lam_g)
        elapsed = time.perf_counter() - started
        if solution is None:
            self._previous = None
            self.n_fallbacks += 1
            return self._safe_stop(state_array, tracked, clamped, elapsed, stats, guess)
        first_acc = float(plan.acceleration[0])
        first_jerk = float(plan.jerk[0]) if plan.jerk is not None else None
        next_state = tuple(float(value) for value in _plan_states(plan, order)[:, 1])
        return MPCStep(
            acceleration=first_acc,
            jerk=first_jerk,
            next_state=next_state,
            status="optimal",
            fallback=False,
            target=tracked,
            target_clamped=clamped,
            plan=plan,
            solve_time=elapsed,
            within_budget=self._within_budget(elapsed),
            iterations=int(stats.get("iter_count", 0)),
            message=f"IPOPT: {stats.get('return_status', '')}",
            guess=guess,
        )

    # -- helpers -------------------------------------------------------------------------------

    def _within_budget(self, elapsed: float) -> bool:
        return self.time_budget is None or elapsed <= self.time_budget

    def _set_guess(
        self,
        program: _Program,
        state: np.ndarray,
        target: float,
        use_previous: bool,
        bounds: tuple[float, float],
    ) -> str:
        """Set the solver's initial guess (scaled); return which one it is."""
        n, opti, scale, order = program.n, program.opti, self._scale, program.order
        pieces = None
        if self.warm_start == "closed_form" and (
            order == 2 or (state[1] == 0.0 and state[2] == 0.0)
        ):
            pieces = _time_optimal_pieces(state[0], target, state[1], self.limits)
        # With a jerk limit the closed form starts at rest; moving, the shifted previous plan is
        # the next best guess.
        if use_previous or (pieces is None and program is self._warm):
            states, inputs, lam_g = self._previous
            # Shift by one period; the previous plan ends at rest, so repeating its end is valid.
            guess = np.hstack([states[:, 1:], states[:, -1:]])
            guess[:, 0] = state
            opti.set_initial(program.states, _scale_columns(scale, guess))
            shifted = np.append(inputs[1:], 0.0)
            opti.set_initial(program.inputs, scale.derivative(shifted, order).reshape(1, n))
            opti.set_initial(opti.lam_g, lam_g)
            return "previous"
        if pieces:
            times = self.dt * np.arange(n + 1)
            guess = _sample_pieces(state[:order], pieces, times, order)
            guess[:, 0] = state
            if order == 2:  # the mean acceleration over each period
                inputs = np.diff(guess[1]) / self.dt
            else:
                inputs = np.diff(guess[2]) / self.dt
            # The time-optimal move may leave the free interval (a turn near an obstacle): a
            # guess need not be feasible, but keep it inside.
            guess[0] = np.clip(guess[0], max(bounds[0], -_FAR), min(bounds[1], _FAR))
            label = "closed_form"
        else:
            guess = np.zeros((order, n + 1))
            guess[0] = state[0]
            guess[:, 0] = state
            inputs = np.zeros(n)
            label = "none"
        opti.set_initial(program.states, _scale_columns(scale, guess))
        opti.set_initial(program.inputs, scale.derivative(inputs, order).reshape(1, n))
        if program is self._warm:  # the previous multipliers: the active set changes little
            opti.set_initial(opti.lam_g, self._previous[2])
        return label

    def _hold(
        self, state: np.ndarray, target: float, clamped: bool, started: float
    ) -> MPCStep:
        elapsed = time.perf_counter() - started
        return MPCStep(
            acceleration=0.0,
            jerk=0.0 if self.limits.order == 3 else None,
            next_state=(float(state[0]), 0.0) + ((0.0,) if self.limits.order == 3 else ()),
            status="at_target",
            fallback=False,
            target=target,
            target_clamped=clamped,
            plan=None,
            solve_time=elapsed,
            within_budget=self._within_budget(elapsed),
            iterations=0,
            message="At rest at the target: holding.",
        )

    def _safe_stop(
        self,
        state: np.ndarray,
        target: float,
        clamped: bool,
        elapsed: float,
        stats: dict,
        guess: str,
    ) -> MPCStep:
        position, velocity = float(state[0]), float(state[1])
        dt, a_max = self.dt, self.limits.a_max
        # Brake at a_max, but no harder than stopping exactly at the end of the period: the
        # velocity must not reverse.
        acc = -math.copysign(min(a_max, abs(velocity) / dt), velocity) if velocity else 0.0
        next_state: tuple[float, ...] = (
            position + velocity * dt + acc * dt**2 / 2,
            velocity + acc * dt,
        )
        jerk = None
        note = ""
        if self.limits.order == 3:
            jerk = 0.0
            next_state = next_state + (acc,)
            note = (
                " The emergency stop ignores j_max (the acceleration steps to the braking value)."
            )
        return MPCStep(
            acceleration=acc,
            jerk=jerk,
            next_state=next_state,
            status="safe_stop",
            fallback=True,
            target=target,
            target_clamped=clamped,
            plan=None,
            solve_time=elapsed,
            within_budget=self._within_budget(elapsed),
            iterations=int(stats.get("iter_count", 0)),
            message=(
                f"Solve failed ({stats.get('return_status', 'unknown')}; iteration limit "
                f"{self.max_iter}, time budget {self.time_budget}): braking to a safe stop "
                f"at a_max={a_max:g} m/s^2.{note}"
            ),
            guess=guess,
        )


def _scale_columns(scale: _Scale, states: np.ndarray) -> np.ndarray:
    """Scale a (order, n) array of physical states column by column."""
    out = states / scale.length * scale.time ** np.arange(states.shape[0])[:, None]
    out[0] = (states[0] - scale.origin) / scale.length
    return out


def _plan_states(plan: Trajectory, order: int) -> np.ndarray:
    """Stack a plan's state samples, shape (order, n + 1)."""
    rows = [plan.position, plan.velocity] + ([plan.acceleration] if order == 3 else [])
    return np.vstack(rows)
