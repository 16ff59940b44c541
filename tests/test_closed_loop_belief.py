"""The closed loop's belief: the controller predicts with the span it is told, not the truth.

Truth here is outside the policy: the spans and models the test builds itself (the simulated
line's and the one the controller is told), the node counts of their meshes, and the standing
wave's closed-form loop length; never the policy's own output compared with itself.
"""

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.closed_loop import belief as closed_loop_belief
from powerline_control.closed_loop import loop as closed_loop_run

LAB = plc.Span.paper_lab()
DAMPING = plc.ModalDamping(0.005)
TRUTH = plc.LineModel(LAB, 40, damping=DAMPING)
MODE3 = float(TRUTH.natural_frequencies(3)[2])          # 24.5 Hz
SENSORS = [8, 18, 30]                                   # 0.73, 1.65, 2.75 m
ROBOT = plc.MDR.tuned(1.2, 0.02, 0.05, MODE3, 0.1)
FORCE = plc.HarmonicForce(1.0, 0.99 * MODE3, 0.5)       # near mode 3
RUN = dict(sensors=SENSORS, duration=6.0, calibration=1.0, seed=2)
# The nominal the controller is told: the catalogue span with the stringing tension, 3 % off the
# tension the line has on the day.
TOLD = plc.Span(LAB.length, LAB.tension / 1.03, LAB.conductor)


def test_no_nominal_is_the_model_itself_to_the_last_digit_and_a_span_assumes_its_damping():
    plain = plc.run_closed_loop(TRUTH, FORCE, ROBOT, **RUN)
    same_model = plc.run_closed_loop(TRUTH, FORCE, ROBOT, nominal=TRUTH, calibrate=False, **RUN)
    # the span alone, with the damping it would assume, meshed as the line is
    same_span = plc.run_closed_loop(
        TRUTH, FORCE, ROBOT, calibrate=False, **RUN,
        nominal=plc.LineModel(LAB, 40, damping=closed_loop_belief.ASSUMED_DAMPING))
    spy = []
    monkey = pytest.MonkeyPatch()
    monkey.setattr(closed_loop_run, "believe", lambda told, **kw: spy.append(told) or
                   closed_loop_belief.believe(told, **kw))
    try:
        told_span = plc.run_closed_loop(TRUTH, FORCE, ROBOT, nominal=LAB, calibrate=False, **RUN)
    finally:
        monkey.undo()
    for other in (same_model, same_span):
        assert np.array_equal(plain.robot_position, other.robot_position) == (other is same_model)
        assert (plain.decisions == other.decisions) == (other is same_model)
    # a Span says nothing of the line's damping: the controller assumes one, never the truth's
    assert spy[0].damping == closed_loop_belief.ASSUMED_DAMPING != TRUTH.damping
    assert np.array_equal(same_span.robot_position, told_span.robot_position)
    assert plain.belief == plain.nominal == plain.span == LAB
    assert plain.calibrations == ()          # told the truth, nothing to calibrate


def test_with_the_tension_3_percent_off_the_belief_is_the_nominal_and_the_span_the_truth():
    truth = plc.LineModel(plc.Span(LAB.length, 1.03 * TOLD.tension, LAB.conductor), 40,
                          damping=DAMPING)
    result = plc.run_closed_loop(truth, FORCE, ROBOT, nominal=TOLD, calibrate=False, **RUN)
    assert result.belief == result.nominal == TOLD
    assert result.span == truth.span and result.span.tension == pytest.approx(LAB.tension)
    assert result.calibrations == ()
    assert "belief: tension 383.5 N, told 383.5 N; truth 395 N" in result.summary()


def test_the_policy_predicts_with_the_nominal_only(monkeypatch):
    # Spies on every prediction of the policy: the receptances, the modes the tone is resolved
    # from, and the loop length a target is anchored with must be the nominal's (tension 383.5 N,
    # a 25-element mesh of its own), never the simulated line's (395 N, 40 elements). Using the
    # simulated line's model or span for any of them fails here.
    truth = plc.LineModel(LAB, 40, damping=DAMPING)
    told = plc.LineModel(TOLD, 25, damping=DAMPING, mdr=ROBOT)   # its robot is ignored
    seen = {"believe": [], "plants": [], "modes": [], "loops": []}

    def spy(name, function, read):
        def wrapped(*args, **kwargs):
            seen[name].append(read(*args, **kwargs))
            return function(*args, **kwargs)
        monkeypatch.setattr(closed_loop_run, function.__name__, wrapped)

    spy("believe", closed_loop_run.believe, lambda model, **kw: model)
    spy("plants", closed_loop_run.kernel_shape, lambda plant, *a: plant.model)
    spy("plants", closed_loop_run.choose_target, lambda shape, plant, *a: plant.model)
    spy("plants", closed_loop_run.predicted_figure,
        lambda objective, shape, plant, *a: plant.model)
    spy("modes", closed_loop_run.resolve_time, lambda tone, modes, *policy: modes)
    accept = closed_loop_run.Targeting.accept

    def accept_spy(self, choice, here, loop, frequency, retarget, excitation=(0.0, 0.0)):
        seen["loops"].append((loop, frequency))
        return accept(self, choice, here, loop, frequency, retarget, excitation)

    monkeypatch.setattr(closed_loop_run.Targeting, "accept", accept_spy)
    result = plc.run_closed_loop(truth, FORCE, ROBOT, nominal=told, calibrate=False, **RUN)
    assert seen["believe"]
    for model in seen["believe"]:   # the nominal as told, without its robot; never the truth
        assert model is not truth and model.span == TOLD and model.mdr is None
        assert np.array_equal(model.node_positions, told.node_positions)
    assert seen["plants"]
    for model in seen["plants"]:
        assert model is not truth and model.span == TOLD and model.n_elements == 25
    nominal_modes = told.with_robot(None).natural_frequencies(8)
    assert seen["modes"] and all(np.allclose(m[:8], nominal_modes, rtol=0.02, atol=0)
                                 for m in seen["modes"])
    # a loop length is the told span's half-wavelength at the tone (closed form, c = sqrt(T/m))
    assert seen["loops"]
    for loop, _ in seen["loops"]:
        assert loop == pytest.approx(
            float(TOLD.loop_length(result.predictions[0][4])), rel=0.05)
    # the predicted shapes live on the nominal's mesh (26 nodes), not the simulated one (41)
    assert all(prediction[3].shape == (26,) for prediction in result.predictions)


def test_a_nominal_on_another_mesh_reads_the_sensors_between_its_nodes():
    # 0.73, 1.65 and 2.75 m are no nodes of a 17-element mesh (0.215 m elements): the belief
    # reads its modes there through the shape functions.
    told = plc.LineModel(TOLD, 17, damping=DAMPING)
    result = plc.run_closed_loop(TRUTH, FORCE, ROBOT, nominal=told, calibrate=False, **RUN)
    assert result.predictions and result.predictions[0][3].shape == (18,)
    assert result.belief == TOLD


@pytest.mark.parametrize("length", [0.98 * LAB.length, 1.02 * LAB.length])
def test_a_nominal_of_another_length_is_refused_by_name(length):
    other = plc.Span(length, LAB.tension, LAB.conductor)
    with pytest.raises(plc.InputError, match=r"'nominal'.*within 1 %") as caught:
        plc.run_closed_loop(TRUTH, FORCE, ROBOT, nominal=other, **RUN)
    assert f"{length:g} m" in str(caught.value) and "3.66 m long" in str(caught.value)


@pytest.mark.parametrize("nominal", ["paper_lab", 395.0, LAB.conductor])
def test_a_nominal_of_the_wrong_type_is_refused_by_name(nominal):
    with pytest.raises(plc.InputError, match=r"'nominal' parameter must be a Span, a LineModel"):
        plc.run_closed_loop(TRUTH, FORCE, ROBOT, nominal=nominal, **RUN)


def test_calibration_moves_the_belief_toward_the_truth_by_the_rule():
    # Told 10 % below the truth (359 N against 395 N): the controller calibrates after the
    # calibration window and at each decision, on the sensors' whole record so far, and
    # predicts with the calibrated span once its tension moves by more than 0.1 %. A wind
    # change (mode 3, then mode 4 at 6 s) makes decisions on records that show more lines.
    told = plc.Span(LAB.length, LAB.tension / 1.10, LAB.conductor)
    mode4 = float(TRUTH.natural_frequencies(4)[3])
    force = [(0.0, plc.HarmonicForce(1.0, 1.02 * MODE3, 0.5)),
             (6.0, plc.HarmonicForce(1.0, 0.99 * mode4, 0.5))]
    result = plc.run_closed_loop(TRUTH, force, ROBOT, nominal=told, **dict(RUN, duration=14.0))
    times = [time for time, _ in result.calibrations]
    assert times[0] == result.calibration_time
    decided = {time for time, _ in result.decisions}
    assert set(times[1:]) <= decided
    for time, calibration in result.calibrations:    # the record from the start up to then
        assert calibration.duration == pytest.approx(time, abs=1.5 * 1e-3)
        assert calibration.nominal == told
    # the rule, replayed on the history: a calibration whose main peak holds at least 80 % of
    # its posterior, and that is not more than twice as uncertain as the one believed, replaces
    # the belief when its tension differs from the believed one by more than 0.1 %
    believed, believed_std = told.tension, np.inf
    for _, calibration in result.calibrations:
        if calibration.peak_share < 0.8 or calibration.tension_std > 2 * believed_std:
            continue
        believed_std = calibration.tension_std
        if abs(calibration.tension - believed) > 1e-3 * believed:
            believed = calibration.tension
    assert result.belief.tension == believed != told.tension
    assert any(text.startswith("believe tension") for _, text in result.decisions)
    # ... and toward the truth (the simulated line's tension, which the controller never read)
    assert abs(result.belief.tension - LAB.tension) < 0.5 * abs(told.tension - LAB.tension)
    assert f"truth {LAB.tension:.5g} N" in result.summary().splitlines()[0]


def test_calibrate_must_be_a_bool():
    with pytest.raises(plc.InputError, match="'calibrate' parameter must be True or False"):
        plc.run_closed_loop(TRUTH, FORCE, ROBOT, nominal=TOLD, calibrate="yes", **RUN)


def test_a_run_that_ends_worse_than_its_start_or_a_clamp_damper_says_so():
    import dataclasses
    import warnings

    result = plc.run_closed_loop(TRUTH, FORCE, ROBOT, **RUN)
    assert result.shortfalls == ()            # this run ends far below both
    closed = result.comparison("closed_loop")
    # the same run, had it ended at 1.2x the start's RMS and above the clamp damper's
    worse = tuple(dataclasses.replace(c, rms=1.2 * result.comparison("start").rms)
                  if c.name == "closed_loop" else c for c in result.comparisons)
    assert result.settled
    shortfalls = dataclasses.replace(result, comparisons=worse).shortfalls
    # a robot still moving at the end is no verdict
    assert dataclasses.replace(result, comparisons=worse, settled=False).shortfalls == ()
    start, clamp = result.comparison("start"), result.comparison("near_clamp")
    expected = [name for name, other, tol in (("started", start, 1.05),
                                              ("near the clamp", clamp, 1.0))
                if 1.2 * start.rms > tol * other.rms]
    assert len(shortfalls) == len(expected) >= 1
    assert "where the robot started" in shortfalls[0] and "1.20x" in shortfalls[0]
    assert closed.rms < start.rms
    with warnings.catch_warnings():
        warnings.simplefilter("error", plc.errors.ShortfallWarning)
        plc.run_closed_loop(TRUTH, FORCE, ROBOT, **RUN)   # no warning for a run that did well
