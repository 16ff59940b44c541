"""Argument checks at the public boundary, in one place.

Each check returns the validated (never silently coerced) value or raises
:class:`~powerline_control.errors.InputError` with a message that names the parameter, what is
allowed and the value received, in the style of scikit-learn's parameter validation.
"""

from __future__ import annotations

import difflib
import functools
import inspect
import numbers
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from .errors import InputError, SaturationWarning

__all__ = [
    "check_real",
    "check_int",
    "check_bool",
    "check_bare_line",
    "check_choice",
    "check_array",
    "check_snapshot_matrix",
    "check_square",
    "check_psd",
    "check_rng",
    "check_indices",
    "read_only",
    "MEMORY_BUDGET_BYTES",
    "WORK_BUDGET",
    "check_budget",
    "check_budget_value",
    "check_write_path",
    "check_forwarded_options",
    "checked_keywords",
]

# Default budgets for what one public call may commit before it starts (documented in
# docs/conventions.md). A user with a bigger machine raises them per call (``memory_budget=``)
# or for the session with the environment variables below; the point is a clear refusal with
# the number, instead of a 12 GiB allocation or a loop that runs for an hour.
MEMORY_BUDGET_BYTES = int(float(os.environ.get("POWERLINE_CONTROL_MEMORY_BUDGET", 4 * 2**30)))
WORK_BUDGET = int(float(os.environ.get("POWERLINE_CONTROL_WORK_BUDGET", 1e12)))


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


def check_bool(name: str, value: object) -> bool:
    """Return ``value`` if it is a bool (``True``/``False`` or a NumPy bool), else refuse.

    A flag given as ``'no'``, ``0`` or ``None`` would be silently truthy or falsy.

    Examples
    --------
    >>> check_bool("warn", False)
    False
    """
    if not isinstance(value, bool | np.bool_):
        raise InputError(
            f"The {name!r} parameter must be True or False. Got {_describe(value)} "
            f"of type {type(value).__name__} instead."
        )
    return bool(value)


def check_bare_line(model: object, why: str) -> None:
    """Refuse a line model that carries a robot (``mdr=``) where the robot is given apart.

    ``why`` says what the call does with the robot instead (it ends the message).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> check_bare_line(SimpleNamespace(mdr=None), "the robot is the 'robot' argument")
    """
    robot = getattr(model, "mdr", None)
    if robot is not None:
        raise InputError(
            "The 'model' parameter must be the bare line (mdr=None): "
            f"{why}. Got a model with a robot at {robot.position:g} m; build it without mdr."
        )


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
    missing measurements); infinity never is. Where a real array is asked for (``dtype=float``,
    the default) complex input is refused rather than cast (the cast would silently drop the
    imaginary part), and so is a boolean array (a mask passed by mistake would become 0/1 data).

    Examples
    --------
    >>> check_array("x", [1, 2]).tolist()
    [1.0, 2.0]
    >>> check_array("x", [1 + 2j])
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: The 'x' parameter must be real...
    """
    real_wanted = np.dtype(dtype).kind != "c"
    try:
        raw = value if isinstance(value, np.ndarray) else np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"The {name!r} parameter must be a numeric array. Got {_describe(value)} instead."
        ) from exc
    if real_wanted and np.iscomplexobj(raw):
        raise InputError(
            f"The {name!r} parameter must be real: got a complex array of shape {raw.shape}, "
            "whose imaginary part would be lost. Pass its real part (x.real), or stack the real "
            "and imaginary parts (np.vstack([x.real, x.imag])) if both carry data."
        )
    if raw.dtype.kind in "US":
        raise InputError(
            f"The {name!r} parameter must be a numeric array. Got {_describe(value)} (text) "
            "instead."
        )
    if raw.dtype == np.bool_:
        raise InputError(
            f"The {name!r} parameter must be a numeric array. Got a boolean array of shape "
            f"{raw.shape} (a mask?); convert it explicitly (x.astype(float)) if 0/1 is meant."
        )
    # Budget before the conversion: converting (an int array, a broadcast view) copies, and a
    # 0-byte broadcast view of 1e9 entries would become 8 GB here.
    itemsize = np.dtype(dtype).itemsize
    if raw.dtype != np.dtype(dtype) or 0 in raw.strides:
        check_budget(f"The {name!r} parameter's {raw.size:.3g} entries as {np.dtype(dtype)}",
                     nbytes=float(raw.size) * itemsize, parameter=name, value=raw.shape,
                     fix="pass a smaller array")
    try:
        array = np.asarray(raw, dtype=dtype)
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
    if not _all_finite(array, allow_nan):
        what = "infinite" if allow_nan else "NaN or infinite"
        count = ""
        if array.size <= 10**7:   # counting allocates a mask the size of the input
            bad = np.isinf(array) if allow_nan else ~np.isfinite(array)
            count = f"{int(np.count_nonzero(bad))} "
        raise InputError(
            f"The {name!r} parameter contains {count}{what} value(s); all entries must be "
            "finite."
        )
    return array


# Arrays up to this many entries are checked through a mask (a 10-sample packet of a filter's
# inputs: 1.5 instead of 5 us); larger ones through reductions, which allocate nothing.
_SMALL = 4096


def _all_finite(array: np.ndarray, allow_nan: bool = False) -> bool:
    """Whether every entry is finite (NaN allowed with ``allow_nan``), without a mask beyond
    ``_SMALL`` entries.

    Reductions allocate nothing the size of the input (``~np.isfinite(x)`` would: 37 GiB of
    bools on a broadcast view): the maximum is NaN if any entry is, and +-inf show in the
    maximum and minimum (of the real and imaginary parts for complex input).
    """
    if array.size == 0:
        return True
    if array.size <= _SMALL:   # a mask of a small array costs less than the two reductions
        return not bool(np.isinf(array).any()) if allow_nan else bool(np.isfinite(array).all())
    parts = (array.real, array.imag) if np.iscomplexobj(array) else (array,)
    for part in parts:
        with np.errstate(invalid="ignore"):
            if allow_nan:
                high, low = np.fmax.reduce(part, axis=None), np.fmin.reduce(part, axis=None)
                if np.isinf(high) or np.isinf(low):
                    return False
            elif not (np.isfinite(part.max()) and np.isfinite(part.min())):
                return False
    return True


def check_snapshot_matrix(name: str, value: object) -> np.ndarray:
    """Return a real ``(n_nodes, n_samples)`` snapshot matrix; refuse one that looks transposed.

    Far more rows than columns with few columns (``n_rows >= 10 n_cols`` and ``n_cols < 100``)
    is a record of a few nodes passed with time along the rows: fitted as given it would make a
    model of thousands of states from a handful of pairs.

    Examples
    --------
    >>> check_snapshot_matrix("X", np.ones((2, 50))).shape
    (2, 50)
    >>> check_snapshot_matrix("X", np.ones((50, 2)))
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: The 'X' parameter has 50 rows (states) but only 2 ...
    """
    X = check_array(name, value, ndim=2)
    if X.shape[0] >= 10 * X.shape[1] and X.shape[1] < 100:
        raise InputError(
            f"The {name!r} parameter has {X.shape[0]} rows (states) but only {X.shape[1]} "
            "columns (samples): it looks transposed. The layout is (n_nodes, n_samples), one "
            "column per sample; pass its transpose (.T) if the rows are samples."
        )
    if X.shape[0] < 1 or X.shape[1] < 2:
        raise InputError(
            f"The {name!r} parameter must be a (n_nodes, n_samples) snapshot matrix with at "
            f"least one row and two samples. Got shape {X.shape} instead."
        )
    return X


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


def check_write_path(value: object, *, name: str = "path",
                     written: Sequence[str | os.PathLike] = ()) -> Path:
    """The one check of a file a public function is about to write: refuse, before writing,
    anything the operating system would answer with a bare ``OSError``.

    ``value`` must be a non-empty ``str``, ``bytes`` or ``os.PathLike``; neither it nor any of
    the files actually ``written`` (when the writer adds a suffix: ``np.savez`` appends
    ``.npz``) may be a folder, FIFO or device; their folder must exist and be writable, and an
    existing file must be writable. The message names the parameter ``name``.

    Parameters
    ----------
    value : str, bytes or os.PathLike
        The path given.
    name : str
        The parameter's name, for messages.
    written : sequence of path-like
        The files written, when they differ from ``value``.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import tempfile
    >>> folder = tempfile.mkdtemp()
    >>> check_write_path(os.path.join(folder, "r.html")).name
    'r.html'
    >>> check_write_path(folder)
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: The 'path' parameter must name a file to write; ...
    >>> check_write_path(5)
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: The 'path' parameter must be a file path (str or \
os.PathLike). Got 5 of type int instead.
    """
    if isinstance(value, bytes):
        value = os.fsdecode(value)
    if not isinstance(value, str | os.PathLike):
        raise InputError(f"The {name!r} parameter must be a file path (str or os.PathLike). Got "
                         f"{_describe(value)} of type {type(value).__name__} instead.")
    path = Path(value)
    if not os.fspath(value):
        raise InputError(f"The {name!r} parameter must not be empty ('' would be the working "
                         "folder): give a file name.")
    for candidate in dict.fromkeys([os.fspath(value), *map(os.fspath, written)]):
        if os.path.exists(candidate) and not os.path.isfile(candidate):
            kind = "a folder" if os.path.isdir(candidate) else "not a regular file (a FIFO?)"
            raise InputError(f"The {name!r} parameter must name a file to write; {candidate!r} "
                             f"is {kind}. Give a file name, e.g. os.path.join(folder, "
                             f"{'report.html' if kind == 'a folder' else 'out.csv'!r}).")
        parent = os.path.dirname(os.path.abspath(candidate))
        if not os.path.isdir(parent):
            raise InputError(f"The {name!r} parameter {os.fspath(value)!r} is in the folder "
                             f"{parent!r}, which does not exist; create it first.")
        target, what = ((candidate, "file") if os.path.exists(candidate)
                        else (parent, "folder"))
        if not os.access(target, os.W_OK):
            raise InputError(f"The {name!r} parameter {os.fspath(value)!r} cannot be written: "
                             f"the {what} {target!r} is not writable.")
    return path


def _keyword_names(function: Callable) -> list[str]:
    """The parameters of ``function`` that a caller may give by keyword."""
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return [name for name, parameter in inspect.signature(function).parameters.items()
            if parameter.kind in kinds]


def check_forwarded_options(
    where: Callable,
    options: Mapping[str, object],
    target: Callable,
    *,
    set_here: Sequence[str] = (),
    why: str = "",
) -> dict[str, object]:
    """The one check of the keywords a public ``**options`` function passes on to ``target``.

    Run it first, before any work: a misspelt name (``wind_curv=``) is refused by name with
    the names that would work (``where``'s own parameters and ``target``'s, less ``set_here``)
    and the nearest one, instead of escaping later as Python's ``TypeError`` from a function the
    user did not call. A name in ``set_here`` (``where`` passes it to ``target`` itself) is
    refused with ``why``.

    Parameters
    ----------
    where : callable
        The public function that takes ``**options`` (named in the message).
    options : mapping
        The keywords it received in ``**options``.
    target : callable
        The function it passes them on to.
    set_here : sequence of str
        ``target``'s parameters that ``where`` sets itself.
    why : str
        Why those are set by ``where`` (one clause, for the message).

    Returns
    -------
    dict
        ``options``, as a new dict.

    Examples
    --------
    >>> def inner(x, *, curve="cigre", k=1.0):
    ...     return x
    >>> def outer(x, *, settle=5.0, **options):
    ...     return inner(x, **check_forwarded_options(outer, options, inner, set_here=["x"]))
    >>> outer(1.0, curve="ieee")
    1.0
    >>> outer(1.0, curv="ieee")
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: outer got an unknown keyword argument 'curv' (did you \
mean 'curve'?). Accepted: its own parameters x, settle; and inner's options curve, k.
    """
    name = getattr(where, "__qualname__", getattr(where, "__name__", str(where)))
    target_name = getattr(target, "__name__", str(target))
    own = [n for n in _keyword_names(where) if n not in ("self", "cls")]
    forwarded = [n for n in _keyword_names(target) if n not in set_here and n not in own]
    for key in options:
        if key in set_here:
            raise InputError(f"The {key!r} option cannot be passed to {name}: it sets it "
                             f"itself{' (' + why + ')' if why else ''}.")
        if key not in forwarded:
            raise InputError(
                f"{name} got an unknown keyword argument {key!r}{_nearest(key, own + forwarded)}"
                f". Accepted: its own parameters {', '.join(own)}; and {target_name}'s options "
                f"{', '.join(forwarded)}.")
    return dict(options)


def _nearest(key: object, names: Sequence[str]) -> str:
    """`` (did you mean 'name'?)`` for the accepted name nearest a misspelt one, or ``''``."""
    close = difflib.get_close_matches(str(key), list(names), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def checked_keywords(function: Callable) -> Callable:
    """Decorator: a keyword ``function`` does not take is an ``InputError``, before any work.

    Python's own refusal of a misspelt keyword (``calibrat=True``) is a ``TypeError`` that
    names neither what is accepted nor the nearest name; this one names the keyword, the nearest
    accepted name and every accepted one, like :func:`check_forwarded_options` (which serves the
    functions that take ``**options``; a function with ``**`` parameters cannot be decorated).
    Positional arguments and everything else are left to the call itself.

    Examples
    --------
    >>> @checked_keywords
    ... def run(model, *, duration=10.0, calibration=2.0):
    ...     return duration + calibration
    >>> run(None, calibration=1.0)
    11.0
    >>> run(None, calibrat=1.0)
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: run got an unknown keyword argument 'calibrat' (did \
you mean 'calibration'?). Accepted: model, duration, calibration.
    """
    parameters = inspect.signature(function).parameters.values()
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        raise TypeError(f"{function.__qualname__} takes **options: check them with "
                        "check_forwarded_options instead.")
    accepted = _keyword_names(function)
    known = frozenset(accepted)
    name = function.__qualname__

    @functools.wraps(function)
    def checked(*args, **kwargs):
        for key in kwargs:
            if key not in known:
                raise InputError(
                    f"{name} got an unknown keyword argument {key!r}"
                    f"{_nearest(key, accepted)}. Accepted: {', '.join(accepted)}.")
        return function(*args, **kwargs)

    return checked


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` (made C-contiguous) marked read-only: results hand out arrays nobody can change."""
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


def _format_bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} TiB"  # pragma: no cover


# Passed by callers whose public signature has no ``memory_budget``/``work_budget`` argument
# (the default): the refusal then must not suggest an argument the user cannot give.
_NOT_GIVEN = object()


def check_budget(
    what: str,
    *,
    nbytes: float = 0.0,
    flops: float = 0.0,
    parameter: str,
    value: object,
    fix: str,
    memory_budget: float | None | object = _NOT_GIVEN,
    work_budget: float | None | object = _NOT_GIVEN,
) -> None:
    """Refuse, before allocating, a call whose estimated memory or work exceeds the budget.

    ``nbytes`` and ``flops`` are estimates made from the arguments alone; ``parameter`` and
    ``value`` name what drives them and ``fix`` says how to reduce it. Budgets default to
    :data:`MEMORY_BUDGET_BYTES` (4 GiB) and :data:`WORK_BUDGET` (1e12 floating-point operations,
    minutes on one core). A caller whose public signature takes ``memory_budget`` (or
    ``work_budget``) passes it on, even when ``None``; the refusal then names that argument, and
    otherwise only the environment variable (read when the package is imported).

    Examples
    --------
    >>> check_budget("the mass matrix", nbytes=8 * 1000**2, parameter="n_elements",
    ...              value=1000, fix="use fewer elements")
    >>> check_budget("the mass matrix", nbytes=8 * 10**6 * 10**6, parameter="n_elements",
    ...              value=10**6, fix="use fewer elements")
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: ...
    """
    if memory_budget is not _NOT_GIVEN:
        check_budget_value("memory_budget", memory_budget)
    if work_budget is not _NOT_GIVEN:
        check_budget_value("work_budget", work_budget)
    memory_hint = _budget_hint("memory_budget", memory_budget, "POWERLINE_CONTROL_MEMORY_BUDGET")
    work_hint = _budget_hint("work_budget", work_budget, "POWERLINE_CONTROL_WORK_BUDGET")
    memory_budget = (MEMORY_BUDGET_BYTES if memory_budget is None or memory_budget is _NOT_GIVEN
                     else memory_budget)
    work_budget = WORK_BUDGET if work_budget is None or work_budget is _NOT_GIVEN else work_budget
    if nbytes > memory_budget:
        raise InputError(
            f"{what} would need about {_format_bytes(nbytes)} of memory (the {parameter!r} "
            f"parameter is {_describe(value)}), over the budget of {_format_bytes(memory_budget)}. "
            f"To fix: {fix}, or raise the budget ({memory_hint})."
        )
    if flops > work_budget:
        raise InputError(
            f"{what} would need about {flops:.2g} floating-point operations (the {parameter!r} "
            f"parameter is {_describe(value)}), over the budget of {work_budget:.2g}. "
            f"To fix: {fix}, or raise the budget ({work_hint})."
        )


def check_budget_value(name: str, value: object) -> float | None:
    """``None`` or a budget (a limit in bytes or operations): a finite real number > 0.

    A budget is a guard: ``nan`` would make every ``estimate > budget`` comparison false and
    switch the guard off, ``inf`` says the same in words the caller did not mean, and a string
    (``"1e6"``) or a bool is not a number. Validate every budget before anything is estimated.

    Examples
    --------
    >>> check_budget_value("memory_budget", 2**30)
    1073741824.0
    >>> check_budget_value("memory_budget", float("nan"))
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: The 'memory_budget' parameter must be finite...
    """
    if value is None:
        return None
    return check_real(name, value, low=0.0)


def _budget_hint(argument: str, given: object, variable: str) -> str:
    if given is _NOT_GIVEN:
        return f"the environment variable {variable}, set before importing powerline_control"
    return f"{argument}=... or the environment variable {variable}"


# --------------------------------------------------------------------------- systems and noise
# (shared by observability, estimate and sensors: one home for the system and covariance rules)


def check_discrete_system(name: str, sys: object):
    """Return ``sys`` if it is a finite discrete-time ``control.StateSpace`` with states.

    Examples
    --------
    >>> import control as ct
    >>> check_discrete_system("sys", ct.ss([[0.5]], [[1.0]], [[1.0]], 0, dt=1.0)).nstates
    1
    """
    import control as ct  # the leaf stays importable without python-control's start-up cost

    if not isinstance(sys, ct.StateSpace):
        raise InputError(
            f"The {name!r} parameter must be a discrete-time control.StateSpace. "
            f"Got an object of type {type(sys).__name__} instead."
        )
    if sys.dt is None or (sys.dt is not True and sys.dt == 0):
        raise InputError(
            f"The {name!r} parameter must be a discrete-time system (dt > 0 or dt=True). "
            f"Got a continuous-time system (dt={sys.dt!r}); discretise it first, e.g. with "
            "sys.sample(dt) or LineModel.to_statespace(dt=...)."
        )
    for label in ("A", "B", "C", "D"):
        matrix = np.asarray(getattr(sys, label))
        if not np.all(np.isfinite(matrix)):
            raise InputError(
                f"The {name!r} parameter has {int(np.count_nonzero(~np.isfinite(matrix)))} "
                f"NaN or infinite entries in its {label} matrix; the model must be finite."
            )
    if sys.nstates == 0:
        raise InputError(f"The {name!r} parameter must have at least one state. Got 0 states.")
    return sys


def check_covariance(
    name: str,
    value: object,
    size: int,
    *,
    index: np.ndarray | None = None,
    definite: bool = False,
) -> np.ndarray:
    """The one rule for noise covariances (``Q``, ``R``, ``P0``): a ``(size, size)`` matrix from

    * a scalar variance (the same for every signal, uncorrelated),
    * a ``(size,)`` vector of variances (one per signal, uncorrelated), or
    * a full ``(size, size)`` symmetric matrix.

    Entries must be finite; the matrix positive semidefinite, or positive definite with
    ``definite`` (a measurement-noise covariance used by a Riccati equation: a sensor without
    noise makes it singular). With ``index`` the value describes all ``size`` signals and the rows
    and columns of ``index`` are returned (checked on those rows).

    Examples
    --------
    >>> check_covariance("R", 2.0, 2).tolist()
    [[2.0, 0.0], [0.0, 2.0]]
    >>> check_covariance("R", [1.0, 3.0, 5.0], 3, index=np.array([2, 0])).tolist()
    [[5.0, 0.0], [0.0, 1.0]]
    """
    what = "positive" if definite else "non-negative"
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        variance = float(value)
        if not np.isfinite(variance) or variance < 0 or (definite and variance == 0):
            raise InputError(
                f"The {name!r} parameter must be a finite {what} variance. Got {variance!r}."
            )
        out = variance * np.eye(size)
    else:
        array = check_array(name, value, ndim=(1, 2))
        shape_ok = array.shape == (size,) if array.ndim == 1 else array.shape == (size, size)
        if not shape_ok:
            raise InputError(
                f"The {name!r} parameter has the wrong shape: expected a scalar, ({size},) "
                f"variances or a ({size}, {size}) matrix but found {array.shape}."
            )
        if array.ndim == 1:
            if np.any(array < 0) or (definite and np.any(array == 0)):
                raise InputError(
                    f"The {name!r} parameter must contain {what} variances. "
                    f"Got a smallest value of {array.min():.3g}."
                )
            out = np.diag(array)
        else:
            out = check_psd(name, array, size)
    if index is not None:
        out = out[np.ix_(index, index)]
    out = (out + out.T) / 2
    # Scalars and vectors were checked > 0 above; only a full matrix needs the factorisation.
    if definite and not np.isscalar(value) and np.ndim(value) == 2 and out.size:
        try:
            np.linalg.cholesky(out)
        except np.linalg.LinAlgError:
            smallest = float(np.linalg.eigvalsh(out).min())
            raise InputError(
                f"The {name!r} parameter must be positive definite (every sensor needs noise: a "
                f"noise-free or perfectly correlated pair makes the Riccati equation singular). "
                f"Its smallest eigenvalue is {smallest:.3g}."
            ) from None
    return out


def check_field_map(field_map: object, n: int) -> np.ndarray | None:
    """``None`` or an ``(n_nodes, n)`` map from the model state to the field of interest.

    Examples
    --------
    >>> check_field_map([[1.0, 0.0]], 2).shape
    (1, 2)
    """
    if field_map is None:
        return None
    matrix = check_array("field_map", field_map, ndim=2)
    if matrix.shape[1] != n:
        raise InputError(
            "The 'field_map' parameter has the wrong shape: expected (n_nodes, "
            f"{n}) (one column per model state) but found {matrix.shape}."
        )
    return matrix


# The saturation rule of warn_if_saturated (its docstring gives the numbers behind each).
_SATURATION_MIN_SAMPLES, _SATURATION_SHARE, _SATURATION_MIN_COUNT, _SATURATION_PILE_UP = \
    50, 0.005, 5, 5


def warn_if_saturated(where: str, values: object, labels: object = None, *,
                      stacklevel: int = 2) -> list:
    """Warn :class:`~powerline_control.errors.SaturationWarning` for each clipped channel.

    A channel (row) is clipped at a level when that level is its largest or smallest finite
    sample, it is not 0 (rest or zero padding), at least 5 samples and 0.5 % of the row's
    samples hold exactly that value, and at least 5 times as many as hold the nearest other
    value (a quantised signal's extreme levels fill alike, a clip piles samples up on one).
    A continuous noisy signal reaches its extreme once; a sine clipped at 99 % of its peak
    still keeps about 4.5 % of its samples on each clip level. Rows with fewer than 50 finite
    samples, or constant ones, are not judged. Cost: a few passes over ``values``.

    Parameters
    ----------
    where : str
        Start of the message: the parameter or file (e.g. ``"The 'measurements' parameter"``).
    values : array_like, shape (n_channels, n_t)
        The channels; NaN = missing.
    labels : sequence of str, optional
        How the message names each channel (default ``"row i"``).
    stacklevel : int, default 2
        Passed to :func:`warnings.warn` (2: the caller of this function).

    Returns
    -------
    list of (int, float, float)
        For each warning: the row, the clipped level and the share of its samples there.

    Examples
    --------
    >>> import warnings
    >>> y = np.clip(np.sin(0.1 * np.arange(1000)), -1.0, 0.6)[None, :]
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     found = warn_if_saturated("The 'y' parameter", y)
    >>> [(row, level, round(share, 2)) for row, level, share in found], len(caught)
    ([(0, 0.6, 0.29)], 1)
    """
    v = np.asarray(values, dtype=float)
    v = v[None, :] if v.ndim == 1 else v
    finite = np.isfinite(v)
    n = finite.sum(axis=1)
    found = []
    for upper in (True, False):
        level = np.where(finite, v, -np.inf if upper else np.inf)
        level = level.max(axis=1) if upper else level.min(axis=1)
        count = np.count_nonzero(v == level[:, None], axis=1)
        suspect = ((n >= _SATURATION_MIN_SAMPLES) & (count < n) & (level != 0.0)
                   & (count >= np.maximum(_SATURATION_MIN_COUNT, _SATURATION_SHARE * n)))
        for i in np.flatnonzero(suspect):
            rest = v[i][finite[i] & (v[i] != level[i])]
            nearest = rest.max() if upper else rest.min()
            if count[i] >= _SATURATION_PILE_UP * np.count_nonzero(rest == nearest):
                found.append((int(i), float(level[i]), float(count[i] / n[i]), int(count[i])))
    found.sort()
    for i, level, share, count in found:
        label = labels[i] if labels is not None else f"row {i}"
        warnings.warn(
            f"{where}: {label} is clipped at {level:.6g} m: {share:.1%} of its samples "
            f"({count} of {int(n[i])}) hold exactly that value, the flat tops of a saturated "
            "sensor (its range reached), which a model or filter takes for the motion. Use a "
            "sensor with a larger range there, or leave the channel out.",
            SaturationWarning, stacklevel=stacklevel + 1)
    return [(i, level, share) for i, level, share, _ in found]
