"""Scenario files on disk: the shipped ones by name, reading a user's file, overriding keys.

:func:`load_scenario` reads TOML (a path, a shipped name or text), validates the whole file with
the schema of :mod:`~powerline_control.scenario.config` and reports every problem at once.
Standard library only at import time, like the schema.
"""

from __future__ import annotations

import dataclasses
import tomllib
from importlib import resources
from os import PathLike
from pathlib import Path

from .._validation import checked_keywords
from ..errors import InputError
from .config import _SECTIONS, Scenario, _check_scenario, _Checker, _read_section, default_scenario
from .truth import check_truth

__all__ = ["load_scenario", "shipped_scenarios", "read_scenario_text", "override_scenario_text"]


def _scenario_dir():
    return resources.files("powerline_control").joinpath("data", "scenarios")


def shipped_scenarios() -> dict[str, str]:
    """The scenarios shipped with the package: name -> one-line description.

    Run one by name: ``powerline-control run drake-300m``.

    Examples
    --------
    >>> sorted(shipped_scenarios())
    ['drake-300m', 'paper-lab-100', 'paper-lab-20']
    """
    found = {}
    for entry in sorted(_scenario_dir().iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".toml"):
            data = tomllib.loads(entry.read_text())
            found[entry.name[:-5]] = data.get("scenario", {}).get("description", "")
    return found


_MAX_SCENARIO_BYTES = 1_000_000  # the shipped scenarios are ~1 kB


def _resolve(path: str | Path) -> tuple[str, str]:
    """The text and a display name of a scenario given as a file path or a shipped name."""
    candidate = Path(path)
    if candidate.is_file() or candidate.suffix == ".toml" or len(candidate.parts) > 1:
        # A device or FIFO (/dev/zero) would be read without end, a huge file whole: a scenario
        # is a few kilobytes of TOML, so only a regular file under the limit is read.
        if candidate.exists() and not candidate.is_file():
            raise InputError(f"The scenario path {str(candidate)!r} is not a regular file (a "
                             "folder, device or pipe). Give a TOML file.")
        if candidate.is_file() and candidate.stat().st_size > _MAX_SCENARIO_BYTES:
            raise InputError(f"The scenario file {str(candidate)!r} has "
                             f"{candidate.stat().st_size} bytes, over the {_MAX_SCENARIO_BYTES} "
                             "a scenario may have. Give a TOML scenario file.")
        try:
            raw = candidate.read_bytes()
            if b"\x00" in raw:
                raise UnicodeDecodeError("utf-8", raw[:1], 0, 1, "a NUL byte")
            # "utf-8-sig": a byte-order mark (Notepad, Excel's "UTF-8") is no part of the TOML
            return raw.decode("utf-8-sig"), str(candidate)
        except UnicodeDecodeError:
            raise InputError(f"The scenario file {str(candidate)!r} is not text (it is not "
                             "UTF-8, or holds NUL bytes): give a TOML scenario file.") from None
        except OSError as exc:
            names = ", ".join(shipped_scenarios())
            raise InputError(f"Cannot read the scenario file {str(candidate)!r}: "
                             f"{exc.strerror or exc}. Give a TOML file or a shipped scenario "
                             f"name ({names}).") from exc
    shipped = _scenario_dir().joinpath(f"{path}.toml")
    if shipped.is_file():
        return shipped.read_text(), f"{path} (shipped scenario)"
    names = ", ".join(shipped_scenarios())
    raise InputError(f"No scenario file or shipped scenario named {str(path)!r}. Shipped "
                     f"scenarios: {names}; or give the path of a TOML file.")


def read_scenario_text(path: str | Path) -> tuple[str, str]:
    """The TOML text of a scenario file or shipped name, and a name for messages.

    Only a regular UTF-8 text file under 1 MB is read (a device, a folder or a binary file is
    refused in one sentence naming it).

    Parameters
    ----------
    path : str or Path
        A TOML file, or the name of a shipped scenario.

    Returns
    -------
    (str, str)
        The text and its display name.

    Raises
    ------
    InputError
        On a missing, unreadable, binary or oversized file, or an unknown name.

    Examples
    --------
    >>> text, source = read_scenario_text("drake-300m")
    >>> source, "[span]" in text
    ('drake-300m (shipped scenario)', True)
    """
    return _resolve(path)


def override_scenario_text(text: str, overrides: dict) -> str:
    """The scenario ``text`` with dotted keys replaced (``{"estimation.n_sensors": 4}``).

    The result is TOML for :func:`load_scenario`, which validates it (comments are dropped).

    Parameters
    ----------
    text : str
        TOML text of a scenario.
    overrides : dict
        Dotted keys (``section.key``) and their values.

    Returns
    -------
    str

    Examples
    --------
    >>> text = override_scenario_text("[model]\\nn_elements = 20", {"estimation.n_sensors": 4})
    >>> load_scenario(text=text).estimation.n_sensors
    4
    """
    data = tomllib.loads(text)
    for key, value in overrides.items():
        section, _, name = key.partition(".")
        data.setdefault(section, {})[name] = value
    lines = []
    for section, table in data.items():
        lines.append(f"[{section}]")
        if isinstance(table, dict):
            lines += [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


@checked_keywords
def load_scenario(path: str | Path | None = None, *, text: str | None = None,
                  source: str | None = None) -> Scenario:
    """Read and fully validate a scenario from a TOML file, a shipped name, or ``text``.

    Missing keys take their defaults. Nothing is computed: the checks need at most the span's
    length and the conductor catalogue.

    Parameters
    ----------
    path : str or Path or None
        A TOML file, or the name of a shipped scenario (see :func:`shipped_scenarios`); None
        with no ``text`` gives :func:`default_scenario`.
    text : str or None
        TOML text instead of a file.
    source : str or None
        Name of the text's origin for messages (default: the path, or "<text>").

    Returns
    -------
    Scenario

    Raises
    ------
    InputError
        On a missing or unreadable file, invalid TOML, unknown sections or keys, keys that
        conflict with the preset or load kind, or bad values; the message names the file and
        the dotted key.

    Examples
    --------
    >>> load_scenario(text="[model]\\nn_elements = 20").model.n_elements
    20
    >>> load_scenario(text="[robot]\\nstart = 10.0")
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: <text>: robot.start = 10.0 is not allowed. The robot \
must be on the span. Allowed: 0 < x < 3.66 m (the span length).
    """
    if text is not None and not isinstance(text, str):
        # tomllib would fail with a raw AttributeError/TypeError ('float' has no 'replace').
        raise InputError(
            f"The 'text' parameter must be TOML text (a str) or None. Got {text!r:.60} of type "
            f"{type(text).__name__}; read a file with load_scenario(path) instead."
        )
    if path is not None and not isinstance(path, str | PathLike):
        raise InputError(
            f"The 'path' parameter must be a file path, a shipped scenario name or None. Got "
            f"{path!r:.60} of type {type(path).__name__}."
        )
    if source is not None and not isinstance(source, str):
        raise InputError(
            f"The 'source' parameter must be a str (a name for messages) or None. Got "
            f"{type(source).__name__}."
        )
    folder = None
    if text is None:
        if path is None:
            return default_scenario()
        text, name = _resolve(path)
        if Path(path).is_file():
            folder = Path(path).resolve().parent
    else:
        name = "<text>"
    check = _Checker(source or name)
    text = text.removeprefix("\ufeff")   # a byte-order mark read as text is no part of the TOML
    if len(text) > _MAX_SCENARIO_BYTES:
        raise InputError(f"{check.source}: {len(text)} characters, over the "
                         f"{_MAX_SCENARIO_BYTES} a scenario may have. Give a TOML scenario.")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{check.source}: not valid TOML: {exc}.") from exc
    for section in data:
        if section not in _SECTIONS:
            check.note(f"unknown section [{section}]. The sections are: "
                       f"{', '.join(f'[{s}]' for s in _SECTIONS)}.")
    scenario = Scenario(**{
        section: _read_section(check, type(factory()), section, data[section])
        for section, factory in _SECTIONS.items() if section in data})
    _check_scenario(check, scenario, data)
    check_truth(check, scenario, data)   # the [truth] against the nominal span
    wind = scenario.severity.wind_record
    if wind is not None and not wind.strip():
        check.note("severity.wind_record = \"\" is not allowed: give the path of a CSV file, "
                   "or remove the key.")
    check.raise_if_any()
    if wind is not None and folder is not None and not Path(wind).is_absolute():
        # relative to the scenario file, not to where the command runs
        scenario = dataclasses.replace(scenario, severity=dataclasses.replace(
            scenario.severity, wind_record=str(folder / wind)))
    return scenario


def _toml_value(value: object) -> str:
    from .toml_values import toml_value

    return toml_value(value)
