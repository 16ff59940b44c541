"""The running mean square of an estimated field: the one definition the filter reports model
error with and the recipe fits it by.

An identified model of a real span is wrong by a share of the field it predicts (measured on the
estimator family of ``tests/estimator_family.py``: 20-50 % at unmeasured nodes), so its error
grows as the line rings up, which no constant covariance can follow. The filter adds
``field_relative_variance`` times this running mean square to each node's reported variance.
"""

from __future__ import annotations

import numpy as np
import scipy.signal as ssig

from .._validation import check_real
from ..errors import InputError


def running_mean_square(field: np.ndarray, window: int) -> np.ndarray:
    """Causal exponential average of ``field**2`` along time, time constant ``window`` samples.

    Parameters
    ----------
    field : numpy.ndarray
        ``(n_nodes, n_t)`` estimated field (finite).
    window : int
        Time constant in samples (``>= 1``): the average over about the last ``window``
        samples, so that the reported variance follows a field that rings up or dies down.

    Returns
    -------
    numpy.ndarray
        ``(n_nodes, n_t)``; the first column is the first sample's square (the average starts
        there as if the field had been steady before).

    Examples
    --------
    >>> import numpy as np
    >>> from powerline_control.estimate._model_error import running_mean_square
    >>> float(running_mean_square(np.full((1, 50), 2.0), 10)[0, -1])
    4.0
    """
    square = np.asarray(field, dtype=float) ** 2
    if square.shape[-1] == 0:
        return square
    return _exponential_average(square, window, square[..., :1])


def _exponential_average(square: np.ndarray, window: int, before: np.ndarray) -> np.ndarray:
    """``m[k] = keep m[k-1] + (1 - keep) square[k]`` along the last axis, ``keep = 1 - 1 /
    window``, ``m[-1] = before`` (shape ``square.shape[:-1] + (1,)``): one recursion for the
    running mean squares of the field and at the sensors."""
    keep = 1.0 - 1.0 / window
    return ssig.lfilter([1.0 - keep], [1.0, -keep], square, axis=-1, zi=keep * before)[0]


def innovation_inflation(at_sensors: np.ndarray, window: int, share: float, reference: float,
                         start: float = 0.0) -> tuple[np.ndarray, float]:
    """Factor on the innovation covariance of each sample, and the running mean square after it.

    An identified model's one-step prediction is wrong by a share of the field, so its
    innovations grow as the line rings up while the Riccati ``S`` stays constant. ``S`` was
    matched (covariance matching) on a record whose running mean square at the sensors was
    ``reference``; of it, ``share`` is model error (the rest the sensor noise). Above that
    level the model error is taken to grow with the field:
    ``S_k = S (1 + share * max(m[k-1] / reference - 1, 0))``, ``m`` the causal running mean
    square (time constant ``window``) of the filtered estimate at the sensors averaged over
    them, known before sample ``k`` arrives. Below it ``S_k = S``: never smaller than matched.

    Parameters
    ----------
    at_sensors : numpy.ndarray
        ``(p, n_t)`` filtered estimate at the sensors (``C x[k|k]``).
    window : int
        Time constant in samples.
    share : float
        Model error's share ``0 <= share <= 1`` of ``S`` at the reference level.
    reference : float
        Running mean square at the sensors where ``S`` was matched (> 0).
    start : float
        Running mean square before the first sample (0: a record from rest).

    Returns
    -------
    factor : numpy.ndarray
        ``(n_t,)`` factors ``>= 1``; the NIS with ``S_k`` is the NIS with ``S`` divided by it.
    end : float
        Running mean square after the last sample (to continue a recursion).

    Examples
    --------
    >>> import numpy as np
    >>> from powerline_control.estimate._model_error import innovation_inflation
    >>> factor, end = innovation_inflation(np.full((2, 3), 2.0), 2, 0.5, 1.0)
    >>> factor.tolist(), end   # m = 0, 2, 3, 3.5: factors 1, 1 + 0.5 * (2 - 1), 1 + 0.5 * 2
    ([1.0, 1.5, 2.0], 3.5)
    """
    m = sensor_mean_square(at_sensors, window, start)
    if m.size == 0:
        return np.ones(0), float(start)
    before = np.concatenate([[start], m[:-1]])
    return growth_factor(before, share, reference), float(m[-1])


def sensor_mean_square(at_sensors: np.ndarray, window: int, start: float = 0.0) -> np.ndarray:
    """``m[k] = keep m[k-1] + (1 - keep) mean_i(x_i[k]^2)``, ``keep = 1 - 1 / window``,
    ``m[-1] = start``: the running mean square at the sensors of :func:`innovation_inflation`
    (``(p, n_t)`` in, ``(n_t,)`` out); the recipe measures its reference level with it."""
    square = np.mean(np.asarray(at_sensors, dtype=float) ** 2, axis=0)
    if square.size == 0:
        return square
    return _exponential_average(square, window, np.array([start], dtype=float))


def next_mean_square(previous: float, at_sensors: np.ndarray, window: int) -> float:
    """One step of :func:`sensor_mean_square`: ``m[k]`` from ``m[k-1]`` and ``x[k]`` ``(p,)``
    (the real-time filter's form, one sample at a time)."""
    keep = 1.0 - 1.0 / window
    return keep * previous + (1.0 - keep) * float(at_sensors @ at_sensors) / at_sensors.size


def growth_factor(mean_square, share: float, reference: float):
    """``1 + share * max(mean_square / reference - 1, 0)``: the factor on ``S`` (array or float;
    see :func:`innovation_inflation`, whose per-sample form this is)."""
    return 1.0 + share * np.maximum(mean_square / reference - 1.0, 0.0)


def check_innovation_growth(innovation_growth: object, steady_state: object
                            ) -> tuple[float, float]:
    """``KalmanFilter``'s ``innovation_growth`` checked: ``(reference, share)``, ``(1, 0)``
    (no growth) for ``None``. Raises ``InputError`` naming the parameter."""
    if innovation_growth is None:
        return 1.0, 0.0
    if not isinstance(innovation_growth, tuple | list) or len(innovation_growth) != 2:
        raise InputError("The 'innovation_growth' parameter must be None or a pair "
                         f"(reference, share). Got {innovation_growth!r}.")
    reference = check_real("innovation_growth[0]", innovation_growth[0], low=0.0)
    share = check_real("innovation_growth[1]", innovation_growth[1], low=0.0, high=1.0,
                       low_inclusive=True)
    if steady_state is not True:
        raise InputError(
            "The 'innovation_growth' parameter scales the steady-state innovation "
            f"covariance and needs steady_state=True. Got steady_state={steady_state!r}."
        )
    return reference, share
