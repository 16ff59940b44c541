"""Bad input through the two doors that are not Python calls: scenario keys and CLI arguments.

The schema is walked from its own metadata (every key of every section, with its kind and
bounds), so a key added later is swept too. Each bad value must be refused by ``load_scenario``
with the package's ``InputError`` naming the dotted key, before anything is computed. Each bad
command-line argument must end the command with exit status 2 and one line on stderr that names
the option, without a traceback and without writing anything.
"""

from __future__ import annotations

import dataclasses
import os

import pytest

from powerline_control.cli import main
from powerline_control.errors import InputError
from powerline_control.scenario import load_scenario
from powerline_control.scenario.config import Scenario

# Context a key needs to apply at all (its metadata's ``when``): the first value that enables it.
_ENABLING = {("preset", "conductor"): 'preset = "conductor"',
             ("kind", "harmonic"): 'kind = "harmonic"', ("kind", "aeolian"): 'kind = "aeolian"',
             ("kind", "random"): 'kind = "random"', ("enabled", True): "enabled = true"}


def _bad_literals(meta: dict) -> list[str]:
    """TOML literals of values the key must refuse, from its kind and bounds."""
    kind, low, high = meta["kind"], meta.get("low"), meta.get("high")
    if kind == "real":
        bad = ["nan", "inf", "-inf", '"3.0"', "true", "[1.0]"]
        if low is not None:
            bad.append(repr(float(low) - 1.0) if meta.get("low_inclusive") else repr(float(low)))
        if high is not None:
            bad.append(repr(float(high) * 2 + 1.0))
        return bad
    if kind == "int":
        bad = ["2.5", '"3"', "true", "[1]"]
        if low is not None:
            bad.append(str(int(low) - 1))
        if high is not None:
            bad.append(str(int(high) * 2 + 1))
        return bad
    if kind == "bool":
        return ['"yes"', "1", "0.0"]
    if kind == "str":
        return ["3", "true", '"no such choice"'] if meta.get("choices") else ["3", "true", "[1]"]
    if kind == "n_elements":
        return ["1", "2.5", '"many"', "true", str(10**6)]
    if kind == "alpha":
        return ['"sometimes"', "nan", "-1.0", "2.0", "true"]
    if kind == "int_list":
        return ["[-1]", "[1.5]", '"1,2"', "[true]", "3"]
    if kind == "real_list":
        return ["[nan]", '["a"]', "3.0", "[inf]", "[true]"]
    raise AssertionError(f"the sweep does not know the schema kind {kind!r}: add its bad values")


def _schema_cases():
    for section in dataclasses.fields(Scenario):
        for key in dataclasses.fields(section.default_factory):
            meta = key.metadata
            if key.name in {"name", "description"}:  # free text: any string is a label
                continue
            context = ""
            if meta.get("when"):
                on, values = meta["when"]
                context = _ENABLING[(on, values[0])] + "\n"
            for literal in _bad_literals(meta):
                dotted = f"{section.name}.{key.name}"
                yield pytest.param(section.name, context, key.name, literal,
                                   id=f"{dotted}={literal}")


@pytest.mark.parametrize(("section", "context", "key", "literal"), list(_schema_cases()))
def test_every_scenario_key_refuses_bad_values_naming_the_key(section, context, key, literal):
    text = f"[{section}]\n{context}{key} = {literal}\n"
    with pytest.raises(InputError) as caught:
        load_scenario(text=text)
    assert f"{section}.{key}" in str(caught.value)


def test_the_schema_sweep_covers_every_key():
    keys = {f"{s.name}.{k.name}" for s in dataclasses.fields(Scenario)
            for k in dataclasses.fields(s.default_factory)}
    swept = {p.id.split("=")[0] for p in _schema_cases()}
    assert keys - swept == {"scenario.name", "scenario.description"}


# ------------------------------------------------------------------------------- the command

@pytest.fixture
def files(tmp_path):
    binary = tmp_path / "binary.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder\n")
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    return {"folder": str(tmp_path), "binary": str(binary), "missing": str(tmp_path / "none.toml"),
            "file": str(blocker), "fifo": str(fifo)}


# (arguments with {placeholders}, the word the one-line message must contain)
_CLI_CASES = {
    "scenario is a folder": (["run", "{folder}"], "{folder}"),
    "scenario is binary": (["simulate", "{binary}"], "binary.toml"),
    "scenario is missing": (["sensors", "{missing}"], "none.toml"),
    "scenario is a FIFO": (["identify", "{fifo}"], "fifo.toml"),
    "scenario is empty text": (["estimate", ""], "scenario"),
    "out is empty": (["simulate", "--out", ""], "--out"),
    "out is a file": (["plan", "--out", "{file}"], "a_file"),
    "workers negative": (["study", "--vary", "model.n_elements=16,20", "--workers", "-3"],
                         "--workers"),
    "workers zero": (["study", "--vary", "model.n_elements=16,20", "--workers", "0"],
                     "--workers"),
    "workers not an integer": (["study", "--vary", "model.n_elements=16,20", "--workers", "1.5"],
                               "--workers"),
    "vary without values": (["study", "--vary", "model.n_elements"], "model.n_elements"),
    "vary an unknown key": (["study", "--vary", "model.colour=red,blue"], "model.colour"),
    "vary a bad value": (["study", "--vary", "model.n_elements=16,x"], "model.n_elements"),
    "record is missing": (["estimate", "--record", "{missing}"], "none.toml"),
    "record is binary": (["identify", "--record", "{binary}"], "binary.toml"),
    "record is a folder": (["estimate", "--record", "{folder}"], "{folder}"),
    "wind record is missing": (["severity", "--wind-record", "{missing}"], "none.toml"),
    "wind record is binary": (["severity", "--wind-record", "{binary}"], "binary.toml"),
    "report needs --out": (["report"], "--out"),
    "unknown shipped scenario": (["scenario", "no-such-scenario"], "no-such-scenario"),
}


@pytest.mark.parametrize("case", sorted(_CLI_CASES))
def test_every_verb_refuses_bad_arguments_with_status_2_and_one_line(case, files, capsys,
                                                                     tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args, word = _CLI_CASES[case]
    argv = [a.format(**files) for a in args]
    before = sorted(os.listdir(tmp_path))
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if "warning:" not in line]
    assert lines and word.format(**files) in lines[-1], err
    assert sorted(os.listdir(tmp_path)) == before   # nothing written on a refusal


def test_a_nan_cannot_slip_through_a_vary_value(capsys):
    # a study axis goes through the same schema check as a file: nan is refused, not run
    assert main(["study", "--vary", "simulation.duration=1.0,nan"]) == 2
    assert "simulation.duration" in capsys.readouterr().err
