"""Saving and loading results without pickle: ``.npz`` arrays plus JSON metadata.

Each file is an uncompressed ``numpy.savez`` archive written and read with
``allow_pickle=False``.  Besides the arrays it holds one entry ``__metadata__``: a JSON string
with the ``format`` (which class), the format ``version`` and the scalar fields.  Loading checks
format, version, presence and shapes of every array and fails with
:class:`~powerline_control.errors.FileFormatError` on a truncated, corrupted or foreign file.

Supported: :class:`~powerline_control.identify.DMDModel`.
"""

from __future__ import annotations

import json
import os
import zipfile
from typing import Any

import numpy as np

from ._validation import read_only
from .errors import FileFormatError, InputError
from .identify import DMDModel

__all__ = ["save_model", "load_model"]

_METADATA_KEY = "__metadata__"
_DMD_FORMAT = "powerline_control.DMDModel"
_DMD_VERSION = 1
_DMD_SCALARS = ("dt", "alpha", "alpha_relative", "delays", "rank", "n_nodes", "n_pairs")


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
    metadata = {name: getattr(model, name) for name in _DMD_SCALARS}
    metadata["has_B"] = model.B is not None
    metadata["has_basis"] = model.basis is not None
    return arrays, metadata


def _expect_shape(name: str, array: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    if array.shape != shape or array.dtype.kind != "f":
        raise FileFormatError(
            f"Array {name!r} in the file has shape {array.shape} and dtype {array.dtype}; "
            f"expected float64 {shape}. The file is corrupted or not a DMDModel."
        )
    return array


def _scalar(fields: dict[str, Any], name: str, kind: type, *, low: float | None = None,
            optional: bool = False) -> Any:
    """A metadata scalar of the right type (bool is no number) and range, or FileFormatError."""
    value = fields[name]
    if value is None and optional:
        return None
    ok = isinstance(value, kind) and not isinstance(value, bool)
    if kind is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and np.isfinite(value)
    if not ok or (low is not None and value < low):
        bound = "" if low is None else f" >= {low:g}"
        raise FileFormatError(f"DMDModel metadata field {name!r} must be a {kind.__name__}{bound}; "
                              f"the file holds {value!r}. The file is corrupted.")
    return kind(value)


def _dmd_from_arrays(arrays: dict[str, np.ndarray], metadata: dict[str, Any]) -> DMDModel:
    if not isinstance(metadata, dict):
        raise FileFormatError(f"DMDModel metadata 'fields' must be a table; the file holds "
                              f"{type(metadata).__name__}.")
    try:
        dt = _scalar(metadata, "dt", float)
        if dt <= 0:
            raise FileFormatError(f"DMDModel metadata field 'dt' must be > 0; the file holds {dt}.")
        alpha = _scalar(metadata, "alpha", float, low=0.0)
        alpha_relative = _scalar(metadata, "alpha_relative", float, low=0.0)
        delays = _scalar(metadata, "delays", int, low=1)
        rank = _scalar(metadata, "rank", int, low=1, optional=True)
        n_nodes = _scalar(metadata, "n_nodes", int, low=1)
        n_pairs = _scalar(metadata, "n_pairs", int, low=1)
        has_B, has_basis = bool(metadata["has_B"]), bool(metadata["has_basis"])
    except KeyError as exc:
        raise FileFormatError(f"DMDModel metadata lacks the field {exc.args[0]!r}.") from exc
    required = ["A", "field_map", "residual_covariance", "initial_state"]
    required += ["B"] * has_B + ["basis"] * has_basis
    missing = [name for name in required if name not in arrays]
    if missing:
        raise FileFormatError(f"The file lacks the array(s) {missing}: it is truncated or foreign.")
    A = arrays["A"]
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise FileFormatError(f"Array 'A' must be square; the file holds shape {A.shape}.")
    n = A.shape[0]
    # The state size follows from the scalars: the POD rank, or the stacked window.
    expected_states = rank if rank is not None else n_nodes * delays
    if n != expected_states or (rank is None) == has_basis:
        raise FileFormatError(
            f"Array 'A' is {n} x {n}, but the metadata (n_nodes={n_nodes}, delays={delays}, "
            f"rank={rank}, basis={'yes' if has_basis else 'no'}) implies {expected_states} states: "
            "the file is corrupted.")
    B = None
    if has_B:
        B = arrays["B"]
        _expect_shape("B", B, (n, B.shape[1] if B.ndim == 2 else -1))
    basis = None
    if has_basis:
        basis = _expect_shape("basis", arrays["basis"], (n_nodes * delays, n))
    return DMDModel(
        A=read_only(_expect_shape("A", A, (n, n))),
        B=None if B is None else read_only(B),
        dt=dt,
        alpha=alpha,
        alpha_relative=alpha_relative,
        delays=delays,
        rank=rank,
        n_nodes=n_nodes,
        field_map=read_only(_expect_shape("field_map", arrays["field_map"], (n_nodes, n))),
        basis=None if basis is None else read_only(basis),
        residual_covariance=read_only(
            _expect_shape("residual_covariance", arrays["residual_covariance"], (n, n))
        ),
        n_pairs=n_pairs,
        initial_state=read_only(_expect_shape("initial_state", arrays["initial_state"], (n,))),
    )


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
        ``model`` is not a supported result type.

    Examples
    --------
    >>> import numpy as np, pathlib, tempfile, powerline_control as plc
    >>> dmd = plc.fit_dmd(np.array([[0.9 ** k for k in range(20)]]), dt=0.1)
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "line.npz"
    >>> plc.save_model(path, dmd)
    >>> bool(np.array_equal(plc.load_model(path).A, dmd.A))
    True
    """
    if not isinstance(model, DMDModel):
        raise InputError(
            f"The 'model' parameter must be a DMDModel. Got {type(model).__name__} instead."
        )
    arrays, metadata = _dmd_to_arrays(model)
    header = {"format": _DMD_FORMAT, "version": _DMD_VERSION, "fields": metadata}
    np.savez(path, **arrays, **{_METADATA_KEY: np.array(json.dumps(header))})


def load_model(path: str | os.PathLike[str]) -> DMDModel:
    """Read a model written by :func:`save_model`; the round trip is exact.

    Parameters
    ----------
    path : str or path-like
        File to read.

    Returns
    -------
    DMDModel
        The saved model, bit for bit.

    Raises
    ------
    FileFormatError
        The file is missing pieces, truncated, corrupted, of another format or version.
    FileNotFoundError
        No such file.

    Examples
    --------
    See :func:`save_model`.
    """
    name = os.fspath(path)
    # Only zip archives are candidates: anything else (a .npy array, a pickle, text) is refused
    # before numpy sees it, so numpy's advice to load "unsafely" with allow_pickle never reaches
    # the user; and np.load runs with allow_pickle=False, so no object array is ever unpickled.
    with open(path, "rb") as handle:
        is_zip = zipfile.is_zipfile(handle)
    if not is_zip:
        raise FileFormatError(f"{name!r} is not a powerline_control .npz file (not a zip archive).")
    try:
        # Open the file ourselves so that it is closed even when numpy fails half-way.
        with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as archive:
            arrays = {key: archive[key] for key in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        reason = "an entry needs pickle, which is refused" if "allow_pickle" in str(exc) \
            else str(exc)
        raise FileFormatError(
            f"Cannot read {name!r} as a powerline_control .npz file: {reason}"
        ) from exc
    if _METADATA_KEY not in arrays:
        raise FileFormatError(
            f"{os.fspath(path)!r} has no {_METADATA_KEY!r} entry: not a powerline_control file."
        )
    try:
        header = json.loads(str(arrays.pop(_METADATA_KEY)))
        file_format, version, fields = header["format"], header["version"], header["fields"]
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise FileFormatError(f"The metadata of {os.fspath(path)!r} is corrupted: {exc}") from exc
    if file_format != _DMD_FORMAT:
        raise FileFormatError(
            f"{os.fspath(path)!r} holds a {file_format!r}; load_model reads {_DMD_FORMAT!r}."
        )
    if version != _DMD_VERSION:
        raise FileFormatError(
            f"{os.fspath(path)!r} has format version {version!r}; this powerline_control reads "
            f"version {_DMD_VERSION}. Upgrade powerline_control or re-save the model."
        )
    return _dmd_from_arrays(arrays, fields)
