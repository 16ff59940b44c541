"""The motion kernels: closed-form time-optimal moves, in pieces, and their exact states.

A move is a list of pieces ``(duration, value)`` over which the highest derivative is constant:
the acceleration of a double integrator (bang-coast-bang), the jerk of a triple integrator (the
seven-segment S-curve from rest).  These functions know nothing of the robot's limits object or
of a trajectory: :class:`~powerline_control.plan.RobotLimits` (its rest-to-rest time) and
:mod:`~powerline_control.plan.closed_form` (the planned motion) both build on them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


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
