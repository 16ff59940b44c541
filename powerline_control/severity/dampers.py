"""The standing wave (loop length, clamped shape) and dampers on it: the power a damper takes,
the harmonic-mean position; the dampers themselves and their impedance come from fem.damper."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .._validation import (
    check_array,
    check_real,
)
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL
from ..fem import MDR, AtAntinode, ImpedanceDamper, damper_impedance
from ..line import Span
from ._common import (
    _check_frequency,
    _check_span,
    _check_wind_speeds,
    _finite_power,
)

__all__ = [
    "ImpedanceDamper",
    "AtAntinode",
    "damper_impedance",
    "damper_power",
    "standing_wave_shape",
    "loop_length",
    "harmonic_mean_position",
]


# --------------------------------------------------------------------------- the standing wave
# Its home is the span (line.py: Span.loop_length, Span.standing_wave_shape); these two are the
# energy balance's public forms, with its checks of the span and the frequency.
def loop_length(span: Span, frequency: float) -> float:
    """Loop length (half wavelength) pi / beta of the taut beam at ``frequency``, m.

    Parameters
    ----------
    span : Span
        Tension and conductor.
    frequency : float
        Hz (> 0).

    Returns
    -------
    float
        m.

    Examples
    --------
    >>> from powerline_control import Span
    >>> round(loop_length(Span.at_rts_fraction(300.0, "drake", 0.2), 6.57), 3)   # string: 9.98
    9.985
    """
    span = _check_span(span)
    return float(span.loop_length(_check_frequency(frequency)))


def standing_wave_shape(span: Span, frequency: float, position: np.ndarray | float,
                        bc: str = "clamped") -> np.ndarray:
    """Relative amplitude phi(x) of the standing wave at ``position``, |phi| = 1 at antinodes.

    Measured from the nearer support (a node). Pinned: phi = sin(beta d). Clamped: the exact
    shape of a semi-infinite clamped taut beam, (sin beta d - (beta/alpha)(cos beta d -
    exp(-alpha d))) / sqrt(1 + (beta/alpha)^2), whose bending boundary layer (width 1/alpha)
    shifts the nodes slightly away from the clamp.

    Parameters
    ----------
    span : Span
        Length, tension, conductor.
    frequency : float
        Hz (> 0).
    position : float or ndarray
        m from the left support, in [0, L].
    bc : {"clamped", "pinned"}
        Support type.

    Returns
    -------
    ndarray
        phi at each position.

    Examples
    --------
    >>> from powerline_control import Span
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> round(float(standing_wave_shape(span, 6.57, 0.0)), 12)
    0.0
    """
    span = _check_span(span)
    return span.standing_wave_shape(_check_frequency(frequency), position, bc)


# --------------------------------------------------------------------------- dampers
# ImpedanceDamper, AtAntinode and damper_impedance live with the MDR in fem/damper.py (the
# simulation's plant below severity needs the robot's impedance); severity re-exports them.
def _label_of(damper: object) -> str:
    if isinstance(damper, ImpedanceDamper | AtAntinode):
        return damper.label
    return f"MDR at {damper.position:g} m"


def damper_power(damper: MDR | ImpedanceDamper | AtAntinode, span: Span,
                 amplitude: np.ndarray | float, frequency: float, *,
                 bc: str = "clamped") -> np.ndarray:
    """Power per metre of span dissipated by a damper, P_d = 1/2 Re Z omega^2 Y^2 phi(x_s)^2 / L.

    First order in the damper (the standing wave is not perturbed by it): Foti's eq. 2.34 as
    quoted by dohl (``stockbridge.power_foti``); phi^2 is the sin^2 placement factor, 1 at an
    antinode, 0 at a node.

    Parameters
    ----------
    damper : MDR, ImpedanceDamper or AtAntinode
        The device and where it is.
    span : Span
        The span (the power is spread over its length).
    amplitude : float or ndarray
        Antinode amplitude Y, m.
    frequency : float
        Hz.
    bc : {"clamped", "pinned"}
        Supports, for the placement factor.

    Returns
    -------
    ndarray
        W/m.

    Examples
    --------
    >>> from powerline_control import MDR, Span
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> robot = MDR.tuned(150.0, 0.0, 1.0, frequency=20.0, damping_ratio=0.25)
    >>> float(damper_power(AtAntinode(robot), span, 0.001, 20.0)) > 0
    True
    """
    span = _check_span(span)
    frequency = _check_frequency(frequency)
    y = check_array("amplitude", amplitude)
    if isinstance(damper, AtAntinode):
        factor = damper.factor
    else:
        if not isinstance(damper, MDR | ImpedanceDamper):
            raise InputError("The 'damper' parameter must be an MDR, an ImpedanceDamper or an "
                             f"AtAntinode. Got {type(damper).__name__}.")
        if damper.position > span.length:
            raise InputError(f"The damper position must lie in [0, {span.length:g}] m (the "
                             f"span). Got {damper.position!r}.")
        factor = float(standing_wave_shape(span, frequency, damper.position, bc)) ** 2
    omega = 2 * math.pi * frequency
    return _finite_power(0.5 * damper_impedance(damper, frequency).real * omega**2 * y**2
                         * factor / span.length, "damper power")


def harmonic_mean_position(span: Span, wind_speeds: Sequence[float] | np.ndarray = (1.0, 7.0),
                           strouhal: float = DEFAULT_STROUHAL) -> float:
    """Fixed-damper position x* = l_min l_max / (l_min + l_max) for the band of loop lengths.

    It gives the same placement factor |sin(pi x / l)| at both band edges (domain.md 2.4).

    Parameters
    ----------
    span : Span
        The span.
    wind_speeds : sequence of float
        The wind band, m/s (its smallest and largest values are used).
    strouhal : float
        Strouhal number.

    Returns
    -------
    float
        Distance from the support, m.

    Examples
    --------
    >>> from powerline_control import Span
    >>> round(harmonic_mean_position(Span.at_rts_fraction(300.0, "drake", 0.2)), 3)
    1.251
    """
    span = _check_span(span)
    speeds = _check_wind_speeds(wind_speeds)
    st = check_real("strouhal", strouhal, low=0.01, low_inclusive=True, high=1.0)
    d = span.conductor.diameter
    l_max = loop_length(span, st * speeds.min() / d)
    l_min = loop_length(span, st * speeds.max() / d)
    return l_min * l_max / (l_min + l_max)
