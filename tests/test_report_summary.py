"""The report's first screen: the summary's numbers are the result's own fields, its
links reach the sections they name, its caveats appear exactly when the result has them; every
row of every section is explained; the JSON says whether the closed loop's headline is steady.

All on the session's small lab result (tests/conftest.py); no figure is drawn.
"""

import html.parser
import json

import numpy as np
import pytest

from powerline_control.output.report import write_report
from powerline_control.scenario.summary import SECTION_IDS, result_sections
from powerline_control.scenario.summary_verdict import result_verdict


@pytest.fixture(scope="module")
def verdict(lab_result):
    return result_verdict(lab_result)


@pytest.fixture(scope="module")
def headlines(verdict):
    return {h.label: h for h in verdict.headlines}


def test_the_estimation_numbers_are_the_layouts_own(lab_result, headlines):
    errors = {n: lay.error_unmeasured_percent for n, lay in lab_result.layouts.items()}
    chosen = headlines["estimation error, chosen sensors"]
    assert chosen.value == errors["chosen"] and chosen.section == "estimation"
    # The best baseline by hand: the lowest error of the other layouts, over the chosen one's.
    best = min(errors[n] for n in errors if n != "chosen")
    assert headlines["against the best baseline"].value == pytest.approx(
        best / errors["chosen"], rel=1e-15)


def test_the_robot_numbers_are_its_comparisons_ratios(lab_result, headlines):
    res = lab_result.closed_loop.result
    rms = {c.name: c.rms for c in res.comparisons}
    for name, label in (("no_robot", "robot against no robot"),
                        ("start", "robot against its start"),
                        ("near_clamp", "robot against a damper near the clamp")):
        line = headlines[label]
        assert line.value == pytest.approx(rms[name] / rms["closed_loop"], rel=1e-15)
        assert line.section == "closed-loop"
        assert f"{line.value:.2f}x" in line.text or f"{1 / line.value:.2f}x" in line.text
    # Against its start is the result's own headline number.
    assert headlines["robot against its start"].value == pytest.approx(
        res.vibration_reduction, rel=1e-15)


def test_the_severity_number_is_the_worst_bare_strain(lab_result, headlines):
    bare = lab_result.severity.bare
    line = headlines["severity: worst clamp strain, no damper"]
    assert line.value == pytest.approx(1e6 * float(np.max(bare.strain_pp)), rel=1e-15)
    # The lab conductor is AAC (assumed: the catalogue conductor Table 1 matches), so its strain
    # is not judged against ACSR's endurance strain, and the verdict says why.
    assert lab_result.severity.endurance_applies is False
    assert "ABOVE" not in line.verdict and "below the" not in line.verdict
    assert "not judged" in line.verdict and "ACSR's (this conductor is AAC)" in line.verdict


def test_the_endurance_line_is_drawn_only_for_its_family(lab_result):
    import powerline_control as plc
    from powerline_control.severity import ENDURANCE_FAMILY

    assert ENDURANCE_FAMILY == "ACSR"
    assert {n: c.family for n, c in plc.conductors.items()} == {
        "drake": "ACSR", "condor": "ACSR", "cardinal": "ACSR", "aster570": "AAAC",
        "oxlip": "AAC"}
    assert plc.Span.paper_lab().conductor.family == "AAC"
    section = next(s for s in result_sections(lab_result) if s["id"] == "severity")
    figure = section["figures"][0]["draw"]()
    labels = [line.get_label() for ax in figure.axes for line in ax.get_lines()]
    assert "endurance limit" not in labels                      # AAC: no ACSR line drawn
    assert section["notes"][0].startswith("No endurance line is drawn")
    rows = {row[0]: row for row in section["rows"]}
    # What it assumed, said where the numbers are.
    assert rows["outer strand diameter"][2].startswith("from assumed: the stranding of 'oxlip'")
    assert rows["assumed"][1] == "; ".join(lab_result.severity.assumptions)
    assert all("not judged" in row[2] for label, row in rows.items()
               if label.startswith("wind ") and "no vibration" not in row[2])


def test_caveats_appear_exactly_when_the_result_has_them(lab_result, verdict):
    res = lab_result.closed_loop.result
    errors = {n: lay.error_unmeasured_percent for n, lay in lab_result.layouts.items()}
    texts = " | ".join(c.text for c in verdict.caveats)
    expected = {
        "A baseline beats the optimised layout": min(
            errors[n] for n in errors if n != "chosen") < errors["chosen"],
        "had not settled": not res.settled,
        "still rings": any(c.transient for c in res.comparisons),
        "estimator was flagged INCONSISTENT": not res.estimator_consistency.consistent,
        "rest on assumed conductor data": bool(lab_result.severity.assumptions),
    }
    for phrase, present in expected.items():
        assert (phrase in texts) == present, (phrase, texts)


class _Links(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links, self.summary_links = set(), [], []
        self._in_summary = 0
        self.summary_text = ""

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        if tag == "section":
            self._in_summary = 1 if attrs.get("id") == "summary" else 0
        if tag == "a" and attrs.get("href", "").startswith("#"):
            (self.summary_links if self._in_summary else self.links).append(attrs["href"][1:])

    def handle_endtag(self, tag):
        if tag == "section":
            self._in_summary = 0

    def handle_data(self, data):
        if self._in_summary:
            self.summary_text += data


def test_the_summary_opens_the_page_and_its_links_reach_their_sections(lab_result, verdict,
                                                                         tmp_path):
    sections = [{**s, "figures": []} for s in result_sections(lab_result)]   # no drawing
    path = write_report(tmp_path / "r.html", "T", sections, summary=verdict.to_report())
    text = path.read_text()
    page = _Links()
    page.feed(text)
    # First after the header, before the table of contents and the sections.
    assert text.index('id="summary"') < text.index("<nav>") < text.index('id="span"')
    assert page.summary_links and set(page.summary_links) <= page.ids
    assert set(page.links) <= page.ids                        # the table of contents too
    expected = {h.section for h in verdict.headlines} | {c.section for c in verdict.caveats}
    assert set(page.summary_links) == expected
    # Every number and caveat of the verdict is on the page, as the verdict words it.
    flat = " ".join(page.summary_text.split())
    for line in verdict.headlines:
        assert line.text in flat and " ".join(line.verdict.split()) in flat
    for caveat in verdict.caveats:
        assert " ".join(caveat.text.split()) in flat


def test_a_summary_link_to_no_section_is_refused(tmp_path):
    summary = {"span": "s", "asked": "a", "rows": [("x", "1", "v", "nowhere")], "caveats": []}
    with pytest.raises(ValueError, match="nowhere"):
        write_report(tmp_path / "r.html", "T", [{"title": "A", "id": "a", "rows": []}],
                     summary=summary)
    assert not (tmp_path / "r.html").exists()


def test_section_ids_are_the_ones_the_summary_links_to(lab_result):
    ids = [s["id"] for s in result_sections(lab_result)]
    assert len(ids) == len(set(ids)) and set(ids) <= set(SECTION_IDS.values())


def test_every_row_of_every_section_is_explained(lab_result):
    for section in result_sections(lab_result):
        for row in section["rows"]:
            assert len(row) == 3 and str(row[2]).strip(), (section["title"], row[0])


def test_the_json_says_whether_the_headline_is_steady(lab_result):
    data = lab_result.to_dict()
    json.dumps(data, allow_nan=False)                        # strict JSON: no NaN
    res = lab_result.closed_loop.result
    closed = res.comparison("closed_loop")
    assert data["settled"] is bool(res.settled)
    assert data["steady_state"] is bool(closed.steady)
    assert data["still_ringing"] is bool(closed.transient)
    assert data["best_position_m"] == res.best_position
    # run gives the closed loop the optimised sensors, and says so.
    assert data["closed_loop_sensor_nodes"] == data["sensor_nodes"]
    assert data["closed_loop_sensors_how"].startswith("the estimator's sensors, optimised")


# ---------------------------------------------------------------- figures on a long span

def test_the_emphasised_layout_and_eigenvalues_are_drawn_on_top():
    from powerline_control.output.plotting import plot_eigenvalues, plot_error_along_span

    many = np.exp(1j * np.linspace(0.0, 3.0, 300))
    fig = plot_eigenvalues({"plain": many, "model": many[::10]}, emphasis="model")
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    assert lines["model"].get_zorder() > lines["plain"].get_zorder()
    assert lines["model"].get_markersize() > lines["plain"].get_markersize()
    x = np.linspace(0.0, 300.0, 301)
    errors = {name: np.full(301, 0.01) for name in ("chosen", "evenly spaced (5)", "first 13")}
    lines = {ln.get_label(): ln for ln in
             plot_error_along_span(x, errors, [10.0], chosen="chosen").axes[0].get_lines()}
    assert lines["chosen"].get_zorder() > max(lines[n].get_zorder() for n in errors
                                               if n != "chosen")
    assert lines["chosen"].get_linewidth() > lines["first 13"].get_linewidth()


def test_the_layout_bars_say_the_tables_numbers(lab_result):
    from powerline_control.output.plotting import plot_layouts

    errors = {n: lay.error_unmeasured_percent for n, lay in lab_result.layouts.items()}
    positions = {n: list(lay.positions) for n, lay in lab_result.layouts.items()}
    fig = plot_layouts(errors, positions, 3.66)
    shown = [text.get_text() for text in fig.axes[0].texts]
    # the estimation table's own wording of each error (summary.py: ":.3g} % of the RMS")
    assert shown == [f"{v:.3g} %" for v in errors.values()]
    low, high = fig.axes[1].get_xlim()
    assert low < 0.0 and high > 3.66          # a sensor at a support is inside the frame


def test_the_closed_loop_legend_names_the_target_for_what_it_is():
    from types import SimpleNamespace

    from powerline_control.output.plotting import plot_closed_loop

    t = np.linspace(0.0, 1.0, 101)
    fake = SimpleNamespace(t=t, robot_position=t, target=t, calibration_time=0.2,
                           displacement=np.ones((3, 101)), baseline_displacement=np.ones((3, 101)))
    labels = [tx.get_text() for tx in plot_closed_loop(fake).axes[0].get_legend().get_texts()]
    # the policy's target is the predicted best parked position, not an antinode
    assert "target (best parked position predicted)" in labels
    assert not any("antinode" in label for label in labels)


def test_a_short_move_on_a_long_span_gets_an_inset_zoomed_on_it():
    from types import SimpleNamespace

    from powerline_control.output.plotting import plot_closed_loop_path

    t = np.linspace(0.0, 3.0, 301)
    x = np.linspace(0.0, 300.0, 61)
    path = 150.5 - 0.7 * np.clip(t - 1.0, 0.0, 1.0)        # a 0.7 m move on a 300 m span
    fake = SimpleNamespace(t=t, x=x, displacement=np.ones((61, 301)), robot_position=path,
                           target=np.full(301, 149.8), retarget_times=(1.0,),
                           calibration_time=0.5, loop_length=3.3)
    ax = plot_closed_loop_path(fake).axes[0]
    (inset,) = ax.child_axes
    low, high = inset.get_xlim()
    assert low < 149.8 and high > 150.5 and high - low < 0.05 * 300.0
    # the retarget line is in the legend, in a colour the legend's white face shows
    assert "new target chosen" in [tx.get_text() for tx in ax.get_legend().get_texts()]
    # a move a fifth of the span long needs no zoom
    wide = SimpleNamespace(**{**vars(fake), "robot_position": np.linspace(100.0, 160.0, 301),
                              "target": np.full(301, 160.0)})
    assert not plot_closed_loop_path(wide).axes[0].child_axes


def test_the_rms_curves_are_over_full_windows_only():
    from types import SimpleNamespace

    from powerline_control.output.plotting import plot_closed_loop

    t = np.arange(0.0, 1.0, 1e-3)
    field = np.tile(np.sin(2 * np.pi * 19.7 * t), (3, 1))     # a window end cuts a period
    fake = SimpleNamespace(t=t, robot_position=t, target=t, calibration_time=0.2,
                           displacement=field, baseline_displacement=field)
    for line in plot_closed_loop(fake).axes[1].get_lines():
        times, rms = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
        assert times[0] > t[0] and times[-1] < t[-1]          # no window cut short at an end
        # two periods of 19.7 Hz in a 0.1 s window: within 3 % of 1/sqrt(2) everywhere
        assert rms == pytest.approx(1e3 / np.sqrt(2), rel=0.03)


def test_a_block_of_sensors_on_a_long_span_is_labelled():
    from powerline_control.output.plotting import plot_layouts

    first = [0.25 * i for i in range(13)]                    # the paper's 13 nodes of 300 m
    fig = plot_layouts({"chosen": 2.86, "first 13": 21.6},
                       {"chosen": [70.0, 120.0, 265.0], "first 13": first}, 300.0)
    assert [tx.get_text() for tx in fig.axes[1].texts] == ["13 sensors, 0-3 m"]
