"""The robot (MDR: a body on the line, a suspended mass on a spring and damper), Den Hartog's
optimum for its absorber, and the dampers' impedance: measured tables (ImpedanceDamper), the robot
parked at the antinode (AtAntinode), damper_impedance.  Tuning the absorber to one mode of a
:class:`~powerline_control.fem.LineModel` is :func:`~powerline_control.fem.tune_damper`
(tuning.py).

Near one of its modes the line at the attachment point ``x`` behaves as a single-degree-of-freedom
system with modal mass and stiffness *seen at x*. With mass-normalised mode shapes
(``phi_n^T M phi_n = 1``) and ``phi_n(x)`` the mode's displacement at ``x``:

    M_eff(x) = M_n / phi_n(x)^2 = 1 / phi_n(x)^2,     K_eff(x) = omega_n^2 / phi_n(x)^2.

A body mass ``m_b`` rigidly attached at x adds to ``M_eff`` (and lowers the mode to
``omega_b = sqrt(K_eff / (M_eff + m_b))``). A suspended mass ``m_a`` on a spring and a damper is
then tuned by Den Hartog's optimum for an undamped main system under a harmonic force
(J. P. Den Hartog, *Mechanical Vibrations*, 4th ed., McGraw-Hill 1956, section 3.3; also
Brock 1946):

    mu = m_a / (M_eff + m_b)
    f_opt = omega_a / omega_b = 1 / (1 + mu)                     (equal fixed points)
    zeta_opt = c / (2 m_a omega_b) = sqrt(3 mu / (8 (1 + mu)^3))   (flat at the fixed points)

so ``k = m_a (f_opt omega_b)^2`` and ``c = 2 zeta_opt m_a omega_b``. Note that zeta is measured
against the critical damping ``2 m_a omega_b`` of the absorber mass at the *main* system's
frequency, as in Den Hartog; against the absorber's own frequency it reads
``sqrt(3 mu / (8 (1 + mu)))``. The receptance of the tuned pair then peaks at
``sqrt(1 + 2 / mu)`` times the static deflection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validation import check_array, check_real
from ..errors import InputError

__all__ = ["MDR", "den_hartog_optimum", "ImpedanceDamper", "AtAntinode", "damper_impedance"]


@dataclass(frozen=True)
class MDR:
    """The mobile damping robot as in the paper's eqs. (3)-(6).

    A body of mass ``body_mass`` rides the line at ``position`` (the paper's F1 = m ÿ(x_r)); a
    suspended mass ``suspended_mass`` hangs from it on a spring ``stiffness`` and a damper
    ``damping`` (F2 = k (y - y_d) + c (ẏ - ẏ_d), m_d ÿ_d = F2 ... sign as in the paper's eq. 6).

    Parameters
    ----------
    position : float
        Distance from the left support, m.
    body_mass : float
        Mass rigidly attached to the line, kg (>= 0).
    suspended_mass : float
        Tuned mass, kg (>= 0; 0 means no absorber, only the body).
    stiffness : float
        Suspension spring, N/m (> 0 when ``suspended_mass`` > 0).
    damping : float
        Suspension damper, N s/m (>= 0).

    Examples
    --------
    >>> robot = MDR.tuned(position=0.915, body_mass=0.05, suspended_mass=0.02, frequency=6.5)
    >>> round(robot.stiffness, 2)
    33.36
    """

    position: float
    body_mass: float = 0.0
    suspended_mass: float = 0.0
    stiffness: float = 0.0
    damping: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "position", check_real("position", self.position, low=0.0, low_inclusive=True)
        )
        for name in ("body_mass", "suspended_mass", "stiffness", "damping"):
            object.__setattr__(
                self, name, check_real(name, getattr(self, name), low=0.0, low_inclusive=True)
            )
        if self.suspended_mass > 0 and self.stiffness == 0:
            raise InputError(
                "The 'stiffness' parameter of MDR must be > 0 when suspended_mass > 0 "
                "(a free suspended mass has a zero-frequency rigid mode). Got 0.0."
            )

    @classmethod
    def tuned(
        cls,
        position: float,
        body_mass: float,
        suspended_mass: float,
        frequency: float,
        damping_ratio: float = 0.0,
    ) -> MDR:
        """An MDR whose suspended mass is tuned to ``frequency`` (Hz) with a damping ratio.

        Examples
        --------
        >>> round(MDR.tuned(1.0, 0.0, 0.01, frequency=10.0, damping_ratio=0.05).damping, 4)
        0.0628
        """
        omega = 2 * np.pi * check_real("frequency", frequency, low=0.0)
        ratio = check_real("damping_ratio", damping_ratio, low=0.0, low_inclusive=True)
        mass = check_real("suspended_mass", suspended_mass, low=0.0)
        if not np.isfinite(mass * omega * omega):  # frequency ~1e300 Hz: stiffness overflows
            raise InputError(f"The 'frequency' parameter ({frequency!r} Hz) makes the absorber "
                             "stiffness overflow; give the tuning frequency in Hz.")
        return cls(position, body_mass, mass, mass * omega**2, 2 * ratio * mass * omega)

    @property
    def has_absorber(self) -> bool:
        """True when the robot carries a suspended mass (an extra DOF)."""
        return self.suspended_mass > 0


def den_hartog_optimum(mass_ratio: float) -> tuple[float, float]:
    """Den Hartog's optimal frequency ratio and damping ratio for a mass ratio ``mu``.

    Parameters
    ----------
    mass_ratio : float
        mu = absorber mass / main (effective) mass, > 0.

    Returns
    -------
    (float, float)
        ``f_opt = 1 / (1 + mu)`` and ``zeta_opt = sqrt(3 mu / (8 (1 + mu)^3))`` (zeta against
        ``2 m_a omega_main``), Den Hartog, *Mechanical Vibrations* (1956), section 3.3.

    Examples
    --------
    >>> f, z = den_hartog_optimum(0.1)
    >>> round(f, 4), round(z, 4)
    (0.9091, 0.1679)
    """
    mu = check_real("mass_ratio", mass_ratio, low=0.0)
    # sqrt(3 mu / (8 (1 + mu)^3)) written so that (1 + mu)^3 cannot overflow (mu = 1e300).
    return 1.0 / (1.0 + mu), float(np.sqrt(3.0 / 8.0 * (mu / (1.0 + mu))) / (1.0 + mu))


# --------------------------------------------------------------------------- impedance
def _check_label(value: object) -> str:
    """A label: a string (None or a number is a mistake, not a name)."""
    if not isinstance(value, str):
        raise InputError(f"The 'label' parameter must be a string. Got {value!r:.60} of type "
                         f"{type(value).__name__}.")
    return value


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
        _check_label(self.label)

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
        _check_label(self.label)


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
