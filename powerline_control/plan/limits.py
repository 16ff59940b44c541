"""The robot's kinematic limits and size, and the checks of a given state against them.

:class:`RobotLimits` holds the speed, acceleration and optional jerk limits of the mobile damping
robot and the length of its body; with a jerk limit the robot is a triple integrator, without one
a double integrator.  Its rest-to-rest time is the closed-form time-optimal move's
(:mod:`~powerline_control.plan.closed_form`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import check_real
from ..errors import InputError
from .kernels import _bang_coast_bang, _s_curve

# Relative slack on limits when checking a *given* state (a measured velocity a hair above v_max
# after round-off is not an error).
_STATE_RTOL = 1e-6


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


def _check_limits(limits: object) -> None:
    if not isinstance(limits, RobotLimits):
        raise InputError(
            f"The 'limits' parameter must be a RobotLimits. Got {type(limits).__name__} instead."
        )


def _check_velocity_state(start_velocity: float, end_velocity: float, limits: RobotLimits) -> None:
    for name, value in (("start_velocity", start_velocity), ("end_velocity", end_velocity)):
        if abs(value) > limits.v_max * (1 + _STATE_RTOL):
            # Bad input, not an infeasible plan: no robot can start (or end) above its limit.
            raise InputError(
                f"The {name!r} parameter ({value:g} m/s) exceeds the speed limit "
                f"v_max={limits.v_max:g} m/s."
            )
