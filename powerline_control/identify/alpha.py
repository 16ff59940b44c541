"""Choosing alpha: :func:`select_alpha` sweeps the Tikhonov parameter and returns the curve.

The first part of the record trains one model per alpha (one SVD of the regressor serves the
whole sweep); the rest is held out for one-step and free-run errors.  :class:`AlphaCurve` holds
the trade-off between stability (the spectral radius) and held-out accuracy, with the smallest
stable alpha and the best held-out one.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._validation import (
    check_array,
    check_choice,
    check_int,
    check_real,
    checked_keywords,
    read_only,
)
from ..errors import InputError
from ._ridge import _ridge_svd
from .fit import (
    _absolute_alpha,
    _check_common,
    _fit_problem,
    _hankel,
    _prepare,
    _refuse_all_zero,
)
from .model import DMDModel


@dataclass(frozen=True, eq=False)
class AlphaCurve:
    """The Tikhonov trade-off of :func:`select_alpha`: stability against held-out accuracy.

    Attributes
    ----------
    alphas : ndarray, shape (n_alphas,)
        The alphas tried, in ``alpha_mode`` units, ascending.
    alpha_mode : str
        "absolute" or "relative" (see :func:`fit_dmd`).
    alphas_absolute, alphas_relative : ndarray, shape (n_alphas,)
        The same alphas in both units (relative to the largest squared singular value of the
        training state data).
    spectral_radius : ndarray, shape (n_alphas,)
        Spectral radius of the model fitted on the training part.
    n_unstable : ndarray of int, shape (n_alphas,)
        Eigenvalues outside the unit circle.
    one_step_error : ndarray, shape (n_alphas,)
        Held-out relative one-step error ``||x_{k+1} - x_hat_{k+1}||_F / ||x_{k+1}||_F``.
    multi_step_error : ndarray, shape (n_alphas,)
        Held-out relative free-run error over ``horizon`` steps from ``n_windows`` windows
        (Frobenius norms pooled over windows); ``inf`` when the free run overflows.
    persistence_error : float
        One-step error of "next sample = this sample" on the same held-out data (a baseline).
    margin : float
        Stability margin: ``stable_alpha`` needs ``spectral_radius <= 1 - margin``.
    horizon : int
        Free-run length in samples.
    stable_alpha : float or None
        Smallest alpha with ``spectral_radius <= 1 - margin`` (``None`` if no alpha qualifies).
    best_alpha : float
        Alpha with the smallest held-out multi-step error.
    best_stable_alpha : float or None
        Alpha with the smallest multi-step error among those meeting the margin.

    Examples
    --------
    >>> import numpy as np, powerline_control as plc
    >>> t = np.arange(400) * 0.01
    >>> X = np.vstack([np.sin(2 * np.pi * 2 * t), np.cos(2 * np.pi * 2 * t)])
    >>> curve = plc.select_alpha(X, dt=0.01, alphas=[1e-6, 1.0], horizon=20)
    >>> bool(curve.spectral_radius[1] < curve.spectral_radius[0])
    True
    """

    alphas: np.ndarray
    alpha_mode: str
    alphas_absolute: np.ndarray
    alphas_relative: np.ndarray
    spectral_radius: np.ndarray
    n_unstable: np.ndarray
    one_step_error: np.ndarray
    multi_step_error: np.ndarray
    persistence_error: float
    margin: float
    horizon: int
    stable_alpha: float | None
    best_alpha: float
    best_stable_alpha: float | None


def _held_out_errors(
    model: DMDModel,
    X: np.ndarray,
    u: np.ndarray | None,
    starts: np.ndarray,
    horizon: int,
) -> tuple[float, float]:
    """One-step error over all held-out pairs and pooled free-run error from ``starts``."""
    d = model.delays
    Z = _hankel(X, d)
    Z0, Z1 = Z[:, :-1], Z[:, 1:]
    S0 = Z0 if model.basis is None else model.basis.T @ Z0
    with np.errstate(over="ignore", invalid="ignore"):
        next_states = model.A @ S0
        if u is not None:
            next_states += model.B @ u[:, d - 1 : d - 1 + Z0.shape[1]]
        prediction = model.field_map @ next_states
        truth = Z1[: model.n_nodes]
        one_step = _relative_error(prediction, truth)
        num = den = 0.0
        for t0 in starts:
            window = X[:, t0 - d + 1 : t0 + 1]
            inputs = None if u is None else u[:, t0 : t0 + horizon]
            u_run = model._check_prediction_inputs(inputs, horizon)
            predicted = model._free_run(model.window_to_state(window), horizon, u_run)
            true = X[:, t0 + 1 : t0 + 1 + horizon]
            num += float(np.sum((predicted - true) ** 2))
            den += float(np.sum(true**2))
    multi = math.sqrt(num / den) if den > 0 and math.isfinite(num) else math.inf
    return one_step, multi


def _relative_error(prediction: np.ndarray, truth: np.ndarray) -> float:
    den = float(np.linalg.norm(truth))
    num = float(np.linalg.norm(prediction - truth))
    if not math.isfinite(num) or den == 0:
        return math.inf
    return num / den


@checked_keywords
def select_alpha(
    X: np.ndarray,
    dt: float,
    alphas: Sequence[float] | np.ndarray | None = None,
    *,
    delays: int = 1,
    rank: int | None = None,
    inputs: np.ndarray | None = None,
    alpha_mode: str = "relative",
    margin: float = 0.0,
    train_fraction: float = 0.7,
    horizon: int = 100,
    n_windows: int = 5,
) -> AlphaCurve:
    """Sweep the Tikhonov alpha and return the whole trade-off curve with two choices.

    The first ``train_fraction`` of the samples trains a model per alpha (the SVD is computed
    once); the rest is held out.  For each alpha the curve records the spectral radius, the
    held-out one-step error and the held-out free-run error over ``horizon`` steps from
    ``n_windows`` evenly spaced starting windows.  The choices:

    * ``stable_alpha``: the smallest alpha with ``spectral_radius <= 1 - margin`` (paper
      section 2.3: "a larger alpha pushes the eigenvalues to the origin");
    * ``best_alpha``: the alpha with the smallest held-out multi-step error (paper: "if alpha is
      too large A_reg may not capture the dynamics").

    Parameters
    ----------
    X : array_like, shape (n_nodes, n_samples)
        Snapshots.
    dt : float
        Sample time in seconds (> 0).
    alphas : sequence of float, optional
        Alphas to try (>= 0), in ``alpha_mode`` units.  Default: 0 and 25 values log-spaced from
        1e-12 to 1 relative (converted when ``alpha_mode`` is "absolute").
    delays, rank, inputs
        As in :func:`fit_dmd` (inputs cover all samples, training and held-out).
    alpha_mode : {"relative", "absolute"}, default "relative"
        Units of ``alphas`` and of the returned choices.
    margin : float, default 0.0
        Required stability margin in [0, 1).
    train_fraction : float, default 0.7
        Fraction of samples used for training, in (0, 1).
    horizon : int, default 100
        Free-run length in samples (>= 1).
    n_windows : int, default 5
        Number of held-out free-run windows (>= 1).

    Returns
    -------
    AlphaCurve
        The curve and the choices.

    Raises
    ------
    InputError
        Bad arguments, or too few held-out samples for ``horizon`` (say how many are needed).
    IdentificationError
        ``X`` is all zeros (as :func:`fit_dmd`).

    Examples
    --------
    >>> import numpy as np, powerline_control as plc
    >>> t = np.arange(600) * 0.01
    >>> X = np.vstack([np.sin(2 * np.pi * 2 * t), np.cos(2 * np.pi * 2 * t)])
    >>> curve = plc.select_alpha(X, dt=0.01, alphas=[1e-9, 1e-3, 1e-1], horizon=50,
    ...                          margin=1e-3)
    >>> curve.best_alpha, curve.stable_alpha
    (1e-09, 0.001)
    """
    X, dt, delays, rank, u = _check_common(X, dt, delays, rank, inputs)
    _refuse_all_zero(X)   # as fit_dmd does: every alpha would "fit" data without dynamics
    alpha_mode = check_choice("alpha_mode", alpha_mode, ("absolute", "relative"))
    margin = check_real("margin", margin, low=0.0, high=1.0, low_inclusive=True,
                        high_inclusive=False)
    train_fraction = check_real("train_fraction", train_fraction, low=0.0, high=1.0,
                                high_inclusive=False)
    horizon = check_int("horizon", horizon, low=1)
    # No more windows than samples (more would only repeat starts, after allocating them all).
    n_windows = check_int("n_windows", n_windows, low=1, high=X.shape[1])
    if u is not None and u.shape[1] == X.shape[1] - 1:
        u = np.hstack([u, np.zeros((u.shape[0], 1))])  # the last column drives nothing
    n_samples = X.shape[1]
    n_train = int(round(train_fraction * n_samples))
    n_held = n_samples - n_train
    if n_train < delays + 2 or n_held < delays + horizon:
        raise InputError(
            f"select_alpha needs at least {delays + 2} training and {delays + horizon} held-out "
            f"samples (delays + horizon); got {n_train} and {n_held} from {n_samples} samples "
            f"with train_fraction={train_fraction}. Use more samples, a shorter horizon or "
            "another train_fraction."
        )
    problem = _prepare(X[:, :n_train], delays, rank, None if u is None else u[:, :n_train])
    svd = _ridge_svd(problem.target, problem.regressor)
    if u is None and math.isnan(problem.s_max):
        problem = dataclasses.replace(problem, s_max=float(svd[1][0]))
    _, problem = _absolute_alpha(0.0, "absolute", problem)
    scale = problem.s_max**2
    if alphas is None:
        # alpha = 0 first: on clean data it is exact, and any floor biases the damping.
        relative = np.concatenate([[0.0], np.logspace(-12, 0, 25)])
        given = relative if alpha_mode == "relative" else relative * scale
    else:
        given = check_array("alphas", alphas, ndim=1)
        if given.size == 0 or np.any(given < 0):
            raise InputError(
                f"The 'alphas' parameter must be a non-empty list of values >= 0. Got {alphas!r}."
            )
        given = np.sort(given)
    absolute = given * scale if alpha_mode == "relative" else given
    relative = absolute / scale if scale > 0 else np.zeros_like(absolute)

    held = X[:, n_train:]
    u_held = None if u is None else u[:, n_train:]
    last_start = held.shape[1] - 1 - horizon
    starts = np.unique(np.linspace(delays - 1, last_start, n_windows).round().astype(int))
    radius, unstable, one_step, multi = [], [], [], []
    for alpha in absolute:
        model = _fit_problem(problem, float(alpha), dt, warn=False, svd=svd)
        radius.append(model.spectral_radius)
        unstable.append(model.n_unstable)
        errors = _held_out_errors(model, held, u_held, starts, horizon)
        one_step.append(errors[0])
        multi.append(errors[1])
    radius_arr, multi_arr = np.array(radius), np.array(multi)
    meets = radius_arr <= 1.0 - margin
    stable_alpha = float(given[np.argmax(meets)]) if meets.any() else None
    best_alpha = float(given[int(np.argmin(multi_arr))])
    best_stable = None
    if meets.any():
        best_stable = float(given[meets][int(np.argmin(multi_arr[meets]))])
    persistence = _relative_error(held[:, :-1], held[:, 1:])
    return AlphaCurve(
        alphas=read_only(given),
        alpha_mode=alpha_mode,
        alphas_absolute=read_only(absolute),
        alphas_relative=read_only(relative),
        spectral_radius=read_only(radius_arr),
        n_unstable=read_only(np.array(unstable, dtype=int)),
        one_step_error=read_only(np.array(one_step)),
        multi_step_error=read_only(multi_arr),
        persistence_error=persistence,
        margin=margin,
        horizon=horizon,
        stable_alpha=stable_alpha,
        best_alpha=best_alpha,
        best_stable_alpha=best_stable,
    )
