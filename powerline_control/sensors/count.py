"""How many sensors: :func:`sensor_count_study` runs the selection for each ``k`` and checks the
optimised Kalman criterion against the RMS error of a steady-state filter on a simulated
trajectory.

Test seam: ``_simulated_rms``: its refusal of a layout that cannot estimate the state
(tests/test_sensors.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import control as ct
import numpy as np

from .._riccati import solve_filter_dare
from .._validation import (
    check_budget,
    check_discrete_system,
    check_forwarded_options,
    check_int,
    check_psd,
    check_real,
    check_rng,
    read_only,
)
from ..errors import EstimationError, InputError, SensorSelectionError
from .constraints import _check_noise, _error_rows
from .results import SensorCountStudy
from .select import select_sensors


def _simulated_rms(a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray, h: np.ndarray,
                   layout: Sequence[int], n_steps: int, rng: np.random.Generator) -> float:
    """RMS of ``H (x - x_hat)`` for a steady-state Kalman filter on a simulated trajectory.

    ``r`` is the candidates' noise covariance, ``(m,)`` variances or a full ``(m, m)`` matrix.
    """
    index = list(layout)
    cs = c[index]
    r_s = np.diag(r[index]) if r.ndim == 1 else r[np.ix_(index, index)]
    try:  # the package's one Riccati solver (doubling, QZ fallback, stabilising only)
        prior = solve_filter_dare(a, cs, q, r_s)
    except EstimationError as exc:
        raise SensorSelectionError(
            f"The steady-state Kalman filter of the layout {index} that checks the "
            f"predicted RMS error could not be computed: {exc}"
        ) from exc
    # solve_filter_dare returns only stabilising solutions: the filter below is stable.
    gain = np.linalg.solve(cs @ prior @ cs.T + r_s, cs @ prior).T
    noise_factor = np.linalg.cholesky(r_s)
    lam, vec = np.linalg.eigh((q + q.T) / 2)
    q_half = vec * np.sqrt(np.clip(lam, 0, None))
    lam, vec = np.linalg.eigh((prior + prior.T) / 2)
    x = vec @ (np.sqrt(np.clip(lam, 0, None)) * rng.standard_normal(len(a)))
    x_pred = np.zeros(len(a))  # the error starts with the steady-state prior covariance
    total = 0.0
    for _ in range(n_steps):
        y = cs @ x + noise_factor @ rng.standard_normal(len(index))
        x_post = x_pred + gain @ (y - cs @ x_pred)
        err = h @ (x - x_post)
        total += float(err @ err)
        x_pred = a @ x_post
        x = a @ x + q_half @ rng.standard_normal(len(a))
    return math.sqrt(total / (n_steps * h.shape[0]))


def sensor_count_study(
    sys: ct.StateSpace,
    k_values: Sequence[int],
    *,
    Q: object,
    R: object = 1.0,
    target_error: float | None = None,
    n_steps: int = 2000,
    seed: int | np.random.Generator | None = 0,
    **options: object,
) -> SensorCountStudy:
    """How many sensors: the optimised Kalman criterion and the simulated RMS error against k.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete model whose outputs are the candidates (as in :func:`select_sensors`).
    k_values : sequence of int
        Sensor counts to study, ascending.
    Q : array_like
        Process-noise covariance ``(n, n)``.
    R : float or array_like
        Measurement-noise covariance of the candidates (scalar, per-candidate variances or a
        full matrix; see :func:`select_sensors`).
    target_error : float, optional
        RMS estimation error (per weighted state) to reach; sets ``smallest_k``.
    n_steps : int
        Length of the simulation that checks each predicted RMS error; refused when the
        simulations exceed the package's work budget (docs/conventions.md).
    seed : int, numpy.random.Generator or None
        Seed of the simulation.
    **options
        Passed to :func:`select_sensors` (constraints, ``error_weight``, ``solver``, ...).

    Returns
    -------
    SensorCountStudy
        Per ``k``: the exact criterion, the predicted and simulated RMS errors, the layout, and
        the smallest ``k`` reaching ``target_error``.

    Raises
    ------
    InputError
        Invalid arguments.
    SensorSelectionError
        As :func:`select_sensors`.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> import powerline_control as plc
    >>> sys = ct.ss(np.diag([0.9, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0)
    >>> study = plc.sensors.sensor_count_study(sys, [1, 2], Q=np.eye(2), R=0.1, n_steps=200)
    >>> study.k, bool(study.rms_error[1] < study.rms_error[0])
    ((1, 2), True)
    """
    options = check_forwarded_options(
        sensor_count_study, options, select_sensors, set_here=("sys", "k", "criterion"),
        why="the count comes from 'k_values'; the criterion is the Kalman one")
    sys = check_discrete_system("sys", sys)
    if isinstance(k_values, str) or not isinstance(k_values, Sequence | np.ndarray):
        raise InputError(
            "The 'k_values' parameter must be a sequence of sensor counts, e.g. [1, 2, 3]. "
            f"Got {k_values!r} of type {type(k_values).__name__}."
        )
    items = np.ravel(k_values).tolist() if isinstance(k_values, np.ndarray) else list(k_values)
    ks = [check_int("k_values", k, low=1) for k in items]
    if not ks or sorted(set(ks)) != ks:
        raise InputError(
            f"The 'k_values' parameter must be a non-empty ascending sequence of distinct "
            f"integers. Got {list(k_values)!r} instead."
        )
    if target_error is not None:
        target_error = check_real("target_error", target_error, low=0.0)
    n_steps = check_int("n_steps", n_steps, low=1)
    rng = check_rng(seed)
    a = np.asarray(sys.A, dtype=float)
    c = np.asarray(sys.C, dtype=float)
    q = check_psd("Q", Q, a.shape[0])
    variances, r_full = _check_noise(R, c.shape[0])
    r = variances if r_full is None else r_full
    h = _error_rows(options.get("error_weight", "states"), c, a.shape[0])
    n = a.shape[0]
    # Each simulated step is a handful of small matrix products plus about ten NumPy calls,
    # whose overhead (~1 us each) is the time of ~1e3 floating-point operations: counted as
    # 1e4 per step, so that the work budget (1e12, minutes) bounds the loop's wall time too.
    per_step = 6.0 * n * n + 4.0 * max(ks) * n + 2.0 * h.shape[0] * n + 1e4
    check_budget("The simulations that check the predicted errors",
                 flops=float(n_steps) * len(ks) * per_step, parameter="n_steps", value=n_steps,
                 fix="simulate fewer steps (n_steps=2000 is the default)")
    options = {"n_random": 0, "brute_force_limit": 0, **options}
    objective, rms, simulated, layouts = [], [], [], []
    for k in ks:
        sel = select_sensors(sys, k, "kalman", Q=Q, R=R, **options)  # type: ignore[arg-type]
        objective.append(sel.objective)
        rms.append(math.sqrt(sel.objective / h.shape[0]))
        simulated.append(_simulated_rms(a, c, q, r, h, sel.nodes, n_steps, rng))
        layouts.append(sel.nodes)
    reached = [k for k, e in zip(ks, rms, strict=True) if target_error is not None
               and e <= target_error]
    return SensorCountStudy(
        k=tuple(ks),
        objective=read_only(np.array(objective)),
        rms_error=read_only(np.array(rms)),
        simulated_rms_error=read_only(np.array(simulated)),
        layouts=tuple(layouts),
        target_error=target_error,
        smallest_k=reached[0] if reached else None,
    )
