"""The JSON summary of a ScenarioResult: plain JSON types, units in the keys and a units table.

Test seam: ``_model_kind``: the JSON's model kind, tested against the model's type.
"""

from __future__ import annotations

from .summary import _least_damped, alpha_at_sweep_cap, consistency_by_phase
from .summary_truth import calibration_json, truth_json

__all__ = ["result_json", "UNITS"]

#: The units of the JSON summary's key suffixes.
UNITS = {
    "_m": "metres", "_mm": "millimetres", "_s": "seconds", "_hz": "hertz",
    "_m_s": "metres per second", "_m_s2": "metres per second squared",
    "_percent": "per cent (of the RMS displacement over the span, for errors)",
    "_microstrain": "1e-6 (peak-to-peak strain)", "_n": "newtons", "_kg": "kilograms",
    "_n_m2": "newton square metres (bending stiffness EI)", "_kg_m": "kilograms per metre",
    "_per_year": "per year (Miner damage accumulated in a year)", "_years": "years",
    "(no suffix)": "dimensionless (counts, ratios, indices, spectral radius, alpha)",
}


#: The closed loop's placements in the self-limiting wind (``AeolianSteady.runs``), as JSON keys.
_STEADY_NAMES = ("no_robot", "near_clamp", "start", "closed_loop", "antinode")


def _f(value) -> float:
    return float(value)


def _finite(value) -> float | None:
    """A float, or None (JSON null) where it is NaN: NaN is not JSON."""
    value = float(value)
    return value if value == value else None


def _model_kind(model) -> dict:
    """The JSON keys that say which model was built: its kind, and an oscillator's lines."""
    from ..identify import OscillatorModel

    if isinstance(model, OscillatorModel):
        return {"model_kind": "oscillator",
                "line_frequencies_hz": [_f(f) for f in model.line_frequencies]}
    return {"model_kind": "dmd"}


def result_json(result) -> dict:
    """The JSON summary of a :class:`ScenarioResult`: units in the keys and a units table.

    Parameters
    ----------
    result : ScenarioResult
        The result.

    Returns
    -------
    dict
        Plain JSON types only.

    Examples
    --------
    >>> from powerline_control.scenario.pipeline import run_scenario
    >>> data = result_json(run_scenario(stages=("model",)))
    >>> data["n_nodes"], data["span_length_m"], data["units"]["_hz"]
    (101, 3.66, 'hertz')
    """
    r = result
    out: dict = {"scenario": r.scenario.name, "stages": list(r.stages),
                 "failure": None if r.failure is None else
                 {"stage": r.failure.stage, "kind": r.failure.kind,
                  "message": r.failure.message},
                 "elapsed_s": dict(r.elapsed)}
    if r.model is not None:
        model = r.model
        out.update(n_nodes=int(model.n_nodes), n_elements=int(model.n_elements),
                   span_length_m=_f(r.span.length), tension_n=_f(r.span.tension),
                   frequencies_hz=[_f(f) for f in model.natural_frequencies(
                       min(5, model.n_dofs))],
                   load_frequency_hz=_f(r.scenario.forcing.load_frequency(r.span)),
                   **truth_json(r))
    if r.records is not None:
        snap = r.records.test
        out.update(n_samples=int(snap.t.size), dt_s=_f(snap.dt), n_train=int(r.records.n_train),
                   noise_std_m=_f(snap.noise_std))
    if r.identification is not None:
        d = r.identification.design
        x = r.records.test.x
        out.update(spectral_radius=_f(d.model.spectral_radius),
                   spectral_radius_plain_dmd=_f(r.identification.plain.spectral_radius),
                   alpha=_f(d.model.alpha), alpha_relative=_f(d.model.alpha_relative),
                   delays=int(d.model.delays), n_states=int(d.model.n_states),
                   filter_noise_std_m=_f(d.noise_std),
                   alpha_at_sweep_cap=alpha_at_sweep_cap(d),
                   sensor_nodes=[int(i) for i in d.sensors],
                   sensor_positions_m=[_f(x[int(i)]) for i in d.sensors],
                   **_model_kind(d.model))
        rm = r.identification.record_model
        if rm is not None:
            out["record_model"] = {"spectral_radius": _f(rm.spectral_radius),
                                   "least_damped_frequencies_hz": _least_damped(rm)}
    from .summary_sensors import sensor_count_json

    out.update(sensor_count_json(r))
    if r.layouts is not None:
        out["error_unmeasured_percent"] = r.layouts["chosen"].error_unmeasured_percent
        out["layouts"] = {name: {"error_unmeasured_percent": lay.error_unmeasured_percent,
                                 "sensor_nodes": list(lay.nodes),
                                 "sensor_positions_m": list(lay.positions)}
                          for name, lay in r.layouts.items()}
    if r.measured is not None:
        m = r.measured
        consistency = getattr(m.estimate, "consistency", None)
        out["measured_record"] = {
            "source": m.record.source, "n_samples": int(m.record.values.shape[1]),
            "n_missing": int(m.record.n_missing),
            "channel_positions_m": [_f(v) for v in m.record.positions],
            "support_channels_not_used_m": [_f(v) for v in getattr(m.record,
                                                                    "support_positions", ())],
            "sensor_nodes": list(m.nodes),
            "consistent": None if consistency is None else bool(consistency.consistent)}
    if r.plan is not None:
        p = r.plan
        out.update(target_m=_f(p.choice.position), antinode_m=_f(p.target.position),
                   true_antinode_m=_f(p.truth.position), n_antinodes=len(p.antinodes),
                   move_duration_s=_f(p.trajectory.duration))
    if r.closed_loop is not None:
        res = r.closed_loop.result
        closed = res.comparison("closed_loop")
        x = res.x
        out.update(vibration_reduction=_f(res.vibration_reduction),
                   # whether the headline is steady: the robot settled, the RMS are the exact
                   # steady state (not a window), and the settled window no longer rings
                   settled=bool(res.settled), steady_state=bool(closed.steady),
                   still_ringing=bool(closed.transient),
                   best_position_m=_finite(res.best_position),
                   final_robot_position_m=_f(res.robot_position[-1]),
                   rms_closed_loop_m=_f(res.rms_closed_loop), rms_baseline_m=_f(res.rms_baseline),
                   real_time_factor=_f(res.real_time_factor),
                   closed_loop_sensor_nodes=list(r.closed_loop.sensors),
                   closed_loop_sensor_positions_m=[_f(x[i]) for i in r.closed_loop.sensors],
                   closed_loop_sensors_how=r.closed_loop.sensors_how,
                   **calibration_json(res),
                   estimator_consistent=None if res.estimator_consistency is None
                   else bool(res.estimator_consistency.consistent),
                   estimator_windows_rejected={
                       phase: {"above": above, "below": below, "rejected": above + below,
                               "tested": n}
                       for phase, (above, below, n) in consistency_by_phase(res).items()})
        steady = res.aeolian_steady
        if steady is None:
            out["closed_loop_aeolian_steady_skipped"] = r.closed_loop.unjudged
        else:   # the same placements in the self-limiting wind
            out["closed_loop_aeolian_steady"] = {
                "wind_speed_m_s": _f(steady.wind_speed),
                **{f"{name}_amplitude_m": _f(run.amplitude)
                   for name, run in zip(_STEADY_NAMES, steady.runs, strict=True)},
                **{f"{name}_balance_amplitude_m": _f(run.balance_amplitude)
                   for name, run in zip(_STEADY_NAMES, steady.runs, strict=True)},
                **{f"{name}_first_order_amplitude_m": _f(run.first_order_amplitude)
                   for name, run in zip(_STEADY_NAMES, steady.runs, strict=True)},
                "near_clamp_position_m": _f(steady.near_clamp.robot_position),
                "start_position_m": _f(steady.start.robot_position),
                "closed_loop_position_m": _f(steady.closed_loop.robot_position),
                "antinode_position_m": _f(steady.at_antinode.robot_position),
                "reduction": _f(steady.reduction),
                "near_clamp_reduction": _f(steady.clamp_reduction),
                "start_reduction": _f(steady.start_reduction),
                "antinode_reduction": _f(steady.antinode_reduction),
                "balance_reduction": _f(steady.balance_reduction),
                "first_order_reduction": _f(steady.first_order_reduction),
                "settled": bool(steady.settled)}
    if r.severity is not None:
        bare, robot = r.severity.bare, r.severity.robot
        out["outer_strand_diameter_m"] = _f(r.severity.outer_strand_diameter)
        out["severity_endurance_applies"] = bool(r.severity.endurance_applies)
        out["severity_assumptions"] = list(r.severity.assumptions)
        out["severity"] = [
            {"wind_speed_m_s": _f(bare.wind_speed[i]), "frequency_hz": _f(bare.frequency[i]),
             "loop_length_m": _f(bare.loop_length[i]), "amplitude_m": _f(bare.amplitude[i]),
             "strain_pp_microstrain": 1e6 * _f(bare.strain_pp[i]),
             "robot_amplitude_m": _f(robot.amplitude[i]),
             "robot_strain_pp_microstrain": 1e6 * _f(robot.strain_pp[i])}
            for i in range(bare.wind_speed.size)]
        runs = r.severity.time_domain
        if runs is not None:
            out["severity_time_domain"] = {
                "wind_speed_m_s": _f(runs.bare.wind_speed),
                **{f"{name}_amplitude_m": _f(run.amplitude) for name, run in (
                    ("bare", runs.bare), ("antinode", runs.at_antinode),
                    ("near_clamp", runs.near_clamp))},
                **{f"{name}_{what}_amplitude_m": _f(getattr(run, f"{what}_amplitude"))
                   for name, run in (("bare", runs.bare), ("antinode", runs.at_antinode),
                                     ("near_clamp", runs.near_clamp))
                   for what in ("balance", "first_order")},
                "near_clamp_position_m": _f(runs.near_clamp.robot_position),
                "reduction": _f(runs.reduction), "near_clamp_reduction": _f(runs.clamp_reduction),
                "robot_impedance_ratio": _f(runs.at_antinode.robot_impedance_ratio),
                "settled": all(run.settled for run in (runs.bare, runs.at_antinode,
                                                       runs.near_clamp))}
        elif r.severity.time_domain_skipped:
            out["severity_time_domain_skipped"] = r.severity.time_domain_skipped
    if r.fatigue is not None:
        life = r.fatigue.life
        out["fatigue"] = {name: {"damage_per_year": _f(life[name].damage_per_year),
                                 "life_years": _f(life[name].life_years)}
                          for name in life.configurations}
        out["fatigue_record"] = {"source": r.fatigue.source,
                                 "n_records": int(r.fatigue.record.n_records),
                                 "step_s": _f(r.fatigue.record.step),
                                 "fixed_damper_position_m": _f(life.fixed_position)}
    out["units"] = dict(UNITS)
    return out
