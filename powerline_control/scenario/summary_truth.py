"""A ScenarioResult's truth and belief in words and numbers: the nominal span the engineer knows,
the line simulated, and the span the closed loop's controller calibrated from its records.

Used by the report's sections (:mod:`.summary`) and the JSON summary (:mod:`.summary_json`).
"""

from __future__ import annotations

__all__ = ["truth_text", "truth_rows", "calibration_rows", "truth_json", "calibration_json"]

#: Which stage uses which line, in words (the one sentence the report and the docs share).
WHICH_LINE = ("The simulated records, the identification and the closed loop's plant run on the "
              "true line; the natural frequencies above (nominal), the robot's tuning, the plan, "
              "the severity study and the closed loop's controller use the nominal span, which "
              "the controller calibrates from its sensors' records.")


def truth_text(scenario, nominal, truth) -> str:
    """How the true span differs from the nominal one, in words with units.

    Parameters
    ----------
    scenario : Scenario
        Its ``truth`` and ``model`` sections (what was asked for).
    nominal, truth : Span
        The nominal span and the true one (:func:`~powerline_control.scenario.truth.true_span`).

    Returns
    -------
    str

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> from powerline_control.scenario.truth import true_span
    >>> s = load_scenario(text="[truth]\\ntension_factor = 0.97")
    >>> truth_text(s, s.span.build(), true_span(s))
    'tension 383.15 N (-3.0 % from the nominal 395 N: truth.tension_factor = 0.97)'
    """
    t = scenario.truth
    change = 100.0 * (truth.tension / nominal.tension - 1.0)
    why = (f"the conductor at {t.temperature:g} degC, strung at {t.stringing_temperature:g} degC"
           if t.temperature is not None else
           f"truth.tension_factor = {t.tension_factor:g}" if t.tension_factor is not None
           else "as the nominal")
    parts = [f"tension {truth.tension:.5g} N ({change:+.1f} % from the nominal "
             f"{nominal.tension:.5g} N: {why})"]
    if t.ei_factor != 1.0:
        parts.append(f"EI {truth.conductor.ei:.4g} N m^2 ({t.ei_factor:g} x the catalogue's "
                     f"{nominal.conductor.ei:.4g})")
    if t.mass_factor != 1.0:
        parts.append(f"mass {truth.conductor.mass_per_length:.4g} kg/m ({t.mass_factor:g} x the "
                     f"catalogue's {nominal.conductor.mass_per_length:.4g})")
    if t.damping_ratio is not None:
        parts.append(f"modal damping ratio {t.damping_ratio:g} (nominal "
                     f"{scenario.model.damping_ratio:g})")
    return "; ".join(parts)


def truth_rows(result) -> list:
    """The model section's rows on the true line: what differs, and its first frequencies.

    Parameters
    ----------
    result : ScenarioResult
        A result with its model stage.

    Returns
    -------
    list of tuple
        (label, value, explanation) rows.

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> from powerline_control.scenario.pipeline import run_scenario
    >>> r = run_scenario(load_scenario(text="[model]\\nn_elements = 12"), stages=("model",))
    >>> truth_rows(r)[0][1]
    'the nominal span itself (the scenario has no [truth] section)'
    """
    r = result
    if not r.scenario.truth.differs:
        return [("line simulated (truth)", "the nominal span itself (the scenario has no "
                 "[truth] section)", WHICH_LINE)]
    frequencies = r.true_model.natural_frequencies(min(5, r.true_model.n_dofs))
    return [("line simulated (truth)", truth_text(r.scenario, r.span, r.true_span), WHICH_LINE),
            ("first natural frequencies (truth)", ", ".join(f"{f:.4g}" for f in frequencies)
             + " Hz", "What the records show; the engineer does not know them."),
            ("which line each stage uses", "truth: the records, the identification, the closed "
             "loop's plant; nominal: the frequencies above, the robot's tuning, the plan, the "
             "severity study, the closed loop's controller (which calibrates it)", WHICH_LINE)]


def _last_calibration(cl_result):
    calibrations = getattr(cl_result, "calibrations", ())
    return calibrations[-1] if calibrations else (None, None)


def calibration_rows(cl_result) -> list:
    """The closed loop section's row on the tension: told, true, calibrated and believed.

    Parameters
    ----------
    cl_result : ClosedLoopResult
        The closed loop's result (its ``nominal``, ``span``, ``belief``, ``calibrations``).

    Returns
    -------
    list of tuple
        (label, value, explanation) rows; empty when the result carries no nominal span.

    Examples
    --------
    >>> calibration_rows(object())
    []
    """
    nominal, truth = getattr(cl_result, "nominal", None), getattr(cl_result, "span", None)
    if nominal is None or truth is None:
        return []
    time, last = _last_calibration(cl_result)
    text = f"told {nominal.tension:.5g} N, true {truth.tension:.5g} N; "
    if last is None:
        kept = [what for _, what in cl_result.decisions if what.startswith("belief kept")]
        text += "not calibrated" + (f" ({kept[-1]})" if kept else "")
    else:
        sigmas = abs(last.tension - truth.tension) / max(last.tension_std, 1e-300)
        text += (f"calibrated {last.tension:.5g} +- {last.tension_std:.2g} N at {time:.3g} s "
                 f"({sigmas:.2g} sigma from the truth; {len(cl_result.calibrations)} "
                 "calibrations)")
    belief = getattr(cl_result, "belief", None)
    if belief is not None:
        text += f"; believed {belief.tension:.5g} N at the end"
    return [("tension: told / true / calibrated", text,
             "The controller is told the nominal span and calibrates it from its sensors' "
             "records (calibrate_span: tension, EI and their uncertainty) after the calibration "
             "window and at each decision; it predicts with the calibrated span once the "
             "tension moves by more than 0.1 % on a calibration the record is sure of (80 % of "
             "the posterior on one tension).")]


def truth_json(result) -> dict:
    """The JSON keys of the nominal and the true line (units in the keys).

    Parameters
    ----------
    result : ScenarioResult
        A result with its model stage.

    Returns
    -------
    dict

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> from powerline_control.scenario.pipeline import run_scenario
    >>> r = run_scenario(load_scenario(text="[model]\\nn_elements = 12\\n[truth]\\n"
    ...                                     "tension_factor = 1.05"), stages=("model",))
    >>> data = truth_json(r)
    >>> data["nominal_tension_n"], round(data["true_tension_n"], 2), data["truth_differs"]
    (395.0, 414.75, True)
    """
    r = result
    true = r.true_model
    return {"nominal_tension_n": float(r.span.tension),
            "true_tension_n": float(r.true_span.tension),
            "true_ei_n_m2": float(r.true_span.conductor.ei),
            "true_mass_per_length_kg_m": float(r.true_span.conductor.mass_per_length),
            "true_frequencies_hz": [float(f) for f in true.natural_frequencies(
                min(5, true.n_dofs))],
            "truth_differs": bool(r.scenario.truth.differs)}


def calibration_json(cl_result) -> dict:
    """The JSON keys of the closed loop's calibration: the last one, with its std, and the
    tension believed at the end (None where there was none).

    Parameters
    ----------
    cl_result : ClosedLoopResult
        The closed loop's result.

    Returns
    -------
    dict

    Examples
    --------
    >>> calibration_json(object())["calibrated_tension_n"] is None
    True
    """
    time, last = _last_calibration(cl_result)
    belief = getattr(cl_result, "belief", None)
    told = getattr(cl_result, "nominal", None)
    return {"calibrated_tension_n": None if last is None else float(last.tension),
            "calibrated_tension_std_n": None if last is None else float(last.tension_std),
            "calibrated_ei_n_m2": None if last is None else float(last.ei),
            "calibrated_ei_std_n_m2": None if last is None else float(last.ei_std),
            "calibration_time_s": None if time is None else float(time),
            "n_calibrations": len(getattr(cl_result, "calibrations", ())),
            "told_tension_n": None if told is None else float(told.tension),
            "believed_tension_n": None if belief is None else float(belief.tension)}
