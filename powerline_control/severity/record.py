"""Wind and temperature records: hourly or 10-minute means of wind speed, direction and air
temperature (and turbulence intensity where measured), read from CSV and checked row by row.

A record is the input of :func:`~powerline_control.severity.fatigue.fatigue_over_record`. The CSV
reader uses the standard library only (pandas is not needed).
"""

from __future__ import annotations

import contextvars
import csv
import math
import os
from dataclasses import dataclass
from datetime import datetime

import numpy as np

from .._validation import check_int, check_real, check_rng, check_write_path, read_only
from ..errors import InputError

__all__ = ["WindRecord"]

#: Required CSV columns (the header names, case-insensitive) and the optional one.
REQUIRED_COLUMNS = ("time", "wind_speed", "direction", "temperature")
OPTIONAL_COLUMNS = ("turbulence_intensity",)
#: Allowed ranges: wind speeds 0..50 m/s, air temperatures -50..80 degC, wind
#: directions 0..360 degrees, turbulence intensities 0..1.
LIMITS = {"wind_speed": (0.0, 50.0), "temperature": (-50.0, 80.0), "direction": (0.0, 360.0),
          "turbulence_intensity": (0.0, 1.0)}
#: An interval longer than this multiple of the record's usual step is a gap.
GAP_FACTOR = 1.5
# While from_csv builds a record: data row -> file line, for the messages of the checks.
_LINE_OF_ROW: contextvars.ContextVar = contextvars.ContextVar("line_of_row", default=None)
UNITS = {"wind_speed": "m/s", "temperature": "degC", "direction": "degrees",
         "turbulence_intensity": ""}


def _where(row: int, line_of_row) -> str:
    return f"row {row}" if line_of_row is None else f"row {row} (line {line_of_row(row)})"


def _check_column(name: str, values: object, n: int | None, line_of_row=None) -> np.ndarray:
    """A finite 1-D float column inside its LIMITS, or an InputError naming column and row."""
    array = np.asarray(values)
    if array.dtype == bool or array.dtype.kind not in "iuf" or array.ndim != 1:
        raise InputError(f"The '{name}' column must be a 1-D array of real numbers. Got "
                         f"{array.dtype} with shape {array.shape}.")
    array = array.astype(float)
    if n is not None and array.size != n:
        raise InputError(f"The '{name}' column must have one value per record ({n}). Got "
                         f"{array.size}.")
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        raise InputError(f"The '{name}' column must be finite: {_where(int(bad[0]), line_of_row)} "
                         f"holds {array[bad[0]]!r}.")
    if name in LIMITS:
        low, high = LIMITS[name]
        bad = np.flatnonzero((array < low) | (array > high))
        if bad.size:
            raise InputError(
                f"The '{name}' column must lie in [{low:g}, {high:g}] {UNITS[name]}: "
                f"{_where(int(bad[0]), line_of_row)} holds {array[bad[0]]:g}.")
    return array


def _interval(median: float, interval: object) -> float:
    """The record's step: ``interval`` when given (it must match the median spacing of a record
    of several rows), else that median; a one-row record has no spacing and needs ``interval``.
    """
    if interval is None:
        if math.isnan(median):
            raise InputError("The 'interval' parameter is required for a one-row record: its "
                             "time column gives no spacing, and the interval each row stands "
                             "for (e.g. 600 s) weighs every result. Got None.")
        return median
    interval = check_real("interval", interval, low=0.0)
    if not math.isnan(median) and not math.isclose(interval, median, rel_tol=1e-9):
        raise InputError(f"The 'interval' parameter must be the spacing of the 'time' column "
                         f"({median!r} s) or None. Got {interval!r} s.")
    return interval


def _check_time(time: np.ndarray, line_of_row=None) -> float:
    """Strictly increasing, evenly spaced up to GAP_FACTOR; returns the usual step (s)."""
    if time.size < 1:
        raise InputError("The 'time' column must have at least one row (a wind record needs "
                         "one row per interval). Got none.")
    if time.size == 1:
        return math.nan
    step = np.diff(time)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        row = int(bad[0]) + 1
        raise InputError(
            f"The 'time' column must increase strictly: {_where(row, line_of_row)} "
            f"({time[row]:g} s) does not come after {_where(row - 1, line_of_row)} "
            f"({time[row - 1]:g} s).")
    usual = float(np.median(step))
    bad = np.flatnonzero(step > GAP_FACTOR * usual)
    if bad.size:
        row = int(bad[0]) + 1
        raise InputError(
            f"The 'time' column has a gap: {_where(row, line_of_row)} comes {step[bad[0]]:g} s "
            f"after the previous row; the record's step is {usual:g} s (more than "
            f"{GAP_FACTOR:g} steps is a gap). Fill the gap (or split the record) before the "
            "analysis; a fatigue total over missing hours would be silently low.")
    return usual


@dataclass(frozen=True, eq=False)
class WindRecord:
    """A record of mean wind speed, direction and air temperature, one row per interval.

    Each row stands for one interval of the record's step (the usual spacing of ``time``:
    10 minutes or an hour) during which the mean values hold.

    Parameters
    ----------
    time : ndarray
        Start of each interval, s (strictly increasing; no gaps beyond 1.5 steps).
    wind_speed : ndarray
        Mean wind speed at conductor height, m/s, in [0, 50].
    direction : ndarray
        Direction the wind blows from, degrees clockwise from north, in [0, 360].
    temperature : ndarray
        Air temperature, degC, in [-50, 80] (taken as the conductor temperature: aeolian
        vibration happens in light winds, when the conductor is close to ambient).
    turbulence_intensity : ndarray or None
        Turbulence intensity Iv per row, in [0, 1], where measured; None: laminar (Iv = 0).
    start : str
        The first row's time stamp when the file gave time stamps ("" otherwise).
    source : str
        Where the record came from (a path, or a description).
    interval : float or None
        The interval each row stands for, s: required for a one-row record (whose time column
        gives no spacing); for more rows None (the median spacing of ``time``) or that spacing.

    Raises
    ------
    InputError
        For a value outside its range, a missing or non-finite value, time stamps that do not
        increase, a gap, or one row without ``interval``; the message names the column and the
        row.

    Examples
    --------
    >>> rec = WindRecord(np.array([0.0, 600.0]), np.array([3.0, 4.0]), np.array([90.0, 80.0]),
    ...                  np.array([12.0, 11.5]))
    >>> rec.step, rec.duration
    (600.0, 1200.0)
    >>> rec.normal_speed(line_azimuth=0.0).round(3)
    array([3.   , 3.939])
    """

    time: np.ndarray
    wind_speed: np.ndarray
    direction: np.ndarray
    temperature: np.ndarray
    turbulence_intensity: np.ndarray | None = None
    start: str = ""
    source: str = ""
    interval: float | None = None

    def __post_init__(self) -> None:
        for name in ("start", "source"):
            if not isinstance(getattr(self, name), str):
                raise InputError(f"The '{name}' parameter must be a string. Got "
                                 f"{getattr(self, name)!r:.60}.")
        if self.start:
            try:
                datetime.fromisoformat(self.start)
            except ValueError:
                raise InputError("The 'start' parameter must be an ISO 8601 time stamp (or ''). "
                                 f"Got {self.start!r:.60}.") from None
        lines = _LINE_OF_ROW.get()
        time = _check_column("time", self.time, None, lines)
        n = time.size
        median = _check_time(time, lines)
        object.__setattr__(self, "time", read_only(time))
        for name in ("wind_speed", "direction", "temperature"):
            object.__setattr__(self, name, read_only(_check_column(name, getattr(self, name), n,
                                                                   lines)))
        if self.turbulence_intensity is not None:
            object.__setattr__(self, "turbulence_intensity", read_only(_check_column(
                "turbulence_intensity", self.turbulence_intensity, n, lines)))
        # last: a bad value names its column and row before a one-row record asks for more
        object.__setattr__(self, "_step", _interval(median, self.interval))

    @property
    def n_records(self) -> int:
        """Number of rows."""
        return int(self.time.size)

    @property
    def step(self) -> float:
        """The record's interval, s: the median spacing of ``time`` (``step=`` of
        :meth:`constant` for a one-row record)."""
        return float(self._step)

    @property
    def duration(self) -> float:
        """Time the record covers, s: rows x step."""
        return self.n_records * self.step

    def normal_speed(self, line_azimuth: float = 0.0) -> np.ndarray:
        """Wind speed component normal to the line, V |sin(direction - azimuth)|, m/s.

        Parameters
        ----------
        line_azimuth : float
            Direction of the line, degrees clockwise from north (a line and its reverse,
            azimuth + 180, are the same).

        Returns
        -------
        ndarray

        Examples
        --------
        >>> rec = WindRecord.constant(4.0, n_records=2, direction=30.0)
        >>> rec.normal_speed(line_azimuth=0.0).round(6).tolist()
        [2.0, 2.0]
        """
        azimuth = check_real("line_azimuth", line_azimuth)
        return self.wind_speed * np.abs(np.sin(np.radians(self.direction - azimuth)))

    @classmethod
    def constant(cls, wind_speed: float, *, n_records: int = 144, step: float = 600.0,
                 direction: float = 90.0, temperature: float = 15.0,
                 turbulence_intensity: float | None = None) -> WindRecord:
        """A record of one steady wind (for checks against the steady analysis).

        Parameters
        ----------
        wind_speed : float
            m/s.
        n_records : int
            Rows (default 144: a day of 10-minute means).
        step : float
            Interval, s (default 600).
        direction : float
            Degrees from north (default 90: normal to a north-south line).
        temperature : float
            degC (default 15).
        turbulence_intensity : float or None
            Iv of every row (default None).

        Returns
        -------
        WindRecord

        Examples
        --------
        >>> WindRecord.constant(3.0, n_records=6, step=3600.0).duration
        21600.0
        """
        n_records = check_int("n_records", n_records, low=1)
        step = check_real("step", step, low=0.0)
        wind_speed = check_real("wind_speed", wind_speed)
        direction = check_real("direction", direction)
        temperature = check_real("temperature", temperature)
        full = np.full(n_records, 1.0)
        ti = (None if turbulence_intensity is None
              else full * check_real("turbulence_intensity", turbulence_intensity))
        return cls(np.arange(n_records) * step, full * wind_speed, full * direction,
                   full * temperature, ti, source=f"constant {wind_speed:g} m/s",
                   interval=step if n_records == 1 else None)

    @classmethod
    def synthetic(cls, days: float = 28.0, *, step: float = 600.0, seed=0, shape: float = 2.0,
                  scale: float = 4.0, diurnal: float = 0.3, prevailing: float = 250.0,
                  mean_temperature: float = 10.0, diurnal_temperature: float = 6.0,
                  correlation_time: float = 3 * 3600.0) -> WindRecord:
        """A synthetic record: Weibull wind speeds with a diurnal cycle, direction, temperature.

        The model (seeded, so the same arguments give the same record):

        - wind speed: a Gaussian AR(1) process of correlation time ``correlation_time``,
          mapped through the normal and the inverse Weibull CDFs, so its marginal is Weibull
          (``shape`` k, ``scale`` c), then multiplied by the diurnal factor
          1 + ``diurnal`` sin(2 pi (hour - 9) / 24) (windier afternoons), capped at 50 m/s;
        - direction: ``prevailing`` plus an AR(1) wander of 40 degrees standard deviation
          (same correlation time), wrapped to [0, 360);
        - temperature: ``mean_temperature`` + ``diurnal_temperature`` sin(2 pi (hour - 9) / 24)
          plus an AR(1) synoptic variation of 3 degC standard deviation and two days'
          correlation time;
        - turbulence intensity: 0.15 - 0.01 V plus 0.02 of white noise, clipped to [0.03, 0.4]
          (gusty light winds, smoother strong ones; an illustration, not a site model).

        Values are rounded as a station would log them (0.01 m/s, 1 degree, 0.1 degC, 0.001).

        Parameters
        ----------
        days : float
            Length, days (> 0).
        step : float
            Interval, s (default 600: 10-minute means).
        seed : int, numpy.random.Generator or None
            Randomness.
        shape, scale : float
            Weibull k and c (m/s) of the wind speed before the diurnal factor.
        diurnal : float
            Relative amplitude of the diurnal wind cycle (0 <= diurnal < 1).
        prevailing : float
            Prevailing direction, degrees from north.
        mean_temperature, diurnal_temperature : float
            degC.
        correlation_time : float
            Of the wind speed and direction, s.

        Returns
        -------
        WindRecord

        Examples
        --------
        >>> rec = WindRecord.synthetic(days=2.0, seed=1)
        >>> rec.n_records, rec.step
        (288, 600.0)
        >>> bool(np.all(rec.wind_speed >= 0) and rec.temperature.std() > 1.0)
        True
        """
        import scipy.special

        rng = check_rng(seed)
        for name, value in (("days", days), ("step", step), ("shape", shape), ("scale", scale),
                            ("correlation_time", correlation_time)):
            check_real(name, value, low=0.0)
        diurnal = check_real("diurnal", diurnal, low=0.0, low_inclusive=True, high=1.0,
                             high_inclusive=False)
        prevailing = check_real("prevailing", prevailing)
        mean_temperature = check_real("mean_temperature", mean_temperature, low=-50.0,
                                      high=80.0)
        diurnal_temperature = check_real("diurnal_temperature", diurnal_temperature, low=0.0,
                                         low_inclusive=True, high=50.0)
        n = int(round(days * 86400.0 / step))
        if n < 1 or n > 10_000_000:
            raise InputError(f"The record would have {n} rows; 'days' / 'step' must give "
                             "1 to 1e7 rows.")
        t = np.arange(n) * float(step)
        hour = (t / 3600.0) % 24.0

        def ar1(tau: float) -> np.ndarray:
            rho = math.exp(-step / tau)
            noise = rng.standard_normal(n)
            out = np.empty(n)
            out[0] = noise[0]
            scale_noise = math.sqrt(1 - rho**2)
            for i in range(1, n):
                out[i] = rho * out[i - 1] + scale_noise * noise[i]
            return out

        u = scipy.special.ndtr(ar1(correlation_time))
        speed = scale * (-np.log1p(-np.minimum(u, 1 - 1e-12))) ** (1.0 / shape)
        speed = np.minimum(speed * (1 + diurnal * np.sin(2 * np.pi * (hour - 9) / 24)), 50.0)
        direction = (prevailing + 40.0 * ar1(correlation_time)) % 360.0
        temperature = (mean_temperature + diurnal_temperature * np.sin(2 * np.pi * (hour - 9)
                                                                        / 24)
                       + 3.0 * ar1(2 * 86400.0))
        iv = np.clip(0.15 - 0.01 * speed + 0.02 * rng.standard_normal(n), 0.03, 0.4)
        rounded = dict(wind_speed=np.round(speed, 2), direction=np.round(direction) % 360.0,
                       temperature=np.round(np.clip(temperature, -50.0, 80.0), 1),
                       turbulence_intensity=np.round(iv, 3))
        return cls(t, **rounded, source=f"WindRecord.synthetic(days={days:g}, step={step:g}, "
                   f"seed={seed!r}, shape={shape:g}, scale={scale:g}, diurnal={diurnal:g})",
                   interval=float(step) if n == 1 else None)

    @classmethod
    def from_csv(cls, path: str | os.PathLike) -> WindRecord:
        """Read a record from a CSV file with a header row.

        Columns (header names, case-insensitive, any order; others are ignored): ``time``
        (seconds, or ISO 8601 time stamps such as ``2024-01-01T00:10:00``), ``wind_speed``
        (m/s), ``direction`` (degrees from north), ``temperature`` (degC) and, optionally,
        ``turbulence_intensity``. What spreadsheets write is read: a UTF-8 byte-order mark
        (Excel's "CSV UTF-8"), quoted cells, CRLF line ends. Lines starting with ``#`` are
        comments, except ``# start = <ISO time stamp>`` (the first row's time stamp, when the
        time column is in seconds) and ``# interval_s = <s>`` (the interval of a one-row
        record), which :meth:`to_csv` writes.

        Parameters
        ----------
        path : str or path-like
            The CSV file.

        Returns
        -------
        WindRecord

        Raises
        ------
        InputError
            For a missing column, an empty or non-numeric cell, a value outside its range,
            time stamps that do not increase, or a gap: the message names the column, the data
            row (0-based) and the file's line.

        Examples
        --------
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "wind.csv"
        >>> _ = path.write_text("time,wind_speed,direction,temperature\\n"
        ...                     "0,3.1,270,12.0\\n600,2.8,265,11.6\\n")
        >>> WindRecord.from_csv(path).wind_speed.tolist()
        [3.1, 2.8]
        """
        if not isinstance(path, str | os.PathLike):
            raise InputError("The 'path' parameter must be a str or path-like. Got "
                             f"{type(path).__name__}.")
        path = os.fspath(path)
        if not os.path.isfile(path):
            # a folder, a FIFO (reading it would block) or nothing at all
            what = "is not a regular file" if os.path.exists(path) else "does not exist"
            raise InputError(f"The 'path' parameter must name a CSV file. Got {path!r}, which "
                             f"{what}.")
        try:
            # "utf-8-sig": Excel's "CSV UTF-8" starts with a byte-order mark
            with open(path, newline="", encoding="utf-8-sig") as handle:
                reader = csv.reader(handle, strict=True)
                rows = list(reader)
        except OSError as exc:
            raise InputError(f"The 'path' parameter {path!r} cannot be read: {exc}.") from None
        except UnicodeDecodeError as exc:
            raise InputError(f"The 'path' parameter {path!r} is not a UTF-8 CSV text file "
                             f"({exc}).") from None
        except csv.Error as exc:
            raise InputError(f"The 'path' parameter {path!r} is not CSV at line "
                             f"{reader.line_num} ({exc}).") from None
        # (line number, cells) of the rows that are neither blank nor comments
        numbered = [(i + 1, row) for i, row in enumerate(rows) if any(c.strip() for c in row)]
        notes = _comments(path, [(n, r) for n, r in numbered if r[0].lstrip().startswith("#")])
        numbered = [(n, r) for n, r in numbered if not r[0].lstrip().startswith("#")]
        if not numbered:
            raise InputError(f"The wind record {path!r} is empty: it needs a header row with "
                             f"the columns {', '.join(REQUIRED_COLUMNS)}.")
        header_row = numbered[0][1]
        header = [name.strip().lower() for name in header_row]
        missing = [name for name in REQUIRED_COLUMNS if name not in header]
        if missing:
            raise InputError(f"The wind record {path!r} has no column {missing[0]!r}: it needs "
                             f"{', '.join(REQUIRED_COLUMNS)} (and optionally "
                             f"{', '.join(OPTIONAL_COLUMNS)}). Its header is {header_row}.")
        columns = [name for name in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if name in header]
        index = {name: header.index(name) for name in columns}
        data = [row for _, row in numbered[1:]]
        lines = [number for number, _ in numbered[1:]]
        values = {name: np.empty(len(data)) for name in columns}
        first_stamp = ""
        origin = None
        for r, row in enumerate(data):
            for name in columns:
                where = f"row {r} (line {lines[r]})"
                cell = row[index[name]].strip() if index[name] < len(row) else ""
                if not cell:
                    raise InputError(f"The '{name}' column of {path!r} has no value in {where}.")
                try:
                    values[name][r] = float(cell)
                    continue
                except ValueError:
                    pass
                if name != "time":
                    raise InputError(f"The '{name}' column of {path!r} must hold numbers: "
                                     f"{where} holds {cell!r}.")
                try:
                    stamp = datetime.fromisoformat(cell)
                except ValueError:
                    raise InputError(f"The 'time' column of {path!r} must hold seconds or ISO "
                                     f"8601 time stamps: {where} holds {cell!r}.") from None
                if origin is None:
                    origin, first_stamp = stamp, cell
                try:
                    values[name][r] = (stamp - origin).total_seconds()
                except TypeError:
                    raise InputError(f"The 'time' column of {path!r} mixes time stamps with and "
                                     f"without a time zone: {where} holds {cell!r}.") from None
        start = notes.get("start", "")
        if first_stamp and start and datetime.fromisoformat(start) != origin:
            raise InputError(f"The wind record {path!r} says '# start = {start}' but its first "
                             f"time stamp is {first_stamp!r}; remove the comment or correct it.")
        token = _LINE_OF_ROW.set(lambda row: lines[row])
        try:
            return cls(values["time"], values["wind_speed"], values["direction"],
                       values["temperature"], values.get("turbulence_intensity"),
                       start=first_stamp or start, source=path, interval=notes.get("interval_s"))
        finally:
            _LINE_OF_ROW.reset(token)

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write the record as CSV (the columns :meth:`from_csv` reads; time in seconds).

        Every number is written with ``repr`` (the shortest text that reads back bit-exact), the
        start time stamp as a ``# start = ...`` comment line and a one-row record's interval as
        ``# interval_s = ...``: :meth:`from_csv` reads back the same record.

        Parameters
        ----------
        path : str or path-like
            Where to write (its folder must exist).

        Raises
        ------
        InputError
            ``path`` is not a file path, is a folder, or its folder does not exist.

        Examples
        --------
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "wind.csv"
        >>> WindRecord.constant(1 / 3, n_records=3).to_csv(path)
        >>> WindRecord.from_csv(path).wind_speed.tolist()
        [0.3333333333333333, 0.3333333333333333, 0.3333333333333333]
        """
        path = check_write_path(path)
        names = [*REQUIRED_COLUMNS] + (["turbulence_intensity"]
                                       if self.turbulence_intensity is not None else [])
        with open(path, "w", newline="", encoding="utf-8") as handle:
            if self.start:
                handle.write(f"# start = {self.start}\n")
            if self.n_records == 1:
                handle.write(f"# interval_s = {self.step!r}\n")
            writer = csv.writer(handle, lineterminator="\n")
            writer.writerow(names)
            for i in range(self.n_records):
                writer.writerow([repr(float(getattr(self, name)[i])) for name in names])


def _comments(path: str, rows: list) -> dict:
    """The settings of a wind CSV's ``# key = value`` comment lines (``start``, ``interval_s``);
    any other comment is ignored."""
    notes: dict = {}
    for number, row in rows:
        key, sep, value = ",".join(row).lstrip().lstrip("#").partition("=")
        key, value = key.strip().lower(), value.strip()
        if not sep or key not in ("start", "interval_s"):
            continue
        if key == "start":
            try:
                datetime.fromisoformat(value)
            except ValueError:
                raise InputError(f"The wind record {path!r}, line {number}: '# start' must be "
                                 f"an ISO 8601 time stamp. Got {value!r:.60}.") from None
            notes[key] = value
        else:
            try:
                notes[key] = float(value)
            except ValueError:
                raise InputError(f"The wind record {path!r}, line {number}: '# interval_s' "
                                 f"must be a number of seconds. Got {value!r:.60}.") from None
    return notes
