"""Motion planning of the mobile damping robot (MDR) along the span, with CasADi.

The robot is a point mass on a line (a double integrator, or a triple integrator when a jerk
limit is given) whose *centre* is at ``position``; its body occupies
``[position - length/2, position + length/2]``.  It must stay inside the span and out of the
obstacles (clamps, spacers, other dampers), which it can neither enter nor cross.  So the
positions it can reach from where it is form one free interval, and planning is a box-bounded
optimal control problem on that interval.

Discretisation (exact, not Euler): the highest derivative is piecewise constant over ``n_intervals``
equal intervals, so the lower derivatives are polynomials in time.  The limits are imposed on the
Bernstein control points of those polynomials, and a polynomial lies in the convex hull of its
Bernstein control points: the limits therefore hold *between* samples too, not only at them.

* :func:`plan_motion` solves one plan: minimum time, or minimum energy (the integral of the squared
  acceleration) in a given time.
* :class:`MotionPlanner` re-plans on a receding horizon (MPC) toward a target that moves when the
  wind changes, warm-started from its previous solution, within a per-step time budget, and brakes
  to a safe stop (and says so) when a solve fails.

The nonlinear programs are built once (CasADi ``Opti`` with IPOPT) and re-solved with new parameter
values, which is what makes a solve take milliseconds rather than the ~100 ms of building one.
"""

from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .._validation import (
    check_array,
    check_budget,
    check_choice,
    check_int,
    check_real,
    read_only,
)
from ..errors import InputError, PlanningError

__all__ = ["RobotLimits", "Trajectory", "free_interval", "plan_motion", "MotionPlanner", "MPCStep"]

_IPOPT_QUIET = {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes"}
# Positions closer than this (metres) are treated as equal when testing contact with obstacles.
_GEOMETRY_TOL = 1e-9
# Relative slack on limits when checking a *given* state (a measured velocity a hair above v_max
# after round-off is not an error).
_STATE_RTOL = 1e-6
# A receding-horizon state whose speed (or acceleration) exceeds its limit by at most this
# fraction is clipped to the limit (tracking and integration errors), not reported as infeasible.
_STATE_CLIP_RTOL = 1e-3
# Tolerance on a given state's position (m): IPOPT meets constraints to about 1e-8.
_STATE_TOL = 1e-6
# Soft margin of receding-horizon plans from the position bounds, as a fraction of the planner's
# tolerance, and the weight of its violation (an exact penalty: larger than any multiplier).
_MARGIN_FRACTION = 0.1
_SLACK_WEIGHT = 1e3
# Stand-in for an infinite position bound (no span ends), m.
_FAR = 1e7


# ----------------------------------------------------------------------------------------------
# Limits and results
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RobotLimits:
    """Kinematic limits and size of the mobile damping robot.

    Parameters
    ----------
    v_max : float
        Largest speed along the line, m/s (> 0).
    a_max : float
        Largest acceleration magnitude, m/s^2 (> 0).
    j_max : float or None
        Largest jerk magnitude, m/s^3 (> 0), or None for no jerk limit (acceleration may jump).
    length : float
        Length of the robot's body along the line, m (>= 0).  The body is centred on the planned
        position and must stay inside the span and out of the obstacles.

    Raises
    ------
    InputError
        If a limit is not a positive finite number or the length is negative.

    Examples
    --------
    >>> limits = RobotLimits(v_max=0.5, a_max=1.0, length=0.3)
    >>> limits.stopping_distance(0.5)
    0.125
    """

    v_max: float
    a_max: float
    j_max: float | None = None
    length: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "v_max", check_real("v_max", self.v_max, low=0.0))
        object.__setattr__(self, "a_max", check_real("a_max", self.a_max, low=0.0))
        if self.j_max is not None:
            object.__setattr__(self, "j_max", check_real("j_max", self.j_max, low=0.0))
        object.__setattr__(
            self, "length", check_real("length", self.length, low=0.0, low_inclusive=True)
        )

    @property
    def order(self) -> int:
        """2 for a double integrator (acceleration is the input), 3 with a jerk limit."""
        return 2 if self.j_max is None else 3

    def stopping_distance(self, velocity: float) -> float:
        """Distance needed to brake from ``velocity`` to rest at ``a_max`` (jerk limit ignored).

        Parameters
        ----------
        velocity : float
            Current velocity, m/s.

        Returns
        -------
        float
            ``velocity**2 / (2 a_max)``, metres.
        """
        velocity = check_real("velocity", velocity)
        distance = velocity * velocity / (2.0 * self.a_max)
        if not np.isfinite(distance):  # |velocity| ~ 1e300: v^2 overflows
            raise InputError(f"The 'velocity' parameter is too large: {velocity!r} m/s squared "
                             "overflows.")
        return distance

    def rest_to_rest_time(self, distance: float) -> float:
        """Minimum time (s) to move ``distance`` m from rest to rest within these limits.

        The closed-form time-optimal move: bang-coast-bang, T = d / v + v / a (or 2 sqrt(d / a)
        when v_max is not reached), or with a jerk limit the seven-segment S-curve,
        T = d / v + v / a + a / j when both v_max and a_max are reached.

        Parameters
        ----------
        distance : float
            Length of the move, m (its sign is ignored).

        Returns
        -------
        float
            Seconds.

        Examples
        --------
        >>> RobotLimits(v_max=0.5, a_max=1.0).rest_to_rest_time(2.0)
        4.5
        >>> RobotLimits(v_max=0.5, a_max=1.0, j_max=2.0).rest_to_rest_time(2.0)
        5.0
        """
        d = abs(check_real("distance", distance))
        if self.j_max is None:
            pieces = _bang_coast_bang(d, 0.0, self.v_max, self.a_max)
        else:
            pieces = _s_curve(d, self.v_max, self.a_max, self.j_max)
        return float(sum(duration for duration, _ in pieces))


@dataclass(frozen=True)
class Trajectory:
    """A planned motion of the robot's centre.

    The highest derivative is constant on each interval ``[t[k], t[k+1])``: the acceleration
    for a double integrator, the jerk when a jerk limit is set.  :meth:`sample` evaluates the exact
    polynomials between the samples.

    Attributes
    ----------
    t : ndarray, shape (n + 1,)
        Sample times, s, from 0 to ``duration``.
    position, velocity : ndarray, shape (n + 1,)
        Robot centre position (m, from the left support) and velocity (m/s) at ``t``.
    acceleration : ndarray, shape (n + 1,)
        Acceleration, m/s^2.  Without a jerk limit, ``acceleration[k]`` holds on
        ``[t[k], t[k+1])`` and the last entry is 0 (the robot ends the plan at its final velocity,
        usually at rest).  With a jerk limit it is the continuous acceleration at ``t``.
    jerk : ndarray, shape (n,), or None
        Jerk on each interval, m/s^3, when the plan is jerk-limited; None otherwise.
    duration : float
        Total time, s.
    energy : float
        Integral of the squared acceleration over the plan, m^2/s^3 (the "energy" objective).
    objective : str
        ``"time"`` or ``"energy"`` (or ``"track"`` for a receding-horizon plan).
    limits : RobotLimits
        The limits the plan respects.
    bounds : tuple of float
        The free interval ``(low, high)`` of the robot's centre between the obstacles and span ends.
    iterations : int
        IPOPT iterations used (0 when no solve was needed).
    solve_time : float
        Wall-clock time of the solve, s (information only: no result depends on it).
    method : str
        ``"closed_form"`` (the exact time-optimal move), ``"ipopt"`` (the discretised nonlinear
        program) or ``"none"`` (no motion needed).

    Examples
    --------
    >>> traj = plan_motion(0.0, 2.0, RobotLimits(v_max=0.5, a_max=1.0))
    >>> round(traj.duration, 3), traj.t.shape, round(float(traj.velocity.max()), 3)
    (4.5, (101,), 0.5)
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray | None
    duration: float
    energy: float
    objective: str
    limits: RobotLimits
    bounds: tuple[float, float]
    iterations: int = 0
    solve_time: float = 0.0
    method: str = "ipopt"

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact position, velocity and acceleration at any times in ``[0, duration]``.

        Parameters
        ----------
        t : float or array_like
            Times, s; values outside ``[0, duration]`` are clipped to it (the robot is at its
            start state before and its end state after).

        Returns
        -------
        position, velocity, acceleration : ndarray
            Arrays of the shape of ``t``.

        Examples
        --------
        >>> traj = plan_motion(0.0, 1.0, RobotLimits(v_max=1.0, a_max=1.0))
        >>> float(np.round(traj.sample(traj.duration / 2)[0], 6))
        0.5
        """
        requested = check_array("t", t, ndim=(0, 1))
        times = np.clip(requested, 0.0, self.duration)
        if self.t.size == 1:
            zeros = np.zeros_like(times)
            return zeros + self.position[0], zeros + self.velocity[0], zeros
        k = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, self.t.size - 2)
        tau = times - self.t[k]
        p, v, a = self.position[k], self.velocity[k], self.acceleration[k]
        j = self.jerk[k] if self.jerk is not None else 0.0
        position = p + v * tau + a * tau**2 / 2 + j * tau**3 / 6
        velocity = v + a * tau + j * tau**2 / 2
        # Before the start and after the end the robot holds its state: no acceleration.
        outside = (requested < 0.0) | (requested > self.duration)
        acceleration = np.where(outside, 0.0, a + j * tau)
        return position, velocity, acceleration


# ----------------------------------------------------------------------------------------------
# Geometry: the free interval between obstacles
# ----------------------------------------------------------------------------------------------


def _check_obstacles(
    obstacles: Sequence[tuple[float, float]], span_length: float | None
) -> list[tuple[float, float]]:
    if isinstance(obstacles, str | bytes) or not isinstance(obstacles, Sequence | np.ndarray):
        raise InputError(
            "The 'obstacles' parameter must be a sequence of (left, right) pairs in metres "
            f"(() for none). Got {obstacles!r:.60} of type {type(obstacles).__name__}."
        )
    checked = []
    for i, item in enumerate(obstacles):
        try:
            left, right = item
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"The 'obstacles' parameter must be a sequence of (left, right) pairs in metres. "
                f"Got {item!r} at index {i} instead."
            ) from exc
        left = check_real(f"obstacles[{i}][0]", left)
        right = check_real(f"obstacles[{i}][1]", right)
        if right < left:
            raise InputError(
                f"The 'obstacles' parameter must hold intervals with left <= right. "
                f"Got ({left!r}, {right!r}) at index {i} instead."
            )
        if span_length is not None and (right < 0.0 or left > span_length):
            raise InputError(
                f"The 'obstacles' parameter must hold intervals that meet the span [0, "
                f"{span_length:g}] m. Got ({left!r}, {right!r}) at index {i} instead."
            )
        checked.append((left, right))
    return sorted(checked)


def _free_interval(
    start: float,
    length: float,
    span_length: float | None,
    obstacles: list[tuple[float, float]],
) -> tuple[float, float, str, str]:
    """Free interval of the robot's centre containing ``start``, and what bounds each side.

    The start must already be known to be free.  Returns ``(low, high, low_reason, high_reason)``.
    """
    half = length / 2
    low, low_reason = (-math.inf, "none") if span_length is None else (half, "the left span end")
    high, high_reason = (
        (math.inf, "none") if span_length is None else (span_length - half, "the right span end")
    )
    for left, right in obstacles:
        # The start is free, so the obstacle's centre tells on which side of the robot it lies.
        if start >= (left + right) / 2:
            if right + half > low:
                low, low_reason = right + half, f"the obstacle ({left:g}, {right:g}) m"
        elif left - half < high:
            high, high_reason = left - half, f"the obstacle ({left:g}, {right:g}) m"
    return low, high, low_reason, high_reason


def free_interval(
    position: float,
    limits: RobotLimits,
    span_length: float,
    obstacles: Sequence[tuple[float, float]] = (),
) -> tuple[float, float]:
    """Where the robot's centre may go from ``position`` without its body leaving the span or
    entering or crossing an obstacle.

    The one rule of the package: the body (``limits.length``, centred on the position) may touch
    a span end or an obstacle (``<=``) but not enter it; :func:`plan_motion` and
    :class:`MotionPlanner` plan inside this interval.

    Parameters
    ----------
    position : float
        The robot's centre now, m from the left support (its body must be free there).
    limits : RobotLimits
        Its limits; ``limits.length`` is the body length, m.
    span_length : float
        Span length, m.
    obstacles : sequence of (left, right)
        Intervals, m, the robot may neither enter nor cross.

    Returns
    -------
    (low, high) : tuple of float
        Bounds of the robot's centre, m.

    Raises
    ------
    InputError
        If the body does not fit at ``position`` (inside an obstacle or off the span), or an
        argument has no meaning.

    Examples
    --------
    >>> free_interval(1.0, RobotLimits(v_max=0.5, a_max=1.0, length=0.2), 3.66, [(2.0, 2.1)])
    (0.1, 1.9)
    """
    if not isinstance(limits, RobotLimits):
        raise InputError(
            f"The 'limits' parameter must be a RobotLimits. Got {type(limits).__name__} instead."
        )
    span_length = check_real("span_length", span_length, low=0.0)
    if limits.length > span_length:
        raise InputError(
            f"The robot length {limits.length:g} m (limits.length) must not exceed the "
            f"span_length {span_length:g} m."
        )
    position = check_real("position", position, low=0.0, high=span_length, low_inclusive=True)
    checked = _check_obstacles(obstacles, span_length)
    _check_start_free(position, limits.length, span_length, checked)
    low, high, _, _ = _free_interval(position, limits.length, span_length, checked)
    return low, high


def _check_position(name: str, value: object, span_length: float | None) -> float:
    if span_length is None:
        return check_real(name, value)
    return check_real(name, value, low=0.0, high=span_length, low_inclusive=True)


def _check_start_free(
    start: float,
    length: float,
    span_length: float | None,
    obstacles: list[tuple[float, float]],
    tol: float = _GEOMETRY_TOL,
) -> None:
    half = length / 2
    if span_length is not None and (start < half - tol or start > span_length - half + tol):
        raise InputError(
            f"The 'start' parameter must leave the robot (length {length:g} m) inside the span "
            f"[0, {span_length:g}] m, i.e. lie in [{half:g}, {span_length - half:g}]. "
            f"Got {start!r} instead."
        )
    for left, right in obstacles:
        if left - half + tol < start < right + half - tol:
            raise InputError(
                f"The 'start' parameter puts the robot (length {length:g} m) inside the obstacle "
                f"({left:g}, {right:g}) m: its centre must be <= {left - half:g} or "
                f">= {right + half:g}. Got {start!r} instead."
            )


def _check_target_reachable(
    target: float,
    start: float,
    length: float,
    obstacles: list[tuple[float, float]],
    interval: tuple[float, float, str, str],
) -> None:
    half = length / 2
    for left, right in obstacles:
        if left - half + _GEOMETRY_TOL < target < right + half - _GEOMETRY_TOL:
            raise PlanningError(
                f"The target {target:g} m puts the robot (length {length:g} m) inside the "
                f"obstacle ({left:g}, {right:g}) m; the nearest positions it can take are "
                f"{left - half:g} m and {right + half:g} m."
            )
    low, high, low_reason, high_reason = interval
    if target < low - _GEOMETRY_TOL:
        raise PlanningError(
            f"The target {target:g} m cannot be reached from {start:g} m: {low_reason} limits "
            f"the robot's centre (length {length:g} m) to >= {low:g} m, and the robot cannot "
            "cross obstacles."
        )
    if target > high + _GEOMETRY_TOL:
        raise PlanningError(
            f"The target {target:g} m cannot be reached from {start:g} m: {high_reason} limits "
            f"the robot's centre (length {length:g} m) to <= {high:g} m, and the robot cannot "
            "cross obstacles."
        )


# ----------------------------------------------------------------------------------------------
# The 1-D time-optimal move in closed form
# ----------------------------------------------------------------------------------------------
# A move is a list of pieces (duration, value) over which the highest derivative is constant: the
# acceleration of a double integrator, the jerk of a triple integrator.


def _bang_coast_bang(
    distance: float, v0: float, v_max: float, a_max: float
) -> list[tuple[float, float]]:
    """Time-optimal pieces of a double integrator from speed ``v0`` to rest ``distance`` away.

    Pontryagin: bang-bang in the acceleration with at most one switch, plus a coast at v_max
    when that speed is reached.  If the robot cannot stop before the target (or moves away from
    it), the first bang brakes and turns it round; mirroring the problem reduces that case to
    the forward one.  Forward: accelerate at a_max from v0 to the peak speed
    v_p = sqrt(a d + v0^2 / 2) (the two bangs together cover d), brake at a_max to rest; if
    v_p > v_max, coast at v_max in between.  From rest: T = d / v + v / a, or 2 sqrt(d / a).
    """
    sign = 1.0
    if distance - v0 * abs(v0) / (2.0 * a_max) < 0.0:
        sign, distance, v0 = -1.0, -distance, -v0
    peak = math.sqrt(max(a_max * distance + v0 * v0 / 2.0, 0.0))
    if peak <= v_max:
        pieces = [((peak - v0) / a_max, sign * a_max), (peak / a_max, -sign * a_max)]
    else:
        cruise = distance - (v_max**2 - v0**2) / (2.0 * a_max) - v_max**2 / (2.0 * a_max)
        pieces = [
            ((v_max - v0) / a_max, sign * a_max),
            (max(cruise, 0.0) / v_max, 0.0),
            (v_max / a_max, -sign * a_max),
        ]
    return [(duration, value) for duration, value in pieces if duration > 0.0]


def _s_curve(
    distance: float, v_max: float, a_max: float, j_max: float
) -> list[tuple[float, float]]:
    """Time-optimal jerk pieces of a triple integrator from rest to rest ``distance`` away.

    The seven-segment S-curve: a speed ramp (jerk +j, hold a_max, jerk -j; or +j, -j when a_max
    is not reached, i.e. for a peak speed below a_max^2 / j_max), a coast, the mirrored ramp.
    A ramp to speed v lasts v / a + a / j (or 2 sqrt(v / j)) and covers v times half that, by
    symmetry.  The peak speed is v_max if the two ramps fit in the distance; otherwise the
    positive root of v^2 / a + v a / j = d, or v = (d^2 j / 4)^(1/3) when a_max is not reached.
    From rest with both limits reached: T = d / v + v / a + a / j.
    """
    sign = 1.0 if distance >= 0.0 else -1.0
    distance = abs(distance)

    def ramp(speed: float) -> tuple[list[tuple[float, float]], float]:
        if speed >= a_max**2 / j_max:
            tj = a_max / j_max
            pieces = [(tj, j_max), (speed / a_max - tj, 0.0), (tj, -j_max)]
            duration = speed / a_max + tj
        else:
            tj = math.sqrt(speed / j_max)
            pieces = [(tj, j_max), (tj, -j_max)]
            duration = 2.0 * tj
        return pieces, speed * duration / 2.0

    up, ramp_distance = ramp(v_max)
    cruise = 0.0
    if 2.0 * ramp_distance <= distance:
        cruise = (distance - 2.0 * ramp_distance) / v_max
    else:
        ratio = a_max / j_max
        peak = a_max / 2.0 * (-ratio + math.sqrt(ratio**2 + 4.0 * distance / a_max))
        if peak < a_max**2 / j_max:
            peak = (distance * distance * j_max / 4.0) ** (1.0 / 3.0)
        up, _ = ramp(peak)
    pieces = up + [(cruise, 0.0)] + [(duration, -value) for duration, value in up]
    return [(duration, sign * value) for duration, value in pieces if duration > 0.0]


def _advance(state: Sequence[float], value: float, tau: float | np.ndarray, order: int) -> tuple:
    """Exact state after ``tau`` under a constant highest derivative ``value``."""
    if order == 2:
        p, v = state[0], state[1]
        return p + v * tau + value * tau**2 / 2, v + value * tau
    p, v, a = state
    return (
        p + v * tau + a * tau**2 / 2 + value * tau**3 / 6,
        v + a * tau + value * tau**2 / 2,
        a + value * tau,
    )


def _extremes(start: float, v0: float, pieces: list[tuple[float, float]]) -> tuple[float, float]:
    """Smallest and largest position of a double-integrator move (where v = 0 inside a piece)."""
    state = (start, v0)
    low = high = start
    for duration, value in pieces:
        if value != 0.0 and 0.0 < -state[1] / value < duration:
            turn = state[0] - state[1] ** 2 / (2.0 * value)
            low, high = min(low, turn), max(high, turn)
        state = _advance(state, value, duration, 2)
        low, high = min(low, state[0]), max(high, state[0])
    return low, high


def _time_optimal_pieces(
    start: float, target: float, start_velocity: float, limits: RobotLimits
) -> list[tuple[float, float]] | None:
    """The closed-form minimum-time move to rest at ``target``, or None where none is coded
    (a jerk limit with a moving start)."""
    if limits.order == 2:
        return _bang_coast_bang(target - start, start_velocity, limits.v_max, limits.a_max)
    if start_velocity == 0.0:
        return _s_curve(target - start, limits.v_max, limits.a_max, limits.j_max)
    return None


def _split_intervals(durations: list[float], n: int) -> list[int]:
    """Intervals per piece: proportional to its duration (largest remainders), at least one."""
    total = sum(durations)
    shares = [n * d / total for d in durations]
    counts = [max(1, int(math.floor(s))) for s in shares]
    order = sorted(range(len(durations)), key=lambda i: counts[i] - shares[i])
    i = 0
    while sum(counts) < n:
        counts[order[i % len(order)]] += 1
        i += 1
    return counts


def _closed_form_trajectory(
    start: float,
    target: float,
    start_velocity: float,
    pieces: list[tuple[float, float]],
    limits: RobotLimits,
    bounds: tuple[float, float],
    n: int,
) -> Trajectory:
    """Sample a closed-form move on about ``n`` intervals that include every switching time."""
    order = limits.order
    counts = _split_intervals([duration for duration, _ in pieces], n)
    times, states, inputs = [0.0], [(start, start_velocity, 0.0)[:order]], []
    t0, state = 0.0, tuple(states[0])
    for (duration, value), count in zip(pieces, counts, strict=True):
        taus = duration * np.arange(1, count + 1) / count
        values = _advance(state, value, taus, order)
        for k in range(count):
            times.append(t0 + taus[k])
            states.append(tuple(float(v[k]) for v in values))
        inputs += [value] * count
        t0 += duration
        state = _advance(state, value, duration, order)
    samples = np.array(states)
    # The move ends at rest on the target, and its speed (acceleration) peaks exactly at the
    # limit: pin both against round-off.
    samples[-1] = [target] + [0.0] * (order - 1)
    samples[:, 1] = np.clip(samples[:, 1], -limits.v_max, limits.v_max)
    if order == 3:
        samples[:, 2] = np.clip(samples[:, 2], -limits.a_max, limits.a_max)
    inputs_array = np.array(inputs)
    h = np.diff(np.array(times))
    if order == 2:
        acceleration = np.append(inputs_array, 0.0)
        jerk = None
        energy = float(np.sum(inputs_array**2 * h))
    else:
        acceleration = samples[:, 2].copy()
        jerk = inputs_array
        a0, a1 = acceleration[:-1], acceleration[1:]
        energy = float(np.sum(h / 3 * (a0 * a0 + a0 * a1 + a1 * a1)))
    return Trajectory(
        t=read_only(np.array(times)),
        position=read_only(samples[:, 0].copy()),
        velocity=read_only(samples[:, 1].copy()),
        acceleration=read_only(acceleration),
        jerk=None if jerk is None else read_only(jerk),
        duration=float(times[-1]),
        energy=energy,
        objective="time",
        limits=limits,
        bounds=bounds,
        method="closed_form",
    )


def _sample_pieces(
    state: Sequence[float], pieces: list[tuple[float, float]], times: np.ndarray, order: int
) -> np.ndarray:
    """States of a closed-form move at ``times`` (at rest at its end afterwards), (order, n)."""
    out = np.zeros((order, times.size))
    t0, current = 0.0, tuple(state)
    remaining = np.ones(times.size, dtype=bool)
    for duration, value in pieces:
        inside = remaining & (times <= t0 + duration)
        values = _advance(current, value, times[inside] - t0, order)
        for row in range(order):
            out[row, inside] = values[row]
        remaining &= ~inside
        current = _advance(current, value, duration, order)
        t0 += duration
    for row in range(order):
        out[row, remaining] = current[row] if row == 0 else 0.0
    return out


# ----------------------------------------------------------------------------------------------
# Units of the nonlinear programs
# ----------------------------------------------------------------------------------------------


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


# ----------------------------------------------------------------------------------------------
# The nonlinear programs (built once per shape, solved many times)
# ----------------------------------------------------------------------------------------------


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


def _solve(program: _Program) -> tuple[ca.OptiSol | None, dict, float]:
    started = time.perf_counter()
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


# ----------------------------------------------------------------------------------------------
# One plan
# ----------------------------------------------------------------------------------------------


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
    if not isinstance(limits, RobotLimits):
        raise InputError(
            f"The 'limits' parameter must be a RobotLimits. Got {type(limits).__name__} instead."
        )
    objective = check_choice("objective", objective, ("time", "energy"))
    method = check_choice("method", method, ("auto", "closed_form", "ipopt"))
    n = check_int("n_intervals", n_intervals, low=2)
    max_iter = check_int("max_iter", max_iter, low=1)
    if span_length is not None:
        span_length = check_real("span_length", span_length, low=0.0)
        if limits.length > span_length:
            raise InputError(
                f"The robot length {limits.length:g} m (limits.length) must not exceed the "
                f"span_length {span_length:g} m."
            )
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
    obstacles = _check_obstacles(obstacles, span_length)
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


def _check_velocity_state(start_velocity: float, end_velocity: float, limits: RobotLimits) -> None:
    for name, value in (("start_velocity", start_velocity), ("end_velocity", end_velocity)):
        if abs(value) > limits.v_max * (1 + _STATE_RTOL):
            # Bad input, not an infeasible plan: no robot can start (or end) above its limit.
            raise InputError(
                f"The {name!r} parameter ({value:g} m/s) exceeds the speed limit "
                f"v_max={limits.v_max:g} m/s."
            )


def _check_braking(
    start: float, velocity: float, limits: RobotLimits, interval: tuple[float, float, str, str]
) -> None:
    low, high, low_reason, high_reason = interval
    stop = start + math.copysign(limits.stopping_distance(velocity), velocity)
    if stop > high + _GEOMETRY_TOL or stop < low - _GEOMETRY_TOL:
        reason, edge = (high_reason, high) if velocity > 0 else (low_reason, low)
        raise PlanningError(
            f"Moving at {velocity:g} m/s from {start:g} m, the robot needs "
            f"{limits.stopping_distance(velocity):g} m to stop at a_max={limits.a_max:g} m/s^2 "
            f"but {reason} is at {edge:g} m (for its centre)."
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


def _stationary(position: float, limits: RobotLimits, bounds: tuple[float, float]) -> Trajectory:
    one = np.array([0.0])
    return Trajectory(
        t=one.copy(),
        position=np.array([position]),
        velocity=one.copy(),
        acceleration=one.copy(),
        jerk=None if limits.order == 2 else np.zeros(0),
        duration=0.0,
        energy=0.0,
        objective="time",
        limits=limits,
        bounds=bounds,
        method="none",
    )


# ----------------------------------------------------------------------------------------------
# Receding horizon
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
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
        if not isinstance(limits, RobotLimits):
            raise InputError(
                f"The 'limits' parameter must be a RobotLimits. Got {type(limits).__name__} "
                "instead."
            )
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
            span_length = check_real("span_length", span_length, low=0.0)
            if limits.length > span_length:
                raise InputError(
                    f"The robot length {limits.length:g} m (limits.length) must not exceed the "
                    f"span_length {span_length:g} m."
                )
        self.span_length = span_length
        self.obstacles = tuple(_check_obstacles(obstacles, span_length))
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


def _push_out_of_obstacles(
    target: float, position: float, length: float, obstacles: list[tuple[float, float]]
) -> float:
    """Move a target inside an (inflated) obstacle to the obstacle's side facing the robot."""
    half = length / 2
    for left, right in obstacles:
        if left - half < target < right + half:
            return left - half if position <= left - half + _GEOMETRY_TOL else right + half
    return target
