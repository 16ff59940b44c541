"""Process noise that follows the record: the scalar covariance matching of
:class:`~powerline_control.estimate.KalmanFilter`'s ``adapt_horizon``.

The filter's ``Q`` is taken as ``q_k Q`` with one scalar ``q_k`` matched to the innovations over
a fading horizon of ``h`` samples (covariance matching: Mehra 1972, Myers and Tapley 1976, here
with one scale on a known shape). A sample predicted with ``P^- = A P A^T + q Q`` has innovation
covariance ``S_k = C P^- C^T + R``; weighting by ``S_k^-1`` and taking traces,

    E[e^T S_k^-1 e] = a_k + q b_k,  a_k = tr(S_k^-1 (C A P A^T C^T + R)),  b_k = tr(S_k^-1 C Q C^T),

so ``q_k = (mean(nis) - mean(a)) / mean(b)``, the three means exponential over ``h`` samples
(time constant ``h``), clipped to ``adapt_range`` and used in the next prediction. Its fixed
point is a mean NIS of exactly ``p`` (there ``a_k + q b_k = tr(S_k^-1 S_k) = p``), and the optimal
filter (``q`` the true scale) is one. The weight ``S_k^-1`` (not ``R^-1``) matters when the model
is wrong in directions ``Q``'s shape does not cover: matching the trace of ``R^-1``-weighted
innovations left the windowed NIS of the lab span's new loads 1.2-1.4x above its bound; matching
the NIS itself is what the consistency test then checks. The means start as if the first
``h`` samples had matched ``q = 1`` (the ``Q`` given): a prior worth one horizon, so ``q``
leaves 1 at the pace the horizon sets.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .._validation import check_int, check_real
from ..errors import InputError

#: Default bounds of the scale on Q: six decades around the Q given (the excitation of a span's
#: records spans about three decades of mean square between 1 and 7 m/s of wind).
DEFAULT_ADAPT_RANGE = (1e-3, 1e3)


def check_adaptation(horizon: object, bounds: object, steady_state: object
                     ) -> tuple[int | None, tuple[float, float]]:
    """``KalmanFilter``'s ``adapt_horizon`` and ``adapt_range`` checked (``InputError`` naming
    the parameter, the value and what is allowed)."""
    if not isinstance(bounds, tuple | list) or len(bounds) != 2:
        raise InputError("The 'adapt_range' parameter must be a pair (low, high) with "
                         f"0 < low <= 1 <= high. Got {bounds!r}.")
    low = check_real("adapt_range[0]", bounds[0], low=0.0, high=1.0)
    high = check_real("adapt_range[1]", bounds[1], low=1.0, low_inclusive=True)
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
    return horizon, (low, high)


class _Adaptation:
    """The running means of the covariance matching (one per recursion)."""

    def __init__(self, spec) -> None:
        """``spec``: the filter's frozen specification (``_recursion.FilterSpec``)."""
        self.horizon = spec.adapt_horizon
        self.low, self.high = spec.adapt_range
        self.keep = 1.0 - 1.0 / self.horizon
        self.q = 1.0
        self.means: np.ndarray | None = None   # (nis, a, b) averaged over the horizon
        c = spec.C
        self.c = c
        self.cqc = c @ spec.Q @ c.T
        self.fixed = spec.epsilon * (c @ c.T) + spec.r_eff   # the parts of S without P or Q

    def update(self, nis: float, propagated: np.ndarray) -> None:
        """One full sample: its NIS and ``A P[k-1|k-1] A^T`` it was predicted from (with the
        current ``q``); sets ``q`` for the next prediction."""
        rest = self.c @ propagated @ self.c.T + self.fixed
        s = rest + self.q * self.cqc
        try:
            s_inv = sla.cho_solve(sla.cho_factor((s + s.T) / 2, lower=True), np.eye(s.shape[0]))
        except np.linalg.LinAlgError:  # pragma: no cover - the update's own S was factorised
            return
        b = float(np.sum(s_inv * self.cqc))
        if not b > 0:  # Q invisible at the sensors: nothing to match
            return
        sample = np.array([nis, float(np.sum(s_inv * rest)), b])
        if self.means is None:  # the prior: one horizon matched at q = 1
            self.means = np.array([sample[1] + self.q * b, sample[1], b])
        self.means = self.keep * self.means + (1.0 - self.keep) * sample
        self.q = float(np.clip((self.means[0] - self.means[1]) / self.means[2],
                               self.low, self.high))
