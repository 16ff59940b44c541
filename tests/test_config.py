"""Scenario files and the command line."""

import pytest

from powerline_control import InputError
from powerline_control.cli import main
from powerline_control.config import default_scenario, load_scenario, scenario_to_toml


def test_default_scenario_round_trips_through_toml():
    text = scenario_to_toml(default_scenario())
    assert load_scenario(text=text) == default_scenario()


def test_partial_file_keeps_other_defaults():
    scenario = load_scenario(text="[model]\nn_elements = 20\n[estimation]\nsensors = [3, 10]\n")
    assert scenario.model.n_elements == 20
    assert scenario.estimation.sensors == (3, 10)
    assert scenario.simulation == default_scenario().simulation


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[modle]\nn_elements = 20", "Unknown section"),
        ("[model]\nn_elemnts = 20", "n_elemnts"),
        ("[model]\nn_elements = 20.5", "model.n_elements"),
        ("[model]\nn_elements = 0", "model.n_elements"),
        ("[simulation]\ndt = 'fast'", "simulation.dt"),
        ("[forcing]\nkind = 'gust'", "forcing.kind"),
        ("[identification]\nalpha = 'best'", "identification.alpha"),
        ("[model\n", "not valid TOML"),
    ],
)
def test_bad_scenarios_name_the_key(text, message):
    with pytest.raises(InputError, match=message):
        scenario = load_scenario(text=text)
        scenario.forcing.build()


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(InputError, match="Cannot read"):
        load_scenario(tmp_path / "nope.toml")


def test_cli_runs_a_small_scenario_and_writes_results(tmp_path, capsys):
    path = tmp_path / "small.toml"
    path.write_text("[model]\nn_elements = 20\n[simulation]\nduration = 3.0\n"
                    "[robot]\nclosed_loop = 3.0\n")
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    for stage in ("first natural frequencies", "Identification", "Estimation", "Antinode",
                  "Closed loop"):
        assert stage in printed
    for name in ("report.html", "summary.json", "dmd_model.npz", "closed_loop.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    # The saved scenario is the one that ran, and it reads back unchanged.
    assert load_scenario(tmp_path / "out" / "scenario.toml") == load_scenario(path)


def test_cli_reports_bad_input_without_traceback(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text("[model]\nbc = 'glued'\n")
    assert main(["run", str(path)]) == 2
    assert "bc" in capsys.readouterr().err
