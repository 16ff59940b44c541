"""Aeolian severity of a span by the energy balance method (EBM), and what a damper or the robot
is worth in clamp strain and fatigue.

The steady antinode amplitude ``Y`` (zero-to-peak) at each wind speed solves the power balance per
metre of span (CIGRE TB 273, IEEE PES-TR17, EPRI Orange Book)::

    P_wind(Y, f) = P_self(Y, f, T) + sum over dampers P_damper(Y, f)

with ``f = St V / D`` the Strouhal frequency, ``P_wind = f^3 D^4 F(Y/D)`` (a published wind power
curve), ``P_self = k Y^l f^m / T^n`` (an empirical self-damping law, T in kN) and
``P_damper = 1/2 Re Z(omega) omega^2 Y^2 phi(x_s)^2 / L`` (a damper of mechanical impedance Z at
``x_s``, where the standing wave has relative amplitude ``phi``). The clamp bending amplitude and
stress follow by Poffenberger-Swart (at x_b = 89 mm) and by the f * y_max formula; margins are taken
against the CIGRE/EPRI safe border line and the 150 microstrain peak-to-peak endurance strain.
``docs/severity.md`` derives every formula and lists the sources.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.interpolate
import scipy.optimize

from .._spectral import fit_phasors
from .._validation import (
    check_array,
    check_budget,
    check_choice,
    check_int,
    check_real,
    read_only,
)
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL, AeolianForce
from ..fem import DENSE_EIGEN_LIMIT, MDR, LineModel, ModalDamping
from ..line import Span
from ..plan import RobotLimits
from ..simulate import simulate

__all__ = [
    "WIND_POWER_CURVES",
    "SELF_DAMPING_LAWS",
    "WindPowerCurve",
    "SelfDampingLaw",
    "ImpedanceDamper",
    "AtAntinode",
    "SeverityResult",
    "WindDistribution",
    "RobotValue",
    "TimeDomainCheck",
    "CatenaryCheck",
    "turbulence_factor",
    "wind_power",
    "self_damping_power",
    "damper_impedance",
    "damper_power",
    "standing_wave_shape",
    "loop_length",
    "harmonic_mean_position",
    "OUTER_STRAND_DIAMETER",
    "TB273_UNDAMPED_LIMITS_FROM_MEMORY",
    "aeolian_severity",
    "robot_value",
    "time_domain_check",
    "catenary_check",
]

def _check_text(name: str, value: object) -> str:
    """A label or source: a string (None or a number is a mistake, not a name)."""
    if not isinstance(value, str):
        raise InputError(f"The '{name}' parameter must be a string. Got {value!r:.60} of type "
                         f"{type(value).__name__}.")
    return value


GRAVITY = 9.80665
AIR_DENSITY = 1.225  # kg/m^3, for the lift coefficient of the time-domain check's load
SECONDS_PER_YEAR = 365.25 * 86400.0
#: Young's modulus of the aluminium outer strands, Pa (domain.md 2.6, E_Al).
ALUMINIUM_MODULUS = 68.9e9
#: Poffenberger-Swart measuring point: 89 mm from the last point of contact (IEEE 1966).
POFFENBERGER_SWART_DISTANCE = 0.089
#: Usual laboratory endurance strain, peak-to-peak (Diana et al., IEEE TPWRD 18(4), 2003).
ENDURANCE_STRAIN_PP = 150e-6
#: Outer-strand diameters of the presets, m (stranding in domain.md 2.6 and data/conductors.toml).
OUTER_STRAND_DIAMETER = {
    "drake": 4.44e-3, "condor": 3.08e-3, "cardinal": 3.38e-3, "aster570": 3.45e-3,
    "oxlip": 3.50e-3,
}


# --------------------------------------------------------------------------- wind power input
@dataclass(frozen=True)
class WindPowerCurve:
    """A reduced wind power curve F(a) = P_w / (f^3 D^4), a = Y / D, in W / (m Hz^3 m^4).

    Either the CIGRE cubic (``coefficients``, highest power first) or digitised points
    (``amplitudes``, ``powers``) joined by a shape-preserving (PCHIP) interpolant through the
    origin; a digitised curve is defined only up to its last point.

    Parameters
    ----------
    name : str
        Key in :data:`WIND_POWER_CURVES`.
    label : str
        Authors and year.
    source : str
        Where the numbers come from, and how far they are verified.
    coefficients : tuple of float
        Polynomial coefficients of F(a), highest power first (empty for digitised curves).
    amplitudes, powers : tuple of float
        Digitised points (a, F) of the curve (empty for a polynomial).

    Examples
    --------
    >>> round(float(WIND_POWER_CURVES["cigre"].reduced_power(0.5)), 4)
    13.2457
    """

    name: str
    label: str
    source: str
    coefficients: tuple = ()
    amplitudes: tuple = ()
    powers: tuple = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InputError(f"The 'name' parameter must be a non-empty string. Got {self.name!r}.")
        _check_text("label", self.label)
        _check_text("source", self.source)
        for field_name in ("coefficients", "amplitudes", "powers"):
            if not isinstance(getattr(self, field_name), Sequence | np.ndarray) \
                    or isinstance(getattr(self, field_name), str):
                raise InputError(f"The '{field_name}' parameter must be a sequence of numbers "
                                 f"(empty if unused). Got {getattr(self, field_name)!r:.60}.")
        if len(self.coefficients) == len(self.amplitudes) == 0 or \
                (len(self.coefficients) > 0 and len(self.amplitudes) > 0):
            raise InputError("A WindPowerCurve needs either 'coefficients' (a polynomial) or "
                             "'amplitudes' and 'powers' (digitised points), not both or neither.")
        if self.coefficients:
            check_array("coefficients", self.coefficients, ndim=1)
        else:
            a = check_array("amplitudes", self.amplitudes, ndim=1)
            powers = check_array("powers", self.powers, shape=(a.size,))
            if np.any(powers < 0):
                raise InputError("The 'powers' parameter must be >= 0 (the wind feeds the "
                                 f"vibration). Got min {powers.min():g}.")
            if np.any(np.diff(a) <= 0) or a[0] <= 0:
                raise InputError("The 'amplitudes' parameter must be ascending values > 0 "
                                 f"(reduced amplitudes Y/D). Got {self.amplitudes!r}.")

    @property
    def max_reduced_amplitude(self) -> float:
        """Largest Y/D at which the curve is defined (the CIGRE cubic: its first zero)."""
        if self.coefficients:
            roots = np.roots(self.coefficients)
            real = roots[(np.abs(roots.imag) < 1e-12) & (roots.real > 0)].real
            return float(real.min())
        return float(self.amplitudes[-1])

    def reduced_power(self, reduced_amplitude: np.ndarray | float) -> np.ndarray:
        """F(a) at a = Y / D (array in, array out); a digitised curve is not extended past its
        last point (the caller checks :attr:`max_reduced_amplitude`)."""
        a = np.asarray(reduced_amplitude, dtype=float)
        if self.coefficients:
            return np.polyval(self.coefficients, a)
        return _pchip(self)(a)


_PCHIP_CACHE: dict[tuple, scipy.interpolate.PchipInterpolator] = {}


def _pchip(curve: WindPowerCurve) -> scipy.interpolate.PchipInterpolator:
    # Keyed by the points, not the name: a user's curve may reuse a built-in curve's name.
    key = (curve.amplitudes, curve.powers)
    if key not in _PCHIP_CACHE:
        _PCHIP_CACHE[key] = scipy.interpolate.PchipInterpolator(
            np.concatenate([[0.0], curve.amplitudes]), np.concatenate([[0.0], curve.powers]),
            extrapolate=False)
    return _PCHIP_CACHE[key]


_DIGITISED = ("digitised points as tabulated in rte-france/pallas-dohl wind_power_data.yaml "
              "(from the EPRI Orange Book figure; checked only for consistency with dohl's own "
              "polynomial fit, to {:.0%}, not against the original)")

#: Wind power curves by name. ``cigre`` (default) is the CIGRE cubic, identical to Foti &
#: Martinelli (2018) eqs. (4)-(5) at zero turbulence. The digitised curves are those of dohl's
#: table whose points and polynomial fit agree (Brika & Laneville 1995 and Rawlins 1983 are left
#: out: dohl's polynomials for them miss their own points by factors of 8-38, so the table cannot
#: be trusted for them).
WIND_POWER_CURVES: dict[str, WindPowerCurve] = {
    "cigre": WindPowerCurve(
        "cigre", "CIGRE (Foti & Martinelli 2018, eqs. 4-5, Iv = 0)",
        "polynomial F(a) = -99.73 a^3 + 101.62 a^2 + 0.1627 a + 0.2256 (domain.md 2.3, verified "
        "against dohl/ebp.py)", coefficients=(-99.73, 101.62, 0.1627, 0.2256)),
    "farquharson": WindPowerCurve(
        "farquharson", "Farquharson & McHugh (1956)", _DIGITISED.format(0.23),
        amplitudes=(0.01, 0.03, 0.06, 0.10), powers=(0.02, 0.11, 0.40, 0.84)),
    "carroll": WindPowerCurve(
        "carroll", "Carroll (1936)", _DIGITISED.format(0.20),
        amplitudes=(0.03, 0.06, 0.10), powers=(0.11, 0.40, 0.85)),
    "rawlins58": WindPowerCurve(
        "rawlins58", "Rawlins (1958)", _DIGITISED.format(0.19),
        amplitudes=(0.03, 0.06, 0.10, 0.20), powers=(0.18, 0.50, 1.20, 3.20)),
    "bate": WindPowerCurve(
        "bate", "Bate (1930)", _DIGITISED.format(0.10),
        amplitudes=(0.06, 0.10, 0.20), powers=(0.65, 1.60, 3.90)),
    "diana": WindPowerCurve(
        "diana", "Diana & Falco (1971)", _DIGITISED.format(0.12),
        amplitudes=(0.03, 0.06, 0.10, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80),
        powers=(0.23, 0.70, 1.80, 5.00, 9.00, 14.00, 18.00, 20.00, 21.00, 20.00)),
    "pon": WindPowerCurve(
        "pon", "Pon et al. (1989)", _DIGITISED.format(0.09),
        amplitudes=(0.01, 0.03, 0.06, 0.10, 0.20, 0.30),
        powers=(0.04, 0.20, 0.60, 1.50, 3.00, 4.50)),
}


def _curve(name: object) -> WindPowerCurve:
    if isinstance(name, WindPowerCurve):
        return name
    return WIND_POWER_CURVES[check_choice("wind_curve", name, tuple(WIND_POWER_CURVES))]


def turbulence_factor(turbulence_intensity: float) -> float:
    """Foti & Martinelli's reduction of the wind power, b = 1 / sqrt(1 + (Iv / 0.09)^2).

    Parameters
    ----------
    turbulence_intensity : float
        Iv, the turbulence intensity (>= 0; 0 for smooth flow, no reduction).

    Returns
    -------
    float
        The factor b in (0, 1].

    Examples
    --------
    >>> round(turbulence_factor(0.09), 4)
    0.7071
    """
    iv = check_real("turbulence_intensity", turbulence_intensity, low=0.0, low_inclusive=True,
                    high=10.0)  # 1000 %: beyond any wind, and (iv / 0.09)^2 stays finite
    return 1.0 / math.sqrt(1.0 + (iv / 0.09) ** 2)


def wind_power(amplitude: np.ndarray | float, frequency: float, diameter: float, *,
               wind_curve: str = "cigre", turbulence_intensity: float = 0.0) -> np.ndarray:
    """Wind power input per metre, P_w = b f^3 D^4 F(Y / D), W/m.

    Parameters
    ----------
    amplitude : float or ndarray
        Antinode amplitude Y (zero-to-peak), m (>= 0).
    frequency : float
        Vibration frequency, Hz (> 0).
    diameter : float
        Conductor diameter D, m (> 0).
    wind_curve : str
        A name of :data:`WIND_POWER_CURVES` (default ``"cigre"``).
    turbulence_intensity : float
        Iv; the power is multiplied by :func:`turbulence_factor` (default 0: smooth flow).

    Returns
    -------
    ndarray
        W/m, the shape of ``amplitude``.

    Raises
    ------
    InputError
        For an unknown curve, or an amplitude beyond a digitised curve's last point.

    Examples
    --------
    >>> round(float(wind_power(0.0269, 6.57, 0.02814)) * 1e3, 3)     # Drake, 1 m/s, mW/m
    1.089
    """
    curve = _curve(wind_curve)
    frequency = _check_frequency(frequency)
    diameter = check_real("diameter", diameter, low=0.0, high=1.0)  # m: 1 m is no conductor
    a = check_array("amplitude", amplitude) / diameter
    if np.any(a < 0) or np.any(a > curve.max_reduced_amplitude * (1 + 1e-12)):
        raise InputError(
            f"The 'amplitude' parameter must lie in [0, {curve.max_reduced_amplitude:g} D] for "
            f"the {curve.name!r} wind power curve. Got Y/D up to {float(np.max(a)):g}.")
    return turbulence_factor(turbulence_intensity) * frequency**3 * diameter**4 \
        * curve.reduced_power(a)


# Upper bounds far above any aeolian case (~1-7 m/s, <= a few hundred Hz) and far below float
# overflow of f^3, f^5.63 or omega^2 (a frequency of 1e300 Hz raised a raw OverflowError).
MAX_FREQUENCY = 1e5
MAX_WIND_SPEED = 100.0


def _check_frequency(frequency: object) -> float:
    return check_real("frequency", frequency, low=0.0, high=MAX_FREQUENCY)


def _finite_power(power: np.ndarray, what: str) -> np.ndarray:
    if not np.all(np.isfinite(power)):
        raise InputError(f"The 'amplitude' parameter is too large: the {what} overflows. Give "
                         "antinode amplitudes in m (a few conductor diameters at most).")
    return power


# --------------------------------------------------------------------------- self-damping
@dataclass(frozen=True)
class SelfDampingLaw:
    """Empirical conductor self-damping P_c = k Y^l f^m / T^n (W/m; Y in m, f in Hz, T in kN).

    Parameters
    ----------
    name : str
        Key in :data:`SELF_DAMPING_LAWS` or ``"custom"``.
    label : str
        Authors and year.
    l, m : float
        Exponents of the amplitude and the frequency.
    n : float or None
        Exponent of the tension; None where the source gives none (then the caller must supply
        one).
    k : float or None
        Coefficient; None means the "Lilien" normalisation k = D[mm] / sqrt(m[kg/m] RTS[kN])
        that rte-france/pallas-dohl uses. That normalisation is taken from dohl and is NOT
        verified against the original publications.

    Examples
    --------
    >>> law = SELF_DAMPING_LAWS["noiseux1991"]
    >>> (law.l, law.m, law.n)
    (2.44, 5.63, 2.76)
    """

    name: str
    label: str
    l: float
    m: float
    n: float | None
    k: float | None = None

    def __post_init__(self) -> None:
        for key in ("name", "label"):
            if not isinstance(getattr(self, key), str):
                raise InputError(f"The {key!r} parameter must be a string. Got "
                                 f"{getattr(self, key)!r}.")
        check_real("l", self.l, low=0.0)
        check_real("m", self.m, low=0.0)
        if self.n is not None:
            check_real("n", self.n, low=0.0, low_inclusive=True)
        if self.k is not None:
            check_real("k", self.k, low=0.0)

    def coefficient(self, span: Span) -> float:
        """The k of this law on ``span`` (the Lilien normalisation when ``k`` is None).

        Parameters
        ----------
        span : Span
            The span; its conductor needs a rated strength for the Lilien k.

        Returns
        -------
        float

        Examples
        --------
        >>> from powerline_control import Span
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> round(SELF_DAMPING_LAWS["noiseux1991"].coefficient(span), 4)
        1.8633
        """
        if self.k is not None:
            return self.k
        cond = span.conductor
        if cond.rated_strength is None:
            raise InputError(
                f"The self-damping law {self.name!r} has no k, and the Lilien normalisation "
                "k = D[mm] / sqrt(m RTS[kN]) needs conductor.rated_strength; give "
                "self_damping_k=... or a conductor with a rated strength.")
        return cond.diameter * 1e3 / math.sqrt(cond.mass_per_length * cond.rated_strength / 1e3)

    def power(self, amplitude: np.ndarray | float, frequency: float, span: Span) -> np.ndarray:
        """P_c in W/m at antinode amplitude ``amplitude`` (m) and ``frequency`` (Hz).

        Parameters
        ----------
        amplitude : float or ndarray
            Y, m.
        frequency : float
            Hz.
        span : Span
            Gives T (converted to kN) and, for the Lilien k, D, m and RTS.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from powerline_control import Span
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> round(float(SELF_DAMPING_LAWS["noiseux1991"].power(0.0269, 6.57, span)) * 1e3, 3)
        1.114
        """
        if self.n is None:
            raise InputError(
                f"The self-damping law {self.name!r} ({self.label}) gives no tension exponent; "
                "pass self_damping_exponents=(l, m, n) with an n of your choice.")
        y = np.asarray(amplitude, dtype=float)
        return self.coefficient(span) * y**self.l * frequency**self.m \
            / (span.tension / 1e3) ** self.n


def _law(name, label, l, m, n):
    return SelfDampingLaw(name, label, l, m, n)


#: Self-damping exponent sets of domain.md 2.2 (from dohl's damping_power_data.yaml). Where a
#: source gives a range, the midpoint is used. Sets without a tension exponent need one from the
#: user.
SELF_DAMPING_LAWS: dict[str, SelfDampingLaw] = {
    law.name: law for law in (
        _law("noiseux1991", "Noiseux (1991)", 2.44, 5.63, 2.76),
        _law("tompkins", "Tompkins et al. (1956), range midpoints", 2.45, 5.5, 1.9),
        _law("claren", "Claren & Diana (1969), n range midpoint", 2.0, 4.0, 2.25),
        _law("seppa", "Seppa (1971)", 2.5, 5.75, 2.8),
        _law("rawlins", "Rawlins (1983)", 2.2, 5.4, None),
        _law("cigre_lab_a", "CIGRE 22.01 (1989), Lab A", 2.0, 4.0, None),
        _law("cigre_lab_b", "CIGRE 22.01 (1989), Lab B", 2.3, 5.2, None),
        _law("cigre_lab_c", "CIGRE 22.01 (1989), Lab C", 2.44, 5.5, None),
        _law("kraus", "Kraus & Hagedorn (1991)", 2.47, 5.38, 2.80),
        _law("tavano", "Tavano (1988), range midpoints", 2.1, 4.0, None),
        _law("mocks", "Möcks & Schmidt (1989)", 2.45, 5.38, 2.4),
        _law("pdm", "Politecnico di Milano (2000)", 2.43, 5.5, 2.0),
    )
}


def _resolve_law(self_damping: object, k: float | None,
                 exponents: Sequence[float] | None) -> SelfDampingLaw:
    if isinstance(self_damping, SelfDampingLaw):
        base = self_damping
    else:
        base = SELF_DAMPING_LAWS[check_choice("self_damping", self_damping,
                                              tuple(SELF_DAMPING_LAWS))]
    l, m, n = base.l, base.m, base.n
    if exponents is not None:
        if not isinstance(exponents, Sequence | np.ndarray) or isinstance(exponents, str) \
                or len(exponents) != 3:
            raise InputError("The 'self_damping_exponents' parameter must be (l, m, n). "
                             f"Got {exponents!r}.")
        l = check_real("self_damping_exponents[0] (l)", exponents[0], low=0.0)
        m = check_real("self_damping_exponents[1] (m)", exponents[1], low=0.0)
        n = check_real("self_damping_exponents[2] (n)", exponents[2])
    if k is not None:
        k = check_real("self_damping_k", k, low=0.0)
    name = base.name if exponents is None and k is None else f"{base.name} (user-modified)"
    return SelfDampingLaw(name, base.label, l, m, n, base.k if k is None else k)


def self_damping_power(amplitude: np.ndarray | float, frequency: float, span: Span, *,
                       self_damping: str = "noiseux1991", self_damping_k: float | None = None,
                       self_damping_exponents: Sequence[float] | None = None) -> np.ndarray:
    """Conductor self-damping power per metre, P_c = k Y^l f^m / T^n (T in kN), W/m.

    The default law is Noiseux (1991), l = 2.44, m = 5.63, n = 2.76, with k = D[mm] /
    sqrt(m RTS[kN]) as rte-france/pallas-dohl does; that normalisation is taken from dohl and is
    unverified against the original.

    Parameters
    ----------
    amplitude : float or ndarray
        Antinode amplitude, m.
    frequency : float
        Hz (> 0).
    span : Span
        Tension, conductor.
    self_damping : str
        A name of :data:`SELF_DAMPING_LAWS`.
    self_damping_k : float or None
        A user coefficient k (W/m for Y in m, f in Hz, T in kN) instead of the Lilien one.
    self_damping_exponents : (l, m, n) or None
        User exponents instead of the named set's.

    Returns
    -------
    ndarray
        W/m.

    Examples
    --------
    >>> from powerline_control import Span
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> p = self_damping_power(0.01, 20.0, span, self_damping_k=1.0,
    ...                        self_damping_exponents=(2.0, 4.0, 2.0))
    >>> round(float(p), 6)     # 1 * 0.01^2 * 20^4 / 28.02^2
    0.020379
    """
    span = _check_span(span)
    frequency = _check_frequency(frequency)
    law = _resolve_law(self_damping, self_damping_k, self_damping_exponents)
    y = check_array("amplitude", amplitude)
    if np.any(y < 0):  # Y^2.44 of a negative amplitude is NaN
        raise InputError("The 'amplitude' parameter must be >= 0 m (a zero-to-peak antinode "
                         f"amplitude). Got {float(np.min(y)):g}.")
    return _finite_power(law.power(y, frequency, span), "self-damping power")


# --------------------------------------------------------------------------- the standing wave
def _wavenumbers(span: Span, frequency: float) -> tuple[float, float]:
    """(beta, alpha): the travelling and the evanescent wavenumber of the taut beam at f.

    beta from m omega^2 = EI k^4 + T k^2 (:meth:`Span.wavenumber`, domain.md 2.3, NOT dohl's
    dimensionally wrong _wavelength); alpha^2 = beta^2 + T / EI (inf for a string).
    """
    beta = float(span.wavenumber(frequency))
    ei = span.conductor.ei
    return beta, (math.sqrt(beta**2 + span.tension / ei) if ei > 0 else math.inf)


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
    frequency = _check_frequency(frequency)
    return math.pi / _wavenumbers(span, frequency)[0]


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
    frequency = _check_frequency(frequency)
    bc = check_choice("bc", bc, ("clamped", "pinned"))
    x = check_array("position", position)
    if np.any(x < 0) or np.any(x > span.length):
        raise InputError(f"The 'position' parameter must lie in [0, {span.length:g}] m (the "
                         f"span). Got values from {x.min():g} to {x.max():g}.")
    d = np.minimum(x, span.length - x)
    beta, alpha = _wavenumbers(span, frequency)
    if bc == "pinned" or not math.isfinite(alpha):
        return np.sin(beta * d)
    ratio = beta / alpha
    return (np.sin(beta * d) - ratio * (np.cos(beta * d) - np.exp(-alpha * d))) \
        / math.sqrt(1 + ratio**2)


# --------------------------------------------------------------------------- dampers
@dataclass(frozen=True)
class ImpedanceDamper:
    """A damper given by its measured mechanical impedance Z(f) = F / v (a Stockbridge damper).

    Z is interpolated linearly (real and imaginary parts) between the tabulated frequencies; it
    is not extrapolated.

    Parameters
    ----------
    position : float
        Distance from the left support, m.
    frequencies : sequence of float
        Ascending frequencies of the table, Hz.
    impedance : sequence of complex
        Z at those frequencies, N s/m (Re Z >= 0: a passive damper).
    label : str
        Name in tables and figures.

    Examples
    --------
    >>> damper = ImpedanceDamper(1.2, [5.0, 50.0], [20.0 + 5j, 40.0 - 5j])
    >>> complex(damper.impedance_at(27.5))
    (30+0j)
    """

    position: float
    frequencies: tuple
    impedance: tuple
    label: str = "damper"

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", check_real("position", self.position, low=0.0,
                                                        low_inclusive=True))
        f = check_array("frequencies", self.frequencies, ndim=1)
        z = check_array("impedance", self.impedance, ndim=1, dtype=complex)
        if f.size < 2 or f.size != z.size or np.any(np.diff(f) <= 0) or f[0] <= 0:
            raise InputError("The 'frequencies' parameter must be >= 2 ascending positive values, "
                             "one per 'impedance' value. Got "
                             f"{f.size} frequencies and {z.size} impedances.")
        if np.any(z.real < 0):
            raise InputError("The 'impedance' parameter must have Re Z >= 0 (a passive damper "
                             f"dissipates). Got min Re Z = {z.real.min():g}.")
        object.__setattr__(self, "frequencies", tuple(float(v) for v in f))
        object.__setattr__(self, "impedance", tuple(complex(v) for v in z))
        _check_text("label", self.label)

    def impedance_at(self, frequency: float) -> complex:
        """Z at ``frequency`` (Hz), N s/m.

        Parameters
        ----------
        frequency : float
            Inside the tabulated range.

        Returns
        -------
        complex

        Examples
        --------
        >>> ImpedanceDamper(0.5, [1.0, 2.0], [1.0, 3.0]).impedance_at(1.5)
        (2+0j)
        """
        low, high = self.frequencies[0], self.frequencies[-1]
        frequency = check_real("frequency", frequency, low=0.0)
        if not low <= frequency <= high:
            raise InputError(
                f"The 'frequency' ({frequency:g} Hz) is outside the impedance table of damper "
                f"{self.label!r} ({low:g}-{high:g} Hz); extend the table or restrict the wind "
                "speeds.")
        z = np.asarray(self.impedance)
        return complex(np.interp(frequency, self.frequencies, z.real)
                       + 1j * np.interp(frequency, self.frequencies, z.imag))


@dataclass(frozen=True)
class AtAntinode:
    """A damper (an :class:`~powerline_control.fem.MDR` or :class:`ImpedanceDamper`) that sits
    at an antinode at every wind speed: the robot that has reached its target.

    Its own ``position`` is ignored; the placement factor phi^2 is ``factor`` (1 at the
    antinode; 1/2 is its average over a uniform traverse from a node to an antinode).

    Parameters
    ----------
    damper : MDR or ImpedanceDamper
        The device.
    label : str
        Name in tables and figures.
    factor : float
        Placement factor phi^2 in [0, 1] (default 1: at the antinode).

    Examples
    --------
    >>> from powerline_control import MDR
    >>> AtAntinode(MDR.tuned(0.0, 5.0, 1.0, frequency=20.0, damping_ratio=0.3)).label
    'robot at antinode'
    """

    damper: MDR | ImpedanceDamper
    label: str = "robot at antinode"
    factor: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "factor", check_real("factor", self.factor, low=0.0,
                                                      low_inclusive=True, high=1.0))
        if not isinstance(self.damper, MDR | ImpedanceDamper):
            raise InputError("The 'damper' parameter of AtAntinode must be an MDR or an "
                             f"ImpedanceDamper. Got {type(self.damper).__name__}.")
        _check_text("label", self.label)


def damper_impedance(damper: MDR | ImpedanceDamper, frequency: float) -> complex:
    """Mechanical impedance Z = F / v (N s/m) the damper presents to the line at ``frequency``.

    For an MDR the body mass m_r gives i omega m_r (reactive, dissipates nothing) and the
    suspended mass m_d on spring k and dashpot c gives
    i omega m_d (k + i omega c) / (k + i omega c - omega^2 m_d), whose real part
    omega^4 m_d^2 c / |k - omega^2 m_d + i omega c|^2 is what dissipates.

    Parameters
    ----------
    damper : MDR or ImpedanceDamper
        The device.
    frequency : float
        Hz (> 0).

    Returns
    -------
    complex

    Examples
    --------
    >>> from powerline_control import MDR
    >>> robot = MDR.tuned(1.0, 0.0, 1.0, frequency=20.0, damping_ratio=0.25)
    >>> round(damper_impedance(robot, 20.0).real, 3)     # omega m_d / (2 zeta) at tuning
    251.327
    """
    if isinstance(damper, AtAntinode):
        damper = damper.damper
    frequency = check_real("frequency", frequency, low=0.0)
    if isinstance(damper, ImpedanceDamper):
        return damper.impedance_at(frequency)
    if not isinstance(damper, MDR):
        raise InputError("The 'damper' parameter must be an MDR, an ImpedanceDamper or an "
                         f"AtAntinode. Got {type(damper).__name__}.")
    omega = 2 * math.pi * frequency
    z = 1j * omega * damper.body_mass
    if damper.has_absorber:
        spring = damper.stiffness + 1j * omega * damper.damping
        z += 1j * omega * damper.suspended_mass * spring \
            / (spring - omega**2 * damper.suspended_mass)
    return complex(z)


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


# --------------------------------------------------------------------------- fatigue indicators
#: CIGRE/EPRI safe border line sigma_a = a N^b MPa (two branches): (N threshold, a1, b1, a2, b2).
#: From the EPRI Orange Book, as in dohl/damage.py.
SAFE_BORDER_LINES = {
    "multi": (1.56e7, 450.0, -0.20, 263.0, -0.17),
    "single": (2.0e7, 730.0, -0.20, 430.0, -0.17),
}


def _sbl_stress(cycles: float, layers: str) -> float:
    """Safe-border-line stress amplitude (Pa) at ``cycles``."""
    threshold, a1, b1, a2, b2 = SAFE_BORDER_LINES[layers]
    a, b = (a1, b1) if cycles <= threshold else (a2, b2)
    return a * cycles**b * 1e6


def _sbl_cycles(stress: np.ndarray, layers: str) -> np.ndarray:
    """Cycles to the safe border line at stress amplitude ``stress`` (Pa); inf at zero stress.

    The two published branches do not meet at the threshold; stresses in the gap get the
    threshold count.
    """
    threshold, a1, b1, a2, b2 = SAFE_BORDER_LINES[layers]
    s = np.maximum(np.asarray(stress, dtype=float) / 1e6, 1e-300)
    with np.errstate(over="ignore"):  # vanishing stress: infinitely many cycles, as intended
        first = (s / a1) ** (1 / b1)
        second = (s / a2) ** (1 / b2)
    cycles = np.where(first <= threshold, first, np.where(second >= threshold, second, threshold))
    return np.where(np.asarray(stress) > 0, cycles, np.inf)


# --------------------------------------------------------------------------- the energy balance
def _check_wind_speeds(wind_speeds: object) -> np.ndarray:
    speeds = np.atleast_1d(check_array("wind_speeds", wind_speeds, ndim=(0, 1)))
    if speeds.size == 0 or np.any(speeds <= 0) or np.any(speeds > MAX_WIND_SPEED):
        bad = (speeds[(speeds <= 0) | (speeds > MAX_WIND_SPEED)].tolist()[:5] if speeds.size
               else "an empty list")
        raise InputError(f"The 'wind_speeds' parameter must hold wind speeds > 0 and <= "
                         f"{MAX_WIND_SPEED:g} m/s (aeolian vibration occurs at about 1-7 m/s). "
                         f"Got {bad}.")
    return speeds


# One energy balance (a bracketed root solve in Python) costs ~3 ms, counted as ~1e7 flops so
# that WORK_BUDGET (1e12) allows ~1e5 speeds (minutes); each speed keeps ~16 float64 results.
_WORK_PER_SPEED = 1e7


def _check_severity_budget(n_speeds: int) -> None:
    check_budget("aeolian_severity's energy balances", nbytes=8.0 * 16 * n_speeds,
                 flops=_WORK_PER_SPEED * n_speeds, parameter="wind_speeds",
                 value=f"{n_speeds} speeds",
                 fix="pass fewer wind speeds (a few dozen resolve the 1-7 m/s band)")


def _check_span(span: object) -> Span:
    if not isinstance(span, Span):
        raise InputError(f"The 'span' parameter must be a Span. Got {type(span).__name__}.")
    rts = span.conductor.rated_strength
    if rts is not None and span.tension >= rts:
        raise InputError(
            f"The 'span.tension' ({span.tension:g} N) must be below the conductor's rated "
            f"strength ({rts:g} N); everyday tensions are 15-25 % of it.")
    if span.tension <= 0:
        raise InputError("The 'span.tension' must be > 0 for the energy balance (aeolian "
                         f"vibration of a taut conductor). Got {span.tension!r}.")
    return span


def _check_dampers(dampers: object, span: Span) -> tuple:
    if isinstance(dampers, MDR | ImpedanceDamper | AtAntinode):
        dampers = (dampers,)
    if not isinstance(dampers, Sequence):
        raise InputError("The 'dampers' parameter must be a sequence of MDR, ImpedanceDamper or "
                         f"AtAntinode. Got {type(dampers).__name__}.")
    for i, damper in enumerate(dampers):
        if not isinstance(damper, MDR | ImpedanceDamper | AtAntinode):
            raise InputError(f"The 'dampers[{i}]' entry must be an MDR, ImpedanceDamper or "
                             f"AtAntinode. Got {type(damper).__name__}.")
        if not isinstance(damper, AtAntinode) and not 0 <= damper.position <= span.length:
            raise InputError(f"The 'dampers[{i}].position' must lie in [0, {span.length:g}] m "
                             f"(the span). Got {damper.position!r}.")
    return tuple(dampers)


@dataclass(frozen=True)
class SeverityResult:
    """Energy-balance severity of one span and damper configuration, one entry per wind speed.

    Attributes
    ----------
    wind_speed : ndarray
        m/s.
    frequency : ndarray
        Strouhal frequency St V / D, Hz.
    mode : ndarray of int
        Number of the span mode nearest that frequency (round(L / loop length)).
    loop_length : ndarray
        Half wavelength of the taut beam, m.
    amplitude : ndarray
        Steady antinode amplitude Y, zero-to-peak, m (0 where no vibration builds up).
    balanced : ndarray of bool
        True where the balance has a root inside the wind curve's range.
    status : tuple of str
        Per wind speed: ``"balanced"``, ``"no vibration"`` (damping exceeds the wind power at
        every amplitude: Y = 0) or ``"above curve range"`` (the wind power still exceeds the
        damping at the curve's last point: Y is given as that bound and is a LOWER bound).
    wind_power, self_damping_power, damper_power : ndarray
        The three terms of the balance at ``amplitude``, W/m.
    bending_amplitude : ndarray
        Poffenberger-Swart Y_b: peak-to-peak displacement at x_b from the clamp, m.
    stress_ps, stress_fymax : ndarray
        Idealised stress amplitude (zero-to-peak) of the outer strand at the clamp, Pa, by
        Poffenberger-Swart and by the f y_max formula.
    strain_pp, strain_pp_fymax : ndarray
        Peak-to-peak bending strain at the clamp (2 sigma_a / E_a) by the two methods.
    sbl_margin : ndarray
        Safe-border-line stress at ``reference_cycles`` divided by ``stress_ps`` (> 1: below;
        +inf where the span does not vibrate).
    endurance_margin : ndarray
        ``endurance_strain_pp`` divided by ``strain_pp`` (> 1: below the endurance strain;
        +inf where the span does not vibrate).
    label : str
        Configuration name.
    damper_labels : tuple of str
        The dampers.
    parameters : dict
        The settings used (curve, law, St, bc, x_b, ...).

    Examples
    --------
    >>> from powerline_control import Span
    >>> sev = aeolian_severity(Span.at_rts_fraction(300.0, "drake", 0.2), [1.0, 3.0])
    >>> (sev.amplitude * 1e3).round(1)
    array([26.9,  8.5])
    >>> sorted(sev.table()[0])[:3]
    ['amplitude_mm', 'balanced', 'bending_amplitude_mm']
    """

    wind_speed: np.ndarray
    frequency: np.ndarray
    mode: np.ndarray
    loop_length: np.ndarray
    amplitude: np.ndarray
    balanced: np.ndarray
    status: tuple
    wind_power: np.ndarray
    self_damping_power: np.ndarray
    damper_power: np.ndarray
    bending_amplitude: np.ndarray
    stress_ps: np.ndarray
    stress_fymax: np.ndarray
    strain_pp: np.ndarray
    strain_pp_fymax: np.ndarray
    sbl_margin: np.ndarray
    endurance_margin: np.ndarray
    label: str = "no damper"
    damper_labels: tuple = ()
    parameters: dict = field(default_factory=dict, repr=False)

    def table(self, as_frame: bool = False):
        """Tidy rows, one per wind speed (display units: mm, microstrain, MPa).

        Parameters
        ----------
        as_frame : bool
            True returns a pandas DataFrame (pandas must be installed); default a list of
            dicts.

        Returns
        -------
        list of dict or pandas.DataFrame

        Examples
        --------
        >>> from powerline_control import Span
        >>> rows = aeolian_severity(Span.at_rts_fraction(300.0, "drake", 0.2), [2.0]).table()
        >>> rows[0]["wind_speed"], rows[0]["configuration"]
        (2.0, 'no damper')
        """
        rows = []
        for i in range(self.wind_speed.size):
            rows.append({
                "configuration": self.label,
                "wind_speed": float(self.wind_speed[i]),
                "frequency_hz": float(self.frequency[i]),
                "mode": int(self.mode[i]),
                "loop_length_m": float(self.loop_length[i]),
                "amplitude_mm": float(self.amplitude[i] * 1e3),
                "balanced": bool(self.balanced[i]),
                "status": self.status[i],
                "bending_amplitude_mm": float(self.bending_amplitude[i] * 1e3),
                "stress_ps_mpa": float(self.stress_ps[i] / 1e6),
                "stress_fymax_mpa": float(self.stress_fymax[i] / 1e6),
                "strain_pp_microstrain": float(self.strain_pp[i] * 1e6),
                "strain_pp_fymax_microstrain": float(self.strain_pp_fymax[i] * 1e6),
                "sbl_margin": float(self.sbl_margin[i]),
                "endurance_margin": float(self.endurance_margin[i]),
            })
        if not as_frame:
            return rows
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise InputError("as_frame=True needs pandas; install it or use the list of "
                             "dicts (as_frame=False).") from exc
        return pd.DataFrame(rows)


def _clamp_stress(span: Span, frequency: float, amplitude: float, *, strand: float,
                  modulus: float, x_b: float) -> tuple[float, float, float]:
    """(Y_b peak-to-peak, sigma_a by Poffenberger-Swart, sigma_a by f y_max) at the clamp."""
    cond = span.conductor
    if cond.ei <= 0:
        raise InputError("Clamp stresses need conductor.ei > 0 (EI_min of the stranded "
                         "conductor).")
    y_xb = float(standing_wave_shape(span, frequency, min(x_b, span.length / 2), "clamped"))
    bending = 2.0 * abs(y_xb) * amplitude
    p = math.sqrt(span.tension / cond.ei)
    px = p * x_b
    # e^{-px} - 1 + px by its series where px is small, to keep its digits.
    denominator = math.expm1(-px) + px
    k_ps = modulus * strand * p**2 / (4.0 * denominator)
    sigma_fy = math.pi * strand * modulus * math.sqrt(cond.mass_per_length / cond.ei) \
        * frequency * amplitude
    return bending, k_ps * bending, sigma_fy


def _solve_balance(balance, y_high: float, scale: float, on_grid=None) -> tuple[float, str]:
    """Root of balance(y) = P_w - P_c - P_d on (0, y_high]: the first sign change on a
    logarithmic scan, polished by Brent's method. ``on_grid`` evaluates the same balance on an
    array at once (the scan, elementwise the same arithmetic as ``balance``)."""
    grid = np.geomspace(1e-9 * scale, y_high, 240)
    values = (np.array([balance(y) for y in grid]) if on_grid is None
              else np.asarray(on_grid(grid), dtype=float))
    if values[0] <= 0:
        return 0.0, "no vibration"
    negative = np.flatnonzero(values <= 0)
    if negative.size == 0:
        return float(y_high), "above curve range"
    j = int(negative[0])
    if values[j] == 0:
        return float(grid[j]), "balanced"
    root = scipy.optimize.brentq(balance, grid[j - 1], grid[j], xtol=1e-300,
                                 rtol=4 * np.finfo(float).eps, maxiter=500)
    return float(root), "balanced"


def aeolian_severity(
    span: Span,
    wind_speeds: Sequence[float] | np.ndarray = np.arange(1.0, 8.0),  # noqa: B008 (read only)
    dampers: Sequence[MDR | ImpedanceDamper | AtAntinode] = (),
    *,
    strouhal: float = DEFAULT_STROUHAL,
    wind_curve: str = "cigre",
    turbulence_intensity: float = 0.0,
    self_damping: str = "noiseux1991",
    self_damping_k: float | None = None,
    self_damping_exponents: Sequence[float] | None = None,
    bc: str = "clamped",
    outer_strand_diameter: float | None = None,
    outer_strand_modulus: float = ALUMINIUM_MODULUS,
    layers: str = "multi",
    x_b: float = POFFENBERGER_SWART_DISTANCE,
    endurance_strain_pp: float = ENDURANCE_STRAIN_PP,
    reference_cycles: float = 5e8,
    label: str | None = None,
) -> SeverityResult:
    """Steady aeolian vibration of a span by the energy balance, with clamp strain and margins.

    For each wind speed: the Strouhal frequency f = St V / D, the loop length and mode from the
    taut-beam dispersion m omega^2 = EI k^4 + T k^2, the antinode amplitude Y solving
    P_w(Y) = P_c(Y) + sum P_d(Y) (a bracketed root, Brent's method), then the clamp bending
    amplitude Y_b at x_b and the stress by Poffenberger-Swart and by f y_max, the
    safe-border-line margin and the endurance-strain margin.

    Parameters
    ----------
    span : Span
        Conductor, length and tension (tension below the rated strength).
    wind_speeds : sequence of float
        m/s, each > 0 (default 1..7).
    dampers : sequence of MDR, ImpedanceDamper or AtAntinode
        Devices on the span (default none).
    strouhal : float
        Strouhal number (default 0.185).
    wind_curve : str
        A name of :data:`WIND_POWER_CURVES` (default "cigre").
    turbulence_intensity : float
        Iv for :func:`turbulence_factor` (default 0).
    self_damping : str
        A name of :data:`SELF_DAMPING_LAWS` (default "noiseux1991"; Lilien k from dohl,
        unverified).
    self_damping_k : float or None
        User coefficient k.
    self_damping_exponents : (l, m, n) or None
        User exponents.
    bc : {"clamped", "pinned"}
        Supports, for the placement factor of dampers (the clamp stress always assumes a clamp).
    outer_strand_diameter : float or None
        Diameter of an outer strand, m; None takes it from the preset table
        :data:`OUTER_STRAND_DIAMETER` (an error for a custom conductor).
    outer_strand_modulus : float
        Young's modulus of the outer strands, Pa (default aluminium, 68.9 GPa).
    layers : {"multi", "single"}
        Safe border line of multilayer or single-layer ACSR.
    x_b : float
        Poffenberger-Swart distance from the last point of contact, m (default 0.089).
    endurance_strain_pp : float
        Allowed peak-to-peak bending strain (default 150e-6).
    reference_cycles : float
        Cycle count at which the safe border line gives the endurance stress for
        ``sbl_margin`` (default 5e8 [from memory: the usual "endurance" count]).
    label : str or None
        Configuration name (default: from the dampers).

    Returns
    -------
    SeverityResult

    Raises
    ------
    InputError
        For wind speeds <= 0, a damper outside the span, an unknown curve or law (the message
        lists the allowed names), a tension at or above the rated strength.

    Examples
    --------
    >>> from powerline_control import Span
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.25)
    >>> sev = aeolian_severity(span, [1.0, 7.0])
    >>> (sev.amplitude * 1e3).round(1), sev.mode.tolist()
    (array([27.7,  1.5]), [27, 188])
    """
    span = _check_span(span)
    if label is not None:
        _check_text("label", label)
    if isinstance(wind_speeds, np.ndarray):  # refuse before the finiteness checks copy it
        _check_severity_budget(wind_speeds.size)
    speeds = _check_wind_speeds(wind_speeds)
    _check_severity_budget(speeds.size)
    dampers = _check_dampers(dampers, span)
    st = check_real("strouhal", strouhal, low=0.01, low_inclusive=True, high=1.0)
    curve = _curve(wind_curve)
    law = _resolve_law(self_damping, self_damping_k, self_damping_exponents)
    bc = check_choice("bc", bc, ("clamped", "pinned"))
    layers = check_choice("layers", layers, tuple(SAFE_BORDER_LINES))
    # x_b from 0.1 mm: Poffenberger-Swart's K divides by e^{-p x_b} - 1 + p x_b ~ (p x_b)^2 / 2
    x_b = check_real("x_b", x_b, low=1e-4, low_inclusive=True, high=span.length / 2)
    modulus = check_real("outer_strand_modulus", outer_strand_modulus, low=0.0)
    endurance = check_real("endurance_strain_pp", endurance_strain_pp, low=0.0)
    reference_cycles = check_real("reference_cycles", reference_cycles, low=1.0)
    b = turbulence_factor(turbulence_intensity)
    cond = span.conductor
    if outer_strand_diameter is None:
        if cond.name not in OUTER_STRAND_DIAMETER:
            raise InputError(
                "The 'outer_strand_diameter' parameter is needed for conductor "
                f"{cond.name!r}; it is known for the presets {sorted(OUTER_STRAND_DIAMETER)}.")
        strand = OUTER_STRAND_DIAMETER[cond.name]
    else:
        strand = check_real("outer_strand_diameter", outer_strand_diameter, low=0.0,
                            high=cond.diameter)
    law.power(0.0, 1.0, span)  # a law without a tension exponent (or k) fails here, clearly
    d = cond.diameter
    y_high = curve.max_reduced_amplitude * d
    sigma_endurance = _sbl_stress(reference_cycles, layers)

    n = speeds.size
    out = {name: np.zeros(n) for name in (
        "frequency", "loop", "amplitude", "pw", "pc", "pd", "yb", "sps", "sfy")}
    modes = np.zeros(n, dtype=int)
    status = []
    for i, speed in enumerate(speeds):
        f = st * float(speed) / d
        loop = loop_length(span, f)
        # Damper coefficients: P_d = coefficient * Y^2, summed over the dampers.
        coefficient = sum(float(damper_power(dmp, span, 1.0, f, bc=bc)) for dmp in dampers)
        base = b * f**3 * d**4

        def balance(y, f=f, base=base, coefficient=coefficient):
            return float(base * curve.reduced_power(y / d) - law.power(y, f, span)
                         - coefficient * y * y)

        def on_grid(y, f=f, base=base, coefficient=coefficient):
            return base * curve.reduced_power(y / d) - law.power(y, f, span) \
                - coefficient * y * y

        y, state = _solve_balance(balance, y_high, d, on_grid)
        status.append(state)
        yb, sps, sfy = _clamp_stress(span, f, y, strand=strand, modulus=modulus, x_b=x_b)
        out["frequency"][i], out["loop"][i], out["amplitude"][i] = f, loop, y
        out["pw"][i] = base * float(curve.reduced_power(y / d))
        out["pc"][i] = float(law.power(y, f, span))
        out["pd"][i] = coefficient * y * y
        out["yb"][i], out["sps"][i], out["sfy"][i] = yb, sps, sfy
        modes[i] = max(1, int(round(span.length / loop)))
    strain_pp = 2 * out["sps"] / modulus
    with np.errstate(divide="ignore"):
        sbl_margin = np.where(out["sps"] > 0, sigma_endurance / np.maximum(out["sps"], 1e-300),
                              np.inf)
        endurance_margin = np.where(strain_pp > 0, endurance / np.maximum(strain_pp, 1e-300),
                                    np.inf)
    labels = tuple(_label_of(dmp) for dmp in dampers)
    return SeverityResult(
        wind_speed=read_only(speeds.copy()), frequency=read_only(out["frequency"]),
        mode=read_only(modes), loop_length=read_only(out["loop"]),
        amplitude=read_only(out["amplitude"]),
        balanced=read_only(np.array([s == "balanced" for s in status])), status=tuple(status),
        wind_power=read_only(out["pw"]), self_damping_power=read_only(out["pc"]),
        damper_power=read_only(out["pd"]), bending_amplitude=read_only(out["yb"]),
        stress_ps=read_only(out["sps"]), stress_fymax=read_only(out["sfy"]),
        strain_pp=read_only(strain_pp), strain_pp_fymax=read_only(2 * out["sfy"] / modulus),
        sbl_margin=read_only(sbl_margin), endurance_margin=read_only(endurance_margin),
        label=label if label is not None else (" + ".join(labels) if labels else "no damper"),
        damper_labels=labels,
        parameters=dict(strouhal=st, wind_curve=curve.name, turbulence_factor=b,
                        self_damping=law.name, self_damping_exponents=(law.l, law.m, law.n),
                        self_damping_k=law.coefficient(span), bc=bc, x_b=x_b,
                        outer_strand_diameter=strand, outer_strand_modulus=modulus,
                        layers=layers, endurance_strain_pp=endurance,
                        reference_cycles=reference_cycles, sbl_endurance_stress=sigma_endurance),
    )


# --------------------------------------------------------------------------- wind climate
def _check_histogram(e: np.ndarray, p: np.ndarray, rtol: float) -> None:
    """Raise unless ``p`` is a density on the bins ``e`` that integrates to 1 (to ``rtol``)."""
    if e.size != p.size + 1 or e.size < 2 or np.any(np.diff(e) <= 0) or e[0] < 0:
        raise InputError("The 'edges' parameter must be n + 1 ascending values >= 0 for n "
                         f"densities. Got {e.size} edges and {p.size} densities.")
    if np.any(p < 0):
        raise InputError(f"The 'density' parameter must be >= 0. Got min {p.min():g}.")
    total = float(np.sum(p * np.diff(e)))
    if abs(total - 1.0) > rtol:
        raise InputError(
            "The 'density' parameter must integrate to 1 over the bins (sum of density * "
            f"bin width), to {rtol:g}. Got {total:.6g}; divide by that to normalise it.")


@dataclass(frozen=True)
class WindDistribution:
    """Distribution of the (10-minute mean) wind speed across the conductor.

    Use :meth:`weibull` or :meth:`histogram`; ``probability_of`` gives the probability of each
    analysis bin (bins centred on the analysis wind speeds, edges half way between them).

    Parameters
    ----------
    kind : {"weibull", "histogram"}
        Which form.
    shape, scale : float
        Weibull shape k and scale c (m/s) (``kind="weibull"``).
    edges : tuple of float
        Histogram bin edges, m/s, ascending (``kind="histogram"``).
    density : tuple of float
        Probability density in each histogram bin, 1/(m/s); sum(density * width) must be 1.
    rtol : float
        Tolerance of that normalisation check (default 1e-6).

    Examples
    --------
    >>> dist = WindDistribution.weibull(shape=2.0, scale=4.0)
    >>> round(float(dist.cdf(4.0)), 4)
    0.6321
    """

    kind: str
    shape: float = 2.0
    scale: float = 4.0
    edges: tuple = ()
    density: tuple = ()
    rtol: float = 1e-6

    @classmethod
    def weibull(cls, shape: float = 2.0, scale: float = 4.0) -> WindDistribution:
        """Weibull distribution, CDF 1 - exp(-(V / c)^k).

        Parameters
        ----------
        shape : float
            k (> 0; 2 is the Rayleigh distribution of open terrain).
        scale : float
            c, m/s (> 0).

        Returns
        -------
        WindDistribution

        Examples
        --------
        >>> WindDistribution.weibull(2.0, 5.0).scale
        5.0
        """
        return cls("weibull", shape=shape, scale=scale)

    @classmethod
    def histogram(cls, edges: Sequence[float], density: Sequence[float],
                  rtol: float = 1e-6) -> WindDistribution:
        """A measured histogram: piecewise-constant density between ``edges``.

        Parameters
        ----------
        edges : sequence of float
            n + 1 ascending bin edges, m/s (>= 0).
        density : sequence of float
            n densities, 1/(m/s), >= 0, integrating to 1 (to ``rtol``).
        rtol : float
            Tolerance of the normalisation check.

        Returns
        -------
        WindDistribution

        Raises
        ------
        InputError
            If the histogram does not integrate to 1.

        Examples
        --------
        >>> WindDistribution.histogram([0.0, 2.0, 4.0], [0.25, 0.25]).kind
        'histogram'
        """
        e = check_array("edges", edges, ndim=1)
        p = check_array("density", density, ndim=1)
        rtol = check_real("rtol", rtol, low=0.0, high=1.0)
        _check_histogram(e, p, rtol)
        return cls("histogram", edges=tuple(map(float, e)), density=tuple(map(float, p)),
                   rtol=rtol)

    def __post_init__(self) -> None:
        # Direct construction is checked as strictly as the two factories.
        check_choice("kind", self.kind, ("weibull", "histogram"))
        rtol = check_real("rtol", self.rtol, low=0.0, high=1.0)
        if self.kind == "weibull":
            object.__setattr__(self, "shape", check_real("shape", self.shape, low=0.0))
            object.__setattr__(self, "scale", check_real("scale", self.scale, low=0.0))
            for field_name in ("edges", "density"):
                if not (isinstance(getattr(self, field_name), tuple | list)
                        and len(getattr(self, field_name)) == 0):
                    raise InputError(f"The '{field_name}' parameter belongs to a histogram; a "
                                     "Weibull distribution takes shape and scale only. Got "
                                     f"{getattr(self, field_name)!r:.60}.")
        else:
            # the factory's tolerance is kept (a re-check at a fixed 1e-6 refused what
            # histogram(..., rtol=...) had accepted)
            _check_histogram(check_array("edges", self.edges, ndim=1),
                             check_array("density", self.density, ndim=1), rtol)

    def cdf(self, speed: np.ndarray | float) -> np.ndarray:
        """Probability that the wind speed is below ``speed``.

        Parameters
        ----------
        speed : float or ndarray
            m/s.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> float(WindDistribution.histogram([0.0, 2.0], [0.5]).cdf(1.0))
        0.5
        """
        v = np.maximum(np.asarray(speed, dtype=float), 0.0)
        if self.kind == "weibull":
            return -np.expm1(-((v / self.scale) ** self.shape))
        e = np.asarray(self.edges)
        cumulative = np.concatenate([[0.0], np.cumsum(np.asarray(self.density) * np.diff(e))])
        return np.interp(v, e, cumulative)

    def probability_of(self, wind_speeds: np.ndarray) -> np.ndarray:
        """Probability of each analysis bin (centred on ``wind_speeds``).

        Parameters
        ----------
        wind_speeds : ndarray
            Strictly ascending analysis wind speeds, m/s (the bins lie between them).

        Returns
        -------
        ndarray
            Probabilities (they sum to the probability of the analysed band, <= 1).

        Raises
        ------
        InputError
            If the speeds are not strictly ascending (descending speeds would give bins of
            negative width and negative probabilities).

        Examples
        --------
        >>> dist = WindDistribution.histogram([0.0, 10.0], [0.1])
        >>> dist.probability_of(np.array([1.0, 2.0, 3.0])).round(3)
        array([0.1, 0.1, 0.1])
        """
        v = np.atleast_1d(check_array("wind_speeds", wind_speeds, ndim=(0, 1)))
        if v.size == 0 or np.any(v < 0) or np.any(np.diff(v) <= 0):
            raise InputError("The 'wind_speeds' parameter must be strictly ascending wind "
                             "speeds >= 0 m/s (sorted, without repeats). Got "
                             f"{v.tolist()[:8]}.")
        edges = _bin_edges(v)
        return np.diff(self.cdf(edges))


def _bin_edges(speeds: np.ndarray) -> np.ndarray:
    if speeds.size == 1:
        return np.array([0.5 * speeds[0], 1.5 * speeds[0]])
    mid = 0.5 * (speeds[1:] + speeds[:-1])
    return np.concatenate([[speeds[0] - (mid[0] - speeds[0])], mid,
                           [speeds[-1] + (speeds[-1] - mid[-1])]]).clip(min=0.0)


@dataclass(frozen=True)
class RobotValue:
    """Fatigue and endurance over a wind climate for three configurations.

    Attributes
    ----------
    configurations : tuple of str
        ``("no damper", "fixed damper at x*", "robot at antinode")``.
    severities : tuple of SeverityResult
        The steady energy balance of each configuration.
    probability : ndarray
        Probability of each wind-speed bin.
    fixed_position : float
        The harmonic-mean position x*, m from the support.
    move_time : ndarray
        Time the robot needs to reach the antinode from the worst start (half a loop), s.
    time_at_antinode : ndarray
        Fraction of each persistence interval the robot spends at the antinode.
    fraction_over_endurance : ndarray, shape (3,)
        Fraction of all time the clamp strain exceeds the endurance strain, per configuration.
    fatigue_index : ndarray, shape (3,)
        Miner's-rule damage per year on the safe border line, per configuration (1 = one
        lifetime used per year).
    persistence : float
        How long a wind speed persists, s.
    en_route : str
        The span's state while the robot travels ("average" or "undamped").

    Examples
    --------
    >>> from powerline_control import MDR, RobotLimits, Span
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> robot = MDR.tuned(0.0, 5.0, 1.5, frequency=15.0, damping_ratio=0.3)
    >>> value = robot_value(span, robot, RobotLimits(v_max=0.3, a_max=0.5))
    >>> bool(value.fatigue_index[2] <= value.fatigue_index[1] <= value.fatigue_index[0])
    True
    """

    configurations: tuple
    severities: tuple
    probability: np.ndarray
    fixed_position: float
    move_time: np.ndarray
    time_at_antinode: np.ndarray
    fraction_over_endurance: np.ndarray
    fatigue_index: np.ndarray
    persistence: float
    en_route: str = "average"

    def table(self) -> list[dict]:
        """One row per configuration.

        Returns
        -------
        list of dict

        Examples
        --------
        >>> from powerline_control import MDR, RobotLimits, Span
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> robot = MDR.tuned(0.0, 5.0, 1.5, frequency=15.0, damping_ratio=0.3)
        >>> rows = robot_value(span, robot, RobotLimits(0.3, 0.5), [1.0, 4.0]).table()
        >>> [row["configuration"] for row in rows]
        ['no damper', 'fixed damper at x*', 'robot at antinode']
        """
        return [{"configuration": name, "fraction_over_endurance": float(frac),
                 "fatigue_index_per_year": float(index),
                 "life_years": float(1.0 / index) if index > 0 else math.inf}
                for name, frac, index in zip(self.configurations, self.fraction_over_endurance,
                                             self.fatigue_index, strict=True)]


def robot_value(
    span: Span,
    damper: MDR | ImpedanceDamper,
    limits: RobotLimits,
    wind_speeds: Sequence[float] | np.ndarray = np.arange(1.0, 8.0),  # noqa: B008 (read only)
    *,
    distribution: WindDistribution | None = None,
    persistence: float = 600.0,
    en_route: str = "average",
    **severity_options,
) -> RobotValue:
    """What a robot at the antinode is worth against no damper and the same damper parked at x*.

    Model (documented in docs/severity.md): each wind speed bin holds for ``persistence``
    seconds at a time; at each change the robot starts, in the worst case, half a loop from the
    nearest antinode and needs the time-optimal rest-to-rest move under ``limits`` to get there.
    Until it arrives the span vibrates at the ``en_route`` amplitude: ``"average"`` (default)
    the steady amplitude with the damper's placement factor averaged over a node-to-antinode
    traverse (phi^2 = 1/2), ``"undamped"`` (a conservative bound) the undamped one; afterwards
    at the antinode amplitude. Cycles per year in a bin are f x probability x one year; Miner's
    damage sums cycles / (cycles to the safe border line at the clamp stress). Both numbers
    assume aeolian vibration whenever the wind is in the band: they compare configurations,
    they do not predict a service life.

    Parameters
    ----------
    span : Span
        The span.
    damper : MDR or ImpedanceDamper
        The robot's damper (its position is ignored; the fixed configuration parks it at x*).
    limits : RobotLimits
        Speed, acceleration (and jerk) limits.
    wind_speeds : sequence of float
        Analysis wind speeds, m/s (ascending).
    distribution : WindDistribution or None
        Wind climate (default Weibull k = 2, c = 4 m/s).
    persistence : float
        How long a wind speed lasts, s (default 600: the 10-minute mean of wind records).
    en_route : {"average", "undamped"}
        The span's state while the robot travels (see above).
    **severity_options
        Passed to :func:`aeolian_severity` (curve, law, St, ...; not ``dampers`` or ``label``,
        which this function sets).

    Returns
    -------
    RobotValue

    Raises
    ------
    InputError
        For bad arguments, or ``dampers=`` / ``label=`` among the severity options.

    Examples
    --------
    >>> from powerline_control import MDR, RobotLimits, Span
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> robot = MDR.tuned(0.0, 5.0, 1.5, frequency=15.0, damping_ratio=0.3)
    >>> value = robot_value(span, robot, RobotLimits(0.3, 0.5), [1.0, 4.0])
    >>> value.configurations[2], bool(value.time_at_antinode.max() <= 1.0)
    ('robot at antinode', True)
    """
    span = _check_span(span)
    if isinstance(wind_speeds, np.ndarray):  # before the checks and the sort copy it
        _check_severity_budget(wind_speeds.size)
    speeds = np.sort(_check_wind_speeds(wind_speeds))
    if not isinstance(damper, MDR | ImpedanceDamper):
        raise InputError("The 'damper' parameter must be an MDR or an ImpedanceDamper. Got "
                         f"{type(damper).__name__}.")
    if not isinstance(limits, RobotLimits):
        raise InputError(f"The 'limits' parameter must be a RobotLimits. Got "
                         f"{type(limits).__name__}.")
    if distribution is None:
        distribution = WindDistribution.weibull()
    if not isinstance(distribution, WindDistribution):
        raise InputError("The 'distribution' parameter must be a WindDistribution. Got "
                         f"{type(distribution).__name__}.")
    persistence = check_real("persistence", persistence, low=0.0)
    en_route = check_choice("en_route", en_route, ("average", "undamped"))
    for reserved in ("dampers", "label"):
        if reserved in severity_options:
            raise InputError(
                f"The '{reserved}' option cannot be passed to robot_value: it compares its own "
                "three configurations (no damper, the damper parked at x*, the robot at the "
                "antinode), built from 'damper'. For another set of dampers call "
                "aeolian_severity(span, wind_speeds, dampers=...) directly.")
    strouhal = severity_options.get("strouhal", DEFAULT_STROUHAL)
    x_star = harmonic_mean_position(span, speeds, strouhal)
    if isinstance(damper, MDR):
        parked = MDR(x_star, damper.body_mass, damper.suspended_mass, damper.stiffness,
                     damper.damping)
    else:
        parked = ImpedanceDamper(x_star, damper.frequencies, damper.impedance, damper.label)
    none = aeolian_severity(span, speeds, (), label="no damper", **severity_options)
    fixed = aeolian_severity(span, speeds, (parked,), label="fixed damper at x*",
                             **severity_options)
    robot = aeolian_severity(span, speeds, (AtAntinode(damper),), label="robot at antinode",
                             **severity_options)
    if en_route == "average":
        moving = aeolian_severity(span, speeds, (AtAntinode(damper, "robot moving", 0.5),),
                                  label="robot moving", **severity_options)
    else:
        moving = none
    move = np.array([limits.rest_to_rest_time(0.5 * loop) for loop in robot.loop_length])
    at_antinode = np.clip(1.0 - move / persistence, 0.0, 1.0)
    probability = distribution.probability_of(speeds)
    layers = none.parameters["layers"]

    def yearly(sev: SeverityResult) -> np.ndarray:
        cycles = sev.frequency * probability * SECONDS_PER_YEAR
        return cycles / _sbl_cycles(sev.stress_ps, layers)

    def over(sev: SeverityResult) -> np.ndarray:
        return probability * (sev.strain_pp > sev.parameters["endurance_strain_pp"])

    fraction = np.array([
        over(none).sum(), over(fixed).sum(),
        (at_antinode * over(robot) + (1 - at_antinode) * over(moving)).sum()])
    index = np.array([
        yearly(none).sum(), yearly(fixed).sum(),
        (at_antinode * yearly(robot) + (1 - at_antinode) * yearly(moving)).sum()])
    return RobotValue(
        configurations=("no damper", "fixed damper at x*", "robot at antinode"),
        severities=(none, fixed, robot), probability=read_only(probability),
        fixed_position=x_star, move_time=read_only(move),
        time_at_antinode=read_only(at_antinode),
        fraction_over_endurance=read_only(fraction), fatigue_index=read_only(index),
        persistence=persistence, en_route=en_route)


# --------------------------------------------------------------------------- time-domain check
@dataclass(frozen=True)
class TimeDomainCheck:
    """EBM antinode amplitude against a time-domain simulation of the same span.

    Attributes
    ----------
    wind_speed : float
        Wind speed whose Strouhal frequency equals the FE mode ``mode``'s frequency, m/s.
    frequency : float
        That frequency, Hz.
    mode : int
        FE mode number (1-based).
    ebm_amplitude : float
        Energy-balance amplitude, m.
    simulated_amplitude : float
        Steady antinode amplitude of the simulation (harmonic fit over the last periods), m.
    relative_error : float
        simulated / EBM - 1.
    damping_ratio : float
        Equivalent modal damping ratio zeta_eq = 2 P_c(Y) / (m omega^3 Y^2).
    lift_coefficient : float
        C_L of the aeolian load whose power at Y equals P_w(Y): q = 4 P_w / (omega Y).
    n_elements : int
        FE mesh of the simulation.
    clamp_time : ndarray or None
        Sample times of ``clamp_stress``, s (clamped supports only; None otherwise).
    clamp_stress : ndarray or None
        Clamp stress history, Pa: the simulated antinode displacement y(t) times the energy
        balance's sigma_a / Y (its clamp stress per metre of antinode amplitude; the FE mesh
        does not resolve the clamp's few-centimetre boundary layer, so the clamp displacement
        is not read from it). Eight periods at 64 samples per period, for a rainflow count
        (:func:`~powerline_control.severity.fatigue.rainflow_damage`).
    ebm_stress : float or None
        The energy balance's Poffenberger-Swart stress amplitude at the clamp, Pa.

    Examples
    --------
    >>> check = TimeDomainCheck(3.0, 19.8, 6, 8.4e-3, 8.3e-3, -0.012, 3e-4, 0.8, 40)
    >>> abs(check.relative_error) < 0.1
    True
    """

    wind_speed: float
    frequency: float
    mode: int
    ebm_amplitude: float
    simulated_amplitude: float
    relative_error: float
    damping_ratio: float
    lift_coefficient: float
    n_elements: int
    clamp_time: np.ndarray | None = field(default=None, repr=False)
    clamp_stress: np.ndarray | None = field(default=None, repr=False)
    ebm_stress: float | None = None


def time_domain_check(span: Span, wind_speed: float, *, n_elements: int, bc: str = "clamped",
                      damper: MDR | None = None, settle: float = 8.0,
                      samples_per_period: int = 16, **severity_options) -> TimeDomainCheck:
    """Check the EBM amplitude against a :func:`~powerline_control.simulate.simulate` run.

    The wind speed is moved to the one whose Strouhal frequency equals the nearest natural
    frequency of the FE model (lock-in: with a ``damper`` the frequency of the coupled, damped
    mode, from the eigenvalues of the model with the robot). The EBM gives Y, P_w(Y) and P_c(Y)
    (and P_d(Y) of the damper). The simulation uses a linear model with the same powers at that
    amplitude: for y = Y sin(beta x) sin(omega t), a viscous damping c = 2 zeta m omega per metre
    dissipates zeta m omega^3 Y^2 / 2 per metre, so zeta_eq = 2 P_c / (m omega^3 Y^2) (a
    :class:`~powerline_control.fem.ModalDamping`); a lift q sin(beta x) in phase with the
    velocity delivers q omega Y / 4 per metre, so q = 4 P_w / (omega Y) sets the
    :class:`~powerline_control.excitation.AeolianForce` lift coefficient. The damper, if any, is
    the FE model's own MDR (its power is not imposed: the FE computes it). The run starts from
    rest and lasts ``settle`` decay times; the amplitude is a least-squares harmonic fit at each
    node over the last 4 periods, maximised over the nodes.

    Parameters
    ----------
    span : Span
        A modest span (tens of metres) so the run is fast.
    wind_speed : float
        Approximate wind speed, m/s (> 0).
    n_elements : int
        FE mesh (explicit: the default mesh is physics' business).
    bc : {"clamped", "pinned"}
        Supports.
    damper : MDR or None
        A robot/damper attached to the FE model at its position (and to the EBM).
    settle : float
        Decay times to simulate before measuring, 1-50 (default 8: transient e^-8 of the
        start); refused when the settling run would exceed 1e6 samples (a very lightly damped
        mode: a very low wind speed).
    samples_per_period : int
        Samples per vibration period, 4-1024.
    **severity_options
        Passed to :func:`aeolian_severity` (not ``dampers``).

    Returns
    -------
    TimeDomainCheck

    Raises
    ------
    InputError
        For bad arguments, or no energy balance at the locked-in wind speed.

    Examples
    --------
    >>> from powerline_control import Span
    >>> check = time_domain_check(Span.at_rts_fraction(20.0, "drake", 0.2), 2.0, n_elements=40)
    >>> check.mode > 1
    True
    """
    span = _check_span(span)
    speed = check_real("wind_speed", wind_speed, low=0.0, high=MAX_WIND_SPEED)
    n_elements = check_int("n_elements", n_elements, low=2)
    # settle: 1-50 decay times (e^-1 .. e^-50 of the start-up left); 4-1024 samples a period
    settle = check_real("settle", settle, low=1.0, low_inclusive=True, high=50.0)
    samples = check_int("samples_per_period", samples_per_period, low=4, high=1024)
    if damper is not None:
        _check_dampers((damper,), span)
        if not isinstance(damper, MDR):
            raise InputError("The 'damper' parameter of time_domain_check must be an MDR (the "
                             f"FE model carries it). Got {type(damper).__name__}.")
    strouhal = severity_options.get("strouhal", DEFAULT_STROUHAL)
    cond = span.conductor
    target = strouhal * speed / cond.diameter
    # Two DOFs per node less at most four at the supports: checked before the model is built,
    # so that a huge mesh is refused with this function's limit (not LineModel's budget, whose
    # memory_budget argument this function does not take).
    if 2 * (n_elements + 1) - 4 > DENSE_EIGEN_LIMIT:
        raise InputError(
            f"The 'n_elements' parameter ({n_elements}) gives at least {2 * n_elements - 2} DOFs; "
            f"the time-domain check solves all modes densely and accepts up to "
            f"{DENSE_EIGEN_LIMIT} DOFs (n_elements <= {(DENSE_EIGEN_LIMIT + 2) // 2}). Use a "
            "shorter span (tens of metres) or fewer elements.")
    bare = LineModel(span, n_elements=n_elements, bc=bc)
    if bare.n_dofs > DENSE_EIGEN_LIMIT:
        raise InputError(
            f"The 'n_elements' parameter ({n_elements}) gives {bare.n_dofs} DOFs; the time-domain "
            f"check solves all modes densely and accepts up to {DENSE_EIGEN_LIMIT} DOFs. Use a "
            "shorter span (tens of metres) or fewer elements.")
    n_modes = min(bare.n_dofs, max(10, int(3 * target / span.pinned_frequencies(1)[0]) + 5))
    frequencies = bare.natural_frequencies(n_modes)
    index = int(np.argmin(np.abs(frequencies - target)))
    f = float(frequencies[index])
    modal_decay = 0.0
    if damper is not None:
        coupled = LineModel(span, n_elements=n_elements, bc=bc, mdr=damper)
        eigenvalues = np.linalg.eigvals(coupled.to_statespace(n_modes=coupled.n_dofs).A)
        eigenvalues = eigenvalues[eigenvalues.imag > 0]
        nearest = eigenvalues[np.argmin(np.abs(eigenvalues.imag / (2 * math.pi) - f))]
        f = float(nearest.imag / (2 * math.pi))
        modal_decay = float(-nearest.real / abs(nearest))
    speed = f * cond.diameter / strouhal
    dampers = () if damper is None else (damper,)
    sev = aeolian_severity(span, [speed], dampers, bc=bc, **severity_options)
    y = float(sev.amplitude[0])
    if not sev.balanced[0] or y <= 0:
        raise InputError(f"No energy balance at {speed:g} m/s ({sev.status[0]}); choose another "
                         "wind speed.")
    omega = 2 * math.pi * f
    zeta = 2 * float(sev.self_damping_power[0]) / (cond.mass_per_length * omega**3 * y**2)
    q = 4 * float(sev.wind_power[0]) / (omega * y)
    lift = q / (0.5 * AIR_DENSITY * speed**2 * cond.diameter)
    # The settling run samples 4 times a period for settle / ((zeta + decay) omega) seconds:
    # refuse here, naming this function's arguments, when that is beyond any reasonable run.
    settling_samples = 4 * settle / (2 * math.pi * (zeta + modal_decay))
    if not math.isfinite(settling_samples) or settling_samples > 1e6:
        raise InputError(
            f"The 'wind_speed' ({speed:g} m/s after lock-in, mode {index + 1}) gives a damping "
            f"ratio of {zeta + modal_decay:.3g}: 'settle' = {settle:g} decay times would take "
            f"{settling_samples:.3g} samples (at most 1e6). Choose a higher wind speed (a "
            "higher mode, more damped) or a smaller settle.")
    model = LineModel(span, n_elements=n_elements, bc=bc, damping=ModalDamping(zeta), mdr=damper)
    force = AeolianForce(wind_speed=speed, strouhal=strouhal, lift_coefficient=lift,
                         air_density=AIR_DENSITY)
    period = 1.0 / f
    # The settling run only has to carry the state forward (harmonic loads are propagated in
    # closed form, exact at any sample interval), so it samples coarsely (Nyquist 2 f); the
    # measured tail continues from its final state at the fine interval.
    settling = simulate(model, force, duration=settle / ((zeta + modal_decay) * omega),
                        dt=period / 4)
    snap = simulate(model, force, duration=4 * period, dt=period / samples,
                    initial_state=settling.final_state, start_time=float(settling.t[-1]))
    # The steady response to a sine has no mean: the fit needs no constant.
    phasors = np.abs(fit_phasors(snap.true_displacement, snap.t, f, constant=False))
    simulated = float(np.max(phasors))
    clamp_time = clamp_stress = ebm_stress = None
    if bc == "clamped":
        # A stress history for a rainflow count: the simulated antinode displacement, on a fine
        # grid continuing the same steady state, times the energy balance's clamp stress per
        # metre of antinode amplitude (sigma_a / Y: the clamped standing wave's shape at x_b
        # and Poffenberger-Swart's K). The FE mesh does not resolve the clamp's boundary layer
        # (1/alpha, a few cm), so the clamp displacement itself is not read from it.
        antinode = float(snap.x[int(np.argmax(phasors))])
        history = simulate(model, force, duration=8 * period, dt=period / 64,
                           initial_state=settling.final_state,
                           start_time=float(settling.t[-1]), outputs=[antinode])
        clamp_time = read_only(np.asarray(history.t, dtype=float))
        clamp_stress = read_only(float(sev.stress_ps[0]) / y
                                 * np.asarray(history.true_displacement[0], dtype=float))
        ebm_stress = float(sev.stress_ps[0])
    return TimeDomainCheck(wind_speed=speed, frequency=f, mode=index + 1, ebm_amplitude=y,
                           simulated_amplitude=simulated, relative_error=simulated / y - 1,
                           damping_ratio=zeta, lift_coefficient=lift, n_elements=n_elements,
                           clamp_time=clamp_time, clamp_stress=clamp_stress,
                           ebm_stress=ebm_stress)


# --------------------------------------------------------------------------- TB 273 H/w
#: CIGRE TB 273 H/w limits (m) for single undamped conductors by terrain category 1-4.
#: FROM MEMORY (domain.md 2.5 marks them so): verify against TB 273 section 4 before relying on
#: them; pass ``limit=`` with the verified value.
TB273_UNDAMPED_LIMITS_FROM_MEMORY = {1: 1000.0, 2: 1125.0, 3: 1225.0, 4: 1425.0}


@dataclass(frozen=True)
class CatenaryCheck:
    """TB 273 catenary-parameter check H / w against a limit.

    Attributes
    ----------
    catenary_parameter : float
        H / w = T / (m g), m.
    limit : float
        The limit used, m.
    within_limit : bool
        True when H / w <= limit (no damper required by this criterion).
    source : str
        Where the limit comes from (user, or TB 273 from memory, unverified).

    Examples
    --------
    >>> CatenaryCheck(1755.0, 1000.0, False, "user").within_limit
    False
    """

    catenary_parameter: float
    limit: float
    within_limit: bool
    source: str


def catenary_check(span: Span, terrain: int = 1, limit: float | None = None) -> CatenaryCheck:
    """CIGRE TB 273 H/w check of an undamped single conductor.

    Parameters
    ----------
    span : Span
        H is the span's tension, w = m g.
    terrain : int
        Terrain category 1-4 for the built-in limits (FROM MEMORY, unverified against TB 273).
    limit : float or None
        A user-supplied limit, m, which takes precedence.

    Returns
    -------
    CatenaryCheck

    Raises
    ------
    InputError
        For a terrain category other than 1-4, a bad limit, or a tension at or above the
        conductor's rated strength.

    Examples
    --------
    >>> from powerline_control import Span
    >>> check = catenary_check(Span.at_rts_fraction(300.0, "drake", 0.2))
    >>> round(check.catenary_parameter), check.within_limit
    (1755, False)
    """
    if not isinstance(span, Span):
        raise InputError(f"The 'span' parameter must be a Span. Got {type(span).__name__}.")
    rts = span.conductor.rated_strength
    if rts is not None and span.tension >= rts:
        raise InputError(
            f"The 'span.tension' ({span.tension:g} N) must be below the conductor's rated "
            f"strength ({rts:g} N): the conductor would have failed, and no H/w limit applies.")
    h_w = span.tension / (span.conductor.mass_per_length * GRAVITY)
    if limit is not None:
        value = check_real("limit", limit, low=0.0)
        source = "user-supplied limit"
    else:
        if isinstance(terrain, bool) or not isinstance(terrain, numbers.Integral) \
                or terrain not in TB273_UNDAMPED_LIMITS_FROM_MEMORY:
            raise InputError("The 'terrain' parameter must be a TB 273 terrain category 1, 2, "
                             f"3 or 4. Got {terrain!r}.")
        value = TB273_UNDAMPED_LIMITS_FROM_MEMORY[int(terrain)]
        source = (f"CIGRE TB 273, terrain category {terrain}, undamped single conductor: value "
                  "FROM MEMORY, unverified against TB 273 section 4")
    return CatenaryCheck(catenary_parameter=h_w, limit=value, within_limit=h_w <= value,
                         source=source)
