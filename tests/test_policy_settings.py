"""PolicySettings: the closed-loop policy's settings, documented, checked, and passed through.

The defaults are the policy's tuned values (a run with ``settings=PolicySettings()`` is the run
without it); each field's documentation names its value and what it guards; a bad value is an
InputError naming the field, the value and what is allowed; the targeting's phases move as the
policy's rules say.
"""

import dataclasses
import math
import re

import numpy as np
import pytest
from numpydoc.docscrape import ClassDoc

import powerline_control as plc
from powerline_control.closed_loop import policy
from powerline_control.closed_loop.policy import Phase, Targeting


def test_every_setting_is_documented_with_its_value():
    documented = {p.name: " ".join(p.desc) for p in ClassDoc(plc.PolicySettings)["Parameters"]}
    settings = plc.PolicySettings()
    assert set(documented) == {f.name for f in dataclasses.fields(settings)}
    for name, text in documented.items():
        value = getattr(settings, name)
        # the description opens with the default ("0.25.", "3.0 s.", "1e-06" as "1e-6")
        assert float(text.split()[0].rstrip(".")) == value, (name, text)


@pytest.mark.parametrize(("field", "value"), [
    ("min_gain", 1.5), ("min_gain", -0.1), ("max_choices", 2.5), ("max_choices", True),
    ("max_choices", 0), ("trusted_share", math.nan), ("unsteady_limit", 0.0),
    ("decision_tone_window", math.inf), ("less_certain", 0.5), ("quiet_fraction", "0.25"),
])
def test_a_bad_setting_names_itself_its_value_and_what_is_allowed(field, value):
    named = rf"'PolicySettings\.{field}' setting must be "
    with pytest.raises(plc.InputError, match=named) as info:
        plc.PolicySettings(**{field: value})
    assert f"Got {value!r}." in str(info.value)


def _stated_ends(allowed: str) -> list[tuple[float, bool]]:
    """(value, accepted) at each end of the range a setting's message states."""
    ends = []
    if match := re.search(r"(>=|>) (-?[0-9.]+)", allowed):
        ends.append((float(match[2]), match[1] == ">="))
    if match := re.search(r"([\[(])(-?[0-9.]+), (-?[0-9.]+)([\])])", allowed):
        ends += [(float(match[2]), match[1] == "["), (float(match[3]), match[4] == "]")]
    return ends


@pytest.mark.parametrize("item", dataclasses.fields(plc.PolicySettings), ids=lambda f: f.name)
def test_each_setting_takes_the_ends_of_its_range_as_its_message_states(item):
    # "an integer >= 1" takes 1; "a number in [0, 1)" takes 0, not 1; "> 0" not 0.
    ends = _stated_ends(item.metadata["allowed"])
    assert ends, item.metadata["allowed"]
    for value, accepted in ends:
        value = int(value) if item.metadata["integer"] else value
        if accepted:
            assert getattr(plc.PolicySettings(**{item.name: value}), item.name) == value
        else:
            with pytest.raises(plc.InputError, match=item.name):
                plc.PolicySettings(**{item.name: value})


def test_settings_are_frozen_and_integers_stay_integers():
    settings = plc.PolicySettings(max_choices=np.int64(2), min_gain=np.float32(0.1))
    assert type(settings.max_choices) is int and type(settings.min_gain) is float
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.min_gain = 0.2


def test_run_closed_loop_refuses_settings_that_are_not_policy_settings():
    model = plc.LineModel(plc.Span.paper_lab(), 20, damping=plc.ModalDamping(0.01))
    robot = plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1)
    with pytest.raises(plc.InputError, match="'settings' parameter must be a PolicySettings"):
        plc.run_closed_loop(model, plc.HarmonicForce(1.0, 24.0, 0.5), robot, sensors=[4, 9, 15],
                            duration=6.0, calibration=1.0, settings={"min_gain": 0.1})


def test_choose_parked_position_takes_the_settings():
    # The docstring's lab span: the loop at 0.58 m is predicted 83 % better than the start.
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=40, damping=plc.ModalDamping(0.01))
    snap = plc.simulate(model, plc.HarmonicForce(1.0, 24.0, 0.5), duration=3.0, dt=1e-3)
    robot = plc.tune_damper(model, 3, 1.83, 0.05, body_mass=0.02)
    args = (model, snap.displacement[:, -2000:], snap.dt, robot, 1.2, plc.RobotLimits(0.5, 1.0))
    default = plc.closed_loop.choose_parked_position(*args)
    same = plc.closed_loop.choose_parked_position(*args, settings=plc.PolicySettings())
    assert same.position == default.position and np.array_equal(same.predicted,
                                                                   default.predicted)
    # a move must pay more than the best one predicted: the robot stays where it is
    stay = plc.closed_loop.choose_parked_position(
        *args, settings=plc.PolicySettings(min_gain=0.9, near_optimal=0.0))
    assert default.gain < 0.9
    finer = plc.closed_loop.choose_parked_position(*args, settings=plc.PolicySettings(min_grid=999))
    assert finer.grid.size == 999 and stay.grid.size == default.grid.size


def _choice(position):
    return policy.Choice(position, np.array([0.5, 1.0, 1.5]), np.array([1e-4, 2e-4, 3e-4]), 1e-3)


def test_targeting_moves_from_first_target_through_confirming_to_final():
    targeting = Targeting()
    assert targeting.phase is Phase.FIRST_TARGET
    assert targeting.due(0.0, True, 1.0, 1.0, 0.0) == (True, False)   # a first target is due
    targeting.accept(_choice(0.5), 1.2, 1.0, 24.0, True)
    assert targeting.phase is Phase.CONFIRMING and targeting.goal == 0.5
    targeting.update_clocks(1.0, True, 24.0, 0.05)                     # still from 1 s
    assert targeting.due(2.5, True, 1.0, 1.0, 0.0) == (False, True)   # confirm after a window
    note = targeting.accept(_choice(0.6), 0.5, 1.0, 24.0, False)      # the same loop (0.25)
    assert targeting.phase is Phase.FINAL and note.startswith("confirm")
    assert targeting.due(9.0, True, 1.0, 1.0, 0.0) == (False, False)  # final: nothing is due


def _small_gain(position, gain):
    """A choice predicted ``gain`` lower at ``position`` than where the robot is."""
    return policy.Choice(position, np.array([position]), np.array([1e-4]), 1e-4 / (1 - gain))


def test_a_hold_is_confirmed_on_a_window_recorded_after_it():
    targeting = Targeting()                                   # min_gain 5 %, refine_gain 1 %
    targeting.update_clocks(0.0, True, 24.0, 0.05)            # parked, still from the start
    note = targeting.accept(_small_gain(1.25, 0.03), 1.2, 1.0, 24.0, True, (0.0, 0.0))
    assert note.startswith("hold at 1.2")
    targeting.decided_at = 5.0                                # the hold was decided at 5 s
    # the robot has been still for 5 s, but the window that decided the hold would only decide
    # it again, by the refinement's smaller bar: the confirmation waits for a new window
    assert targeting.due(5.05, True, 1.0, 1.0, 0.0) == (False, False)
    assert targeting.due(6.0, True, 1.0, 1.0, 0.0) == (False, True)


def test_a_refinement_pays_refine_gain():
    targeting = Targeting()
    targeting.accept(_choice(0.5), 1.2, 1.0, 24.0, True)      # moved to 0.5 m
    assert targeting.accept(_small_gain(0.55, 0.03), 0.5, 1.0, 24.0, False).startswith(
        "confirm 0.55")
    assert targeting.accept(_small_gain(0.56, 0.005), 0.55, 1.0, 24.0, False).startswith(
        "confirm 0.55 m (the refinement")


def test_a_confirmation_elsewhere_tries_another_loop_until_max_choices():
    targeting = Targeting(settings=plc.PolicySettings(max_choices=2))
    targeting.accept(_choice(0.5), 1.2, 1.0, 24.0, True)
    assert targeting.accept(_choice(1.5), 0.5, 1.0, 24.0, False).startswith("another loop")
    assert targeting.phase is Phase.CONFIRMING and targeting.choices == 2
    assert targeting.accept(_choice(0.5), 1.5, 1.0, 24.0, False).startswith("final")
    assert targeting.phase is Phase.FINAL


def test_a_wider_same_loop_confirms_where_the_default_tries_another():
    wide = Targeting(settings=plc.PolicySettings(same_loop=1.5))
    wide.accept(_choice(0.5), 1.2, 1.0, 24.0, True)
    assert wide.accept(_choice(1.5), 0.5, 1.0, 24.0, False).startswith("confirm")


def _after_a_move(predicted_rise, settings=None):
    """A targeting that decided at 1.2 m (the sensors measured power 1.0 there, steady) and
    sent the robot to 0.5 m, its belief predicting the sensors' power x ``predicted_rise``."""
    targeting = Targeting() if settings is None else Targeting(settings=settings)
    targeting.check_measured(1.0, 1e-4, 1.2, True, True)             # the reference
    targeting.accept(_choice(0.5), 1.2, 1.0, 24.0, True)
    targeting.remember(1.2, 1.0, True, predicted_rise)
    return targeting


def test_a_move_whose_measured_rise_contradicts_the_prediction_is_undone():
    # measured 5x the power where 0.2x was predicted: 5 > 2 (rise) and 5 > 4 * 0.2 (factor)
    targeting = _after_a_move(0.2)
    note = targeting.check_measured(5.0, 1e-4, 0.5, False, True, return_reach=1.0)
    assert note.startswith("return to 1.2 m") and "contradict" in note
    assert targeting.goal == 1.2 and targeting.phase is Phase.FINAL
    assert targeting.contradictions == 1


def test_a_contradicted_move_too_far_to_undo_is_final_where_it_is():
    targeting = _after_a_move(0.2)
    note = targeting.check_measured(5.0, 1e-4, 0.5, False, True, return_reach=0.5)
    assert note.startswith("final at 0.5 m") and "longer than the rest of the run" in note
    assert targeting.goal == 0.5 and targeting.phase is Phase.FINAL
    assert targeting.contradictions == 1


@pytest.mark.parametrize(("measured", "predicted", "steady"), [
    (5.0, 2.0, True),      # the rise was predicted (5 < 4 x 2): the belief holds
    (1.9, 0.1, True),      # below contradiction_rise (2)
    (5.0, 0.2, False),     # a window still beating is no measurement of the move
])
def test_a_rise_that_was_predicted_or_small_or_unsteady_is_no_contradiction(
        measured, predicted, steady):
    targeting = _after_a_move(predicted)
    assert targeting.check_measured(measured, 1e-4, 0.5, False, steady) is None
    assert targeting.contradictions == 0 and targeting.goal == 0.5


def test_the_contradiction_thresholds_are_the_settings():
    lenient = plc.PolicySettings(contradiction_rise=6.0)
    assert _after_a_move(0.2, lenient).check_measured(5.0, 1e-4, 0.5, False, True) is None
    strict = plc.PolicySettings(contradiction_factor=1.0)
    assert _after_a_move(2.0, strict).check_measured(
        5.0, 1e-4, 0.5, False, True).startswith("return to 1.2 m")
