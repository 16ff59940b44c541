"""Argument checks at the public boundary, in one place.

Each check returns the validated (never silently coerced) value or raises
:class:`~powerline_control.errors.InputError` with a message that names the parameter, what is
allowed and the value received, in the style of scikit-learn's parameter validation.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence

import numpy as np

from .errors import InputError

__all__ = [
    "check_real",
    "check_int",
    "check_choice",
    "check_array",
    "check_square",
    "check_psd",
    "check_rng",
    "check_indices",
    "read_only",
]


def _describe(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def check_real(
    name: str,
    value: object,
    *,
    low: float | None = None,
    high: float | None = None,
    low_inclusive: bool = False,
    high_inclusive: bool = True,
) -> float:
    """Return ``value`` as a float if it is a finite real number inside the given bounds.

    ``low`` is exclusive unless ``low_inclusive``; ``high`` is inclusive unless told otherwise.
    Booleans are rejected: ``True`` is not a tension.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(
            f"The {name!r} parameter must be a real number. Got {_describe(value)} "
            f"of type {type(value).__name__} instead."
        )
    value = float(value)
    if not np.isfinite(value):
        raise InputError(f"The {name!r} parameter must be finite. Got {value!r} instead.")
    if low is not None and (value < low or (value == low and not low_inclusive)):
        op = ">=" if low_inclusive else ">"
        raise InputError(f"The {name!r} parameter must be {op} {low:g}. Got {value!r} instead.")
    if high is not None and (value > high or (value == high and not high_inclusive)):
        op = "<=" if high_inclusive else "<"
        raise InputError(f"The {name!r} parameter must be {op} {high:g}. Got {value!r} instead.")
    return value


def check_int(name: str, value: object, *, low: int | None = None, high: int | None = None) -> int:
    """Return ``value`` as an int if it is an integer (not a float, not a bool) in [low, high]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(
            f"The {name!r} parameter must be an integer. Got {_describe(value)} "
            f"of type {type(value).__name__} instead."
        )
    value = int(value)
    if low is not None and value < low:
        raise InputError(f"The {name!r} parameter must be >= {low}. Got {value} instead.")
    if high is not None and value > high:
        raise InputError(f"The {name!r} parameter must be <= {high}. Got {value} instead.")
    return value


def check_choice(name: str, value: object, choices: Sequence[str]) -> str:
    """Return ``value`` if it is one of the allowed strings."""
    if not isinstance(value, str) or value not in choices:
        allowed = ", ".join(repr(c) for c in choices)
        raise InputError(
            f"The {name!r} parameter must be one of {allowed}. Got {_describe(value)} instead."
        )
    return value


def check_array(
    name: str,
    value: object,
    *,
    ndim: int | tuple[int, ...] | None = None,
    shape: tuple[int | None, ...] | None = None,
    allow_nan: bool = False,
    dtype: type = float,
) -> np.ndarray:
    """Return ``value`` as a float (or complex) ndarray after checking dimensions and finiteness.

    ``shape`` entries that are ``None`` are free. NaN is allowed only when ``allow_nan`` (for
    missing measurements); infinity never is.
    """
    try:
        array = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"The {name!r} parameter must be a numeric array. Got {_describe(value)} instead."
        ) from exc
    if ndim is not None:
        allowed = (ndim,) if isinstance(ndim, int) else ndim
        if array.ndim not in allowed:
            raise InputError(
                f"The {name!r} parameter must be a {' or '.join(map(str, allowed))}-d array. "
                f"Got an array of shape {array.shape} instead."
            )
    if shape is not None:
        ok = array.ndim == len(shape) and all(
            want is None or want == got for want, got in zip(shape, array.shape, strict=False)
        )
        if not ok:
            expected = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
            raise InputError(
                f"The {name!r} parameter has the wrong shape: expected {expected} "
                f"but found {array.shape}."
            )
    bad = np.isinf(array) if allow_nan else ~np.isfinite(array)
    if np.any(bad):
        what = "infinite" if allow_nan else "NaN or infinite"
        raise InputError(
            f"The {name!r} parameter contains {int(np.count_nonzero(bad))} {what} value(s); "
            "all entries must be finite."
        )
    return array


def check_square(name: str, value: object, n: int | None = None) -> np.ndarray:
    """Return a finite square matrix, of size ``n`` when given."""
    matrix = check_array(name, value, ndim=2)
    if matrix.shape[0] != matrix.shape[1] or (n is not None and matrix.shape[0] != n):
        size = "n" if n is None else str(n)
        raise InputError(
            f"The {name!r} parameter must be a square ({size}, {size}) matrix. "
            f"Got shape {matrix.shape} instead."
        )
    return matrix


def check_psd(name: str, value: object, n: int | None = None, *, rtol: float = 1e-10) -> np.ndarray:
    """Return a symmetric positive semidefinite matrix (checked to a relative tolerance)."""
    matrix = check_square(name, value, n)
    scale = max(float(np.max(np.abs(matrix))), np.finfo(float).tiny)
    if np.max(np.abs(matrix - matrix.T)) > rtol * scale:
        raise InputError(f"The {name!r} parameter must be symmetric. Got a non-symmetric matrix.")
    smallest = float(np.linalg.eigvalsh((matrix + matrix.T) / 2).min()) if matrix.size else 0.0
    if smallest < -1e3 * rtol * scale:
        raise InputError(
            f"The {name!r} parameter must be positive semidefinite. "
            f"Its smallest eigenvalue is {smallest:.3g}."
        )
    return matrix


def check_rng(seed: object) -> np.random.Generator:
    """Return a Generator from a Generator, an int seed or None (fresh entropy)."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        return np.random.default_rng()
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise InputError(
            "The 'seed' parameter must be a numpy Generator, a non-negative integer or None. "
            f"Got {_describe(seed)} instead."
        )
    return np.random.default_rng(int(seed))


def check_indices(name: str, value: object, n: int, *, allow_empty: bool = False) -> np.ndarray:
    """Return distinct integer indices into ``0..n-1`` (in the order given) as an int array.

    Used for sensor, node and candidate lists. Booleans, floats and strings are rejected, as is
    a bare integer where a list is expected.
    """
    if isinstance(value, str | numbers.Integral) or not isinstance(value, Sequence | np.ndarray):
        raise InputError(
            f"The {name!r} parameter must be a sequence of integer indices. "
            f"Got {_describe(value)} instead."
        )
    items = list(np.ravel(value)) if isinstance(value, np.ndarray) else list(value)
    for item in items:
        if isinstance(item, bool | np.bool_) or not isinstance(item, numbers.Integral):
            raise InputError(
                f"The {name!r} parameter must contain integer indices. "
                f"Got {_describe(item)} of type {type(item).__name__}."
            )
    index = np.asarray(items, dtype=int)
    if index.size == 0 and not allow_empty:
        raise InputError(f"The {name!r} parameter must name at least one index. Got none.")
    if index.size and (index.min() < 0 or index.max() >= n):
        raise InputError(
            f"The {name!r} parameter must hold indices in [0, {n - 1}]. Got {index.tolist()}."
        )
    if np.unique(index).size != index.size:
        raise InputError(f"The {name!r} parameter must not repeat an index. Got {index.tolist()}.")
    return index


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` (made C-contiguous) marked read-only: results hand out arrays nobody can change."""
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array
