"""The closed loop judged in the self-limiting aeolian wind (``run_closed_loop(aeolian_steady=)``).

Independent truths: ``simulate_aeolian`` called directly for the same line, wind and robot
position (the judgement must be that function's answer, not a copy of its physics); the energy
balance without a robot (a root of P_w = P_c found by bracketing, no time integration); the
conservation of energy over the final window (wind input = self-damping + robot + energy
gained); and the closed-form antinodes of a pinned span's mode, (j + 1/2) L / n, and of a clamped
taut beam's standing wave (``Span.standing_wave_shape``). Also the report's words that link the
closed loop's numbers to the severity section's.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.closed_loop.aeolian_steady import antinode_near
from powerline_control.errors import InputError, TruncationWarning
from powerline_control.severity import simulate_aeolian

WIND = 3.0
# Drake at 20 % RTS, 30 m, pinned: the wind at 3 m/s locks into mode 9 (19.6 Hz, loops 3.33 m)
SPAN = plc.Span.at_rts_fraction(30.0, "drake", 0.2)


@pytest.fixture(scope="module")
def run():
    """A closed loop in a 3 m/s wind, started 1.1 m (a third of a loop) off the antinode at
    15 m, judged in the self-limiting wind (about 2 s)."""
    model = plc.LineModel(SPAN, bc="pinned", damping=plc.ModalDamping(0.0005))
    robot = dataclasses.replace(plc.tune_damper(model, 9, 15.0, 3.0, body_mass=5.0),
                                position=13.9)
    n = model.n_nodes
    return model, robot, plc.run_closed_loop(
        model, plc.AeolianForce(WIND), robot, sensors=[n // 5, 2 * n // 5, 3 * n // 5 + 3,
                                                       4 * n // 5],
        duration=8.0, calibration=2.0, aeolian_steady=True)


def test_the_judgement_is_simulate_aeolian_at_the_final_position(run):
    model, robot, result = run
    steady = result.aeolian_steady
    final = float(result.robot_position[-1])
    direct = simulate_aeolian(SPAN, WIND, dataclasses.replace(robot, position=final),
                              bc="pinned")
    assert steady.closed_loop.robot_position == pytest.approx(final)
    # the same function on the same line: the same amplitude (to the integrator's round-off)
    assert steady.closed_loop.amplitude == pytest.approx(direct.amplitude, rel=1e-9)
    assert steady.reduction == pytest.approx(
        simulate_aeolian(SPAN, WIND, bc="pinned").amplitude / direct.amplitude, rel=1e-9)
    # the fixed damper sits where the closed loop's own near-clamp comparison parks it
    assert steady.near_clamp.robot_position == pytest.approx(
        result.comparison("near_clamp").position)
    assert steady.settled


def test_without_the_robot_the_line_settles_at_the_energy_balance(run):
    steady = run[2].aeolian_steady
    balance = plc.severity.aeolian_severity(SPAN, [WIND], bc="pinned")
    # the run locks to mode 9 at 19.64 Hz, the balance works at St V / D = 19.72 Hz: 0.5 %
    assert steady.no_robot.amplitude == pytest.approx(float(balance.amplitude[0]), rel=0.02)


def test_the_robot_takes_what_the_wind_puts_in(run):
    closed = run[2].aeolian_steady.closed_loop
    # energy over the final window: the wind's input is the conductor's and the robot's
    # dissipation plus the energy the line gained (the absorber beats with the line, so the
    # window's gain is not zero); conserved to 1 %
    assert abs(closed.energy_residual) < 0.01
    assert closed.robot_power > 0.5 * closed.wind_power


def test_the_antinode_is_the_locked_modes(run):
    steady = run[2].aeolian_steady
    loop = SPAN.length / steady.no_robot.mode     # pinned: mode n has loops of L / n
    assert steady.no_robot.mode == 9
    antinodes = (np.arange(9) + 0.5) * loop
    nearest = antinodes[np.argmin(np.abs(antinodes - steady.closed_loop.robot_position))]
    # parabolic refinement of the nodal amplitude: within 1 % of a loop
    assert steady.at_antinode.robot_position == pytest.approx(nearest, abs=0.01 * loop)
    # the robot damps best at the antinode of the mode the wind feeds, better than at the clamp
    assert steady.antinode_reduction >= 0.98 * steady.reduction
    assert steady.reduction > 10 and steady.clamp_reduction > 1


def test_the_summary_states_the_self_limiting_numbers(run):
    result = run[2]
    text = result.summary()
    assert "self-limiting wind 3 m/s" in text
    assert f"reduction {result.aeolian_steady.reduction:.3g}x against no robot" in text


def test_antinode_of_a_clamped_span_is_the_standing_waves():
    span = plc.Span.at_rts_fraction(40.0, "drake", 0.2)
    bare = simulate_aeolian(span, WIND, bc="clamped")
    x = np.linspace(18.0, 22.0, 40001)
    shape = np.abs(span.standing_wave_shape(bare.frequency, x, "clamped"))
    peaks = x[1:-1][(shape[1:-1] >= shape[:-2]) & (shape[1:-1] >= shape[2:])]
    expected = peaks[np.argmin(np.abs(peaks - 20.0))]
    loop = float(span.loop_length(bare.frequency))
    # the FE mode's frequency, the closed form's wave: within 1 % of a loop
    assert antinode_near(bare, 20.0) == pytest.approx(expected, abs=0.01 * loop)


def _lab_call(**options):
    model = plc.LineModel(plc.Span.paper_lab(), 20)
    robot = plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1)
    return lambda: plc.run_closed_loop(model, options.pop("force", plc.AeolianForce(1.0)),
                                       robot, sensors=[4, 9, 15], duration=3.0,
                                       calibration=1.0, **options)


@pytest.mark.parametrize(("options", "words"), [
    ({"aeolian_steady": "yes"}, ["'aeolian_steady'", "'yes'", "True, False or a mapping"]),
    ({"aeolian_steady": {"wind_curv": "cigre"}},
     ["'aeolian_steady'", "wind_curv", "wind_curve"]),
    ({"aeolian_steady": True, "force": plc.HarmonicForce(1.0, 24.0, 0.5)},
     ["'aeolian_steady'", "HarmonicForce", "one AeolianForce"]),
    # the lab span's conductor has no rated strength for the Lilien k: refused before the run
    ({"aeolian_steady": True}, ["self_damping_k", "rated_strength"]),
])
def test_bad_requests_are_refused_before_the_run(options, words):
    with pytest.raises(InputError) as caught:
        _lab_call(**options)()
    for word in words:
        assert word in str(caught.value)


def test_a_wind_beyond_the_power_curves_data_is_refused_before_the_run():
    # Drake 30 m at 20 % RTS in 3 m/s: the Farquharson curve's data end before the wind's power
    # falls to the self-damping's (the energy balance's status "above curve range")
    model = plc.LineModel(SPAN, bc="pinned")
    robot = plc.tune_damper(model, 9, 15.0, 3.0, body_mass=5.0)
    assert plc.severity.aeolian_severity(SPAN, [WIND], bc="pinned", wind_curve="farquharson"
                                         ).status[0] == "above curve range"
    with pytest.raises(InputError, match=r"'force' wind speed 3 m/s.*'farquharson'.*wind_curve"):
        plc.run_closed_loop(model, plc.AeolianForce(WIND), robot, sensors=[20, 40],
                            duration=3.0, calibration=1.0,
                            aeolian_steady={"wind_curve": "farquharson"})


@pytest.mark.parametrize(("arguments", "name"), [
    ({"wind": plc.HarmonicForce(1.0, 19.6, 1.0)}, "'wind'"),
    ({"position": 31.0}, "'position'"),
    ({"clamp_distance": -1.0}, "'clamp_distance'"),
    ({"model": SPAN}, "'model'"),
])
def test_the_judgement_refuses_what_it_cannot_place(arguments, name):
    from powerline_control.closed_loop import aeolian_steady_state

    model = plc.LineModel(SPAN, bc="pinned")
    call = {"model": model, "wind": plc.AeolianForce(WIND),
            "robot": plc.tune_damper(model, 9, 15.0, 3.0, body_mass=5.0), "position": 15.0,
            "clamp_distance": 1.0, **arguments}
    with pytest.raises(InputError, match=name):
        aeolian_steady_state(**call)


def test_supports_that_differ_are_refused():
    model = plc.LineModel(SPAN, bc=("clamped", "pinned"))
    robot = plc.tune_damper(model, 9, 15.0, 3.0, body_mass=5.0)
    with pytest.raises(InputError, match=r"same support at both ends.*\('clamped', 'pinned'\)"):
        plc.run_closed_loop(model, plc.AeolianForce(WIND), robot, sensors=[20, 40],
                            duration=3.0, calibration=1.0, aeolian_steady=True)


SCENARIO = "\n".join([
    "[span]", 'preset = "conductor"', 'conductor = "drake"', "length = 30.0",
    "rts_fraction = 0.2", "[model]", 'bc = "pinned"', "damping_ratio = 0.0005", "[forcing]",
    'kind = "aeolian"', "wind_speed = 3.0", "[robot]", "start = 13.9", "body_mass = 5.0",
    "suspended_mass = 3.0", "closed_loop = 8.0", "[severity]", "enabled = true"])


def test_scenario_reports_the_closed_loop_in_the_self_limiting_wind():
    from powerline_control.scenario.summary import result_sections
    from powerline_control.scenario.summary_json import result_json
    from powerline_control.scenario.summary_verdict import result_verdict

    result = plc.run_scenario(plc.load_scenario(text=SCENARIO),
                              stages=("model", "closed_loop", "severity"))
    steady = result.closed_loop.result.aeolian_steady
    # the severity study's physics (its curve and law) on the line the closed loop simulated
    mesh = result.closed_loop.result.x.size - 1     # the scenario's equal elements
    direct = simulate_aeolian(SPAN, WIND, bc="pinned", n_elements=mesh)
    assert steady.no_robot.amplitude == pytest.approx(direct.amplitude, rel=1e-9)
    section = next(s for s in result_sections(result) if s["title"].startswith("Closed loop"))
    label, value, note = next(row for row in section["rows"] if row[0].startswith("self-lim"))
    assert f"{steady.reduction:.3g}x below no robot" in value
    assert f"{steady.clamp_reduction:.3g}x below a fixed damper" in value
    # each number's meaning beside the others: the fixed lift, the balance, severity's check
    assert "fixed amplitude" in note and f"says {steady.balance_reduction:.3g}x" in note
    assert f"says {result.severity.time_domain.reduction:.3g}x" in note
    assert result_json(result)["closed_loop_aeolian_steady"]["reduction"] == pytest.approx(
        steady.reduction)
    # Severity's "with the robot" (its time-domain check, the robot at its antinode) on the same
    # line (no [truth] here) and wind: the same antinode, and reductions within 10 % there (the
    # closed loop's 100 equal elements against severity's physics mesh: 44.1x against 41.3x);
    # where the loop ended (14.69 m, 9 % of a loop off) within the 25 % (41.5x)
    runs = result.severity.time_domain
    loop = SPAN.length / steady.no_robot.mode
    assert steady.at_antinode.robot_position == pytest.approx(
        runs.at_antinode.robot_position, abs=0.01 * loop)
    assert steady.antinode_reduction == pytest.approx(runs.reduction, rel=0.1)
    assert steady.reduction == pytest.approx(runs.reduction, rel=0.25)
    headline = next(h for h in result_verdict(result).headlines
                    if h.label == "robot in the self-limiting wind")
    assert headline.value == pytest.approx(steady.reduction)


@pytest.mark.parametrize(("extra", "asked"), [
    ("", True), ("time_domain = false", False)])
def test_scenario_asks_for_the_judgement_with_the_time_domain_check(extra, asked):
    from powerline_control.scenario.stages import wind_judgement

    scenario = plc.load_scenario(text=SCENARIO + "\n" + extra)
    options, unjudged = wind_judgement(scenario, SPAN)
    assert bool(options) is asked
    assert ("time_domain is off" in unjudged) is not asked
    if asked:   # the severity study's curve and law, with the Lilien k of the conductor
        law = plc.severity.SELF_DAMPING_LAWS["noiseux1991"]
        assert options == {"wind_curve": "cigre", "self_damping": "noiseux1991",
                           "self_damping_k": pytest.approx(law.coefficient(SPAN))}


def test_a_wind_whose_balance_lies_below_the_curves_data_is_not_judged_in_it():
    # Oxlip 40 m at 20 % RTS in 2.5 m/s: the energy balance settles at 5.4e-4 D, below the
    # 1e-3 D where the simulated wind's power is capped (test_closed_loop_self_limiting)
    from powerline_control.scenario.stages import wind_judgement

    span = plc.Span.at_rts_fraction(40.0, "oxlip", 0.2)
    scenario = plc.load_scenario(text="\n".join([
        "[span]", 'preset = "conductor"', 'conductor = "oxlip"', "length = 40.0",
        "rts_fraction = 0.2", "[model]", 'bc = "pinned"', "[forcing]", 'kind = "aeolian"',
        "wind_speed = 2.5", "[robot]", "start = 20.3", "[severity]", "enabled = true"]))
    balance = plc.aeolian_severity(span, [2.5], bc="pinned")
    assert 0 < balance.amplitude[0] < 1e-3 * span.conductor.diameter
    options, unjudged = wind_judgement(scenario, span)
    assert options is False
    for words in ("wind speed 2.5 m/s", "0.00054 D", "0.001 D", "choose another wind speed"):
        assert words in unjudged
    # the severity section's time-domain check is skipped for the same reason, and says so
    from powerline_control.scenario.summary import result_sections

    result = plc.run_scenario(scenario, stages=("model", "severity"))
    assert result.severity.time_domain is None
    assert result.severity.time_domain_skipped == unjudged
    section = next(s for s in result_sections(result) if "severity" in s["title"].lower())
    row = next(row for row in section["rows"] if row[0] == "time domain at 2.5 m/s")
    assert row[1] == "not run: " + unjudged
    from powerline_control.scenario.summary_json import result_json

    assert result_json(result)["severity_time_domain_skipped"] == unjudged


def test_a_closed_loop_under_another_load_says_it_is_not_the_severity_sections():
    from powerline_control.scenario.summary import result_sections

    result = plc.run_scenario(plc.load_scenario(
        text="[model]\nn_elements = 20\n[robot]\nclosed_loop = 4.0\n[severity]\nenabled = true"),
        stages=("model", "closed_loop", "severity"))
    assert result.closed_loop.result.aeolian_steady is None
    section = next(s for s in result_sections(result) if s["title"].startswith("Closed loop"))
    rows = {row[0]: row for row in section["rows"]}
    assert rows["against the severity section"][1] == \
        "not comparable: the [forcing] is harmonic, not the wind"


def test_the_severity_section_says_when_its_winds_miss_the_robots_tuning():
    # The lab span's robot is tuned near its third mode (about 21 Hz); its 10.5 mm conductor
    # sheds at 17.6 Hz per m/s, so 1-7 m/s drive 17.6-123 Hz and the robot does nearly nothing
    from powerline_control.scenario.summary_severity import severity_section

    result = plc.run_scenario(plc.load_scenario(text="[severity]\nenabled = true"),
                              stages=("model", "severity"))
    sev = result.severity
    tuned = result.severity.robot_frequency
    assert 15.0 < tuned < 30.0
    idle = sev.robot.amplitude > 0.95 * sev.bare.amplitude
    assert idle.all()
    note = next(n for n in severity_section(result)["notes"] if "absorber is tuned" in n)
    assert f"tuned to {tuned:.3g} Hz" in note
    # St V / D = f: the wind speed that would drive the tuning
    speed = tuned * result.span.conductor.diameter / sev.bare.parameters["strouhal"]
    assert f"at about {speed:.3g} m/s" in note


def test_losing_to_the_fixed_damper_in_the_wind_is_a_shortfall(run):
    # The same runs with the placements swapped: the robot where the loop ended then sits where
    # the fixed damper was, and the fixed damper's amplitude is the loop's
    result = run[2]
    steady = result.aeolian_steady
    assert not result.steady_verdict          # a fixed-lift run: its window is judged too
    assert not any("self-limiting" in text for text in result.shortfalls)
    swapped = dataclasses.replace(steady, near_clamp=steady.closed_loop,
                                  closed_loop=steady.near_clamp)
    worse = dataclasses.replace(result, aeolian_steady=swapped)
    said = [text for text in worse.shortfalls if "self-limiting" in text]
    assert said == [f"in the self-limiting wind the line settles {steady.clamp_reduction:.2f}x "
                    f"as high (antinode amplitude {1e3 * steady.near_clamp.amplitude:.4g} mm) as "
                    f"with the robot parked at {steady.closed_loop.robot_position:.4g} m, a "
                    f"fixed damper parked near the clamp "
                    f"({1e3 * steady.closed_loop.amplitude:.4g} mm)"]


def test_ending_above_the_start_in_the_wind_is_a_shortfall(run):
    # The robot's start judged as the loop's end and the reverse: ending more than 5 % above
    # the start in steady state is said; a run in the self-limiting wind is judged by its steady
    # state alone (its own window is the amplitude still on its way)
    model, robot, result = run
    steady = result.aeolian_steady
    direct = simulate_aeolian(SPAN, WIND, robot, bc="pinned")   # parked at 13.9 m
    assert steady.start.robot_position == pytest.approx(13.9)
    assert steady.start.amplitude == pytest.approx(direct.amplitude, rel=1e-9)
    ratio = steady.start.amplitude / steady.closed_loop.amplitude
    assert ratio > 1.05      # a third of a loop off the antinode, against near it
    back = dataclasses.replace(steady, start=steady.closed_loop, closed_loop=steady.start)
    said = [text for text in dataclasses.replace(result, aeolian_steady=back).shortfalls
            if "where the robot started" in text]
    assert said == [f"in the self-limiting wind the line settles {ratio:.2f}x as high (antinode "
                    f"amplitude {1e3 * steady.start.amplitude:.4g} mm) as with the robot parked "
                    f"at {steady.closed_loop.robot_position:.4g} m, where the robot started "
                    f"({1e3 * steady.closed_loop.amplitude:.4g} mm)"]
    windy = dataclasses.replace(result, wind="self_limiting", aeolian_steady=back)
    assert all(text.startswith("in the self-limiting wind") for text in windy.shortfalls)


def test_a_run_in_the_self_limiting_wind_is_reported_by_its_steady_state():
    # The report of a closed loop run in that wind: its robot rows are the steady amplitudes'
    # ratios, not the run's own window (the amplitude on its way), and nothing asks to run longer
    from powerline_control.scenario.summary import result_sections
    from powerline_control.scenario.summary_verdict import result_verdict

    text = SCENARIO.replace("[severity]", 'wind = "self_limiting"\n[severity]')
    with warnings.catch_warnings():
        # an 8 s run in that wind does not settle, and says so: the steady state is the verdict
        warnings.simplefilter("ignore", TruncationWarning)
        result = plc.run_scenario(plc.load_scenario(text=text),
                                  stages=("model", "closed_loop", "severity"))
    loop = result.closed_loop.result
    steady = loop.aeolian_steady
    assert loop.wind == "self_limiting" and loop.steady_verdict
    # the start's steady state is simulate_aeolian's with the robot parked there (13.9 m)
    robot = dataclasses.replace(result.closed_loop.tuning.robot, position=13.9)
    mesh = loop.x.size - 1
    direct = simulate_aeolian(SPAN, WIND, robot, bc="pinned", n_elements=mesh)
    assert steady.start.amplitude == pytest.approx(direct.amplitude, rel=1e-9)
    verdict = result_verdict(result)
    rows = {h.label: h for h in verdict.headlines}
    ended = steady.closed_loop.amplitude
    for label, other in (("robot against no robot", steady.no_robot),
                         ("robot against its start", steady.start),
                         ("robot against a damper near the clamp", steady.near_clamp)):
        assert rows[label].value == pytest.approx(other.amplitude / ended, rel=1e-12)
        assert "steady antinode amplitude" in rows[label].verdict
    assert rows["robot against its start"].value > 1.05     # a third of a loop off, then near
    assert all("run longer" not in c.text for c in verdict.caveats)
    section = next(s for s in result_sections(result) if s["title"].startswith("Closed loop"))
    label, value, note = next(row for row in section["rows"] if row[0] == "vibration reduction")
    assert value == f"{steady.start_reduction:.2f}x"
    assert f"{loop.vibration_reduction:.2f}x" in note       # the window's, said beside it
