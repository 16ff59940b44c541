"""Wind power input (the CIGRE curve and digitised curves, turbulence) and conductor
self-damping laws (the power-law exponent sets of domain.md 2.2; the physical model is in
self_damping)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.interpolate
import scipy.optimize

from .._validation import (
    check_array,
    check_choice,
    check_real,
)
from ..errors import InputError
from ..line import Span
from ._common import (
    _check_amplitudes,
    _check_frequency,
    _check_span,
    _check_text,
    _finite_power,
)
from .self_damping import FotiMartinelli

__all__ = [
    "WIND_POWER_CURVES",
    "SELF_DAMPING_LAWS",
    "WindPowerCurve",
    "SelfDampingLaw",
    "turbulence_factor",
    "wind_power",
    "self_damping_power",
]


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
                 exponents: Sequence[float] | None) -> SelfDampingLaw | FotiMartinelli:
    if isinstance(self_damping, FotiMartinelli):
        if k is not None or exponents is not None:
            raise InputError(
                "The 'self_damping_k' and 'self_damping_exponents' parameters apply to power "
                "laws only; a FotiMartinelli model has its own EI_max and limit curvature. Got "
                f"self_damping_k={k!r}, self_damping_exponents={exponents!r}.")
        return self_damping
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
                       self_damping: str | SelfDampingLaw | FotiMartinelli = "noiseux1991",
                       self_damping_k: float | None = None,
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
    self_damping : str, SelfDampingLaw or FotiMartinelli
        A name of :data:`SELF_DAMPING_LAWS`, a law, or the physical model
        :class:`FotiMartinelli` (then ``self_damping_k`` and ``self_damping_exponents`` must be
        None).
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
    return _finite_power(law.power(_check_amplitudes(amplitude), frequency, span),
                         "self-damping power")
