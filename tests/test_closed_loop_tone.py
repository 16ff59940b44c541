"""The tone the closed loop decides at: resolved from the free modes beside the load.

On a lightly damped long span the line rings in free modes a mode spacing or less from the load
for tens of seconds, and the 2 s window the controller watches for wind changes puts the spectral
peak up to a mode spacing off the load. Truth here: the taut string's closed-form mode spacing
c / 2L, the load's own frequency, and the family judge's sparse FE steady state with the robot
attached (tests/closed_loop_family.py), all independent of the policy.
"""

import closed_loop_family as fam
import numpy as np
import pytest

import powerline_control as plc
from powerline_control.closed_loop import policy


def _string_frequencies(span, n):
    """Taut string: f_k = k c / 2L (c = sqrt(T / m)); the spacing is c / 2L."""
    c = np.sqrt(span.tension / span.conductor.mass_per_length)
    return np.arange(1, n + 1) * c / (2 * span.length)


@pytest.mark.parametrize("where", [0.3, 17.5, 39.9])   # in the band, at either end
def test_mode_spacing_is_the_string_fundamental(where):
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    modes = _string_frequencies(span, 40)
    spacing = float(modes[0])
    assert policy.mode_spacing(modes, where * spacing) == pytest.approx(spacing, rel=1e-12)
    assert policy.resolve_time(where * spacing, modes) == pytest.approx(
        min(policy.TONE_RESOLUTION / spacing, policy.MAX_TONE_WAIT))


def test_one_mode_has_no_spacing_and_needs_no_wait():
    assert policy.mode_spacing(np.array([10.0]), 10.0) == np.inf
    assert policy.resolve_time(10.0, np.array([10.0])) == 0.0


def test_a_new_target_waits_for_the_record_and_for_time_to_move():
    targeting = policy.Targeting()
    # 8 s resolves the tone; a 40 s run leaves time for it, a 12 s run only for a quarter of it
    assert targeting.tone_wait(7.9, 8.0, 40.0) and not targeting.tone_wait(8.0, 8.0, 40.0)
    assert not targeting.tone_wait(3.0, 8.0, 12.0)
    # after a wind change seen at 20 s, the excitation's record starts a change window earlier
    targeting.pending_since = 20.0
    assert targeting.tone_start(True, 21.0, 2.0) == 18.0
    assert targeting.excitation_seen == 20.0
    assert targeting.tone_wait(25.9, 8.0, 60.0) and not targeting.tone_wait(26.0, 8.0, 60.0)


def test_decisions_are_made_at_the_load_where_a_short_window_is_a_mode_off():
    # Cardinal 306 m clamped, zeta 0.18 %, a 5 N sine on mode 90 (16.364 Hz; mode spacing
    # 0.18 Hz): over the first 2 s the sensors' spectral peak is a mode spacing below the load
    # (16.16 Hz), and a shape fitted there parked the robot on the true worst spot (2.85x the best).
    scenario = fam.scenario(52)
    args = scenario.run_arguments()
    result = plc.run_closed_loop(args.pop("span"), args.pop("force"), args.pop("robot"),
                                 args.pop("limits"), **args)
    load = scenario.final_load.frequency
    c = np.sqrt(scenario.span.tension / scenario.span.conductor.mass_per_length)
    spacing = c / (2 * scenario.span.length)
    assert abs(result.frequency[0] - load) > 0.5 * spacing   # the 2 s window at calibration's end
    tones = np.array([p[4] for p in result.predictions])
    assert tones.size and np.all(np.abs(tones - load) < 0.1 * spacing)
    outcome = fam.evaluate(scenario, result)
    assert outcome.settled
    assert outcome.closed_over_best < 1.5 and outcome.closed_over_start < 1.0
