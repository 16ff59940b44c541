"""The energy balance with the robot coupled to the line (``severity.coupled_balance``).

Independent truths: the energy balance's closed form for the bare line (aeolian_severity at the
wind speed that locks into the FE mode), the first-order damper power for a robot whose
impedance is small against the line's wave impedance, the time-domain run that integrates the
approach to the same steady state (simulate_aeolian), and a pinned string's antinodes.
"""

import warnings

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import InputError, TruncationWarning
from powerline_control.fem import AtAntinode, ImpedanceDamper
from powerline_control.severity import aeolian_severity, coupled_balance, simulate_aeolian

SPAN = plc.Span.at_rts_fraction(60.0, "drake", 0.2)


def test_bare_line_is_the_closed_form_balance_at_the_locked_frequency():
    balance = coupled_balance(SPAN, 3.0, bc="pinned")
    # the wind speed whose Strouhal frequency is the FE mode the wind locks into
    speed = balance.frequency * SPAN.conductor.diameter / 0.185
    closed_form = float(aeolian_severity(SPAN, [speed], bc="pinned").amplitude[0])
    assert balance.status == "balanced"
    assert balance.amplitude == pytest.approx(closed_form, rel=1e-9)
    assert balance.mode == round(SPAN.length / SPAN.loop_length(balance.frequency))
    assert balance.robot_power == 0.0
    assert balance.wind_power == pytest.approx(balance.self_damping_power, rel=1e-9)


@pytest.mark.parametrize("absorber", [0.003, 0.03])
def test_light_robot_takes_the_first_order_power(absorber):
    """|Z| well below sqrt(T m): the robot leaves the standing wave as it is."""
    robot = plc.MDR.tuned(30.0, 0.0, absorber, frequency=19.7, damping_ratio=0.1)
    balance = coupled_balance(SPAN, 3.0, AtAntinode(robot), bc="pinned")
    assert balance.robot_impedance_ratio < 0.1
    assert balance.robot_power > 0.4 * balance.wind_power      # the robot matters
    assert balance.amplitude == pytest.approx(balance.first_order_amplitude, rel=0.01)


def test_at_antinode_parks_the_robot_on_the_pinned_string_antinode():
    robot = plc.MDR.tuned(30.0, 0.0, 0.01, frequency=19.7, damping_ratio=0.1)
    balance = coupled_balance(SPAN, 3.0, AtAntinode(robot), bc="pinned")
    n = balance.mode
    antinodes = (np.arange(n) + 0.5) * SPAN.length / n
    assert balance.robot_position == pytest.approx(
        antinodes[np.argmin(np.abs(antinodes - 30.0))], abs=1e-3)


@pytest.mark.parametrize("case", [("drake", 60.0, "clamped", 3.0, 5.0),
                                  ("drake", 60.0, "clamped", 0.3, 0.5),
                                  ("cardinal", 80.0, "pinned", 1.0, 1.0)])
def test_heavy_robot_agrees_with_the_time_domain_run(case):
    """A robot many times the wave impedance reshapes the wave: the first-order power is 1.3-5x
    off, the coupled balance and the integrated approach to steady state agree."""
    conductor, length, bc, absorber, body = case
    span = plc.Span.at_rts_fraction(length, conductor, 0.2)
    position = (18 // 3 + 0.5) * length / 18
    robot = plc.tune_damper(plc.LineModel(span, bc=bc), 18, position, absorber, body_mass=body)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")    # amplitudes below the power curves' data
        run = simulate_aeolian(span, 3.0, robot, bc=bc)
        balance = coupled_balance(span, 3.0, robot, bc=bc)
    assert balance.status == "balanced"
    assert balance.amplitude == pytest.approx(run.amplitude, rel=0.02)
    assert abs(balance.energy_residual) < 1e-9
    assert balance.wind_power == pytest.approx(
        balance.self_damping_power + balance.robot_power, rel=1e-9)


def test_heavy_robot_first_order_is_far_off():
    span = plc.Span.at_rts_fraction(60.0, "drake", 0.2)
    robot = plc.tune_damper(plc.LineModel(span, bc="clamped"), 18, 6.5 * 60 / 18, 3.0,
                            body_mass=5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        balance = coupled_balance(span, 3.0, robot, bc="clamped")
    assert balance.robot_impedance_ratio > 3
    assert balance.amplitude > 3 * balance.first_order_amplitude


def test_no_vibration_where_the_time_domain_run_dies_out():
    """Oxlip 220 m at 1 m/s: the closed form balances at 1.4e-3 D, below the power curves'
    data, with a wind damping ratio beyond the 10 % the shared modal damping allows; the
    time-domain run decays to nothing and the coupled balance finds no limit cycle."""
    oxlip = plc.Span.at_rts_fraction(220.0, "oxlip", 0.2)
    with pytest.warns(TruncationWarning, match="wind damping ratio of 0.53"):
        run = simulate_aeolian(oxlip, 1.0, bc="pinned")
    balance = coupled_balance(oxlip, 1.0, bc="pinned")
    assert run.amplitude < 0.05 * run.balance_amplitude     # decayed 40x from its start
    assert balance.status == "no vibration"
    assert balance.amplitude == 0.0 and balance.wind_power == 0.0


@pytest.mark.parametrize(("robot", "words"), [
    (ImpedanceDamper(1.0, [10.0, 30.0], [5.0, 5.0]), "ImpedanceDamper"),
    (AtAntinode(plc.MDR.tuned(30.0, 0.0, 0.01, frequency=19.7, damping_ratio=0.1),
                factor=0.5), "factor 0.5"),
    (plc.MDR.tuned(75.0, 0.0, 0.01, frequency=19.7, damping_ratio=0.1), "75"),
])
def test_bad_robot_is_refused_by_name(robot, words):
    with pytest.raises(InputError, match="robot") as info:
        coupled_balance(SPAN, 3.0, robot, bc="pinned")
    assert words in str(info.value)


def test_bad_wind_speed_is_refused_by_name():
    with pytest.raises(InputError, match="wind_speed"):
        coupled_balance(SPAN, -1.0)


def test_severity_with_the_coupled_robot_is_the_coupled_balance():
    robot = plc.tune_damper(plc.LineModel(SPAN, bc="clamped"), 18, 6.5 * 60 / 18, 3.0,
                            body_mass=5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        severity = aeolian_severity(SPAN, [3.0], [robot], bc="clamped", damper_model="coupled")
        coupled = coupled_balance(SPAN, 3.0, robot, bc="clamped")
        first = aeolian_severity(SPAN, [3.0], [robot], bc="clamped")
    assert float(severity.amplitude[0]) == pytest.approx(coupled.amplitude, rel=1e-12)
    assert float(severity.damper_power[0]) == pytest.approx(coupled.robot_power, rel=1e-12)
    assert float(first.amplitude[0]) == pytest.approx(coupled.first_order_amplitude, rel=1e-12)


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"dampers": [ImpedanceDamper(1.0, [10.0, 30.0], [5.0, 5.0])], "damper_model": "coupled"},
     "dampers"),
    ({"damper_model": "exact"}, "damper_model"),
])
def test_severity_refuses_what_the_coupled_model_cannot_take(kwargs, words):
    with pytest.raises(InputError, match=words):
        aeolian_severity(SPAN, [3.0], **kwargs)
