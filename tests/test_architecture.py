"""Project rules that code review would otherwise have to catch: import direction, docstrings."""

import ast
import importlib
import inspect
import pathlib
import re

import pytest
from numpydoc.docscrape import ClassDoc
from numpydoc.validate import validate

import powerline_control as plc

PACKAGE = pathlib.Path(plc.__file__).parent

# design.md section 2: a module may import only modules above it. Leaf utilities are free.
ORDER = ["line", "fem", "excitation", "simulation", "identify", "riccati", "estimate", "sensors",
         "recipe", "antinode", "plan", "severity", "closed_loop", "studies"]
# Shared helpers every stage may use: validation, errors, tones and phasors, constants, threads,
# the verbs the results share.
LEAVES = {"errors", "_validation", "_spectral", "_constants", "_threads", "_results"}
# The output side and the scenario pipeline (design.md: scenario/ runs every stage, then the
# report) sit below every stage.
ANYTHING_GOES = {"output", "scenario", "cli", "__init__", "__main__"}
# No line limit on a module: one concept per module. A long module that holds one concept is
# fine (python-control's statesp.py); a cut that follows a line count rather than a concept is
# not (it leaves two halves that import each other, which test_no_import_cycles refuses).


def _internal_imports(path: pathlib.Path) -> set[str]:
    """The package's top-level modules (or subpackages) that ``path`` imports."""
    tree = ast.parse(path.read_text())
    # a file of a subpackage reaches the package's top level with two dots
    top_level = 1 if path.parent == PACKAGE else 2
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == top_level and node.module:
            found.add(node.module.split(".")[0])
        elif isinstance(node, ast.ImportFrom) and node.module and \
                node.module.startswith("powerline_control."):
            found.add(node.module.split(".")[1])
    return found


def _rank(module: str) -> int | None:
    # A private helper module (``_sensor_criteria``) ranks with the module it serves.
    base = module.lstrip("_")
    for i, name in enumerate(ORDER):
        if base == name or base.startswith(name.rstrip("s") + "_") or base.startswith(name + "_"):
            return i
    return None


def _module_of(path: pathlib.Path) -> str:
    """The top-level name a file belongs to: its own stem, or its subpackage's name."""
    return path.stem if path.parent == PACKAGE else path.relative_to(PACKAGE).parts[0]


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_flow_one_way(path):
    module = _module_of(path)
    if module in LEAVES | ANYTHING_GOES:
        return
    own = _rank(module)
    assert own is not None, f"{module}.py is not placed in design.md's module order"
    for imported in _internal_imports(path) - LEAVES:
        other = _rank(imported)
        assert other is not None and other < own or (other == own and imported != module), (
            f"{module}.py imports {imported}, which sits below it in the data flow")


def _dotted(path: pathlib.Path) -> str:
    """``powerline_control.estimate.filter`` for a file (a package: its ``__init__``'s name)."""
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(dotted: str) -> bool:
    relative = pathlib.Path(*dotted.split("."))
    return (PACKAGE.parent / relative.with_suffix(".py")).is_file() or \
        (PACKAGE.parent / relative / "__init__.py").is_file()


def _module_imports(path: pathlib.Path) -> set[str]:
    """Every module of the package that ``path`` imports, wherever the import stands: at the
    top, inside a function (a lazy import) or under ``if TYPE_CHECKING`` (an annotation-only
    import is a dependency too). ``from .x import y`` counts as ``x.y`` when ``y`` is a module,
    else as ``x`` (a package's names come from its ``__init__``)."""
    here = _dotted(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                target = ".".join(base + [p for p in (node.module or "").split(".") if p])
            elif (node.module or "").split(".")[0] == "powerline_control":
                target = node.module
            else:
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.add(sub if _is_module(sub) else target)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names
                         if alias.name.split(".")[0] == "powerline_control")
    return found - {_dotted(path)}


def _import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan): each holds a circle."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in graph.get(node, ()):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while not component or component[-1] != node:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_the_cycle_finder_finds_a_circle_and_nothing_else():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _import_cycles(graph) == [["a", "b", "c"]]
    assert _import_cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    """No two modules import each other, directly or around a circle: between subpackages and
    inside each of them (``scenario.result`` <-> ``scenario.summary`` counts as much as
    ``fem`` <-> ``plan``), lazy and annotation-only imports included, with no exemptions. A
    circle means two concepts are cut in the wrong place: move what both need below both."""
    graph = {_dotted(path): _module_imports(path) for path in PACKAGE.rglob("*.py")}
    cycles = _import_cycles(graph)
    described = ["; ".join(f"{module} -> {', '.join(sorted(graph[module] & set(cycle)))}"
                           for module in cycle) for cycle in cycles]
    assert not cycles, "import circles:\n" + "\n".join(described)


def _imported_modules(path: pathlib.Path) -> list[tuple[list[str], list[str]]]:
    """Each ``from ... import`` of ``path`` inside the package: (target path parts, names)."""
    where = list(path.relative_to(PACKAGE).parts[:-1])
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = where[:len(where) - (node.level - 1)]
            target = base + [part for part in (node.module or "").split(".") if part]
            found.append((target, [alias.name for alias in node.names]))
    return found


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_private_cross_imports(path):
    """A concept reaches another only through its public names (the leaves are shared)."""
    module = _module_of(path)
    for target, names in _imported_modules(path):
        if not target:  # ``from . import x`` at the top level: x is the concept
            if names == ["__version__"]:
                continue
            target, names = [names[0]], []
        if target[0] == module or target[0] in LEAVES | {"_riccati"}:  # the one DARE solver
            continue
        private = [part for part in target if part.startswith("_")] + [
            name for name in names if name.startswith("_") and name != "__version__"]
        assert not private, f"{path.relative_to(PACKAGE)} imports private {private} of {target}"


TESTS = pathlib.Path(__file__).parent
# A module's one documented private seam: a paragraph of its docstring that starts "Test seam:"
# and names (in double backquotes) the private names tests may reach, and says why.
SEAM_PARAGRAPH = re.compile(r"^Test seam:(.*?)(?:\n\s*\n|\Z)", re.S | re.M)


def _module_file(module: str) -> pathlib.Path | None:
    parts = module.split(".")[1:]
    if not parts:
        return PACKAGE / "__init__.py"
    relative = pathlib.Path(*parts)
    for candidate in (PACKAGE / relative.with_suffix(".py"), PACKAGE / relative / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _private_reaches(path: pathlib.Path) -> set[tuple[str, str]]:
    """(module, private name) pairs a test file imports, reads or monkeypatches."""
    tree = ast.parse(path.read_text())
    modules, found = {}, set()      # local name -> the package module it stands for
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("powerline_control"):
            for alias in node.names:
                modules[alias.asname or alias.name] = f"{node.module}.{alias.name}"
                if alias.name.startswith("_"):
                    found.add((node.module, alias.name))
        elif isinstance(node, ast.Import):
            modules.update({alias.asname or alias.name: alias.name for alias in node.names
                            if alias.name.startswith("powerline_control")})
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            owner, name = modules.get(node.value.id), node.attr
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "setattr"
              and len(node.args) >= 2 and isinstance(node.args[0], ast.Name)
              and isinstance(node.args[1], ast.Constant)):
            owner, name = modules.get(node.args[0].id), str(node.args[1].value)
        else:
            continue
        if owner and name.startswith("_") and not name.startswith("__"):
            found.add((owner, name))
    # A private module (``_spectral``, ``estimate._recursion``) is tested through its own names.
    return {(module, name) for module, name in found if not _module_file(f"{module}.{name}")}


def _declared_seam(module: str) -> set[str]:
    path = _module_file(module)
    match = SEAM_PARAGRAPH.search(ast.get_docstring(ast.parse(path.read_text())) or "") \
        if path else None
    return set(re.findall(r"``(_\w+)``", match.group(1))) if match else set()


@pytest.mark.parametrize("path", sorted(TESTS.glob("*.py")), ids=lambda p: p.name)
def test_tests_reach_private_names_only_through_a_documented_seam(path):
    """Tests go through public names, or through the one seam a module's docstring declares."""
    undeclared = sorted(f"{module}.{name}" for module, name in _private_reaches(path)
                        if name not in _declared_seam(module))
    assert not undeclared, (f"{path.name} reaches {undeclared}: test through a public name, or "
                            "name it in its module's 'Test seam:' docstring paragraph")


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_a_declared_seam_names_what_the_module_has(path):
    relative = path.relative_to(PACKAGE.parent).with_suffix("")
    module = ".".join(relative.parts[:-1] if relative.name == "__init__" else relative.parts)
    declared = _declared_seam(module)
    if declared:
        missing = sorted(declared - set(vars(importlib.import_module(module))))
        assert not missing, f"{module} declares test seams it does not have: {missing}"


@pytest.mark.parametrize("init", sorted(PACKAGE.glob("*/__init__.py")),
                         ids=lambda p: p.parent.name)
def test_each_subpackage_says_what_it_owns_in_two_lines(init):
    doc = ast.get_docstring(ast.parse(init.read_text()))
    assert doc, f"{init.parent.name}/__init__.py has no docstring"
    assert len(doc.strip().split("\n\n")[0].splitlines()) <= 2, doc


def test_the_package_is_a_plain_module():
    """No class swap guards the public names: no module file carries a public name."""
    import types

    assert type(plc) is types.ModuleType
    shadowing = sorted(path.name for path in PACKAGE.iterdir()
                       if path.name.removesuffix(".py") in set(plc.__all__))
    assert not shadowing, f"modules named after public names of the package: {shadowing}"


def test_the_top_level_is_sorted_and_everything_else_has_a_subpackage():
    """``__all__`` is sorted, lists each name once, and the package resolves each lazily; the
    names it leaves out stay public in their subpackage (the API page lists those too)."""
    assert plc.__all__ == sorted(plc.__all__) and len(set(plc.__all__)) == len(plc.__all__)
    assert all(getattr(plc, name, None) is not None for name in plc.__all__)
    assert plc.severity.robot_value and plc.estimate.analyze_observability
    assert plc.errors.ReachWarning and plc.simulation.parked_steady_state


def test_no_module_only_forwards_to_another():
    """No deprecation layer before the first release: each module path is a real home."""
    forwarding = sorted(path.name for path in PACKAGE.rglob("*.py")
                        if "is deprecated; import from" in path.read_text())
    assert not forwarding, f"modules that only warn and forward: {forwarding}"


def test_simulate_is_the_function_and_no_module():
    """``plc.simulate`` is the function; the subpackage ``simulation`` never replaces it."""
    import powerline_control.simulation

    assert callable(plc.simulate) and plc.simulate is powerline_control.simulation.simulate
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("powerline_control.simulate")


def _public_objects():
    for name in sorted(getattr(plc, "__all__", None) or dir(plc)):
        obj = getattr(plc, name)
        if name.startswith("_") or not (inspect.isclass(obj) or inspect.isfunction(obj)):
            continue
        if not getattr(obj, "__module__", "").startswith("powerline_control"):
            continue
        if issubclass(obj, Warning | Exception) if inspect.isclass(obj) else False:
            continue
        yield name, obj


# Checks that matter to users: summary present, parameters documented, an Examples section.
REQUIRED = {"GL08": "no docstring", "SS01": "no summary", "PR01": "undocumented parameter",
            "EX01": "no Examples section"}


@pytest.mark.parametrize(("name", "obj"), list(_public_objects()),
                         ids=lambda v: v if isinstance(v, str) else "")
def test_public_docstrings(name, obj):
    qualified = f"{obj.__module__}.{obj.__qualname__}"
    importlib.import_module(obj.__module__)
    errors = [(code, msg) for code, msg in validate(qualified)["errors"] if code in REQUIRED]
    if inspect.isclass(obj) and any(code == "PR01" for code, _ in errors):
        # Result dataclasses document their fields under "Attributes": that counts.
        doc = ClassDoc(obj)
        documented = {name.strip() for section in ("Parameters", "Attributes")
                      for entry in doc[section] for name in entry.name.split(",")}
        init = inspect.signature(obj).parameters
        if all(p in documented for p in init):
            errors = [e for e in errors if e[0] != "PR01"]
    assert not errors, f"{name}: {errors}"
