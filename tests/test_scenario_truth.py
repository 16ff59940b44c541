"""A scenario's [truth] (the line simulated) apart from its [span] (what the engineer
knows), and the ``calibrate`` verb that reads the true span back from a record.

The truth's frequencies are checked against the closed form of the pinned taut beam
(``Span.pinned_frequencies``) of a span built here from the numbers, not from the package's
truth code; the change of state against ``tension_at_temperature``'s own documented values.
"""

import json
import tomllib
import warnings

import numpy as np
import pytest
from cli_support import run_cli

import powerline_control as plc
from powerline_control.errors import InputError
from powerline_control.scenario import load_scenario, scenario_to_toml
from powerline_control.scenario.pipeline import run_scenario
from powerline_control.scenario.truth import on_nodes, true_model, true_span

LAB = plc.Span.paper_lab()


# ------------------------------------------------------------------------ the schema

@pytest.mark.parametrize("text", [
    "[truth]\ntension_factor = 0.97",
    "[truth]\ntension_factor = 1.05\nei_factor = 1.3\nmass_factor = 0.98\ndamping_ratio = 0.002",
    "[span]\npreset = 'conductor'\n[truth]\ntemperature = 35.0",
    "[span]\npreset = 'conductor'\n[truth]\ntemperature = -10.0\nstringing_temperature = 5.0\n"
    "ei_factor = 0.5",
    "",   # no [truth]: the truth is the nominal
])
def test_the_truth_table_round_trips_through_the_template(text):
    scenario = load_scenario(text=text)
    written = scenario_to_toml(scenario)
    assert load_scenario(text=written) == scenario
    assert load_scenario(text=scenario_to_toml(scenario, comments=False)) == scenario
    # the template shows only the keys that apply: unset alternatives are commented out
    active = tomllib.loads(written).get("truth", {})
    assert ("temperature" in active) == (scenario.truth.temperature is not None)
    assert ("tension_factor" in active) == (scenario.truth.tension_factor is not None)
    assert ("stringing_temperature" in active) == (scenario.truth.temperature is not None)


def test_the_shipped_scenarios_simulate_a_line_off_their_nominal():
    lab, drake = load_scenario("paper-lab-20"), load_scenario("drake-300m")
    assert lab.truth.tension_factor == 0.97 and load_scenario("paper-lab-100").truth == lab.truth
    assert (drake.truth.temperature, drake.truth.stringing_temperature) == (35.0, 15.0)
    # tension_at_temperature's doctest: Drake 300 m at 20 % RTS, 28.02 kN at 15 degC, 24.37 kN
    # at 40 degC; 35 degC lies between, several per cent below the nominal
    tension = true_span(drake).tension
    assert 24368 < tension < 28020 and tension == pytest.approx(
        plc.tension_at_temperature(drake.span.build(), 35.0, 15.0), rel=1e-12)


@pytest.mark.parametrize(("text", "named"), [
    ("[span]\npreset = 'conductor'\n[truth]\ntemperature = 30.0\ntension_factor = 0.9",
     ["truth.temperature conflicts with truth.tension_factor", "not both"]),
    ("[truth]\ntemperature = 30.0",   # the lab conductor (Table 1) has no change of state
     ["truth.temperature = 30.0 is not allowed", "truth.tension_factor instead", "area"]),
    ("[truth]\nstringing_temperature = 20.0",
     ["truth.stringing_temperature applies only when truth.temperature is set"]),
    ("[truth]\ntension_factor = 2.0", ["truth.tension_factor = 2.0", ">= 0.5 and <= 1.5"]),
    ("[truth]\nei_factor = 0.1", ["truth.ei_factor = 0.1", ">= 0.2 and <= 5"]),
    ("[truth]\nmass_factor = 1.3", ["truth.mass_factor = 1.3", ">= 0.8 and <= 1.2"]),
    ("[truth]\ndamping_ratio = 1.0", ["truth.damping_ratio = 1.0", ">= 0 and < 1"]),
    ("[span]\npreset = 'conductor'\n[truth]\ntemperature = 120.0",
     ["truth.temperature = 120.0", "<= 100 degC"]),
    ("[truth]\ntension = 400.0", ["unknown key truth.tension", "tension_factor"]),
    ("[span]\npreset = 'conductor'\nrts_fraction = 0.6\n[truth]\ntension_factor = 1.5\n"
     "[robot]\nstart = 150.0", None),   # 0.9 RTS: allowed
])
def test_bad_truth_keys_are_refused_by_name(text, named):
    if named is None:
        assert load_scenario(text=text).truth.tension_factor == 1.5
        return
    with pytest.raises(InputError) as caught:
        load_scenario(text=text)
    for words in named:
        assert words in str(caught.value)


def test_every_problem_of_the_truth_table_is_listed_at_once():
    with pytest.raises(InputError, match=r"3 problems: \(1\) truth\.tension_factor = 0\.1 .*"
                                         r"\(2\) truth\.ei_factor = \"big\" .*"
                                         r"\(3\) truth\.mass_factor = 2\.0"):
        load_scenario(text="[truth]\ntension_factor = 0.1\nei_factor = 'big'\nmass_factor = 2.0")


def test_a_true_tension_at_the_rated_strength_is_refused():
    # 0.6 RTS x 1.5 = 0.9 RTS is allowed (above); a tension given in N near the rated
    # strength with a factor above it would break the conductor
    text = ("[span]\npreset = 'conductor'\ntension = 130000.0\n[truth]\ntension_factor = 1.2\n"
            "[robot]\nstart = 150.0")
    with pytest.raises(InputError, match=r"truth.tension_factor = 1.2 .* would break"):
        load_scenario(text=text)


def test_the_scenario_verb_prints_the_truth_table_commented():
    result = run_cli("scenario", "drake-300m")
    assert result.returncode == 0, result.stderr
    text = result.stdout
    block = text[text.index("[truth]"):text.index("[forcing]")]
    assert "# The line as it really is" in block and "Unit: degC" in block
    assert "\ntemperature = 35.0" in block and "\nstringing_temperature = 15.0" in block
    assert "# tension_factor = " in block     # the alternative, commented out
    assert load_scenario(text=text) == load_scenario("drake-300m")


# ------------------------------------------------------------------------ the line simulated

# A harmonic load between modes 3 and 4 (25 and 38 Hz): started from rest, the line rings at
# its natural frequencies through the whole record (damping 0.2 %), deterministic lines whose
# peaks a windowed FFT locates to a small fraction of its resolution.
FORCED = """\
[model]
n_elements = 20
damping_ratio = 0.002
[forcing]
kind = "harmonic"
frequency = 31.0
position = 0.5
[simulation]
duration = 10.0
[truth]
tension_factor = 1.05
"""


def _peak_near(signal, dt, frequency, half_width):
    """The spectral peak of ``signal`` within half_width of ``frequency`` (Hz): a Hann-windowed
    FFT, zero-padded 16x, its largest bin in the window."""
    n = signal.size
    spectrum = np.abs(np.fft.rfft((signal - signal.mean()) * np.hanning(n), 16 * n))
    f = np.fft.rfftfreq(16 * n, dt)
    window = np.abs(f - frequency) <= half_width
    return float(f[window][np.argmax(spectrum[window])])


def test_the_records_are_the_true_lines_and_the_nominal_is_reported_unchanged():
    result = run_scenario(load_scenario(text=FORCED), stages=("model", "records"))
    # the independent truth: the closed form of a span built here with 5 % more tension
    truth = plc.Span(LAB.length, 1.05 * LAB.tension, LAB.conductor)
    true_f = truth.pinned_frequencies(3)
    nominal_f = LAB.pinned_frequencies(3)
    # the FE model's low modes on 20 elements agree with the closed form to 1e-3 (mesh error)
    np.testing.assert_allclose(result.true_model.natural_frequencies(3), true_f, rtol=1e-3)
    np.testing.assert_allclose(result.model.natural_frequencies(3), nominal_f, rtol=1e-3)
    # the record rings at the true line's modes: each peak within 10 % of the gap between the
    # true and the nominal frequency (0.15-0.36 Hz; the 10 s record resolves 0.1 Hz, and the
    # peak of a steady line in its Hann-windowed, zero-padded spectrum a few thousandths)
    snap = result.records.test
    node = int(np.argmin(np.abs(snap.x - 0.31 * LAB.length)))   # off the low modes' nodes
    for f_true, f_nominal in zip(true_f, nominal_f, strict=True):
        gap = f_true - f_nominal
        peak = _peak_near(snap.true_displacement[node], snap.dt, f_true, 1.5 * gap)
        assert abs(peak - f_true) < 0.1 * gap, (peak, f_true, f_nominal)
    # what the engineer knows is reported as it was given
    numbers = result.to_dict()
    assert numbers["tension_n"] == numbers["nominal_tension_n"] == LAB.tension
    assert numbers["true_tension_n"] == pytest.approx(truth.tension, rel=1e-12)
    np.testing.assert_allclose(numbers["frequencies_hz"][:3], nominal_f, rtol=1e-3)
    np.testing.assert_allclose(numbers["true_frequencies_hz"][:3], true_f, rtol=1e-3)
    rows = {row[0]: row[1] for row in result.sections()[0]["rows"]}
    assert "tension 395 N" in rows["span (nominal)"]
    assert rows["line simulated (truth)"].startswith("tension 414.75 N (+5.0 % from the nominal")


def test_without_a_truth_table_the_line_simulated_is_the_nominal_model_itself():
    result = run_scenario(load_scenario(text="[model]\nn_elements = 12"), stages=("model",))
    assert result.true_model is result.model and result.true_span is result.span
    assert result.to_dict()["truth_differs"] is False


def test_the_true_model_shares_a_uniform_mesh_and_a_graded_one_is_read_at_the_nominal_nodes():
    text = "[model]\nn_elements = 'auto'\nbc = 'clamped'\n[truth]\ntension_factor = 0.9\n" \
           "ei_factor = 1.5\ndamping_ratio = 0.01"
    scenario = load_scenario(text=text)
    nominal = scenario.model.build(scenario.span.build())
    truth = true_model(scenario, nominal)
    assert truth.span.tension == pytest.approx(0.9 * LAB.tension)
    assert truth.span.conductor.ei == pytest.approx(1.5 * LAB.conductor.ei)
    assert truth.damping.ratio == 0.01 and truth.bc == nominal.bc
    # a graded mesh follows its own span's boundary layer: the nodes differ, and a field on
    # the true mesh is read at the nominal's nodes by linear interpolation (exact for a line)
    assert truth.n_nodes != nominal.n_nodes
    slope = np.vstack([truth.node_positions, 2 * truth.node_positions]).T
    np.testing.assert_allclose(on_nodes(slope, truth.node_positions, nominal.node_positions),
                               np.vstack([nominal.node_positions,
                                          2 * nominal.node_positions]).T, atol=1e-12)
    uniform = load_scenario(text="[model]\nn_elements = 30\n[truth]\nmass_factor = 1.1")
    nominal = uniform.model.build(uniform.span.build())
    assert np.array_equal(true_model(uniform, nominal).node_positions, nominal.node_positions)


# ------------------------------------------------------------------------ the closed loop

def test_the_closed_loop_is_told_the_nominal_and_the_summary_shows_its_calibration():
    scenario = load_scenario(text="[model]\nn_elements = 20\n[simulation]\nduration = 3.0\n"
                                  "[truth]\ntension_factor = 0.97\n[estimation]\nn_sensors = 3\n"
                                  "[robot]\nclosed_loop = 6.0")
    with warnings.catch_warnings():
        # the estimator trains on the parked calibration record of a harmonic load: narrowband,
        # as the closed loop's own tests know (it does not target from that estimate)
        warnings.simplefilter("ignore", plc.ExcitationWarning)
        result = run_scenario(scenario, stages=("model", "closed_loop"))
    run = result.closed_loop.result
    assert run.span.tension == pytest.approx(0.97 * LAB.tension)   # the plant: the truth
    assert run.nominal.tension == LAB.tension                       # the controller: told 395 N
    numbers = result.to_dict()
    assert numbers["nominal_tension_n"] == LAB.tension
    assert numbers["true_tension_n"] == pytest.approx(0.97 * LAB.tension)
    assert numbers["n_calibrations"] == len(run.calibrations) >= 1
    time, last = run.calibrations[-1]
    assert numbers["calibrated_tension_n"] == last.tension
    assert numbers["calibrated_tension_std_n"] == last.tension_std > 0
    assert numbers["calibration_time_s"] == time and numbers["units"]["_n"] == "newtons"
    rows = {row[0]: row[1] for s in result.sections() for row in s["rows"]}
    row = rows["tension: told / true / calibrated"]
    assert row.startswith("told 395 N, true 383.15 N; calibrated ")
    assert f"{last.tension:.5g} +- {last.tension_std:.2g} N" in row


# ------------------------------------------------------------------------ the calibrate verb

def test_calibrate_without_a_record_finds_the_shipped_lab_truth_within_two_sigma():
    result = run_cli("calibrate", "paper-lab-20", "--json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["record_simulated"] is True and data["nominal_tension_n"] == LAB.tension
    truth = 0.97 * LAB.tension     # the shipped scenario's [truth]: tension 3 % low
    assert data["true_tension_n"] == pytest.approx(truth, rel=1e-12)
    assert abs(data["calibrated_tension_n"] - truth) < 2 * data["calibrated_tension_std_n"]
    assert "no record given" in result.stderr      # it says what it calibrates from
    text = run_cli("calibrate", "paper-lab-20")
    assert text.returncode == 0, text.stderr
    assert text.stdout.startswith("Calibrated span (3.66 m, pinned) from a 6 s record")
    assert "simulated, since no --record was given" in text.stdout
    assert "True line (simulated): tension 383.15 N" in text.stdout


def _record_of(span, positions, path):
    model = plc.LineModel(span, 20, damping=plc.ModalDamping(0.005))
    snap = plc.simulate(model, plc.RandomForce(0.5, 0.31 * span.length, 150.0, seed=1),
                        duration=6.0, dt=1e-3, noise_fraction=0.01, seed=2)
    nodes = [int(np.argmin(np.abs(snap.x - p))) for p in positions]
    plc.save_record(path, plc.Record(snap.t, snap.x[nodes], snap.displacement[nodes], "other"))
    return path.with_suffix(".npz")


def test_calibrate_from_a_record_of_the_scenarios_own_line(tmp_path):
    truth = plc.Span(LAB.length, 1.04 * LAB.tension, LAB.conductor)
    record = _record_of(truth, [0.7, 1.6, 2.9], tmp_path / "lab")
    result = run_cli("calibrate", "paper-lab-20", "--record", record, "--json")
    data = json.loads(result.stdout)
    assert result.returncode == 0 and data["record_simulated"] is False
    assert data["true_tension_n"] is None                       # a record's truth is unknown
    assert abs(data["calibrated_tension_n"] - truth.tension) < 3 * data["calibrated_tension_std_n"]
    quiet = run_cli("calibrate", "paper-lab-20", "--record", record, "-q")
    assert quiet.returncode == 0 and quiet.stdout.startswith("Done. tension = ")


@pytest.mark.parametrize(("length", "positions", "code", "words"), [
    # a 6 m span's channels beyond the 3.66 m lab span: refused by name (bad input)
    (6.0, [1.0, 2.5, 4.5], 2, "lies outside the span (0 < x < 3.66 m)"),
    # a 2.5 m span measured inside the lab span's length: no tension of the lab conductor
    # explains its lines (numerical trouble: the record was read, the line is another)
    (2.5, [0.6, 1.3, 2.1], 1, "tension"),
])
def test_calibrate_with_a_record_of_another_span_fails_clearly(tmp_path, length, positions,
                                                               code, words):
    record = _record_of(plc.Span(length, LAB.tension, LAB.conductor), positions,
                        tmp_path / "other")
    result = run_cli("calibrate", "paper-lab-20", "--record", record)
    assert result.returncode == code, (result.returncode, result.stderr)
    assert "Traceback" not in result.stderr and words in result.stderr
    # one error line (after the progress lines), nothing on stdout
    lines = result.stderr.strip().splitlines()
    assert lines[-1].startswith("powerline-control: ") and words in lines[-1]
    assert sum(line.startswith("powerline-control: ") for line in lines) == 1
    assert result.stdout == ""
