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
