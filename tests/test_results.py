"""Results behave alike: comparing two never raises, and the top-level results share one verb set.

A result that holds numpy arrays cannot compare by value with the ``__eq__`` a dataclass
generates (the tuple comparison asks ``bool(array == array)``, which raises), so such results
compare by identity (``eq=False``). The check below finds every such dataclass itself, by walking
the package's modules, so that a result added later is checked too.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib
import inspect
import json
import pkgutil
import re
from collections.abc import Mapping

import numpy as np
import pytest

import powerline_control as plc

# An annotation that may hold an array: an ndarray, or a value typed as anything at all (the
# scenario's stage records hold the stages' results as ``Any``).
_ARRAY_LIKE = re.compile(r"\b(?:np\.ndarray|ndarray|NDArray|Any)\b")


def _package_dataclasses() -> list[type]:
    found = {}
    for info in pkgutil.walk_packages(plc.__path__, f"{plc.__name__}."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if inspect.isclass(obj) and dataclasses.is_dataclass(obj) \
                    and obj.__module__ == module.__name__:
                found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return [found[key] for key in sorted(found)]


def _array_holding(classes: list[type]) -> dict[str, type]:
    """The dataclasses with a field that may hold an array, directly or through another one."""
    holding = {cls.__name__: cls for cls in classes
               if any(_ARRAY_LIKE.search(str(f.type)) for f in dataclasses.fields(cls))}
    changed = True
    while changed:  # a field typed as a holding dataclass holds arrays too
        changed = False
        for cls in classes:
            if cls.__name__ not in holding and any(
                    re.search(rf"\b{name}\b", str(f.type))
                    for f in dataclasses.fields(cls) for name in holding):
                holding[cls.__name__] = cls
                changed = True
    return holding


def _filled(cls: type, holding: dict[str, type], depth: int = 0):
    """An instance with a fresh array in every field that may hold one (no ``__init__``: the
    comparison is the point, not the validation)."""
    obj = cls.__new__(cls)
    for f in dataclasses.fields(cls):
        kind = str(f.type)
        nested = [holding[n] for n in holding if re.search(rf"\b{n}\b", kind)]
        if _ARRAY_LIKE.search(kind):
            value = np.arange(3.0)
        elif nested and depth < 3:
            value = _filled(nested[0], holding, depth + 1)
        else:  # an empty container where one is declared (a Mapping result iterates it)
            value = next((empty for word, empty in (("tuple", ()), ("dict", {}), ("list", []))
                          if kind.startswith(word)), None)
        object.__setattr__(obj, f.name, value)
    return obj


ALL_DATACLASSES = _package_dataclasses()
ARRAY_HOLDING = _array_holding(ALL_DATACLASSES)


def test_the_search_finds_the_array_holding_results():
    # cannot pass vacuously: the package has dozens of them, among them the section-3 results
    assert len(ARRAY_HOLDING) > 20, sorted(ARRAY_HOLDING)
    for name in ("DMDModel", "Estimate", "SensorSelection", "ClosedLoopResult", "SeverityResult",
                 "SpanCalibration", "ScenarioResult", "Snapshots", "Trajectory"):
        assert name in ARRAY_HOLDING, name


@pytest.mark.parametrize("cls", sorted(ARRAY_HOLDING.values(), key=lambda c: c.__qualname__),
                         ids=lambda c: c.__qualname__)
def test_comparing_a_result_never_raises(cls):
    first = _filled(cls, ARRAY_HOLDING)
    second = copy.deepcopy(first)  # equal arrays, other objects: a value comparison would raise
    assert first == first  # noqa: PLR0124 - the point: == on the same result
    assert isinstance(first == second, bool)
    assert isinstance(first != second, bool)
    if cls.__dataclass_params__.eq:  # a value comparison only where the class defines its own
        assert "__eq__" in vars(cls)
    elif not isinstance(first, Mapping):  # a Mapping result compares its (identity) entries
        assert (first == second) is False  # by identity
    if cls.__dataclass_params__.frozen and not isinstance(first, Mapping):
        hash(first)  # does not raise: a frozen result keeps object's hash


# ------------------------------------------------------------------ one verb set, one display

# The results the section-3 verbs return, by their defining module (some are reached through a
# subpackage, not the package's top level).
TOP_LEVEL_RESULTS = {
    "simulation": ["Snapshots"], "identify": ["DMDModel", "OscillatorModel", "SpanCalibration"],
    "estimate": ["Estimate", "Consistency", "Accuracy"], "recipe": ["EstimatorDesign", "Coverage"],
    "sensors": ["SensorSelection"],
    "plan": ["Trajectory"], "closed_loop": ["ClosedLoopResult"],
    "severity": ["SeverityResult", "RobotValue", "FatigueOverRecord"], "studies": ["StudyResult"],
    "scenario.result": ["ScenarioResult"], "scenario.calibrate": ["ScenarioCalibration"],
}
RESULT_CLASSES = [getattr(importlib.import_module(f"powerline_control.{module}"), name)
                  for module, names in TOP_LEVEL_RESULTS.items() for name in names]


@pytest.mark.parametrize("cls", RESULT_CLASSES, ids=lambda c: c.__name__)
def test_every_top_level_result_has_the_verbs(cls):
    for verb in ("summary", "to_dict", "to_json", "_repr_html_"):
        assert callable(getattr(cls, verb, None)), f"{cls.__name__}.{verb}"
    if hasattr(cls, "table"):  # tabular: the rows as a DataFrame too
        assert callable(getattr(cls, "to_dataframe", None)), cls.__name__


def test_the_display_has_one_home():
    """Every result shows itself the same way (one function, not a copy per class)."""
    assert len({cls._repr_html_ for cls in RESULT_CLASSES}) == 1


def _strict_json(text: str) -> object:
    def refuse(constant):
        raise AssertionError(f"not standard JSON: {constant}")
    return json.loads(text, parse_constant=refuse)


def _numbers(text: str) -> list[str]:
    return re.findall(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?", text)


def _check_display(result) -> str:
    """The HTML table holds every number of the summary, and the JSON is standard."""
    summary, page = result.summary(), result._repr_html_()
    assert page.startswith('<table class="powerline-control-result">') and \
        page.rstrip().endswith("</table>")
    assert "<caption" in page and type(result).__name__ in page
    numbers = _numbers(summary)
    assert numbers, summary
    for number in numbers:
        assert number in page, (number, page)
    assert isinstance(_strict_json(result.to_json()), dict)
    return page


def test_a_trajectory_shows_its_move():
    limits = plc.RobotLimits(v_max=0.5, a_max=1.0)
    traj = plc.plan_motion(start=0.2, target=1.8, limits=limits)
    page = _check_display(traj)
    assert f"{traj.duration:.4g} s" in page and "1.8 m" in page  # what it holds, not a copy
    data = _strict_json(traj.to_json())
    assert data["position"] == traj.position.tolist() and data["duration"] == traj.duration
    assert traj.table()[-1]["position_m"] == pytest.approx(1.8)


def test_a_severity_result_shows_its_table():
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    sev = plc.aeolian_severity(span, wind_speeds=[2.0, 4.0])
    page = _check_display(sev)
    for row in sev.table():  # each wind speed's row, its amplitude in mm as the table says
        assert f"<td style=\"text-align: left\">{row['amplitude_mm']:.4g}</td>" in page
    assert _strict_json(sev.to_json())["wind_speed"] == [2.0, 4.0]


def test_a_sensor_selection_shows_its_layout_and_certificate():
    a_diag = np.array([0.9, 0.5, 0.95, 0.7, 0.3])
    sys = __import__("control").ss(np.diag(a_diag), np.zeros((5, 0)), np.eye(5),
                                   np.zeros((5, 0)), 1.0)
    sel = plc.select_sensors(sys, k=2, Q=np.diag([1.0, 2.0, 5.0, 3.0, 0.2]), R=0.5)
    page = _check_display(sel)
    assert f"{sel.objective:.6g}" in page and str(list(sel.nodes)) in page
    for baseline in sel.baselines.values():  # the markdown table's rows become table rows
        assert f"<td style=\"text-align: left\">{baseline.name}</td>" in page
    assert "|" not in page  # the markdown is read, not pasted


def test_the_display_escapes_text():
    study = plc.run_study(_tagged, plc.parameter_grid(k=[1, 2]))
    page = study._repr_html_()
    assert "&lt;b&gt;" in page and "<b>" not in page
    assert _strict_json(study.to_json())["results"][0]["label"] == "<b>1</b>"


def _tagged(k):
    return {"label": f"<b>{k}</b>", "nan": float("nan")}


def test_every_result_of_a_scenario_shows_itself(lab_result):
    """The results a scenario holds (the session's lab run): a display and a summary each, and
    strict JSON from the small ones (the records' JSON is megabytes: not worth the seconds)."""
    design = lab_result.identification.design
    shown = [lab_result, lab_result.records.test, design, design.model,
             lab_result.layouts["chosen"].estimate, lab_result.plan.trajectory,
             lab_result.closed_loop.result, lab_result.severity.bare]
    for result in shown:
        page = result._repr_html_()
        assert page.startswith('<table class="powerline-control-result">'), type(result)
        assert result.summary().strip(), type(result)
    for result in (lab_result, design.model, lab_result.plan.trajectory,
                   lab_result.severity.bare):
        assert isinstance(_strict_json(result.to_json()), dict)
    assert _strict_json(lab_result.to_json()).keys() == lab_result.to_dict().keys()
