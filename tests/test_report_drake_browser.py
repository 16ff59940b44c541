"""The drake-300m report as a browser shows it: every figure drawn, every caption said.

``powerline-control run drake-300m`` (the shipped 300 m span: 41 s on 2 shared cores, hence
``slow``) writes report.html; headless Chromium opens a copy of it with a probe script added
(the report itself has none) that, once the page has loaded, writes what the browser sees into
the page: each <figure>'s image and its natural size, its caption, and the page's text. The
test reads that back from ``--dump-dom``. A small page with a broken image, an empty caption
and a 'nan' checks the probe itself (about 2 s, not slow). Skipped without Chromium unless
POWERLINE_CONTROL_REQUIRE_BROWSER=1 (CI installs it).
"""

import html
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from cli_support import COMMAND

import powerline_control as plc

# Runs in the page after every image has loaded (or failed): what a reader sees, as JSON.
PROBE = """<script>
window.addEventListener("load", function () {
  var figures = Array.prototype.map.call(document.querySelectorAll("figure"), function (f) {
    var img = f.querySelector("img"), cap = f.querySelector("figcaption");
    return {id: f.id, img: !!img, complete: !!img && img.complete,
            width: img ? img.naturalWidth : 0, height: img ? img.naturalHeight : 0,
            alt: img ? img.alt : null, caption: cap ? cap.innerText : null};
  });
  var out = document.createElement("pre");
  out.id = "plc-probe";
  out.textContent = JSON.stringify({figures: figures, text: document.body.innerText});
  document.body.appendChild(out);
});
</script>"""

# A number that did not come out: 'nan', 'NaN', 'inf' as a word, or Python's None printed (the
# English "none" is fine).
MISSING = re.compile(r"\b(?i:nan|inf)\b|\bNone\b")


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


@pytest.fixture(scope="module")
def browser():
    found = _chromium()
    if found is None:
        if os.environ.get("POWERLINE_CONTROL_REQUIRE_BROWSER") == "1":
            pytest.fail("Chromium is required (POWERLINE_CONTROL_REQUIRE_BROWSER=1) but absent")
        pytest.skip("Chromium is not installed (CI installs it and sets "
                    "POWERLINE_CONTROL_REQUIRE_BROWSER=1)")
    return found


@pytest.fixture(scope="module")
def drake_report(tmp_path_factory, browser):
    folder = tmp_path_factory.mktemp("drake")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(plc.__file__).parents[1])] + env.get("PYTHONPATH", "").split(os.pathsep))
    result = subprocess.run(COMMAND + ["run", "drake-300m", "--out", str(folder / "out"), "-q"],
                            capture_output=True, text=True, env=env, timeout=1200)
    assert result.returncode == 0, result.stderr[-3000:]
    return folder / "out" / "report.html"


def _seen(browser: str, report: Path, folder: Path) -> dict:
    """What Chromium shows of ``report``: the probe's JSON, read from the page after load."""
    page = report.read_text()
    assert page.count("</body>") == 1
    probed = folder / "probed.html"
    probed.write_text(page.replace("</body>", PROBE + "</body>"))
    result = subprocess.run(
        [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={folder / 'profile'}",
         "--virtual-time-budget=20000", "--dump-dom", probed.as_uri()],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    found = re.search(r'<pre id="plc-probe">(.*?)</pre>', result.stdout, re.DOTALL)
    assert found, "the probe did not run: " + result.stderr[-2000:]
    return json.loads(html.unescape(found[1]))


@pytest.fixture(scope="module")
def seen(browser, drake_report, tmp_path_factory):
    return _seen(browser, drake_report, tmp_path_factory.mktemp("chromium"))


def _unloaded(figures: list[dict]) -> list[str]:
    """The figures without an image, or whose image the browser could not draw."""
    return [f["id"] for f in figures
            if not (f["img"] and f["complete"] and f["width"] > 0 and f["height"] > 0)]


def _unsaid(figures: list[dict]) -> list[str]:
    """The figures whose caption is missing, says nothing after its number, or prints a
    missing number; or whose image's alt text does."""
    return [f["id"] for f in figures
            if not re.match(r"Figure \d+\.\s+\S.{20,}", (f["caption"] or "").strip(), re.DOTALL)
            or MISSING.search(f["caption"] or "") or MISSING.search(f["alt"] or "")]


def _missing_numbers(text: str) -> list[str]:
    return [text[max(m.start() - 80, 0):m.end() + 40] for m in MISSING.finditer(text)]


def test_the_probe_sees_a_broken_image_an_empty_caption_and_a_nan(browser, tmp_path):
    good = ("data:image/svg+xml;base64,PHN2ZyB4bWxucz0naHR0cDovL3d3dy53My5vcmcvMjAwMC9zdmcnIHd"
            "pZHRoPSc0MCcgaGVpZ2h0PSczMCc+PHJlY3Qgd2lkdGg9JzQwJyBoZWlnaHQ9JzMwJy8+PC9zdmc+")
    page = tmp_path / "report.html"
    page.write_text(
        "<html><body><p>A ratio of nan x; none of the layouts; 1e-3 inference</p>"
        f"<figure id='fig-a'><img src='{good}' alt='a'><figcaption>Figure 1. A caption that "
        "says what to look for.</figcaption></figure>"
        "<figure id='fig-b'><img src='data:image/svg+xml;base64,AAAA' alt='b'><figcaption>"
        "Figure 2. </figcaption></figure>"
        f"<figure id='fig-c'><img src='{good}' alt='c'><figcaption>Figure 3. The robot ends "
        "at None m, against the target.</figcaption></figure></body></html>")
    seen = _seen(browser, page, tmp_path)
    assert _unloaded(seen["figures"]) == ["fig-b"]
    assert _unsaid(seen["figures"]) == ["fig-b", "fig-c"]
    # 'none' and 'inference' are words; 'nan' and 'None' are numbers that did not come out.
    assert [m[0] for m in MISSING.finditer(seen["text"])] == ["nan", "None"]
    assert len(_missing_numbers(seen["text"])) == 2


@pytest.mark.slow
def test_every_drake_figure_has_an_image_that_loaded(seen):
    assert len(seen["figures"]) >= 8, [f["id"] for f in seen["figures"]]
    assert _unloaded(seen["figures"]) == []


@pytest.mark.slow
def test_every_drake_caption_says_something(seen):
    assert _unsaid(seen["figures"]) == []


@pytest.mark.slow
def test_no_text_of_the_drake_report_says_nan_or_none(seen):
    assert _missing_numbers(seen["text"]) == []
