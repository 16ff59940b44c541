"""The Sphinx site's generated pages: every public name in the API reference, every example in
the gallery, every hand-written page in a toctree. (CI builds the site itself with -W.)"""

from __future__ import annotations

import importlib
import importlib.util
import pathlib
import re
import tomllib

import pytest

import powerline_control as plc

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _load_pages_module():
    spec = importlib.util.spec_from_file_location("plc_pages", DOCS / "_ext" / "plc_pages.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


pages = _load_pages_module()


def autosummary_entries(rst: str) -> list[str]:
    """Names listed in the autosummary directives of an RST page (a reader written here)."""
    names, inside = [], False
    for line in rst.splitlines():
        if line.startswith(".. autosummary::"):
            inside = True
            continue
        if inside:
            if line.strip().startswith(":") or not line.strip():
                continue
            if line.startswith("   "):
                names.append(line.strip())
            else:
                inside = False
    return names


def _top_level_part(rst: str) -> str:
    """The API page up to its second part (the subpackages' names)."""
    return rst.split(f"\n{pages.SUBPACKAGE_PART}\n")[0]


def test_every_public_name_is_in_the_api_reference_once():
    rst = pages.api_page()
    entries = autosummary_entries(_top_level_part(rst))
    assert sorted(entries) == sorted(plc.__all__)
    assert len(entries) == len(set(entries))
    # every subpackage's public names too, each once, after the top level's
    below = autosummary_entries(rst.split(f"\n{pages.SUBPACKAGE_PART}\n")[1])
    assert len(below) == len(set(below)) and not set(below) & set(entries)
    for module in ("errors", "estimate", "severity", "simulation", "sensors", "closed_loop"):
        exported = set(importlib.import_module(f"powerline_control.{module}").__all__)
        assert exported <= set(entries) | set(below), module
    assert {"robot_value", "ReachWarning", "analyze_observability"} <= set(below)


def test_each_name_sits_in_the_section_of_its_defining_module():
    rst = _top_level_part(pages.api_page())
    sections = re.split(r"\n(?=[^\n]+\n-{3,}\n)", rst)
    for section in sections[1:]:
        module = re.search(r"\(``([a-z_]+)``\)", section).group(1)
        for name in autosummary_entries(section):
            obj = getattr(plc, name)
            if isinstance(getattr(obj, "__module__", None), str):
                # a subpackage's section holds the names of its modules, a module's section
                # those of its private helper modules (_recipe_count for recipe)
                assert obj.__module__ == f"powerline_control.{module}" or \
                    obj.__module__.startswith(f"powerline_control.{module}.") or \
                    obj.__module__.startswith(f"powerline_control._{module}_"), (name, module)
            else:  # a constant: it must be the module's own object
                submodule = importlib.import_module(f"powerline_control.{module}")
                assert getattr(submodule, name) is obj, (name, module)


def test_a_name_added_by_another_branch_is_listed(monkeypatch):
    """A new public name from a module the page has never heard of still gets a section."""
    import types

    module = types.ModuleType("powerline_control.brand_new")
    module.__doc__ = "Brand-new things: one function."

    def fresh_function():
        """Do nothing."""

    fresh_function.__module__ = module.__name__
    module.fresh_function = fresh_function
    monkeypatch.setitem(__import__("sys").modules, module.__name__, module)
    monkeypatch.setattr(plc, "fresh_function", fresh_function, raising=False)
    monkeypatch.setattr(plc, "__all__", [*plc.__all__, "fresh_function"])
    rst = pages.api_page()
    assert "fresh_function" in autosummary_entries(rst)
    assert "Brand-new things (``brand_new``)" in rst


def test_every_example_has_a_gallery_page_with_its_source():
    scripts = pages.example_scripts()
    assert {p.name for p in scripts} >= {"simulate_paper_span.py", "dask_study.py"}
    index = pages.gallery_index(scripts)
    for path in scripts:
        page = pages.example_page(path)
        assert page.startswith("# ") and len(page.splitlines()[0]) > 5
        assert f"{{literalinclude}} ../../examples/{path.name}" in page
        assert f"({path.stem}.md)" in index


def test_pages_the_index_does_not_list_go_under_more():
    index = (DOCS / "index.md").read_text()
    found = {p.stem for p in DOCS.glob("*.md")} | {"api/index", "gallery/index"}
    extra = pages.other_pages(index, found)
    # Every hand-written page is in a toctree: either listed in the index or added under "More".
    listed = {line.strip() for line in index.splitlines()}
    for page in found - {"index"}:
        assert page in listed or page in extra, page
    assert pages.other_pages(index, found | {"new_page"}) == sorted({*extra, "new_page"})


def test_docs_extra_declares_what_conf_py_loads():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    declared = {re.split(r"[<>=\[ ]", req)[0].lower() for req in extras["docs"]}
    conf = (DOCS / "conf.py").read_text()
    assert {"sphinx", "numpydoc", "myst-parser"} <= declared
    assert '"myst_parser"' in conf and '"numpydoc"' in conf


@pytest.mark.parametrize("page", ["getting_started.md", "theory.md", "studies.md"])
def test_the_pages_this_site_adds_exist_and_have_a_title(page):
    text = (DOCS / page).read_text()
    assert text.startswith("# ")


def test_an_executed_example_shows_its_output_and_figures(tmp_path):
    script = tmp_path / "tiny_example.py"
    script.write_text(
        '"""A tiny example: prints and writes a figure."""\n'
        "import pathlib, sys\n"
        "out = pathlib.Path(sys.argv[1]); out.mkdir()\n"
        "(out / 'fig.png').write_bytes(b'\\x89PNG\\r\\n\\x1a\\n' + bytes(200))\n"
        "print('hello from the example')\n")
    stdout, pngs = pages.run_example(script, tmp_path / "figures")
    assert stdout.strip() == "hello from the example" and pngs == ["fig.png"]
    page = pages.example_page(script, (stdout, pngs))
    assert "hello from the example" in page
    assert "{image} _figures/tiny_example/fig.png" in page
    assert page.startswith("# A tiny example")
    failing = tmp_path / "failing.py"
    failing.write_text("raise SystemExit('no luck')\n")
    with pytest.raises(RuntimeError, match="no luck"):
        pages.run_example(failing, tmp_path / "figures")


@pytest.mark.parametrize(("variable", "expected"), [("all", "every"), ("none", set()),
                                                     ("", {"simulate_paper_span"})])
def test_which_examples_the_build_runs(monkeypatch, variable, expected):
    monkeypatch.setenv("PLC_DOCS_EXECUTE", variable)
    chosen = pages.executed_examples(["simulate_paper_span"])
    if expected == "every":
        expected = {p.stem for p in pages.example_scripts()}
    assert chosen == expected


def test_the_site_runs_every_example_so_each_gallery_page_shows_its_figures(monkeypatch):
    monkeypatch.delenv("PLC_DOCS_EXECUTE", raising=False)
    namespace = {"__file__": str(DOCS / "conf.py")}
    conf = (DOCS / "conf.py").read_text()
    line = next(line for line in conf.splitlines() if line.startswith("plc_gallery_execute"))
    exec(line, namespace)
    chosen = pages.executed_examples(namespace["plc_gallery_execute"])
    assert chosen == {p.stem for p in pages.example_scripts()}
    monkeypatch.setenv("PLC_DOCS_EXECUTE", "none")
    assert pages.executed_examples("all") == set()


@pytest.mark.parametrize(("line", "expected"), [
    ("gives |sin(pi x / l)| at both ends", r"gives \|sin(pi x / l)\| at both ends"),
    ("a literal ``|lambda| < 1`` stays", "a literal ``|lambda| < 1`` stays"),
    ("math :math:`|y|` and `|z|` stay", "math :math:`|y|` and `|z|` stay"),
    ("   | a line block stays", "   | a line block stays"),
    ("+---+---+", "+---+---+"),
])
def test_absolute_values_in_docstrings_are_not_substitutions(line, expected):
    assert pages.escape_bars(line) == expected
    # And docutils agrees: the escaped text parses without a substitution error.
    from docutils.core import publish_doctree
    from docutils.utils import Reporter

    tree = publish_doctree(pages.escape_bars(line), settings_overrides={
        "report_level": Reporter.SEVERE_LEVEL + 1, "halt_level": Reporter.SEVERE_LEVEL + 1})
    assert not [n for n in tree.findall() if n.tagname in ("problematic", "system_message")]


def test_the_gallery_names_whole_output_files_only(tmp_path):
    script = tmp_path / "writes.py"
    script.write_text('"""Writes."""\nname = "x"\nopen(f"fig_{name}.png", "w")\n'
                      'open("table.csv", "w")\n')
    assert pages._figure_names(script) == {"table.csv"}


def _load_layout_module():
    spec = importlib.util.spec_from_file_location("plc_layout", DOCS / "_ext" / "plc_layout.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_layout_page_reads_imports_and_heights_from_a_known_tree(tmp_path):
    # a toy package whose diagram is known by hand: a <- b <- sub (a leaf, then two rows up)
    layout = _load_layout_module()
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text('"""Leaf."""\n')
    (pkg / "b.py").write_text('"""Middle."""\nfrom .a import x\n')
    (pkg / "sub" / "__init__.py").write_text(
        '"""Top part.\nSecond line."""\nfrom .inner import y\n')
    (pkg / "sub" / "inner.py").write_text('"""Inner."""\nfrom ..b import z\nfrom .. import a\n')
    edges = layout.import_edges(pkg)
    assert edges == {"a": set(), "b": {"a"}, "sub": {"a", "b"}}
    assert layout.layers(edges) == {"a": 0, "b": 1, "sub": 2}
    page = layout.layout_page(edges, pkg)
    assert "| `sub/` | 2 | 6 | Top part. Second line. |" in page
    with pytest.raises(ValueError, match="import cycle"):
        layout.layers({"a": {"b"}, "b": {"a"}})


def test_layout_page_covers_every_part_of_the_package():
    layout = _load_layout_module()
    edges = layout.import_edges()
    parts = {p.stem if p.is_file() else p.name for p in (ROOT / "powerline_control").iterdir()
             if (p.suffix == ".py" or (p / "__init__.py").exists())}
    assert set(edges) == parts - {"__init__", "__main__"}


def test_the_gallery_index_shows_a_thumbnail_of_each_example_that_ran(tmp_path):
    from matplotlib import image
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 5), dpi=100)
    figure.add_subplot().plot([0, 1], [1, 0])
    figure.savefig(tmp_path / "big.png")
    pages.make_thumbnail(tmp_path / "big.png", tmp_path / "thumbs" / "a.png")
    # 800 x 500 px fits in 200 x 150 as 200 x 125
    assert image.imread(tmp_path / "thumbs" / "a.png").shape[:2] == (125, 200)
    pages.make_thumbnail(tmp_path / "thumbs" / "a.png", tmp_path / "thumbs" / "b.png", (60, 60))
    assert image.imread(tmp_path / "thumbs" / "b.png").shape[:2] == (38, 60)
    scripts = pages.example_scripts()[:2]
    index = pages.gallery_index(scripts, {scripts[0].stem: "_figures/_thumbnails/x.png"})
    assert f"| [![{scripts[0].stem}](_figures/_thumbnails/x.png){{.plc-thumbnail}}]" \
           f"({scripts[0].stem}.md) | [{scripts[0].name}]" in index
    assert f"|  | [{scripts[1].name}]({scripts[1].stem}.md) |" in index   # it did not run
    assert "| | example | what it shows |" not in pages.gallery_index(scripts)
