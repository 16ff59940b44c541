"""The HTML report: one self-contained file, every figure embedded and captioned, and it renders
in headless Chromium with no console errors and no network requests."""

import base64
import html.parser
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from cli_support import COMMAND
from matplotlib.figure import Figure

import powerline_control as plc
from powerline_control.output.report import figure_data_uri, write_report

SCENARIO = """\
[scenario]
name = "report-check"
description = "A 14-element lab span forced at 31 Hz, for the report test."
[model]
n_elements = 14
[forcing]
frequency = 31.0
position = 0.7
[simulation]
duration = 2.5
[estimation]
n_sensors = 2
[robot]
start = 0.8
closed_loop = 1.5
"""

# Every figure the report carries, by its id in the page.
FIGURES = ["eigenvalues", "sensor_count", "estimate", "error_along_span", "layouts",
           "envelope", "robot_path", "closed_loop", "closed_loop_path"]
SECTIONS = ["Span and model", "Simulated data", "Identification", "Sensor placement",
            "Estimation", "Antinodes and motion plan", "Closed loop"]


class _Page(html.parser.HTMLParser):
    """Collects what the checks need: headings, figures with their image and caption, links."""

    def __init__(self):
        super().__init__()
        self.headings, self.figures, self.urls = [], [], []
        self._tag = None
        self._figure = None
        self._in_caption = False

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        for name in ("src", "href"):
            if name in attrs:
                self.urls.append(attrs[name])
        if tag == "figure":
            self._figure = {"id": attrs.get("id"), "src": None, "caption": ""}
        elif tag == "img" and self._figure is not None:
            self._figure["src"] = attrs.get("src")
        elif tag == "figcaption":
            self._in_caption = True
        self._tag = tag

    def handle_endtag(self, tag):
        if tag == "figure" and self._figure is not None:
            self.figures.append(self._figure)
            self._figure = None
        if tag == "figcaption":
            self._in_caption = False
        self._tag = None

    def handle_data(self, data):
        if self._tag == "h2":
            self.headings.append(data.strip())
        if self._figure is not None and self._in_caption:
            self._figure["caption"] += data


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("report")
    path = folder / "scenario.toml"
    path.write_text(SCENARIO)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(plc.__file__).parents[1])] + env.get("PYTHONPATH", "").split(os.pathsep))
    result = subprocess.run(COMMAND + ["report", str(path), "--out", str(folder / "out"), "-q"],
                            capture_output=True, text=True, env=env, timeout=600)
    assert result.returncode == 0, result.stderr
    return folder / "out" / "report.html"


def test_report_is_one_file_with_the_scenario_date_and_version(report):
    text = report.read_text()
    assert [p.name for p in report.parent.iterdir() if p.suffix != ".json"] == ["report.html"]
    assert "report-check" in text and "14-element lab span" in text
    assert re.search(r"Date:</strong> \d{4}-\d\d-\d\d \d\d:\d\d UTC", text)
    assert f"powerline_control</strong> {plc.__version__}" in text


def test_report_sections_and_captioned_embedded_figures(report):
    page = _Page()
    page.feed(report.read_text())
    for title in SECTIONS:
        assert any(h.startswith(title) for h in page.headings), (title, page.headings)
    by_id = {f["id"]: f for f in page.figures}
    assert sorted(by_id) == sorted(f"fig-{name}" for name in FIGURES)
    for figure in page.figures:
        assert figure["src"].startswith("data:image/svg+xml;base64,")
        svg = base64.b64decode(figure["src"].split(",", 1)[1]).decode()
        assert svg.lstrip().startswith("<?xml") and "<svg" in svg
        # No external reference inside the figure (namespace declarations are not requests).
        assert not re.search(r'(href|src)="https?:', svg)
        # A caption that says what to look at, not just a title.
        assert "Look for" in figure["caption"] and len(figure["caption"]) > 60


def test_report_has_no_network_reference_and_words_not_reprs(report):
    text = report.read_text()
    assert not re.search(r"https?://", text)
    page = _Page()
    page.feed(text)
    assert all(url.startswith(("data:", "#")) for url in page.urls)
    # Loads and models in words, numbers with units, no Python reprs.
    assert "HarmonicForce(" not in text and "LineModel(" not in text
    assert "harmonic point force of 1 N at 31 Hz, applied at x = 0.7 m" in text
    for explained in ("real-time factor", "vibration reduction", "where it ended"):
        assert explained in text


def test_long_lists_are_summarised():
    from powerline_control.scenario.summary import positions_text as _summarise_positions

    # 90 antinodes 3.3 m apart: one line of count, range and spacing, not 90 numbers.
    line = _summarise_positions([1.65 + 3.3 * i for i in range(90)])
    assert line == "90 positions from 1.65 to 295 m, typically 3.3 m apart"
    assert _summarise_positions([0.5, 1.25]) == "0.5, 1.25 m"


def test_write_report_escapes_text_and_refuses_unembedded_figures(tmp_path):
    fig = Figure()
    fig.add_subplot().plot([0, 1], [1, 0])
    sections = [{"title": "A <b>bold</b> title", "rows": [("x < y", "1 & 2")],
                 "figures": [{"name": "f", "figure": fig, "caption": "Look for the line."}]}]
    text = write_report(tmp_path / "r.html", "T", sections, "9.9").read_text()
    assert "A &lt;b&gt;bold&lt;/b&gt; title" in text and "1 &amp; 2" in text
    assert figure_data_uri(fig) in text
    with pytest.raises(ValueError, match="not embedded"):
        write_report(tmp_path / "s.html", "T", [{"title": "t", "rows": [], "figures": [
            {"name": "g", "uri": "g.png", "caption": "c"}]}])


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def test_report_renders_in_headless_chromium(report, tmp_path):
    browser = _chromium()
    if browser is None:
        if os.environ.get("POWERLINE_CONTROL_REQUIRE_BROWSER") == "1":
            pytest.fail("Chromium is required (POWERLINE_CONTROL_REQUIRE_BROWSER=1) but absent")
        pytest.skip("Chromium is not installed (CI installs it and sets "
                    "POWERLINE_CONTROL_REQUIRE_BROWSER=1)")
    shot = tmp_path / "report.png"
    result = subprocess.run(
        [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
         "--window-size=1200,3000", "--enable-logging=stderr", "--v=0", report.as_uri()],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    # A PNG of the page (its signature, and more than a blank page's few kB).
    data = shot.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 50_000
    # Console errors of the page are logged as 'CONSOLE' lines; failed loads as net errors.
    log = result.stderr
    assert "CONSOLE" not in log and "Uncaught" not in log, log[-2000:]
    assert "ERR_FILE_NOT_FOUND" not in log and "net::ERR" not in log, log[-2000:]


def test_severity_section_when_the_scenario_asks_for_it(tmp_path):
    path = tmp_path / "sev.toml"
    path.write_text("[scenario]\nname = 'sev'\n[span]\npreset = 'conductor'\nlength = 250.0\n"
                    "[model]\nn_elements = 150\n[robot]\nstart = 100.0\n[severity]\n"
                    "enabled = true\nwind_speeds = [1.5, 3.5]\n")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(plc.__file__).parents[1])] + env.get("PYTHONPATH", "").split(os.pathsep))
    result = subprocess.run(COMMAND + ["severity", str(path), "--out", str(tmp_path / "out"),
                                       "-q"], capture_output=True, text=True, env=env,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    page = _Page()
    page.feed((tmp_path / "out" / "report.html").read_text())
    assert any(h.startswith("Aeolian severity") for h in page.headings)
    figure = {f["id"]: f for f in page.figures}["fig-severity"]
    assert figure["src"].startswith("data:image/svg+xml;base64,") and "µε" in figure["caption"]
    # The rows name the wind speeds asked for, with units.
    text = (tmp_path / "out" / "report.html").read_text()
    assert "wind 1.5 m/s" in text and "wind 3.5 m/s" in text and "µε peak-to-peak" in text


def test_pdf_export_or_a_clear_refusal(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.replace("closed_loop = 1.5", "closed_loop = 0"))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(plc.__file__).parents[1])] + env.get("PYTHONPATH", "").split(os.pathsep))
    out = tmp_path / "out"
    result = subprocess.run(COMMAND + ["report", str(path), "--out", str(out), "--pdf", "-q"],
                            capture_output=True, text=True, env=env, timeout=600)
    if _chromium() is None and os.environ.get("POWERLINE_CONTROL_REQUIRE_BROWSER") != "1":
        # Refused before the run, in one line.
        assert result.returncode == 2 and "--pdf needs Chromium" in result.stderr
        assert not out.exists()
        return
    assert result.returncode == 0, result.stderr
    assert (out / "report.pdf").read_bytes()[:5] == b"%PDF-"
