"""One motion plan: the CasADi nonlinear programs and :func:`plan_motion`.

Discretisation (exact, not Euler): the highest derivative is piecewise constant over
``n_intervals`` equal intervals, so the lower derivatives are polynomials in time.  The limits are
imposed on the Bernstein control points of those polynomials, and a polynomial lies in the convex
hull of its Bernstein control points: the limits therefore hold *between* samples too, not only
at them.  The programs are built once (CasADi ``Opti`` with IPOPT) and re-solved with new
parameter values, which is what makes a solve take milliseconds rather than the ~100 ms of
building one; :func:`plan_motion` uses the closed form where it applies and IPOPT otherwise.

Test seam: ``_ctrl_c_after_the_solve``, tested with a real IPOPT solve and a real SIGINT.
"""

from __future__ import annotations

import contextlib
import functools
import math
import signal
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .._validation import check_choice, check_int, check_real, checked_keywords, read_only
from ..errors import InputError, PlanningError
from .closed_form import (
    Trajectory,
    _closed_form_trajectory,
    _stationary,
    _time_optimal_pieces,
)
from .free_space import (
    _GEOMETRY_TOL,
    _check_braking,
    _check_position,
    _check_span_length,
    _check_start_free,
    _check_target_reachable,
    _free_interval,
    check_obstacles,
)
from .kernels import _extremes
from .limits import RobotLimits, _check_limits, _check_velocity_state

_IPOPT_QUIET = {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes"}
# Stand-in for an infinite position bound (no span ends), m.
_FAR = 1e7


@dataclass(frozen=True)
class _Scale:
    """Units for IPOPT: time v_max / a_max, length v_max^2 / a_max, positions from ``origin``.

    IPOPT's tolerances are absolute (1e-8 on the constraints, 1e-8 on the optimality error): in
    these units v_max = a_max = 1 and the tolerances are relative to the limits, whatever their
    size (with metres and seconds, limits of 1e-3 m/s met "to 1e-8" were exceeded 11-fold).
    """

    time: float
    length: float
    origin: float = 0.0

    @classmethod
    def of(cls, limits: RobotLimits, origin: float = 0.0) -> _Scale:
        unit_time = limits.v_max / limits.a_max
        return cls(unit_time, limits.v_max * unit_time, origin)

    def position(self, value: float) -> float:
        return max(min((value - self.origin) / self.length, _FAR), -_FAR)

    def derivative(self, value: float | np.ndarray, order: int) -> float | np.ndarray:
        """A derivative of the position (order 1: velocity, ...) in the scaled units."""
        return value * self.time**order / self.length

    def state(self, state: Sequence[float]) -> np.ndarray:
        return np.array(
            [(state[0] - self.origin) / self.length]
            + [self.derivative(state[i], i) for i in range(1, len(state))]
        )

    def unscale_states(self, states: np.ndarray) -> np.ndarray:
        out = states * self.length / self.time ** np.arange(states.shape[0])[:, None]
        out[0] += self.origin
        return out


@dataclass
class _Program:
    """A CasADi Opti problem with its variables and parameters, reused across solves."""

    opti: ca.Opti
    order: int
    n: int
    states: ca.MX
    inputs: ca.MX
    duration: ca.MX
    params: dict[str, ca.MX]
    lock: threading.Lock = field(default_factory=threading.Lock)


def _add_dynamics_and_limits(
    opti: ca.Opti, states: ca.MX, inputs: ca.MX, h: ca.MX, params: dict[str, ca.MX], order: int
) -> None:
    """Exact integration of a piecewise-constant highest derivative, limits on Bernstein points."""
    p, v = states[0, :], states[1, :]
    lo, hi, vmax, amax = params["low"], params["high"], params["v_max"], params["a_max"]
    p0, v0 = p[:-1], v[:-1]
    if order == 2:
        a0 = inputs
        opti.subject_to(p[1:] == p0 + v0 * h + a0 * h**2 / 2)
        opti.subject_to(v[1:] == v0 + a0 * h)
        opti.subject_to(opti.bounded(-amax, a0, amax))
        opti.subject_to(opti.bounded(-vmax, v, vmax))  # v is linear on each interval
    else:
        a = states[2, :]
        a0, j = a[:-1], inputs
        opti.subject_to(p[1:] == p0 + v0 * h + a0 * h**2 / 2 + j * h**3 / 6)
        opti.subject_to(v[1:] == v0 + a0 * h + j * h**2 / 2)
        opti.subject_to(a[1:] == a0 + j * h)
        opti.subject_to(opti.bounded(-params["j_max"], j, params["j_max"]))
        opti.subject_to(opti.bounded(-amax, a, amax))  # a is linear on each interval
        # v is quadratic: inner Bernstein point v + a h / 2.
        opti.subject_to(opti.bounded(-vmax, v, vmax))
        opti.subject_to(opti.bounded(-vmax, v0 + a0 * h / 2, vmax))
    for point in _position_points(states, h, order):
        opti.subject_to(opti.bounded(lo, point, hi))


def _position_points(states: ca.MX, h: ca.MX, order: int) -> list[ca.MX]:
    """Samples and inner Bernstein control points of the position polynomials.

    Quadratic pieces (order 2): inner point p + v h / 2.  Cubic pieces (order 3): p + v h / 3 and
    p + 2 v h / 3 + a h^2 / 6.  Bounding these bounds the whole piece (convex hull property).
    """
    p, v = states[0, :], states[1, :]
    p0, v0 = p[:-1], v[:-1]
    if order == 2:
        return [p, p0 + v0 * h / 2]
    a0 = states[2, :-1]
    return [p, p0 + v0 * h / 3, p0 + 2 * v0 * h / 3 + a0 * h**2 / 6]


def _acceleration_energy(states: ca.MX, inputs: ca.MX, h: ca.MX, order: int) -> ca.MX:
    """Exact integral of a^2 for piecewise-constant a (order 2) or piecewise-linear a (order 3)."""
    if order == 2:
        return ca.sumsqr(inputs) * h
    a = states[2, :]
    a0, a1 = a[:-1], a[1:]
    return h / 3 * ca.sum2(a0 * a0 + a0 * a1 + a1 * a1)


def _new_program(n: int, order: int) -> tuple[ca.Opti, ca.MX, ca.MX, dict[str, ca.MX]]:
    opti = ca.Opti()
    states = opti.variable(order, n + 1)
    inputs = opti.variable(1, n)
    names = ["low", "high", "v_max", "a_max"] + (["j_max"] if order == 3 else [])
    params = {name: opti.parameter() for name in names}
    params["start"] = opti.parameter(order)
    return opti, states, inputs, params


@functools.lru_cache(maxsize=16)
def _plan_program(n: int, order: int, objective: str, max_iter: int) -> _Program:
    """Plan to a target and end velocity: free duration ("time") or fixed ("energy")."""
    opti, states, inputs, params = _new_program(n, order)
    params["target"] = opti.parameter()
    params["end_velocity"] = opti.parameter()
    params["duration"] = opti.parameter()  # upper bound ("time") or exact value ("energy")
    duration = opti.variable()
    h = duration / n
    _add_dynamics_and_limits(opti, states, inputs, h, params, order)
    opti.subject_to(states[:, 0] == params["start"])
    opti.subject_to(states[0, -1] == params["target"])
    opti.subject_to(states[1, -1] == params["end_velocity"])
    if order == 3:
        opti.subject_to(states[2, -1] == 0)
    if objective == "time":
        opti.subject_to(opti.bounded(1e-6, duration, params["duration"]))
        opti.minimize(duration)
    else:
        opti.subject_to(duration == params["duration"])
        opti.minimize(_acceleration_energy(states, inputs, h, order))
    # Adaptive barrier updates: measured 10-15 iterations on every distance where the monotone
    # default needs up to 80 for short jerk-limited moves.
    opti.solver(
        "ipopt", {**_IPOPT_QUIET, "ipopt.mu_strategy": "adaptive", "ipopt.max_iter": max_iter}
    )
    return _Program(opti, order, n, states, inputs, duration, params)


def _set_limits(
    program: _Program, limits: RobotLimits, low: float, high: float, scale: _Scale
) -> None:
    opti, params = program.opti, program.params
    # CasADi parameters must be finite: "no span" becomes a bound far beyond any real line.
    opti.set_value(params["low"], scale.position(low))
    opti.set_value(params["high"], scale.position(high))
    opti.set_value(params["v_max"], scale.derivative(limits.v_max, 1))
    opti.set_value(params["a_max"], scale.derivative(limits.a_max, 2))
    if program.order == 3:
        opti.set_value(params["j_max"], scale.derivative(limits.j_max, 3))


@contextlib.contextmanager
def _ctrl_c_after_the_solve():
    """Hold a Ctrl-C (SIGINT) that arrives during a CasADi solve until the solve returns, then
    raise it. CasADi turns it into a failed solve ("NonIpopt_Exception_Thrown"), which the
    planner takes for an infeasible program and falls back from, so the user's Ctrl-C was
    lost and the run went on (only in the main thread can a handler be set; elsewhere the
    solve runs as it is)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(frame))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        if callable(previous):
            previous(signal.SIGINT, caught[0])
        elif previous != signal.SIG_IGN:
            raise KeyboardInterrupt


def _solve(program: _Program) -> tuple[ca.OptiSol | None, dict, float]:
    started = time.perf_counter()
    with _ctrl_c_after_the_solve():
        try:
            solution = program.opti.solve_limited()
        except RuntimeError:  # CasADi raises on evaluation errors (NaN in a function, ...)
            solution = None
    elapsed = time.perf_counter() - started
    stats = program.opti.stats()
    if solution is not None and not stats.get("success", False):
        solution = None
    return solution, stats, elapsed


def _trajectory_from(
    program: _Program,
    solution: ca.OptiSol,
    stats: dict,
    elapsed: float,
    objective: str,
    limits: RobotLimits,
    bounds: tuple[float, float],
    scale: _Scale,
) -> Trajectory:
    states = scale.unscale_states(np.atleast_2d(solution.value(program.states)))
    inputs = np.atleast_1d(solution.value(program.inputs)).ravel()
    inputs = inputs * scale.length / scale.time**program.order
    duration = float(solution.value(program.duration)) * scale.time
    n = program.n
    h = duration / n
    if program.order == 2:
        acceleration = np.append(inputs, 0.0)
        jerk = None
        energy = float(np.sum(inputs**2) * h)
    else:
        acceleration = states[2].copy()
        jerk = inputs
        a0, a1 = acceleration[:-1], acceleration[1:]
        energy = float(h / 3 * np.sum(a0 * a0 + a0 * a1 + a1 * a1))
    return Trajectory(
        t=read_only(np.linspace(0.0, duration, n + 1)),
        position=read_only(states[0].copy()),
        velocity=read_only(states[1].copy()),
        acceleration=read_only(acceleration),
        jerk=None if jerk is None else read_only(jerk),
        duration=duration,
        energy=energy,
        objective=objective,
        limits=limits,
        bounds=bounds,
        iterations=int(stats.get("iter_count", 0)),
        solve_time=elapsed,
        method="ipopt",
    )


@checked_keywords
def plan_motion(
    start: float,
    target: float,
    limits: RobotLimits,
    *,
    objective: str = "time",
    duration: float | None = None,
    span_length: float | None = None,
    obstacles: Sequence[tuple[float, float]] = (),
    start_velocity: float = 0.0,
    end_velocity: float = 0.0,
    n_intervals: int = 100,
    method: str = "auto",
    max_iter: int = 3000,
) -> Trajectory:
    """Plan the robot's motion from ``start`` to ``target`` within its limits.

    A minimum-time move that ends at rest is the closed-form time-optimal motion (bang-coast-bang
    for ``v_max`` and ``a_max``; the seven-segment S-curve with a jerk limit, from rest): exact,
    microseconds, and the same on any machine.  Other requests (minimum energy, an end velocity,
    a jerk limit with a moving start) are solved by IPOPT on
    the discretised problem, in units where ``v_max = a_max = 1`` so that its absolute
    tolerances are relative to the limits, and with an iteration limit, not a clock.

    Parameters
    ----------
    start, target : float
        Positions of the robot's centre, m from the left support.
    limits : RobotLimits
        Speed, acceleration, optional jerk limit and robot length.
    objective : {"time", "energy"}
        ``"time"``: the fastest motion (no longer than ``duration`` if given).  ``"energy"``: the
        least integral of squared acceleration for a motion lasting exactly ``duration``.
    duration : float or None
        Time bound, s: required for ``"energy"``, optional upper bound for ``"time"``.
    span_length : float or None
        Span length, m; its ends are hard limits for the robot's body.  None: no span ends.
    obstacles : sequence of (left, right)
        Intervals, m, that no part of the robot may enter or cross (clamps, spacers, dampers).
    start_velocity, end_velocity : float
        Velocities at the start and the end, m/s (default: from rest to rest).  The acceleration
        starts and ends at zero when a jerk limit is set.
    n_intervals : int
        Number of time intervals of the samples (>= 2): of the discretisation for IPOPT; for the
        closed form, the samples include every switching time (at least one interval per piece).
    method : {"auto", "closed_form", "ipopt"}
        ``"auto"``: the closed form where it applies, else IPOPT.  ``"closed_form"``: insist on
        it (an InputError says why it does not apply).  ``"ipopt"``: always the nonlinear program
        (for comparison).
    max_iter : int
        IPOPT iteration limit (>= 1); reaching it raises PlanningError.

    Returns
    -------
    Trajectory
        Samples and the exact piecewise-polynomial motion; the limits hold between samples.
        ``method`` says which way it was computed.

    Raises
    ------
    InputError
        If an argument has no meaning: non-finite numbers, a start or target outside the span, a
        start that puts the robot in an obstacle, ``duration`` missing for ``"energy"``,
        ``method="closed_form"`` where it does not apply, ...
    PlanningError
        If no motion satisfies the limits; the message names the limit: an obstacle or span end
        between start and target, a target inside an obstacle, a ``duration`` shorter than
        ``v_max`` and ``a_max`` allow, a start speed above ``v_max`` or one ``a_max`` cannot brake
        before an obstacle; or if IPOPT fails (with its status).

    Examples
    --------
    >>> limits = RobotLimits(v_max=0.5, a_max=1.0)
    >>> traj = plan_motion(0.2, 1.8, limits, span_length=3.66)
    >>> round(traj.duration, 6), traj.method  # 1.6 m / 0.5 m/s + 0.5 m/s / 1 m/s^2
    (3.7, 'closed_form')
    >>> plan_motion(0.2, 1.8, limits, span_length=3.66, obstacles=[(1.0, 1.1)])
    Traceback (most recent call last):
    ...
    powerline_control.errors.PlanningError: The target 1.8 m cannot be reached from 0.2 m: ...
    """
    _check_limits(limits)
    objective = check_choice("objective", objective, ("time", "energy"))
    method = check_choice("method", method, ("auto", "closed_form", "ipopt"))
    n = check_int("n_intervals", n_intervals, low=2)
    max_iter = check_int("max_iter", max_iter, low=1)
    if span_length is not None:
        span_length = _check_span_length(span_length, limits)
    start = _check_position("start", start, span_length)
    target = _check_position("target", target, span_length)
    start_velocity = check_real("start_velocity", start_velocity)
    end_velocity = check_real("end_velocity", end_velocity)
    if duration is None and objective == "energy":
        raise InputError(
            "The 'duration' parameter is required for objective='energy' (the least energy "
            "motion takes as long as it is allowed to). Got None."
        )
    if duration is not None:
        duration = check_real("duration", duration, low=0.0)
    obstacles = check_obstacles(obstacles, span_length)
    _check_start_free(start, limits.length, span_length, obstacles)
    interval = _free_interval(start, limits.length, span_length, obstacles)
    _check_target_reachable(target, start, limits.length, obstacles, interval)
    low, high = interval[0], interval[1]
    _check_velocity_state(start_velocity, end_velocity, limits)
    _check_braking(start, start_velocity, limits, interval)
    # A measured speed a hair above v_max (round-off) is the limit.
    start_velocity = min(max(start_velocity, -limits.v_max), limits.v_max)
    end_velocity = min(max(end_velocity, -limits.v_max), limits.v_max)

    distance = abs(target - start)
    at_rest = start_velocity == 0.0 and end_velocity == 0.0
    lower_bound = limits.rest_to_rest_time(distance) if at_rest else 0.0
    if duration is not None and duration < lower_bound * (1 - 1e-9):
        active = "a_max" if distance < limits.v_max**2 / limits.a_max else "v_max and a_max"
        jerk = "" if limits.j_max is None else f", j_max={limits.j_max:g} m/s^3"
        raise PlanningError(
            f"The duration {duration:g} s is too short: moving {distance:g} m from rest to rest "
            f"takes at least {lower_bound:.6g} s with {active} (v_max={limits.v_max:g} m/s, "
            f"a_max={limits.a_max:g} m/s^2{jerk}). Allow more time or raise the limits."
        )
    if objective == "time" and at_rest and distance <= _GEOMETRY_TOL:
        return _stationary(start, limits, (low, high))

    if method != "ipopt":
        pieces, reason = _closed_form_request(
            start, target, start_velocity, end_velocity, objective, limits, (low, high)
        )
        if pieces is not None:
            minimum = sum(piece[0] for piece in pieces)
            if duration is not None and minimum > duration * (1 + 1e-12):
                raise PlanningError(
                    f"The duration {duration:g} s is too short: the fastest motion from "
                    f"{start:g} m (at {start_velocity:g} m/s) to rest at {target:g} m takes "
                    f"{minimum:.6g} s with v_max={limits.v_max:g} m/s, a_max={limits.a_max:g} "
                    f"m/s^2, j_max={limits.j_max}. Allow more time or raise the limits."
                )
            return _closed_form_trajectory(
                start, target, start_velocity, pieces, limits, (low, high), n
            )
        if method == "closed_form":
            raise InputError(
                f"The 'method' parameter 'closed_form' does not apply to this request: {reason}. "
                "Use method='auto' (IPOPT where the closed form does not apply) or 'ipopt'."
            )

    return _ipopt_plan(
        start, target, limits, objective, duration, start_velocity, end_velocity, n, max_iter,
        (low, high),
    )


def _closed_form_request(
    start: float,
    target: float,
    start_velocity: float,
    end_velocity: float,
    objective: str,
    limits: RobotLimits,
    bounds: tuple[float, float],
) -> tuple[list[tuple[float, float]] | None, str]:
    """The closed-form pieces for a request, or None and the reason it does not apply."""
    if objective != "time":
        return None, "it is the minimum-time move (objective='time'), not a minimum-energy one"
    if end_velocity != 0.0:
        return None, "the closed form ends at rest (end_velocity=0)"
    pieces = _time_optimal_pieces(start, target, start_velocity, limits)
    if pieces is None:
        return None, "with a jerk limit the closed form (S-curve) starts at rest"
    if limits.order == 2:
        # The first bang brakes at a_max, so a turn goes no further than braking does, which
        # _check_braking has allowed; kept as a guard.
        lowest, highest = _extremes(start, start_velocity, pieces)
        if lowest < bounds[0] - _GEOMETRY_TOL or highest > bounds[1] + _GEOMETRY_TOL:
            return None, (
                "turning round, the time-optimal move would leave the free interval "
                f"[{bounds[0]:g}, {bounds[1]:g}] m"
            )
    return pieces, ""


def _ipopt_plan(
    start: float,
    target: float,
    limits: RobotLimits,
    objective: str,
    duration: float | None,
    start_velocity: float,
    end_velocity: float,
    n: int,
    max_iter: int,
    bounds: tuple[float, float],
) -> Trajectory:
    low, high = bounds
    distance = abs(target - start)
    program = _plan_program(n, limits.order, objective, max_iter)
    speed_time = distance / limits.v_max + limits.v_max / limits.a_max
    if limits.j_max is not None:
        speed_time += limits.a_max / limits.j_max
    if objective == "energy":
        guess_time = duration
    else:
        # Long enough for the quintic guess to respect the limits (its peaks: 1.875 d/T,
        # 5.77 d/T^2 and 60 d/T^3), and for braking from the start velocity.
        guess_time = max(
            speed_time,
            1.875 * distance / limits.v_max,
            math.sqrt(5.774 * distance / limits.a_max),
            0.0 if limits.j_max is None else (60 * distance / limits.j_max) ** (1 / 3),
        ) + abs(start_velocity) / limits.a_max
    bound = duration if duration is not None else 1e3 * (guess_time + limits.v_max / limits.a_max)
    scale = _Scale.of(limits, origin=start)
    start_state = [start, start_velocity] + ([0.0] if limits.order == 3 else [])
    with program.lock:
        opti, params = program.opti, program.params
        _set_limits(program, limits, low, high, scale)
        opti.set_value(params["start"], scale.state(start_state))
        opti.set_value(params["target"], scale.position(target))
        opti.set_value(params["end_velocity"], scale.derivative(end_velocity, 1))
        opti.set_value(params["duration"], bound / scale.time)
        _set_cold_guess(program, scale, start, target, start_velocity, guess_time)
        solution, stats, elapsed = _solve(program)
        if solution is None:
            raise PlanningError(
                f"IPOPT found no {objective}-optimal motion from {start:g} m to {target:g} m "
                f"(status {stats.get('return_status', 'unknown')!r}, iteration limit {max_iter}) "
                f"with v_max={limits.v_max:g} m/s, a_max={limits.a_max:g} m/s^2, "
                f"j_max={limits.j_max}, duration={duration}, free interval [{low:g}, {high:g}] "
                "m. A too-short duration or a start velocity that cannot be braked in time are "
                "the usual causes."
            )
        return _trajectory_from(
            program, solution, stats, elapsed, objective, limits, (low, high), scale
        )


def _set_cold_guess(
    program: _Program,
    scale: _Scale,
    start: float,
    target: float,
    start_velocity: float,
    guess_time: float,
) -> None:
    """Initial guess: the minimum-jerk quintic from start to target (smooth and consistent)."""
    n, opti = program.n, program.opti
    s = np.linspace(0.0, 1.0, n + 1)
    d, T = target - start, guess_time
    guess = np.zeros((program.order, n + 1))
    guess[0] = start + d * (10 * s**3 - 15 * s**4 + 6 * s**5)
    guess[1] = d / T * (30 * s**2 - 60 * s**3 + 30 * s**4)
    guess[1, 0] = start_velocity
    acceleration = d / T**2 * (60 * s - 180 * s**2 + 120 * s**3)
    if program.order == 3:
        guess[2] = acceleration
        inputs = np.diff(acceleration) / (T / n)
    else:
        inputs = (acceleration[:-1] + acceleration[1:]) / 2
    scaled = np.vstack([scale.state(column) for column in guess.T]).T
    opti.set_initial(program.states, scaled)
    opti.set_initial(program.inputs, scale.derivative(inputs, program.order).reshape(1, n))
    opti.set_initial(program.duration, guess_time / scale.time)
