"""Scenario files written out: the commented TOML template and the Markdown key reference.

Both are generated from the schema in :mod:`~powerline_control.scenario.config` (the metadata
on each section's fields), so the template, the reference page and the validation never
disagree.
"""

from __future__ import annotations

import dataclasses
import textwrap

from .config import (  # noqa: F401  (default_scenario: doctests)
    _SECTIONS,
    MAX_SAMPLES,
    Scenario,
    _range_text,
    default_scenario,
)
from .files import shipped_scenarios
from .toml_values import toml_key, toml_string, toml_value

__all__ = ["scenario_to_toml", "scenario_reference", "toml_value", "toml_string", "toml_key"]


_SUPERSEDED = {
    ("span", "rts_fraction"): (("tension",), "span.tension is set"),
    ("estimation", "n_sensors"): (("sensors", "sensor_positions"), "the sensors are listed"),
}


def _applies(section_obj, meta: dict, section: str = "", key: str = "") -> bool:
    others, _ = _SUPERSEDED.get((section, key), ((), ""))
    if any(getattr(section_obj, other) is not None for other in others):
        return False
    if meta["needs"] is not None and getattr(section_obj, meta["needs"]) is None:
        return False
    if meta["when"] is None:
        return True
    other, allowed_values = meta["when"]
    return getattr(section_obj, other) in allowed_values


def _when_text(meta: dict, section: str = "") -> str:
    if meta["needs"] is not None:
        return f"{section}.{meta['needs']} set" if section else f"{meta['needs']} set"
    other, allowed_values = meta["when"]
    return f"{other} = " + " or ".join(toml_value(v) for v in allowed_values)


def scenario_to_toml(scenario: Scenario, *, comments: bool = True) -> str:
    """Write a scenario as TOML text that :func:`load_scenario` reads back to an equal scenario.

    With ``comments`` every key is preceded by its unit, meaning and allowed values, and keys
    that do not apply under the chosen preset or load kind are written commented out, so the
    template never shows a setting that would be ignored.

    Parameters
    ----------
    scenario : Scenario
        The scenario to write.
    comments : bool
        Write the explanatory comments (default True).

    Returns
    -------
    str

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> text = scenario_to_toml(default_scenario())
    >>> load_scenario(text=text) == default_scenario()
    True
    >>> '# conductor = "drake"' in text      # the lab preset fixes the conductor
    True
    """
    lines = ["# powerline_control scenario (SI units; positions in m from the left support).",
             "# Reference of every key: docs/scenarios.md (powerline-control scenario --help)."]
    for name in _SECTIONS:
        section = getattr(scenario, name)
        lines.append(f"\n[{name}]")
        if comments:   # what the section is, from its schema's docstring
            lines += textwrap.wrap(_section_doc(type(section)), width=98, initial_indent="# ",
                                   subsequent_indent="# ") + ["#"]
        for f in dataclasses.fields(section):
            meta = f.metadata
            value = getattr(section, f.name)
            if comments:
                unit = f" Unit: {meta['unit']}." if meta["unit"] else ""
                lines += textwrap.wrap(f"{meta['doc']}{unit} Allowed: {_range_text(meta)}.",
                                       width=98, initial_indent="# ", subsequent_indent="# ")
            active = _applies(section, meta, name, f.name)
            alternative = _ALTERNATIVES.get((name, f.name))
            if value is None and alternative is not None:
                others = " and ".join(f"{name}.{o}" for o in alternative)
                lines.append(f"# {f.name} = {toml_value(_example(scenario, name, f.name))}"
                             f"    # an alternative to {others}: set one, not both")
            elif value is None:
                lines.append(f"# {f.name} = (not set)")
            elif not active:
                others, reason = _SUPERSEDED.get((name, f.name), ((), ""))
                superseded = any(getattr(section, other) is not None for other in others)
                why = (f"unset because {reason}" if superseded
                       else f"used only with {_when_text(meta, name)}")
                lines.append(f"# {f.name} = {toml_value(value)}    # {why}")
            else:
                unset = [o for o in _ALTERNATIVES_OF.get((name, f.name), ())
                         if getattr(section, o) is None]
                lines.append(f"{f.name} = {toml_value(value)}" + (
                    f"    # or set {' or '.join(f'{name}.{o}' for o in unset)} below instead "
                    f"(then remove {f.name})" if comments and unset else ""))
    return "\n".join(lines) + "\n"


def _section_doc(cls) -> str:
    """The first paragraph of a section's docstring, on one line."""
    return " ".join((cls.__doc__ or "").strip().split("\n\n")[0].split())


# Keys that replace another (alternatives: a file sets one of them): key -> what it replaces.
_ALTERNATIVES = {
    ("span", "tension"): ("rts_fraction",),
    ("estimation", "sensors"): ("n_sensors", "sensor_positions"),
    ("estimation", "sensor_positions"): ("n_sensors", "sensors"),
    ("truth", "temperature"): ("tension_factor",),
    ("truth", "tension_factor"): ("temperature",),
}
_ALTERNATIVES_OF = {("span", "rts_fraction"): ("tension",),
                    ("estimation", "n_sensors"): ("sensors", "sensor_positions"),
                    ("truth", "temperature"): ("tension_factor",),
                    ("truth", "tension_factor"): ("temperature",)}


def _example(scenario: Scenario, section: str, key: str) -> object:
    """A valid example value of an unset alternative key, for the template."""
    est = scenario.estimation
    if section == "truth":
        # a warm afternoon (the tension several per cent low), or a tension 3 % low
        return {"temperature": 35.0, "tension_factor": 0.97}[key]
    if key == "tension":
        from ..line import conductors

        cond = conductors[scenario.span.conductor] if scenario.span.conductor in conductors \
            else None
        rated = getattr(cond, "rated_strength", None) or 1e5
        return float(round(scenario.span.rts_fraction * rated, -1))
    k = est.n_sensors
    length = scenario.span_length()
    if key == "sensor_positions":
        return tuple(round(length * (j + 1) / (k + 1), 3) for j in range(k))
    n_el = scenario.model.n_elements if scenario.model.n_elements != "auto" else 100
    return tuple(max(1, round(n_el * (j + 1) / (k + 1))) for j in range(k))


def scenario_reference() -> str:
    """The Markdown reference of every scenario key, generated from the validating schema.

    ``docs/scenarios.md`` is this text (a test checks that the committed page matches).

    Returns
    -------
    str

    Examples
    --------
    >>> "| `robot.start` |" in scenario_reference()
    True
    """
    out = [
        "# Scenario files",
        "",
        "<!-- Generated by powerline_control.scenario.scenario_reference(); do not edit by hand.",
        "     Regenerate: python -c \"from powerline_control.scenario import scenario_reference;"
        " print(scenario_reference(), end='')\" > docs/scenarios.md -->",
        "",
        "A scenario is a TOML file of the sections below; every key has a default, so a file "
        "names only what differs. Run one with `powerline-control run FILE.toml` or a shipped "
        "one by name (`powerline-control scenario` lists them; `powerline-control scenario NAME` "
        "prints one as a commented template). The whole file is checked before anything is "
        "computed, and every problem of it is reported at once, each naming the dotted key, "
        "the value and what is allowed. Keys that are alternatives (`span.tension` or "
        "`span.rts_fraction`; `estimation.sensors`, `estimation.sensor_positions` or "
        "`estimation.n_sensors`; `truth.temperature` or `truth.tension_factor`) are set one at a "
        "time. "
        "Units are SI; positions are in metres from the left support.",
        "",
        "Shipped scenarios:",
        "",
    ]
    out += [f"- `{name}`: {text}" for name, text in shipped_scenarios().items()]
    for name, factory in _SECTIONS.items():
        cls = type(factory())
        out += ["", f"## [{name}]", "", _section_doc(cls), "",
                "| key | default | unit | allowed | meaning |", "|---|---|---|---|---|"]
        for f in dataclasses.fields(cls):
            meta = f.metadata
            default = "(not set)" if f.default is None else f"`{toml_value(f.default)}`"
            doc = meta["doc"]
            if meta["needs"] is not None:
                doc += f" Only with `{name}.{meta['needs']}` set."
            elif meta["when"] is not None:
                doc += f" Only with `{_when_text(meta)}`."
            out.append(f"| `{name}.{f.name}` | {default} | {meta['unit'] or '-'} | "
                       f"{_range_text(meta)} | {doc.replace('|', '/')} |")
    out += ["", "Cross-checks: `forcing.position`, `robot.start` and "
            "`estimation.sensor_positions` must lie strictly inside the span; "
            "`estimation.sensors` must be node indices 1..n_elements-1 (the end nodes sit on "
            "the supports, which never move) and need a numeric `model.n_elements`; "
            "`simulation.duration / simulation.dt` must give 50 to "
            f"{MAX_SAMPLES:.0e} samples; a harmonic `forcing.frequency` must lie below the "
            "Nyquist frequency 1 / (2 dt). `truth.temperature` and `truth.tension_factor` are "
            "alternatives; the change of state of `truth.temperature` needs a conductor preset "
            "(the lab conductor of Table 1 carries no area, elastic modulus or thermal "
            "expansion), and the true tension must stay below the conductor's rated strength. "
            "The `[span]` and `[model]` sections are the nominal line (what the engineer knows: "
            "the model's natural frequencies, the robot's tuning, the plan, the severity study "
            "and the closed loop's controller use it); `[truth]` is the line simulated (the "
            "records, the identification and the closed loop's plant run on it).", ""]
    return "\n".join(out)
