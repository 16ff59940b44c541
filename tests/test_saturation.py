"""Bad input: a sensor that saturates (a channel clipped at its range) is named where
measured data enter: design_estimator's training record, KalmanFilter.filter's measurements,
load_record and the command's ``estimate --record``.

Independent truth: the records are clipped here by ``np.clip`` at a known level (60 % of the
channel's peak), so which channel and which level must be named is known before the code runs;
unclipped noisy records (FE simulations, 20 seeds of a harmonic and of a random load) must never
warn: a continuous noisy signal reaches its extreme in one sample.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from cli_support import TINY, run_cli

import powerline_control as plc
from powerline_control._validation import warn_if_saturated
from powerline_control.errors import SaturationWarning
from powerline_control.output.records import Record, load_record, save_record

NODE = 7  # a moving interior node of the 20-element span (x = 1.281 m)


@pytest.fixture(scope="module")
def lab():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    snap = plc.simulate(model, plc.HarmonicForce(1.0, 18.3, 1.6), duration=4.0, dt=1e-3,
                        noise_fraction=0.01, seed=3)
    return model, snap


def _clipped(x, fraction=0.6):
    """``x`` clipped at +-fraction of its peak |x|, and the level."""
    level = fraction * np.abs(x).max()
    return np.clip(x, -level, level), level


def _saturation(caught):
    return [str(w.message) for w in caught if issubclass(w.category, SaturationWarning)]


def test_a_clipped_training_node_is_named_with_its_level_and_share(lab):
    model, snap = lab
    X = np.array(snap.displacement)
    X[NODE], level = _clipped(X[NODE])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plc.design_estimator(X, dt=snap.dt, positions=snap.x, n_sensors=3, seed=0)
    messages = _saturation(caught)
    # Both clip levels of the one clipped node, and nothing else (the held-out filter runs of
    # the recipe do not repeat it).
    assert len(messages) == 2, messages
    x = f"{snap.x[NODE]:.6g}"
    for sign, message in zip(("-", ""), sorted(messages, key=lambda m: "-" not in m),
                             strict=True):
        assert message.startswith(f"The 'snapshots' parameter: node {NODE} (x = {x} m) is "
                                  f"clipped at {sign}{level:.6g} m")
        share = float(re.search(r"m: ([0-9.]+)% of its samples", message).group(1)) / 100
        # The share is the count of samples at the level, counted here independently.
        at = np.count_nonzero(X[NODE] == float(f"{sign}1") * level) / X.shape[1]
        assert share == pytest.approx(at, abs=1e-3)


def test_a_clipped_measurement_row_warns_in_the_filter_and_the_unclipped_does_not(lab):
    _, snap = lab
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.ExcitationWarning)  # a harmonic record: named
        design = plc.design_estimator(snap, n_sensors=3, seed=0)
    y = np.array(snap.displacement[design.sensors])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        design.filter.filter(y)
    assert _saturation(caught) == []
    y[1], level = _clipped(y[1])
    with pytest.warns(SaturationWarning) as caught:
        design.filter.filter(y)
    starts = sorted(m.split(" m:")[0] for m in _saturation(caught))
    assert starts == [f"The 'measurements' parameter: row 1 is clipped at {sign}{level:.6g}"
                      for sign in ("-", "")]


@pytest.mark.parametrize("kind", ["harmonic", "random"])
def test_twenty_unclipped_noisy_records_never_warn(kind):
    """False alarms: 20 seeds x 21 nodes of each load (the two supports read noise only)."""
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    for seed in range(20):
        force = (plc.HarmonicForce(1.0, 12.0 + seed, 0.4 + 0.14 * seed) if kind == "harmonic"
                 else plc.RandomForce(1.0, 1.3, 90.0, seed=seed))
        snap = plc.simulate(model, force, duration=4.0, dt=1e-3, noise_fraction=0.01,
                            seed=100 + seed)
        assert warn_if_saturated("The 'snapshots' parameter", snap.displacement) == []


def test_the_rule_judges_flat_tops_not_quantisation_rest_or_short_rows():
    rng = np.random.default_rng(0)
    t = np.arange(4000) * 1e-3
    y = 1e-3 * np.sin(2 * np.pi * 6.5 * t) + 1e-5 * rng.standard_normal(t.size)
    # A clean sine through an 8-bit logger (quantum 1/256 of the range): about 3 % of the
    # samples sit on the top level, but the level below fills alike (no pile-up: no clip).
    q = 2e-3 / 256
    quantised = np.round(1e-3 * np.sin(2 * np.pi * 6.5 * t) / q) * q
    assert np.count_nonzero(quantised == quantised.max()) > 0.02 * t.size
    at_rest = np.concatenate([np.zeros(300), np.abs(y[300:])])  # exact zeros: rest, not a clip
    constant = np.full(t.size, 2e-4)                             # not judged (no extreme)
    short = np.clip(y[:40], -5e-4, 5e-4)                          # under 50 samples: not judged
    assert warn_if_saturated("x", np.vstack([y, quantised, at_rest, constant])) == []
    assert warn_if_saturated("x", short) == []
    # Clipped at 99 % of the peak: still named (about 4.5 % of a sine's samples per level).
    with pytest.warns(SaturationWarning):
        found = warn_if_saturated("x", np.clip(y, -0.99e-3, 0.99e-3))
    assert [row for row, _, _ in found] == [0, 0]
    assert all(0.02 < share < 0.1 for _, _, share in found)


def test_a_clipped_csv_channel_warns_through_load_record(lab, tmp_path):
    _, snap = lab
    rows = [4, NODE, 12]
    values = np.array(snap.displacement[rows])
    values[1], level = _clipped(values[1])
    with pytest.warns(SaturationWarning):        # a Record judges its channels when made
        save_record(tmp_path / "field", Record(snap.t, snap.x[rows], values, "field"))
    column = f"x_{snap.x[NODE]:.10g}_m"
    with pytest.warns(SaturationWarning) as caught:
        record = load_record(tmp_path / "field.csv")
    starts = sorted(str(w.message).split(" m:")[0] for w in caught)
    assert starts == [f"{tmp_path / 'field.csv'}: column {column} (channel 1, at "
                      f"{snap.x[NODE]:g} m) is clipped at {sign}{level:.6g}" for sign in ("-", "")]
    assert np.array_equal(record.values, values)  # warned, not changed


def test_the_command_prints_the_warning_and_still_exits_0(tmp_path):
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(TINY)
    result = run_cli("simulate", scenario, "--out", tmp_path / "sim", "-q")
    assert result.returncode == 0, result.stderr
    rec = load_record(tmp_path / "sim" / "record.npz").without_supports(3.66)
    values = np.array(rec.values)
    values[4], level = _clipped(values[4])
    with pytest.warns(SaturationWarning):        # a Record judges its channels when made
        clipped = Record(rec.t, rec.positions, values, "field")
    save_record(tmp_path / "field", clipped)
    result = run_cli("estimate", scenario, "--record", tmp_path / "field.csv")
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stderr.splitlines() if "SaturationWarning" in line]
    column = f"x_{rec.positions[4]:.10g}_m"
    named = [line for line in lines if f"column {column}" in line]
    # once per clip level (top and bottom), by its column; the filter does not repeat it
    assert len(named) == len(lines) == 2, lines
    assert all(line.startswith("powerline-control: warning: SaturationWarning: ")
               for line in lines)
    assert any(f"clipped at {level:.6g} m" in line for line in named)
    assert "Traceback" not in result.stderr


def test_two_channels_at_one_position_are_refused_naming_it(tmp_path):
    """Duplicated sensors: the command's estimate once kept the first of two channels at
    one position and dropped the other without a word."""
    t = np.arange(100) * 1e-3
    y = 1e-3 * np.sin(2 * np.pi * 12 * t)
    with pytest.raises(plc.InputError, match=r"'positions' parameter names 1\.22 m \(column "
                                             r"x_1\.22_m\) 2 times"):
        Record(t, [1.22, 2.0, 1.22], np.vstack([y, y, y]), "f.csv")
    path = tmp_path / "dup.csv"
    path.write_text("time_s,x_1.22_m,x_1.22_mm\n" + "".join(
        f"{k / 1000!r},{float(v)!r},{float(v) * 1e3!r}\n" for k, v in enumerate(y)))
    with pytest.raises(plc.InputError, match=r"dup\.csv: the 'positions' parameter names 1\.22 m"):
        load_record(path)


def test_a_constant_channel_inside_the_span_is_refused_by_the_command(tmp_path):
    """Constant channels: the command's estimate once ran a dead sensor (one value in
    every sample) as if it measured the line, and said only 'consistent: false'."""
    t = np.arange(100) * 1e-3
    rec = Record(t, [1.0, 2.0], np.vstack([1e-3 * np.sin(2 * np.pi * 12 * t),
                                           np.full(t.size, 2e-4)]), "f.csv")
    with pytest.raises(plc.InputError, match=r"f\.csv: channel x_2_m at 2 m holds one value "
                                             r"\(0\.0002 m\) in all its 100 samples"):
        rec.check_span(3.66)
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(TINY)
    path = tmp_path / "dead.csv"
    path.write_text("time_s,x_1_m,x_2_m\n" + "".join(
        f"{k / 1000!r},{1e-3 * np.sin(k / 10):.6g},0\n" for k in range(2500)))
    result = run_cli("estimate", scenario, "--record", path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "x_2_m at 2 m holds one value (0 m) in all its 2500" in lines[0]


def test_dropping_the_support_channels_does_not_judge_the_record_again(lab):
    """A record of every node (supports included) with one clipped channel warns once per clip
    level when it is made; its channels without the supports are the same, with no new warning."""
    _, snap = lab
    values = np.array(snap.displacement)
    values[NODE], _ = _clipped(values[NODE])
    with pytest.warns(SaturationWarning) as caught:
        record = Record(snap.t, snap.x, values, "field")
    assert len(_saturation(caught)) == 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        inner = record.without_supports(float(snap.x[-1]))
    assert inner.support_positions == (float(snap.x[0]), float(snap.x[-1]))
    np.testing.assert_array_equal(inner.values, values[1:-1])
    np.testing.assert_array_equal(inner.positions, snap.x[1:-1])
    assert inner.n_missing == 0 and record.values.shape[0] == inner.values.shape[0] + 2


def test_design_estimator_refuses_a_stuck_node_naming_it(lab):
    """A node of the training record that keeps one non-zero value (a stuck sensor at an offset)
    has a large RMS, so the motion floor kept it as a candidate, and its offset entered the
    basis as a mode no other node sees (at 2e-2 m the recipe ended in "a mode on or outside the
    unit circle is unobservable"). Refused, named, at any offset; a support's zero row is not."""
    _, snap = lab
    for offset in (2e-3, 2e-2, -1e-9):
        values = np.array(snap.displacement)
        values[NODE] = offset
        with pytest.raises(plc.InputError, match=rf"node\(s\) \[{NODE}\] keep one non-zero "
                                                 rf"value in every sample \(node {NODE}: "):
            plc.design_estimator(values, 3, dt=snap.dt, seed=0)
    values = np.array(snap.true_displacement)   # noise-free: the supports' rows are zeros
    assert not np.any(values[0]) and not np.any(values[-1])
    assert plc.design_estimator(values, 3, dt=snap.dt, seed=0).sensors.size == 3


def test_a_record_shorter_than_the_delays_need_names_the_record_not_a_default(lab):
    """30 samples with the default delays: the error says the record is too short (it used to
    say "'delays' must be <= 7", a parameter the user never gave), before any embedding; the
    parts' lengths are what the rule counts (one home for it, where the arguments are read)."""
    _, snap = lab
    values = np.array(snap.displacement)[:, :30]
    with pytest.raises(plc.InputError, match=r"record of 30 samples is too short for delays=8 "
                                             r"with train_fraction=0.7: its training and "
                                             r"held-out parts \(21 and 9 samples\) need at least "
                                             r"32 each"):
        plc.design_estimator(values, 3, dt=snap.dt)
    # the held-out part (30 % of 100 = 30 samples) is what falls short, not the record
    with pytest.raises(plc.InputError, match=r"\(70 and 30 samples\) need at least 32"):
        plc.design_estimator(np.array(snap.displacement)[:, :100], 3, dt=snap.dt)
    with pytest.raises(plc.InputError, match=r"record of 4001 samples is too short for "
                                             r"delays=2000 .* need at least 8000"):
        plc.design_estimator(np.array(snap.displacement), 3, dt=snap.dt, delays=2000)
