"""Saving and loading results without pickle: ``.npz`` arrays plus JSON metadata.

Each file is an uncompressed ``numpy.savez`` archive.  Besides the arrays it holds one entry
``__metadata__``: a JSON string with the ``format`` (which class), the format ``version`` and the
scalar fields.

:func:`load_model` treats the file as hostile until proved otherwise, and decides from headers
before it reads any data:

* the path must be a regular file (not ``/dev/zero``, a FIFO or a directory) of at most
  ``max_bytes`` bytes;
* the archive may hold only the entries a DMDModel (or OscillatorModel) has, each of a declared
  (uncompressed) size within ``max_bytes`` (so a zip bomb is refused from its directory, not by
  running out of memory), and no more than the file itself when stored uncompressed;
* each ``.npy`` header (:func:`numpy.lib.format.read_magic` and ``read_array_header_*``) must
  declare float64 and exactly the shape that the metadata implies, before the data are read;
* the contents must be finite, ``residual_covariance`` symmetric positive semidefinite,
  ``field_map`` the leading rows of ``basis``, the flags ``has_B`` / ``has_basis`` consistent
  with the entries present.

* an OscillatorModel file must also hold its line frequencies, line shapes and unseen
  directions, and its ``A``, ``field_map``, ``basis`` and ``residual_covariance`` must be those
  that these build (a forged kind or edited frequency is refused, naming the field).

Anything else is a :class:`~powerline_control.errors.FileFormatError` that says what is wrong.
Nothing is ever unpickled.

Supported: :class:`~powerline_control.identify.DMDModel` (format ``powerline_control.DMDModel``,
as every earlier release wrote it) and its subclass
:class:`~powerline_control.identify.OscillatorModel` (format
``powerline_control.OscillatorModel``: the DMDModel entries plus its own). Measured or simulated
records
(:class:`~powerline_control.output.records.Record`) have their own module, ``records``.
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

from .._validation import (
    MEMORY_BUDGET_BYTES,
    check_budget_value,
    check_write_path,
    checked_keywords,
    read_only,
)
from ..errors import FileFormatError, InputError
from ..identify import DMDModel, OscillatorModel, SpanModel

__all__ = ["save_model", "load_model"]

_METADATA_KEY = "__metadata__"
_DMD_FORMAT = "powerline_control.DMDModel"
_DMD_VERSION = 1
_DMD_SCALARS = ("dt", "alpha", "alpha_relative", "delays", "rank", "n_nodes", "n_pairs")
_OSC_FORMAT = "powerline_control.OscillatorModel"
_OSC_VERSION = 1
_VERSIONS = {_DMD_FORMAT: _DMD_VERSION, _OSC_FORMAT: _OSC_VERSION}
_OSC_SCALARS = ("n_lines", "process_noise", "unseen_noise", "radius")
_OSC_ARRAYS = ("line_frequencies", "line_shapes", "unseen")
_ARRAYS = ("A", "B", "field_map", "basis", "residual_covariance", "initial_state",
           "regressor_gram") + _OSC_ARRAYS
#: The JSON metadata is a few hundred bytes; anything beyond this is not ours.
_METADATA_MAX_BYTES = 1 << 20
#: save_model stores entries uncompressed; float64 data never deflate by more than this.
_MAX_COMPRESSION_RATIO = 50
#: Relative tolerance of the PSD / symmetry / orthonormality checks (round-off of a fit).
_CONTENT_RTOL = 1e-8
#: Relative tolerance between an OscillatorModel file's arrays and those its lines rebuild.
_OSC_RTOL = 1e-8


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
    if isinstance(model, OscillatorModel):
        arrays.update({name: getattr(model, name) for name in _OSC_ARRAYS})
        metadata.update({name: getattr(model, name) for name in _OSC_SCALARS})
    return arrays, metadata


@checked_keywords
def save_model(path: str | os.PathLike[str], model: DMDModel) -> None:
    """Write a model to ``path`` as ``.npz`` (no pickle) with JSON metadata.

    Parameters
    ----------
    path : str or path-like
        Target file; numpy appends ``.npz`` if missing.
    model : DMDModel
        The model to save; an :class:`~powerline_control.identify.OscillatorModel` is written
        with its kind and its own fields, and loads as one.

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
            "The 'model' parameter must be a DMDModel (or an OscillatorModel). Got "
            f"{type(model).__name__} instead."
        )
    if isinstance(model, SpanModel):
        # Its lock-in process noise is not what the file's oscillator fields rebuild: a file
        # written now would be refused as corrupted when read back.
        raise InputError(
            "The 'model' parameter is a SpanModel, which save_model cannot write yet (its "
            "lock-in process noise has no place in the file format). Save the span it was "
            "built from (model.calibration) and rebuild it with identify.span_model, or save "
            "the recipe's DMD design instead.")
    if isinstance(path, str | bytes | os.PathLike):
        name = os.fsdecode(path)   # np.savez writes name + ".npz" unless it ends so already
        check_write_path(path, written=[name if name.endswith(".npz") else name + ".npz"])
    arrays, metadata = _dmd_to_arrays(model)
    kind = _OSC_FORMAT if isinstance(model, OscillatorModel) else _DMD_FORMAT
    header = {"format": kind, "version": _VERSIONS[kind], "fields": metadata}
    np.savez(path, **arrays, **{_METADATA_KEY: np.array(json.dumps(header))})


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


def _metadata(archive: _Archive) -> tuple[str, dict[str, Any]]:
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
    if not isinstance(file_format, str) or file_format not in _VERSIONS:
        raise FileFormatError(
            f"{name!r}: its metadata field 'format' is {file_format!r}; load_model reads "
            f"{_DMD_FORMAT!r} and {_OSC_FORMAT!r}."
        )
    if version != _VERSIONS[file_format]:
        raise FileFormatError(
            f"{name!r} has format version {version!r}; this powerline_control reads "
            f"version {_VERSIONS[file_format]} of {file_format!r}. Upgrade powerline_control or "
            "re-save the model."
        )
    if not isinstance(fields, dict):
        raise FileFormatError(f"{name!r}: DMDModel metadata 'fields' must be a table; the file "
                              f"holds {type(fields).__name__}.")
    return file_format, fields


def _scalar(source: str, fields: dict[str, Any], name: str, kind: type, *,
            low: float | None = None, optional: bool = False) -> Any:
    """A metadata scalar of the right type (bool is no number) and range, or FileFormatError."""
    if name not in fields:
        raise FileFormatError(f"{source!r}: the model metadata lacks the field {name!r}.")
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
        raise FileFormatError(f"{source!r}: the model metadata field {name!r} must be a "
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


@checked_keywords
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
        The saved model, bit for bit, of the type saved: an
        :class:`~powerline_control.identify.OscillatorModel` comes back as one.

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
                return _read_model(_Archive(name, zf, file_size, max_bytes))
    except FileFormatError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError,
            NotImplementedError) as exc:
        raise FileFormatError(
            f"Cannot read {name!r} as a powerline_control .npz file: {exc}"
        ) from exc


def _read_model(archive: _Archive) -> DMDModel:
    """The model of a checked archive: a DMDModel, or an OscillatorModel when its kind says so."""
    name = archive.name
    kind, fields = _metadata(archive)
    oscillator = kind == _OSC_FORMAT
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
    extra: dict[str, Any] = {}
    if oscillator:
        extra = _oscillator_scalars(name, fields)
        _check_oscillator_layout(name, {"delays": delays, "alpha": alpha,
                                        "alpha_relative": alpha_relative, "has_B": has_B,
                                        "has_basis": has_basis,
                                        "has_regressor_gram": has_gram}, n, extra["n_lines"])
    # Every entry must match the flags: nothing missing, nothing extra.
    expected = {"A", "field_map", "residual_covariance", "initial_state"}
    expected |= {"B"} if has_B else set()
    expected |= {"basis"} if has_basis else set()
    expected |= {"regressor_gram"} if has_gram else set()
    expected |= set(_OSC_ARRAYS) if oscillator else set()
    present = set(archive.entries) - {_METADATA_KEY}
    if present - expected:
        surplus = sorted(present - expected)
        raise FileFormatError(
            f"{name!r} holds the array(s) {surplus}, which its metadata (format {kind!r}, "
            f"has_B={has_B}, has_basis={has_basis}) says it does not have. The file is "
            "corrupted."
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
    r = extra.get("n_lines", 0)
    shapes = {"A": (n, n), "field_map": (n_nodes, n), "residual_covariance": (n, n),
              "initial_state": (n,), "B": (n, n_inputs), "basis": (n_nodes * delays, n),
              "regressor_gram": (n + n_inputs, n + n_inputs), "line_frequencies": (r,),
              "line_shapes": (n_nodes, r), "unseen": (n_nodes, n - 2 * r)}
    needed = sum(8 * int(np.prod(shapes[key], dtype=np.int64)) for key in expected)
    if needed > archive.max_bytes:
        raise FileFormatError(
            f"{name!r}: its metadata (n_nodes={n_nodes}, delays={delays}, rank={rank}) implies "
            f"{needed} bytes of arrays, over the limit of {archive.max_bytes:.0f} (max_bytes)."
        )
    arrays = {key: archive.read(key, shapes[key], f8) for key in sorted(expected)}
    _check_contents(name, arrays)
    common = dict(
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
    if not oscillator:
        return DMDModel(**common)
    model = OscillatorModel(**common, **{key: read_only(arrays[key]) for key in _OSC_ARRAYS},
                            **{key: extra[key] for key in _OSC_SCALARS if key != "n_lines"})
    _check_oscillator(name, model)
    return model


def _oscillator_scalars(name: str, fields: dict[str, Any]) -> dict[str, Any]:
    """The OscillatorModel's own metadata fields, each checked."""
    values = {"n_lines": _scalar(name, fields, "n_lines", int, low=0)}
    for key in ("process_noise", "unseen_noise", "radius"):
        values[key] = _scalar(name, fields, key, float, low=0.0)
    if not 0.0 < values["radius"] <= 1.0:
        raise FileFormatError(f"{name!r}: the model metadata field 'radius' must be in (0, 1]; "
                              f"the file holds {values['radius']!r}. The file is corrupted.")
    return values


#: What an OscillatorModel file's DMDModel fields must be (it is built, not fitted).
_OSC_LAYOUT = {"delays": 2, "alpha": 0.0, "alpha_relative": 0.0, "has_B": False,
               "has_basis": True, "has_regressor_gram": False}


def _check_oscillator_layout(name: str, found: dict[str, Any], n: int, n_lines: int) -> None:
    """Refuse an OscillatorModel file whose DMDModel fields no oscillator model has."""
    for key, value in _OSC_LAYOUT.items():
        if found[key] != value or type(found[key]) is not type(value):
            raise FileFormatError(
                f"{name!r}: the model metadata field {key!r} is {found[key]!r}; an "
                f"OscillatorModel has {value!r}. The file is corrupted or not an OscillatorModel."
            )
    if 2 * n_lines > n:
        raise FileFormatError(
            f"{name!r}: the model metadata field 'n_lines' is {n_lines}, more than half of its "
            f"{n} states (two per line). The file is corrupted."
        )


#: Which of an OscillatorModel's own fields build each of its DMDModel arrays.
_BUILT_FROM = {"A": ("line_frequencies", "line_shapes", "radius"),
               "field_map": ("line_shapes", "unseen"), "basis": ("line_shapes", "unseen"),
               "residual_covariance": ("process_noise", "unseen_noise"),
               "initial_state": ()}


def _check_oscillator(name: str, model: OscillatorModel) -> None:
    """Refuse a file whose arrays are not those its lines build (an edited or forged file)."""
    try:
        built = OscillatorModel.from_lines(
            model.line_frequencies, model.line_shapes, model.dt, n_pairs=model.n_pairs,
            process_noise=model.process_noise, unseen=model.unseen,
            unseen_noise=model.unseen_noise, radius=model.radius)
    except InputError as exc:
        raise FileFormatError(f"{name!r}: its oscillator fields build no model: {exc}") from exc
    for key, sources in _BUILT_FROM.items():
        ours, theirs = np.asarray(getattr(model, key)), np.asarray(getattr(built, key))
        scale = max(float(np.abs(theirs).max()) if theirs.size else 0.0, np.finfo(float).tiny)
        # The file's arrays are the bits save_model wrote; rebuilding them on another machine
        # differs by round-off (amplified by the shapes' conditioning), never by 1e-8.
        if theirs.size and float(np.abs(ours - theirs).max()) > _OSC_RTOL * scale:
            made = (f"the one its fields {', '.join(repr(s) for s in sources)} build" if sources
                    else "zero (an oscillator model starts at rest)")
            raise FileFormatError(
                f"{name!r}: array {key!r} is not {made}: the file is corrupted or forged."
            )
