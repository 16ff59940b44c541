"""The report's plan section: the antinodes of the estimated field and the robot's
minimum-time move to its target, every row explained from the numbers.

Used by :func:`~.summary.result_sections`.
"""

from __future__ import annotations

import functools

from .summary_format import _figure, _plotting, positions_text

__all__ = ["plan_section", "move_note"]


def plan_section(r) -> dict:
    """The plan section of a :class:`ScenarioResult` (see :func:`.summary.result_sections`).

    Parameters
    ----------
    r : ScenarioResult
        A result with its plan stage.

    Returns
    -------
    dict
    """
    p, robot = r.plan, r.scenario.robot
    snap = r.records.test
    loop = p.truth.loop_length
    rows = [
        ("antinodes (estimated field)", positions_text([a.position for a in p.antinodes]),
         f"Peaks of the estimated field's amplitude over the held-out record; the true field's "
         f"loops are {loop:.3g} m long, so neighbouring antinodes sit about that far apart."),
        ("target", f"{p.choice.position:.4g} m ({p.choice.gain_words()}"
         + ("" if p.choice.objective == "antinode" else " than at the start") + ")",
         "The closed loop's rule: the predicted best parked position within reach (the "
         "nearest of those within 3 % of the best), from the estimated field"
         + (": in the self-limiting wind, where the robot couples most to the field's standing "
            "wave." if p.choice.objective == "antinode" else ".")),
        ("nearest antinode", f"{p.target.position:.4g} m (true field: {p.truth.position:.4g} m, "
         f"{100 * abs(p.target.position - p.truth.position) / loop:.2g} % of a loop length "
         "apart)", "The estimated antinode nearest the target, checked against the true field."),
        ("minimum-time move", f"{robot.start:g} m -> {p.choice.position:.4g} m in "
         f"{p.trajectory.duration:.3g} s (v_max {robot.v_max:g} m/s, a_max "
         f"{robot.a_max:g} m/s^2)", move_note(abs(p.choice.position - robot.start),
                                               robot.v_max, robot.a_max)),
    ]
    sensors = [float(snap.x[i]) for i in r.sensors]
    envelope_draw = functools.partial(
        _plotting().plot_envelope, snap.x, {"true amplitude": p.envelope},
        {"estimated antinodes": [a.position for a in p.antinodes], "sensors": sensors})
    path_draw = functools.partial(_plotting().plot_plan_path, snap.x, p.envelope,
                                  p.trajectory.t, p.trajectory.position,
                                  target=p.choice.position, antinode=p.target.position)
    figures = [
        _figure("envelope", envelope_draw,
                "Vibration amplitude along the span (largest |y| over the held-out record) "
                "with the estimated antinodes and the sensors.",
                "the antinode marks on the envelope's peaks"),
        _figure("robot_path", path_draw,
                "The robot's planned move to the predicted best parked position under the "
                "amplitude envelope, zoomed to where it travels, with the estimated antinode "
                "nearest that target.",
                "the path ending on its target, and how far that target sits from the "
                "nearest antinode"),
    ]
    return {"title": "Antinodes and motion plan", "rows": rows, "figures": figures}


def move_note(distance: float, v_max: float, a_max: float) -> str:
    """The shape of a rest-to-rest minimum-time move, from its distance and limits.

    Parameters
    ----------
    distance : float
        How far the robot moves, m.
    v_max, a_max : float
        Its speed (m/s) and acceleration (m/s^2) limits.

    Returns
    -------
    str

    Examples
    --------
    >>> move_note(0.1, 0.5, 1.0)
    'Over 0.1 m the robot never reaches v_max: it accelerates at a_max for half the way and \
brakes for the other half.'
    >>> move_note(2.0, 0.5, 1.0)
    'Over 2 m the robot accelerates to v_max, cruises for 3.5 s and brakes.'
    """
    if distance <= 0:
        return "The robot is already at its target: no move."
    if distance < v_max**2 / a_max:   # too short to reach v_max: accelerate, then brake
        return (f"Over {distance:.3g} m the robot never reaches v_max: it accelerates at a_max "
                "for half the way and brakes for the other half.")
    return (f"Over {distance:.3g} m the robot accelerates to v_max, cruises for "
            f"{distance / v_max - v_max / a_max:.3g} s and brakes.")
