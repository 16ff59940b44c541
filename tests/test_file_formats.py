"""Property tests of every file format the package writes: anything the writer
accepts reads back equal, bit for bit, NaN (a missing sample) included.

Formats: scenario TOML (``scenario_to_toml`` -> ``load_scenario``), record CSV and ``.npz``
(``save_record`` -> ``load_record``), wind record CSV (``WindRecord.to_csv`` -> ``from_csv``).
Model files (``save_model`` -> ``load_model``) have theirs in ``test_reliability.py``
(``test_dmd_model_save_load_round_trip_is_exact``). Examples are few and small: the whole file
runs in a few seconds.
"""

import dataclasses
import datetime

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from strategies import scenarios

from powerline_control import WindRecord
from powerline_control.output.records import Record, load_record, save_record
from powerline_control.scenario import load_scenario, scenario_to_toml

FORMATS = settings(max_examples=30, deadline=None, derandomize=True, database=None,
                   suppress_health_check=[HealthCheck.function_scoped_fixture,
                                          HealthCheck.too_slow])

# Any Unicode text a file can hold: control characters, quotes and backslashes included
# (hypothesis' text() leaves out lone surrogates, which no UTF-8 file holds).
texts = st.text(max_size=30)


@FORMATS
@given(scenario=scenarios(), name=texts, description=texts,
       wind=st.one_of(st.none(), texts.filter(str.strip).map(lambda t: "/data/" + t)))
def test_scenario_toml_round_trips_any_text(scenario, name, description, wind, tmp_path):
    info = dataclasses.replace(scenario.scenario, name=name, description=description)
    scenario = dataclasses.replace(scenario, scenario=info, severity=dataclasses.replace(
        scenario.severity, wind_record=wind))
    text = scenario_to_toml(scenario)
    assert load_scenario(text=text) == scenario
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    assert load_scenario(path) == scenario   # an absolute wind_record stays as written


finite_or_nan = st.one_of(st.just(float("nan")),
                          st.floats(allow_nan=False, allow_infinity=False, width=64))


@st.composite
def records(draw) -> Record:
    """Records of up to 4 channels and 40 samples (fewer than the 50 the saturation check
    judges): any finite values or NaN, positions anywhere, any start time and interval."""
    n_channels, n_t = draw(st.integers(1, 4)), draw(st.integers(2, 40))
    positions = draw(st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=n_channels,
                              max_size=n_channels, unique=True))
    dt = draw(st.floats(1e-6, 10.0))
    t = draw(st.floats(-1e3, 1e3)) + dt * np.arange(n_t)
    values = np.array(draw(st.lists(finite_or_nan, min_size=n_channels * n_t,
                                    max_size=n_channels * n_t))).reshape(n_channels, n_t)
    truth = np.nan_to_num(values) if draw(st.booleans()) else None
    return Record(t, positions, values, "drawn", truth)


@FORMATS
@given(record=records())
def test_record_csv_and_npz_round_trip_bit_exact(record, tmp_path):
    npz, csv = save_record(tmp_path / "rec", record)
    for path in (npz, csv):
        back = load_record(path)
        np.testing.assert_array_equal(back.t, record.t)          # equal_nan: NaN stays NaN
        np.testing.assert_array_equal(back.positions, record.positions)
        np.testing.assert_array_equal(back.values, record.values)
        assert back.dt == record.dt
    # the exact file keeps what CSV (for a spreadsheet) has no column for
    back = load_record(npz)
    if record.truth is None:
        assert back.truth is None
    else:
        np.testing.assert_array_equal(back.truth, record.truth)


def _column(low: float, high: float, n: int) -> st.SearchStrategy:
    return st.lists(st.floats(low, high), min_size=n, max_size=n)


@st.composite
def wind_records(draw) -> WindRecord:
    n = draw(st.integers(1, 12))
    step = draw(st.sampled_from([60.0, 600.0, 3600.0, 1.0 / 3.0]))
    stamp = draw(st.one_of(st.just(""), st.datetimes(
        datetime.datetime(1990, 1, 1), datetime.datetime(2100, 1, 1)).map(
        lambda d: d.isoformat())))
    turbulence = draw(st.one_of(st.none(), _column(0.0, 1.0, n)))
    return WindRecord(np.arange(n) * step, np.array(draw(_column(0.0, 50.0, n))),
                      np.array(draw(_column(0.0, 360.0, n))),
                      np.array(draw(_column(-50.0, 80.0, n))),
                      None if turbulence is None else np.array(turbulence), start=stamp,
                      interval=step if n == 1 else None)


@FORMATS
@given(record=wind_records())
def test_wind_record_csv_round_trips_bit_exact(record, tmp_path):
    path = tmp_path / "wind.csv"
    record.to_csv(path)
    back = WindRecord.from_csv(path)
    for name in ("time", "wind_speed", "direction", "temperature", "turbulence_intensity"):
        want, got = getattr(record, name), getattr(back, name)
        if want is None:
            assert got is None
        else:
            np.testing.assert_array_equal(got, want)
    assert (back.start, back.step, back.n_records) == (record.start, record.step,
                                                       record.n_records)
