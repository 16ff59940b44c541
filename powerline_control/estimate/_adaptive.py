"""Process noise that follows the record: the scalar covariance matching of
:class:`~powerline_control.estimate.KalmanFilter`'s ``adapt_horizon``.

The filter's ``Q`` is taken as ``q_k Q`` with one scalar ``q_k`` matched to the innovations over
a fading horizon of ``h`` samples (Myers and Tapley 1976, "Adaptive sequential estimation with
unknown noise statistics", with one scale on a known shape; the innovation-based covariance
matching of Mehra 1972). The innovation of a sample has covariance
``S_k = C (A P[k-1|k-1] A^T) C^T + q C Q C^T + R``; weighting by ``W = R^-1`` and taking traces,

    E[e^T W e] = a_k + q b,   a_k = tr(W C A P A^T C^T) + p,   b = tr(W C Q C^T),

so ``q_k = (mean(e^T W e) - mean(a)) / b`` with both means exponential over ``h`` samples
(time constant ``h``), clipped to ``adapt_range``, used in the next prediction. The optimal
filter (``q`` equal to the true scale) is its fixed point: there ``E[e^T W e]`` is exactly
``a + q b``. The averages start as if the first ``h`` samples had matched ``q = 1`` (the ``Q``
given): a prior worth one horizon, so ``q`` leaves 1 at the pace the horizon sets.
"""

from __future__ import annotations

import numpy as np

from .._validation import check_int, check_real
from ..errors import InputError

#: Default bounds of the scale on Q: six decades around the Q given (the excitation of a span's
#: records spans about three decades of mean square between 1 and 7 m/s of wind).
DEFAULT_ADAPT_RANGE = (1e-3, 1e3)


def check_adaptation(horizon: object, bounds: object, steady_state: object
                     ) -> tuple[int | None, tuple[float, float]]:
    """``KalmanFilter``'s ``adapt_horizon`` and ``adapt_range`` checked (``InputError`` naming
    the parameter, the value and what is allowed)."""
    if horizon is None:
        return None, DEFAULT_ADAPT_RANGE
    if isinstance(horizon, bool) or not isinstance(horizon, int | np.integer) or horizon < 2:
        raise InputError(
            "The 'adapt_horizon' parameter must be None (no adaptation) or an integer number "
            f"of samples >= 2 (the time constant of the covariance matching). Got {horizon!r}."
        )
    horizon = check_int("adapt_horizon", horizon, low=2)
    if steady_state is not False:
        raise InputError(
            "The 'adapt_horizon' parameter adapts Q sample by sample, so the gain changes with "
            f"it: it needs steady_state=False. Got steady_state={steady_state!r}; start the "
            "time-varying filter from the stationary covariance (P0) instead."
        )
    if not isinstance(bounds, tuple | list) or len(bounds) != 2:
        raise InputError("The 'adapt_range' parameter must be a pair (low, high) with "
                         f"0 < low <= 1 <= high. Got {bounds!r}.")
    low = check_real("adapt_range[0]", bounds[0], low=0.0, high=1.0)
    high = check_real("adapt_range[1]", bounds[1], low=1.0, low_inclusive=True)
    return horizon, (low, high)


class _Adaptation:
    """The running sums of the covariance matching (one per recursion)."""

    def __init__(self, kf) -> None:
        self.horizon = kf._adapt_horizon
        self.low, self.high = kf._adapt_range
        self.keep = 1.0 - 1.0 / self.horizon
        self.q = 1.0
        self.mean_e: float | None = None
        self.mean_a = 0.0
        self.weight = np.linalg.inv(kf._r_eff)
        self.weight = (self.weight + self.weight.T) / 2
        c = kf._C
        self.b = float(np.sum(self.weight * (c @ kf._Q @ c.T)))
        # tr(W C (eps I) C^T) + tr(W R_eff): the parts of a_k that do not depend on P
        self.a_fixed = float(np.sum(self.weight * (kf._epsilon * c @ c.T + kf._r_eff)))
        self.c = c

    def update(self, innovation: np.ndarray, propagated: np.ndarray) -> None:
        """One full sample: its innovation ``(p,)`` and ``A P[k-1|k-1] A^T`` it was predicted
        with; sets ``q`` for the next prediction."""
        if not self.b > 0:  # Q invisible at the sensors: nothing to match
            return
        e_w = float(innovation @ self.weight @ innovation)
        a = float(np.sum(self.weight * (self.c @ propagated @ self.c.T))) + self.a_fixed
        if self.mean_e is None:  # the prior: one horizon matched at q = 1
            self.mean_e, self.mean_a = a + self.q * self.b, a
        keep = self.keep
        self.mean_e = keep * self.mean_e + (1.0 - keep) * e_w
        self.mean_a = keep * self.mean_a + (1.0 - keep) * a
        self.q = float(np.clip((self.mean_e - self.mean_a) / self.b, self.low, self.high))
