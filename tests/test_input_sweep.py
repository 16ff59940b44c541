"""No raw error, no silent wrong answer, no hang, for every public name.

The sweep (``tests/sweep_cases.py``) starts from one valid call per public callable of
``powerline_control.__all__`` (and the public methods users call on what those return), walks
its signature and replaces one parameter at a time by a bad value of its kind. Each case runs in
a worker subprocess under an address-space limit with the package's memory budget lowered below
that limit, and a generous timeout as a hang guard (never a pass criterion). A case passes when

* the call raises the package's own error (a ``PowerlineControlError`` that is a ``ValueError``
  or ``TypeError``) whose message names the parameter (or, for a relation between two
  parameters, the other one of this call; for a path, the path), or
* the call returns and the value has a defined meaning: ``None`` where the signature allows it,
  an in-domain value (zero, tiny, huge, negative, reversed, empty, ...) with a result free of
  NaN and infinity (when the valid call's result is), or a value listed in :data:`ALLOWED`
  with the reason. A value with no meaning (NaN, infinity, text for a number, a bool for a
  number, a wrong type, a wrong shape, a folder for a file) that is answered is *silent*.

Raw exceptions, unnamed own errors, RuntimeError-family errors for bad input, MemoryErrors, hangs
and crashes fail. Cases in modules this test's owner does not maintain are strict xfails with the
module and the symptom (:data:`XFAIL`): they turn into failures the day they are fixed, so the
mark is removed then. Names whose valid call takes over a second are marked ``slow``.
"""

from __future__ import annotations

import collections
import inspect
import os

import numpy as np
import pytest
import sweep_cases as sweep  # beside this file (pytest puts tests/ on sys.path, as strategies)
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import powerline_control as plc

# Kinds of value that have no meaning for the parameter they replace: answering one is silent.
STRICT_KINDS = {"nan", "inf", "-inf", "text", "bool", "complex", "object", "none", "text_flag",
                "int_flag", "float_int", "nan_entry", "inf_entry", "extra_axis", "transposed",
                "bool_array", "text_array", "number", "folder", "fifo", "missing_dir",
                "empty_text", "unknown_text", "empty_mapping"}
# Kinds that may be in the domain (zero noise, a negative phase, a reversed list of positions):
# answered, the result must be free of NaN and infinity (when the valid call's result is).
DOMAIN_KINDS = {"negative", "zero", "huge", "tiny", "huge_int", "empty", "scalar", "negated",
                "reversed", "binary"}
assert STRICT_KINDS.isdisjoint(DOMAIN_KINDS)

# Labels are free text: any string is a label (a number or None is still refused).
_LABELS = {"label", "name", "source", "description", "material"}

# (name, parameter, kind) -> why the answer is right. "*" matches any name, parameter or kind.
ALLOWED: dict[tuple[str, str, str], str] = {
    **{("*", label, kind): "any text is a label" for label in _LABELS
       for kind in ("empty_text", "unknown_text", "text")},
    ("WindRecord", "start", "empty_text"): "'' is the default: no time stamp given",
    ("KalmanFilter.filter", "measurements", "nan_entry"): "NaN marks a missing sample (documented)",
    ("KalmanFilter.step", "y_k", "nan_entry"): "NaN marks a missing sample (documented)",
    ("Record", "values", "nan_entry"): "NaN marks a missing sample (documented)",
    ("parameter_grid", "a", "*"): "grid axis values are any values; run_study checks them",
    ("load_model", "path", "missing_dir"): "FileNotFoundError, documented, as open() does",
    ("OnlineDMD", "X", "transposed"): "IdentificationError: 3 pairs cannot identify 20 states "
                                      "(the documented data failure; too few rows to look "
                                      "transposed)",
    ("Span.loop_length", "frequency", "zero"): "inf: a static load has no loops (documented)",
    ("point_seed", "point", "empty_mapping"): "{} is the one point of parameter_grid() (no axes)",
    ("run_closed_loop", "damping", "none"): "None: no damping (the documented default)",
    ("select_sensors.cost", "budget", "zero"): "SensorSelectionError: no 2 sensors fit the budget "
                                               "(documented: constraints that cannot be met)",
    ("select_sensors.cost", "budget", "tiny"): "SensorSelectionError: no 2 sensors fit the budget "
                                               "(documented: constraints that cannot be met)",
}

# (name, parameter, kind) -> why: values of an in-domain kind that are physically impossible, so
# an answer is silent even when finite.
MUST_REFUSE: dict[tuple[str, str, str], str] = {
    ("Span", "tension", "huge"): "a tension above the rated strength breaks the conductor",
    ("select_sensors.cost", "cost", "negated"): "a negative cost makes the budget meaningless",
    ("select_sensors.cost", "cost", "negative"): "a negative cost makes the budget meaningless",
    ("WindPowerCurve", "powers", "negated"): "the wind cannot take power from the conductor",
}

# Strict xfails: cases in modules other engineers own (name::parameter::kinds | owner: symptom),
# regenerated from a full sweep (slow part included) when this table last changed. A fix there
# turns its row into an XPASS failure: delete the row then.
_OWNERS = {"severity": "severity (fatigue engineer)", "sensors": "sensors.py (estimator engineer)",
           "estimator": "estimate/recipe (estimator engineer)",
           "closed_loop": "closed_loop (lead)", "pipeline": "scenario (pipeline engineer)",
           "records": "output/records.py (pipeline engineer)"}
_XFAIL_TABLE = """
"""


def _xfails(table: str) -> dict[tuple[str, str, str], str]:
    out = {}
    for line in filter(None, map(str.strip, table.splitlines())):
        case, reason = (part.strip() for part in line.split("|"))
        name, parameter, kinds = case.split("::")
        owner, symptom = (part.strip() for part in reason.split(":", 1))
        for kind in kinds.split(","):
            out[(name, parameter, kind)] = f"{_OWNERS[owner]}: {symptom}"
    return out


XFAIL = _xfails(_XFAIL_TABLE)


def _match(table: dict, name: str, parameter: str, kind: str) -> str | None:
    for key in ((name, parameter, kind), (name, parameter, "*"), (name, "*", kind),
                ("*", parameter, kind), ("*", parameter, "*")):
        if key in table:
            return table[key]
    return None


KIT = sweep.kit()
CASES = sweep.case_ids(KIT)


def _none_allowed(name: str, parameter: str) -> bool:
    fn, _ = sweep.BASELINES[name].make(KIT)
    p = inspect.signature(fn).parameters.get(parameter)
    return p is not None and (p.default is None or "None" in str(p.annotation))


def _is_default(name: str, parameter: str, kind: str) -> bool:
    """Whether the bad value is the parameter's own default (travel_time=inf means no limit)."""
    fn, _ = sweep.BASELINES[name].make(KIT)
    p = inspect.signature(fn).parameters.get(parameter)
    default = p.default if p is not None else inspect.Parameter.empty
    return (kind == "inf" and default == float("inf")) or (kind == "-inf"
                                                           and default == -float("inf"))


def verdict(case: str, record: dict, baseline: dict) -> str:
    """``"ok"`` or what is wrong with the outcome of ``case``."""
    name, parameter, kind = case.split("::")
    outcome = record["outcome"]
    described = f"{outcome}: {record.get('error', '')} {record.get('message', '')}".strip()
    if kind == "baseline":
        return "ok" if outcome == "accepted" else f"the valid call fails: {described}"
    if outcome in ("own", "related"):
        return "ok"
    if _match(ALLOWED, name, parameter, kind):
        return "ok"
    if outcome == "accepted":
        if (kind == "none" and _none_allowed(name, parameter)) or _is_default(name, parameter,
                                                                             kind):
            return "ok"
        nonfinite = record.get("nonfinite") and not baseline.get("nonfinite")
        if kind in DOMAIN_KINDS and not nonfinite and not _match(MUST_REFUSE, name, parameter,
                                                                 kind):
            return "ok"
        why = "a NaN/inf result" if nonfinite else "a value without meaning answered"
        return f"silent ({why}): returned {record.get('result', '')}"
    return described


def _params():
    for case in CASES:
        name, parameter, kind = case.split("::")
        marks = [pytest.mark.slow] if sweep.BASELINES[name].slow else []
        reason = _match(XFAIL, name, parameter, kind)
        if reason:
            marks.append(pytest.mark.xfail(strict=True, reason=reason))
        yield pytest.param(case, id=case, marks=marks)


@pytest.fixture(scope="module")
def outcomes(request):
    """Run every selected case (and the baselines) once, over two guarded workers."""
    here = request.module.__name__
    # (a doctest item of the package has no module attribute: only this module's own cases)
    selected = {item.callspec.params["case"] for item in request.session.items
                if hasattr(item, "callspec") and "case" in item.callspec.params
                and getattr(item, "module", None) is not None
                and item.module.__name__ == here}
    names = {case.split("::")[0] for case in selected}
    cases = sorted(selected | {f"{name}::-::baseline" for name in names})
    # 120 s: a hang guard only (the slowest valid case takes about 2 s on a loaded machine).
    results = sweep.run_all(cases, workers=2, timeout=120.0)
    if os.environ.get("PLC_SWEEP_DUMP"):   # every outcome as JSON, to read the messages
        import json

        with open(os.environ["PLC_SWEEP_DUMP"], "w") as handle:
            json.dump(results, handle, indent=0, default=str)
    return results


@pytest.mark.parametrize("case", list(_params()))
def test_bad_input_is_refused_by_name_or_answered_correctly(case, outcomes):
    name = case.split("::")[0]
    result = verdict(case, outcomes[case], outcomes[f"{name}::-::baseline"])
    assert result == "ok", f"{case}: {result}"


def test_sweep_covers_every_public_callable_and_reports_its_size(capsys):
    public = {n for n in plc.__all__ if callable(getattr(plc, n))   # not tables (STRANDINGS)
              and not (isinstance(getattr(plc, n), type)
                       and issubclass(getattr(plc, n), BaseException))}
    swept = {name.split(".")[0] for name in sweep.BASELINES}
    missing = public - swept - sweep.RESULTS - sweep.NOT_CALLABLE
    assert not missing, f"no baseline for {sorted(missing)}"
    per_name = collections.Counter(case.split("::")[0] for case in CASES
                                   if not case.endswith("::baseline"))
    slow = sum(n for name, n in per_name.items() if sweep.BASELINES[name].slow)
    with capsys.disabled():
        print(f"\ninput sweep: {sum(per_name.values())} cases over {len(per_name)} callables "
              f"({slow} slow); per name:")
        print(", ".join(f"{name} {n}" for name, n in sorted(per_name.items())))
    # Every parameter of every baseline is swept (none silently dropped by the kind table).
    for name in sweep.available(KIT):
        _, values = sweep.bound_arguments(name, KIT)
        for parameter in set(values) - set(sweep.BASELINES[name].skip):
            assert any(c.startswith(f"{name}::{parameter}::") for c in CASES), (name, parameter)
    assert sum(per_name.values()) > 3000


# ======================================= the named classes of bad input, one test each
# (the sweep above finds them too; these state the physics or the contract directly)
DRAKE = plc.Span.at_rts_fraction(300.0, "drake", 0.2)


def test_histogram_honours_its_rtol():
    # The densities integrate to 1.0005. Old code re-checked at a fixed 1e-6 whatever rtol said.
    edges, density = [0.0, 2.0, 4.0, 8.0], [0.125, 0.25, 0.0626]
    w = plc.severity.WindDistribution.histogram(edges, density, rtol=1e-3)
    assert float(w.cdf(8.0)) == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(plc.InputError, match="'density'"):
        plc.severity.WindDistribution.histogram(edges, density, rtol=1e-4)


def test_descending_wind_speeds_never_give_negative_probabilities():
    w = plc.severity.WindDistribution.weibull()
    # Old code: differences of the CDF over descending speeds were negative probabilities.
    with pytest.raises(plc.InputError, match="'wind_speeds'"):
        w.probability_of(np.array([6.0, 4.0, 2.0]))
    ascending = w.probability_of(np.array([2.0, 4.0, 6.0]))
    assert np.all(ascending > 0) and ascending.sum() <= 1.0


def test_robot_value_refuses_dampers_by_name_not_by_a_forwarding_type_error():
    # Old code: "got multiple values for argument 'dampers'" from aeolian_severity.
    with pytest.raises(plc.InputError, match="'dampers'"):
        plc.severity.robot_value(DRAKE, plc.MDR(1.0, 1.0), plc.RobotLimits(0.5, 1.0),
                        wind_speeds=[2.0, 4.0], dampers=[plc.MDR(2.0, 1.0)])


def test_catenary_check_never_sees_a_tension_at_or_above_rts():
    drake = plc.conductors["drake"]
    with pytest.raises(plc.InputError, match="'tension'"):
        plc.severity.catenary_check(plc.Span(300.0, 1.5 * drake.rated_strength, drake))
    # At 20 % RTS the catenary parameter H / w is 28020 N / (1.628 kg/m g) = 1755 m.
    check = plc.severity.catenary_check(DRAKE)
    assert check.catenary_parameter == pytest.approx(28020.0 / (1.628 * 9.80665), rel=1e-3)


def test_negative_sensor_cost_is_refused():
    with pytest.raises(plc.InputError, match="'cost'"):
        plc.select_sensors(KIT.sys_all, 2, "gramian", Q=KIT.q, horizon=10,
                           cost=[-1.0, 1.0, 2.0, 2.0], budget=3.0)


def test_sensor_positions_closer_than_a_mesh_cell_are_refused_not_merged():
    from powerline_control.scenario.stages import given_sensors

    scenario = plc.load_scenario(text="[model]\nn_elements = 4\n[estimation]\n"
                                      "sensor_positions = [1.0, 1.001]")
    # Old code: both become node 1, one sensor where the user asked for two.
    with pytest.raises(plc.InputError, match=r"sensor_positions.*1 m and 1\.001 m.*0\.915 m"):
        given_sensors(scenario, [0.0, 0.915, 1.83, 2.745, 3.66])


# ====================================== the reduction-based finiteness check against the mask
@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(values=hnp.arrays(np.float64, hnp.array_shapes(min_dims=1, max_dims=3, max_side=6),
                         elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
       allow_nan=st.booleans())
def test_check_array_finiteness_equals_the_elementwise_truth(values, allow_nan):
    from powerline_control._validation import check_array

    # Truth: the elementwise mask (what the check once allocated).
    bad = np.isinf(values) if allow_nan else ~np.isfinite(values)
    if bad.any():
        with pytest.raises(plc.InputError, match="'v' parameter contains"):
            check_array("v", values, allow_nan=allow_nan)
    else:
        out = check_array("v", values, allow_nan=allow_nan)
        assert out.tobytes() == values.tobytes()   # returned unchanged, bit for bit


# ================================= edge cases found by a second sweep of the newest public calls
_TUNED = plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1)
_LAB_LOAD = plc.HarmonicForce(1.0, 24.0, 0.5)


def test_a_closed_loop_that_ends_before_any_decision_returns_its_result():
    # Old code: ValueError from zip(strict=True) once the whole run had been simulated.
    result = plc.run_closed_loop(plc.Span.paper_lab(), _LAB_LOAD, _TUNED, sensors=[5, 10, 15],
                                 n_elements=20, duration=1.2, calibration=1.0)
    assert result.decisions == () and result.retarget_times == ()
    # the robot never moved: the run's field is the parked start's, sample for sample
    np.testing.assert_array_equal(result.robot_position, 1.2)
    np.testing.assert_allclose(result.displacement, result.baseline_displacement, rtol=0,
                               atol=1e-12 * np.abs(result.baseline_displacement).max())


def test_a_closed_loop_load_above_the_nyquist_frequency_of_dt_is_refused():
    # Old code: the 24 Hz load aliased to 4 Hz at dt = 0.05 s, and the robot chased the alias.
    with pytest.raises(plc.InputError, match=r"'dt'.*24 Hz.*Nyquist frequency 10 Hz"):
        plc.run_closed_loop(plc.Span.paper_lab(), _LAB_LOAD, _TUNED, sensors=[5, 10, 15],
                            n_elements=20, duration=12.0, calibration=8.0, dt=0.05,
                            control_period=0.05)


@pytest.mark.parametrize("force", [plc.HarmonicForce(1.0, 24.0, 0.0), []],
                         ids=["at-a-support", "empty"])
def test_a_closed_loop_without_load_on_the_line_names_force(force):
    # Old code: IdentificationError "The 'snapshots' are all zeros" (no 'snapshots' was given).
    with pytest.raises(plc.InputError, match="'force'.*no load on the line"):
        plc.run_closed_loop(plc.Span.paper_lab(), force, _TUNED, sensors=[5, 10, 15],
                            n_elements=20, duration=3.0, calibration=1.0)


def test_choose_parked_position_refuses_a_model_that_carries_the_robot():
    model = plc.LineModel(plc.Span.paper_lab(), 20, damping=plc.ModalDamping(0.01))
    field = plc.simulate(model, _LAB_LOAD, duration=2.0, dt=1e-3).displacement[:, -1000:]
    robot = plc.tune_damper(model, 3, 1.83, 0.05, body_mass=0.02)
    limits = plc.RobotLimits(0.5, 1.0)
    # Old code: answered 1.825 m (the robot counted twice) against 0.554 m for the bare line.
    with pytest.raises(plc.InputError, match="'model'.*bare line"):
        plc.closed_loop.choose_parked_position(model.with_robot(robot), field, 1e-3, robot, 1.2,
                                               limits)
    with pytest.raises(plc.InputError, match="'field' parameter is constant in time"):
        plc.closed_loop.choose_parked_position(model, np.zeros_like(field), 1e-3, robot, 1.2,
                                               limits)


def test_locate_antinodes_refuses_a_shape_sampled_twice_per_loop():
    # sin(10 pi x): 10 loops, antinodes at 0.05 + 0.1 k. On 21 points (2 per loop) the samples
    # fall on its nodes and antinodes only; old code: one "antinode" at 0.5 m, a node.
    x = np.linspace(0.0, 1.0, 21)
    with pytest.raises(plc.InputError, match="'field'.*too sparse"):
        plc.locate_antinodes(np.sin(10 * np.pi * x), x)
    x = np.linspace(0.0, 1.0, 31)                      # 3 per loop: found, to 1e-6
    found = [a.position for a in plc.locate_antinodes(np.sin(10 * np.pi * x), x)]
    np.testing.assert_allclose(found, 0.05 + 0.1 * np.arange(10), atol=1e-6)


def test_design_estimator_never_puts_a_sensor_on_a_support_of_a_noisy_record():
    model = plc.LineModel(plc.Span.paper_lab(), 20, damping=plc.ModalDamping(0.01))
    record = plc.simulate(model, _LAB_LOAD, duration=2.0, dt=1e-3, noise_std=1e-6, seed=0)
    # Old code: n_sensors = 20 and 21 were allowed and put sensors on nodes 0 and 20, where
    # the pinned line never moves (or failed with an IdentificationError about alphas).
    for n in (20, 21):
        with pytest.raises(plc.InputError, match=rf"'n_sensors' parameter \({n}\).*<= 19"):
            plc.design_estimator(record, n_sensors=n)


def test_a_closed_loop_too_short_to_calibrate_is_refused_at_load():
    # Old code: accepted, then stage errors about 'calibration' or 'delays'. The recipe needs
    # 106 samples (two parts of >= 4 x 8 delays at a 0.7 split); a third of 0.3 s at 1 ms is 101.
    with pytest.raises(plc.InputError, match=r"robot.closed_loop = 0.3 is not allowed.*106 "
                                             r"samples.*at least 0.4 s"):
        plc.load_scenario(text="[robot]\nclosed_loop = 0.3")
    assert plc.load_scenario(text="[robot]\nclosed_loop = 0.4")
    with pytest.raises(plc.InputError, match=r"closed_loop = 12.0 is not allowed.*lower "
                                             r"simulation.dt"):   # 2 s hold 67 samples of 30 ms
        plc.load_scenario(text="[simulation]\ndt = 0.03\nduration = 60.0\n[forcing]\n"
                               "frequency = 5.0\n[robot]\nclosed_loop = 12.0")


def test_a_sensor_position_that_rounds_to_a_support_is_refused():
    from powerline_control.scenario.stages import given_sensors

    scenario = plc.load_scenario(text="[model]\nn_elements = 4\n[estimation]\n"
                                      "sensor_positions = [0.3, 1.0]")
    with pytest.raises(plc.InputError, match=r"sensor_positions.*0\.3 m falls on the support"):
        given_sensors(scenario, [0.0, 0.915, 1.83, 2.745, 3.66])


def test_parked_steady_state_warns_of_a_load_the_mesh_cannot_show():
    model = plc.LineModel(plc.Span.paper_lab(), 20, damping=plc.ModalDamping(0.01))
    with pytest.warns(plc.TruncationWarning, match="n_elements"):
        plc.simulation.parked_steady_state(model, plc.HarmonicForce(1.0, 1e5, 0.5), plc.MDR(1.0,
                                                                                            0.02),
                                [1.0])


def test_fatigue_over_record_names_an_unknown_option_and_an_impossible_default():
    record = plc.WindRecord.constant(3.0, n_records=2)
    with pytest.raises(plc.InputError, match=r"unknown keyword argument 'nonsense'"):
        plc.fatigue_over_record(DRAKE, record, nonsense=1)
    short = plc.Span(length=1.0, tension=28e3, conductor=plc.conductors["drake"])
    with pytest.raises(plc.InputError, match="default fixed damper position.*'fixed_position'"):
        plc.fatigue_over_record(short, record)


@pytest.mark.filterwarnings("ignore::powerline_control.TruncationWarning")
@pytest.mark.parametrize("n_elements", [6, 8])
def test_the_scenario_tunes_the_robot_at_the_driven_modes_antinode_on_a_coarse_mesh(n_elements):
    from powerline_control.scenario.stages import tune_robot

    # Mode 3 of the pinned lab span is sin(3 pi x / L): antinodes at L/6, L/2, 5L/6; the robot
    # starts at 1.2 m, nearest L/6. A loop (L/3) spans 2 and 2.7 elements: read at the nodes
    # alone the shape was under-resolved (at 20 elements, mode 10: an "antinode" on a node).
    scenario = plc.load_scenario(text=f"[model]\nn_elements = {n_elements}")
    tuning = tune_robot(scenario, plc.LineModel(scenario.span.build(), n_elements=n_elements))
    assert tuning.mode == 3
    assert tuning.antinode == pytest.approx(plc.Span.paper_lab().length / 6, abs=2e-3)


# The truth of a scenario (design.md 4.7): its [truth] keys are swept by the schema sweep; the
# sweep above gives true_span / true_model and run_closed_loop(nominal=) the bad kinds of their
# types. These are the relations: a span or model of another line as the scenario's nominal.
_TRUTH = plc.load_scenario(text="[truth]\ntension_factor = 0.97")   # the lab span, 3 % slack


@pytest.mark.parametrize(("call", "named"), [
    # Old: answered with the 300 m span at 0.97 of its tension (a truth of another line).
    (lambda: plc.scenario.true_span(_TRUTH, DRAKE), "'nominal' parameter of true_span"),
    (lambda: plc.scenario.true_model(_TRUTH, plc.LineModel(DRAKE, 10)),
     "'nominal' parameter of true_model"),
    # Old: AttributeError ('Span' object has no attribute 'span'; 'str' ... 'truth').
    (lambda: plc.scenario.true_model(_TRUTH, plc.Span.paper_lab()), "must be the scenario's "
                                                                   "nominal LineModel"),
    (lambda: plc.scenario.true_span("paper-lab-20"), "load_scenario('paper-lab-20')"),
    # The nominal a controller is told: the same line, within 1 % of its length.
    (lambda: plc.run_closed_loop(plc.Span.paper_lab(), plc.HarmonicForce(1.0, 9.0, 1.1),
                                 plc.MDR(1.2, 0.02), plc.RobotLimits(0.5, 1.0), sensors=[3, 5],
                                 n_elements=10, duration=0.6, calibration=0.3,
                                 nominal=plc.Span(36.6, 395.0, plc.Span.paper_lab().conductor)),
     "'nominal' parameter describes a span 36.6 m long"),
])
def test_a_nominal_of_another_line_is_refused_by_name(call, named):
    with pytest.raises(plc.InputError) as info:
        call()
    assert named in str(info.value), str(info.value)


def test_the_scenarios_own_span_gives_its_truth():
    nominal = _TRUTH.span.build()
    assert plc.scenario.true_span(_TRUTH, nominal) == plc.scenario.true_span(_TRUTH)
    assert plc.scenario.true_span(_TRUTH).tension == pytest.approx(0.97 * nominal.tension,
                                                                   rel=1e-15)
