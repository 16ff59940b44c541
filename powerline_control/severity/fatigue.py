"""Fatigue over a wind record: the energy balance per record, Miner damage on the safe border
line, the robot moving to the antinode as the wind changes; and rainflow counting (ASTM E1049).

The steady physics is :func:`~powerline_control.severity.balance.aeolian_severity`'s (called per
group of records, never re-derived); the robot's move time is
:meth:`~powerline_control.plan.RobotLimits.rest_to_rest_time`'s. ``docs/severity.md`` section 8
describes the model and its assumptions.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._results import TabularResult
from .._validation import check_choice, check_forwarded_options, check_real, read_only
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL
from ..fem import MDR
from ..line import Span, tension_at_temperature
from ..plan import RobotLimits
from ._common import SECONDS_PER_YEAR, _check_limits, _check_robot_damper, _check_span
from .balance import SAFE_BORDER_LINES, SeverityResult, _sbl_cycles, aeolian_severity
from .dampers import AtAntinode, ImpedanceDamper, harmonic_mean_position
from .record import WindRecord

__all__ = ["RecordDamage", "FatigueOverRecord", "RainflowCount", "fatigue_over_record",
           "rainflow_count", "rainflow_damage"]

CONFIGURATIONS = ("no_damper", "fixed_damper", "robot")


def default_robot() -> tuple[MDR, RobotLimits]:
    """The robot of docs/severity.md's examples: a 6 kg body with a 1.5 kg absorber tuned to
    15 Hz at damping ratio 0.3, moving at up to 0.3 m/s and 0.5 m/s^2."""
    return (MDR.tuned(0.0, body_mass=6.0, suspended_mass=1.5, frequency=15.0, damping_ratio=0.3),
            RobotLimits(v_max=0.3, a_max=0.5))


@dataclass(frozen=True, eq=False)
class RecordDamage:
    """Damage of one configuration over a wind record.

    Attributes
    ----------
    configuration : str
        ``"no_damper"``, ``"fixed_damper"`` or ``"robot"``.
    damage_per_year : float
        Miner damage on the safe border line per year of this climate (the record's damage
        divided by its duration in years; 1 = one lifetime per year).
    life_years : float
        1 / damage_per_year (inf without damage).
    damage : ndarray
        Miner damage of each record.
    amplitude : ndarray
        Antinode amplitude Y in each record, m (the robot: time-weighted between parked and
        moving; 0 where the normal wind is outside the band).
    strain_pp : ndarray
        Peak-to-peak clamp strain in each record (the robot: while parked).
    fraction_over_endurance : float
        Fraction of the record's time with the clamp strain above the endurance strain.

    Examples
    --------
    >>> r = RecordDamage("robot", 0.01, 100.0, np.zeros(1), np.zeros(1), np.zeros(1), 0.0)
    >>> r.life_years
    100.0
    """

    configuration: str
    damage_per_year: float
    life_years: float
    damage: np.ndarray
    amplitude: np.ndarray
    strain_pp: np.ndarray
    fraction_over_endurance: float


@dataclass(frozen=True, eq=False)
class FatigueOverRecord(Mapping, TabularResult):
    """Fatigue over a wind record for no damper, a fixed damper and the robot.

    Index it by configuration: ``result["robot"].life_years``,
    ``result["fixed_damper"].damage_per_year``, ``result["no_damper"]``.

    Attributes
    ----------
    configurations : tuple of str
        ``("no_damper", "fixed_damper", "robot")``.
    results : dict
        Configuration -> :class:`RecordDamage`.
    normal_speed : ndarray
        Wind component normal to the line in each record, m/s.
    tension : ndarray
        Tension in each record from the change of state, N.
    frequency, loop_length : ndarray
        Strouhal frequency (Hz) and loop length (m) in each record (0 outside the band).
    vibrating : ndarray of bool
        Records whose normal wind lies in the aeolian band.
    robot_position : ndarray
        Where the robot is parked at the end of each record, m from the left support.
    move_time : ndarray
        Time the robot spends moving in each record, s (from ``RobotLimits.rest_to_rest_time``).
    fixed_position : float
        The fixed damper's position, m.
    years : float
        The record's duration in years.
    assumptions : tuple of str
        What the life figures assume; print them beside the figures.
    parameters : dict
        The settings used.

    Examples
    --------
    >>> from powerline_control import Span, WindRecord
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> life = fatigue_over_record(span, WindRecord.constant(3.0, n_records=6))
    >>> sorted(life)
    ['fixed_damper', 'no_damper', 'robot']
    >>> bool(life["robot"].life_years > life["no_damper"].life_years)
    True
    """

    configurations: tuple
    results: dict
    normal_speed: np.ndarray
    tension: np.ndarray
    frequency: np.ndarray
    loop_length: np.ndarray
    vibrating: np.ndarray
    robot_position: np.ndarray
    move_time: np.ndarray
    fixed_position: float
    years: float
    assumptions: tuple = ()
    parameters: dict = field(default_factory=dict, repr=False)
    # what with_limits needs to redo the robot's moves (set by fatigue_over_record)
    _robot_inputs: dict = field(default_factory=dict, repr=False, init=False)

    def with_limits(self, limits: RobotLimits) -> FatigueOverRecord:
        """The same record with another robot: only the robot's moves are recomputed (the
        energy balances do not depend on the limits), so a speed-limit study is cheap.

        Parameters
        ----------
        limits : RobotLimits
            The robot's new limits.

        Returns
        -------
        FatigueOverRecord

        Examples
        --------
        >>> from powerline_control import RobotLimits, Span, WindRecord
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> rec = WindRecord(np.arange(3) * 600.0, np.array([2.0, 3.0, 2.5]), np.full(3, 90.0),
        ...                  np.full(3, 15.0))
        >>> life = fatigue_over_record(span, rec)
        >>> slow = life.with_limits(RobotLimits(v_max=0.001, a_max=0.01))
        >>> bool(slow["robot"].damage_per_year > life["robot"].damage_per_year)
        True
        """
        _check_limits(limits)
        positions, move_time, robot = _robot_over_record(self._robot_inputs, limits)
        move = self.parameters["move"]
        text = (f"fixed damper at {self.fixed_position:.3f} m; robot moves ({move}) at "
                f"v_max {limits.v_max:g} m/s, a_max {limits.a_max:g} m/s^2, en route "
                f"{self.parameters['en_route']}")
        assumptions = tuple(text if a.startswith("fixed damper at") else a
                            for a in self.assumptions)
        other = dataclasses.replace(self, results={**self.results, "robot": robot},
                                    robot_position=read_only(positions),
                                    move_time=read_only(move_time), assumptions=assumptions,
                                    parameters={**self.parameters, "limits": limits})
        object.__setattr__(other, "_robot_inputs", self._robot_inputs)
        return other

    def __getitem__(self, configuration: str) -> RecordDamage:
        try:
            return self.results[configuration]
        except KeyError:
            raise KeyError(f"{configuration!r}: the configurations are "
                           f"{', '.join(self.configurations)}") from None

    def __iter__(self):
        return iter(self.configurations)

    def __len__(self) -> int:
        return len(self.configurations)

    def table(self) -> list[dict]:
        """One row per configuration: damage per year, life, time over the endurance strain.

        Returns
        -------
        list of dict

        Examples
        --------
        >>> from powerline_control import Span, WindRecord
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> rows = fatigue_over_record(span, WindRecord.constant(3.0, n_records=2)).table()
        >>> [row["configuration"] for row in rows]
        ['no_damper', 'fixed_damper', 'robot']
        """
        return [{"configuration": name, "damage_per_year": self[name].damage_per_year,
                 "life_years": self[name].life_years,
                 "fraction_over_endurance": self[name].fraction_over_endurance}
                for name in self.configurations]

    def summary(self) -> str:
        """The life figures with the assumptions beside them, as text.

        Returns
        -------
        str

        Examples
        --------
        >>> from powerline_control import Span, WindRecord
        >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> text = fatigue_over_record(span, WindRecord.constant(3.0, n_records=2)).summary()
        >>> text.splitlines()[0].startswith("Fatigue over")
        True
        """
        lines = [f"Fatigue over {self.years * 365.25:.4g} days of record "
                 f"({int(self.vibrating.sum())} of {self.vibrating.size} records in the "
                 "aeolian band):"]
        for row in self.table():
            lines.append(f"  {row['configuration']:<13} damage/year {row['damage_per_year']:.3g}"
                         f"   life {row['life_years']:.3g} years   over endurance "
                         f"{100 * row['fraction_over_endurance']:.1f} % of the time")
        lines.append("Assumptions:")
        lines.extend(f"  - {text}" for text in self.assumptions)
        return "\n".join(lines)


def _quantise(values: np.ndarray, step: float | None) -> np.ndarray:
    if step is None:
        return values.copy()
    return np.round(values / step) * step


def _nearest_antinode(position: float, loop: float, length: float) -> float:
    """The antinode (k + 1/2) loop nearest ``position`` inside the span."""
    k = math.floor(position / loop)
    candidates = [(j + 0.5) * loop for j in (k - 1, k, k + 1)]
    inside = [x for x in candidates if 0.0 < x < length] or [min(0.5 * loop, 0.5 * length)]
    return min(inside, key=lambda x: abs(x - position))


_SET_BY_FATIGUE = ("dampers", "label", "turbulence_intensity", "wind_speeds", "span")


def _record_damage(name: str, o: dict, vibrating: np.ndarray, step: float, years: float,
                   layers: str, endurance: float) -> RecordDamage:
    """Miner damage per record, f x time / N_SBL(sigma), of a configuration parked all along."""
    damage = np.where(vibrating, o["frequency"] * step / _sbl_cycles(o["stress_ps"], layers),
                      0.0)
    over = (vibrating & (o["strain_pp"] > endurance)).astype(float)
    return _finish(name, damage, over, o["amplitude"], o["strain_pp"], years)


def _finish(name, damage, over, amplitude, strain_pp, years) -> RecordDamage:
    per_year = float(damage.sum() / years)
    return RecordDamage(configuration=name, damage_per_year=per_year,
                        life_years=1.0 / per_year if per_year > 0 else math.inf,
                        damage=read_only(damage), amplitude=read_only(np.array(amplitude)),
                        strain_pp=read_only(np.array(strain_pp)),
                        fraction_over_endurance=float(over.mean()))


def _robot_over_record(inputs: dict, limits: RobotLimits):
    """(positions, move times, RecordDamage) of the robot under ``limits``."""
    vibrating, step, loop = inputs["vibrating"], inputs["step"], inputs["robot"]["loop_length"]
    n = vibrating.size
    position = inputs["start"]
    positions = np.zeros(n)
    move_time = np.zeros(n)
    for i in range(n):
        if vibrating[i]:
            target = _nearest_antinode(position, loop[i], inputs["length"])
            distance = 0.5 * loop[i] if inputs["move"] == "worst" else abs(target - position)
            move_time[i] = limits.rest_to_rest_time(distance)
            position = target
        positions[i] = position
    parked = np.clip(1.0 - move_time / step, 0.0, 1.0)
    args = (vibrating, step, inputs["years"], inputs["layers"], inputs["endurance"])
    at_antinode = _record_damage("robot", inputs["robot"], *args)
    moving = _record_damage("moving", inputs["moving"], *args)
    damage = parked * at_antinode.damage + (1 - parked) * moving.damage
    over = parked * (vibrating & (inputs["robot"]["strain_pp"] > inputs["endurance"])) \
        + (1 - parked) * (vibrating & (inputs["moving"]["strain_pp"] > inputs["endurance"]))
    amplitude = parked * inputs["robot"]["amplitude"] + (1 - parked) * inputs["moving"]["amplitude"]
    result = _finish("robot", damage, over, amplitude, inputs["robot"]["strain_pp"],
                     inputs["years"])
    return positions, move_time, result


def _balances(span: Span, configs: dict, speeds: np.ndarray, tensions: np.ndarray,
              iv: np.ndarray, vibrating: np.ndarray, options: dict) -> tuple[dict, float, str]:
    """Per-record balance results of each configuration: one aeolian_severity call per
    configuration and group of (tension, Iv), over the group's distinct speeds."""
    n = speeds.size
    fields = ("amplitude", "frequency", "loop_length", "stress_ps", "strain_pp")
    out = {c: {f: np.zeros(n) for f in fields} for c in configs}
    endurance, layers = None, options.get("layers", "multi")
    keys = np.stack([tensions, iv], axis=1)
    for key in np.unique(keys[vibrating], axis=0):
        rows = np.flatnonzero(vibrating & np.all(keys == key, axis=1))
        group_span = Span(span.length, float(key[0]), span.conductor)
        unique, inverse = np.unique(speeds[rows], return_inverse=True)
        for name, dampers in configs.items():
            sev: SeverityResult = aeolian_severity(group_span, unique, dampers,
                                                   turbulence_intensity=float(key[1]),
                                                   label=name, **options)
            for f in fields:
                out[name][f][rows] = np.asarray(getattr(sev, f))[inverse]
            endurance = sev.parameters["endurance_strain_pp"]
            layers = sev.parameters["layers"]
    return out, endurance, layers


def _parked(damper, position: float):
    if isinstance(damper, MDR):
        return MDR(position, damper.body_mass, damper.suspended_mass, damper.stiffness,
                   damper.damping)
    return ImpedanceDamper(position, damper.frequencies, damper.impedance, damper.label)


def _assumptions(span, reference_temperature, line_azimuth, low, high, layers, fixed_position,
                 move, limits, en_route, speed_step, tension_step, turbulence_step) -> tuple:
    return (
        f"tension from the parabolic, creep-free change of state of a {span.length:g} m level "
        f"ruling span, {span.tension:g} N at {reference_temperature:g} degC; conductor "
        "temperature = air temperature",
        f"aeolian vibration whenever the wind normal to the line (azimuth {line_azimuth:g} deg) "
        f"is within {low:g}-{high:g} m/s, locked in on the mode nearest the Strouhal frequency; "
        "steady state in every record",
        "turbulence reduces the wind power by 1/sqrt(1 + (Iv/0.09)^2) (Foti & Martinelli)",
        f"Miner's rule on the CIGRE/EPRI safe border line ({layers}-layer), Poffenberger-Swart "
        "clamp stress; the self-damping k is the unverified Lilien normalisation, so absolute "
        "lives are illustrative and the configurations compare",
        f"fixed damper at {fixed_position:.3f} m; robot moves ({move}) at "
        f"v_max {limits.v_max:g} m/s, a_max {limits.a_max:g} m/s^2, en route {en_route}",
        f"records grouped to {speed_step} m/s, {tension_step} N and Iv {turbulence_step} for "
        "the energy balance (None: exact values)",
    )


def fatigue_over_record(
    span: Span,
    record: WindRecord,
    damper: MDR | ImpedanceDamper | None = None,
    limits: RobotLimits | None = None,
    *,
    line_azimuth: float = 0.0,
    reference_temperature: float = 15.0,
    band: Sequence[float] = (1.0, 7.0),
    fixed_position: float | str | None = None,
    robot_start: float | None = None,
    move: str = "tracked",
    en_route: str = "average",
    speed_step: float | None = 0.05,
    tension_resolution: float | None = 0.005,
    turbulence_step: float | None = 0.01,
    **severity_options,
) -> FatigueOverRecord:
    """Damage per year and life over a wind record: no damper, a fixed damper, the robot.

    For each record: the wind component normal to the line, V |sin(direction - azimuth)|; the
    tension from the change of state at the air temperature
    (:func:`~powerline_control.line.tension_at_temperature`, ``span.tension`` at
    ``reference_temperature``); the turbulence intensity of the record; then the steady energy
    balance of :func:`~powerline_control.severity.balance.aeolian_severity` for each
    configuration and Miner damage on the safe border line, f x time / N_SBL(sigma_a) (the
    same count :func:`robot_value` uses). Records whose normal wind is outside ``band`` do not
    vibrate (calm, or turbulent winds above the aeolian range).

    The robot: when the loop pattern changes it moves to the nearest antinode of the new pattern
    (``move="tracked"``; ``"worst"`` starts every record half a loop away, as
    :func:`robot_value` assumes), taking ``limits.rest_to_rest_time(distance)``; while moving the
    span vibrates with the damper's placement factor averaged over the traverse, phi^2 = 1/2
    (``en_route="average"``), or undamped (``"undamped"``); parked, at the antinode (phi^2 = 1).
    A move longer than the record takes the whole record (the robot arrives at its end).

    Records are grouped for the energy balance: normal speeds to ``speed_step`` (m/s) and
    tensions to ``tension_resolution`` times ``span.tension`` (default 0.5 %); None uses the
    exact values (one balance per distinct value).

    Parameters
    ----------
    span : Span
        Ruling span; ``span.tension`` holds at ``reference_temperature``.
    record : WindRecord
        The wind record.
    damper : MDR, ImpedanceDamper or None
        The robot's damper, also parked as the fixed damper (default: docs/severity.md's robot,
        a 6 kg body with a 1.5 kg absorber tuned to 15 Hz, damping ratio 0.3).
    limits : RobotLimits or None
        The robot's limits (default v_max 0.3 m/s, a_max 0.5 m/s^2).
    line_azimuth : float
        Direction of the line, degrees from north.
    reference_temperature : float
        degC at which the span has ``span.tension`` (default 15).
    band : (float, float)
        Normal wind speeds that excite aeolian vibration, m/s (default 1-7).
    fixed_position : float, None or "best"
        Fixed damper position, m; None: the harmonic-mean position x* for the loop lengths of
        the band's normal speeds that occur in the record (equal participation at both ends);
        ``"best"``: the least damage over the record among 13 positions from x*/4 to 4 x*
        (geometric; the candidates and their damage in ``parameters["fixed_search"]``).
    robot_start : float or None
        The robot's position before the first record, m (default ``fixed_position``).
    move : {"tracked", "worst"}
        How far the robot moves at each record (see above).
    en_route : {"average", "undamped"}
        The span's state while the robot moves.
    speed_step : float or None
        Grouping resolution of the normal speeds, m/s (default 0.05; None: exact).
    tension_resolution : float or None
        Grouping resolution of the tensions, a fraction of ``span.tension`` (default 0.005;
        None: exact).
    turbulence_step : float or None
        Grouping resolution of the turbulence intensities (default 0.01; None: exact).
    **severity_options
        Passed to :func:`aeolian_severity` (wind curve, self-damping law, St, layers, ...).

    Returns
    -------
    FatigueOverRecord

    Raises
    ------
    InputError
        For bad arguments, a tension at or above the rated strength at some temperature, or
        options this function sets itself (``dampers``, ``label``, ``turbulence_intensity``).

    Examples
    --------
    >>> from powerline_control import Span, WindRecord
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> life = fatigue_over_record(span, WindRecord.constant(3.0, n_records=6))
    >>> bool(life["robot"].damage_per_year < life["no_damper"].damage_per_year)
    True
    """
    span = _check_span(span)
    if not isinstance(record, WindRecord):
        raise InputError(f"The 'record' parameter must be a WindRecord (WindRecord.from_csv). "
                         f"Got {type(record).__name__}.")
    default_damper, default_limits = default_robot()
    damper = default_damper if damper is None else damper
    limits = default_limits if limits is None else limits
    _check_robot_damper(damper)
    _check_limits(limits)
    options = check_forwarded_options(
        fatigue_over_record, severity_options, aeolian_severity, set_here=_SET_BY_FATIGUE,
        why="dampers from damper= and fixed_position=, turbulence from the record")
    move = check_choice("move", move, ("tracked", "worst"))
    en_route = check_choice("en_route", en_route, ("average", "undamped"))
    try:
        low, high = (check_real("band", b, low=0.0) for b in band)
    except (TypeError, ValueError):
        raise InputError(f"The 'band' parameter must be two wind speeds (low, high) in m/s. "
                         f"Got {band!r}.") from None
    if not low < high:
        raise InputError(f"The 'band' parameter must be (low, high) with low < high. Got {band!r}.")
    if speed_step is not None:
        speed_step = check_real("speed_step", speed_step, low=0.0, high=1.0)
    if turbulence_step is not None:
        turbulence_step = check_real("turbulence_step", turbulence_step, low=0.0, high=0.1)
    tension_step = None
    if tension_resolution is not None:
        tension_step = span.tension * check_real("tension_resolution", tension_resolution,
                                                 low=0.0, high=0.5)
    strouhal = options.get("strouhal", DEFAULT_STROUHAL)

    n = record.n_records
    step = record.step
    if not math.isfinite(step):
        raise InputError("The 'record' has one row and so no step (time per record): build it "
                         "with WindRecord.constant(..., n_records=1, step=...) or give more rows.")
    line_azimuth = check_real("line_azimuth", line_azimuth)
    # the record's own range of air temperatures
    reference_temperature = check_real("reference_temperature", reference_temperature,
                                       low=-50.0, low_inclusive=True, high=80.0)
    normal = record.normal_speed(line_azimuth)
    tension = np.atleast_1d(tension_at_temperature(span, record.temperature,
                                                   reference_temperature))
    speeds = _quantise(normal, speed_step)
    tensions = _quantise(tension, tension_step)
    iv = (np.zeros(n) if record.turbulence_intensity is None
          else _quantise(np.asarray(record.turbulence_intensity), turbulence_step))
    vibrating = (speeds >= low) & (speeds <= high) & (speeds > 0)

    active = speeds[vibrating]
    edges = (low, high) if active.size == 0 else (float(active.min()), float(active.max()))
    x_star = harmonic_mean_position(span, edges, strouhal)
    search = None
    if isinstance(fixed_position, str):
        check_choice("fixed_position", fixed_position, ("best",))
        candidates = np.unique(np.clip(x_star * np.geomspace(0.25, 4.0, 13), 1e-3,
                                       0.5 * span.length))
        damages = []
        for x in candidates:
            o, e, lay = _balances(span, {"fixed_damper": (_parked(damper, float(x)),)}, speeds,
                                  tensions, iv, vibrating, options)
            damages.append(float(_record_damage("fixed_damper", o["fixed_damper"], vibrating,
                                                step, 1.0, lay, e or 0.0).damage.sum()))
        fixed_position = float(candidates[int(np.argmin(damages))])
        search = dict(positions=tuple(candidates.tolist()), damages=tuple(damages))
    elif fixed_position is None:
        fixed_position = x_star
        if not 0.0 < x_star <= span.length:
            raise InputError(
                f"The default fixed damper position (x* = {x_star:.3g} m, the harmonic mean of "
                f"the band's loop lengths) lies beyond the {span.length:g} m span: the span is "
                "shorter than the loops of the wind band. Give 'fixed_position' (m) or a "
                "'band' of higher wind speeds.")
    fixed_position = check_real("fixed_position", fixed_position, low=0.0, high=span.length)
    robot_start = fixed_position if robot_start is None else \
        check_real("robot_start", robot_start, low=0.0, low_inclusive=True, high=span.length)
    configs = {"no_damper": (), "fixed_damper": (_parked(damper, fixed_position),),
               "robot": (AtAntinode(damper),)}
    if en_route == "average":
        configs["moving"] = (AtAntinode(damper, "robot moving", 0.5),)
    out, endurance, layers = _balances(span, configs, speeds, tensions, iv, vibrating, options)
    if "moving" not in out:
        out["moving"] = out["no_damper"]
    if endurance is None:  # nothing vibrates: the options are still checked once
        endurance = aeolian_severity(span, [0.5 * (low + high)], **options) \
            .parameters["endurance_strain_pp"]

    layers_and_endurance = (layers, endurance)
    years = record.duration / SECONDS_PER_YEAR
    results = {name: _record_damage(name, out[name], vibrating, step, years, *layers_and_endurance)
               for name in ("no_damper", "fixed_damper")}
    inputs = dict(robot=out["robot"], moving=out["moving"], vibrating=vibrating, step=step,
                  years=years, layers=layers, endurance=endurance, start=float(robot_start),
                  length=span.length, move=move)
    positions, move_time, results["robot"] = _robot_over_record(inputs, limits)
    assumptions = _assumptions(span, reference_temperature, line_azimuth, low, high, layers,
                               fixed_position, move, limits, en_route, speed_step, tension_step,
                               turbulence_step)
    result = FatigueOverRecord(
        configurations=CONFIGURATIONS, results=results, normal_speed=read_only(normal),
        tension=read_only(tension), frequency=read_only(out["robot"]["frequency"].copy()),
        loop_length=read_only(out["robot"]["loop_length"].copy()),
        vibrating=read_only(vibrating),
        robot_position=read_only(positions), move_time=read_only(move_time),
        fixed_position=float(fixed_position), years=years, assumptions=assumptions,
        parameters=dict(line_azimuth=line_azimuth, reference_temperature=reference_temperature,
                        band=(low, high), move=move, en_route=en_route, speed_step=speed_step,
                        tension_step=tension_step, turbulence_step=turbulence_step,
                        step=step, layers=layers, endurance_strain_pp=endurance,
                        limits=limits, harmonic_mean_position=x_star, fixed_search=search,
                        **options))
    object.__setattr__(result, "_robot_inputs", inputs)
    return result


# --------------------------------------------------------------------------- rainflow
@dataclass(frozen=True, eq=False)
class RainflowCount:
    """Cycles of a signal counted by the rainflow method (ASTM E1049-85).

    Attributes
    ----------
    ranges : ndarray
        Range (peak-to-peak) of each counted cycle or half cycle, in the signal's unit.
    means : ndarray
        Mean of each.
    counts : ndarray
        1.0 for a full cycle, 0.5 for a half cycle.

    Examples
    --------
    >>> count = rainflow_count([-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0])
    >>> float(count.counts.sum())
    4.0
    """

    ranges: np.ndarray
    means: np.ndarray
    counts: np.ndarray

    def histogram(self) -> dict:
        """Total count per distinct range, {range: count}.

        Returns
        -------
        dict

        Examples
        --------
        >>> rainflow_count([0.0, 1.0, 0.0, 1.0, 0.0]).histogram()
        {1.0: 2.0}
        """
        totals: dict[float, float] = {}
        for r, c in zip(self.ranges.tolist(), self.counts.tolist(), strict=True):
            totals[r] = totals.get(r, 0.0) + c
        return dict(sorted(totals.items()))


def _check_signal(signal: object, name: str) -> np.ndarray:
    array = np.asarray(signal)
    if array.dtype == bool or array.dtype.kind not in "iuf" or array.ndim != 1:
        raise InputError(f"The '{name}' parameter must be a 1-D array of real numbers. Got "
                         f"{array.dtype} with shape {array.shape}.")
    array = array.astype(float)
    if not np.all(np.isfinite(array)):
        raise InputError(f"The '{name}' parameter must be finite. Got a non-finite value at "
                         f"index {int(np.flatnonzero(~np.isfinite(array))[0])}.")
    return array


def rainflow_count(signal: Sequence[float] | np.ndarray) -> RainflowCount:
    """Rainflow cycle count of a time history (ASTM E1049-85, the ``rainflow`` library).

    Parameters
    ----------
    signal : sequence of float
        The history (strain, stress, displacement), one sample per time step.

    Returns
    -------
    RainflowCount

    Examples
    --------
    >>> t = np.linspace(0.0, 3.0, 13)                 # three periods of a cosine, on its peaks
    >>> count = rainflow_count(np.cos(2 * np.pi * t))
    >>> count.ranges.round(12).tolist(), float(count.counts.sum())
    ([2.0, 2.0, 2.0, 2.0, 2.0, 2.0], 3.0)
    """
    import rainflow

    x = _check_signal(signal, "signal")
    cycles = list(rainflow.extract_cycles(x))
    if not cycles:
        return RainflowCount(read_only(np.zeros(0)), read_only(np.zeros(0)),
                             read_only(np.zeros(0)))
    ranges, means, counts = (np.array(column, dtype=float) for column in zip(*[c[:3]
                                                                              for c in cycles],
                                                                             strict=True))
    return RainflowCount(read_only(ranges), read_only(means), read_only(counts))


def rainflow_damage(stress: Sequence[float] | np.ndarray, layers: str = "multi") -> float:
    """Miner damage of a stress history on the safe border line, cycles by rainflow counting.

    Each counted cycle of range r has the stress amplitude r / 2 and uses 1 / N_SBL(r / 2) of
    the life (a half cycle half of that); the mean stress is ignored, as the safe border line
    is drawn against the idealised bending amplitude.

    Parameters
    ----------
    stress : sequence of float
        Idealised outer-strand stress history at the clamp, Pa.
    layers : {"multi", "single"}
        Safe border line of multilayer or single-layer ACSR.

    Returns
    -------
    float

    Examples
    --------
    >>> t = np.arange(0.0, 1.0, 1e-3)                  # 20 periods of 20 Hz, 10 MPa amplitude
    >>> float(f"{rainflow_damage(10e6 * np.sin(2 * np.pi * 20.0 * t)):.3g}")  # ~20 / 2.3e8
    8.56e-08
    """
    layers = check_choice("layers", layers, tuple(SAFE_BORDER_LINES))
    count = rainflow_count(_check_signal(stress, "stress"))
    if count.counts.size == 0:
        return 0.0
    return float(np.sum(count.counts / _sbl_cycles(0.5 * count.ranges, layers)))
