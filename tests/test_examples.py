"""Every script in examples/ runs as a user would run it, and writes what it says it writes.

Each runs in a subprocess from an empty working folder, with an output folder (its first
argument) in tmp_path and ``--fast`` when the script has that mode; it must exit 0, write its
outputs there and nothing in the working folder. The checkout's package is imported
(PYTHONPATH), not an installed copy.
"""

from __future__ import annotations

import csv
import importlib.util
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p for p in (ROOT / "examples").glob("*.py") if not p.name.startswith("_"))
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

# What each script writes into its output folder (the ones not listed must write something).
OUTPUTS = {
    "closed_loop.py": ["closed_loop.png"],
    "dask_study.py": ["dask_study.csv", "dask_study.json", "dask_study.png"],
    "identify_paper_span.py": ["identified_spectrum.png", "paper_span_dmd.npz"],
    "plan_to_antinode.py": ["plan_to_antinode.png"],
    "severity_study.py": ["severity_study.png", "severity_robot_value.png"],
    "paper_kalman.py": ["paper_fig7_20_elements.png", "paper_fig8_100_elements.png",
                        "paper_fig8_100_elements_between_resonances.png",
                        "better_recipe_100_elements.png", "error_along_span.png"],
    "scenario_report.py": ["report.html", "summary.json", "layouts.csv"],
    "sensor_report.py": ["sensor_count.png", "sensor_report.md"],
    "simulate_paper_span.py": ["span_response.png"],
    "wind_speed_study.py": ["wind_speed_study.csv", "wind_speed_study.json"],
}
NEEDS = {"dask_study.py": "distributed"}


def takes_output_folder(source: str) -> bool:
    """The script reads an output folder argument (argparse or sys.argv[1])."""
    return "argparse" in source or "sys.argv[1]" in source


def run_example(path: pathlib.Path, out: pathlib.Path, cwd: pathlib.Path):
    source = path.read_text()
    command = [sys.executable, str(path), str(out)]
    if "--fast" in source:
        command.append("--fast")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    # The timeout only stops a hung script; examples finish in well under a minute.
    return subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600, check=False)


def test_the_outputs_table_names_existing_examples():
    """A renamed example must not leave its outputs unchecked."""
    assert set(OUTPUTS) <= {p.name for p in EXAMPLES}


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_runs_and_writes_its_outputs(path, tmp_path):
    if path.name in NEEDS and importlib.util.find_spec(NEEDS[path.name]) is None:
        pytest.skip(f"{path.name} needs {NEEDS[path.name]} (pip install 'powerline_control[dask]')")
    cwd, out = tmp_path / "cwd", tmp_path / "out"
    cwd.mkdir()
    result = run_example(path, out, cwd)
    assert result.returncode == 0, (
        f"{path.name} exited {result.returncode}\n--- stdout\n{result.stdout[-3000:]}\n"
        f"--- stderr\n{result.stderr[-3000:]}")
    assert "Traceback" not in result.stderr, result.stderr[-3000:]
    assert takes_output_folder(path.read_text()), f"{path.name} takes no output folder"
    assert sorted(p.name for p in cwd.iterdir()) == [], "wrote into the working folder"
    written = sorted(p.name for p in out.iterdir()) if out.exists() else []
    expected = OUTPUTS.get(path.name)
    if expected is None:
        assert written, f"{path.name} wrote nothing into its output folder"
    else:
        assert set(expected) <= set(written), (expected, written)
    for name in written:
        data = (out / name).read_bytes()
        assert len(data) > 100, name
        if name.endswith(".png"):
            assert data.startswith(PNG_MAGIC), name
    check = CONTENT_CHECKS.get(path.name)
    if check is not None:
        check(out)


def _wind_speed_table(out: pathlib.Path) -> None:
    """The study's frequencies are the Strouhal law f = St V / d (St 0.185, Drake d 28.14 mm)."""
    with (out / "wind_speed_study.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [float(r["wind_speed"]) for r in rows] == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    speeds = np.array([float(r["wind_speed"]) for r in rows])
    frequency = np.array([float(r["frequency_hz"]) for r in rows])
    # domain notes: Drake's diameter is 28.14 mm; the CSV holds repr-exact floats.
    np.testing.assert_allclose(frequency, 0.185 * speeds / 0.02814, rtol=1e-12)
    # A robot limited to 0.5 m/s covers its travel no faster than travel / v_max.
    travel = np.array([float(r["travel_m"]) for r in rows])
    move = np.array([float(r["move_time_s"]) for r in rows])
    assert np.all(move >= travel / 0.5 - 1e-9)


def _dask_table(out: pathlib.Path) -> None:
    from powerline_control.studies import StudyResult, point_seed

    study = StudyResult.from_json(out / "dask_study.json")
    assert len(study.table()) == 6  # the --fast grid: 2 noise levels x 3 sensor counts
    # Seeds are those documented in point_seed, recomputed here.
    assert study.seeds == tuple(point_seed(2026, p) for p in study.parameters)
    errors = study.column("relative_rms_error")
    assert np.all((errors > 0) & (errors < 1))


def _scenario_report(out: pathlib.Path) -> None:
    """The report and the summary describe the same run: sensors at the 20-element mesh's
    nodes (x_j = j L / 20), the CSV's errors those of the JSON, every figure embedded."""
    import json

    summary = json.loads((out / "summary.json").read_text())
    nodes = np.asarray(summary["sensor_nodes"])
    np.testing.assert_allclose(summary["sensor_positions_m"], 3.66 * nodes / 20, rtol=1e-12)
    with (out / "layouts.csv").open() as handle:
        rows = {r["layout"]: float(r["error_unmeasured_percent"]) for r in csv.DictReader(handle)}
    assert rows == {name: lay["error_unmeasured_percent"]
                    for name, lay in summary["layouts"].items()}
    html = (out / "report.html").read_text()
    assert html.count("<figure") >= 7 and "data:image/svg+xml;base64," in html


CONTENT_CHECKS = {"wind_speed_study.py": _wind_speed_table, "dask_study.py": _dask_table,
                  "scenario_report.py": _scenario_report}


def test_the_output_folder_detection():
    assert takes_output_folder("import argparse\n")
    assert takes_output_folder("out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path('out')")
    assert not takes_output_folder("main(plot='--plot' in sys.argv)")
