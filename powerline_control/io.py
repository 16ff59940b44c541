"""Saving and loading results without pickle: ``.npz`` arrays plus JSON metadata.

Each file is an uncompressed ``numpy.savez`` archive.  Besides the arrays it holds one entry
``__metadata__``: a JSON string with the ``format`` (which class), the format ``version`` and the
scalar fields.

:func:`load_model` treats the file as hostile until proved otherwise, and decides from headers
before it reads any data:

* the path must be a regular file (not ``/dev/zero``, a FIFO or a directory) of at most
  ``max_bytes`` bytes;
* the archive may hold only the entries a DMDModel has, each of a declared (uncompressed) size
  within ``max_bytes`` (so a zip bomb is refused from its directory, not by running out of
  memory), and no more than the file itself when stored uncompressed;
* each ``.npy`` header (:func:`numpy.lib.format.read_magic` and ``read_array_header_*``) must
  declare float64 and exactly the shape that the metadata implies, before the data are read;
* the contents must be finite, ``residual_covariance`` symmetric positive semidefinite,
  ``field_map`` the leading rows of ``basis``, the flags ``has_B`` / ``has_basis`` consistent
  with the entries present.

Anything else is a :class:`~powerline_control.errors.FileFormatError` that says what is wrong.
Nothing is ever unpickled.

Supported: :class:`~powerline_control.identify.DMDModel`, and measured or simulated records
(:class:`Record`: :func:`save_record` writes ``.npz`` plus ``.csv``, :func:`load_record` reads
either).
"""

from __future__ import annotations

import json
import math
import os
import stat
import zipfile
from typing import Any

import numpy as np
from numpy.lib import format as npy_format

from ._validation import MEMORY_BUDGET_BYTES, check_budget_value, read_only
from .errors import FileFormatError, InputError
from .identify import DMDModel

__all__ = ["save_model", "load_model", "Record", "save_record", "load_record"]

_METADATA_KEY = "__metadata__"
_DMD_FORMAT = "powerline_control.DMDModel"
_DMD_VERSION = 1
_DMD_SCALARS = ("dt", "alpha", "alpha_relative", "delays", "rank", "n_nodes", "n_pairs")
_ARRAYS = ("A", "B", "field_map", "basis", "residual_covariance", "initial_state",
           "regressor_gram")
#: The JSON metadata is a few hundred bytes; anything beyond this is not ours.
_METADATA_MAX_BYTES = 1 << 20
#: save_model stores entries uncompressed; float64 data never deflate by more than this.
_MAX_COMPRESSION_RATIO = 50
#: Relative tolerance of the PSD / symmetry / orthonormality checks (round-off of a fit).
_CONTENT_RTOL = 1e-8


def _dmd_to_arrays(model: DMDModel) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    arrays = {
        "A": model.A,
        "field_map": model.field_map,
        "residual_covariance": model.residual_covariance,
        "initial_state": model.initial_state,
    }
    if model.B is not None:
        arrays["B"] = model.B
    if model.basis is not None:
        arrays["basis"] = model.basis
    if model.regressor_gram is not None:
        arrays["regressor_gram"] = model.regressor_gram
    metadata = {name: getattr(model, name) for name in _DMD_SCALARS}
    metadata["has_B"] = model.B is not None
    metadata["has_basis"] = model.basis is not None
    metadata["has_regressor_gram"] = model.regressor_gram is not None
    return arrays, metadata


def save_model(path: str | os.PathLike[str], model: DMDModel) -> None:
    """Write a model to ``path`` as ``.npz`` (no pickle) with JSON metadata.

    Parameters
    ----------
    path : str or path-like
        Target file; numpy appends ``.npz`` if missing.
    model : DMDModel
        The model to save.

    Raises
    ------
    InputError
        ``path`` is not a path or an open file, or ``model`` is not a supported result type.

    Examples
    --------
    >>> import numpy as np, pathlib, tempfile, powerline_control as plc
    >>> dmd = plc.fit_dmd(np.array([[0.9 ** k for k in range(20)]]), dt=0.1)
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "line.npz"
    >>> plc.save_model(path, dmd)
    >>> bool(np.array_equal(plc.load_model(path).A, dmd.A))
    True
    """
    # np.savez also takes an open binary file; anything else (an int is read as a file
    # descriptor by some paths, a model passed first by mistake) is refused before writing.
    if not (isinstance(path, str | bytes | os.PathLike) or hasattr(path, "write")):
        raise InputError(
            f"The 'path' parameter must be a file path (str or os.PathLike) or an open binary "
            f"file. Got {path!r:.60} of type {type(path).__name__} instead."
        )
    if isinstance(path, str | bytes) and not path:
        raise InputError("The 'path' parameter must not be empty: give a file name.")
    if not isinstance(model, DMDModel):
        raise InputError(
            f"The 'model' parameter must be a DMDModel. Got {type(model).__name__} instead."
        )
    if isinstance(path, str | bytes | os.PathLike):
        _check_writable_target(os.fsdecode(path))
    arrays, metadata = _dmd_to_arrays(model)
    header = {"format": _DMD_FORMAT, "version": _DMD_VERSION, "fields": metadata}
    np.savez(path, **arrays, **{_METADATA_KEY: np.array(json.dumps(header))})


def _check_writable_target(name: str) -> None:
    """Refuse, before writing, a target that is not a (new or existing) regular file.

    ``np.savez`` onto a folder would write ``folder.npz`` beside it, and onto a FIFO would block
    until a reader comes; a missing folder would surface as a bare ``FileNotFoundError``.
    """
    target = name if name.endswith(".npz") else name + ".npz"   # what np.savez writes
    for candidate in dict.fromkeys((name, target)):
        if os.path.exists(candidate) and not os.path.isfile(candidate):
            kind = "a folder" if os.path.isdir(candidate) else "not a regular file (a FIFO?)"
            raise InputError(
                f"The 'path' parameter must name a file to write; {candidate!r} is {kind}. Give "
                "a file name, e.g. os.path.join(folder, 'model.npz')."
            )
    parent = os.path.dirname(os.path.abspath(target))
    if not os.path.isdir(parent):
        raise InputError(
            f"The 'path' parameter {name!r} is in the folder {parent!r}, which does not exist; "
            "create it first."
        )


# ------------------------------------------------------------------------------------ reading


class _Archive:
    """The entries of a checked zip file, read one at a time after their headers are checked."""

    def __init__(self, name: str, archive: zipfile.ZipFile, file_size: int, max_bytes: float):
        self.name, self.zip, self.max_bytes = name, archive, max_bytes
        self.entries: dict[str, zipfile.ZipInfo] = {}
        for info in archive.infolist():
            key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            if key not in _ARRAYS and key != _METADATA_KEY:
                raise FileFormatError(
                    f"{name!r} holds an entry {info.filename!r} that a DMDModel file does not "
                    f"have (expected {', '.join(_ARRAYS)} and {_METADATA_KEY}): not a "
                    "powerline_control file."
                )
            if key in self.entries:
                raise FileFormatError(f"{name!r} holds the entry {info.filename!r} twice.")
            if info.file_size > max_bytes:
                raise FileFormatError(
                    f"{name!r}: entry {info.filename!r} declares {info.file_size} bytes when "
                    f"unpacked, over the limit of {max_bytes:.0f} bytes (max_bytes); refused "
                    "before reading (a zip bomb or a foreign file)."
                )
            if info.file_size > _MAX_COMPRESSION_RATIO * info.compress_size + 4096:
                raise FileFormatError(
                    f"{name!r}: entry {info.filename!r} unpacks {info.compress_size} bytes into "
                    f"{info.file_size}, a ratio above {_MAX_COMPRESSION_RATIO} that float data "
                    "never reach (a zip bomb); refused before reading."
                )
            if info.compress_size > file_size:
                raise FileFormatError(
                    f"{name!r}: entry {info.filename!r} claims more bytes than the file has: "
                    "truncated or corrupted."
                )
            self.entries[key] = info
        total = sum(info.file_size for info in self.entries.values())
        if total > max_bytes:
            raise FileFormatError(
                f"{name!r}: its entries declare {total} bytes when unpacked, over the limit of "
                f"{max_bytes:.0f} bytes (max_bytes); refused before reading."
            )

    def header(self, key: str) -> tuple[tuple[int, ...], bool, np.dtype]:
        """(shape, fortran_order, dtype) from the entry's .npy header, without its data."""
        with self.zip.open(self.entries[key]) as stream:
            return self._read_header(key, stream)

    def _read_header(self, key: str, stream: Any) -> tuple[tuple[int, ...], bool, np.dtype]:
        try:
            version = npy_format.read_magic(stream)
            if version == (1, 0):
                shape, fortran, dtype = npy_format.read_array_header_1_0(stream)
            elif version == (2, 0):
                shape, fortran, dtype = npy_format.read_array_header_2_0(stream)
            else:
                raise ValueError(f"unsupported .npy version {version}")
        except (ValueError, OSError, EOFError, SyntaxError, zipfile.BadZipFile) as exc:
            raise FileFormatError(
                f"{self.name!r}: entry {key!r} has no valid .npy header ({exc})."
            ) from exc
        if dtype.hasobject:
            raise FileFormatError(
                f"{self.name!r}: entry {key!r} is an object array, which needs pickle; "
                "refused (load_model never unpickles)."
            )
        return tuple(int(n) for n in shape), bool(fortran), dtype

    def read(self, key: str, shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        """The entry's data, after checking that its header declares ``shape`` and ``dtype``."""
        info = self.entries[key]
        try:
            with self.zip.open(info) as stream:
                got_shape, fortran, got_dtype = self._read_header(key, stream)
                if got_dtype != dtype or got_shape != shape:
                    raise FileFormatError(
                        f"{self.name!r}: array {key!r} is declared {got_dtype} {got_shape}; "
                        f"expected {dtype} {shape} from the metadata. The file is corrupted or "
                        "not a DMDModel."
                    )
                nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
                if nbytes > self.max_bytes:
                    raise FileFormatError(
                        f"{self.name!r}: array {key!r} would need {nbytes} bytes, over the "
                        f"limit of {self.max_bytes:.0f} bytes (max_bytes)."
                    )
                data = stream.read(nbytes)
                extra = stream.read(1)  # reaching the end makes zipfile check the CRC-32
        except zipfile.BadZipFile as exc:
            raise FileFormatError(f"{self.name!r}: entry {key!r} is corrupted ({exc}).") from exc
        if len(data) != nbytes or extra:
            raise FileFormatError(
                f"{self.name!r}: entry {key!r} holds {len(data) + len(extra)} data bytes; its "
                f"header declares {nbytes}. The file is truncated or corrupted."
            )
        order = "F" if fortran else "C"
        return np.frombuffer(data, dtype=dtype).reshape(shape, order=order).copy(order="C")


def _check_regular_file(name: str, max_bytes: float) -> int:
    try:
        info = os.stat(name)
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise FileFormatError(f"Cannot read {name!r}: {exc}") from exc
    if not stat.S_ISREG(info.st_mode):
        raise FileFormatError(
            f"{name!r} is not a regular file (a device, FIFO or directory); load_model reads "
            "only .npz files written by save_model."
        )
    if info.st_size > max_bytes:
        raise FileFormatError(
            f"{name!r} has {info.st_size} bytes, over the limit of {max_bytes:.0f} bytes "
            "(max_bytes): not a model this machine should load. Raise max_bytes if you trust it."
        )
    return int(info.st_size)


def _metadata(archive: _Archive) -> dict[str, Any]:
    name = archive.name
    if _METADATA_KEY not in archive.entries:
        raise FileFormatError(
            f"{name!r} has no {_METADATA_KEY!r} entry: not a powerline_control file."
        )
    shape, _, dtype = archive.header(_METADATA_KEY)
    if dtype.kind != "U" or shape != () or dtype.itemsize > _METADATA_MAX_BYTES:
        raise FileFormatError(
            f"{name!r}: the {_METADATA_KEY!r} entry must be one text string of at most "
            f"{_METADATA_MAX_BYTES} bytes; it is {dtype} {shape}. The file is corrupted."
        )
    text = str(archive.read(_METADATA_KEY, (), dtype)[()])
    try:
        header = json.loads(text)
        file_format, version, fields = header["format"], header["version"], header["fields"]
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise FileFormatError(f"The metadata of {name!r} is corrupted: {exc}") from exc
    if file_format != _DMD_FORMAT:
        raise FileFormatError(
            f"{name!r} holds a {file_format!r}; load_model reads {_DMD_FORMAT!r}."
        )
    if version != _DMD_VERSION:
        raise FileFormatError(
            f"{name!r} has format version {version!r}; this powerline_control reads "
            f"version {_DMD_VERSION}. Upgrade powerline_control or re-save the model."
        )
    if not isinstance(fields, dict):
        raise FileFormatError(f"{name!r}: DMDModel metadata 'fields' must be a table; the file "
                              f"holds {type(fields).__name__}.")
    return fields


def _scalar(source: str, fields: dict[str, Any], name: str, kind: type, *,
            low: float | None = None, optional: bool = False) -> Any:
    """A metadata scalar of the right type (bool is no number) and range, or FileFormatError."""
    if name not in fields:
        raise FileFormatError(f"{source!r}: DMDModel metadata lacks the field {name!r}.")
    value = fields[name]
    if value is None and optional:
        return None
    if kind is bool:
        ok = isinstance(value, bool)
    elif kind is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(
            value)
    else:
        ok = isinstance(value, kind) and not isinstance(value, bool)
    if not ok or (low is not None and value < low):
        bound = "" if low is None else f" >= {low:g}"
        raise FileFormatError(f"{source!r}: DMDModel metadata field {name!r} must be a "
                              f"{kind.__name__}{bound}; the file holds {value!r}. The file is "
                              "corrupted.")
    return kind(value)


def _check_contents(name: str, arrays: dict[str, np.ndarray]) -> None:
    for key, array in arrays.items():
        if not np.all(np.isfinite(array)):
            raise FileFormatError(f"{name!r}: array {key!r} contains NaN or infinite values.")
    q = arrays["residual_covariance"]
    scale = max(float(np.abs(q).max()) if q.size else 0.0, np.finfo(float).tiny)
    if q.size and np.abs(q - q.T).max() > _CONTENT_RTOL * scale:
        raise FileFormatError(f"{name!r}: 'residual_covariance' is not symmetric.")
    if q.size:
        smallest = float(np.linalg.eigvalsh((q + q.T) / 2).min())
        if smallest < -_CONTENT_RTOL * scale * q.shape[0]:
            raise FileFormatError(
                f"{name!r}: 'residual_covariance' is not positive semidefinite (smallest "
                f"eigenvalue {smallest:.3g}); a covariance never is."
            )
    basis = arrays.get("basis")
    if basis is not None:
        gram = basis.T @ basis
        if np.abs(gram - np.eye(gram.shape[0])).max() > 1e-6:
            raise FileFormatError(f"{name!r}: 'basis' does not have orthonormal columns.")
        if not np.array_equal(arrays["field_map"], basis[: arrays["field_map"].shape[0]]):
            raise FileFormatError(f"{name!r}: 'field_map' is not the leading rows of 'basis'.")


def load_model(path: str | os.PathLike[str], *, max_bytes: float | None = None) -> DMDModel:
    """Read a model written by :func:`save_model`; the round trip is exact.

    Parameters
    ----------
    path : str or path-like
        File to read.
    max_bytes : float, optional
        Largest file and unpacked archive accepted, bytes (default the package's memory budget,
        :data:`~powerline_control._validation.MEMORY_BUDGET_BYTES`, 4 GiB).

    Returns
    -------
    DMDModel
        The saved model, bit for bit.

    Raises
    ------
    FileFormatError
        Not a regular file, too large, missing pieces, truncated, corrupted, of another format
        or version, arrays of the wrong dtype or shape, non-finite or inconsistent contents.
    FileNotFoundError
        No such file.

    Examples
    --------
    See :func:`save_model`.
    """
    if not isinstance(path, str | bytes | os.PathLike):
        raise InputError(
            f"The 'path' parameter must be a file path (str or os.PathLike). Got {path!r:.60} "
            f"of type {type(path).__name__} instead."
        )
    name = os.fsdecode(path)
    if not name:
        raise InputError("The 'path' parameter must not be empty: give a file name.")
    # A limit is validated first: nan would make every "size > max_bytes" false (no limit) and
    # "1e6" is text, not a number.
    max_bytes = (MEMORY_BUDGET_BYTES if max_bytes is None
                 else check_budget_value("max_bytes", max_bytes))
    file_size = _check_regular_file(name, max_bytes)
    try:
        with open(name, "rb") as handle:
            if not zipfile.is_zipfile(handle):
                raise FileFormatError(
                    f"{name!r} is not a powerline_control .npz file (not a zip archive)."
                )
            handle.seek(0)
            with zipfile.ZipFile(handle) as zf:
                return _read_dmd(_Archive(name, zf, file_size, max_bytes))
    except FileFormatError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError,
            NotImplementedError) as exc:
        raise FileFormatError(
            f"Cannot read {name!r} as a powerline_control .npz file: {exc}"
        ) from exc


def _read_dmd(archive: _Archive) -> DMDModel:
    name = archive.name
    fields = _metadata(archive)
    dt = _scalar(name, fields, "dt", float, low=0.0)
    if dt <= 0:
        raise FileFormatError(
            f"{name!r}: DMDModel metadata field 'dt' must be > 0; the file holds {dt}."
        )
    alpha = _scalar(name, fields, "alpha", float, low=0.0)
    alpha_relative = _scalar(name, fields, "alpha_relative", float, low=0.0)
    delays = _scalar(name, fields, "delays", int, low=1)
    rank = _scalar(name, fields, "rank", int, low=1, optional=True)
    n_nodes = _scalar(name, fields, "n_nodes", int, low=1)
    n_pairs = _scalar(name, fields, "n_pairs", int, low=1)
    has_B = _scalar(name, fields, "has_B", bool)
    has_basis = _scalar(name, fields, "has_basis", bool)
    has_gram = bool(fields.get("has_regressor_gram", False))
    if (rank is None) == has_basis:
        raise FileFormatError(
            f"{name!r}: metadata rank={rank} contradicts has_basis={has_basis} (a POD basis "
            "exists exactly when a rank is set). The file is corrupted."
        )
    n = rank if rank is not None else n_nodes * delays
    # Every entry must match the flags: nothing missing, nothing extra.
    expected = {"A", "field_map", "residual_covariance", "initial_state"}
    expected |= {"B"} if has_B else set()
    expected |= {"basis"} if has_basis else set()
    expected |= {"regressor_gram"} if has_gram else set()
    present = set(archive.entries) - {_METADATA_KEY}
    if present - expected:
        extra = sorted(present - expected)
        raise FileFormatError(
            f"{name!r} holds the array(s) {extra}, which its metadata (has_B={has_B}, "
            f"has_basis={has_basis}) says it does not have. The file is corrupted."
        )
    if expected - present:
        raise FileFormatError(
            f"The file {name!r} lacks the array(s) {sorted(expected - present)}: it is "
            "truncated or foreign."
        )
    f8 = np.dtype("<f8")
    n_inputs = 0
    if has_B:
        b_shape, _, _ = archive.header("B")
        if len(b_shape) != 2 or b_shape[0] != n:
            raise FileFormatError(
                f"{name!r}: array 'B' is declared {b_shape}; expected ({n}, n_inputs) from the "
                "metadata. The file is corrupted."
            )
        n_inputs = b_shape[1]
    shapes = {"A": (n, n), "field_map": (n_nodes, n), "residual_covariance": (n, n),
              "initial_state": (n,), "B": (n, n_inputs), "basis": (n_nodes * delays, n),
              "regressor_gram": (n + n_inputs, n + n_inputs)}
    needed = sum(8 * int(np.prod(shapes[key], dtype=np.int64)) for key in expected)
    if needed > archive.max_bytes:
        raise FileFormatError(
            f"{name!r}: its metadata (n_nodes={n_nodes}, delays={delays}, rank={rank}) implies "
            f"{needed} bytes of arrays, over the limit of {archive.max_bytes:.0f} (max_bytes)."
        )
    arrays = {key: archive.read(key, shapes[key], f8) for key in sorted(expected)}
    _check_contents(name, arrays)
    return DMDModel(
        A=read_only(arrays["A"]),
        B=read_only(arrays["B"]) if has_B else None,
        dt=dt,
        alpha=alpha,
        alpha_relative=alpha_relative,
        delays=delays,
        rank=rank,
        n_nodes=n_nodes,
        field_map=read_only(arrays["field_map"]),
        basis=read_only(arrays["basis"]) if has_basis else None,
        residual_covariance=read_only(arrays["residual_covariance"]),
        n_pairs=n_pairs,
        initial_state=read_only(arrays["initial_state"]),
        regressor_gram=read_only(arrays["regressor_gram"]) if has_gram else None,
    )


# ----------------------------------------------------------------------------- records

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

    Examples
    --------
    >>> rec = Record([0.0, 0.001, 0.002], [1.0], [[0.0, 1e-3, np.nan]])
    >>> rec.dt, rec.n_missing, rec.values.shape
    (0.001, 1, (1, 3))
    """

    def __init__(self, t, positions, values, source: str = "<record>", truth=None):
        t = np.asarray(t, dtype=float)
        positions = np.asarray(positions, dtype=float).reshape(-1)
        values = np.asarray(values, dtype=float)
        if values.ndim == 1:
            values = values[None, :]
        where = f"{source}: "
        if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)):
            raise InputError(f"{where}the time column must hold at least 2 finite times, s.")
        steps = np.diff(t)
        dt = float(np.median(steps))
        if dt <= 0 or np.max(np.abs(steps - dt)) > _RATE_RTOL * dt + 1e-12:
            raise InputError(f"{where}the time column is not uniformly sampled (steps from "
                             f"{steps.min():.6g} to {steps.max():.6g} s); resample the record "
                             "or mark missing samples with NaN (empty CSV cells).")
        if values.shape != (positions.size, t.size):
            raise InputError(f"{where}values must be (n_channels, n_t) = ({positions.size}, "
                             f"{t.size}); got {values.shape}.")
        if not np.all(np.isfinite(positions)):
            raise InputError(f"{where}channel positions must be finite numbers, m.")
        if np.isinf(values).any():
            raise InputError(f"{where}values must be finite or NaN (missing); found inf.")
        self.t, self.positions, self.values = read_only(t), read_only(positions), \
            read_only(values)
        self.truth = None if truth is None else read_only(np.asarray(truth, dtype=float))
        self.dt = dt
        self.source = source
        self.n_missing = int(np.isnan(values).sum())

    def __repr__(self) -> str:
        return (f"Record({self.values.shape[0]} channels, {self.t.size} samples at "
                f"dt = {self.dt:g} s, {self.n_missing} missing, from {self.source})")

    def check_span(self, length: float) -> None:
        """Refuse channels outside the span (0 < x < length).

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
        for x in self.positions:
            if not 0.0 < x < length:
                raise InputError(f"{self.source}: channel {_column(x)} at {x:g} m lies outside "
                                 f"the span (0 < x < {length:g} m).")


def _column(x: float) -> str:
    return f"x_{x:.10g}_m"


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

    if not isinstance(record, Record):
        raise InputError(f"The 'record' parameter must be a Record. Got "
                         f"{type(record).__name__}.")
    base = Path(path)
    base = base.with_suffix("") if base.suffix in (".npz", ".csv") else base
    npz, csv = base.with_name(base.name + ".npz"), base.with_name(base.name + ".csv")
    header = {"format": _RECORD_FORMAT, "version": _RECORD_VERSION, "units": "m",
              "source": record.source}
    arrays = {"t": np.asarray(record.t), "positions": np.asarray(record.positions),
              "values": np.asarray(record.values)}
    if record.truth is not None:
        arrays["truth"] = np.asarray(record.truth)
    np.savez(npz, **arrays, **{_METADATA_KEY: np.array(json.dumps(header))})
    columns = ["time_s", *(_column(x) for x in record.positions)]
    with open(csv, "w", encoding="utf-8") as handle:
        handle.write(f"# sample_rate_hz = {1.0 / record.dt!r}\n")
        handle.write(",".join(columns) + "\n")
        for k in range(record.t.size):
            cells = [repr(float(record.t[k]))] + [
                "" if np.isnan(v) else repr(float(v)) for v in record.values[:, k]]
            handle.write(",".join(cells) + "\n")
    return [npz, csv]


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
        An unreadable, binary or oversized file, a column that is not numeric (named, with its
        line), a time column that is not uniform or disagrees with ``sample_rate``.

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
    try:
        with np.load(name, allow_pickle=False) as data:
            header = json.loads(str(data[_METADATA_KEY]))
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
    header = [c.strip() for c in lines[0][1].split(",")]
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
        cells = line.split(",")
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
