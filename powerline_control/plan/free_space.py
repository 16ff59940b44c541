"""Free space of the robot between the span ends and the obstacles, and the one obstacle rule.

The robot's *centre* is at ``position`` and its body occupies ``[position - length/2, position +
length/2]``; it must stay inside the span and out of the obstacles (clamps, spacers, other
dampers), which it can neither enter nor cross.  So the positions it can reach from where it is
form one free interval (:func:`free_interval`): its body may touch a span end or an obstacle but
not enter it.  Every planner and the closed loop use these checks, never a copy of them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .._validation import check_real
from ..errors import InputError, PlanningError
from .limits import RobotLimits, _check_limits

# Positions closer than this (metres) are treated as equal when testing contact with obstacles.
_GEOMETRY_TOL = 1e-9


def check_obstacles(
    obstacles: Sequence[tuple[float, float]], span_length: float | None
) -> list[tuple[float, float]]:
    """The obstacles as the package reads them: (left, right) pairs in metres, sorted.

    The one obstacle rule (the planners, :func:`free_interval` and the closed loop all read
    obstacles through it): each is a pair of finite numbers with ``left <= right`` (a point
    obstacle, such as a spacer's clamp, has ``left == right``) that meets the span
    ``[0, span_length]``. The robot's body may touch an obstacle but not enter it
    (:func:`free_interval`).

    Parameters
    ----------
    obstacles : sequence of (left, right)
        Intervals, m; ``()`` for none.
    span_length : float or None
        Span length, m (None: no span to meet).

    Returns
    -------
    list of (float, float)
        The obstacles, sorted by their left ends.

    Raises
    ------
    InputError
        If ``obstacles`` is not a sequence of pairs, a pair is not finite, has ``right < left``
        or misses the span; the message names the pair's index.

    Examples
    --------
    >>> check_obstacles([(2.0, 2.1), (0.5, 0.5)], 3.66)
    [(0.5, 0.5), (2.0, 2.1)]
    """
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
    _check_limits(limits)
    span_length = _check_span_length(span_length, limits)
    position = check_real("position", position, low=0.0, high=span_length, low_inclusive=True)
    checked = check_obstacles(obstacles, span_length)
    _check_start_free(position, limits.length, span_length, checked)
    low, high, _, _ = _free_interval(position, limits.length, span_length, checked)
    return low, high


def _check_span_length(span_length: object, limits: RobotLimits) -> float:
    """A span length, m, that the robot's body fits in."""
    span_length = check_real("span_length", span_length, low=0.0)
    if limits.length > span_length:
        raise InputError(
            f"The robot length {limits.length:g} m (limits.length) must not exceed the "
            f"span_length {span_length:g} m."
        )
    return span_length


def _obstacle_containing(
    centre: float, half: float, obstacles: list[tuple[float, float]], tol: float
) -> tuple[float, float] | None:
    """The obstacle the robot's body (half-length ``half``) enters at ``centre``, or None.

    The one margin rule: the body may touch an obstacle, within ``tol``, but not enter it.
    """
    for left, right in obstacles:
        if left - half + tol < centre < right + half - tol:
            return left, right
    return None


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
    hit = _obstacle_containing(start, half, obstacles, tol)
    if hit is not None:
        left, right = hit
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
    hit = _obstacle_containing(target, half, obstacles, _GEOMETRY_TOL)
    if hit is not None:
        left, right = hit
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


def _push_out_of_obstacles(
    target: float, position: float, length: float, obstacles: list[tuple[float, float]]
) -> float:
    """Move a target inside an (inflated) obstacle to the obstacle's side facing the robot."""
    half = length / 2
    hit = _obstacle_containing(target, half, obstacles, 0.0)
    if hit is None:
        return target
    left, right = hit
    return left - half if position <= left - half + _GEOMETRY_TOL else right + half
