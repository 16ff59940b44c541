"""Physical parameters of a conductor and a span, and the conductor preset catalogue.

The presets live in ``data/conductors.toml`` inside the package, with their sources.
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ._validation import check_int, check_real
from .errors import InputError, PresetNotFoundError

__all__ = ["Conductor", "Span", "conductors", "PAPER_LAB_MASS_PER_LENGTH"]

#: Table 1 of the paper gives "mass 0.68 kg": the mass of the whole 3.66 m specimen.
PAPER_LAB_MASS_PER_LENGTH = 0.68 / 3.66


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

    Examples
    --------
    >>> cond = Conductor(mass_per_length=1.628, diameter=0.02814, ei=44.0, rated_strength=140.1e3)
    >>> round(cond.tension_at(0.20))
    28020
    """

    mass_per_length: float
    diameter: float
    ei: float
    rated_strength: float | None = None
    name: str = "custom"

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "mass_per_length", check_real("mass_per_length", self.mass_per_length, low=0.0)
        )
        object.__setattr__(self, "diameter", check_real("diameter", self.diameter, low=0.0))
        object.__setattr__(self, "ei", check_real("ei", self.ei, low=0.0, low_inclusive=True))
        if self.rated_strength is not None:
            object.__setattr__(
                self, "rated_strength", check_real("rated_strength", self.rated_strength, low=0.0)
            )

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
        conductor = Conductor(mass_per_length=mass, diameter=0.0105, ei=40.8,
                              rated_strength=None, name="paper lab (Table 1)")
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
        f = np.asarray(frequency, dtype=float)
        if np.any(~np.isfinite(f)) or np.any(f < 0):
            raise InputError(
                f"The 'frequency' parameter must be finite and >= 0. Got {frequency!r}."
            )
        cond = self.conductor
        mw2 = cond.mass_per_length * (2 * np.pi * f) ** 2
        t = self.tension
        k2 = 2 * mw2 / (t + np.sqrt(t**2 + 4 * cond.ei * mw2)) if t > 0 else np.sqrt(mw2 / cond.ei)
        k = np.sqrt(k2)
        return float(k) if np.ndim(k) == 0 else k

    def loop_length(self, frequency: float | np.ndarray) -> float | np.ndarray:
        """Half wavelength pi / k (m) of the standing wave at ``frequency`` (Hz): one loop.

        Examples
        --------
        >>> round(Span.at_rts_fraction(300.0, "drake", 0.20).loop_length(46.0), 3)
        1.431
        """
        return np.pi / self.wavenumber(frequency)

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
        k = np.arange(1, n_modes + 1) * np.pi / self.length
        cond = self.conductor
        omega = np.sqrt((cond.ei * k**4 + self.tension * k**2) / cond.mass_per_length)
        return omega / (2 * np.pi)


class _ConductorCatalogue(Mapping[str, Conductor]):
    """Read-only mapping of preset names to :class:`Conductor`, loaded from the package data."""

    def __init__(self) -> None:
        text = resources.files(__package__).joinpath("data/conductors.toml").read_text()
        self._raw = tomllib.loads(text)
        self._presets = {
            name: Conductor(
                mass_per_length=entry["mass_per_length"], diameter=entry["diameter"],
                ei=entry["ei"], rated_strength=entry.get("rated_strength"), name=name,
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
