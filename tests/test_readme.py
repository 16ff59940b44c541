"""The README's first steps, as printed: its Python snippet runs, its shell commands are the ones
CI runs (.ci/run) and name an entry point that exists.

The snippet's first line runs the paper-lab-20 scenario (about 25 s on 2 cores). The default
test runs every other line as printed, with that one scenario run answered by the session's small
lab result (tests/conftest.py); the ``slow`` test runs the whole snippet as a user would.
"""

from __future__ import annotations

import pathlib
import re
import shlex
import tomllib

import pytest

import powerline_control as plc

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
CI = (ROOT / ".ci" / "run").read_text()


def fenced(text: str, language: str) -> list[str]:
    """The bodies of the ```language blocks of a Markdown text, in order."""
    return re.findall(rf"^```{language}\n(.*?)^```$", text, flags=re.MULTILINE | re.DOTALL)


def section(text: str, title: str) -> str:
    """The Markdown of the '## title' section, up to the next '## ' heading."""
    return re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", text,
                     flags=re.MULTILINE | re.DOTALL).group(1)


SNIPPETS = fenced(section(README, "Using it from Python"), "python")
QUICK_START = [block.strip() for block in fenced(section(README, "Quick start"), "bash")]


def test_the_readers_find_the_blocks():
    page = "## A\n```python\nx = 1\n```\n## B\n```bash\nls\n```\n"
    assert fenced(section(page, "A"), "python") == ["x = 1\n"]
    assert fenced(section(page, "A"), "bash") == [] and fenced(page, "bash") == ["ls\n"]
    assert len(SNIPPETS) == 1 and len(QUICK_START) == 2


def _run(code: str, folder: pathlib.Path, monkeypatch) -> dict:
    monkeypatch.chdir(folder)
    namespace = {"__name__": "__readme__"}
    exec(compile(code, "README.md (Using it from Python)", "exec"), namespace)  # noqa: S102
    return namespace


def test_the_python_snippet_runs_as_printed(tmp_path, monkeypatch, lab_result):
    asked = []

    def run_scenario(scenario, *args, **kwargs):
        asked.append(scenario)
        return lab_result

    monkeypatch.setattr(plc, "run_scenario", run_scenario)
    namespace = _run(SNIPPETS[0], tmp_path, monkeypatch)
    # The scenario it names was loaded for real; the record it reads is the one it wrote.
    assert [s.name for s in asked] == ["paper-lab-20"]
    assert (tmp_path / "report.html").is_file() and (tmp_path / "field.csv").is_file()
    rec = namespace["rec"]
    assert rec.positions.tolist() == pytest.approx([0.915, 1.83, 2.745])
    assert rec.values.shape == (3, 10001) and rec.dt == pytest.approx(1e-3)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::powerline_control.errors.ExcitationWarning")
def test_the_python_snippet_runs_whole(tmp_path, monkeypatch):
    # The closed loop of paper-lab-20 identifies its estimator on a narrowband record and says
    # so (ExcitationWarning): a user sees that warning, and the snippet goes on.
    namespace = _run(SNIPPETS[0], tmp_path, monkeypatch)
    assert namespace["result"].ok and (tmp_path / "report.html").is_file()


def test_the_test_command_is_the_one_ci_runs_verbatim():
    assert QUICK_START[1] in CI.splitlines()


def test_the_first_command_names_an_installed_entry_point_and_a_verb(capsys):
    words = shlex.split(QUICK_START[0])
    assert words[:4] == ["python3", "-m", "venv", ".venv"]
    command, verb = words[-2:]
    assert command == ".venv/bin/powerline-control" and verb == "run"
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    module, _, function = scripts["powerline-control"].partition(":")
    from powerline_control import cli

    assert module == cli.__name__ and callable(getattr(cli, function))
    # The entry point knows the verb: its help, not an "invalid choice" (exit 2).
    assert getattr(cli, function)([verb, "--help"]) == 0
    assert f"usage: powerline-control {verb}" in capsys.readouterr().out


def test_the_docs_command_builds_what_ci_builds():
    """The README's docs command and CI's build run Sphinx with the same arguments (CI adds -q and
    skips the examples, which its test pass ran)."""
    readme = [line for block in fenced(README, "bash") for line in block.splitlines()
              if "sphinx" in line]
    ci = [line for line in CI.splitlines() if "-m sphinx" in line]
    assert len(readme) == 1 and len(ci) == 1
    arguments = readme[0].split("-m sphinx", 1)[1].split()
    assert set(arguments) <= set(ci[0].split("-m sphinx", 1)[1].split())
    assert readme[0].startswith('.venv/bin/pip install -q -e ".[docs]"')
