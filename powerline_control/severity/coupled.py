"""The energy balance with the line and the robot coupled (:func:`coupled_balance`): the steady
vibration as a limit cycle of the line's plant damped by the energy balance's own powers
(:mod:`.modal` derives it), beside the first-order damper power's amplitude.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from .._validation import check_real
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL
from ..fem import MDR, AtAntinode
from ..line import Span
from ._common import MAX_WIND_SPEED, _check_span
from .balance import aeolian_severity
from .modal import CoupledBalance, coupled_cycle, coupled_robot
from .self_damping import FotiMartinelli
from .wind import SelfDampingLaw

__all__ = ["coupled_balance"]

def coupled_balance(
    span: Span,
    wind_speed: float,
    robot: MDR | AtAntinode | None = None,
    *,
    bc: str = "clamped",
    n_elements: int | None = None,
    strouhal: float = DEFAULT_STROUHAL,
    wind_curve: str = "cigre",
    turbulence_intensity: float = 0.0,
    self_damping: str | SelfDampingLaw | FotiMartinelli = "noiseux1991",
    self_damping_k: float | None = None,
    self_damping_exponents: Sequence[float] | None = None,
) -> CoupledBalance:
    """The energy balance's steady amplitude with the robot coupled to the line.

    The plant is :func:`simulate_aeolian`'s (the FE line's modes near the tone, the robot's
    Ritz vector, the robot parked), damped by the energy balance's own powers at the vibration's
    amplitudes (:class:`AeolianDamping`). The steady amplitude is the locked mode's amplitude at
    which the coupled mode the wind feeds has a zero real part (Brent's method on its logarithm;
    at each trial the shape is iterated so that every mode's self-damping is at its own
    amplitude). That mode's shape gives the field, its frequency the vibration's, and its powers
    the balance (module doc).

    Parameters
    ----------
    span : Span
        The line.
    wind_speed : float
        m/s, in (0, 30].
    robot : MDR, AtAntinode or None
        An MDR is parked at its ``position``; ``AtAntinode(robot)`` at the antinode of the
        locked mode nearest the robot's position (its ``factor`` must be 1: the coupled model
        places the robot, it does not scale its power); None: the bare line.
    bc : {"clamped", "pinned"}
        Supports.
    n_elements : int or None
        FE mesh (None: the mesh that resolves the aeolian band).
    strouhal, wind_curve, turbulence_intensity, self_damping, self_damping_k, \
self_damping_exponents
        As in :func:`aeolian_severity`.

    Returns
    -------
    CoupledBalance

    Raises
    ------
    InputError
        For bad arguments, a robot that is not an MDR (an ``ImpedanceDamper`` has no FE model),
        or a limit cycle whose shape does not converge.

    Examples
    --------
    >>> from powerline_control import MDR, Span
    >>> from powerline_control.fem import AtAntinode
    >>> span = Span.at_rts_fraction(60.0, "drake", 0.2)
    >>> robot = MDR.tuned(30.0, 0.5, 0.3, frequency=19.7, damping_ratio=0.2)
    >>> balance = coupled_balance(span, 3.0, AtAntinode(robot), bc="pinned")
    >>> balance.amplitude > balance.first_order_amplitude    # the robot reshapes the wave
    True
    """
    span = _check_span(span)
    speed = check_real("wind_speed", wind_speed, low=0.0, high=MAX_WIND_SPEED)
    device = coupled_robot(robot, "robot", "park an MDR at the position you mean, or use "
                           "aeolian_severity for other dampers")
    if device is not None and not 0 <= device.position <= span.length:
        raise InputError(f"The 'robot' position must lie in [0, {span.length:g}] m (the span). "
                         f"Got {device.position!r}.")
    balance = coupled_cycle(
        span, speed, robot, bc=bc, n_elements=n_elements, strouhal=strouhal,
        wind_curve=wind_curve, turbulence_intensity=turbulence_intensity,
        self_damping=self_damping, self_damping_k=self_damping_k,
        self_damping_exponents=self_damping_exponents)
    parked = () if balance.robot_position is None else (
        dataclasses.replace(device, position=balance.robot_position),)
    first_order = aeolian_severity(
        span, [speed], parked, strouhal=strouhal, bc=bc, wind_curve=wind_curve,
        turbulence_intensity=turbulence_intensity, self_damping=self_damping,
        self_damping_k=self_damping_k, self_damping_exponents=self_damping_exponents)
    return dataclasses.replace(balance, first_order_amplitude=float(first_order.amplitude[0]))
