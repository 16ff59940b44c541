"""Parameter studies: run one function over a grid of parameters, serially or on any executor.

Any ``concurrent.futures.Executor`` works: ``ProcessPoolExecutor`` on one machine, or Dask's
(``dask.distributed.Client(...).get_executor()``) across many. The study function must be a
module-level function (picklable for process pools) that takes the grid's keys as keyword
arguments and returns a dict of numbers. Results come back in grid order, whatever the order in
which workers finish, so a study is reproducible when its function is seeded.
"""

from __future__ import annotations

import csv
import itertools
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["parameter_grid", "run_study", "StudyResult"]


def parameter_grid(**axes: Iterable) -> list[dict]:
    """Every combination of the given values (the last axis varies fastest).

    Parameters
    ----------
    **axes : iterable
        Parameter name -> values.

    Returns
    -------
    list of dict

    Raises
    ------
    InputError
        If an axis is empty.

    Examples
    --------
    >>> parameter_grid(k=[1, 2], noise=[0.01])
    [{'k': 1, 'noise': 0.01}, {'k': 2, 'noise': 0.01}]
    """
    names = list(axes)
    values = [list(axes[name]) for name in names]
    for name, options in zip(names, values, strict=True):
        if not options:
            raise InputError(f"The grid axis {name!r} has no values.")
    return [
        dict(zip(names, combination, strict=True)) for combination in itertools.product(*values)
    ]


@dataclass(frozen=True)
class StudyResult:
    """Parameters and results of a study, one row per grid point, in grid order.

    Attributes
    ----------
    parameters : tuple of dict
        The grid points.
    results : tuple of dict
        What the study function returned for each.

    Examples
    --------
    >>> study = run_study(lambda k: {"square": k * k}, parameter_grid(k=[1, 2, 3]))
    >>> study.column("square")
    array([1, 4, 9])
    """

    parameters: tuple
    results: tuple

    def column(self, name: str) -> np.ndarray:
        """One parameter or result across the grid, as an array."""
        rows = self.rows()
        if name not in rows[0]:
            raise InputError(f"No column {name!r}; the columns are {sorted(rows[0])}.")
        return np.array([row[name] for row in rows])

    def rows(self) -> list[dict]:
        """Parameters and results merged, one dict per grid point."""
        return [{**p, **r} for p, r in zip(self.parameters, self.results, strict=True)]

    def to_csv(self, path: str | Path) -> Path:
        """Write the rows as CSV (a file to open in any spreadsheet) and return its path."""
        rows = self.rows()
        path = Path(path)
        with path.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        return path


def _call(func: Callable, parameters: Mapping) -> dict:
    result = func(**parameters)
    if not isinstance(result, Mapping):
        raise InputError(
            f"The study function must return a dict of results. Got "
            f"{type(result).__name__} for {dict(parameters)}."
        )
    return dict(result)


def run_study(
    func: Callable[..., Mapping], grid: Sequence[Mapping], executor: Executor | None = None
) -> StudyResult:
    """Evaluate ``func(**point)`` at every grid point, on ``executor`` if given.

    Parameters
    ----------
    func : callable
        Takes the grid's keys as keyword arguments, returns a dict of results.
    grid : sequence of dict
        Grid points, e.g. from :func:`parameter_grid`.
    executor : concurrent.futures.Executor or None
        Where to run; None runs serially in this process.

    Returns
    -------
    StudyResult

    Raises
    ------
    InputError
        If the grid is empty or ``func`` returns something other than a dict.

    Examples
    --------
    >>> from concurrent.futures import ThreadPoolExecutor
    >>> with ThreadPoolExecutor(2) as pool:
    ...     study = run_study(lambda a, b: {"sum": a + b}, parameter_grid(a=[1, 2], b=[10]), pool)
    >>> study.column("sum")
    array([11, 12])
    """
    if not callable(func):
        raise InputError(f"The 'func' parameter must be callable. Got {type(func).__name__}.")
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise InputError(
            "The 'executor' parameter must be a concurrent.futures.Executor (with "
            f"submit) or None. Got {type(executor).__name__}."
        )
    grid = [dict(point) for point in grid]
    if not grid:
        raise InputError("The 'grid' parameter is empty: a study needs at least one point.")
    if executor is None:
        results = [_call(func, point) for point in grid]
    else:
        futures = [executor.submit(_call, func, point) for point in grid]
        results = [future.result() for future in futures]
    return StudyResult(parameters=tuple(grid), results=tuple(results))
