"""Every code snippet in docs/*.md runs, page by page, in order, in one namespace per page.

A ```pycon block (or a ```python block with ``>>>`` prompts) is a doctest: its printed output
must match. Any other ```python block is executed and must not raise. Other fences (console,
text, toml) are not Python. Each page runs as a module of its own, in an empty temporary folder
(snippets that write files leave nothing behind), under the suite's warnings-are-errors filter
(a snippet that warns must say so, with ``warnings.catch_warnings`` in the page).
"""

from __future__ import annotations

import doctest
import pathlib
import re
import sys
import types

import pytest

DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs"
GENERATED = {"api", "gallery", "_build", "_templates", "_ext"}
FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>[^\n`]*)$")
PYTHON = {"python", "py", "python3"}
DOCTEST = {"pycon", "doctest"}
OPTIONS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def pages() -> list[pathlib.Path]:
    """The hand-written Markdown pages (generated API and gallery pages hold no snippets)."""
    return sorted(
        p for p in DOCS.rglob("*.md")
        if not GENERATED & set(p.relative_to(DOCS).parts[:-1])
    )


def snippets(text: str) -> list[tuple[int, str, str]]:
    """(line number, language, code) of each fenced block, in page order."""
    blocks, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if not match:
            i += 1
            continue
        fence, info = match["fence"], match["info"].strip()
        start, body = i + 1, []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            body.append(lines[i])
            i += 1
        i += 1  # the closing fence
        language = info.split()[0].strip("{}").lower() if info else ""
        blocks.append((start, language, "\n".join(body) + "\n"))
    return blocks


def test_the_fence_reader_finds_every_block():
    page = "text\n```python\na = 1\n```\n\n````pycon\n>>> a\n1\n````\n~~~text\nx\n~~~\n"
    assert snippets(page) == [(2, "python", "a = 1\n"), (6, "pycon", ">>> a\n1\n"),
                              (10, "text", "x\n")]


def _runnable(language: str, code: str) -> bool:
    return language in DOCTEST or language in PYTHON


PAGES_WITH_SNIPPETS = [p for p in pages() if any(_runnable(lang, code)
                                                 for _, lang, code in snippets(p.read_text()))]


def test_the_pages_with_snippets_are_found():
    # The getting-started page has snippets by construction; the module pages had some too.
    names = {p.name for p in PAGES_WITH_SNIPPETS}
    assert "getting_started.md" in names and "studies.md" in names and len(names) >= 4


@pytest.mark.parametrize("page", PAGES_WITH_SNIPPETS, ids=lambda p: str(p.relative_to(DOCS)))
def test_page_snippets_run(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # The page runs as a module, as a user's script would: functions it defines pickle by
    # reference, so the studies page can send them to a process pool.
    module = types.ModuleType(f"_docs_page_{page.stem}")
    monkeypatch.setitem(sys.modules, module.__name__, module)
    namespace = module.__dict__
    for line, language, code in snippets(page.read_text()):
        if language in DOCTEST or (language in PYTHON and ">>>" in code):
            _run_doctest(page, line, code, namespace)
        elif language in PYTHON:
            try:
                exec(compile(code, f"{page.name}:{line}", "exec"), namespace)  # noqa: S102
            except Exception as error:
                raise AssertionError(
                    f"{page.name}, the python block at line {line} failed: "
                    f"{type(error).__name__}: {error}") from error


def _run_doctest(page: pathlib.Path, line: int, code: str, namespace: dict) -> None:
    test = doctest.DocTestParser().get_doctest(code, namespace, f"{page.name}:{line}",
                                               str(page), line)
    runner = doctest.DocTestRunner(optionflags=OPTIONS)
    report: list[str] = []
    runner.run(test, out=report.append, clear_globs=False)
    namespace.update(test.globs)  # DocTest works on a copy: carry its names to the next block
    if runner.failures:
        raise AssertionError(f"{page.name}, the doctest block at line {line}:\n" + "".join(report))
