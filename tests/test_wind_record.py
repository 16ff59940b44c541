"""WindRecord: reading a CSV record and refusing bad rows with the column and row named."""

import math

import numpy as np
import pytest

import powerline_control as plc

HEADER = "time,wind_speed,direction,temperature"
GOOD = [(0, 3.1, 270, 12.0), (600, 2.8, 265, 11.6), (1200, 4.0, 250, 11.0)]


def _write(tmp_path, rows, header=HEADER, name="wind.csv"):
    path = tmp_path / name
    lines = [header] + [",".join(str(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_reads_seconds_and_values(tmp_path):
    rec = plc.WindRecord.from_csv(_write(tmp_path, GOOD))
    np.testing.assert_array_equal(rec.time, [0.0, 600.0, 1200.0])
    np.testing.assert_array_equal(rec.wind_speed, [3.1, 2.8, 4.0])
    assert rec.step == 600.0 and rec.duration == 1800.0 and rec.turbulence_intensity is None
    assert not rec.wind_speed.flags.writeable


def test_reads_iso_time_stamps_any_column_order_and_turbulence(tmp_path):
    header = "Temperature, Direction ,time,wind_speed,turbulence_intensity,station"
    rows = [(10.0, 90, "2024-03-01T00:00:00", 2.0, 0.05, "A"),
            (9.5, 95, "2024-03-01T01:00:00", 2.5, 0.08, "A")]
    rec = plc.WindRecord.from_csv(_write(tmp_path, rows, header))
    np.testing.assert_array_equal(rec.time, [0.0, 3600.0])
    np.testing.assert_array_equal(rec.temperature, [10.0, 9.5])
    np.testing.assert_array_equal(rec.turbulence_intensity, [0.05, 0.08])
    assert rec.start == "2024-03-01T00:00:00"


def test_round_trip_through_to_csv(tmp_path):
    rec = plc.WindRecord.constant(3.3, n_records=5, direction=40.0, temperature=-3.0,
                                  turbulence_intensity=0.1)
    rec.to_csv(tmp_path / "r.csv")
    back = plc.WindRecord.from_csv(tmp_path / "r.csv")
    for name in ("time", "wind_speed", "direction", "temperature", "turbulence_intensity"):
        np.testing.assert_array_equal(getattr(back, name), getattr(rec, name))


def test_normal_component():
    rec = plc.WindRecord(np.array([0.0, 1.0, 2.0]), np.array([4.0, 4.0, 4.0]),
                         np.array([0.0, 90.0, 210.0]), np.zeros(3))
    # sin of 0, 90 and 180 + 30 degrees to a north-south line
    np.testing.assert_allclose(rec.normal_speed(0.0), [0.0, 4.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(rec.normal_speed(180.0), rec.normal_speed(0.0), atol=1e-12)


# Each bad file names the column and the data row (0-based) and the file line.
@pytest.mark.parametrize("rows, column, row", [
    ([(0, 3.1, 270, 12.0), (600, -0.5, 265, 11.6)], "wind_speed", 1),
    ([(0, 3.1, 270, 12.0), (600, 50.5, 265, 11.6)], "wind_speed", 1),
    ([(0, 3.1, 270, 12.0), (600, 3.0, 265, 81.0)], "temperature", 1),
    ([(0, 3.1, 270, -50.1), (600, 3.0, 265, 10.0)], "temperature", 0),
    ([(0, 3.1, 370, 12.0)], "direction", 0),
    ([(0, 3.1, 270, 12.0), (600, "", 265, 11.6)], "wind_speed", 1),
    ([(0, 3.1, 270, 12.0), (600, "calm", 265, 11.6)], "wind_speed", 1),
    ([(0, 3.1, 270, 12.0), (600, "nan", 265, 11.6)], "wind_speed", 1),
    ([(0, 3.1, 270, 12.0), (600, 2.0, 265)], "temperature", 1),
])
def test_bad_values_name_column_and_row(tmp_path, rows, column, row):
    with pytest.raises(plc.InputError, match=rf"'{column}'.*row {row} \(line {row + 2}\)"):
        plc.WindRecord.from_csv(_write(tmp_path, rows))


def test_non_monotonic_time_names_the_row(tmp_path):
    rows = [(0, 3, 90, 10), (600, 3, 90, 10), (1200, 3, 90, 10), (1100, 3, 90, 10)]
    with pytest.raises(plc.InputError, match=r"'time'.*increase.*row 3 \(line 5\)"):
        plc.WindRecord.from_csv(_write(tmp_path, rows))
    rows[3] = (1200, 3, 90, 10)           # a repeated time stamp
    with pytest.raises(plc.InputError, match=r"'time'.*row 3"):
        plc.WindRecord.from_csv(_write(tmp_path, rows))


def test_a_gap_names_the_row(tmp_path):
    rows = [(0, 3, 90, 10), (600, 3, 90, 10), (1200, 3, 90, 10), (3000, 3, 90, 10),
            (3600, 3, 90, 10)]
    with pytest.raises(plc.InputError, match=r"gap.*row 3 \(line 5\).*1800 s"):
        plc.WindRecord.from_csv(_write(tmp_path, rows))


def test_a_missing_column_is_named(tmp_path):
    path = _write(tmp_path, [(0, 3.1, 12.0)], header="time,wind_speed,temperature")
    with pytest.raises(plc.InputError, match="no column 'direction'"):
        plc.WindRecord.from_csv(path)


def test_an_empty_file_a_missing_file_and_a_bad_stamp(tmp_path):
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(plc.InputError, match="empty"):
        plc.WindRecord.from_csv(tmp_path / "empty.csv")
    with pytest.raises(plc.InputError, match="does not exist"):
        plc.WindRecord.from_csv(tmp_path / "absent.csv")
    with pytest.raises(plc.InputError, match=r"'time'.*ISO 8601.*row 1"):
        plc.WindRecord.from_csv(_write(tmp_path, [(0, 3, 90, 10), ("noon", 3, 90, 10)]))


@pytest.mark.parametrize("column, value", [
    ("wind_speed", math.inf), ("wind_speed", -1.0), ("temperature", 90.0),
    ("turbulence_intensity", 1.5), ("direction", -10.0)])
def test_the_constructor_checks_the_same_way(column, value):
    base = dict(time=np.array([0.0, 600.0]), wind_speed=np.array([3.0, 3.0]),
                direction=np.array([90.0, 90.0]), temperature=np.array([10.0, 10.0]),
                turbulence_intensity=np.array([0.1, 0.1]))
    base[column] = np.array([base[column][0], value])
    with pytest.raises(plc.InputError, match=rf"'{column}'.*row 1"):
        plc.WindRecord(**base)


def test_columns_of_the_wrong_length_or_type_are_refused():
    with pytest.raises(plc.InputError, match="one value per record"):
        plc.WindRecord(np.array([0.0, 1.0]), np.array([3.0]), np.array([1.0, 1.0]),
                       np.array([1.0, 1.0]))
    with pytest.raises(plc.InputError, match="real numbers"):
        plc.WindRecord(np.array([0.0, 1.0]), np.array([True, False]), np.array([1.0, 1.0]),
                       np.array([1.0, 1.0]))


def test_the_shipped_example_record_is_what_its_seeded_script_makes():
    import importlib.util
    import pathlib

    examples = pathlib.Path(__file__).resolve().parents[1] / "examples"
    spec = importlib.util.spec_from_file_location("make_wind_record",
                                                  examples / "make_wind_record.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    made = script.make_record()
    shipped = plc.WindRecord.from_csv(examples / "data" / "wind_record_28d.csv")
    for name in ("time", "wind_speed", "direction", "temperature", "turbulence_intensity"):
        # the file holds the generator's rounded values, written with 10 significant digits
        np.testing.assert_allclose(getattr(shipped, name), getattr(made, name), rtol=1e-12,
                                   atol=1e-12)
    # the documented model: Weibull-like speeds around c = 4 m/s, a diurnal temperature cycle
    assert 2.5 < shipped.wind_speed.mean() < 4.5 and shipped.n_records == 4032
    hour = (shipped.time / 3600) % 24
    assert shipped.temperature[(hour > 13) & (hour < 17)].mean() > \
        shipped.temperature[(hour > 1) & (hour < 5)].mean() + 6


def test_synthetic_is_reproducible_and_refuses_bad_arguments():
    a = plc.WindRecord.synthetic(days=1.0, seed=5)
    b = plc.WindRecord.synthetic(days=1.0, seed=5)
    np.testing.assert_array_equal(a.wind_speed, b.wind_speed)
    assert not np.array_equal(a.wind_speed, plc.WindRecord.synthetic(days=1.0, seed=6).wind_speed)
    for kwargs in (dict(days=0.0), dict(step=-1.0), dict(diurnal=1.5), dict(shape=math.nan)):
        with pytest.raises(plc.InputError):
            plc.WindRecord.synthetic(**kwargs)


def test_paths_that_are_not_csv_files_are_refused_naming_path(tmp_path):
    import os

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    binary = tmp_path / "blob.csv"
    binary.write_bytes(b"\xff\xfe\x00\x81" * 50)
    for path in (fifo, tmp_path, binary, ""):
        with pytest.raises(plc.InputError, match="'path'"):
            plc.WindRecord.from_csv(path)
    with pytest.raises(plc.InputError, match="'path'"):
        plc.WindRecord.from_csv(3.0)


def test_start_and_source_are_strings_and_start_a_time_stamp():
    args = (np.array([0.0, 600.0]), np.ones(2), np.ones(2), np.ones(2))
    for bad in (dict(start=None), dict(source=3), dict(start="yesterday")):
        with pytest.raises(plc.InputError, match="'start'|'source'"):
            plc.WindRecord(*args, **bad)
    assert plc.WindRecord(*args, start="2024-01-01T00:00:00").start == "2024-01-01T00:00:00"
    with pytest.raises(plc.InputError, match="'time'"):
        plc.WindRecord(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0))


# ------------------------------------------------------------------------ files and preconditions
def test_to_csv_keeps_every_bit_and_the_start_time_stamp(tmp_path):
    path = tmp_path / "wind.csv"
    rows = ["time,wind_speed,direction,temperature,turbulence_intensity",
            "2024-03-01T00:00:00,0.3333333333333333,1.0979999999999999,12.1,0.1",
            "2024-03-01T00:10:00,2.0,265.0,11.6,0.2"]
    path.write_text("\n".join(rows) + "\n")
    record = plc.WindRecord.from_csv(path)
    assert record.start == "2024-03-01T00:00:00"
    out = tmp_path / "out.csv"
    record.to_csv(out)
    back = plc.WindRecord.from_csv(out)
    assert back.start == "2024-03-01T00:00:00"
    assert back.wind_speed.tolist() == [1 / 3, 2.0]           # not 0.3333333333
    assert back.direction.tolist() == [1.0979999999999999, 265.0]
    assert back.turbulence_intensity.tolist() == [0.1, 0.2]
    assert back.time.tolist() == [0.0, 600.0]


def test_a_spreadsheets_csv_is_read(tmp_path):
    """Excel's "CSV UTF-8": a byte-order mark, every cell quoted, CRLF line ends."""
    path = tmp_path / "wind.csv"
    text = '"time","wind_speed","direction","temperature"\r\n"0","3.1","270","12"\r\n' \
           '"600","2.8","265","11.6"\r\n'
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    record = plc.WindRecord.from_csv(path)
    assert record.wind_speed.tolist() == [3.1, 2.8] and record.step == 600.0


def test_a_one_row_record_needs_its_interval_and_keeps_it_through_csv(tmp_path):
    with pytest.raises(plc.InputError, match="'interval' parameter is required for a one-row"):
        plc.WindRecord(np.array([0.0]), np.array([3.0]), np.array([90.0]), np.array([10.0]))
    one = plc.WindRecord(np.array([0.0]), np.array([3.0]), np.array([90.0]), np.array([10.0]),
                         interval=600.0)
    assert (one.step, one.duration) == (600.0, 600.0)
    one.to_csv(tmp_path / "one.csv")
    assert plc.WindRecord.from_csv(tmp_path / "one.csv").step == 600.0
    _write(tmp_path, [(0, 3.0, 90, 10.0)], name="bare.csv")
    with pytest.raises(plc.InputError, match="'interval'"):
        plc.WindRecord.from_csv(tmp_path / "bare.csv")
    with pytest.raises(plc.InputError, match=r"'interval' parameter must be the spacing"):
        plc.WindRecord(np.array([0.0, 600.0]), np.array([3.0, 3.0]), np.array([90.0, 90.0]),
                       np.array([10.0, 10.0]), interval=60.0)


@pytest.mark.parametrize(("target", "words"), [
    (5, "'path' parameter must be a file path"),
    ("", "'path' parameter must not be empty"),
    ("{tmp}", "is a folder"),
    ("{tmp}/missing/w.csv", "does not exist; create it first"),
])
def test_to_csv_refuses_a_path_it_cannot_write_naming_path(tmp_path, target, words):
    if isinstance(target, str):
        target = target.format(tmp=tmp_path)
    with pytest.raises(plc.InputError, match=words):
        plc.WindRecord.constant(3.0, n_records=2).to_csv(target)


def test_an_unclosed_quote_is_refused_naming_the_line(tmp_path):
    path = tmp_path / "wind.csv"
    path.write_text(f'{HEADER}\n0,3.1,270,12\n600,"2.8,265,11.6\n')
    with pytest.raises(plc.InputError, match="not CSV at line 3"):
        plc.WindRecord.from_csv(path)
