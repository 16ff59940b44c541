"""The report's severity and fatigue sections: the energy balance's verdict per wind speed, and
damage over a wind record, every row with its explanation from the numbers.

Used by :func:`~.summary.result_sections`; the summary at the top of the report reads the same
results (:mod:`.summary_verdict`).
"""

from __future__ import annotations

import functools

from ..severity import ENDURANCE_FAMILY, ENDURANCE_STRAIN_PP
from .summary_format import _figure, _plotting, mm

__all__ = ["severity_section", "fatigue_section", "wind_speed_note", "closed_loop_wind_row",
           "FATIGUE_DAYS"]

#: The fatigue figure shows the robot's positions over this many days of the record's start.
FATIGUE_DAYS = 7.0


def wind_speed_note(bare, robot, i: int, endurance_applies: bool = True) -> str:
    """One wind speed's row explained: what the balance found, what the robot does, and the
    clamp strain against the endurance strain the balance used (when it applies).

    Parameters
    ----------
    bare, robot : SeverityResult
        Without dampers, and with the robot at the antinode.
    i : int
        Index of the wind speed.
    endurance_applies : bool
        Whether the endurance strain belongs to the conductor's family (``Severity``'s): if
        not, the strain is not judged against it.

    Returns
    -------
    str

    Examples
    --------
    >>> import powerline_control as plc
    >>> span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> bare = plc.aeolian_severity(span, [1.0])
    >>> head, robot, strain = wind_speed_note(bare, bare, 0).split("; ")
    >>> head
    'Mode 30 locks in at 1 m/s (f = St V / d)'
    >>> strain
    '947 µε is above the 150 µε endurance strain: this wind fatigues the bare conductor.'
    """
    endurance = _endurance(bare)
    status = bare.status[i]
    head = f"Mode {int(bare.mode[i])} locks in at {bare.wind_speed[i]:g} m/s (f = St V / d)"
    if status == "no vibration":
        return head + "; the conductor's self-damping exceeds the wind's power: no vibration."
    ratio = float(bare.amplitude[i] / robot.amplitude[i]) if robot.amplitude[i] > 0 \
        else float("inf")
    robot_text = ("the robot at the antinode stops it" if ratio == float("inf") else
                  f"the robot at the antinode cuts the amplitude {ratio:.3g}x")
    strain = 1e6 * float(bare.strain_pp[i])
    if not endurance_applies:
        return (f"{head}; {robot_text}; {strain:.3g} µε is not judged: the {endurance:g} µε "
                f"endurance strain is {ENDURANCE_FAMILY}'s, not this conductor family's.")
    verdict = (f"{strain:.3g} µε is below the {endurance:g} µε endurance strain "
               f"({float(bare.endurance_margin[i]):.3g}x margin)"
               if bare.endurance_margin[i] >= 1 else
               f"{strain:.3g} µε is above the {endurance:g} µε endurance strain: this wind "
               "fatigues the bare conductor")
    bound = ("; the wind still outpowers the damping at the power curve's end, so the "
             "amplitude is a lower bound" if status == "above curve range" else "")
    return f"{head}; {robot_text}; {verdict}{bound}."


def severity_section(r) -> dict:
    """The severity section of a :class:`ScenarioResult` (see :func:`.summary.result_sections`).

    Parameters
    ----------
    r : ScenarioResult
        A result with its severity stage.

    Returns
    -------
    dict
    """
    sev = r.severity
    bare, robot = sev.bare, sev.robot
    rated = _rated(r)
    rows = [("outer strand diameter", f"{1e3 * sev.outer_strand_diameter:.3g} mm",
             f"from {sev.strand_source}; the clamp strain scales with it "
             "(Poffenberger-Swart)"),
            ("rated strength (self-damping)", f"{rated / 1e3:.4g} kN",
             f"Normalises the self-damping law (Lilien k = D / sqrt(m RTS)); the tension is "
             f"{100 * r.span.tension / rated:.3g} % of it."),
            ("Poffenberger-Swart distance", f"{1e3 * r.scenario.severity.clamp_distance:g} mm",
             "Y_b is taken this far from the last point of contact at the clamp.")]
    for i, speed in enumerate(bare.wind_speed):
        rows.append((f"wind {speed:g} m/s",
                     f"{bare.frequency[i]:.3g} Hz, loops {bare.loop_length[i]:.3g} m; antinode "
                     f"amplitude {mm(bare.amplitude[i])}, clamp strain "
                     f"{1e6 * bare.strain_pp[i]:.3g} µε peak-to-peak; with the robot "
                     f"{mm(robot.amplitude[i])}, {1e6 * robot.strain_pp[i]:.3g} µε",
                     wind_speed_note(bare, robot, i, sev.endurance_applies)))
    notes = []
    if sev.time_domain is not None:
        judged = r.closed_loop is not None and \
            getattr(r.closed_loop.result, "aeolian_steady", None) is not None
        row, note = _time_domain_row(sev.time_domain, judged)
        rows.append(row)
        notes.append(note)
    elif sev.time_domain_skipped:
        rows.append((f"time domain at {r.scenario.forcing.wind_speed:g} m/s",
                     "not run: " + sev.time_domain_skipped,
                     "The time-domain check simulates the balance's own powers until the "
                     "amplitude settles (severity.simulate_aeolian); it is skipped where that "
                     "simulation cannot hold the balance (severity.self_limiting."
                     "settling_balance)."))
    missed = _tuning_note(sev, r.span.conductor.diameter)
    if missed:
        notes.append(missed)
    if sev.assumptions:
        rows.append(("assumed", "; ".join(sev.assumptions),
                     "The span gives no such data: the study takes the catalogue conductor it "
                     "matches; set them in the scenario's [severity] section to replace them."))
    draw = functools.partial(_plotting().plot_severity, [bare, robot],
                             endurance=sev.endurance_applies)
    family = r.span.conductor.family
    note = (f"The dotted line, {_endurance(bare):g} µε peak-to-peak, is the endurance limit "
            f"commonly used for {ENDURANCE_FAMILY} conductors (CIGRE / EPRI)."
            if sev.endurance_applies else
            f"No endurance line is drawn: the {_endurance(bare):g} µε endurance limit in common "
            f"use is that of {ENDURANCE_FAMILY} conductors (CIGRE / EPRI), and this conductor is "
            + (f"{family}." if family else "of no stated family.")
            + " Its strains compare wind speeds and the robot, not a fatigue limit.")
    return {"title": "Aeolian severity (energy balance)", "rows": rows,
            "intro": "For each wind speed the steady antinode amplitude is where the wind's "
            "power input equals the power the conductor's self-damping (and any damper) "
            "dissipates; the clamp strain follows from it (Poffenberger-Swart). With the robot: "
            "its absorber parked at the antinode of each wind speed.",
            "notes": [note, *notes],
            "figures": [_figure("severity", draw,
                                "Antinode amplitude (zero to peak) and peak-to-peak bending "
                                "strain at the clamp (µε) against wind speed, from the energy "
                                "balance, without dampers and with the robot.",
                                "strains above the endurance line: those winds fatigue the "
                                "conductor" if sev.endurance_applies else
                                "how far the robot lowers the strain at each wind speed")]}


#: A robot that changes the amplitude by less than this fraction at a wind speed does nothing
#: there worth a row of its own: the note says why (its absorber's tuning).
NEGLIGIBLE_CHANGE = 0.05


def _tuning_note(sev, diameter: float) -> str:
    """Why the robot changes (nearly) nothing at some wind speeds: those winds drive the line at
    frequencies away from its absorber's tuning ("" when it helps at every speed)."""
    import math

    bare, robot, tuned = sev.bare, sev.robot, sev.robot_frequency
    if not math.isfinite(tuned):
        return ""
    idle = [i for i in range(bare.wind_speed.size)
            if bare.amplitude[i] > 0 and robot.amplitude[i] > (1 - NEGLIGIBLE_CHANGE)
            * bare.amplitude[i]]
    if not idle:
        return ""
    strouhal = float(bare.parameters.get("strouhal", float("nan")))
    speeds = ", ".join(f"{bare.wind_speed[i]:g} m/s ({bare.frequency[i]:.3g} Hz, "
                       f"{100 * (bare.frequency[i] / tuned - 1):+.0f} %)" for i in idle)
    text = (f"The robot's absorber is tuned to {tuned:.3g} Hz, and an absorber takes power only "
            f"near its tuning: at {speeds} it changes the antinode amplitude by less than "
            f"{100 * NEGLIGIBLE_CHANGE:.0f} %.")
    if len(idle) == bare.wind_speed.size and math.isfinite(strouhal):
        text += (" None of the wind speeds studied drives the line near it; the wind locks into "
                 f"its tuning at about {tuned * diameter / strouhal:.3g} m/s (St V / D = "
                 f"{tuned:.3g} Hz).")
    return text


def _time_domain_row(runs, judged: bool = False) -> tuple[tuple, str]:
    """The time-domain check's row (the same powers: no damper, the robot parked at the
    antinode and near the clamp) and the note that says what each number means and why the
    balance's robot differs; ``judged``: the closed loop's final position was judged in the
    same wind (its section says so beside its own load's numbers)."""
    def versus(run) -> str:
        said = "" if run.settled else ", still moving at the end of the run"
        return (f"{mm(run.amplitude)} against the balance's {mm(run.balance_amplitude)} "
                f"({100 * run.relative_error:+.3g} %{said})")

    bare, robot, clamp = runs.bare, runs.at_antinode, runs.near_clamp
    row = (f"time domain at {bare.wind_speed:g} m/s",
           f"no damper: {versus(bare)}; robot parked at the antinode: {versus(robot)}, "
           f"{runs.reduction:.3g}x lower; parked near the clamp as a fixed damper "
           f"({clamp.robot_position:.3g} m): {versus(clamp)}, {runs.clamp_reduction:.3g}x lower",
           "The same wind power and self-damping in a simulation of the span's modes with the FE "
           "robot, run until the amplitude settles (severity.simulate_aeolian): the steady "
           "amplitudes to trust for the robot's value.")
    note = ("The time-domain check and the energy balance use the same wind power and "
            "self-damping, so without dampers they agree up to the locked mode's frequency "
            "against St V / D. With the robot the balance takes the robot's power from the "
            "line and robot coupled (severity.coupled_balance: the amplitude at which the mode "
            "the wind feeds neither grows nor decays), since the robot's impedance is "
            f"{robot.robot_impedance_ratio:.3g} times the line's wave impedance sqrt(T m) and "
            "reshapes the standing wave where it sits. The textbook damper power, first order "
            "(1/2 Re Z omega^2 Y^2 phi^2 / L, the standing wave left as it is), gives "
            f"{mm(robot.first_order_amplitude)} at the antinode"
            + (": it overstates the power such a robot takes."
               if robot.robot_impedance_ratio > 0.3 else ", close to the coupled one.")
            + " The closed loop's own load is a lift of fixed amplitude, not self-limiting: its "
            "RMS rows compare the robot's positions under one load, not the line's steady "
            "vibration"
            + ("; the closed-loop section judges where the robot ended in this self-limiting "
               "wind, beside this check." if judged else "."))
    return row, note


def closed_loop_wind_row(steady, span, severity_runs=None, severity_span=None,
                         wind: str = "fixed_lift") -> tuple:
    """The closed-loop section's row of the self-limiting wind: where the loop ended, no robot,
    the fixed damper, the robot's start and the antinode in steady state, and what each number
    means beside the run's own window, the energy balance and the severity study's time-domain
    check.

    Parameters
    ----------
    steady : AeolianSteady
        ``ClosedLoopResult.aeolian_steady``.
    span : Span
        The line the closed loop simulated.
    severity_runs : SeverityTimeDomain or None
        The severity section's time-domain check at the same wind, when it ran.
    severity_span : Span or None
        The span it ran on.
    wind : str
        The wind the closed loop itself ran in (``ClosedLoopResult.wind``).

    Returns
    -------
    (str, str, str)
        Label, value and note.
    """
    closed, bare, clamp, antinode = (steady.closed_loop, steady.no_robot, steady.near_clamp,
                                     steady.at_antinode)
    unsettled = [name for name, run in zip(("no robot", "near the clamp", "where it started",
                                            "where it ended", "at the antinode"), steady.runs,
                                           strict=True)
                 if not run.settled]
    value = (f"robot where the loop ended ({closed.robot_position:.4g} m): {mm(closed.amplitude)}"
             f", {steady.reduction:.3g}x below no robot ({mm(bare.amplitude)}) and "
             f"{steady.clamp_reduction:.3g}x below a fixed damper near the clamp "
             f"({clamp.robot_position:.3g} m: {mm(clamp.amplitude)}) and "
             f"{steady.start_reduction:.3g}x below its start ({steady.start.robot_position:.4g} "
             f"m: {mm(steady.start.amplitude)}); at the antinode "
             f"{antinode.robot_position:.4g} m: {mm(antinode.amplitude)}, "
             f"{steady.antinode_reduction:.3g}x"
             + (f" (not settled: {', '.join(unsettled)})" if unsettled else ""))
    note = ("Steady antinode amplitudes (zero to peak) of the line simulated in the "
            "self-limiting wind: the energy balance's wind power at the current amplitude and "
            "the conductor's self-damping, run until the amplitude settles "
            "(severity.simulate_aeolian). This is where the line settles, and the robot's value "
            "to trust. " + _window_words(wind) + " The energy balance at the same position, "
            "with the robot's power from the line and robot coupled, says "
            f"{steady.balance_reduction:.3g}x; with the textbook first-order damper power "
            f"(the standing wave left as it is, while the robot's impedance is "
            f"{closed.robot_impedance_ratio:.3g} times the line's wave impedance sqrt(T m)) it "
            f"would say {steady.first_order_reduction:.3g}x.")
    if severity_runs is not None:
        note += " " + _against_severity(steady, span, severity_runs, severity_span, wind)
    return (f"self-limiting wind {steady.wind_speed:g} m/s, steady state", value, note)


def _window_words(wind: str) -> str:
    """What the closed loop's RMS rows are, beside the steady state."""
    if wind == "self_limiting":
        return ("The RMS rows above are the run's own last window in the same wind: the "
                "amplitude on its way, which with the robot settles over minutes, longer than "
                "the run.")
    return ("The RMS rows above are under the closed loop's own load, a lift of fixed "
            "amplitude on a fixed modal damping: they rank positions under one load, and do not "
            "settle where wind and conductor balance.")


def _against_severity(steady, span, runs, severity_span, wind: str) -> str:
    """The closed loop's self-limiting reduction against the severity section's, and what
    makes them differ: the line (tension) and the robot's position."""
    theirs = runs.reduction
    differ = 100 * (steady.reduction / theirs - 1)
    text = (f"The severity section's time-domain check, the same physics with the robot at its "
            f"antinode ({runs.at_antinode.robot_position:.4g} m), says {theirs:.3g}x: "
            f"{differ:+.0f} % from the closed loop's {steady.reduction:.3g}x.")
    causes = []
    if severity_span is not None and abs(severity_span.tension / span.tension - 1) > 1e-3:
        causes.append(
            f"the severity study runs on the nominal span ({severity_span.tension:.5g} N), the "
            f"closed loop on the line simulated ({span.tension:.5g} N), whose self-damping and "
            f"locked mode differ (no robot: {mm(runs.bare.amplitude)} against "
            f"{mm(steady.no_robot.amplitude)}; at its own antinode the robot gives "
            f"{steady.antinode_reduction:.3g}x)")
    apart = abs(steady.closed_loop.robot_position - steady.at_antinode.robot_position)
    if apart > 1e-6:
        loop = float(span.loop_length(steady.no_robot.frequency))
        causes.append(
            f"the loop ended {100 * apart / loop:.2g} % of a loop ({apart:.3g} m) from the "
            f"antinode, where the robot gives {steady.antinode_reduction:.3g}x against "
            f"{steady.reduction:.3g}x"
            + (": the closed loop chose its position under its own load, a sine at St V / D "
               "that drives the modes around it off resonance, not in the self-limiting wind, "
               "which locks into one mode at that mode's frequency" if wind != "self_limiting"
               else ""))
    if causes:
        text += " They differ because " + "; and ".join(causes) + "."
    return text


def _endurance(result) -> float:
    """The endurance strain the balance used, µε peak-to-peak."""
    return 1e6 * float(result.parameters.get("endurance_strain_pp", ENDURANCE_STRAIN_PP))


def fatigue_section(r) -> dict:
    """The fatigue section of a :class:`ScenarioResult` (see :func:`.summary.result_sections`).

    Parameters
    ----------
    r : ScenarioResult
        A result with its fatigue stage.

    Returns
    -------
    dict
    """
    f = r.fatigue
    life, record = f.life, f.record
    robot = r.scenario.robot
    lines = life.summary().splitlines()
    rows = [("wind record", lines[0].rstrip(":") + f"; {record.n_records} records of "
             f"{record.step:g} s from {f.source}",
             f"{life.years:.3g} years of wind: each configuration's damage over it, divided by "
             "that, is its damage per year."),
            ("robot", f"the scenario's tuned robot ({robot.body_mass:g} kg body, "
             f"{robot.suspended_mass:g} kg absorber), v_max {robot.v_max:g} m/s, a_max "
             f"{robot.a_max:g} m/s^2; fixed damper at {life.fixed_position:.4g} m",
             f"The fixed damper is the same absorber held at {life.fixed_position:.4g} m for the "
             "whole record: what the robot's moving is compared with.")]
    for row in life.table():
        rows.append((row["configuration"].replace("_", " "),
                     f"damage/year {row['damage_per_year']:.3g}, life {row['life_years']:.3g} "
                     f"years, over endurance {100 * row['fraction_over_endurance']:.1f} % of the "
                     "time", "Miner damage on the safe border line, summed over the record."))
    rows.append(("assumptions", "; ".join(life.assumptions),
                 "What the damage numbers rest on; each is a setting of the fatigue study."))
    draw = functools.partial(_plotting().plot_fatigue_record, life, days=FATIGUE_DAYS)
    shown = min(FATIGUE_DAYS, life.years * 365.25)
    return {"title": "Fatigue over the wind record",
            "rows": rows,
            "intro": "For each record the tension from the change of state at its "
            "air temperature, the wind normal to the line, the energy balance and Miner damage; "
            "the robot moves to the nearest antinode when the loop pattern changes.",
            "figures": [_figure("fatigue_record", draw,
                                "Miner damage per year by wind-speed bin for no damper, a fixed "
                                "damper and the robot over the wind record, and the robot's "
                                f"parking position over the record's first {shown:.3g} days.",
                                "how much lower the robot's bars are than the fixed damper's, "
                                "and how often the robot moves")]}


def _rated(r) -> float:
    """The rated strength the severity study used (its stage's, not recomputed here)."""
    return float(r.severity.rated_strength)
