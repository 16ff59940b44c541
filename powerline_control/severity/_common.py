"""What the severity modules share: constants with their sources and the argument checks of
spans, frequencies, powers, labels and the robot (its damper and limits)."""

from __future__ import annotations

import numpy as np

from .._constants import AIR_DENSITY, GRAVITY  # noqa: F401  (re-exported by severity)
from .._validation import check_array, check_real
from ..errors import InputError
from ..fem import MDR, ImpedanceDamper
from ..line import Span, conductors
from ..plan import RobotLimits


def _check_text(name: str, value: object) -> str:
    """A label or source: a string (None or a number is a mistake, not a name)."""
    if not isinstance(value, str):
        raise InputError(f"The '{name}' parameter must be a string. Got {value!r:.60} of type "
                         f"{type(value).__name__}.")
    return value


SECONDS_PER_YEAR = 365.25 * 86400.0
#: Young's modulus of the aluminium outer strands, Pa (domain.md 2.6, E_Al).
ALUMINIUM_MODULUS = 68.9e9
#: Poffenberger-Swart measuring point: 89 mm from the last point of contact (IEEE 1966).
POFFENBERGER_SWART_DISTANCE = 0.089
#: Usual laboratory endurance strain, peak-to-peak (Diana et al., IEEE TPWRD 18(4), 2003).
ENDURANCE_STRAIN_PP = 150e-6
#: The conductor family that endurance strain belongs to (CIGRE / EPRI, for ACSR): on another
#: family (AAC, AAAC) or an unknown one the severity report draws no endurance line.
ENDURANCE_FAMILY = "ACSR"
#: Outer-strand diameters of the presets, m: a view of ``Conductor.outer_strand_diameter``
#: (stranding in domain.md 2.6 and data/conductors.toml, where the numbers live).
OUTER_STRAND_DIAMETER = {name: cond.outer_strand_diameter for name, cond in conductors.items()
                         if cond.outer_strand_diameter is not None}


# Upper bounds far above any aeolian case (~1-7 m/s, <= a few hundred Hz) and far below float
# overflow of f^3, f^5.63 or omega^2 (a frequency of 1e300 Hz raised a raw OverflowError).
MAX_FREQUENCY = 1e5
MAX_WIND_SPEED = 100.0


def _check_frequency(frequency: object) -> float:
    return check_real("frequency", frequency, low=0.0, high=MAX_FREQUENCY)


def _check_amplitudes(amplitude: object) -> np.ndarray:
    """Antinode amplitudes Y, zero-to-peak, m, >= 0 (Y^2.44 of a negative one is NaN)."""
    y = check_array("amplitude", amplitude)
    if np.any(y < 0):
        raise InputError("The 'amplitude' parameter must be >= 0 m (a zero-to-peak antinode "
                         f"amplitude). Got {float(np.min(y)):g}.")
    return y


def _finite_power(power: np.ndarray, what: str) -> np.ndarray:
    if not np.all(np.isfinite(power)):
        raise InputError(f"The 'amplitude' parameter is too large: the {what} overflows. Give "
                         "antinode amplitudes in m (a few conductor diameters at most).")
    return power


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


def _check_wind_speeds(wind_speeds: object) -> np.ndarray:
    speeds = np.atleast_1d(check_array("wind_speeds", wind_speeds, ndim=(0, 1)))
    if speeds.size == 0 or np.any(speeds <= 0) or np.any(speeds > MAX_WIND_SPEED):
        bad = (speeds[(speeds <= 0) | (speeds > MAX_WIND_SPEED)].tolist()[:5] if speeds.size
               else "an empty list")
        raise InputError(f"The 'wind_speeds' parameter must hold wind speeds > 0 and <= "
                         f"{MAX_WIND_SPEED:g} m/s (aeolian vibration occurs at about 1-7 m/s). "
                         f"Got {bad}.")
    return speeds


def _check_robot_damper(damper: object) -> None:
    """The robot's damper: an MDR or an ImpedanceDamper (a placement wrapper is not a robot)."""
    if not isinstance(damper, MDR | ImpedanceDamper):
        raise InputError("The 'damper' parameter must be an MDR or an ImpedanceDamper. Got "
                         f"{type(damper).__name__}.")


def _check_limits(limits: object) -> None:
    if not isinstance(limits, RobotLimits):
        raise InputError(f"The 'limits' parameter must be a RobotLimits. Got "
                         f"{type(limits).__name__}.")
