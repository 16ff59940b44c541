"""Wind climates (Weibull, histogram) and what the robot is worth over one: time over the
endurance strain and Miner damage per year for no damper, a fixed damper and the robot."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._results import TabularResult
from .._validation import (
    check_array,
    check_choice,
    check_forwarded_options,
    check_real,
    read_only,
)
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL
from ..fem import MDR
from ..line import Span
from ..plan import RobotLimits
from ._common import (
    SECONDS_PER_YEAR,
    _check_limits,
    _check_robot_damper,
    _check_span,
    _check_wind_speeds,
)
from .balance import (
    SeverityResult,
    _check_severity_budget,
    _sbl_cycles,
    aeolian_severity,
)
from .dampers import AtAntinode, ImpedanceDamper, harmonic_mean_position

__all__ = [
    "WindDistribution",
    "RobotValue",
    "robot_value",
]


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


@dataclass(frozen=True, eq=False)
class RobotValue(TabularResult):
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
    severity_options = check_forwarded_options(
        robot_value, severity_options, aeolian_severity,
        set_here=("span", "wind_speeds", "dampers", "label"),
        why="it compares its own three configurations (no damper, the damper parked at x*, the "
            "robot at the antinode), built from 'damper'; for another set of dampers call "
            "aeolian_severity(span, wind_speeds, dampers=...) directly")
    span = _check_span(span)
    if isinstance(wind_speeds, np.ndarray):  # before the checks and the sort copy it
        _check_severity_budget(wind_speeds.size)
    speeds = np.sort(_check_wind_speeds(wind_speeds))
    _check_robot_damper(damper)
    _check_limits(limits)
    if distribution is None:
        distribution = WindDistribution.weibull()
    if not isinstance(distribution, WindDistribution):
        raise InputError("The 'distribution' parameter must be a WindDistribution. Got "
                         f"{type(distribution).__name__}.")
    persistence = check_real("persistence", persistence, low=0.0)
    en_route = check_choice("en_route", en_route, ("average", "undamped"))
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
