"""Parameter studies: run one function over a grid of parameters, serially or on any executor.

Any ``concurrent.futures.Executor`` works: ``ProcessPoolExecutor`` on one machine, or Dask's
(``dask.distributed.Client(...).get_executor()``) across many. The study function must be a
module-level function (picklable for process pools) that takes the grid's keys as keyword
arguments and returns a dict of scalars (numbers, strings, booleans). Results come back in grid
order, whatever the order in which workers finish.

Reproducibility: with ``seed=`` the study passes each grid point its own seed, derived from the
base seed and the point's *values* (not its index, not the worker, not the order of completion),
so a study gives the same table on one core, on a process pool and on a Dask cluster, and a single
point can be re-run alone with :func:`point_seed`. Each point also runs with one BLAS thread by
default: a multi-threaded BLAS splits its sums differently with the number of threads (a Dask
worker, for one, starts with ``OPENBLAS_NUM_THREADS=1``), which changes the last bits of the
results; one thread per point also keeps parallel workers from oversubscribing the cores.
"""

from __future__ import annotations

import csv
import hashlib
import itertools
import json
import math
import numbers
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Executor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._results import TabularResult, to_dataframe
from ._validation import check_budget, check_int, check_real, check_write_path, checked_keywords
from .errors import FileFormatError, InputError

__all__ = ["parameter_grid", "point_seed", "run_study", "StudyResult"]

_FORMAT = "powerline_control.study"
_FORMAT_VERSION = 2   # 2: non-finite floats as {"$float": "nan"}; 1 wrote them as null
_FLOAT_TAG = "$float"
_SEED_KEY = "seed"


def parameter_grid(**axes: Iterable) -> list[dict]:
    """Every combination of the given values (the last axis varies fastest).

    Parameters
    ----------
    **axes : iterable
        Parameter name -> values.

    Returns
    -------
    list of dict
        One dict per grid point, in ``itertools.product`` order.

    Raises
    ------
    InputError
        If an axis is empty, is not a collection of values (a number, or a string, which would
        be split into characters), or the grid would exceed the memory budget (the number of
        points is the product of the axis lengths; checked before any point is built).

    Examples
    --------
    >>> parameter_grid(k=[1, 2], noise=[0.01])
    [{'k': 1, 'noise': 0.01}, {'k': 2, 'noise': 0.01}]
    """
    names = list(axes)
    values = []
    for name in names:
        options = axes[name]
        if isinstance(options, str | bytes | Mapping) or not isinstance(options, Iterable):
            raise InputError(
                f"The grid axis {name!r} must be a list (or other iterable) of values, e.g. "
                f"{name}=[{options!r:.40}]. Got {options!r:.60} of type "
                f"{type(options).__name__}."
            )
        values.append(list(options))
    for name, options in zip(names, values, strict=True):
        if not options:
            raise InputError(f"The grid axis {name!r} has no values.")
    lengths = [len(options) for options in values]
    n_points = math.prod(lengths)
    # One dict per point (~200 bytes plus ~16 per key in CPython) and its list slot: a grid of
    # 1e14 points once filled the memory for minutes before a MemoryError.
    check_budget(
        f"parameter_grid's {n_points:.3g} points", nbytes=n_points * (208.0 + 16 * len(names)),
        parameter="axes", value=" x ".join(f"{name}: {n}" for name, n in zip(names, lengths,
                                                                             strict=True)),
        fix="use fewer values per axis, or evaluate the points lazily with itertools.product",
    )
    return [
        dict(zip(names, combination, strict=True)) for combination in itertools.product(*values)
    ]


def _plain(value: object, where: str) -> object:
    """``value`` as a plain Python scalar (numpy scalars unwrapped), or a clear error."""
    if isinstance(value, np.generic | np.ndarray) and np.ndim(value) == 0:
        value = value.item()
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    shape = f" of shape {np.shape(value)}" if hasattr(value, "shape") else ""
    raise InputError(
        f"{where} must be a scalar (a number, string, boolean or None) so that the study is a "
        f"tidy table. Got {type(value).__name__}{shape}; return summary numbers (e.g. a maximum "
        "or an RMS) instead of arrays."
    )


def _canonical(point: Mapping) -> str:
    """A text form of a grid point that is the same in every process and on every machine."""
    return json.dumps(
        {str(key): _plain(value, f"The grid value {key!r}") for key, value in point.items()},
        sort_keys=True,
        allow_nan=True,
    )


def point_seed(seed: int, point: Mapping) -> int:
    """The seed :func:`run_study` gives the study function at one grid point.

    It depends only on the base ``seed`` and the point's keys and values (SHA-256 of their
    canonical JSON form, mixed by ``numpy.random.SeedSequence``), so it is the same whatever the
    executor, the worker or the order in which points finish.

    Parameters
    ----------
    seed : int
        The study's base seed (>= 0).
    point : dict
        One grid point.

    Returns
    -------
    int
        A seed in [0, 2**63).

    Raises
    ------
    InputError
        If ``seed`` is not a non-negative integer or a value of the point is not a scalar.

    Examples
    --------
    >>> point_seed(7, {"k": 2}) == point_seed(7, {"k": 2})
    True
    >>> point_seed(7, {"k": 2}) != point_seed(7, {"k": 3})
    True
    """
    seed = check_int("seed", seed, low=0)
    if not isinstance(point, Mapping):
        raise InputError(
            f"The 'point' parameter must be a dict of parameter name -> value (one grid point). "
            f"Got {point!r:.60} of type {type(point).__name__}."
        )
    digest = hashlib.sha256(_canonical(point).encode()).digest()
    words = [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 32, 4)]
    state = np.random.SeedSequence(entropy=seed, spawn_key=words).generate_state(1, np.uint64)
    return int(state[0]) >> 1


@dataclass(frozen=True)
class StudyResult(TabularResult):
    """Parameters and results of a study, one row per grid point, in grid order.

    Attributes
    ----------
    parameters : tuple of dict
        The grid points.
    results : tuple of dict
        What the study function returned for each (plain Python scalars).
    seeds : tuple of int or None
        The seed each point received (see :func:`point_seed`), or None for an unseeded study.
    base_seed : int or None
        The study's ``seed`` argument.
    wall_time : float
        Seconds the whole study took (informative only: not compared by ``==``).

    Examples
    --------
    >>> study = run_study(lambda k: {"square": k * k}, parameter_grid(k=[1, 2, 3]))
    >>> study.column("square")
    array([1, 4, 9])
    >>> study.table()[0]
    {'k': 1, 'square': 1}
    """

    parameters: tuple
    results: tuple
    seeds: tuple | None = None
    base_seed: int | None = None
    wall_time: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        for label in ("parameters", "results"):
            rows = getattr(self, label)
            if not isinstance(rows, tuple) or not all(isinstance(r, Mapping) for r in rows):
                raise InputError(
                    f"The {label!r} parameter must be a tuple of dicts (one per grid point). "
                    f"Got {rows!r:.60} of type {type(rows).__name__}."
                )
        if not self.parameters or len(self.results) != len(self.parameters):
            raise InputError(
                f"The 'parameters' and 'results' parameters must hold one dict per grid point, "
                f"at least one. Got {len(self.parameters)} points and {len(self.results)} results."
            )
        if self.seeds is not None and (
            not isinstance(self.seeds, tuple) or len(self.seeds) != len(self.parameters)
            or not all(isinstance(s, numbers.Integral) and not isinstance(s, bool)
                       for s in self.seeds)):
            raise InputError(
                f"The 'seeds' parameter must be None or a tuple of {len(self.parameters)} "
                f"integers (one per grid point). Got {self.seeds!r:.60}."
            )
        if self.base_seed is not None:
            check_int("base_seed", self.base_seed, low=0)
        check_real("wall_time", self.wall_time, low=0.0, low_inclusive=True)
        for label, rows in (("parameters", self.parameters), ("results", self.results)):
            for row in rows:
                for key, value in row.items():
                    if not isinstance(key, str):
                        raise InputError(f"The {label!r} parameter has the key {key!r}; keys "
                                         "must be strings.")
                    _plain(value, f"The {label!r} parameter's value {key!r}")
        _check_keys(self.parameters, self.results, self.seeds is not None)

    @property
    def columns(self) -> list[str]:
        """Column names of the table: parameters, then the seed (if any), then the results."""
        return list(self.table()[0])

    def column(self, name: str) -> np.ndarray:
        """One parameter, seed or result across the grid, as an array.

        Parameters
        ----------
        name : str
            A column name (see :attr:`columns`).

        Returns
        -------
        numpy.ndarray
            One value per grid point, in grid order.

        Raises
        ------
        InputError
            If there is no such column.
        """
        rows = self.table()
        if not isinstance(name, str) or name not in rows[0]:
            raise InputError(f"The 'name' parameter must be a column of the study, one of "
                             f"{sorted(rows[0])}. Got {name!r:.60}.")
        return np.array([row[name] for row in rows])

    def table(self) -> list[dict]:
        """The tidy table: one dict per grid point (parameters, seed, results), in grid order."""
        seeds = self.seeds if self.seeds is not None else (None,) * len(self.parameters)
        rows = []
        for point, seed, result in zip(self.parameters, seeds, self.results, strict=True):
            row = dict(point)
            if seed is not None:
                row[_SEED_KEY] = seed
            row.update(result)
            rows.append(row)
        return rows

    def rows(self) -> list[dict]:
        """Same as :meth:`table` (kept for existing scripts)."""
        return self.table()

    def to_dataframe(self):
        """The table as a ``pandas.DataFrame`` (pandas is optional; this needs it installed)."""
        return to_dataframe(self.table(), "StudyResult", columns=self.columns)

    def to_csv(self, path: str | Path) -> Path:
        """Write the table as CSV (a file to open in any spreadsheet) and return its path."""
        rows = self.table()
        path = _study_path(path, reading=False)
        with path.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        return path

    def to_json(self, path: str | Path | None = None, *, indent: int = 1) -> Path | str:
        """The study as JSON: written to ``path`` (read back with :meth:`from_json`), or the text.

        Lossless: standard JSON has no NaN or infinity, so a non-finite float (a result or a
        parameter) is written as the object ``{"$float": "nan"}`` (``"inf"``, ``"-inf"``), which
        :meth:`from_json` reads back as the float (format version 2; version 1 wrote ``null``).

        Parameters
        ----------
        path : str or Path, optional
            The file to write; None returns the JSON text instead.
        indent : int
            Spaces of indentation per level, 0-16.

        Returns
        -------
        Path or str
            The path written, or the text when ``path`` is None.

        Examples
        --------
        >>> import json
        >>> study = run_study(lambda k: {"square": k * k}, parameter_grid(k=[1, 2]))
        >>> json.loads(study.to_json())["results"]
        [{'square': 1}, {'square': 4}]
        """
        indent = check_int("indent", indent, low=0, high=16)
        text = json.dumps(self.to_dict(), indent=indent, allow_nan=False) + "\n"
        if path is None:
            return text
        path = _study_path(path, reading=False)
        path.write_text(text)
        return path

    def to_dict(self) -> dict:
        """The study as plain JSON types: the document :meth:`to_json` writes.

        Returns
        -------
        dict

        Examples
        --------
        >>> study = run_study(lambda k: {"square": k * k}, parameter_grid(k=[1, 2]))
        >>> study.to_dict()["columns"]
        ['k', 'square']
        """
        return {
            "format": _FORMAT,
            "version": _FORMAT_VERSION,
            "base_seed": self.base_seed,
            "columns": self.columns,
            "parameters": [_encode_floats(point) for point in self.parameters],
            "seeds": None if self.seeds is None else list(self.seeds),
            "results": [_encode_floats(result) for result in self.results],
        }

    @classmethod
    def from_json(cls, path: str | Path) -> StudyResult:
        """Read a study written by :meth:`to_json`.

        Raises
        ------
        FileFormatError
            If the file is not a study written by :meth:`to_json`.
        """
        path = _study_path(path, reading=True)
        try:
            document = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
            raise FileFormatError(f"Cannot read the study file {str(path)!r}: {error}") from error
        if not isinstance(document, dict) or document.get("format") != _FORMAT:
            raise FileFormatError(
                f"The file {str(path)!r} is not a study written by StudyResult.to_json "
                f"(its 'format' must be {_FORMAT!r})."
            )
        if "version" not in document:
            raise FileFormatError(f"The study file {str(path)!r} is incomplete or damaged: it "
                                  "has no 'version'.")
        version = document["version"]
        if version not in (1, _FORMAT_VERSION) or isinstance(version, bool):
            raise FileFormatError(
                f"The study file {str(path)!r} has format version {version!r}; this version of "
                f"powerline_control reads versions 1 and {_FORMAT_VERSION}."
            )
        seeds = document.get("seeds")
        try:
            return cls(
                parameters=tuple(_decode_floats(dict(p)) for p in document["parameters"]),
                results=tuple(_decode_floats(dict(r)) for r in document["results"]),
                seeds=None if seeds is None else tuple(int(s) for s in seeds),
                base_seed=document.get("base_seed"),
            )
        except (KeyError, TypeError, ValueError) as error:
            raise FileFormatError(
                f"The study file {str(path)!r} is incomplete or damaged: {error!r}."
            ) from error


def _study_path(path: object, *, reading: bool) -> Path:
    """``path`` as a Path to a regular file (existing when ``reading``; its folder when writing).

    A FIFO would block the call until another process opens it, a folder cannot be a file, and
    ``''`` would mean the working folder: all refused by name, before anything is opened.
    """
    if not reading:
        return check_write_path(path)
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, str | os.PathLike) or not os.fspath(path):
        raise InputError(
            f"The 'path' parameter must be a non-empty file path (str or os.PathLike). Got "
            f"{path!r:.60} of type {type(path).__name__}."
        )
    path = Path(path)
    if path.exists() and not path.is_file():
        kind = "a folder" if path.is_dir() else "not a regular file (a FIFO or a device)"
        raise InputError(f"The 'path' parameter {str(path)!r} is {kind}; give a file.")
    if not path.exists():
        raise InputError(f"The 'path' parameter {str(path)!r} names no file.")
    return path


def _encode_floats(row: Mapping) -> dict:
    """``row`` with each non-finite float as ``{"$float": "nan" | "inf" | "-inf"}``."""
    return {key: {_FLOAT_TAG: repr(value)} if isinstance(value, float)
            and not math.isfinite(value) else value for key, value in row.items()}


def _decode_floats(row: dict) -> dict:
    """The inverse of :func:`_encode_floats`; any other object in a row is damage."""
    out = {}
    for key, value in row.items():
        if isinstance(value, dict):
            if set(value) != {_FLOAT_TAG} or value[_FLOAT_TAG] not in ("nan", "inf", "-inf"):
                raise ValueError(f"the value of {key!r} is {value!r:.60}, not a scalar")
            value = float(value[_FLOAT_TAG])
        out[key] = value
    return out


def _check_keys(parameters: Sequence[Mapping], results: Sequence[Mapping],
                seeded: bool) -> None:
    """Every point has the first point's keys, every result the first result's keys, and no
    result is named like a parameter (or ``seed`` in a seeded study): the table would lose it."""
    for what, rows in (("grid point", parameters), ("result of grid point", results)):
        if not rows:
            continue
        first = list(rows[0])
        for index, row in enumerate(rows):
            if set(row) != set(first):
                raise InputError(
                    f"The {what} {index} has the keys {sorted(row)} but the {what} 0 has "
                    f"{sorted(first)}: every row of a study table has the same columns."
                )
    if parameters and results:
        names = set(parameters[0]) | ({_SEED_KEY} if seeded else set())
        clash = sorted(names & set(results[0]))
        if clash:
            raise InputError(
                f"The study function returns {clash}, named like the study's parameters (or its "
                "seed): the table would overwrite one with the other. Rename the result keys."
            )


_BLAS_LOCK = threading.Lock()
_BLAS_STATE: dict = {"depth": 0, "limiter": None}


class _BlasThreads:
    """Limit BLAS to ``n`` threads while any study (or point) of this process runs.

    threadpoolctl's limits are process-wide, so overlapping users (points running in a worker
    process's threads, nested studies) share one limit, applied by the first to start and lifted
    by the last to finish. A limit set from a thread other than the main one does not always
    reach OpenBLAS's thread pool, so run_study sets it in the calling thread for the whole study
    (which covers serial runs and thread executors) and worker processes set it per point.
    """

    def __init__(self, n: int | None) -> None:
        self.n = n

    def __enter__(self) -> None:
        if self.n is None:
            return
        with _BLAS_LOCK:
            if _BLAS_STATE["depth"] == 0:
                # threadpoolctl limits the libraries loaded when the limit is set: load SciPy's
                # BLAS (numpy's is loaded already) first, or a study whose first point imports
                # scipy.linalg would run that point with the default thread count.
                import scipy.linalg  # noqa: F401
                from threadpoolctl import threadpool_limits

                _BLAS_STATE["limiter"] = threadpool_limits(limits=self.n, user_api="blas")
            _BLAS_STATE["depth"] += 1

    def __exit__(self, *exc_info: object) -> None:
        if self.n is None:
            return
        with _BLAS_LOCK:
            _BLAS_STATE["depth"] -= 1
            if _BLAS_STATE["depth"] == 0:
                _BLAS_STATE["limiter"].restore_original_limits()
                _BLAS_STATE["limiter"] = None


def _call(
    func: Callable, parameters: Mapping, blas_threads: int | None = None, caller: int = -1
) -> dict:
    """Run one grid point (in the worker) and return its results as plain scalars.

    ``caller`` is the process id of run_study's process, whose limit already applies here when
    the point runs in that same process.
    """
    with _BlasThreads(None if os.getpid() == caller else blas_threads):
        result = func(**parameters)
    if not isinstance(result, Mapping):
        raise InputError(
            f"The study function must return a dict of results. Got "
            f"{type(result).__name__} for {dict(parameters)}."
        )
    return {str(key): _plain(value, f"The result {key!r}") for key, value in result.items()}


@checked_keywords
def run_study(
    func: Callable[..., Mapping],
    grid: Sequence[Mapping],
    executor: Executor | None = None,
    *,
    seed: int | None = None,
    progress: bool | None = None,
    description: str = "study",
    blas_threads: int | None = 1,
) -> StudyResult:
    """Evaluate ``func(**point)`` at every grid point, on ``executor`` if given.

    Parameters
    ----------
    func : callable
        Takes the grid's keys as keyword arguments (and ``seed=`` when ``seed`` is given) and
        returns a dict of scalars. Module-level for process pools and Dask (it is pickled).
    grid : sequence of dict
        Grid points, e.g. from :func:`parameter_grid`.
    executor : concurrent.futures.Executor or None
        Where to run: None runs serially in this process; a ``ProcessPoolExecutor``, a
        ``ThreadPoolExecutor`` or a Dask ``Client.get_executor()`` runs the points in parallel
        (a Dask ``Client`` itself is accepted too: its ``get_executor()`` is used).
    seed : int or None
        Base seed. When given, each point is called with ``seed=point_seed(seed, point)``, which
        depends only on the point's values: the results are identical on every executor.
    progress : bool or None
        Show a progress bar (tqdm, on stderr) as points finish; None shows it only when stderr
        is a terminal.
    description : str
        Label of the progress bar.
    blas_threads : int or None
        BLAS threads while a point runs (default 1, through threadpoolctl): the same arithmetic
        in every worker, hence identical floating-point results on every executor, and no
        oversubscription by parallel workers. None leaves the BLAS library as it is.

    Returns
    -------
    StudyResult
        Results in grid order, whatever the order in which they finished.

    Raises
    ------
    InputError
        If the grid is empty, a point is not a dict of scalars, a point already has a ``seed``
        key while ``seed`` is given, or ``func`` returns something other than a dict of scalars.
        An exception raised by ``func`` propagates with a note naming the grid point.

    Examples
    --------
    >>> from concurrent.futures import ThreadPoolExecutor
    >>> with ThreadPoolExecutor(2) as pool:
    ...     study = run_study(lambda a, b: {"sum": a + b}, parameter_grid(a=[1, 2], b=[10]), pool)
    >>> study.column("sum")
    array([11, 12])

    Seeded: each point draws from its own generator, the same on any executor.

    >>> import numpy as np
    >>> def noisy(k, seed):
    ...     return {"draw": float(np.random.default_rng(seed).normal(k, 0.1))}
    >>> run_study(noisy, parameter_grid(k=[1, 2]), seed=5) == run_study(
    ...     noisy, parameter_grid(k=[1, 2]), seed=5)
    True
    """
    if not callable(func):
        raise InputError(f"The 'func' parameter must be callable. Got {type(func).__name__}.")
    if executor is not None and callable(getattr(executor, "get_executor", None)):
        executor = executor.get_executor()  # a dask.distributed.Client: its futures executor
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise InputError(
            "The 'executor' parameter must be a concurrent.futures.Executor (with "
            f"submit) or None. Got {type(executor).__name__}."
        )
    if seed is not None:
        seed = check_int("seed", seed, low=0)
    if blas_threads is not None:
        blas_threads = check_int("blas_threads", blas_threads, low=1)
    if not isinstance(description, str):
        raise InputError(f"The 'description' parameter must be a string (the progress bar's "
                         f"label). Got {description!r:.60} of type {type(description).__name__}.")
    if progress is not None and not isinstance(progress, bool):
        raise InputError(
            f"The 'progress' parameter must be True, False or None. Got {progress!r}."
        )
    if isinstance(grid, Mapping | str) or not isinstance(grid, Iterable):
        raise InputError(
            "The 'grid' parameter must be a sequence of dicts (one per grid point), e.g. from "
            f"parameter_grid(). Got a {type(grid).__name__}."
        )
    points = []
    for index, point in enumerate(grid):
        if not isinstance(point, Mapping):
            raise InputError(
                f"The 'grid' parameter must hold dicts; point {index} is a "
                f"{type(point).__name__}."
            )
        for key in point:
            # Strings, not necessarily identifiers: a function taking **kwargs accepts dotted
            # names such as "estimation.n_sensors" (the CLI's study verb varies TOML keys).
            if not isinstance(key, str) or not key:
                raise InputError(
                    f"Grid point {index} has the key {key!r}; keys must be parameter names "
                    "(non-empty strings)."
                )
        if seed is not None and _SEED_KEY in point:
            raise InputError(
                f"Grid point {index} has a {_SEED_KEY!r} key and run_study(seed=...) was given: "
                "use one or the other."
            )
        _canonical(point)  # every value a scalar, checked before any work starts
        if points and set(point) != set(points[0]):
            raise InputError(
                f"The 'grid' parameter's point {index} has the keys {sorted(point)} but point 0 "
                f"has {sorted(points[0])}: every grid point needs the same keys (one column "
                "each in the study table)."
            )
        points.append(dict(point))
    if not points:
        raise InputError("The 'grid' parameter is empty: a study needs at least one point.")

    seeds = None if seed is None else tuple(point_seed(seed, point) for point in points)
    calls = (
        points
        if seeds is None
        else [{**point, _SEED_KEY: s} for point, s in zip(points, seeds, strict=True)]
    )
    show = sys.stderr.isatty() if progress is None else progress

    from tqdm import tqdm  # a light import, kept out of the package import path

    start = time.perf_counter()
    results: list[dict | None] = [None] * len(calls)
    caller = os.getpid()
    with (
        _BlasThreads(blas_threads),
        tqdm(total=len(calls), desc=description, unit="point", disable=not show) as bar,
    ):
        if executor is None:
            for index, call in enumerate(calls):
                results[index] = _run_point(func, call, index, points[index], caller)
                _check_result(results, index, points, seeds is not None)
                bar.update()
        else:
            futures = {
                executor.submit(_call, func, call, blas_threads, caller): i
                for i, call in enumerate(calls)
            }
            try:
                for future in as_completed(futures):
                    index = futures[future]
                    results[index] = _result_of(future, index, points[index])
                    _check_result(results, index, points, seeds is not None)
                    bar.update()
            except BaseException:
                for future in futures:
                    future.cancel()
                raise
    return StudyResult(
        parameters=tuple(points),
        results=tuple(results),
        seeds=seeds,
        base_seed=seed,
        wall_time=time.perf_counter() - start,
    )


def _check_result(results: list, index: int, points: list, seeded: bool) -> None:
    """Refuse a result as soon as it arrives if its keys differ from the first result to
    arrive (in whatever order) or clash with a parameter."""
    result = results[index]
    reference = next(r for r in results if r is not None)
    if set(result) != set(reference):
        raise InputError(
            f"The study function returned the keys {sorted(result)} at grid point {index} "
            f"({points[index]}) but {sorted(reference)} at an earlier point: every row of a "
            "study table has the same columns."
        )
    _check_keys([points[0]], [result], seeded)


def _run_point(func: Callable, call: Mapping, index: int, point: Mapping, caller: int) -> dict:
    try:
        return _call(func, call, None, caller)
    except Exception as error:
        error.add_note(f"(run_study: at grid point {index}, {point})")
        raise


def _result_of(future, index: int, point: Mapping) -> dict:
    try:
        return future.result()
    except Exception as error:
        error.add_note(f"(run_study: at grid point {index}, {point})")
        raise
