"""Field records in and out: :class:`Record` (displacements at a few positions, regularly sampled).

:func:`save_record` writes ``.npz`` (the exact record) plus ``.csv`` (for a spreadsheet);
:func:`load_record` reads either, and the ``.csv`` a data logger writes (a time column, one column
per position, a header naming the positions and the unit).
"""

from __future__ import annotations

import copy
import csv
import json
import math
import os
import stat
import zipfile

import numpy as np

from .._validation import (
    check_array,
    check_real,
    check_write_path,
    checked_keywords,
    read_only,
    warn_if_saturated,
)
from ..errors import FileFormatError, InputError
from .io import _METADATA_KEY

__all__ = ["Record", "save_record", "load_record"]

_RECORD_FORMAT = "powerline_control.Record"
_RECORD_VERSION = 1
#: A record file larger than this is refused before it is read (a day at 1 kHz on 10 channels
#: is ~7 GB as text: split it).
RECORD_MAX_BYTES = 1 << 30
_UNIT_SCALE = {"m": 1.0, "mm": 1e-3, "um": 1e-6}
#: Relative tolerance on the sample interval: the time column must be uniform to this.
_RATE_RTOL = 1e-6


class Record:
    """A record of displacements at a few positions along the span, regularly sampled.

    The one format a field record and a simulated one share: rows are channels (sensors),
    columns are instants (the package's (signal, time) convention); NaN marks a missing sample.

    Parameters
    ----------
    t : array_like, shape (n_t,)
        Sample times, s, uniformly spaced (``dt`` apart).
    positions : array_like, shape (n_channels,)
        Where each channel measures, m from the left support.
    values : array_like, shape (n_channels, n_t)
        Displacements, m; NaN = missing.
    source : str
        Where the record came from (a file name, "simulated"), for messages.
    truth : array_like or None, shape (n_channels, n_t)
        The noise-free displacements, when known (a simulated record).

    Attributes
    ----------
    dt : float
        Sample interval, s.
    n_missing : int
        Number of NaN samples.
    support_positions : tuple of float
        Channels dropped because they sat on a support (:meth:`without_supports`), m; empty
        for a record as read.

    Examples
    --------
    >>> rec = Record([0.0, 0.001, 0.002], [1.0], [[0.0, 1e-3, np.nan]])
    >>> rec.dt, rec.n_missing, rec.values.shape
    (0.001, 1, (1, 3))
    """

    def __init__(self, t, positions, values, source: str = "<record>", truth=None):
        if not isinstance(source, str):
            raise InputError(f"The 'source' parameter must be a string (where the record came "
                             f"from). Got {source!r:.60} of type {type(source).__name__}.")
        where = f"{source}: "
        try:
            t = check_array("t", t, ndim=1)
            positions = check_array("positions", positions, ndim=1)
            values = check_array("values", values, ndim=(1, 2), allow_nan=True)
            if values.ndim == 1:
                values = values[None, :]
            if truth is not None:
                truth = check_array("truth", truth, shape=values.shape)
        except InputError as error:
            raise InputError(f"{where}{_infinite(positions, values) or error}") from None
        if t.size < 2:
            raise InputError(f"{where}the 't' parameter (the time column) must hold at least 2 "
                             f"times, s; got {t.size}.")
        if positions.size == 0:
            raise InputError(f"{where}the 'positions' parameter is empty: a record has at least "
                             "one channel.")
        steps = np.diff(t)
        dt = float(np.median(steps))
        if dt <= 0 or np.max(np.abs(steps - dt)) > _RATE_RTOL * dt + 1e-12:
            raise InputError(f"{where}the time column is not uniformly sampled (steps from "
                             f"{steps.min():.6g} to {steps.max():.6g} s); resample the record "
                             "or mark missing samples with NaN (empty CSV cells).")
        if values.shape != (positions.size, t.size):
            raise InputError(f"{where}the 'values' parameter must be (n_channels, n_t) = "
                             f"({positions.size}, {t.size}); got {values.shape}.")
        unique, counts = np.unique(positions, return_counts=True)
        if (counts > 1).any():  # an estimator can use one channel per position, never two
            x = float(unique[counts > 1][0])
            raise InputError(f"{where}the 'positions' parameter names {x:g} m (column "
                             f"{_column(x)}) {int(counts[counts > 1][0])} times: two channels at "
                             "one position. Keep one (or their mean) per position.")
        self.t, self.positions, self.values = read_only(t), read_only(positions), \
            read_only(values)
        self.truth = None if truth is None else read_only(truth)
        self.dt = dt
        self.source = source
        self.n_missing = int(np.isnan(values).sum())
        self.support_positions: tuple = ()
        # Measured data enter as a Record (from a file or built in Python): a channel held at
        # its sensor's range (flat tops) is named here, once, by its column.
        warn_if_saturated(source, values, [f"column {_column(x)} (channel {i}, at {x:g} m)"
                                           for i, x in enumerate(positions)])

    def __repr__(self) -> str:
        return (f"Record({self.values.shape[0]} channels, {self.t.size} samples at "
                f"dt = {self.dt:g} s, {self.n_missing} missing, from {self.source})")

    def check_span(self, length: float) -> None:
        """Refuse channels on a support (x = 0 or length), outside the span (0 < x < length),
        constant (one value in every sample: a dead sensor, where the line moves) or missing
        in every sample; and a ``length`` that is not a finite number > 0.

        Parameters
        ----------
        length : float
            Span length, m.

        Examples
        --------
        >>> Record([0.0, 1.0], [5.0], [[0.0, 0.0]], "f.csv").check_span(3.66)
        Traceback (most recent call last):
        ...
        powerline_control.errors.InputError: f.csv: channel x_5_m at 5 m lies outside the \
span (0 < x < 3.66 m).
        """
        on_support = self._on_support(length)   # checks the length
        for x, support in zip(self.positions, on_support, strict=True):
            if support:
                raise InputError(f"{self.source}: channel {_column(x)} at {x:g} m sits on a "
                                 f"support (x = 0 or {length:g} m), where the line does not "
                                 "move: it carries no information about the span. Drop it "
                                 "(Record.without_supports does).")
            if not 0.0 < x < length:
                raise InputError(f"{self.source}: channel {_column(x)} at {x:g} m lies outside "
                                 f"the span (0 < x < {length:g} m).")
        for x, row in zip(self.positions, self.values, strict=True):
            seen = row[~np.isnan(row)]
            if seen.size == 0:   # as dead as a constant channel, and nothing to estimate from
                raise InputError(f"{self.source}: channel {_column(x)} at {x:g} m is missing "
                                 f"(NaN) in all its {row.size} samples: a dead or disconnected "
                                 "sensor, which carries no information about the span. Drop "
                                 "the column.")
            if seen.size >= 2 and np.all(seen == seen[0]):  # inside the span the line moves
                raise InputError(f"{self.source}: channel {_column(x)} at {x:g} m holds one "
                                 f"value ({float(seen[0]):g} m) in all its {seen.size} samples: "
                                 "a dead, disconnected or stuck sensor, which carries no "
                                 "information about the span. Drop the column.")

    def _on_support(self, length: float) -> np.ndarray:
        # "On a support" to round-off of the written position (a logger's CSV column name may
        # keep a few significant digits; 1e-9 of the span is far below any sensor's size).
        length = check_real("length", length, low=0.0)   # a NaN length would match no support
        tol = 1e-9 * length
        x = np.asarray(self.positions)
        return (np.abs(x) <= tol) | (np.abs(x - float(length)) <= tol)

    def without_supports(self, length: float) -> Record:
        """The record without the channels that sit on a support (x = 0 or x = length).

        Both supports (pinned and clamped) hold the line still, so a channel there measures
        only its sensor's noise: it carries no information and must not become a sensor. A
        record of every node (``powerline-control simulate --out``) has two such channels.

        Parameters
        ----------
        length : float
            Span length, m.

        Returns
        -------
        Record
            The other channels (this record itself when none sits on a support); its
            ``support_positions`` lists the channels dropped, m.

        Raises
        ------
        InputError
            Every channel sits on a support, or ``length`` is not a finite number > 0.

        Examples
        --------
        >>> rec = Record([0.0, 1.0], [0.0, 1.5, 3.66], [[0.0, 0.0], [1e-3, 2e-3], [0.0, 0.0]])
        >>> kept = rec.without_supports(3.66)
        >>> kept.positions.tolist(), kept.support_positions
        ([1.5], (0.0, 3.66))
        """
        on_support = self._on_support(length)
        if not on_support.any():
            return self
        if on_support.all():
            raise InputError(f"{self.source}: every channel ("
                             + ", ".join(_column(x) for x in self.positions)
                             + f") sits on a support (x = 0 or {float(length):g} m), where the "
                             "line does not move; a record needs a channel inside the span.")
        # A subset of channels this record already validated and judged for saturation: copied,
        # not rebuilt, so nothing is checked or warned a second time.
        keep = ~on_support
        kept = copy.copy(self)
        kept.positions, kept.values = read_only(self.positions[keep]), read_only(self.values[keep])
        kept.truth = None if self.truth is None else read_only(self.truth[keep])
        kept.n_missing = int(np.isnan(kept.values).sum())
        kept.support_positions = tuple(float(x) for x in self.positions[on_support])
        return kept


def _number(x: float) -> str:
    """``x`` as the shortest text that reads back bit-exact (``repr``), ``5`` for ``5.0``."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def _column(x: float) -> str:
    """A channel's CSV column name: its exact position, so that a saved record reloads equal."""
    return f"x_{_number(x)}_m"


def _infinite(positions, values) -> str | None:
    """'column x_.._m holds an infinite value at sample k ...' when ``values`` holds inf."""
    try:
        x = np.atleast_1d(np.asarray(positions, dtype=float))
        v = np.asarray(values, dtype=float)
        v = v[None, :] if v.ndim == 1 else v
    except (TypeError, ValueError):
        return None
    if v.ndim != 2 or not np.isinf(v).any():
        return None
    channels, samples = np.nonzero(np.isinf(v))
    i, k = int(channels[0]), int(samples[0])
    column = _column(float(x[i])) if x.shape == (v.shape[0],) else f"channel {i}"
    return (f"column {column} (row {i} of the 'values') holds {int(np.isinf(v).sum())} infinite "
            f"value(s), the first at sample {k} ({float(v[i, k])!r}); a displacement must be "
            "finite (mark a missing sample with NaN, an empty CSV cell).")


@checked_keywords
def save_record(path: str | os.PathLike[str], record: Record) -> list:
    """Write a record as ``PATH.npz`` (arrays + JSON metadata) and ``PATH.csv`` (text).

    The CSV starts with a comment line ``# sample_rate_hz = ...``, then a ``time_s`` column and
    one column per channel named ``x_<position>_m`` (displacement in m, an empty cell for a
    missing sample): ``pandas.read_csv(path, comment="#")`` and
    ``numpy.genfromtxt(path, delimiter=",", names=True, skip_header=1)`` read it. The
    ``.npz`` holds ``t``, ``positions``, ``values`` (and ``truth`` when known), no pickle.

    Parameters
    ----------
    path : str or path-like
        The file name without extension (an extension is replaced).
    record : Record
        The record.

    Returns
    -------
    list of Path
        The two files written.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> base = pathlib.Path(tempfile.mkdtemp()) / "rec"
    >>> rec = Record([0.0, 0.5, 1.0], [1.0, 2.0], [[0.0, 1e-3, np.nan], [0.0, 2e-3, 1e-3]])
    >>> [p.name for p in save_record(base, rec)]
    ['rec.npz', 'rec.csv']
    >>> load_record(base.with_suffix(".csv")).n_missing
    1
    """
    from pathlib import Path

    check_write_path(path)   # its type first: the targets below are built from it
    if not isinstance(record, Record):
        raise InputError(f"The 'record' parameter must be a Record. Got "
                         f"{type(record).__name__}.")
    base = Path(path)
    base = base.with_suffix("") if base.suffix in (".npz", ".csv") else base
    npz, csv_path = base.with_name(base.name + ".npz"), base.with_name(base.name + ".csv")
    check_write_path(path, written=[npz, csv_path])   # nothing is written unless both can be
    header = {"format": _RECORD_FORMAT, "version": _RECORD_VERSION, "units": "m",
              "source": record.source}
    arrays = {"t": np.asarray(record.t), "positions": np.asarray(record.positions),
              "values": np.asarray(record.values)}
    if record.truth is not None:
        arrays["truth"] = np.asarray(record.truth)
    np.savez(npz, **arrays, **{_METADATA_KEY: np.array(json.dumps(header))})
    columns = ["time_s", *(_column(x) for x in record.positions)]
    with open(csv_path, "w", newline="", encoding="utf-8") as handle:
        # 10 significant digits: 1 / dt carries the round-off of the time column's steps
        # (999.9999999999991 for dt = 1e-3); the reader checks the rate to 1e-6 anyway.
        handle.write(f"# sample_rate_hz = {1.0 / record.dt:.10g}\n")
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(columns)
        # repr: the shortest text that reads back bit-exact; an empty cell is a missing sample
        for k in range(record.t.size):
            writer.writerow([_number(record.t[k])] + [
                "" if np.isnan(v) else _number(v) for v in record.values[:, k]])
    return [npz, csv_path]


@checked_keywords
def load_record(path: str | os.PathLike[str], *, sample_rate: float | None = None,
                units: str | None = None) -> Record:
    """Read a measured (or saved) record: positions, sample rate, units, missing samples.

    ``.npz`` files are those :func:`save_record` writes. A ``.csv`` file has a header row, a
    time column (``time_s``, or ``t``/``time``, s) and one column per channel named
    ``x_<position>_<unit>`` (unit ``m``, ``mm`` or ``um``; e.g. ``x_0.915_m``); an empty cell,
    ``nan`` or ``NA`` is a missing sample. Lines starting with ``#`` are comments, except
    ``# sample_rate_hz = 1000``, which the time column must agree with.

    Parameters
    ----------
    path : str or path-like
        The ``.npz`` or ``.csv`` file.
    sample_rate : float or None
        The sample rate the record should have, Hz: refused when the time column disagrees.
    units : str or None
        Displacement unit of every channel when the column names carry none (``m``, ``mm``,
        ``um``).

    Returns
    -------
    Record
        Displacements in m.

    Raises
    ------
    InputError
        An unreadable, binary or oversized file, a column that is not numeric or holds an
        infinite value (named, with its line), a time column that is not uniform or disagrees
        with ``sample_rate``.
    FileFormatError
        A ``.npz`` name on a file that is not a zip archive.

    Warns
    -----
    SaturationWarning
        A channel is clipped at its sensor's range: many samples exactly at its largest or
        smallest value (``_validation.warn_if_saturated``).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "field.csv"
    >>> _ = path.write_text("time_s,x_0.9_mm,x_2.4_mm\\n0,0.1,0.2\\n0.001,,0.3\\n0.002,0.2,0.1\\n")
    >>> rec = load_record(path)
    >>> rec.positions.tolist(), rec.dt, rec.n_missing, float(rec.values[1, 1])
    ([0.9, 2.4], 0.001, 1, 0.0003)
    """
    name = os.fsdecode(path) if isinstance(path, str | os.PathLike) else None
    if not name:
        raise InputError(f"The 'path' parameter must be a file path. Got {path!r:.60}.")
    if sample_rate is not None:
        sample_rate = check_real("sample_rate", sample_rate, low=0.0)
    if units is not None and units not in _UNIT_SCALE:
        raise InputError(f"The 'units' parameter must be None or one of "
                         f"{', '.join(map(repr, _UNIT_SCALE))}. Got {units!r:.60}.")
    try:
        info = os.stat(name)
    except OSError as exc:
        raise InputError(f"Cannot read the record {name!r}: {exc.strerror or exc}.") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"The record {name!r} is not a regular file.")
    if info.st_size > RECORD_MAX_BYTES:
        raise InputError(f"The record {name!r} has {info.st_size} bytes, over the "
                         f"{RECORD_MAX_BYTES} a record may have; split it.")
    if name.endswith(".npz"):
        record = _load_record_npz(name)
    else:
        record = _load_record_csv(name, units)
    if sample_rate is not None:
        rate = 1.0 / record.dt
        if not math.isclose(rate, float(sample_rate), rel_tol=1e-6):
            raise InputError(f"{name}: the time column gives {rate:.6g} Hz, not the sample "
                             f"rate {float(sample_rate):.6g} Hz given.")
    return record


def _load_record_npz(name: str) -> Record:
    # Refused before numpy reads it: np.load takes a file that is not a zip archive for a
    # pickle and answers with advice to set allow_pickle (never done here).
    if not zipfile.is_zipfile(name):
        raise FileFormatError(f"{name}: not an .npz file (not a zip archive); a record is the "
                              ".npz that save_record writes, or CSV text.")
    try:
        with np.load(name, allow_pickle=False) as data:
            header = json.loads(str(data[_METADATA_KEY]))
            if not isinstance(header, dict):   # JSON, but not the object save_record writes
                raise InputError(f"{name}: its metadata is a JSON {type(header).__name__}, not "
                                 "the object save_record writes; not a record.")
            if header.get("format") != _RECORD_FORMAT:
                raise InputError(f"{name}: holds {header.get('format')!r}, not a record.")
            if header.get("version") != _RECORD_VERSION:
                raise InputError(f"{name}: record format version {header.get('version')!r}; "
                                 f"this version reads {_RECORD_VERSION}.")
            arrays = {k: np.array(data[k]) for k in ("t", "positions", "values")}
            truth = np.array(data["truth"]) if "truth" in data.files else None
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{name}: not a record written by save_record ({exc}).") from None
    for key, value in arrays.items():
        if value.dtype.kind not in "fi":
            raise InputError(f"{name}: array {key!r} is not numeric ({value.dtype}).")
    return Record(arrays["t"], arrays["positions"], arrays["values"], name, truth)


def _cells(name: str, number: int, line: str) -> list[str]:
    """The cells of one CSV line, as the csv module reads them (quoted cells, as spreadsheets
    export, included)."""
    try:
        return next(csv.reader([line], strict=True))
    except csv.Error as exc:
        raise InputError(f"{name}: line {number} is not CSV ({exc}).") from None


def _load_record_csv(name: str, units: str | None) -> Record:
    import re

    with open(name, "rb") as handle:  # the size was checked above
        raw = handle.read()
    if b"\x00" in raw:
        raise InputError(f"{name}: not a text file (NUL bytes); a record is CSV text or .npz.")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{name}: not UTF-8 text; a record is CSV text or .npz.") from None
    all_lines = text.splitlines()
    declared = None
    for i, line in enumerate(all_lines):
        match = re.match(r"^\s*#\s*sample_rate_hz\s*[=:]\s*(\S+)\s*$", line)
        if match:
            try:
                declared = float(match.group(1))
            except ValueError:
                raise InputError(f"{name}: line {i + 1}: sample_rate_hz {match.group(1)!r} is "
                                 "not a number of Hz.") from None
    lines = [(i + 1, line) for i, line in enumerate(all_lines)
             if line.strip() and not line.lstrip().startswith("#")]
    if len(lines) < 3:
        raise InputError(f"{name}: a record needs a header row and at least 2 samples.")
    header = [c.strip() for c in _cells(name, *lines[0])]
    if header[0].lower() not in ("time_s", "t", "time", "t_s"):
        raise InputError(f"{name}: the first column must be the time, s (named time_s); got "
                         f"{header[0]!r}.")
    positions, scales = [], []
    pattern = re.compile(r"^x_?([-+0-9.eE]+)_?(m|mm|um)?$")
    for column in header[1:]:
        match = pattern.match(column)
        if not match:
            raise InputError(f"{name}: column {column!r} does not name a position; name each "
                             "channel x_<position>_<unit>, e.g. x_0.915_m.")
        try:
            position = float(match.group(1))
        except ValueError:
            raise InputError(f"{name}: column {column!r}: {match.group(1)!r} is not a "
                             "position in m.") from None
        unit = match.group(2) or units or "m"
        if unit not in _UNIT_SCALE:
            raise InputError(f"{name}: unit {unit!r} of column {column!r}; allowed: "
                             f"{', '.join(_UNIT_SCALE)}.")
        positions.append(position)
        scales.append(_UNIT_SCALE[unit])
    if not positions:
        raise InputError(f"{name}: no channel columns after the time column.")
    n = len(header)
    table = np.full((len(lines) - 1, n), np.nan)
    for row, (number, line) in enumerate(lines[1:]):
        cells = _cells(name, number, line)
        if len(cells) != n:
            raise InputError(f"{name}: line {number} has {len(cells)} cells; the header has "
                             f"{n}.")
        for col, cell in enumerate(cells):
            cell = cell.strip()
            if cell.lower() in ("", "nan", "na", "null"):
                if col == 0:
                    raise InputError(f"{name}: line {number}: the time column "
                                     f"{header[0]!r} is empty.")
                continue
            try:
                table[row, col] = float(cell)
            except ValueError:
                raise InputError(f"{name}: line {number}, column {header[col]!r}: {cell!r:.30} "
                                 "is not a number.") from None
    values = table[:, 1:].T * np.asarray(scales)[:, None]
    record = Record(table[:, 0], positions, values, name)
    if declared is not None and not math.isclose(1.0 / record.dt, declared, rel_tol=1e-6):
        raise InputError(f"{name}: the header says sample_rate_hz = {declared:g}, but the "
                         f"time column {header[0]!r} gives {1.0 / record.dt:.6g} Hz.")
    return record
