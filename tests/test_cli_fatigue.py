"""Fatigue over a wind record from the command line: ``severity --wind-record FILE``.

The record is the shipped one (examples/data/wind_record_28d.csv), cut to its first two days
(288 ten-minute records) so that each run takes a few seconds.
"""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cli_support import COMMAND, run_cli

import powerline_control as plc
from powerline_control.output.captions import describe_figure, figure_caption
from powerline_control.scenario import load_scenario
from powerline_control.scenario.pipeline import VERB_STAGES, run_scenario, stage_plan
from powerline_control.scenario.stages import tune_robot

RECORD = Path(__file__).resolve().parents[1] / "examples" / "data" / "wind_record_28d.csv"
N_RECORDS = 288  # two days of 10-minute records

SCENARIO = """\
[scenario]
name = "drake-fatigue"
[span]
preset = "conductor"
conductor = "drake"
length = 300.0
rts_fraction = 0.2
[model]
n_elements = 40
[robot]
start = 2.0
body_mass = 6.0
suspended_mass = 1.5
v_max = 0.3
a_max = 0.5
closed_loop = 0
[severity]
enabled = true
wind_speeds = [2.0, 4.0]
"""


@pytest.fixture
def files(tmp_path):
    scenario = tmp_path / "drake.toml"
    scenario.write_text(SCENARIO)
    lines = RECORD.read_text().splitlines(keepends=True)
    record = tmp_path / "wind_2d.csv"
    record.write_text("".join(lines[:N_RECORDS + 1]))  # header + two days
    return scenario, record


def _direct(scenario_path, record_path):
    """The same study by a direct call: the span from its preset, the scenario's tuned robot,
    RobotLimits from the scenario's numbers, the severity study's default clamp inputs."""
    scenario = load_scenario(scenario_path)
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    robot = tune_robot(scenario, plc.LineModel(span, n_elements=40)).robot
    return plc.fatigue_over_record(span, plc.WindRecord.from_csv(record_path), robot,
                                   plc.RobotLimits(v_max=0.3, a_max=0.5),
                                   outer_strand_modulus=68.9e9, x_b=0.089)


def test_severity_with_a_wind_record_matches_the_direct_call(files, tmp_path):
    scenario, record = files
    out = tmp_path / "out"
    result = run_cli("severity", scenario, "--wind-record", record, "--json", "-q",
                     "--out", out)
    assert result.returncode == 0, result.stderr
    numbers = json.loads(result.stdout)
    life = _direct(scenario, record)
    assert set(numbers["fatigue"]) == {"no_damper", "fixed_damper", "robot"}
    for name in life:
        assert numbers["fatigue"][name]["damage_per_year"] == pytest.approx(
            life[name].damage_per_year, rel=1e-12)
        assert numbers["fatigue"][name]["life_years"] == pytest.approx(
            life[name].life_years, rel=1e-12)
    # the robot moving beats the fixed damper, which beats none (this span and record)
    damage = {k: v["damage_per_year"] for k, v in numbers["fatigue"].items()}
    assert damage["robot"] < damage["fixed_damper"] < damage["no_damper"]
    assert numbers["fatigue_record"]["n_records"] == N_RECORDS
    assert "fatigue" in numbers["elapsed_s"]
    html = (out / "report.html").read_text()
    assert "Fatigue over the wind record" in html
    assert json.loads((out / "summary.json").read_text())["fatigue"] == numbers["fatigue"]


def test_severity_text_summary_has_the_life_lines(files):
    scenario, record = files
    result = run_cli("severity", scenario, "--wind-record", record)
    assert result.returncode == 0, result.stderr
    assert "Fatigue over the wind record" in result.stdout
    for label in ("no damper", "fixed damper", "robot"):
        assert any(line.strip().startswith(label) and "damage/year" in line
                   for line in result.stdout.splitlines()), label
    assert "2 days of record (" in result.stdout


def test_the_fatigue_figure_and_its_caption(files):
    scenario, record_path = files
    full = plc.WindRecord.from_csv(record_path)
    result = run_scenario(load_scenario(scenario), stages=VERB_STAGES["severity"],
                          wind_record=full)
    section = next(s for s in result.sections() if s["title"] == "Fatigue over the wind record")
    (spec,) = section["figures"]
    fig = spec["draw"]()
    caption = figure_caption(fig, spec["purpose"], spec["look_for"])
    facts = describe_figure(fig)
    assert facts["n_panels"] == 3 and caption.count("Three panels") == 1
    for panel in facts["panels"]:
        assert f"{panel['ylabel']} against {panel['xlabel']}" in caption
        for entry in panel["legend"]:
            assert entry in caption
    assert facts["panels"][0]["legend"] == ["no damper", "fixed damper", "robot"]
    assert "first 2 days" in caption  # the record is shorter than a week
    # The bars hold the damage: per configuration they sum to its damage per year (every
    # vibrating record lies in a bin of the band).
    life = result.fatigue.life
    top = fig.axes[0]
    n_bins = len(top.patches) // 3
    for k, name in enumerate(life.configurations):
        heights = [p.get_height() for p in top.patches[k * n_bins:(k + 1) * n_bins]]
        assert sum(h for h in heights if h > 1e-20) == pytest.approx(
            life[name].damage_per_year, rel=1e-9)
    # The lower panel is the robot's parking position, record by record, over those days.
    line = fig.axes[2].get_lines()[0]
    np.testing.assert_array_equal(line.get_ydata(), life.robot_position)


def test_no_wind_record_no_fatigue_stage(files):
    scenario, _ = files
    s = load_scenario(scenario)
    assert stage_plan(s, VERB_STAGES["severity"]) == ("model", "severity")
    assert run_scenario(s, stages=VERB_STAGES["severity"]).fatigue is None


@pytest.mark.parametrize("change, words", [
    (lambda rows: [rows[0]] + [rows[1].replace(",1.55,", ",-3,", 1)] + rows[2:],
     ("wind_speed", "row 0")),
    (lambda rows: [rows[0].replace("temperature", "temp")] + rows[1:], ("temperature",)),
])
def test_a_bad_wind_record_exits_2_naming_file_column_and_row(files, tmp_path, change, words):
    scenario, record = files
    rows = record.read_text().splitlines(keepends=True)
    bad = tmp_path / "bad.csv"
    bad.write_text("".join(change(rows)))
    out = tmp_path / "never"
    result = run_cli("severity", scenario, "--wind-record", bad, "--out", out)
    assert result.returncode == 2, result.stderr
    message = result.stderr.strip().splitlines()
    assert len(message) == 1, result.stderr
    assert "bad.csv" in message[0] and all(w in message[0] for w in words), message[0]
    assert not out.exists()  # refused before anything ran or was written


def test_the_scenario_key_reads_the_record_beside_the_scenario(files, tmp_path):
    scenario, record = files
    keyed = scenario.with_name("keyed.toml")
    keyed.write_text(SCENARIO.replace("[severity]\n", f"[severity]\nwind_record = "
                                      f"\"{record.name}\"\n"))
    loaded = load_scenario(keyed)
    assert loaded.severity.wind_record == str(record.resolve())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    result = subprocess.run(COMMAND + ["severity", str(keyed), "--json", "-q"],
                            capture_output=True, text=True, cwd=elsewhere, timeout=300,
                            env={**os.environ, "PYTHONPATH": str(Path(plc.__file__).parents[1])})
    assert result.returncode == 0, result.stderr
    life = _direct(scenario, record)
    assert json.loads(result.stdout)["fatigue"]["robot"]["damage_per_year"] == pytest.approx(
        life["robot"].damage_per_year, rel=1e-12)
    # other verbs do not read it
    assert stage_plan(loaded, VERB_STAGES["simulate"]) == ("model", "records")
    with pytest.raises(plc.InputError, match="severity.wind_record"):
        load_scenario(text='[severity]\nwind_record = ""')
