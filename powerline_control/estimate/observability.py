"""Observability of a discrete model for a given sensor set: rank, Gramian, estimation error.

Three views of "can these sensors see the whole span, and how well":

* :func:`observability_rank` -- the rank of python-control's observability matrix
  (``control.obsv``) with a tolerance at the round-off level of that matrix (yes/no answer);
* :func:`observability_gramian` -- the finite-horizon discrete Gramian
  ``W_N = sum_{k<N} (A^T)^k C^T C A^k``, computed by doubling, so it exists for marginally stable
  and unstable models too (python-control's ``gram`` needs slycot and refuses those);
* :func:`steady_state_covariance` -- the exact steady-state error covariance of the Kalman filter
  from the discrete algebraic Riccati equation: the quantitative answer, in the units of the
  states, that also accounts for the noise levels ``Q`` and ``R``.

:func:`analyze_observability` gathers them (plus the per-node standard deviation of the estimated
field) into an :class:`ObservabilityReport`; :func:`compare_sensor_sets` tabulates several sensor
sets side by side.

Sensors are always *indices into the outputs* of the system: the candidates are the outputs of
``sys`` (e.g. ``dmd.to_statespace(measured=all_nodes)`` or a modal model with all nodal
displacements as outputs), and a sensor set picks rows of ``C``.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import control as ct
import numpy as np

from .._riccati import field_variances, gramian_sum, posterior_from_predicted, solve_filter_dare
from .._validation import (
    WORK_BUDGET,
    check_budget,
    check_choice,
    check_covariance,
    check_discrete_system,
    check_field_map,
    check_indices,
    check_int,
    read_only,
)
from ..errors import EstimationError, InputError

__all__ = [
    "observability_rank",
    "observability_gramian",
    "steady_state_covariance",
    "ObservabilityReport",
    "analyze_observability",
    "SensorSetComparison",
    "compare_sensor_sets",
]


# --------------------------------------------------------------------------- argument checks


def _check_sensors(sensors: object, n_outputs: int) -> np.ndarray:
    """Sensor indices into the outputs of the system (all of them when None)."""
    if sensors is None:
        return np.arange(n_outputs)
    return check_indices("sensors", sensors, n_outputs)


# --------------------------------------------------------------------------- rank and Gramian


def observability_rank(
    sys: ct.StateSpace, sensors: Sequence[int] | None = None, *, tol: float | None = None
) -> int:
    """Numerical rank of the observability matrix ``[C; CA; ...; CA^(n-1)]``.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete-time model; its outputs are the candidate sensors.
    sensors : sequence of int, optional
        Output indices that are measured (default: all outputs).
    tol : float, optional
        Singular values at or below ``tol`` count as zero. The default,
        ``max(O.shape) * eps * sigma_max(O)``, is the round-off level of the SVD of ``O``: smaller
        singular values cannot be told apart from zero in floating point. For an unstable model
        (spectral radius ``rho > 1``) the matrix is built from ``A / rho`` (same rank, no
        overflow) and ``tol`` applies to that one. Note that
        ``control.obsv`` forms powers of ``A``, so for lightly damped high-order models a
        full-rank answer can still mean "observable only in theory"; the Gramian
        (:func:`observability_gramian`) and the estimation error (:func:`steady_state_covariance`)
        say how well.

    Returns
    -------
    int
        The rank; the pair is observable when it equals ``sys.nstates``.

    Raises
    ------
    InputError
        If ``sys`` is not a finite discrete-time StateSpace, or ``sensors``/``tol`` are invalid.
    EstimationError
        If the observability matrix is not finite even after scaling.

    Examples
    --------
    >>> import control as ct
    >>> import numpy as np
    >>> sys = ct.ss(np.diag([0.5, 0.9]), np.ones((2, 1)), np.eye(2), 0, dt=0.01)
    >>> observability_rank(sys, sensors=[0])
    1
    >>> observability_rank(sys)
    2
    """
    sys = check_discrete_system("sys", sys)
    index = _check_sensors(sensors, sys.noutputs)
    if tol is not None and (
        isinstance(tol, bool) or not isinstance(tol, numbers.Real) or not np.isfinite(tol)
        or not tol >= 0
    ):
        raise InputError(
            f"The 'tol' parameter must be a finite non-negative real number. Got {tol!r}."
        )
    a = np.asarray(sys.A, dtype=float)
    n = a.shape[0]
    check_budget("The observability matrix", nbytes=8.0 * n * index.size * n,
                 flops=2.0 * (n * index.size) * n * n, parameter="sys", value=f"{n} states",
                 fix="use a reduced model (fewer states) or fewer sensors")
    # Scaling A by 1/rho leaves the rank unchanged (row blocks scale by rho^-k) and keeps the
    # powers of an unstable model from overflowing to inf / NaN singular values.
    radius = float(np.max(np.abs(np.linalg.eigvals(a))))
    if radius > 1.0:
        a = a / radius
    with np.errstate(all="ignore"):
        matrix = ct.obsv(a, np.asarray(sys.C, dtype=float)[index])
    if not np.all(np.isfinite(matrix)):
        raise EstimationError(
            "The observability matrix of 'sys' overflows even after scaling A by its spectral "
            f"radius ({radius:.3g}); the rank cannot be computed reliably."
        )
    singular_values = np.linalg.svd(matrix, compute_uv=False)
    if tol is None:
        tol = max(matrix.shape) * np.finfo(float).eps * float(singular_values[0])
    return int(np.count_nonzero(singular_values > tol))


#: Flops of one doubling step of :func:`~powerline_control._riccati.gramian_sum` per n^3: at
#: most three products of (n, n) matrices to append a block and three to double (2 n^3 each).
_GRAMIAN_FLOPS_PER_BIT = 12.0


def _check_gramian_work(n: int, horizon: int) -> None:
    """Refuse, before the doubling starts, a Gramian of ``n`` states over ``horizon`` samples
    whose ``12 n^3 log2(N + 1)`` flops exceed the work budget; the message gives the longest
    horizon this model affords (a horizon of 1e8 on 2000 states: 2.6e12 flops, minutes)."""
    bits = max(1, math.ceil(math.log2(horizon + 1)))
    per_bit = _GRAMIAN_FLOPS_PER_BIT * float(n) ** 3
    affordable = int(WORK_BUDGET // per_bit)
    if affordable >= 1:
        works = (f"with these {n} states horizons up to {2 ** min(affordable, 62) - 1} fit; "
                 "or use a reduced model (fewer states)")
    else:
        works = f"use a reduced model: no horizon fits with {n} states"
    check_budget(f"The observability Gramian of {n} states over {horizon} samples",
                 nbytes=8.0 * 6 * n * n, flops=per_bit * bits, parameter="horizon",
                 value=horizon, fix=works)


def observability_gramian(
    sys: ct.StateSpace, horizon: int, sensors: Sequence[int] | None = None
) -> np.ndarray:
    """Finite-horizon discrete observability Gramian ``sum_{k=0}^{N-1} (A^T)^k C^T C A^k``.

    ``x0^T W_N x0`` is the output energy of the free response from ``x0`` over ``N`` samples, so
    small eigenvalues mark state directions the sensors barely see. Being a finite sum, it exists
    for marginally stable and unstable models (identified DMD models often have eigenvalues on or
    near the unit circle), unlike the infinite-horizon Gramian.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete-time model; its outputs are the candidate sensors.
    horizon : int
        Number of samples ``N >= 1``.
    sensors : sequence of int, optional
        Output indices that are measured (default: all outputs).

    Returns
    -------
    numpy.ndarray
        The symmetric positive semidefinite ``(n, n)`` Gramian.

    Raises
    ------
    InputError
        If an argument is invalid, or the work (``O(n^3 log N)``) exceeds the budget (the
        message gives the longest horizon that fits).
    EstimationError
        If the Gramian overflows (an unstable model over a long horizon: the message gives the
        longest horizon that stays finite).

    Notes
    -----
    Computed by doubling, ``W_{2N} = W_N + (A^N)^T W_N A^N``, with the binary expansion of ``N``:
    ``O(n^3 log N)`` instead of ``O(n^3 N)`` for the plain sum.

    Examples
    --------
    >>> import control as ct
    >>> import numpy as np
    >>> sys = ct.ss([[0.5]], [[1.0]], [[2.0]], 0, dt=1.0)
    >>> float(observability_gramian(sys, 3)[0, 0])   # 4 * (1 + 0.25 + 0.0625)
    5.25
    """
    sys = check_discrete_system("sys", sys)
    horizon = check_int("horizon", horizon, low=1)
    index = _check_sensors(sensors, sys.noutputs)
    a = np.asarray(sys.A, dtype=float)
    _check_gramian_work(a.shape[0], horizon)
    c = np.asarray(sys.C, dtype=float)[index]
    total = gramian_sum(a, c.T @ c, horizon)
    if not np.all(np.isfinite(total)) or np.max(np.abs(total)) > 1e300:
        radius = float(np.max(np.abs(np.linalg.eigvals(a))))
        longest = int(300 * np.log(10) / (2 * np.log(radius))) if radius > 1 else None
        hint = (f"the model has spectral radius {radius:.6g} > 1, so the Gramian grows like "
                f"radius^(2 N); horizons up to about {longest} stay finite"
                if longest is not None else "the model's powers overflow")
        raise EstimationError(
            f"The observability Gramian over horizon={horizon} overflows floating point: "
            f"{hint}. Use a shorter 'horizon' or stabilise the model."
        )
    return read_only((total + total.T) / 2)


# --------------------------------------------------------------------------- Riccati


def steady_state_covariance(
    sys: ct.StateSpace,
    Q: object,
    R: object,
    sensors: Sequence[int] | None = None,
    *,
    form: str = "filter",
) -> np.ndarray:
    """Exact steady-state Kalman error covariance of the states for a sensor set.

    Solves the discrete algebraic Riccati equation for the *predicted* covariance
    ``P = A P A^T + Q - A P C^T (C P C^T + R)^-1 C P A^T`` and, for ``form="filter"``, returns the
    *posterior* (filtered, after the measurement update) covariance
    ``P - P C^T (C P C^T + R)^-1 C P``: the error covariance of ``x[k|k]``, what a
    :class:`~powerline_control.estimate.KalmanFilter` reports once its gain has converged.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete-time model ``x[k+1] = A x[k] + B u[k] + w[k]``, ``y = C x + D u + v``; its outputs
        are the candidate sensors.
    Q : array_like
        Process-noise covariance ``(n, n)``, symmetric positive semidefinite.
    R : float or array_like
        Measurement-noise covariance of the candidates, the package's one rule for ``R``: one
        variance for all, one variance per output ``(n_outputs,)``, or a full
        ``(n_outputs, n_outputs)`` symmetric matrix. The rows and columns of ``sensors`` are used
        and must be positive definite (a zero variance is an ``InputError``: a noise-free sensor
        makes the Riccati equation singular).
    sensors : sequence of int, optional
        Output indices that are measured (default: all outputs).
    form : {"filter", "predicted"}
        Posterior ``P[k|k]`` (default) or one-step predicted ``P[k|k-1]`` covariance.

    Returns
    -------
    numpy.ndarray
        Symmetric ``(n, n)`` covariance.

    Raises
    ------
    InputError
        If an argument is invalid (``R`` of the sensors not positive definite included).
    EstimationError
        If the Riccati equation has no stabilising solution (a mode on or outside the unit
        circle that the sensors cannot see: the message names its eigenvalue).

    Notes
    -----
    Solved by :func:`powerline_control._riccati.solve_filter_dare` (doubling first, SciPy's QZ as
    the fallback, a solution accepted only if stabilising with a small residual), in the
    information form: the cost is ``O(n^3)`` in the model order plus ``O(p n^2)`` in the number
    of sensors, so a reduced model with 1,001 outputs costs what its ``n`` states cost.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.ss([[1.0]], [[0.0]], [[1.0]], 0, dt=1.0)   # random walk, measured directly
    >>> P = steady_state_covariance(sys, Q=1.0 * np.eye(1), R=1.0)
    >>> round(float(P[0, 0]), 6)   # (sqrt(5) - 1) / 2, the golden-ratio closed form
    0.618034
    """
    form = check_choice("form", form, ("filter", "predicted"))
    sys = check_discrete_system("sys", sys)
    index = _check_sensors(sensors, sys.noutputs)
    n = sys.nstates
    q = check_covariance("Q", Q, n)
    r = check_covariance("R", R, sys.noutputs, index=index, definite=True)
    a = np.asarray(sys.A, dtype=float)
    c = np.asarray(sys.C, dtype=float)[index]
    predicted = solve_filter_dare(a, c, q, r)
    if form == "predicted":
        return read_only(predicted)
    return read_only(posterior_from_predicted(predicted, c, r))


# --------------------------------------------------------------------------- reports


@dataclass(frozen=True, eq=False)
class ObservabilityReport:
    """How well a sensor set sees the model: rank, Gramian spectrum and estimation error.

    Attributes
    ----------
    sensors : numpy.ndarray
        Output indices measured, ``(p,)``.
    n_states : int
        Model order ``n``.
    rank : int
        Numerical rank of the observability matrix (see :func:`observability_rank`).
    observable : bool
        ``rank == n_states``.
    horizon : int
        Gramian horizon ``N`` in samples.
    gramian_min_singular_value : float
        Smallest singular value of the finite-horizon Gramian (output energy of the worst-seen
        unit initial state over ``N`` samples).
    gramian_condition_number : float
        Largest over smallest singular value (``inf`` when the smallest is zero).
    node_std : numpy.ndarray or None
        Steady-state posterior standard deviation of each field value ``(n_nodes,)`` (of each
        state without a field map), from the Riccati solution; ``None`` without ``Q`` and ``R``.
    mean_std : float or None
        Root mean square of ``node_std`` over the field (the average estimation error).
    max_std : float or None
        Largest entry of ``node_std`` (the worst-estimated point).
    covariance : numpy.ndarray or None
        Steady-state posterior state covariance ``(n, n)``; ``None`` without ``Q`` and ``R``.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.ss(np.diag([0.5, 0.9]), np.zeros((2, 1)), np.eye(2), 0, dt=0.01)
    >>> analyze_observability(sys).observable
    True
    """

    sensors: np.ndarray
    n_states: int
    rank: int
    observable: bool
    horizon: int
    gramian_min_singular_value: float
    gramian_condition_number: float
    node_std: np.ndarray | None
    mean_std: float | None
    max_std: float | None
    covariance: np.ndarray | None


def analyze_observability(
    sys: ct.StateSpace,
    sensors: Sequence[int] | None = None,
    *,
    Q: object = None,
    R: object = None,
    horizon: int | None = None,
    field_map: object = None,
    tol: float | None = None,
) -> ObservabilityReport:
    """Rank, Gramian and (with noise covariances) per-node steady-state estimation error.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete-time model; its outputs are the candidate sensors.
    sensors : sequence of int, optional
        Output indices that are measured (default: all outputs).
    Q : array_like, optional
        Process-noise covariance ``(n, n)``; with ``R`` it enables the Riccati part.
    R : float or array_like, optional
        Measurement-noise covariance of the candidates (scalar, per-output vector or matrix).
    horizon : int, optional
        Gramian horizon in samples (default ``2 n``: long enough for every mode to show up in
        the output of an observable model, short enough to stay finite for unstable ones).
    field_map : array_like, optional
        ``(n_nodes, n)`` map from the model state to the field of interest (e.g. the full nodal
        displacement of a reduced or delay-embedded DMD model). Default: the states themselves.
    tol : float, optional
        Rank tolerance, see :func:`observability_rank`.

    Returns
    -------
    ObservabilityReport
        The analysis.

    Raises
    ------
    InputError
        If an argument is invalid, or only one of ``Q`` and ``R`` is given.
    EstimationError
        If the Riccati equation has no stabilising solution.

    Examples
    --------
    >>> import control as ct
    >>> import numpy as np
    >>> sys = ct.ss(np.diag([0.5, 0.9]), np.zeros((2, 1)), np.eye(2), 0, dt=0.01)
    >>> report = analyze_observability(sys, sensors=[1], Q=np.eye(2), R=1.0)
    >>> report.rank, report.observable
    (1, False)
    >>> round(float(report.node_std[0]), 4)   # state 0 unseen: its stationary std 1/sqrt(1-0.25)
    1.1547
    """
    sys = check_discrete_system("sys", sys)
    index = _check_sensors(sensors, sys.noutputs)
    n = sys.nstates
    horizon = 2 * n if horizon is None else check_int("horizon", horizon, low=1)
    matrix = check_field_map(field_map, n)
    rank = observability_rank(sys, index, tol=tol)
    singular_values = np.linalg.svd(
        observability_gramian(sys, horizon, index), compute_uv=False
    )
    if not np.all(np.isfinite(singular_values)):  # pragma: no cover - the Gramian is checked
        raise EstimationError("The Gramian's singular values are not finite.")
    smallest = float(singular_values[-1])
    condition = float(singular_values[0] / smallest) if smallest > 0 else float("inf")
    if (Q is None) != (R is None):
        raise InputError(
            "The 'Q' and 'R' parameters must be given together (both or neither). "
            f"Got Q={'set' if Q is not None else None}, R={'set' if R is not None else None}."
        )
    node_std = covariance = mean_std = max_std = None
    if Q is not None:
        covariance = steady_state_covariance(sys, Q, R, index)
        node_std = read_only(np.sqrt(field_variances(covariance, matrix)))
        mean_std = float(np.sqrt(np.mean(node_std**2)))
        max_std = float(np.max(node_std))
    return ObservabilityReport(
        sensors=read_only(index),
        n_states=n,
        rank=rank,
        observable=rank == n,
        horizon=horizon,
        gramian_min_singular_value=smallest,
        gramian_condition_number=condition,
        node_std=node_std,
        mean_std=mean_std,
        max_std=max_std,
        covariance=covariance,
    )


@dataclass(frozen=True, eq=False)
class SensorSetComparison:
    """Several sensor sets analysed with the same model, noise and horizon.

    Attributes
    ----------
    names : tuple of str
        One label per sensor set.
    reports : tuple of ObservabilityReport
        The analysis of each set, in the same order.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.ss(np.diag([0.5, 0.9]), np.zeros((2, 1)), np.eye(2), 0, dt=0.01)
    >>> print(compare_sensor_sets(sys, {"s0": [0]}).to_markdown().splitlines()[2][:18])
    | s0 | 1 | 1 / 2 |
    """

    names: tuple[str, ...]
    reports: tuple[ObservabilityReport, ...]

    def to_markdown(self, unit_scale: float = 1.0, unit: str = "") -> str:
        """Return the comparison as a markdown table.

        Parameters
        ----------
        unit_scale : float
            Factor applied to the standard deviations (e.g. ``1e3`` to print millimetres).
        unit : str
            Unit label printed in the header of the standard-deviation columns.

        Returns
        -------
        str
            One row per sensor set: sensors, rank, Gramian smallest singular value and
            condition number, RMS and largest per-node standard deviation.
        """
        suffix = f" [{unit}]" if unit else ""
        lines = [
            f"| sensor set | p | rank / n | Gramian sigma_min | Gramian cond | "
            f"RMS node std{suffix} | max node std{suffix} |",
            "|---|---|---|---|---|---|---|",
        ]
        for name, rep in zip(self.names, self.reports, strict=True):
            mean = "-" if rep.mean_std is None else f"{rep.mean_std * unit_scale:.4g}"
            worst = "-" if rep.max_std is None else f"{rep.max_std * unit_scale:.4g}"
            lines.append(
                f"| {name} | {rep.sensors.size} | {rep.rank} / {rep.n_states} | "
                f"{rep.gramian_min_singular_value:.3g} | {rep.gramian_condition_number:.3g} | "
                f"{mean} | {worst} |"
            )
        return "\n".join(lines)


def compare_sensor_sets(
    sys: ct.StateSpace,
    sensor_sets: dict[str, Sequence[int]] | Sequence[Sequence[int]],
    *,
    Q: object = None,
    R: object = None,
    horizon: int | None = None,
    field_map: object = None,
    tol: float | None = None,
) -> SensorSetComparison:
    """Analyse several sensor sets on the same model (see :func:`analyze_observability`).

    Parameters
    ----------
    sys : control.StateSpace
        Discrete-time model; its outputs are the candidate sensors.
    sensor_sets : dict of str to sequence of int, or sequence of sequences of int
        The sets to compare; without names they are labelled by their indices.
    Q, R, horizon, field_map, tol
        As in :func:`analyze_observability`.

    Returns
    -------
    SensorSetComparison
        Reports in the given order; ``.to_markdown()`` prints the table.

    Raises
    ------
    InputError
        If an argument is invalid or no sensor set is given.
    EstimationError
        If the Riccati equation has no stabilising solution for one of the sets.

    Examples
    --------
    >>> import control as ct
    >>> import numpy as np
    >>> sys = ct.ss(np.diag([0.5, 0.9]), np.zeros((2, 1)), np.eye(2), 0, dt=0.01)
    >>> table = compare_sensor_sets(sys, {"first": [0], "both": [0, 1]}, Q=np.eye(2), R=1.0)
    >>> [r.rank for r in table.reports]
    [1, 2]
    """
    sys = check_discrete_system("sys", sys)
    if isinstance(sensor_sets, dict):
        names = tuple(str(name) for name in sensor_sets)
        sets = list(sensor_sets.values())
    elif isinstance(sensor_sets, Sequence | np.ndarray) and not isinstance(sensor_sets, str):
        sets = list(sensor_sets)
        names = None
    else:
        raise InputError(
            "The 'sensor_sets' parameter must be a dict of name -> sensor indices or a sequence "
            f"of sensor-index sequences. Got {sensor_sets!r} of type "
            f"{type(sensor_sets).__name__}."
        )
    # Each set is checked here, so that a bad one is named by its key or position.
    labels = (tuple(f'"{name}"' for name in names) if names is not None
              else tuple(range(len(sets))))
    sets = [check_indices(f"sensor_sets[{label}]", s, sys.noutputs).tolist()
            for label, s in zip(labels, sets, strict=True)]
    if names is None:
        names = tuple(str(s) for s in sets)
    if not sets:
        raise InputError("The 'sensor_sets' parameter must contain at least one sensor set.")
    reports = tuple(
        analyze_observability(
            sys, s, Q=Q, R=R, horizon=horizon, field_map=field_map, tol=tol
        )
        for s in sets
    )
    return SensorSetComparison(names=names, reports=reports)
