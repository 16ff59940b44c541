"""Loads on the span: a harmonic point force, aeolian (vortex-shedding) lift, random forcing.

Every load is separable, ``F(x, t) = spatial(x) * values(t)``: :meth:`load_vector` gives the
consistent FE load vector of the spatial part on a :class:`~powerline_control.fem.LineModel`,
:meth:`values` the time history in newtons (or N/m for distributed loads). ``frequency`` (Hz) is set
for harmonic loads, which :func:`~powerline_control.simulation.simulate` then integrates exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._constants import AIR_DENSITY, STROUHAL
from ._validation import check_array, check_budget, check_int, check_real
from .errors import InputError
from .fem import LineModel
from .line import Conductor

__all__ = ["HarmonicForce", "AeolianForce", "RandomForce", "DEFAULT_STROUHAL",
           "strouhal_frequency"]

#: Strouhal number of a stranded conductor (PLP's f = 3.26 V/d in mph and inches is St = 0.185).
DEFAULT_STROUHAL = STROUHAL


def strouhal_frequency(wind_speed: float, diameter: float,
                       strouhal: float = DEFAULT_STROUHAL) -> float:
    """Vortex-shedding frequency f = St V / d, Hz.

    Parameters
    ----------
    wind_speed : float
        m/s (> 0).
    diameter : float
        Conductor diameter, m (> 0).
    strouhal : float
        Strouhal number (default 0.185, PLP's 3.26 V/d in mph and inches).

    Returns
    -------
    float
        Shedding frequency, Hz.

    Examples
    --------
    >>> round(strouhal_frequency(1.0, 0.0105), 2)     # the paper's 10.5 mm conductor
    17.62
    """
    speed = check_real("wind_speed", wind_speed, low=0.0)
    d = check_real("diameter", diameter, low=0.0)
    st = check_real("strouhal", strouhal, low=0.0, high=1.0)
    return st * speed / d


@dataclass(frozen=True)
class HarmonicForce:
    """Point force ``amplitude * sin(2 pi frequency t + phase)`` at ``position`` (paper eq. 2).

    Parameters
    ----------
    amplitude : float
        f0, N (> 0).
    frequency : float
        Hz (> 0).
    position : float
        m from the left support (checked against the span when used).
    phase : float
        rad.

    Examples
    --------
    >>> force = HarmonicForce(amplitude=2.0, frequency=1.0, position=0.5)
    >>> force.values(np.array([0.0, 0.25])).round(12)
    array([0., 2.])
    """

    amplitude: float
    frequency: float
    position: float
    phase: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", check_real("amplitude", self.amplitude, low=0.0))
        object.__setattr__(self, "frequency", check_real("frequency", self.frequency, low=0.0))
        object.__setattr__(self, "position", check_real("position", self.position, low=0.0,
                                                        low_inclusive=True))
        object.__setattr__(self, "phase", check_real("phase", self.phase))

    def values(self, t: np.ndarray) -> np.ndarray:
        """Force at times ``t`` (s), N."""
        t = check_array("t", t, ndim=1)
        return self.amplitude * np.sin(2 * np.pi * self.frequency * t + self.phase)

    def load_vector(self, model: LineModel) -> np.ndarray:
        """Consistent load vector of a unit force at ``position``."""
        return model.point_load(self.position)


@dataclass(frozen=True)
class AeolianForce:
    """Vortex-shedding lift in lock-in with the span's standing wave.

    Frequency from the Strouhal relation f = St V / d. The lift per metre has amplitude
    ``0.5 rho V^2 d C_L`` (C_L: fluctuating lift coefficient, about 0.2-0.4 for a cylinder at
    these Reynolds numbers; default 0.3). In lock-in the shedding is correlated along each vibration
    loop and alternates in sign from loop to loop, so the load is distributed as
    ``sin(k x + k_offset)`` with k the wavenumber of the taut beam at f
    (m omega^2 = EI k^4 + T k^2). This is the simplest load that feeds the resonant loop pattern;
    richer wake-oscillator models are not implemented.

    Its amplitude is fixed: it does not follow the vibration, so a line damped by a fixed modal
    ratio does not settle where the energy balance says (on real spans it stays one to two
    orders of magnitude below it over a minute). For the self-limiting vibration, the wind power
    of the energy balance at the current amplitude on a line damped by the conductor's
    self-damping, use :func:`powerline_control.severity.simulate_aeolian`.

    Parameters
    ----------
    wind_speed : float
        m/s (> 0); aeolian vibration occurs at about 1-7 m/s.
    strouhal : float
        Strouhal number (default 0.185).
    lift_coefficient : float
        C_L (default 0.3).
    air_density : float
        kg/m^3 (default 1.225).
    correlated : bool
        True (default): lock-in pattern sin(k x); False: uniform lift along the span.

    Examples
    --------
    >>> from powerline_control import Span
    >>> force = AeolianForce(wind_speed=1.0)
    >>> round(force.frequency_for(Span.paper_lab().conductor), 2)
    17.62
    """

    wind_speed: float
    strouhal: float = DEFAULT_STROUHAL
    lift_coefficient: float = 0.3
    air_density: float = AIR_DENSITY
    correlated: bool = True
    position: float | None = field(default=None, repr=False)   # distributed: no single point

    def __post_init__(self) -> None:
        check_real("wind_speed", self.wind_speed, low=0.0)
        check_real("strouhal", self.strouhal, low=0.0, high=1.0)
        check_real("lift_coefficient", self.lift_coefficient, low=0.0)
        check_real("air_density", self.air_density, low=0.0)
        if self.position is not None:
            # The lift is distributed along the span: a point would be silently ignored.
            raise InputError(
                "The 'position' parameter of an AeolianForce must be None: the lift acts along "
                f"the whole span (got {self.position!r:.40}). Use HarmonicForce for a point load."
            )
        if not isinstance(self.correlated, bool | np.bool_):
            # 'no' or 0.0 would be truthy or silently cast: a flag must be a bool.
            raise InputError(
                "The 'correlated' parameter must be True or False. Got "
                f"{self.correlated!r} of type {type(self.correlated).__name__}."
            )

    def frequency_for(self, conductor: Conductor) -> float:
        """Shedding frequency on ``conductor``, Hz."""
        return strouhal_frequency(self.wind_speed, conductor.diameter, self.strouhal)

    def lift_per_length(self, conductor: Conductor) -> float:
        """Lift amplitude per metre, N/m."""
        return 0.5 * self.air_density * self.wind_speed**2 * conductor.diameter \
            * self.lift_coefficient

    def bind(self, model: LineModel) -> BoundAeolianForce:
        """The force on a particular span: frequency and load pattern become concrete."""
        cond = model.span.conductor
        frequency = self.frequency_for(cond)
        # m omega^2 = EI k^4 + T k^2 (Span.wavenumber; the string limit when EI = 0)
        wavenumber = float(model.span.wavenumber(frequency))
        q = self.lift_per_length(cond)
        if self.correlated:
            load = model.distributed_load(lambda x: q * np.sin(wavenumber * x))
        else:
            load = model.distributed_load(lambda x: q * np.ones_like(x))
        return BoundAeolianForce(frequency=frequency, wavenumber=wavenumber, load=load)


@dataclass(frozen=True, eq=False)
class BoundAeolianForce:
    """An :class:`AeolianForce` applied to one model (see :meth:`AeolianForce.bind`)."""

    frequency: float
    wavenumber: float
    load: np.ndarray = field(repr=False)
    position: float | None = None

    def values(self, t: np.ndarray) -> np.ndarray:
        """Time factor sin(2 pi f t) (the load vector carries the newtons)."""
        return np.sin(2 * np.pi * self.frequency * np.asarray(t, dtype=float))

    def load_vector(self, model: LineModel) -> np.ndarray:
        """The consistent load vector computed at binding."""
        return self.load


@dataclass(frozen=True)
class RandomForce:
    """Seeded broadband random point force: Gaussian, band-limited to ``bandwidth`` Hz.

    White Gaussian samples on a grid of spacing 1 / (2.5 bandwidth) are joined by Catmull-Rom
    cubic interpolation, which keeps the spectrum essentially below ``bandwidth``; ``std`` is the
    standard deviation of the grid samples. The same seed gives the same force for any query times.

    Parameters
    ----------
    std : float
        Standard deviation of the force, N (> 0).
    position : float
        m from the left support.
    bandwidth : float
        Highest frequency of the force, Hz (default 200).
    seed : int
        Seed of the random sequence.

    Examples
    --------
    >>> force = RandomForce(std=1.0, position=0.5, bandwidth=50.0, seed=0)
    >>> bool(np.allclose(force.values(np.linspace(0, 1, 5)), force.values(np.linspace(0, 1, 5))))
    True
    """

    std: float
    position: float
    bandwidth: float = 200.0
    seed: int = 0
    frequency: None = field(default=None, init=False)

    def __post_init__(self) -> None:
        check_real("std", self.std, low=0.0)
        check_real("position", self.position, low=0.0, low_inclusive=True)
        check_real("bandwidth", self.bandwidth, low=0.0)
        # An int, not a Generator: values(t) must give the same force on every call (a
        # Generator would advance, None would draw fresh entropy each time).
        check_int("seed", self.seed, low=0)

    def values(self, t: np.ndarray) -> np.ndarray:
        """Force at times ``t`` (s, >= 0), N."""
        t = check_array("t", t, ndim=1)
        if t.size == 0:
            return t.copy()
        spacing = 1.0 / (2.5 * self.bandwidth)
        # The knots run from t = 0 to max(t): refuse before drawing a huge sequence.
        n_knots_estimate = float(np.max(t)) / spacing + 3
        check_budget("RandomForce's knot sequence", nbytes=16.0 * n_knots_estimate,
                     parameter="bandwidth", value=self.bandwidth,
                     fix="lower the bandwidth or evaluate at earlier times")
        position = np.maximum(t, 0.0) / spacing + 1.0       # knot 0 is a guard before t = 0
        n_knots = int(np.floor(position.max())) + 3
        # A prefix of a Generator's normal stream does not depend on how many are drawn, and
        # Catmull-Rom interpolation is local: the value at t never depends on the query range.
        knots = self.std * np.random.default_rng(self.seed).standard_normal(n_knots)
        k = np.floor(position).astype(int)
        s = position - k
        p0, p1, p2, p3 = knots[k - 1], knots[k], knots[k + 1], knots[k + 2]
        return 0.5 * (2 * p1 + (p2 - p0) * s + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s**2
                      + (3 * p1 - p0 - 3 * p2 + p3) * s**3)

    def load_vector(self, model: LineModel) -> np.ndarray:
        """Consistent load vector of a unit force at ``position``."""
        return model.point_load(self.position)
