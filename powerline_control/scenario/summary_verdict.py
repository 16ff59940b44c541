"""The report's first screen: a ScenarioResult's verdict in a few numbers, each with a one-line
verdict and the section that holds it, and the caveats that change a decision.

Every number is read from the result's own objects (a field, or the ratio of two the report's
sections show); nothing is recomputed here, so the summary cannot disagree with the sections
below it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..severity import ENDURANCE_FAMILY
from .summary import SECTION_IDS, best_baseline, mm

__all__ = ["Headline", "Caveat", "Verdict", "result_verdict"]


@dataclass(frozen=True)
class Headline:
    """One number of the summary: its value, in words, its verdict and where it comes from.

    Attributes
    ----------
    label : str
        What the number is.
    value : float
        The number (its unit in ``text``).
    text : str
        The number in words, with its unit.
    verdict : str
        What it means for the line, in one sentence.
    section : str
        The id of the report section that holds it (:data:`.summary.SECTION_IDS`).
    """

    label: str
    value: float
    text: str
    verdict: str
    section: str


@dataclass(frozen=True)
class Caveat:
    """A finding that changes a decision, and the section that shows it.

    Attributes
    ----------
    text : str
        The finding and what to do about it.
    section : str
        The id of the report section that shows it.
    """

    text: str
    section: str


@dataclass(frozen=True)
class Verdict:
    """A ScenarioResult at a glance: the span, what was asked, the headline numbers, caveats.

    Attributes
    ----------
    span : str
        The span in words.
    asked : str
        What the scenario asked, in words.
    headlines : tuple of Headline
    caveats : tuple of Caveat
    """

    span: str
    asked: str
    headlines: tuple
    caveats: tuple

    def to_report(self) -> dict:
        """The ``summary`` mapping of :func:`~powerline_control.output.report.write_report`."""
        return {"span": self.span, "asked": self.asked,
                "rows": [(h.label, h.text, h.verdict, h.section) for h in self.headlines],
                "caveats": [(c.text, c.section) for c in self.caveats]}


def result_verdict(result) -> Verdict:
    """The verdict of a :class:`ScenarioResult`: what the top of its report says.

    Parameters
    ----------
    result : ScenarioResult
        The result (any stages; a failed run says so as a caveat).

    Returns
    -------
    Verdict

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> from powerline_control.scenario.pipeline import run_scenario
    >>> v = result_verdict(run_scenario(load_scenario(text="[model]\\nn_elements = 12"),
    ...                                 stages=("model",)))
    >>> v.span
    '3.66 m paper lab (Table 1) span, tension 395 N, pinned / pinned supports'
    >>> v.headlines, v.caveats
    ((), ())
    """
    headlines = (*_estimation(result), *_robot(result), *_severity(result))
    caveats = (*_estimation_caveats(result), *_robot_caveats(result),
               *_severity_caveats(result))
    if result.failure is not None:
        caveats += (Caveat(f"The {result.failure.stage} stage failed ({result.failure.kind}: "
                           f"{result.failure.message}); the stages after it did not run.",
                           SECTION_IDS["failure"]),)
    return Verdict(span=_span_text(result), asked=_asked_text(result), headlines=headlines,
                   caveats=caveats)


def _span_text(r) -> str:
    span, model = r.span, r.model
    supports = "" if model is None else f", {model.bc[0]} / {model.bc[1]} supports"
    return (f"{span.length:g} m {span.conductor.name} span, tension {span.tension:.5g} N"
            + supports)


def _asked_text(r) -> str:
    sc = r.scenario
    parts = [f"load: {sc.forcing.describe(r.span, sc.robot.wind)}"]
    if r.layouts is not None:
        parts.append(f"estimate the whole span from {len(r.layouts['chosen'].nodes)} sensors")
    if r.closed_loop is not None:
        parts.append(f"move the robot from {sc.robot.start:g} m to where the line vibrates "
                     f"least ({sc.robot.closed_loop:g} s of closed loop)")
    if r.severity is not None:
        speeds = r.severity.bare.wind_speed
        parts.append(f"judge the aeolian severity at {speeds.min():g}-{speeds.max():g} m/s")
    return "; ".join(parts)


def _estimation(r) -> tuple:
    if r.layouts is None:
        return ()
    chosen = r.layouts["chosen"]
    error = float(chosen.error_unmeasured_percent)
    out = [Headline("estimation error, chosen sensors", error, f"{error:.3g} %",
                    f"of the RMS displacement, at the nodes without a sensor ("
                    f"{len(chosen.nodes)} sensors, held-out data).", SECTION_IDS["layouts"])]
    best = best_baseline(r.layouts)
    if best is not None:
        name, ratio = best
        baseline = float(r.layouts[name].error_unmeasured_percent)
        counts = _counts(r.layouts, name)
        verdict = (f"than “{name}” ({counts}): {baseline:.3g} %; the chosen layout is "
                   "the better one." if ratio >= 1 else
                   f"than “{name}” ({counts}): {baseline:.3g} %; that baseline is the better "
                   "one.")
        out.append(Headline("against the best baseline", ratio,
                            f"{ratio:.3g}x lower" if ratio >= 1 else f"{1 / ratio:.3g}x higher",
                            verdict, SECTION_IDS["layouts"]))
    return tuple(out)


def _counts(layouts, name: str) -> str:
    """A baseline's sensor count against the chosen layout's, in words."""
    n, k = len(layouts[name].nodes), len(layouts["chosen"].nodes)
    return f"{n} sensors, as many as the chosen layout" if n == k else \
        f"{n} sensors against the chosen {k}"


#: The robot's comparisons the summary states, in order, and what each is in words.
_AGAINST = (("no_robot", "robot against no robot", "with no robot on the line"),
            ("start", "robot against its start", "with the robot parked where it started"),
            ("near_clamp", "robot against a damper near the clamp",
             "with the robot parked near the clamp as a fixed damper"))


def _robot(r) -> tuple:
    if r.closed_loop is None:
        return ()
    res = r.closed_loop.result
    steady = getattr(res, "aeolian_steady", None)
    if getattr(res, "steady_verdict", False):
        return _robot_settled(steady)
    closed = res.comparison("closed_loop")
    names = {c.name for c in res.comparisons}
    how = "steady state" if closed.steady else "settled window"
    if getattr(res, "wind", "fixed_lift") == "self_limiting":
        how += " in the self-limiting wind"
    elif steady is not None:
        how += " under the simulation's fixed-amplitude lift"
    ended = f" The robot ended at {closed.position:.4g} m."
    out = []
    for name, label, words in _AGAINST:
        if name not in names:
            continue
        other = res.comparison(name)
        out.append(_against(label, words, other.position, other.rms, closed.rms,
                            f"RMS {mm(other.rms)} -> {mm(closed.rms)} ({how}).{ended}"))
        ended = ""   # said once, in the first row
    if steady is not None:
        out.append(_robot_in_wind(steady))
    return tuple(out)


def _against(label: str, words: str, position: float, other: float, closed: float,
             how: str) -> Headline:
    """One comparison of the robot where the loop ended with another placement: ``other`` over
    ``closed`` (a line at rest with the robot, no load, has no finite ratio)."""
    ratio = float(other) / float(closed) if closed > 0 else math.inf
    where = "" if not math.isfinite(position) else f" at {position:.4g} m"
    verdict = f"{'less' if ratio >= 1 else 'MORE'} vibration than {words}{where}: {how}"
    return Headline(label, ratio, f"{ratio:.2f}x" if ratio >= 1 else f"{1 / ratio:.2f}x worse",
                    verdict, SECTION_IDS["closed_loop"])


def _robot_settled(steady) -> tuple:
    """The comparisons of a run in the self-limiting wind, in its steady state
    (``aeolian_steady``): steady antinode amplitudes, zero to peak."""
    closed = steady.closed_loop
    ended = f" The robot ended at {closed.robot_position:.4g} m."
    out = []
    for name, label, words in _AGAINST:
        other = getattr(steady, name)
        position = math.nan if other.robot_position is None else other.robot_position
        out.append(_against(
            label, words, position, other.amplitude, closed.amplitude,
            f"steady antinode amplitude {mm(other.amplitude)} -> {mm(closed.amplitude)} in the "
            f"{steady.wind_speed:g} m/s self-limiting wind, simulated until it settles.{ended}"))
        ended = ""
    return tuple(out)


def _robot_in_wind(steady) -> Headline:
    """The robot where the loop ended, in the self-limiting wind (``aeolian_steady``)."""
    ratio = steady.reduction
    clamp = steady.near_clamp
    verdict = (f"lower steady antinode amplitude than with no robot in the {steady.wind_speed:g} "
               f"m/s self-limiting wind ({mm(steady.no_robot.amplitude)} -> "
               f"{mm(steady.closed_loop.amplitude)}), and {steady.clamp_reduction:.3g}x "
               f"{'lower' if steady.clamp_reduction >= 1 else 'HIGHER'} than a fixed damper "
               f"near the clamp at {clamp.robot_position:.3g} m ({mm(clamp.amplitude)}): the "
               "energy balance's wind power and the conductor's self-damping, simulated until "
               "the amplitude settles.")
    return Headline("robot in the self-limiting wind", ratio, f"{ratio:.3g}x", verdict,
                    SECTION_IDS["closed_loop"])


def _severity(r) -> tuple:
    if r.severity is None:
        return ()
    bare, robot = r.severity.bare, r.severity.robot
    worst = int(max(range(bare.wind_speed.size), key=lambda i: bare.strain_pp[i]))
    strain = 1e6 * float(bare.strain_pp[worst])
    endurance = 1e6 * float(bare.parameters.get("endurance_strain_pp", float("nan")))
    over = [float(v) for v, m in zip(bare.wind_speed, bare.endurance_margin, strict=True)
            if m < 1]
    with_robot = 1e6 * float(robot.strain_pp.max())
    family = r.span.conductor.family or "of no stated family"
    verdict = (f"peak-to-peak at {bare.wind_speed[worst]:g} m/s, {with_robot:.4g} µε at worst "
               f"with the robot; not judged against the {endurance:g} µε endurance strain, "
               f"which is {ENDURANCE_FAMILY}'s (this conductor is {family})."
               if not r.severity.endurance_applies else
               f"peak-to-peak at {bare.wind_speed[worst]:g} m/s: ABOVE the {endurance:g} µε "
               f"endurance strain at {', '.join(f'{v:g}' for v in over)} m/s, so the bare span "
               f"needs damping; with the robot the worst is {with_robot:.4g} µε ("
               + ("still above" if with_robot > endurance else "below") + " it)." if over else
               f"peak-to-peak at {bare.wind_speed[worst]:g} m/s: below the {endurance:g} µε "
               "endurance strain at every wind speed studied, without any damper.")
    return (Headline("severity: worst clamp strain, no damper", strain, f"{strain:.4g} µε",
                     verdict, SECTION_IDS["severity"]),)


def _severity_caveats(r) -> tuple:
    if r.severity is None or not r.severity.assumptions:
        return ()
    return (Caveat("The severity numbers rest on assumed conductor data: "
                   + "; ".join(r.severity.assumptions) + ".", SECTION_IDS["severity"]),)


def _estimation_caveats(r) -> tuple:
    out = []
    if r.layouts is not None:
        best = best_baseline(r.layouts)
        if best is not None and best[1] < 1:
            name = best[0]
            more = len(r.layouts[name].nodes) > len(r.layouts["chosen"].nodes)
            out.append(Caveat(f"A baseline beats the optimised layout: “{name}” "
                              f"({_counts(r.layouts, name)}) estimates the span "
                              f"{1 / best[1]:.3g}x better on held-out data. "
                              + ("Weigh its extra sensors against that gain." if more else
                                 "Instrument that layout instead."), SECTION_IDS["layouts"]))
    if r.measured is not None:
        consistency = getattr(r.measured.estimate, "consistency", None)
        if consistency is not None and not consistency.consistent:
            out.append(Caveat("The filter is INCONSISTENT on the measured record (windowed "
                              "NIS): the model does not explain it, so its estimate and error "
                              "bars are not to be trusted.", SECTION_IDS["measured"]))
    return tuple(out)


def _robot_caveats(r) -> tuple:
    if r.closed_loop is None:
        return ()
    res = r.closed_loop.result
    at = SECTION_IDS["closed_loop"]
    out = []
    if not res.settled:
        out.append(Caveat("The robot had not settled when the run ended: its window numbers "
                          "are over the last second; a longer robot.closed_loop lets it "
                          "arrive.", at))
    ringing = [c.name.replace("_", " ") for c in res.comparisons if c.transient]
    judged_steady = res.comparison("closed_loop").steady or getattr(res, "steady_verdict",
                                                                     False)
    if ringing:
        out.append(Caveat(f"The settled window still rings ({', '.join(ringing)}): its window "
                          "RMS says little about where the line settles"
                          + ("; the ratios above are the steady state." if judged_steady else
                             "; run longer before trusting the ratios above."), at))
    if res.estimator_consistency is not None and not res.estimator_consistency.consistent:
        why = ("its model (the robot's force as an input) no longer fits: the line or its "
               "load changed" if getattr(res, "estimator", "recipe") == "robot_input" else
               "its model no longer fits the line the robot changed (robot.estimator = "
               "\"robot_input\" carries the robot in the model)")
        out.append(Caveat("The closed loop's estimator was flagged INCONSISTENT (windowed NIS): "
                          f"{why}; the robot's targeting does not use it, but its estimate is "
                          "not to be trusted.", at))
    out += [Caveat(f"Shortfall: {text}.", at) for text in res.shortfalls]
    return tuple(out)
