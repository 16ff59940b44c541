"""A report that tells the truth: each defect of a fresh-venv run of the shipped
scenarios, tested against something independent of the code's earlier output (the file's bytes,
what a figure draws, a hand computation)."""

import json

import numpy as np
import pytest
from cli_support import TINY, run_cli

import powerline_control as plc
from powerline_control.output.records import Record, load_record, save_record


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


# ------------------------------------------------------------------ 1. records round trip

@pytest.fixture
def simulated(tiny, tmp_path):
    out = tmp_path / "sim"
    result = run_cli("simulate", tiny, "--out", out, "-q")
    assert result.returncode == 0, result.stderr
    return out


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_simulate_out_then_estimate_record_round_trips(tiny, simulated, suffix):
    # The file's own bytes: simulate writes every node, the supports x = 0 and x = L included.
    header = (simulated / "record.csv").read_text().splitlines()[1].split(",")
    assert header[1] == "x_0_m" and header[-1] == "x_3.66_m"
    result = run_cli("estimate", tiny, "--record", simulated / f"record{suffix}", "--json")
    assert result.returncode == 0, result.stderr
    numbers = json.loads(result.stdout)
    measured = numbers["measured_record"]
    # The two support channels are dropped (the line does not move there), never sensors:
    # the 11 interior nodes of 12 elements are the sensors.
    assert measured["support_channels_not_used_m"] == pytest.approx([0.0, 3.66])
    assert measured["sensor_nodes"] == list(range(1, 12))
    assert all(0 < x < 3.66 for x in measured["channel_positions_m"])


def test_a_channel_on_a_support_and_one_outside_get_different_messages():
    on = Record([0.0, 1.0], [0.0, 1.0], [[0.0, 0.0], [1.0, 2.0]], "f.csv")
    with pytest.raises(plc.InputError, match=r"x_0_m at 0 m sits on a support"):
        on.check_span(3.66)
    out = Record([0.0, 1.0], [1.0, 4.0], [[0.0, 0.0], [1.0, 2.0]], "f.csv")
    with pytest.raises(plc.InputError, match=r"x_4_m at 4 m lies outside the span"):
        out.check_span(3.66)
    # Dropping the support channels keeps the others with their values (and truth).
    kept = Record([0.0, 1.0], [0.0, 1.0, 3.66], [[0.0, 0.0], [1.0, 2.0], [0.0, 0.0]], "f.csv",
                  truth=[[0.0, 0.0], [1.5, 2.5], [0.0, 0.0]]).without_supports(3.66)
    assert kept.positions.tolist() == [1.0] and kept.values.tolist() == [[1.0, 2.0]]
    assert kept.truth.tolist() == [[1.5, 2.5]] and kept.support_positions == (0.0, 3.66)
    with pytest.raises(plc.InputError, match="every channel"):
        Record([0.0, 1.0], [0.0], [[0.0, 0.0]], "f.csv").without_supports(3.66)


def test_a_channel_outside_the_span_still_exits_2(tiny, tmp_path):
    path = tmp_path / "field.csv"
    path.write_text("time_s,x_1_m,x_5_m\n" + "".join(
        f"{k / 1000!r},{1e-3 * np.sin(k / 10):.6g},0\n" for k in range(2500)))
    result = run_cli("estimate", tiny, "--record", path)
    assert result.returncode == 2
    assert "x_5_m at 5 m lies outside the span" in result.stderr


# ------------------------------------------------------------------ 5. record files

def test_sample_rate_header_is_written_to_10_digits_and_agrees_with_the_time_column(tmp_path):
    t = np.arange(50) * 1e-3    # steps of 1e-3 with round-off: 1/dt = 999.9999999999991
    assert 1.0 / float(np.median(np.diff(t))) != 1000.0
    rec = Record(t, [1.0], np.sin(t)[None, :], "sim")
    save_record(tmp_path / "r", rec)
    first = (tmp_path / "r.csv").read_bytes().split(b"\n")[0]
    assert first == b"# sample_rate_hz = 1000"
    back = load_record(tmp_path / "r.csv", sample_rate=1000.0)  # the reader checks the header
    assert back.dt == pytest.approx(1e-3, rel=1e-12)


def test_random_bytes_npz_is_refused_as_not_a_zip_naming_the_file(tmp_path):
    path = tmp_path / "junk.npz"
    path.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(plc.FileFormatError, match="junk.npz: not an .npz file") as info:
        load_record(path)
    assert "pickle" not in str(info.value)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_an_infinite_sample_names_the_file_and_the_column(tmp_path, suffix):
    base = tmp_path / "rec"
    values = np.zeros((2, 5))
    rec = Record(np.arange(5) * 1e-3, [0.5, 1.25], values, "sim")
    save_record(base, rec)
    if suffix == ".csv":
        lines = (tmp_path / "rec.csv").read_text().splitlines()
        cells = lines[4].split(",")
        cells[2] = "inf"
        lines[4] = ",".join(cells)
        (tmp_path / "rec.csv").write_text("\n".join(lines) + "\n")
    else:
        with np.load(tmp_path / "rec.npz") as data:
            arrays = {k: np.array(data[k]) for k in data.files}
        arrays["values"][1, 2] = np.inf
        np.savez(tmp_path / "rec.npz", **arrays)
    with pytest.raises(plc.InputError) as info:
        load_record(base.with_suffix(suffix))
    message = str(info.value)
    assert f"rec{suffix}" in message and "x_1.25_m" in message and "infinite" in message
    assert "'values' parameter" not in message


# ------------------------------------------------------------------ 8. exit codes

def test_a_plain_value_error_inside_a_stage_is_numerical_trouble(tiny, monkeypatch, capsys):
    from powerline_control import cli
    from powerline_control.errors import InputError
    from powerline_control.scenario import pipeline

    # InputError subclasses ValueError (errors.py): a plain ValueError must still not be bad
    # input; it is what SciPy raises on a singular or non-finite matrix.
    assert issubclass(InputError, ValueError)

    def scipy_like(*args, **kwargs):
        raise ValueError("array must not contain infs or NaNs")

    monkeypatch.setattr(pipeline, "_records", scipy_like)
    assert cli.main(["simulate", str(tiny), "-q"]) == cli.EXIT_NUMERICAL
    err = capsys.readouterr().err
    assert err == "powerline-control: numerical trouble: array must not contain infs or NaNs\n"

    def bad_input(*args, **kwargs):
        raise InputError("The 'x' parameter must be positive. Got -1.")

    monkeypatch.setattr(pipeline, "_records", bad_input)
    assert cli.main(["simulate", str(tiny), "-q"]) == cli.EXIT_USAGE
    assert capsys.readouterr().err.startswith("powerline-control: error: The 'x' parameter")


# ------------------------------------------------------------------ 9. no empty folder left

@pytest.fixture
def outside_record(tmp_path):
    path = tmp_path / "outside.csv"
    path.write_text("time_s,x_1_m,x_5_m\n" + "".join(f"{k / 1000!r},0,0\n" for k in range(50)))
    return path


def test_a_refused_record_leaves_no_new_folder_behind(tiny, tmp_path, outside_record, capsys):
    from powerline_control import cli

    out = tmp_path / "new" / "deeper"
    code = cli.main(["estimate", str(tiny), "--record", str(outside_record), "--out", str(out),
                     "-q"])
    assert code == cli.EXIT_USAGE and "outside the span" in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "new").exists()


def test_a_refused_record_keeps_the_users_own_empty_folder(tiny, tmp_path, outside_record,
                                                          capsys):
    from powerline_control import cli

    out = tmp_path / "mine"
    out.mkdir()
    code = cli.main(["estimate", str(tiny), "--record", str(outside_record), "--out", str(out),
                     "-q"])
    assert code == cli.EXIT_USAGE
    assert out.is_dir() and list(out.iterdir()) == []


# ------------------------------------------------------------------ 2. captions

# A lab span with every stage the report draws (sensor count, closed loop, severity): the
# session's ``lab_result`` (tests/conftest.py), shared with the report summary's tests.
@pytest.fixture(scope="module")
def lab(lab_result):
    return lab_result


@pytest.fixture(scope="module")
def drawn(lab):
    from powerline_control.scenario.summary import draw_sections

    return {f["name"]: f for s in draw_sections(lab.sections()) for f in s["figures"]}


def test_no_report_caption_has_an_empty_description(drawn):
    assert {"layouts", "sensor_count", "error_along_span", "closed_loop_path"} <= set(drawn)
    for name, figure in drawn.items():
        caption = figure["caption"]
        for bad in (",  ", " ,", ", ;", ": ;", "( )", "()", " against .", " against ;",
                    "left, against", "right, against", "top, against", "bottom, against"):
            assert bad not in caption, (name, bad, caption)
        assert "  " not in caption, (name, caption)
    # The layouts figure: its left panel's rows are the compared layouts (its tick labels);
    # its right panel shares those rows.
    layouts = drawn["layouts"]["caption"]
    names = ", ".join(drawn["layouts"]["figure"].axes[0].get_yticklabels()[i].get_text()
                      for i in range(len(drawn["layouts"]["figure"].axes[0].get_yticks())))
    assert f"left, error at unmeasured nodes (%) for each of {names}" in layouts
    assert "right, sensor position x (m) for the same rows as the left panel" in layouts


# ------------------------------------------------------------------ 4. figures

def test_sensor_marks_take_a_colour_no_curve_of_the_error_figure_uses():
    from matplotlib.colors import to_rgba

    from powerline_control.output.plotting import plot_error_along_span

    x = np.linspace(0.0, 3.0, 31)
    errors = {f"layout {i}": (i + 1) * 0.01 * np.ones(31) for i in range(6)}  # C0..C5: C2 green
    fig = plot_error_along_span(x, errors, [1.0, 2.0])
    lines = fig.axes[0].get_lines()
    curves = [to_rgba(ln.get_color()) for ln in lines if ln.get_label() in errors]
    marks = [to_rgba(ln.get_color()) for ln in lines if ln.get_label() not in errors]
    assert len(curves) == 6 and len(marks) == 2
    assert to_rgba("tab:green") in curves                  # the clash the report had
    assert not set(marks) & set(curves)


def _fake_closed_loop(t, field):
    from types import SimpleNamespace

    return SimpleNamespace(t=t, x=np.arange(field.shape[0], dtype=float), displacement=field,
                           baseline_displacement=field, robot_position=np.ones(t.size),
                           target=np.ones(t.size), retarget_times=(0.5,),
                           calibration_time=0.2)


def test_closed_loop_path_legend_explains_the_calibration_line_and_shows_the_target():
    from matplotlib.colors import to_rgb

    from powerline_control.output.plotting import plot_closed_loop, plot_closed_loop_path

    t = np.linspace(0.0, 1.0, 201)
    fake = _fake_closed_loop(t, np.ones((4, 201)))
    fig = plot_closed_loop_path(fake)
    legend = fig.axes[0].get_legend()
    texts = [text.get_text() for text in legend.get_texts()]
    assert "end of calibration" in texts and "target" in texts
    face = np.array(to_rgb(legend.get_frame().get_facecolor()))
    handles = dict(zip(texts, legend.legend_handles, strict=True))
    for label in texts:   # every entry's line differs from the legend's face (white: "w:" hid)
        colour = np.array(to_rgb(handles[label].get_color()))
        assert np.abs(colour - face).max() > 0.3, (label, colour, face)
    top = plot_closed_loop(fake).axes[0]
    assert "end of calibration" in [tx.get_text() for tx in top.get_legend().get_texts()]


def test_windowed_rms_of_a_constant_sine_is_a_over_root_2_to_the_ends():
    from powerline_control.output.plotting import plot_closed_loop

    # 40 Hz at 1 ms: a full 0.1 s window (100 samples) holds 4 whole periods, so its mean of
    # sin^2 is 1/2 to round-off. A window cut short at an end still holds >= 2 periods: its mean
    # of sin^2 is within 1/(4 pi 2) = 0.04 of 1/2, so the RMS within 4 % of A / sqrt(2). The old
    # division by the full window gave sqrt(51/100) of it at the ends: 29 % low.
    dt, amplitude = 1e-3, 2e-3
    t = np.arange(0.0, 1.0, dt)
    field = amplitude * np.tile(np.sin(2 * np.pi * 40.0 * t), (3, 1))
    bottom = plot_closed_loop(_fake_closed_loop(t, field)).axes[1]
    expected = 1e3 * amplitude / np.sqrt(2)
    for line in bottom.get_lines():
        rms = np.asarray(line.get_ydata())
        assert rms[60:-60] == pytest.approx(expected, rel=1e-9), line.get_label()
        assert rms == pytest.approx(expected, rel=0.045), line.get_label()
        assert rms[0] > 0.95 * expected and rms[-1] > 0.95 * expected


# ------------------------------------------------------------------ 7. alpha at the sweep's cap

def test_the_identification_text_says_when_alpha_sits_at_the_cap_of_its_sweep(lab):
    import warnings

    from powerline_control.scenario.summary import _recipe_text, alpha_at_sweep_cap

    # A record white in time (one smooth shape times white noise): no linear one-step map
    # predicts it, so the held-out error falls with every alpha up to the recipe's cap.
    rng = np.random.default_rng(0)
    x = np.linspace(0.0, 1.0, 12)[1:-1]
    y = (np.sin(np.pi * x)[:, None] * rng.standard_normal(2000)[None, :]
         + 0.01 * rng.standard_normal((10, 2000)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the recipe's warnings about such a record
        design = plc.design_estimator(y, n_sensors=2, dt=1e-3)
    sweep = design.alpha_sweep
    errors = np.asarray(sweep.held_out_error)
    # Independent of the summary: the best held-out error is the sweep's last alpha.
    assert int(np.argmin(errors)) == errors.size - 1
    assert design.model.alpha_relative == sweep.alphas[-1]
    text = _recipe_text(design)
    assert alpha_at_sweep_cap(design)
    assert f"alpha {sweep.alphas[-1]:.3g} relative" in text
    assert "sits at the cap of the sweep" in text and "may still have been falling" in text
    # The lab scenario's alpha is inside its sweep: the plain wording, and the JSON says so.
    lab_design = lab.identification.design
    lab_errors = np.asarray(lab_design.alpha_sweep.held_out_error)
    assert int(np.argmin(lab_errors)) < lab_errors.size - 1
    assert "(chosen on held-out data)" in _recipe_text(lab_design)
    assert lab.to_dict()["alpha_at_sweep_cap"] is False


# ------------------------------------------------------------------ 6. a study not run says so

def test_a_skipped_sensor_count_study_says_so_in_progress_report_and_json(monkeypatch, tiny):
    from powerline_control.scenario import load_scenario, sensor_count
    from powerline_control.scenario.pipeline import run_scenario

    # The tiny span's 13 nodes stand for drake-300m's 840: the limit set below them.
    monkeypatch.setattr(sensor_count, "SENSOR_COUNT_MAX_NODES", 10)
    said = []
    result = run_scenario(load_scenario(tiny), stages=("model", "records", "identification",
                                                       "sensors"), progress=said.append)
    assert result.ok and result.sensor_count is None
    reason = "the model has 13 nodes, above the 10 the study runs on"
    line = [s for s in said if s.startswith("how many sensors")]
    assert line and line[0].startswith(f"how many sensors: skipped ({reason}")
    assert "predicted error of 1 to" not in line[0]        # not printed as if it ran
    rows = {row[0]: row[1] for s in result.sections() for row in s["rows"]}
    assert rows["how many sensors"].startswith(f"not studied: {reason}")
    entry = result.to_dict()["sensor_count"]
    assert entry["studied"] is False and entry["reason"].startswith(reason)
    assert not [f for s in result.sections() for f in s.get("figures", ())
                if f["name"] == "sensor_count"]


def test_drake_300m_is_over_the_sensor_count_limit():
    from powerline_control.scenario import load_scenario
    from powerline_control.scenario.pipeline import SENSOR_COUNT_MAX_NODES, run_scenario

    model = run_scenario(load_scenario("drake-300m"), stages=("model",)).model
    assert model.node_positions.size > SENSOR_COUNT_MAX_NODES   # 840 > 201


# ------------------------------------------------------------------ 3. how many sensors, in %

def test_sensor_count_figure_is_in_percent_and_its_chosen_point_is_the_tables(lab, drawn):
    figure = drawn["sensor_count"]
    ax = figure["figure"].axes[0]
    assert "%" in ax.get_ylabel() and "mm" not in ax.get_ylabel()
    assert "% of RMS displacement over the span" in " ".join(ax.get_ylabel().split())
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    measured = lines["measured on held-out data"]
    predicted = lines["predicted by the filter (its covariance)"]
    k = int(lab.identification.design.sensors.size)
    at = list(measured.get_xdata()).index(k)
    chosen = lab.layouts["chosen"]
    # The caption says the measured curve at the recipe's count is the table's error at
    # unmeasured nodes: the figure draws exactly that number.
    assert measured.get_ydata()[at] == pytest.approx(chosen.error_unmeasured_percent, rel=1e-12)
    assert f"the table's error at unmeasured nodes, {chosen.error_unmeasured_percent:.3g} %" \
        in figure["caption"]
    # ... and the predicted curve is the chosen filter's own variance at the unmeasured nodes,
    # recomputed here from the table's estimate (its field variances) over the same samples.
    est, nodes = chosen.estimate, list(chosen.nodes)
    unmeasured = np.setdiff1d(np.arange(est.field.shape[0]), nodes)
    discard = chosen.accuracy.n_samples
    discard = est.field.shape[1] - discard                  # the transient the table leaves out
    variance = np.asarray(est.field_variances)[unmeasured, discard:]
    expected = 100 * np.sqrt(np.mean(variance)) / chosen.accuracy.rms_truth
    assert predicted.get_ydata()[at] == pytest.approx(expected, rel=1e-12)
    assert "predicts it from its own covariance" in figure["caption"]
    assert "measured against the simulated truth" in figure["caption"]
    numbers = lab.to_dict()["sensor_count"]
    assert numbers["error_unmeasured_percent"][at] == pytest.approx(
        chosen.error_unmeasured_percent, rel=1e-12)


def test_a_random_bytes_npz_record_is_bad_input_for_the_command(tiny, tmp_path, capsys):
    from powerline_control import cli

    path = tmp_path / "junk.npz"
    path.write_bytes(np.random.default_rng(1).bytes(1000))
    assert cli.main(["estimate", str(tiny), "--record", str(path), "-q"]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert err.startswith("powerline-control: error: ") and "junk.npz: not an .npz file" in err


def test_the_recipe_row_says_when_the_scenarios_own_alpha_was_not_the_one_used(tiny):
    import warnings

    from powerline_control.scenario import load_scenario
    from powerline_control.scenario.pipeline import run_scenario

    scenario = load_scenario(text=TINY + "[identification]\nalpha = 1e-8\n", source="given")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the recipe's warnings about its sweep
        result = run_scenario(scenario, stages=("model", "records", "identification"))
    used = float(result.identification.design.model.alpha_relative)
    row = [row[1] for s in result.sections() for row in s["rows"] if row[0] == "recipe"][0]
    if used == pytest.approx(1e-8):
        assert "the scenario's alpha" not in row
    else:   # the recipe widened the sweep from the given alpha (measured: to 1e-4)
        assert "the scenario's alpha = 1e-08 was only where the sweep started" in row
        assert f"lower at {used:.3g}, which the recipe used" in row


def test_every_row_explanation_is_words_not_a_code(lab):
    """An explanation is a phrase a reader understands (the R row once said just "given", the
    recipe's internal code for where the noise level came from)."""
    rows = {}
    for section in lab.sections():
        for label, _, *explanation in section["rows"]:   # (label, value[, explanation])
            text = str(explanation[0] if explanation else "").strip()
            assert not text or " " in text, (section["title"], label, text)
            rows[label] = text
    assert rows["sensor noise std (the filter's R)"] == lab.identification.design.noise_origin
    assert "training record's sensor noise" in rows["sensor noise std (the filter's R)"]


def test_consistency_phases_count_every_tested_window_once_against_the_windows_times(lab):
    """The consistency row's phases (parked, moving, settled) partition the windows the
    filter's test counted, each judged by its own samples' times (recounted here by hand)."""
    from powerline_control.scenario.summary import consistency_by_phase

    res = lab.closed_loop.result
    test = res.estimator_consistency
    t = np.asarray(res.t)
    by_hand = {"calibration": [0, 0, 0], "moving": [0, 0, 0], "settled": [0, 0, 0]}
    for k in range(1, test.window_start.size):   # window 0 holds the prior's transient
        first, last = t[test.window_start[k]], t[test.window_start[k] + test.window - 1]
        phase = ("calibration" if last <= res.calibration_time else
                 "settled" if first >= res.settled_window[0] else "moving")
        rejected = k in set(test.rejected.tolist())
        high = test.window_nis[k] > test.window_bounds[k, 1]
        by_hand[phase][0] += int(rejected and high)
        by_hand[phase][1] += int(rejected and not high)
        by_hand[phase][2] += 1
    phases = consistency_by_phase(res)
    assert phases == {name: tuple(v) for name, v in by_hand.items()}
    assert sum(n for *_, n in phases.values()) == test.n_tested
    assert sum(a + b for a, b, _ in phases.values()) == test.rejected.size
    row = next(value for s in lab.sections() for label, value, *_ in s["rows"]
               if label == "estimator consistency")
    for name, (above, below, n) in phases.items():
        assert (f"{name} {above} of {n}" in row.split("; below")[0]) == (n > 0), row
        assert (f"{name} {below} of {n}" in row.split("; below")[1]) == (n > 0), row
    assert lab.to_dict()["estimator_windows_rejected"]["moving"] == {
        "above": phases["moving"][0], "below": phases["moving"][1],
        "rejected": phases["moving"][0] + phases["moving"][1], "tested": phases["moving"][2]}


def test_consistency_row_names_the_robot_as_the_cause_only_when_the_model_fits_parked():
    """Hand-built windows of 1 s on a 10 s run, calibration 3 s (windows 1-2 parked; window 0
    untested), the robot settled from 7 s. The row blames the robot's move only when the robot
    moved, windows after the move lie above their bound, and no more parked windows lie above
    than chance allows (allowed_rejections(2) = 1)."""
    from types import SimpleNamespace

    from powerline_control.scenario.summary import _consistency_text

    def row(above_windows, moved):
        above = np.isin(np.arange(10), above_windows)
        test = SimpleNamespace(window=100, window_start=np.arange(10) * 100,
                               tested=np.arange(10) > 0, rejected=np.flatnonzero(above),
                               above=above, consistent=not above.any())
        position = np.where(np.arange(1000) < 400, 1.2, 0.6) if moved else np.full(1000, 1.2)
        run = SimpleNamespace(estimator_consistency=test, t=np.arange(1000) * 0.01,
                              calibration_time=3.0, settled_window=(7.0, 9.99),
                              robot_position=position)
        return _consistency_text(run, noise_fraction=0.01)

    blamed = "the robot damps the line differently elsewhere"
    assert blamed in row([8, 9], moved=True)
    assert "settled 2 of 3" in row([8, 9], moved=True)
    assert blamed in row([2, 8, 9], moved=True)          # one of two parked: chance
    assert blamed not in row([1, 2, 8, 9], moved=True)   # both parked above: the model
    assert blamed not in row([8, 9], moved=False)        # the robot never moved
    assert blamed not in row([], moved=True)


def test_consistency_row_says_when_the_estimator_was_rebuilt_and_the_sensors_are_noiseless():
    """The row names each rebuild of the robot_input estimator with its time and reason, and a
    noiseless record's assumed noise floor (the test then weighs the model's error)."""
    from types import SimpleNamespace

    from powerline_control.scenario.summary import _consistency_text

    test = SimpleNamespace(window=100, window_start=np.arange(10) * 100,
                           tested=np.arange(10) > 0, rejected=np.zeros(0, dtype=int),
                           above=np.zeros(10, dtype=bool), consistent=True)
    run = SimpleNamespace(estimator_consistency=test, t=np.arange(1000) * 0.01,
                          calibration_time=3.0, settled_window=(7.0, 9.99),
                          robot_position=np.full(1000, 1.2), estimator="robot_input",
                          estimator_updates=((3.5, "line"), (6.25, "tone")))
    text = _consistency_text(run, noise_fraction=0.0)
    assert "rebuilt at 3.5 s (on the calibrated line)" in text
    assert "rebuilt at 6.25 s (at the load's new tone)" in text
    assert "noiseless" in text and "0.0001 of its record's RMS" in text
    assert "noiseless" not in _consistency_text(run, noise_fraction=0.01)
