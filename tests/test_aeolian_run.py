"""The self-limiting aeolian run: it settles where the energy balance says, conserves energy, and
refuses what it cannot do.

Independent truths: the energy balance's amplitude (a root of P_w = P_c found by bracketing, no
time integration), the conservation of energy over the final window (wind input = dissipation +
energy gained), and the closed-form decay of quadratic power laws (constant damping ratios).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import InputError, TruncationWarning
from powerline_control.severity import simulate_aeolian


def _span(name: str, length: float) -> plc.Span:
    return plc.Span.at_rts_fraction(length, name, 0.2)


@pytest.mark.parametrize(("name", "length", "bc", "wind_speed"), [
    ("drake", 60.0, "clamped", 3.0),
    ("condor", 80.0, "pinned", 2.0),
    ("cardinal", 80.0, "pinned", 4.0),
])
def test_bare_line_settles_at_the_energy_balance(name, length, bc, wind_speed):
    span = _span(name, length)
    run = simulate_aeolian(span, wind_speed, bc=bc)
    balance = plc.severity.aeolian_severity(span, [wind_speed], bc=bc)
    assert run.settled
    # the energy balance at the Strouhal frequency; the run locks to the nearest mode, whose
    # frequency differs by at most half a mode spacing (a few % on these short spans)
    assert run.balance_amplitude == pytest.approx(float(balance.amplitude[0]))
    assert abs(run.relative_error) < 0.05
    # energy: what the wind puts in is what the conductor takes out (steady state)
    assert abs(run.energy_residual) < 0.01
    assert run.self_damping_power == pytest.approx(run.wind_power, rel=0.02)
    assert run.robot_power == 0.0


def test_run_approaches_the_balance_from_above_and_below():
    span = _span("drake", 60.0)
    low = simulate_aeolian(span, 3.0, start_amplitude=1e-3)
    high = simulate_aeolian(span, 3.0, start_amplitude=20e-3)
    assert low.envelope[0] < low.amplitude and high.envelope[0] > high.amplitude
    assert low.amplitude == pytest.approx(high.amplitude, rel=0.02)


def test_measured_powers_are_the_power_curve_and_the_law_at_the_amplitude():
    # The window's wind power is the power curve's at the locked mode's amplitude, at the mode's
    # frequency: the run uses the energy balance's functions, not a lift of its own.
    span = _span("drake", 60.0)
    run = simulate_aeolian(span, 3.0)
    d = span.conductor.diameter
    expected = float(plc.severity.wind_power(run.amplitude, run.frequency, d))
    assert run.wind_power == pytest.approx(expected, rel=0.02)
    law = float(plc.severity.self_damping_power(run.amplitude, run.frequency, span))
    assert run.self_damping_power == pytest.approx(law, rel=0.02)


def test_robot_takes_power_and_lowers_the_amplitude():
    span = _span("drake", 60.0)
    model = plc.LineModel(span, bc="clamped")
    robot = plc.tune_damper(model, 18, 32.6, 3.0, body_mass=5.0)
    bare = simulate_aeolian(span, 3.0)
    damped = simulate_aeolian(span, 3.0, robot)
    assert damped.settled and damped.amplitude < 0.2 * bare.amplitude
    assert damped.robot_power > 0.5 * damped.wind_power
    assert abs(damped.energy_residual) < 0.01


def test_a_wind_that_cannot_sustain_vibration_lets_it_die_out():
    # Oxlip (AAC, 10.5 mm) at 20 % RTS: the energy balance's 5 m/s amplitude is Y/D = 3e-4, a
    # balance of the self-damping with the CIGRE cubic's constant term at Y = 0, below any
    # measured power curve point; the wind's negative damping, capped at Y/D = 1e-3, cannot
    # hold the line there, and the run ends with the vibration gone, saying why.
    span = _span("oxlip", 50.0)
    with pytest.warns(TruncationWarning, match="5 m/s sustains only .* far below"):
        run = simulate_aeolian(span, 5.0)
    assert run.settled and run.amplitude < 1e-3 * run.balance_amplitude
    assert "wind damping ratio" in run.unreachable
    assert run.balance_amplitude / span.conductor.diameter < 1e-3


def test_too_short_a_run_says_so():
    with pytest.warns(TruncationWarning, match="max_duration"):
        run = simulate_aeolian(_span("drake", 60.0), 3.0, max_duration=1.0)
    assert not run.settled


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"wind_speed": -1.0}, "wind_speed"),
    ({"wind_speed": 3.0, "robot": "mdr"}, "robot"),
    ({"wind_speed": 3.0, "settle_tolerance": 0.0}, "settle_tolerance"),
    ({"wind_speed": 3.0, "max_duration": 0.0}, "max_duration"),
    ({"wind_speed": 3.0, "samples_per_period": 4}, "samples_per_period"),
    ({"wind_speed": 3.0, "wind_curve": "nope"}, "wind_curve"),
    ({"wind_speed": 3.0, "start_amplitude": 1.0}, "start_amplitude"),
])
def test_bad_input_is_named(kwargs, match):
    with pytest.raises(InputError, match=match):
        simulate_aeolian(_span("drake", 60.0), **kwargs)


def test_a_wind_beyond_the_power_curve_is_refused():
    # Bate's digitised curve starts at Y/D = 0.06 and ends at 0.2: a 1 m/s wind on Drake
    # balances beyond it (the energy balance says "above curve range")
    span = _span("drake", 300.0)
    balance = plc.severity.aeolian_severity(span, [1.0], wind_curve="bate", bc="clamped")
    assert balance.status[0] == "above curve range"
    with pytest.raises(InputError, match="wind_curve"):
        simulate_aeolian(span, 1.0, wind_curve="bate")


def test_decay_rate_matches_the_net_damping_closed_form():
    # Quadratic powers make both dampings constant ratios, zeta = 2 P / (m omega^3 Y^2): the
    # wind's zeta_w = 2 c D^2 / (m (2 pi)^3) for F(a) = c a^2, the conductor's
    # zeta_c = 2 k / (m (2 pi)^3) for P_c = k Y^2 f^3 (T^0). The amplitude then decays exactly
    # as exp(-(zeta_c - zeta_w) omega t).
    span = _span("drake", 60.0)
    d, m = span.conductor.diameter, span.conductor.mass_per_length
    c, k = 1e4, 10.0
    curve = plc.severity.WindPowerCurve("quadratic", "test", "F(a) = c a^2",
                                        coefficients=(-1e-9, c, 0.0, 0.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TruncationWarning)
        run = simulate_aeolian(span, 3.0, wind_curve=curve, self_damping_k=k,
                               self_damping_exponents=(2.0, 3.0, 0.0), start_amplitude=1e-3,
                               max_duration=2.0)
    zeta_w = 2 * c * d**2 / (m * (2 * math.pi) ** 3)
    zeta_c = 2 * k / (m * (2 * math.pi) ** 3)
    assert zeta_c - zeta_w > 0.005          # a decay of a few e-folds in 2 s
    omega = 2 * math.pi * run.frequency
    expected = np.exp(-(zeta_c - zeta_w) * omega * run.t_envelope)
    assert run.t_envelope[-1] > 1.5
    assert np.allclose(run.envelope / run.envelope[0], expected, rtol=1e-3)


def test_scenario_choices_are_the_severity_tables():
    # The schema imports no numerical module, so it spells the names out: they must stay the
    # tables' (every wind curve; the self-damping laws that carry a tension exponent).
    from powerline_control.scenario.config import SELF_DAMPING_NAMES, WIND_CURVE_NAMES

    assert set(WIND_CURVE_NAMES) == set(plc.severity.WIND_POWER_CURVES)
    laws = plc.severity.SELF_DAMPING_LAWS
    assert set(SELF_DAMPING_NAMES) == {name for name, law in laws.items() if law.n is not None}


def test_scenario_severity_reports_the_time_domain_beside_the_balance():
    from powerline_control.scenario.summary_severity import severity_section

    text = "\n".join([
        "[span]", 'preset = "conductor"', 'conductor = "drake"', "length = 60.0",
        "rts_fraction = 0.2", "[model]", 'bc = "clamped"', "[forcing]", 'kind = "aeolian"',
        "wind_speed = 3.0", "[robot]", "start = 30.0", "body_mass = 5.0",
        "suspended_mass = 3.0", "[severity]", "enabled = true"])
    result = plc.run_scenario(plc.load_scenario(text=text), stages=("model", "severity"))
    runs = result.severity.time_domain
    balance = plc.severity.aeolian_severity(_span("drake", 60.0), [3.0])
    assert runs.bare.balance_amplitude == pytest.approx(float(balance.amplitude[0]))
    assert abs(runs.bare.relative_error) < 0.05
    # the robot at the antinode does better than parked near the clamp, and both help
    assert runs.reduction > runs.clamp_reduction > 1
    assert runs.near_clamp.robot_position == pytest.approx(
        plc.severity.harmonic_mean_position(_span("drake", 60.0)))
    rows = {row[0]: row[1] for row in severity_section(result)["rows"]}
    said = rows["time domain at 3 m/s"]
    assert f"{runs.reduction:.3g}x lower" in said and f"{runs.clamp_reduction:.3g}x lower" in said
    # the command's JSON carries the same numbers
    from powerline_control.scenario.summary_json import result_json

    data = result_json(result)["severity_time_domain"]
    assert data["reduction"] == pytest.approx(runs.reduction)
    assert data["bare_amplitude_m"] == pytest.approx(runs.bare.amplitude)


def test_a_mode_the_wind_has_not_fed_gets_no_self_damping_and_no_nan():
    # A band mode at 3e-163 m: its Y^2 underflows and P_c / Y^2 was 0 / 0 (NaN stopped a run on
    # a 372 m Condor span). The law's ratio, 2 k Y^(a-2) f^b / (m omega^3) with a = 2.44, tends
    # to 0 there; the locked mode's coefficients are those of the state without that mode.
    from powerline_control.severity import aeolian_damping
    from powerline_control.simulation.plant import ModalPlant

    span = _span("drake", 60.0)
    plant = ModalPlant(plc.LineModel(span), None, 24, dt=1e-3)
    damping = aeolian_damping(plant, span, 3.0)
    z = damping.start_state(plant, 0.005)
    quiet = (damping.locked + 1) % damping.band
    z_quiet = z.copy()
    z_quiet[quiet] = 2.3e-162    # the smallest modal coordinate whose square is not 0
    assert 0 < damping.amplitudes(z_quiet)[quiet] and damping.amplitudes(z_quiet)[quiet] ** 2 == 0
    own, wind = damping.coefficients(z_quiet)
    own_without, wind_without = damping.coefficients(z)
    assert np.all(np.isfinite(own)) and np.isfinite(wind)
    assert own[quiet] == 0.0
    assert np.array_equal(own, own_without) and wind == wind_without


@pytest.mark.parametrize(("name", "rts", "wind_speed", "settles"), [
    ("drake", 0.2, 7.0, True),     # 3.6e-2 D, the wind's ratio 1.1e-3 at the balance
    ("condor", 0.2, 7.0, True),    # 2.9e-2 D, 1.6e-3
    ("oxlip", 0.4, 1.0, False),    # 3.2e-3 D, 0.11: the simulated wind gives at most 0.1
    ("oxlip", 0.2, 1.0, False),    # 1.4e-3 D, 0.53
    ("oxlip", 0.2, 2.5, False),    # 5.4e-4 D, below the 1e-3 D floor
])
def test_settling_balance_tells_where_the_run_settles_at_the_balance(name, rts, wind_speed,
                                                                    settles):
    """settling_balance's verdict, from the energy balance alone, against the time-domain run
    itself: where it says the self-limiting wind cannot hold the balance, the run settles more
    than 10 % below it; where it can, within 10 %."""
    from powerline_control.severity.self_limiting import settling_balance

    span = plc.Span.at_rts_fraction(40.0, name, rts)
    amplitude, problem = settling_balance(span, plc.AeolianForce(wind_speed), "pinned")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = simulate_aeolian(span, wind_speed, bc="pinned", max_duration=900.0)
    assert run.settled and run.balance_amplitude == pytest.approx(amplitude)
    assert (problem is None) is settles
    # the run itself says so: its result and a warning carry the same reason
    assert run.unreachable == problem
    assert any(issubclass(w.category, TruncationWarning) for w in caught) is not settles
    assert (abs(run.relative_error) < 0.1) is settles
