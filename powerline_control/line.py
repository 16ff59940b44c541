"""Physical parameters of a conductor and a span, and the conductor preset catalogue.

The presets live in ``data/conductors.toml`` inside the package, with their sources.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ._constants import GRAVITY
from ._validation import (
    check_array,
    check_budget,
    check_choice,
    check_int,
    check_real,
    checked_keywords,
)
from .errors import InputError, PresetNotFoundError

__all__ = ["Conductor", "Span", "conductors", "tension_at_temperature",
           "PAPER_LAB_MASS_PER_LENGTH"]

#: Table 1 of the paper gives "mass 0.68 kg": the mass of the whole 3.66 m specimen.
PAPER_LAB_MASS_PER_LENGTH = 0.68 / 3.66


#: Conductor families by their stranding: all-aluminium, all-aluminium-alloy, aluminium
#: conductor alloy-reinforced, steel-reinforced (ACSR, ACSS: annealed aluminium; AACSR: alloy),
#: composite-cored (ACCC, ACCR).
CONDUCTOR_FAMILIES = ("AAC", "AAAC", "ACAR", "ACSR", "ACSS", "AACSR", "ACCC", "ACCR")


@dataclass(frozen=True)
class Conductor:
    """Mechanical properties of a conductor.

    Parameters
    ----------
    mass_per_length : float
        Mass per unit length, kg/m (> 0).
    diameter : float
        Outer diameter, m (> 0); sets the vortex-shedding frequency.
    ei : float
        Bending stiffness EI, N m^2 (>= 0; 0 gives a taut string).
    rated_strength : float or None
        Rated tensile strength (RTS), N (> 0), where known.
    name : str
        Label used in reports.
    area : float or None
        Total cross-section of the wires, m^2 (> 0), where known; with ``elastic_modulus`` and
        ``thermal_expansion`` it sets the change of state (:func:`tension_at_temperature`).
    elastic_modulus : float or None
        Creep-free (final) elastic modulus of the whole conductor, Pa (> 0), where known.
    thermal_expansion : float or None
        Linear thermal expansion coefficient of the whole conductor, 1/K (> 0), where known.
    outer_strand_diameter : float or None
        Diameter of the wires of the outer layer, m (> 0, below ``diameter``), where known: the
        bending strain at the clamp is read on them (severity, clamp strain).
    family : str or None
        The conductor family, one of ``CONDUCTOR_FAMILIES``, where known: endurance strains are
        published per family, so the severity study compares clamp strain with the ACSR
        endurance strain only on an ACSR conductor.

    Examples
    --------
    >>> cond = Conductor(mass_per_length=1.628, diameter=0.02814, ei=44.0, rated_strength=140.1e3)
    >>> round(cond.tension_at(0.20))
    28020
    >>> round(conductors["drake"].area * 1e6, 1)  # mm^2
    468.0
    """

    mass_per_length: float
    diameter: float
    ei: float
    rated_strength: float | None = None
    name: str = "custom"
    area: float | None = None
    elastic_modulus: float | None = None
    thermal_expansion: float | None = None
    outer_strand_diameter: float | None = None
    family: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise InputError(f"The 'name' parameter must be a string (a label). Got "
                             f"{self.name!r:.60} of type {type(self.name).__name__}.")
        if self.family is not None:
            check_choice("family", self.family, CONDUCTOR_FAMILIES)
        object.__setattr__(
            self, "mass_per_length", check_real("mass_per_length", self.mass_per_length, low=0.0)
        )
        object.__setattr__(self, "diameter", check_real("diameter", self.diameter, low=0.0))
        object.__setattr__(self, "ei", check_real("ei", self.ei, low=0.0, low_inclusive=True))
        if self.rated_strength is not None:
            object.__setattr__(
                self, "rated_strength", check_real("rated_strength", self.rated_strength, low=0.0)
            )
        for field_name in ("area", "elastic_modulus", "thermal_expansion"):
            value = getattr(self, field_name)
            if value is not None:
                object.__setattr__(self, field_name, check_real(field_name, value, low=0.0))
        if self.outer_strand_diameter is not None:
            object.__setattr__(self, "outer_strand_diameter", check_real(
                "outer_strand_diameter", self.outer_strand_diameter, low=0.0,
                high=self.diameter, high_inclusive=False))

    def tension_at(self, fraction_of_rts: float) -> float:
        """Everyday tension as a fraction of the rated strength, N.

        Parameters
        ----------
        fraction_of_rts : float
            Fraction in (0, 1); everyday practice is 0.15-0.25 (CIGRE TB 273).

        Returns
        -------
        float
            Tension in newtons.

        Raises
        ------
        InputError
            If the conductor has no rated strength or the fraction is outside (0, 1).

        Examples
        --------
        >>> round(conductors["drake"].tension_at(0.2))
        28020
        """
        fraction = check_real("fraction_of_rts", fraction_of_rts, low=0.0, high=1.0,
                              high_inclusive=False)
        if self.rated_strength is None:
            raise InputError(
                f"Conductor {self.name!r} has no rated_strength, so a tension cannot be given as "
                "a fraction of it; pass the tension in newtons instead."
            )
        return fraction * self.rated_strength


@dataclass(frozen=True)
class Span:
    """A span between two supports.

    Parameters
    ----------
    length : float
        Distance between the supports, m (> 0).
    tension : float
        Horizontal tension, N (>= 0; 0 gives a beam).
    conductor : Conductor
        The conductor strung in the span.

    Examples
    --------
    >>> span = Span(length=300.0, tension=28e3, conductor=conductors["drake"])
    >>> round(span.wave_speed, 1)
    131.1
    """

    length: float
    tension: float
    conductor: Conductor

    def __post_init__(self) -> None:
        object.__setattr__(self, "length", check_real("length", self.length, low=0.0))
        object.__setattr__(
            self, "tension", check_real("tension", self.tension, low=0.0, low_inclusive=True)
        )
        if not isinstance(self.conductor, Conductor):
            raise InputError(
                "The 'conductor' parameter must be a Conductor. "
                f"Got {type(self.conductor).__name__} instead."
            )
        if self.tension == 0.0 and self.conductor.ei == 0.0:
            raise InputError(
                "A span needs tension > 0 or conductor.ei > 0: with both zero it has no stiffness."
            )
        rts = self.conductor.rated_strength
        if rts is not None and self.tension >= rts:
            # At or above the rated tensile strength the conductor breaks: no answer about its
            # vibration means anything (everyday tensions are 15-25 % RTS).
            raise InputError(
                f"The 'tension' parameter ({self.tension:.6g} N) must be below the conductor's "
                f"rated tensile strength ({rts:.6g} N): {100 * self.tension / rts:.3g} % RTS "
                "breaks it. Everyday tensions are 15-25 % RTS."
            )

    @classmethod
    def paper_lab(cls, mass_reading: str = "total") -> Span:
        """The laboratory span of the paper's Table 1.

        L = 3.66 m, T = 395 N, d = 10.5 mm, EI = 40.8 N m^2 (printed "m^4", a unit typo).
        Table 1's "mass 0.68 kg" is read as the mass of the whole span, so
        m = 0.68 / 3.66 = 0.1858 kg/m: the catalogue mass of a 10.5 mm AAC conductor, whose
        solid-section EI is the printed 40.8 N m^2.

        Parameters
        ----------
        mass_reading : {"total", "per_metre"}
            "total" (default) reads 0.68 kg as the span's mass; "per_metre" takes the printed
            number as 0.68 kg/m (a solid steel rod of that diameter), for comparison.

        Returns
        -------
        Span

        Examples
        --------
        >>> span = Span.paper_lab()
        >>> round(span.conductor.mass_per_length, 4)
        0.1858
        """
        if mass_reading == "total":
            mass = PAPER_LAB_MASS_PER_LENGTH
        elif mass_reading == "per_metre":
            mass = 0.68
        else:
            raise InputError(
                "The 'mass_reading' parameter must be 'total' or 'per_metre'. "
                f"Got {mass_reading!r} instead."
            )
        # Table 1's 10.5 mm conductor matches AAC 2/0 "Oxlip", 7 strands of 3.50 mm
        # (data/conductors.toml); the paper names neither stranding nor material, so both are
        # that match, assumed (the severity study says so).
        conductor = Conductor(mass_per_length=mass, diameter=0.0105, ei=40.8,
                              rated_strength=None, name="paper lab (Table 1)",
                              outer_strand_diameter=3.50e-3, family="AAC")
        return cls(length=3.66, tension=395.0, conductor=conductor)

    @classmethod
    def at_rts_fraction(cls, length: float, conductor: Conductor | str,
                        fraction_of_rts: float = 0.20) -> Span:
        """A span strung at an everyday tension given as a fraction of rated strength.

        Parameters
        ----------
        length : float
            Span length, m.
        conductor : Conductor or str
            A conductor or the name of a preset in :data:`conductors`.
        fraction_of_rts : float
            Tension as a fraction of the rated tensile strength (default 0.20).

        Returns
        -------
        Span

        Examples
        --------
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.20)
        >>> round(span.tension)
        28020
        """
        cond = conductors[conductor] if isinstance(conductor, str) else conductor
        if not isinstance(cond, Conductor):
            raise InputError(
                "The 'conductor' parameter must be a preset name (see conductors) or a "
                f"Conductor. Got {type(conductor).__name__}."
            )
        return cls(length=length, tension=cond.tension_at(fraction_of_rts), conductor=cond)

    @property
    def wave_speed(self) -> float:
        """Transverse wave speed of the taut string, sqrt(T/m), m/s."""
        return float(np.sqrt(self.tension / self.conductor.mass_per_length))

    @property
    def boundary_layer(self) -> float:
        """Width of the bending boundary layer at a clamp, sqrt(EI / T), m (inf without tension).

        Within about this distance of a clamped support the slope turns from zero to the slope of
        the travelling wave; a mesh must resolve it for clamped frequencies to converge at the
        interior rate.

        Examples
        --------
        >>> round(Span.at_rts_fraction(300.0, "drake", 0.20).boundary_layer, 4)
        0.0396
        """
        if self.tension == 0.0:
            return float("inf")
        return float(np.sqrt(self.conductor.ei / self.tension))

    def wavenumber(self, frequency: float | np.ndarray) -> float | np.ndarray:
        """Wavenumber k (rad/m) of a free wave at ``frequency`` (Hz), from the taut-beam dispersion.

        m omega^2 = EI k^4 + T k^2, so k^2 = (-T + sqrt(T^2 + 4 EI m omega^2)) / (2 EI) (the string
        limit omega / c when EI = 0). Written as 2 m omega^2 / (T + sqrt(...)) to avoid the
        cancellation of the first form on tension-dominated spans.

        Examples
        --------
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.20)
        >>> round(float(span.wavenumber(span.pinned_frequencies(10)[-1])) * 300 / np.pi, 6)
        10.0
        """
        # check_array refuses text ("1.0" would parse), bools, complex and NaN/inf
        f = check_array("frequency", frequency)
        if np.any(f < 0):
            raise InputError(
                f"The 'frequency' parameter must be finite and >= 0. Got {frequency!r}."
            )
        cond = self.conductor
        omega = 2 * np.pi * f
        t = self.tension
        with np.errstate(over="ignore", invalid="ignore"):
            # k = omega sqrt(2 m / (T + sqrt(T^2 + 4 EI m omega^2))): omega^2 never stands alone,
            # so a tiny frequency does not underflow to k = 0 (an infinite loop)
            if t > 0:
                k = omega * np.sqrt(2 * cond.mass_per_length
                                    / (t + np.sqrt(t**2 + 4 * cond.ei * cond.mass_per_length
                                                   * omega**2)))
            else:
                k = np.sqrt(omega) * (cond.mass_per_length / cond.ei) ** 0.25
        if not np.all(np.isfinite(k)) or np.any((k == 0) & (f > 0)):
            raise InputError(
                f"The 'frequency' parameter is out of range: {frequency!r} Hz has no finite "
                "wavenumber on this span."
            )
        return float(k) if np.ndim(k) == 0 else k

    def loop_length(self, frequency: float | np.ndarray) -> float | np.ndarray:
        """Half wavelength pi / k (m) of the standing wave at ``frequency`` (Hz): one loop.

        Examples
        --------
        >>> round(Span.at_rts_fraction(300.0, "drake", 0.20).loop_length(46.0), 3)
        1.431
        >>> Span.paper_lab().loop_length(0.0)   # a static load has no loops
        inf
        """
        k = np.asarray(self.wavenumber(frequency), dtype=float)
        with np.errstate(divide="ignore"):
            loop = np.pi / k   # inf at f = 0: a static load has no finite loop
        return float(loop) if np.ndim(loop) == 0 else loop

    def standing_wave_shape(self, frequency: float, position: np.ndarray | float,
                            bc: str = "clamped") -> np.ndarray:
        """Relative amplitude phi(x) of the standing wave at ``position`` (m); 1 at antinodes.

        Measured from the nearer support (a node). Pinned: phi = sin(beta d). Clamped: the exact
        shape of a semi-infinite clamped taut beam, (sin beta d - (beta/alpha)(cos beta d -
        exp(-alpha d))) / sqrt(1 + (beta/alpha)^2), with beta the travelling wavenumber
        (:meth:`wavenumber`) and alpha^2 = beta^2 + T / EI the evanescent one, whose bending
        boundary layer (width 1/alpha) shifts the nodes slightly away from the clamp.

        Examples
        --------
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> round(float(span.standing_wave_shape(6.57, span.loop_length(6.57) / 2, "pinned")), 9)
        1.0
        """
        bc = check_choice("bc", bc, ("clamped", "pinned"))
        x = check_array("position", position)
        if np.any(x < 0) or np.any(x > self.length):
            raise InputError(f"The 'position' parameter must lie in [0, {self.length:g}] m (the "
                             f"span). Got values from {x.min():g} to {x.max():g}.")
        d = np.minimum(x, self.length - x)
        beta = float(self.wavenumber(frequency))
        ei = self.conductor.ei
        if bc == "pinned" or ei <= 0:
            return np.sin(beta * d)
        alpha = math.sqrt(beta**2 + self.tension / ei)
        ratio = beta / alpha
        return (np.sin(beta * d) - ratio * (np.cos(beta * d) - np.exp(-alpha * d))) \
            / math.sqrt(1 + ratio**2)

    def frequency_of_wavenumber(self, wavenumber: float | np.ndarray) -> float | np.ndarray:
        """Frequency (Hz) of a free wave of wavenumber k (rad/m): the inverse of :meth:`wavenumber`.

        Examples
        --------
        >>> span = Span.paper_lab()
        >>> round(float(span.frequency_of_wavenumber(np.pi / span.length)), 3)
        6.534
        """
        k = np.asarray(wavenumber, dtype=float)
        cond = self.conductor
        f = np.sqrt((cond.ei * k**4 + self.tension * k**2) / cond.mass_per_length) / (2 * np.pi)
        return float(f) if np.ndim(f) == 0 else f

    def pinned_frequencies(self, n_modes: int) -> np.ndarray:
        """Closed-form natural frequencies (Hz) of the pinned-pinned taut beam.

        omega_n^2 = (EI (n pi / L)^4 + T (n pi / L)^2) / m.

        Examples
        --------
        >>> Span.paper_lab().pinned_frequencies(2).round(3)
        array([ 6.534, 14.388])
        """
        n_modes = check_int("n_modes", n_modes, low=1)
        check_budget(f"pinned_frequencies({n_modes})", nbytes=32.0 * n_modes,
                     parameter="n_modes", value=n_modes, fix="ask for fewer modes")
        k = np.arange(1, n_modes + 1) * np.pi / self.length
        cond = self.conductor
        omega = np.sqrt((cond.ei * k**4 + self.tension * k**2) / cond.mass_per_length)
        return omega / (2 * np.pi)


#: Absolute zero, degC: a temperature at or below it is refused.
_ABSOLUTE_ZERO = -273.15
#: Melting point of aluminium, degC: no conductor temperature above it has a change of state
#: (1e300 degC overflowed the cubic to NaN).
_ALUMINIUM_MELTING = 660.3


@checked_keywords
def tension_at_temperature(span: Span, temperature: float | np.ndarray,
                           reference_temperature: float = 15.0, *,
                           load: float | None = None,
                           reference_load: float | None = None) -> float | np.ndarray:
    """Horizontal tension (N) at a conductor temperature: the change of state of a level span.

    ``span.tension`` is the tension at ``reference_temperature``. The conductor length of a level
    parabolic span, S + w^2 S^3 / (24 H^2), must change with the elastic and thermal strain,
    (H - H_ref) / (E A) + alpha (t - t_ref); that is the parabolic change-of-state equation

        H^2 [H - H_ref + E A w_ref^2 S^2 / (24 H_ref^2) + E A alpha (t - t_ref)] = E A w^2 S^2 / 24

    (S span length, w load per metre, E A axial stiffness, alpha expansion; creep-free, the
    supports do not move), a cubic with one positive root, found by Newton's method from above
    (the cubic is convex and increasing there, so the iteration converges monotonically).
    Use it for a ruling span: the tension of a section of suspension spans is that of its
    ruling span.

    Parameters
    ----------
    span : Span
        Length, tension at ``reference_temperature`` and conductor; the conductor needs
        ``area``, ``elastic_modulus`` and ``thermal_expansion`` (every preset has them).
    temperature : float or ndarray
        Conductor temperature(s), degC.
    reference_temperature : float
        Temperature at which the span has ``span.tension``, degC (default 15, the everyday
        temperature of CIGRE TB 273's tension criteria).
    load : float or None
        Load per metre at ``temperature``, N/m (default the conductor's weight m g; give the
        resultant of weight, ice and wind for a loaded state).
    reference_load : float or None
        Load per metre in the reference state, N/m (default the conductor's weight m g).

    Returns
    -------
    float or ndarray
        Horizontal tension, N (a float for a scalar temperature).

    Raises
    ------
    InputError
        If the conductor lacks a change-of-state property, a temperature is not finite or at or
        below absolute zero, or the tension would reach the conductor's rated strength.

    Examples
    --------
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.20)      # 28.02 kN at 15 degC
    >>> round(tension_at_temperature(span, 15.0))
    28020
    >>> [round(t) for t in tension_at_temperature(span, np.array([-5.0, 40.0]))]
    [32050, 24368]
    """
    if not isinstance(span, Span):
        raise InputError(f"The 'span' parameter must be a Span. Got {type(span).__name__}.")
    cond = span.conductor
    for name in ("area", "elastic_modulus", "thermal_expansion"):
        if getattr(cond, name) is None:
            raise InputError(
                f"The change of state needs conductor.{name}; conductor {cond.name!r} has none. "
                "Use a preset (conductors[...]) or give Conductor(..., area=, elastic_modulus=, "
                "thermal_expansion=).")
    if span.tension <= 0:
        raise InputError("The change of state needs span.tension > 0 (a strung conductor). "
                         f"Got {span.tension!r}.")
    t_ref = check_real("reference_temperature", reference_temperature, low=_ABSOLUTE_ZERO,
                       high=_ALUMINIUM_MELTING)
    scalar = np.ndim(temperature) == 0
    t = np.atleast_1d(np.asarray(temperature))
    if t.dtype.kind not in "iuf" or t.ndim != 1 or not np.all(np.isfinite(t)) \
            or np.any(t <= _ABSOLUTE_ZERO) or np.any(t > _ALUMINIUM_MELTING):
        raise InputError("The 'temperature' parameter must be a real number or 1-D array of "
                         f"finite temperatures above {_ABSOLUTE_ZERO} degC and at most "
                         f"{_ALUMINIUM_MELTING} degC (aluminium melts). Got {temperature!r}.")
    t = t.astype(float)
    weight = cond.mass_per_length * GRAVITY
    # loads up to 1e5 N/m (a hundred times a heavily iced conductor's): a bound that keeps the
    # cubic's coefficients finite
    w = weight if load is None else check_real("load", load, low=0.0, high=1e5)
    w_ref = weight if reference_load is None else check_real("reference_load", reference_load,
                                                             low=0.0, high=1e5)
    ea = cond.elastic_modulus * cond.area
    h_ref = span.tension
    s2 = span.length**2
    k = ea * w**2 * s2 / 24.0
    c = ea * w_ref**2 * s2 / (24.0 * h_ref**2) - h_ref + ea * cond.thermal_expansion * (t - t_ref)
    # f(H) = H^3 + c H^2 - k: f(H_hi) >= k - k = 0 at H_hi = max(0, -c) + k^(1/3), and f is
    # convex and increasing on [root, H_hi] (the root exceeds max(0, -c) >= -c/3).
    h = np.maximum(0.0, -c) + np.cbrt(k)
    for _ in range(200):
        f = h**3 + c * h**2 - k
        step = f / (3 * h**2 + 2 * c * h)
        h = h - step
        if np.all(np.abs(step) <= 4 * np.finfo(float).eps * h):
            break
    rts = cond.rated_strength
    if rts is not None and np.any(h >= rts):
        worst = float(t[np.argmax(h)])
        raise InputError(
            f"The change of state gives a tension of {float(h.max()):.6g} N at {worst:g} degC, "
            f"at or above the rated strength of {cond.name!r} ({rts:g} N): the span cannot be "
            "strung at this reference tension for that temperature.")
    return float(h[0]) if scalar else h


class _ConductorCatalogue(Mapping[str, Conductor]):
    """Read-only mapping of preset names to :class:`Conductor`, loaded from the package data."""

    def __init__(self) -> None:
        text = resources.files(__package__).joinpath("data/conductors.toml").read_text()
        self._raw = tomllib.loads(text)
        self._presets = {
            name: Conductor(
                mass_per_length=entry["mass_per_length"], diameter=entry["diameter"],
                ei=entry["ei"], rated_strength=entry.get("rated_strength"), name=name,
                area=entry.get("area"), elastic_modulus=entry.get("elastic_modulus"),
                thermal_expansion=entry.get("thermal_expansion"),
                outer_strand_diameter=entry.get("outer_strand_diameter"),
                family=entry.get("family"),
            )
            for name, entry in self._raw.items()
        }

    def __getitem__(self, name: str) -> Conductor:
        try:
            return self._presets[name]
        except KeyError:
            allowed = ", ".join(repr(n) for n in self._presets)
            raise PresetNotFoundError(
                f"Unknown conductor preset {name!r}; the presets are {allowed}."
            ) from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._presets)

    def __len__(self) -> int:
        return len(self._presets)

    def source(self, name: str) -> str:
        """Where the numbers of preset ``name`` come from."""
        self[name]
        return self._raw[name]["source"]


#: The preset catalogue: ``conductors["drake"]``, ``list(conductors)``.
conductors = _ConductorCatalogue()
