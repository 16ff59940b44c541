"""Closed-form time-optimal moves of the robot along the line, and the planned motion itself.

A move is a list of pieces ``(duration, value)`` over which the highest derivative is constant:
the acceleration of a double integrator (bang-coast-bang), the jerk of a triple integrator (the
seven-segment S-curve from rest); the pieces come from :mod:`~powerline_control.plan.kernels`.
These are exact, take microseconds and are the same on any machine; :class:`Trajectory` holds a
sampled motion, whichever way it was computed, with the exact polynomials between its samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._results import TabularResult
from .._validation import check_array, read_only
from .kernels import _advance, _bang_coast_bang, _s_curve
from .limits import RobotLimits


@dataclass(frozen=True, eq=False)
class Trajectory(TabularResult):
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
    >>> from powerline_control.plan import RobotLimits, plan_motion
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

    def summary(self) -> str:
        """The move in a few lines: from where to where, how long, how fast.

        Returns
        -------
        str

        Examples
        --------
        >>> from powerline_control.plan import RobotLimits, plan_motion
        >>> print(plan_motion(0.0, 2.0, RobotLimits(v_max=0.5, a_max=1.0)).summary())
        move: 0 m to 2 m
        duration: 4.5 s (closed_form, objective time)
        peak speed: 0.5 m/s (v_max 0.5 m/s)
        peak acceleration: 1 m/s^2 (a_max 1 m/s^2)
        samples: 101
        """
        return "\n".join([
            f"move: {self.position[0]:.4g} m to {self.position[-1]:.4g} m",
            f"duration: {self.duration:.4g} s ({self.method}, objective {self.objective})",
            f"peak speed: {np.abs(self.velocity).max():.4g} m/s (v_max {self.limits.v_max:g} m/s)",
            f"peak acceleration: {np.abs(self.acceleration).max():.4g} m/s^2 "
            f"(a_max {self.limits.a_max:g} m/s^2)",
            f"samples: {self.t.size}",
        ])

    def table(self) -> list[dict]:
        """One row per sample: time (s), position (m), velocity (m/s), acceleration (m/s^2).

        Returns
        -------
        list of dict

        Examples
        --------
        >>> from powerline_control.plan import RobotLimits, plan_motion
        >>> plan_motion(0.0, 2.0, RobotLimits(v_max=0.5, a_max=1.0)).table()[-1]
        {'t_s': 4.5, 'position_m': 2.0, 'velocity_m_s': 0.0, 'acceleration_m_s2': 0.0}
        """
        return [{"t_s": float(t), "position_m": float(x), "velocity_m_s": float(v),
                 "acceleration_m_s2": float(a)}
                for t, x, v, a in zip(self.t, self.position, self.velocity, self.acceleration,
                                      strict=True)]

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
        >>> from powerline_control.plan import RobotLimits, plan_motion
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
