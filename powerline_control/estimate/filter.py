"""Kalman filtering on identified (or physical) discrete models: :class:`KalmanFilter`.

The filter of the paper (section 2.4, eqs. 15-20) in a numerically robust form:

* prediction ``x[k|k-1] = A x[k-1|k-1] + B u[k-1]`` (the paper's eq. 15 prints ``+ Q``: adding a
  covariance to a state is a typo), ``P[k|k-1] = A P A^T + Q + eps I`` (eq. 16);
* update with ``S = C P C^T + R + eps I`` (eq. 18), gain ``K = P C^T S^-1`` through a Cholesky
  solve, and the Joseph form ``P = (I - K C) P (I - K C)^T + K (R + eps I) K^T`` (eq. 20 in a form
  that stays symmetric positive semidefinite), with ``P`` symmetrised after every step. ``eps`` thus
  acts as extra process and measurement noise, which is what the paper uses it for;
* missing measurements: a NaN in a sample drops that sensor from that update; an all-NaN sample
  only predicts;
* speed without changing the result: a ``C`` that selects states (the usual case: "measure the
  displacement at these nodes") is applied by indexing, never by matrix products; once the gain
  has converged (to ``gain_rtol``) the covariance recursion stops, and NaN-free stretches are run as
  the linear closed-loop recursion ``x[k] = F x[k-1] + G z[k]``, diagonalised and evaluated as a
  blocked scan over all modes at once (no Python loop over samples);
* a steady-state mode (``steady_state=True``) with the filter-form gain from the discrete Riccati
  equation. Beware: ``control.dlqe`` returns the *predictor* gain ``A P C^T S^-1`` (for
  ``x[k+1|k]``); the filter-form gain used here is ``P C^T S^-1`` (for ``x[k|k]``), so
  ``dlqe``'s ``L`` equals ``A @ kf.steady_gain``.

Accuracy and consistency of a run are measured by :func:`estimation_accuracy` (RMS errors relative
to the RMS displacement, all and unmeasured signals) and :func:`filter_consistency` (NEES and NIS
against their chi-square bands).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import control as ct
import numpy as np
import scipy.linalg as sla
import scipy.stats as sstats

from ._estimate_spectrum import spectral_test, whitened_psd, whitening_factor
from ._riccati import (
    describe_modes,
    filter_gain,
    posterior_from_predicted,
    solve_filter_dare,
    undetectable_modes,
)
from ._riccati import (
    field_variances as mapped_variances,
)
from ._validation import (
    check_array,
    check_covariance,
    check_discrete_system,
    check_field_map,
    check_indices,
    check_int,
    check_real,
    read_only,
)
from .errors import (
    EstimationError,
    EstimatorInconsistentWarning,
    InputError,
    UndetectableModeWarning,
)

__all__ = [
    "Estimate",
    "KalmanFilter",
    "Accuracy",
    "estimation_accuracy",
    "Consistency",
    "filter_consistency",
]

# Stretches of converged, NaN-free samples shorter than this are run by the per-sample loop: below
# it the set-up of the modal batch recursion costs more than it saves.
_MIN_BATCH = 256
# The modal batch recursion is used only when the eigenvector matrix of the closed loop is this
# well conditioned; its round-off grows with cond(V), and beyond this it could differ from the
# loop by more than 1e-9 relative.
_MAX_MODAL_CONDITION = 1e6
# Consecutive full samples with a gain change below gain_rtol before the gain is frozen.
_CONFIRM_SAMPLES = 10
# Block length of the vectorised diagonal recursion: in-block work grows with it, the Python
# loop over blocks shrinks with it; 16 was fastest for n = 101 on the reference machine.
_SCAN_BLOCK = 16
# Covariance eigenvalues below this fraction of the largest count as zero in the NEES: a
# rank-truncated model claims near-certainty in directions it does not model, and the true error
# there would dominate the statistic.
_NEES_RANK_RTOL = 1e-9
#: Samples per window of the consistency test (design.md 4.7): 0.2 s at 1 kHz, long enough for a
#: tight chi-square band (p = 5 sensors: 1000 degrees of freedom, +-12 % at 1 %), short enough to
#: localise a change of load within a record.
DEFAULT_CONSISTENCY_WINDOW = 200
#: Two-sided level of each window's chi-square test, and of the run-level count of rejections.
_WINDOW_LEVEL = 0.01


@dataclass(frozen=True)
class Estimate:
    """Result of :meth:`KalmanFilter.filter`: filtered states and their uncertainty.

    Attributes
    ----------
    states : numpy.ndarray
        Posterior (filtered) state estimates ``x[k|k]``, shape ``(n, n_t)``.
    variances : numpy.ndarray
        Diagonal of the posterior covariance ``P[k|k]``, shape ``(n, n_t)`` (a read-only
        broadcast view when the covariance is constant over the whole record).
    innovations : numpy.ndarray
        Measurement residuals ``y[k] - C x[k|k-1] - D u[k]``, shape ``(p, n_t)``; NaN where the
        measurement was missing.
    nis : numpy.ndarray
        Normalised innovation squared ``e^T S^-1 e`` per sample, ``(n_t,)``; NaN for all-missing
        samples. For a consistent filter it is chi-square with ``n_used[k]`` degrees of freedom.
    n_used : numpy.ndarray
        Number of sensors used in each update, ``(n_t,)`` (``p`` without dropouts).
    covariance : numpy.ndarray
        Posterior covariance after the last sample, ``(n, n)``.
    gain : numpy.ndarray
        Filter-form gain ``(n, p)`` of the last update that used every sensor (the steady-state
        gain once converged).
    converged_at : int or None
        First sample from which the gain was frozen (the change of the covariance and of the
        gain stayed below ``gain_rtol``); ``0`` in steady-state mode, ``None`` if it never
        converged (always ``None`` when ``undetectable_modes`` is not empty).
    dt : float or None
        Sample time of the model (``None`` when the model's timebase is unspecified).
    field : numpy.ndarray or None
        Full field ``field_map @ states``, ``(n_nodes, n_t)``, when the filter has a field map.
    field_variances : numpy.ndarray or None
        Posterior variance of each field value, ``(n_nodes, n_t)``, when the filter has a field map.
    undetectable_modes : tuple of complex
        Eigenvalues on or outside the unit circle that the sensors cannot see (empty when the
        model is detectable). Their variance grows without bound and is reported as it grows.
    consistency : Consistency or None
        The windowed NIS test of this run (:func:`filter_consistency` with the filter's
        ``consistency_window`` and ``nis_dof_fraction``); ``None`` when the filter's window is
        ``None`` or no sample had a measurement. When it rejects, ``filter`` has warned
        :class:`~powerline_control.errors.EstimatorInconsistentWarning`.

    All arrays are read-only.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.ss([[0.9]], [[0.0]], [[1.0]], 0, dt=0.01)
    >>> est = KalmanFilter(sys, Q=1.0, R=1.0, field_map=[[1.0], [2.0]]).filter(np.ones((1, 3)))
    >>> est.states.shape, est.field.shape, est.t.round(2).tolist()
    ((1, 3), (2, 3), [0.0, 0.01, 0.02])
    """

    states: np.ndarray
    variances: np.ndarray
    innovations: np.ndarray
    nis: np.ndarray
    n_used: np.ndarray
    covariance: np.ndarray
    gain: np.ndarray
    converged_at: int | None
    dt: float | None
    field: np.ndarray | None = None
    field_variances: np.ndarray | None = None
    undetectable_modes: tuple[complex, ...] = ()
    consistency: Consistency | None = None

    def __post_init__(self) -> None:
        _freeze_arrays(self)

    @property
    def t(self) -> np.ndarray:
        """Sample times ``k * dt`` in seconds, ``(n_t,)`` (sample indices without a timebase)."""
        step = 1.0 if self.dt is None else self.dt
        return np.arange(self.states.shape[1]) * step


def _freeze_arrays(result: object) -> None:
    """Mark every ndarray field of a result read-only (no copy: the result owns them)."""
    for value in vars(result).values():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)


def _selection_indices(c: np.ndarray) -> np.ndarray | None:
    """Column index of the single 1 in each row if ``C`` only selects states, else None."""
    if c.size == 0:
        return None
    ones = c == 1.0
    if not np.all((c == 0.0) | ones) or not np.all(ones.sum(axis=1) == 1):
        return None
    return np.argmax(ones, axis=1)


class _Recursion:
    """The per-sample filter state shared by :meth:`KalmanFilter.step` and ``filter``.

    Holds the estimate, the covariance and, once the covariance has converged (or in
    steady-state mode), the frozen gain with its covariances, so that full samples need no
    covariance work.
    """

    def __init__(self, kf: KalmanFilter) -> None:
        self.kf = kf
        self.x = kf._x0.copy()
        self.first = True  # the prior describes sample 0: no prediction before its update
        self.u_prev = np.zeros(kf._m)
        self.k = 0
        self.last_full_gain: np.ndarray | None = None
        self.converged = False
        self.converged_at: int | None = None
        self.batch = None
        self.settled = 0  # consecutive full samples whose covariance changed by <= gain_rtol
        self.last_posterior: np.ndarray | None = None
        # Windowed NIS of the real-time recursion (step): running sums of the open window and
        # the sums of the windows closed so far (three numbers per window, never per sample).
        self.w_sum, self.w_valid, self.w_used, self.w_len = 0.0, 0, 0, 0
        self.closed: list[tuple[float, int, int]] = []
        if kf.steady_state:
            gain, posterior, predicted = kf._steady_solution()
            self.freeze(gain, posterior, predicted)
            self.P = predicted  # prior of sample 0: the stationary predicted covariance
            self.converged_at = 0
            self.last_full_gain = gain
        else:
            self.P = kf._P0.copy()

    def freeze(self, gain: np.ndarray, posterior: np.ndarray, predicted: np.ndarray) -> None:
        """Adopt a converged gain: from now on full samples need no covariance work."""
        kf = self.kf
        self.converged = True
        self.gain_ss, self.posterior_ss, self.predicted_ss = gain, posterior, predicted
        if kf._info_form:
            self.s_factor = None  # NIS through Woodbury with posterior_ss, O(n p)
        else:
            s = (
                predicted[np.ix_(kf._sel, kf._sel)]
                if kf._sel is not None
                else kf._C @ predicted @ kf._C.T
            )
            s = s + kf._r_eff
            self.s_factor = sla.cho_factor((s + s.T) / 2, lower=True)
            # e^T S^-1 e = |L^-1 e|^2: L^-1 once, then one small product per sample (a
            # triangular solve per sample cost as much as the rest of the step)
            self.whitener = sla.solve_triangular(self.s_factor[0], np.eye(s.shape[0]),
                                                 lower=True)
        self.batch = None

    def monitor(self, nis: float, used: int) -> None:
        """Add one sample's NIS to the open consistency window (closing it when full)."""
        if used:
            self.w_sum += nis
            self.w_valid += 1
            self.w_used += used
        self.w_len += 1
        if self.w_len == self.kf._window:
            self.closed.append((self.w_sum, self.w_valid, self.w_used))
            self.w_sum, self.w_valid, self.w_used, self.w_len = 0.0, 0, 0, 0

    def nis_frozen(self, e: np.ndarray) -> np.ndarray:
        """``e^T S^-1 e`` per column of ``e`` ``(p, L)`` with the frozen covariance."""
        kf = self.kf
        if self.s_factor is not None:
            whitened = self.whitener @ e
            return np.einsum("ij,ij->j", whitened, whitened)
        # Woodbury: S^-1 = R^-1 - R^-1 C P+ C^T R^-1 (P+ the posterior), never a p x p solve.
        r_inv_e = kf._apply_r_inv(e)
        w = kf._C.T @ r_inv_e
        return np.einsum("ij,ij->j", e, r_inv_e) - np.einsum("ij,ij->j", w, self.posterior_ss @ w)

    def check_divergence(self, what: str) -> None:
        """EstimationError when the covariance or the state stops being finite or explodes."""
        kf = self.kf
        with np.errstate(all="ignore"):
            size = float(np.max(np.abs(self.P))) if self.P.size else 0.0
        if np.isfinite(size) and size <= kf._diverged and np.all(np.isfinite(self.x)):
            return
        unseen = kf._undetectable
        cause = (
            f"the modes with eigenvalues {describe_modes(unseen)} lie on or outside the unit "
            "circle and are not detectable from the sensors"
            if unseen.size
            else f"the model has spectral radius {kf._radius:.6g} and {what}"
        )
        raise EstimationError(
            f"The Kalman filter diverged at sample {self.k - 1}: its error covariance reached "
            f"{size:.3g} (over {kf._diverged:.3g}, 1e100 times its scale): {cause}. The "
            "estimate has no meaning any more; shorten the dropout, add sensors that see those "
            "modes, or stabilise the model."
        )

    def advance(self, y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, float, int]:
        """Process one sample; return (innovation, NIS, number of sensors used)."""
        kf = self.kf
        mask = ~np.isnan(y)
        full = bool(mask.all())
        # --- prediction of the state (the covariance only when it is needed)
        if self.first:
            x_pred, p_pred = self.x, self.P
            self.first = False
        else:
            x_pred = kf._A @ self.x
            if kf._m:
                x_pred += kf._B @ self.u_prev
            p_pred = None
        self.u_prev = u
        innovation = np.full(kf._p, np.nan)
        self.k += 1
        # --- converged covariance and every sensor present: a plain linear update
        if self.converged and full:
            e = y - kf._measure(x_pred) - (kf._D @ u if kf._m else 0.0)
            self.x = x_pred + self.gain_ss @ e
            self.P = self.posterior_ss
            innovation[:] = e
            return innovation, float(self.nis_frozen(e[:, None])[0]), kf._p
        if p_pred is None:
            # From the current covariance: after a frozen full sample P is the stationary
            # posterior and this is the stationary prior; during a dropout it grows as it must.
            p_pred = kf._A @ self.P @ kf._A.T + kf._q_eff
        if not mask.any():
            self.x, self.P = x_pred, (p_pred + p_pred.T) / 2
            self.last_full_gain = None if not kf.steady_state else self.last_full_gain
            if not kf.steady_state:
                self.converged, self.settled, self.last_posterior = False, 0, None
            self.check_divergence("every measurement is missing (a dropout only predicts)")
            return innovation, float("nan"), 0
        # --- measurement update with the available sensors
        index = np.flatnonzero(mask)
        if kf._info_form:
            gain, nis, e = self._information_update(p_pred, x_pred, y, u, index, full)
        else:
            gain, nis, e = self._joseph_update(p_pred, x_pred, y, u, index)
        innovation[index] = e
        self.check_divergence("some sensors are missing")
        if kf.steady_state:
            return innovation, nis, index.size
        if not full:
            self.converged, self.settled = False, 0
            self.last_full_gain = self.last_posterior = None
            return innovation, nis, index.size
        self._track_convergence(gain)
        return innovation, nis, index.size

    def _joseph_update(self, p_pred, x_pred, y, u, index):
        """Covariance form (``p <= n``): gain through a Cholesky of ``S``, Joseph update."""
        kf = self.kf
        r_used = kf._r_eff[np.ix_(index, index)]
        if kf._sel is not None:
            cols = kf._sel[index]
            pht = p_pred[:, cols]  # P C^T by indexing: C only selects states
            s = pht[cols] + r_used
            hx = x_pred[cols]
        else:
            c = kf._C[index]
            pht = p_pred @ c.T
            s = c @ pht + r_used
            hx = c @ x_pred
        if kf._m:
            hx = hx + kf._D[index] @ u
        try:
            with np.errstate(all="ignore"):
                factor = sla.cho_factor((s + s.T) / 2, lower=True)
        except (np.linalg.LinAlgError, ValueError) as exc:
            self.P = p_pred
            self.check_divergence("the innovation covariance is not finite")
            raise EstimationError(
                f"The innovation covariance S is singular at sample {self.k - 1}; give every "
                "sensor a positive noise variance R, or use epsilon > 0."
            ) from exc
        gain = sla.cho_solve(factor, pht.T).T
        e = y[index] - hx
        self.x = x_pred + gain @ e
        # Joseph form through the structure, O(n^2 p): M = (I - K C) P = P - K (P C^T)^T, then
        # M (I - K C)^T + K R K^T = M - (M C^T) K^T + K R K^T.
        m = p_pred - gain @ pht.T
        mht = m[:, cols] if kf._sel is not None else m @ c.T
        posterior = m - mht @ gain.T + gain @ r_used @ gain.T
        self.P = (posterior + posterior.T) / 2
        return gain, float(e @ sla.cho_solve(factor, e)), e

    def _information_update(self, p_pred, x_pred, y, u, index, full):
        """Information form (``p > n``): ``P+ = (I + P G)^-1 P``, ``K = P+ C^T R^-1``.

        Every product is ``O(n^3 + n^2 p)``; the ``p x p`` innovation covariance is never formed.
        """
        kf = self.kf
        n = kf._n
        if full:
            c, r_inv_c, info = kf._C, kf._r_inv_c, kf._info_full
        else:
            c = kf._C[index]
            r_inv_c = kf._apply_r_inv(c, index)
            info = c.T @ r_inv_c
        hx = c @ x_pred
        if kf._m:
            hx = hx + kf._D[index] @ u
        with np.errstate(all="ignore"):
            posterior = np.linalg.solve(np.eye(n) + p_pred @ info, p_pred)
        posterior = (posterior + posterior.T) / 2
        gain = posterior @ r_inv_c.T
        e = y[index] - hx
        self.x = x_pred + gain @ e
        self.P = posterior
        r_inv_e = kf._apply_r_inv(e[:, None], index)[:, 0]
        w = c.T @ r_inv_e
        return gain, float(e @ r_inv_e - w @ posterior @ w), e

    def _track_convergence(self, gain: np.ndarray) -> None:
        """Freeze the gain once the *covariance* has stopped changing (not only the gain).

        The covariance of a direction the sensors cannot see keeps growing while the gain (zero
        there) looks settled; the old gain-only test froze a small, wrong covariance. A model
        with undetectable modes on or outside the unit circle is never frozen.
        """
        kf = self.kf
        previous_gain, previous_p = self.last_full_gain, self.last_posterior
        rtol = kf.gain_rtol
        steady = (
            rtol > 0
            and not kf._undetectable.size
            and previous_gain is not None
            and previous_p is not None
            and np.max(np.abs(gain - previous_gain)) <= rtol * np.max(np.abs(gain))
            and np.max(np.abs(self.P - previous_p)) <= rtol * np.max(np.abs(self.P))
        )
        self.settled = self.settled + 1 if steady else 0
        # Freeze only after the covariance has stayed put for a few samples: the extra steps
        # shrink what is left of the geometric convergence at almost no cost.
        if self.settled >= _CONFIRM_SAMPLES:
            self.freeze(gain, self.P, kf._A @ self.P @ kf._A.T + kf._q_eff)
            if self.converged_at is None:
                self.converged_at = self.k
        self.last_full_gain, self.last_posterior = gain, self.P


class KalmanFilter:
    """Kalman filter on a discrete ``control.StateSpace`` (time-varying or steady-state gain).

    Model ``x[k+1] = A x[k] + B u[k] + w[k]``, ``y[k] = C x[k] + D u[k] + v[k]`` with
    ``w ~ N(0, Q)`` and ``v ~ N(0, R)``. The outputs of ``sys`` are the sensors.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete-time model (e.g. ``dmd.to_statespace(measured=[...])`` or a discretised
        :class:`~powerline_control.fem.LineModel`). Continuous-time systems are rejected.
    Q : float or array_like
        Process-noise covariance: a variance for every state, ``(n,)`` variances or an ``(n, n)``
        symmetric positive semidefinite matrix (e.g. ``dmd.residual_covariance``).
    R : float or array_like
        Measurement-noise covariance, the package's one rule for ``R``: one variance, ``(p,)``
        variances or a ``(p, p)`` symmetric matrix; ``R + epsilon I`` must be positive definite
        (a zero variance needs ``epsilon > 0``, otherwise it is an ``InputError``).
    epsilon : float
        The paper's regulariser ``eps >= 0`` added to ``P`` (eq. 16) and ``S`` (eq. 18), i.e. to
        ``Q`` and ``R``. Default 0.
    steady_state : bool
        Use the constant steady-state gain from the Riccati equation (``P0`` is then ignored).
    x0 : array_like, optional
        Prior mean of the state at sample 0 (before its measurement); default zeros.
    P0 : array_like, optional
        Prior covariance at sample 0; default the identity.
    field_map : array_like, optional
        ``(n_nodes, n)`` map from the (possibly reduced or delay-embedded) state to the full field,
        e.g. the map of a rank-truncated DMD model; the filter runs in the model coordinates and
        lifts only its output (``Estimate.field``).
    gain_rtol : float
        The time-varying filter freezes its gain (and stops updating the covariance) once, for
        10 consecutive full-sensor samples, both the posterior *covariance* and the gain change
        by at most ``gain_rtol`` relative to their largest entry (default 1e-10: the Riccati
        recursion of a 100-state model stalls at a round-off floor of about 1e-14 to 1e-11, so a
        tighter value may never trigger); 0 keeps the textbook recursion throughout. A model
        with undetectable modes (see ``undetectable_modes``) is never frozen: the covariance of
        what the sensors cannot see keeps growing as it truly does.
    consistency_window : int or None
        Samples per window of the consistency test run on every record (default 200; see
        :class:`Consistency`); ``None`` turns the test (and its warning) off.
    nis_dof_fraction : float
        Share ``0 < f <= 1`` of each window's nominal chi-square degrees of freedom treated as
        independent (default 1: the white innovations of an exact model). An identified model's
        innovations are not quite white; :func:`~powerline_control.recipe.design_estimator`
        measures the share on held-out data.
    warn_inconsistent : bool
        Warn :class:`~powerline_control.errors.EstimatorInconsistentWarning` from
        :meth:`filter` when the test rejects (default False: the test always runs and
        ``Estimate.consistency`` always says what it found; a filter on a textbook model with
        an assumed ``Q`` would otherwise warn on every record it does not describe).
    spectral_reference : array_like, optional
        ``(segment // 2 + 1,)`` whitened innovation power per frequency bin on records the model
        describes (measured on held-out data by
        :func:`~powerline_control.recipe.design_estimator`). With it, :meth:`filter` also runs
        the spectral test (see :class:`Consistency`): a bin whose power exceeds the reference by
        far rejects the record, which catches a load driving modes the training never saw even
        when the NIS summed over all frequencies hardly moves. Default ``None``: no spectral
        test.
    spectral_reference_count : int
        Segments times channels averaged in ``spectral_reference`` (its sampling spread).
    field_variance_scale : float
        Factor ``> 0`` on the field variances the filter reports (``Estimate.field_variances``;
        the state covariance, the gain and the NIS are unchanged): the model error at nodes
        the sensors do not see, which the innovations cannot show.
        :func:`~powerline_control.recipe.design_estimator` measures it on held-out data at the
        unmeasured nodes. Default 1.

    Attributes
    ----------
    Q, R : numpy.ndarray
        The noise covariances as full matrices (read-only: a filter's noise model is fixed at
        construction; build a new filter to change it).
    epsilon, gain_rtol : float
        As given (read-only).
    n_states, n_outputs, n_inputs : int
        Dimensions ``n``, ``p``, ``m`` of the model.
    dt : float or None
        Sample time (``None`` for an unspecified timebase).
    steady_state : bool
        Whether the gain is the constant steady-state one.
    undetectable_modes : numpy.ndarray
        Eigenvalues on or outside the unit circle the sensors cannot see (empty if none).
    consistency_window : int or None
        Samples per consistency window (``None``: no test).
    nis_dof_fraction : float
        As given.
    warn_inconsistent : bool
        As given.
    consistency : Consistency or None
        Windowed NIS test of the real-time recursion (:meth:`step`) over the windows it has
        completed since construction or :meth:`reset`.
    spectral_reference : numpy.ndarray or None
        As given (read-only); ``spectral_reference_count`` likewise.
    innovation_covariance : numpy.ndarray
        Steady-state innovation covariance ``S`` (what whitens the spectral test).

    Raises
    ------
    InputError
        If ``sys`` is not a finite discrete-time StateSpace, or a covariance has the wrong
        shape, is not symmetric positive semidefinite or not finite, or ``R + epsilon I`` is
        not positive definite.
    EstimationError
        In steady-state mode, if the Riccati equation has no stabilising solution. While
        filtering, if the covariance diverges (an unstable mode the sensors cannot see, or a
        long dropout on an unstable model) or stops being finite.

    Warns
    -----
    UndetectableModeWarning
        When a time-varying filter's sensors cannot see a mode on or outside the unit circle.

    Notes
    -----
    Cost per sample: ``O(n^2 p)`` for the covariance update while it converges (``O(n^3 +
    n^2 p)`` in the information form used when there are more outputs than states, ``p > n``:
    ``P+ = (I + P C^T R^-1 C)^-1 P`` and ``K = P+ C^T R^-1``, never a ``p x p`` solve), then
    ``O(n p)`` per sample once frozen. A reduced model of ``r`` states with ``p`` outputs costs
    what ``r`` and ``p`` cost, not what the number of nodes costs.

    Examples
    --------
    >>> import control as ct
    >>> import numpy as np
    >>> sys = ct.ss([[1.0]], [[0.0]], [[1.0]], 0, dt=1.0)      # a random walk, measured
    >>> kf = KalmanFilter(sys, Q=1.0, R=1.0)
    >>> est = kf.filter(np.array([[1.0, 2.0, np.nan, 3.0]]))
    >>> est.states.round(3)
    array([[0.5  , 1.4  , 1.4  , 2.556]])
    >>> kf.step(np.array([1.0])).round(3)                     # real time, one sample at a time
    array([0.5])
    """

    def __init__(
        self,
        sys: ct.StateSpace,
        Q: object,
        R: object,
        epsilon: float = 0.0,
        steady_state: bool = False,
        x0: object = None,
        P0: object = None,
        *,
        field_map: object = None,
        gain_rtol: float = 1e-10,
        consistency_window: int | None = DEFAULT_CONSISTENCY_WINDOW,
        nis_dof_fraction: float = 1.0,
        warn_inconsistent: bool = False,
        spectral_reference: object = None,
        spectral_reference_count: int = 1,
        field_variance_scale: float = 1.0,
    ) -> None:
        sys = check_discrete_system("sys", sys)
        if not isinstance(warn_inconsistent, bool):
            raise InputError("The 'warn_inconsistent' parameter must be True or False. Got "
                             f"{warn_inconsistent!r}.")
        self._warn = warn_inconsistent
        self._window = (None if consistency_window is None
                        else check_int("consistency_window", consistency_window, low=1))
        self._dof_fraction = check_real("nis_dof_fraction", nis_dof_fraction, low=0.0, high=1.0)
        self._spectral_ref = None
        self._fv_scale = check_real("field_variance_scale", field_variance_scale, low=0.0)
        self._spectral_count = check_int("spectral_reference_count", spectral_reference_count,
                                         low=1)
        if spectral_reference is not None:
            ref = check_array("spectral_reference", spectral_reference, ndim=1)
            if ref.size < 3 or ref.size % 2 == 0 or np.any(ref < 0):
                raise InputError(
                    "The 'spectral_reference' parameter must hold the whitened innovation power "
                    "of segment // 2 + 1 bins (an odd count >= 3, every value >= 0). Got "
                    f"{ref.size} values, smallest {float(ref.min()):.3g}."
                )
            self._spectral_ref = read_only(ref.copy())
        self._A = np.array(sys.A, dtype=float)
        self._B = np.array(sys.B, dtype=float)
        self._C = np.array(sys.C, dtype=float)
        self._D = np.array(sys.D, dtype=float)
        self._dims = (sys.nstates, sys.noutputs, sys.ninputs)
        self._n, self._p = sys.nstates, sys.noutputs
        # A zero B (an autonomous model built with a dummy input) is skipped entirely.
        has_input = sys.ninputs > 0 and (np.any(self._B) or np.any(self._D))
        self._m = sys.ninputs if has_input else 0
        self._dt = None if sys.dt is True else float(sys.dt)
        if not isinstance(steady_state, bool):
            raise InputError(
                f"The 'steady_state' parameter must be True or False. Got {steady_state!r}."
            )
        self._steady_state = steady_state
        self._epsilon = check_real("epsilon", epsilon, low=0.0, low_inclusive=True)
        self._gain_rtol = check_real("gain_rtol", gain_rtol, low=0.0, low_inclusive=True)
        if self._p == 0:
            raise InputError("The 'sys' parameter must have at least one output (sensor).")
        n, p = self._n, self._p
        self._Q = read_only(check_covariance("Q", Q, n))
        self._R = read_only(check_covariance("R", R, p))
        self._q_eff = self._Q + self._epsilon * np.eye(n)
        self._r_eff = self._R + self._epsilon * np.eye(p)
        try:  # the one rule for R: positive definite (here with the paper's epsilon added)
            np.linalg.cholesky(self._r_eff)
        except np.linalg.LinAlgError:
            raise InputError(
                "The 'R' parameter plus epsilon * I must be positive definite: every sensor "
                "needs measurement noise (a noise-free sensor makes the innovation covariance "
                f"singular). Got smallest eigenvalue {np.linalg.eigvalsh(self._r_eff).min():.3g}"
                f" with epsilon={self._epsilon!r}; give R > 0 or use epsilon > 0."
            ) from None
        self._x0 = (
            np.zeros(n) if x0 is None else check_array("x0", x0, shape=(n,)).astype(float)
        )
        self._P0 = np.eye(n) if P0 is None else check_covariance("P0", P0, n)
        self._field_map = check_field_map(field_map, n)
        self._sel = _selection_indices(self._C)
        # Information (Woodbury) form when there are more outputs than states: every update
        # then costs O(n^3 + n^2 p) instead of the O(p^3) of a p x p innovation covariance.
        self._info_form = p > n and self._sel is None
        diagonal = not np.any(self._r_eff - np.diag(np.diag(self._r_eff)))
        self._r_diag = np.diag(self._r_eff).copy() if diagonal else None
        if self._info_form:
            self._r_inv_c = self._apply_r_inv(self._C)
            self._info_full = self._C.T @ self._r_inv_c
        self._radius = float(np.max(np.abs(np.linalg.eigvals(self._A))))
        self._undetectable = read_only(undetectable_modes(self._A, self._C))
        # Divergence: a covariance 1e100 times its natural scale has lost all meaning.
        scale = max(float(np.max(np.abs(self._P0))), float(np.max(np.abs(self._q_eff))),
                    float(np.max(np.abs(self._r_eff))), 1e-300)
        self._diverged = 1e100 * scale
        self._steady: tuple | None = None
        self._steady_batch: dict | bool | None = None
        if steady_state:
            self._steady_solution()  # fail early (EstimationError) if no steady state exists
        elif self._undetectable.size:
            warnings.warn(
                f"The sensors cannot see the modes with eigenvalues "
                f"{describe_modes(self._undetectable)} (on or outside the unit circle): their "
                "estimation error grows without bound. The filter keeps propagating their "
                "covariance honestly (never frozen) and Estimate.undetectable_modes names them.",
                UndetectableModeWarning,
                stacklevel=2,
            )
        self._running = _Recursion(self)

    # ------------------------------------------------------------------ read-only parameters

    @property
    def Q(self) -> np.ndarray:  # noqa: N802 - the covariance's conventional name
        """Process-noise covariance ``(n, n)`` given at construction (read-only)."""
        return self._Q

    @property
    def R(self) -> np.ndarray:  # noqa: N802 - the covariance's conventional name
        """Measurement-noise covariance ``(p, p)`` given at construction (read-only)."""
        return self._R

    @property
    def epsilon(self) -> float:
        """The paper's regulariser added to ``Q`` and ``R``."""
        return self._epsilon

    @property
    def gain_rtol(self) -> float:
        """Relative change of the covariance and gain below which the gain is frozen."""
        return self._gain_rtol

    @property
    def steady_state(self) -> bool:
        """Whether the gain is the constant steady-state one."""
        return self._steady_state

    @property
    def dt(self) -> float | None:
        """Sample time (``None`` for an unspecified timebase)."""
        return self._dt

    @property
    def n_states(self) -> int:
        """Model order ``n``."""
        return self._dims[0]

    @property
    def n_outputs(self) -> int:
        """Number of outputs (sensors) ``p``."""
        return self._dims[1]

    @property
    def n_inputs(self) -> int:
        """Number of inputs ``m``."""
        return self._dims[2]

    @property
    def undetectable_modes(self) -> np.ndarray:
        """Eigenvalues on or outside the unit circle that the sensors cannot see (read-only)."""
        return self._undetectable

    @property
    def consistency_window(self) -> int | None:
        """Samples per consistency window (``None``: the test is off)."""
        return self._window

    @property
    def nis_dof_fraction(self) -> float:
        """Share of each window's nominal chi-square degrees of freedom treated as independent."""
        return self._dof_fraction

    @property
    def warn_inconsistent(self) -> bool:
        """Whether :meth:`filter` warns when its consistency test rejects."""
        return self._warn

    @property
    def consistency(self) -> Consistency | None:
        """Windowed NIS test of the real-time recursion (:meth:`step`) so far.

        Every completed window of ``consistency_window`` samples stepped since construction or
        :meth:`reset` (or continued from ``filter(..., update_state=True)``), tested as
        :meth:`filter` tests a record; ``None`` before a window with a measurement completes
        or when the test is off. :meth:`step` itself never warns (it runs inside control
        loops): read ``consistency.consistent`` there.
        """
        closed = self._running.closed
        if self._window is None or not closed:
            return None
        sums, counts, used = (np.array(v, dtype=float) for v in zip(*closed, strict=True))
        if not counts.sum():
            return None
        total, n_valid = float(used.sum()), int(counts.sum())
        bounds = _chi2_band(total, n_valid)
        mean = float(sums.sum() / n_valid)
        return Consistency(
            mean_nis=mean, nis_dof=total / n_valid, nis_bounds=bounds,
            nis_consistent=bool(bounds[0] <= mean <= bounds[1]),
            window_start=read_only(np.arange(sums.size) * self._window),
            **_window_test(sums, counts, used, self._window, self._dof_fraction),
        )

    def _apply_r_inv(self, values: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """``R_uu^-1 values`` for the sensors ``index`` (all without), diagonal fast path."""
        if self._r_diag is not None:
            r = self._r_diag if index is None else self._r_diag[index]
            return values / r[:, None]
        r = self._r_eff if index is None else self._r_eff[np.ix_(index, index)]
        return sla.cho_solve(sla.cho_factor(r), values)

    # ------------------------------------------------------------------ steady state

    def _steady_solution(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(filter gain, posterior covariance, predicted covariance) from the DARE, cached."""
        if self._steady is None:
            predicted = solve_filter_dare(self._A, self._C, self._q_eff, self._r_eff)
            posterior = posterior_from_predicted(predicted, self._C, self._r_eff)
            gain = filter_gain(predicted, self._C, self._r_eff, posterior)
            self._steady = (gain, posterior, predicted)
        return self._steady

    @property
    def steady_gain(self) -> np.ndarray:
        """Filter-form steady-state gain ``K = P C^T (C P C^T + R)^-1``, ``(n, p)``.

        ``control.dlqe`` returns the predictor-form gain, which equals ``A @ steady_gain``.
        """
        return read_only(self._steady_solution()[0].copy())

    @property
    def steady_covariance(self) -> np.ndarray:
        """Steady-state posterior covariance ``P[k|k]`` from the Riccati equation, ``(n, n)``."""
        return read_only(self._steady_solution()[1].copy())

    @property
    def innovation_covariance(self) -> np.ndarray:
        """Steady-state innovation covariance ``S = C P C^T + R + epsilon I``, ``(p, p)``.

        ``P`` is the steady predicted covariance of the Riccati equation; the innovations of a
        consistent filter have this covariance, and the NIS is ``e^T S^-1 e``.

        Examples
        --------
        >>> import control as ct
        >>> kf = KalmanFilter(ct.ss([[1.0]], [[0.0]], [[1.0]], 0, dt=1.0), Q=1.0, R=1.0)
        >>> float(kf.innovation_covariance[0, 0].round(4))   # P = (1 + sqrt 5) / 2, S = P + 1
        2.618
        """
        predicted = self._steady_solution()[2]
        s = self._C @ predicted @ self._C.T + self._r_eff
        return read_only((s + s.T) / 2)

    @property
    def spectral_reference(self) -> np.ndarray | None:
        """Reference whitened innovation power per bin of the spectral test (``None``: off)."""
        return self._spectral_ref

    @property
    def field_variance_scale(self) -> float:
        """Factor on the reported field variances (as given)."""
        return self._fv_scale

    @property
    def spectral_reference_count(self) -> int:
        """Segments times channels averaged in :attr:`spectral_reference` (as given)."""
        return self._spectral_count

    def _measure(self, x: np.ndarray) -> np.ndarray:
        return x[self._sel] if self._sel is not None else self._C @ x

    # ------------------------------------------------------------------ public API

    def reset(self, x0: object = None, P0: object = None) -> None:
        """Restart the real-time recursion of :meth:`step` from a prior.

        Parameters
        ----------
        x0 : array_like, optional
            New prior mean (default: the one given at construction).
        P0 : array_like, optional
            New prior covariance (default: the one given at construction).

        Raises
        ------
        InputError
            If ``x0`` or ``P0`` has the wrong shape or is not finite / PSD.
        """
        if x0 is not None:
            self._x0 = check_array("x0", x0, shape=(self._n,)).astype(float)
        if P0 is not None:
            self._P0 = check_covariance("P0", P0, self._n)
        self._running = _Recursion(self)

    @property
    def state(self) -> np.ndarray:
        """Current real-time estimate (after the last :meth:`step`, or the prior), ``(n,)``."""
        return self._running.x.copy()

    @property
    def covariance(self) -> np.ndarray:
        """Current real-time error covariance, ``(n, n)``."""
        return self._running.P.copy()

    def step(self, y_k: object, u_k: object = None) -> np.ndarray:
        """Process one sample in real time and return the filtered state ``x[k|k]``.

        Parameters
        ----------
        y_k : array_like
            Measurement ``(p,)``; NaN entries are missing sensors (all NaN: prediction only).
        u_k : array_like, optional
            Known input ``(m,)`` at this sample (used for ``D u[k]`` now and ``B u[k]`` in the
            next prediction); default zeros.

        Returns
        -------
        numpy.ndarray
            The filtered state ``(n,)``.

        Raises
        ------
        InputError
            If ``y_k`` or ``u_k`` has the wrong shape or contains infinities.
        EstimationError
            If the innovation covariance becomes singular.
        """
        y = check_array("y_k", y_k, shape=(self._p,), allow_nan=True)
        return self._advance(y, self._check_input_sample(u_k)).copy()

    def _advance(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One checked sample through the real-time recursion and its consistency window."""
        run = self._running
        _, nis, used = run.advance(y, u)
        if self._window is not None:
            run.monitor(nis, used)
        return run.x

    def step_block(self, measurements: object, inputs: object = None) -> np.ndarray:
        """Process a block of samples in real time: :meth:`step` on each column, in order.

        The same recursion, state and consistency windows as calling :meth:`step` once per
        sample, with the arguments checked once for the block instead of once per sample (a
        controller that receives its sensors in packets).

        Parameters
        ----------
        measurements : array_like
            ``(p, n_t)`` measurements, one column per sample; NaN entries are missing sensors.
        inputs : array_like, optional
            ``(m, n_t)`` known inputs at those samples; default zeros.

        Returns
        -------
        numpy.ndarray
            The filtered states ``(n, n_t)``, ``x[k|k]`` column by column.

        Raises
        ------
        InputError
            If an array has the wrong shape or contains infinities (or NaN in the inputs).
        EstimationError
            If the innovation covariance becomes singular.

        Examples
        --------
        >>> import numpy as np
        >>> import control as ct
        >>> import powerline_control as plc
        >>> sys = ct.ss([[0.9, 0.1], [0.0, 0.8]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], dt=1)
        >>> y = np.sin(0.3 * np.arange(6))[None, :]
        >>> one, block = plc.KalmanFilter(sys, 0.01, 0.1), plc.KalmanFilter(sys, 0.01, 0.1)
        >>> by_step = np.column_stack([one.step(y[:, k]) for k in range(6)])
        >>> bool(np.array_equal(block.step_block(y), by_step))
        True
        """
        y_all = check_array("measurements", measurements, shape=(self._p, None),
                            allow_nan=True)
        n_t = y_all.shape[1]
        if inputs is None or not self._m:
            if inputs is not None:
                check_array("inputs", inputs, shape=(self.n_inputs, n_t))
            u_all = np.zeros((self._m, n_t))
        else:
            u_all = check_array("inputs", inputs, shape=(self.n_inputs, n_t))
        states = np.empty((self._n, n_t))
        for k in range(n_t):
            states[:, k] = self._advance(y_all[:, k], u_all[:, k])
        return states

    def _check_input_sample(self, u_k: object) -> np.ndarray:
        if u_k is None:
            return np.zeros(self._m)
        u = check_array("u_k", u_k, shape=(self.n_inputs,))
        return u if self._m else np.zeros(0)

    def filter(
        self, measurements: object, inputs: object = None, *, update_state: bool = False
    ) -> Estimate:
        """Filter a whole record from the prior ``(x0, P0)``.

        Parameters
        ----------
        measurements : array_like
            ``(p, n_t)`` measurements, one row per output of the model; NaN = missing.
        inputs : array_like, optional
            ``(m, n_t)`` known inputs (e.g. the shaker force of a DMDc model); default zeros.
        update_state : bool
            If True, the real-time recursion of :meth:`step` continues from the end of this
            record (warm start: filter a calibration record, then step sample by sample). By
            default the real-time state is left untouched.

        Returns
        -------
        Estimate
            States, variances, innovations, NIS, the windowed consistency test (and the full
            field with a field map).

        Raises
        ------
        InputError
            If an array has the wrong shape or contains infinities (or NaN in the inputs).
        EstimationError
            If the innovation covariance becomes singular.

        Warns
        -----
        EstimatorInconsistentWarning
            With ``warn_inconsistent=True``, when the windowed NIS test rejects at 1 %
            (``Estimate.consistency.consistent`` is False): the innovations contradict the
            filter's own covariance.
        """
        if not isinstance(update_state, bool):
            raise InputError(
                f"The 'update_state' parameter must be True or False. Got {update_state!r}."
            )
        y_all = check_array("measurements", measurements, ndim=2, allow_nan=True)
        if y_all.shape[0] != self._p:
            raise InputError(
                "The 'measurements' parameter has the wrong shape: expected "
                f"({self._p}, n_t) (one row per model output, time along columns) but found "
                f"{y_all.shape}."
            )
        n_t = y_all.shape[1]
        if inputs is None:
            u_all = np.zeros((self._m, n_t))
        else:
            u_all = check_array("inputs", inputs, shape=(self.n_inputs, n_t))
            if not self._m:
                u_all = np.zeros((0, n_t))
        n, p = self._n, self._p
        states = np.empty((n, n_t))
        innovations = np.full((p, n_t), np.nan)
        nis = np.full(n_t, np.nan)
        n_used = np.zeros(n_t, dtype=int)
        missing_rows = np.isnan(y_all).any(axis=0)
        nan_positions = np.flatnonzero(missing_rows)  # to find NaN-free stretches
        # With a constant gain and no dropout the covariance never changes: store it once.
        variance_constant = self.steady_state and nan_positions.size == 0
        variances = None if variance_constant else np.empty((n, n_t))
        field_map = self._field_map
        field_variances = None
        if field_map is not None and not variance_constant:
            field_variances = np.empty((field_map.shape[0], n_t))
        # The field variance diag(M P M^T) needs the full P: compute it whenever P changes and
        # reuse it while P is the frozen one (the same object).
        last_p, last_field_var = None, None

        def field_variance_of(cov: np.ndarray) -> np.ndarray:
            nonlocal last_p, last_field_var
            if cov is not last_p:
                last_p, last_field_var = cov, self._fv_scale * mapped_variances(cov, field_map)
            return last_field_var

        run = _Recursion(self)
        k = 0
        while k < n_t:
            if run.converged and not run.first and not missing_rows[k]:
                nxt = np.searchsorted(nan_positions, k)
                end = int(nan_positions[nxt]) if nxt < nan_positions.size else n_t
                if end - k >= _MIN_BATCH and self._batch_ready(run):
                    self._run_batch(run, y_all, u_all, k, end, states, innovations, nis)
                    run.P = run.posterior_ss  # every sample of the stretch was a frozen update
                    if variances is not None:
                        variances[:, k:end] = np.diag(run.P)[:, None]
                    if field_variances is not None:
                        field_variances[:, k:end] = field_variance_of(run.P)[:, None]
                    n_used[k:end] = p
                    k = end
                    continue
            innovation, nis[k], n_used[k] = run.advance(y_all[:, k], u_all[:, k])
            innovations[:, k] = innovation
            states[:, k] = run.x
            if variances is not None:
                variances[:, k] = np.diag(run.P)
            if field_variances is not None:
                field_variances[:, k] = field_variance_of(run.P)
            k += 1
        if variance_constant:
            variances = np.broadcast_to(np.diag(run.P)[:, None], (n, n_t))
        if update_state:
            self._running = run
        field = None
        if field_map is not None:
            field = field_map @ states
            if variance_constant:
                field_variances = np.broadcast_to(
                    self._fv_scale * mapped_variances(run.P, field_map)[:, None],
                    (field.shape[0], n_t)
                )
        gain = run.last_full_gain if run.last_full_gain is not None else np.full((n, p), np.nan)
        estimate = Estimate(
            states=states,
            variances=variances,
            innovations=innovations,
            nis=nis,
            n_used=n_used,
            covariance=run.P.copy(),
            gain=gain.copy(),
            converged_at=run.converged_at,
            dt=self.dt,
            field=field,
            field_variances=field_variances,
            undetectable_modes=tuple(complex(v) for v in self._undetectable),
        )
        if update_state and self._window is not None:
            # The real-time monitor continues from this record's windows.
            sums, counts, _ = _window_sums(nis, self._window)
            used_sums = n_used[: sums.size * self._window].reshape(-1, self._window).sum(axis=1)
            run.closed = list(zip(sums.tolist(), counts.tolist(), used_sums.tolist(),
                                  strict=True))
            tail = n_t - sums.size * self._window
            rest_nis, rest_used = nis[n_t - tail:], n_used[n_t - tail:]
            ok = ~np.isnan(rest_nis)
            run.w_sum, run.w_valid = float(rest_nis[ok].sum()), int(ok.sum())
            run.w_used, run.w_len = int(rest_used.sum()), tail
        if self._window is None or not np.any(n_used):
            return estimate
        consistency = filter_consistency(estimate, window=self._window,
                                         dof_fraction=self._dof_fraction)
        if self._spectral_ref is not None:
            consistency = self._spectral_consistency(consistency, innovations, run)
        if self._warn and not consistency.consistent:
            warnings.warn(
                consistency.message + " Neither the estimate nor its variances describe this "
                "record (a load that drives modes the training never saw, or a changed line): "
                "retrain on a record with this excitation, add sensors, or do not act on it.",
                EstimatorInconsistentWarning,
                stacklevel=2,
            )
        return dataclasses.replace(estimate, consistency=consistency)

    def _spectral_consistency(self, consistency: Consistency, innovations: np.ndarray,
                              run: _Recursion) -> Consistency:
        """``consistency`` with the spectral test of the whitened innovations added."""
        if not run.converged:
            return consistency
        if run.s_factor is not None:
            factor = np.tril(run.s_factor[0])
        else:
            s = self._C @ run.predicted_ss @ self._C.T + self._r_eff
            factor = whitening_factor(s)
        segment = 2 * (self._spectral_ref.size - 1)
        psd, n_avg = whitened_psd(innovations, factor, discard=self._window, segment=segment)
        fields = spectral_test(psd, n_avg, self._spectral_ref, self._spectral_count)
        fields["spectral_ratio"] = read_only(fields["spectral_ratio"])
        fields["spectral_rejected"] = read_only(fields["spectral_rejected"])
        dt = 1.0 if self.dt is None else self.dt
        fields["spectral_frequencies"] = read_only(np.fft.rfftfreq(segment, dt))
        consistent = consistency.consistent and fields["spectral_consistent"] is not False
        return dataclasses.replace(consistency, consistent=consistent, **fields)

    # ------------------------------------------------------------------ batch recursion

    def _batch_ready(self, run: _Recursion) -> bool:
        """Prepare the modal form of the converged closed loop; False if too ill-conditioned."""
        if run.batch is None:
            if self.steady_state:
                # The steady gain never changes: decompose the closed loop once per filter.
                if self._steady_batch is None:
                    self._steady_batch = self._build_batch(run.gain_ss)
                run.batch = self._steady_batch
            else:
                run.batch = self._build_batch(run.gain_ss)
        return run.batch is not False

    def _build_batch(self, gain: np.ndarray):
        """Modal form of the converged posterior recursion, or False if it would lose accuracy.

        ``x[k] = F x[k-1] + K y[k] + (I - K C) B u[k-1] - K D u[k]`` with ``F = (I - K C) A``.
        With ``F = V diag(lambda) V^-1`` every mode is a first-order recursion, all evaluated
        together by :func:`_diagonal_recursion`; conjugate pairs are run once and lifted back
        with ``2 Re(.)``, so the lift is one real ``(n, n)`` product per stretch.
        """
        n = self._n
        i_kc = np.eye(n) - gain @ self._C
        closed = i_kc @ self._A
        eigenvalues, vectors = np.linalg.eig(closed)
        if np.linalg.cond(vectors) > _MAX_MODAL_CONDITION:
            return False
        real = np.flatnonzero(eigenvalues.imag == 0)
        upper = np.flatnonzero(eigenvalues.imag > 0)
        if real.size + 2 * upper.size != n:
            return False  # eigenvalues not in exact conjugate pairs: keep the loop
        keep = np.concatenate([real, upper])
        lu = sla.lu_factor(vectors)
        drive = gain if not self._m else np.hstack([gain, i_kc @ self._B, -gain @ self._D])
        modal_drive = sla.lu_solve(lu, drive.astype(complex))[keep]
        lift = np.hstack(
            [vectors[:, real].real, 2 * vectors[:, upper].real, -2 * vectors[:, upper].imag]
        )
        powers, toeplitz = _recursion_tables(eigenvalues[keep], _SCAN_BLOCK)
        return {
            "powers": powers,
            "toeplitz": toeplitz,
            "eigenvalues": eigenvalues[keep],
            "n_real": real.size,
            "lift": np.ascontiguousarray(lift),
            "drive_re": np.ascontiguousarray(modal_drive.real),
            "drive_im": np.ascontiguousarray(modal_drive[real.size :].imag),
            "lu": lu,
            "keep": keep,
            "predict_output": self._C @ self._A,
            "predict_input": self._C @ self._B if self._m else None,
        }

    def _run_batch(self, run, y_all, u_all, start, end, states, innovations, nis) -> None:
        """Samples ``start:end`` (converged, NaN-free) through the diagonalised closed loop."""
        cache = run.batch
        n_real = cache["n_real"]
        length = end - start
        y = y_all[:, start:end]
        if self._m:
            u = u_all[:, start:end]
            u_prev = np.empty_like(u)
            u_prev[:, 0] = run.u_prev
            u_prev[:, 1:] = u[:, :-1]
            drivers = np.vstack([y, u_prev, u])
        else:
            drivers = y
        drive_re = cache["drive_re"] @ drivers
        drive_im = cache["drive_im"] @ drivers
        z0 = sla.lu_solve(cache["lu"], run.x.astype(complex))[cache["keep"]]
        drive = drive_re.astype(complex)
        drive[n_real:] += 1j * drive_im
        modal = _diagonal_recursion(cache["powers"], cache["toeplitz"], drive, z0)
        n_pairs = modal.shape[0] - n_real
        stacked = np.empty((self._n, length))
        stacked[:n_real] = modal[:n_real].real
        stacked[n_real : n_real + n_pairs] = modal[n_real:].real
        stacked[n_real + n_pairs :] = modal[n_real:].imag
        block = np.matmul(cache["lift"], stacked, out=states[:, start:end])
        # Innovations y[k] - C (A x[k-1] + B u[k-1]) - D u[k] from the states just computed.
        seen = cache["predict_output"] @ block
        predicted = np.empty_like(y)
        predicted[:, 0] = cache["predict_output"] @ run.x
        predicted[:, 1:] = seen[:, :-1]
        if self._m:
            predicted += cache["predict_input"] @ u_prev + self._D @ u
        e = y - predicted
        innovations[:, start:end] = e
        nis[start:end] = run.nis_frozen(e)
        run.x = block[:, -1].copy()
        if self._m:
            run.u_prev = u[:, -1].copy()
        run.k += length


def _recursion_tables(eigenvalues: np.ndarray, block: int) -> tuple[np.ndarray, np.ndarray]:
    """Powers ``lambda^j`` (j = 0..block) and the transposed in-block Toeplitz matrices."""
    powers = eigenvalues[:, None] ** np.arange(block + 1)[None, :]
    lag = np.arange(block)[:, None] - np.arange(block)[None, :]  # i - j
    toeplitz = np.where(lag >= 0, powers[:, np.clip(lag, 0, block)], 0.0)
    return powers, np.ascontiguousarray(toeplitz.transpose(0, 2, 1))


def _diagonal_recursion(
    powers: np.ndarray, toeplitz_t: np.ndarray, drive: np.ndarray, z0: np.ndarray
) -> np.ndarray:
    """All ``z_j[k] = lambda_j z_j[k-1] + drive_j[k]`` at once, with ``z_j[-1] = z0_j``.

    A blocked scan without a Python loop over samples: inside blocks of ``b`` samples the
    response to the drive is a batched product with the lower-triangular Toeplitz matrices of
    ``lambda^(i-j)``; the state carried between blocks follows ``s_k = lambda^b s_{k-1} + end_k``
    (a loop over ``n_t / b`` blocks, vectorised over modes). Only non-negative powers of
    ``lambda`` appear (``|lambda| < 1`` for a converged filter), so nothing overflows.
    """
    n_modes, length = drive.shape
    block = powers.shape[1] - 1
    n_blocks = -(-length // block)
    padded = np.zeros((n_modes, n_blocks * block), dtype=complex)
    padded[:, :length] = drive
    local = np.matmul(padded.reshape(n_modes, n_blocks, block), toeplitz_t)
    ends = local[:, :, -1].copy()
    carried = np.empty((n_modes, n_blocks), dtype=complex)
    state = z0.astype(complex)
    step = powers[:, block]
    for k in range(n_blocks):
        carried[:, k] = state
        state = step * state + ends[:, k]
    local += carried[:, :, None] * powers[:, None, 1:]
    return local.reshape(n_modes, n_blocks * block)[:, :length]


# --------------------------------------------------------------------------- accuracy


@dataclass(frozen=True)
class Accuracy:
    """RMS estimation errors, relative to the RMS of the true signal.

    Attributes
    ----------
    relative_rms_error : float
        ``rms(estimate - truth) / rms(truth)`` over all signals and samples used.
    relative_rms_error_unmeasured : float or None
        The same over the unmeasured signals only, still relative to the RMS of *all* true signals
        (the RMS displacement of the span); ``None`` when every signal is measured.
    relative_rms_error_unmeasured_own : float or None
        Unmeasured error relative to the RMS of the unmeasured true signals themselves.
    rms_truth : float
        RMS of the true signals (e.g. the RMS displacement, metres).
    per_signal_rms_error : numpy.ndarray
        RMS error of each signal ``(n_signals,)`` in the signals' units.
    n_samples : int
        Number of samples used (after ``discard``).

    Examples
    --------
    >>> acc = estimation_accuracy(np.array([[1.1, -0.9]]), np.array([[1.0, -1.0]]))
    >>> round(acc.relative_rms_error, 3), acc.n_samples
    (0.1, 2)
    """

    relative_rms_error: float
    relative_rms_error_unmeasured: float | None
    relative_rms_error_unmeasured_own: float | None
    rms_truth: float
    per_signal_rms_error: np.ndarray
    n_samples: int


def estimation_accuracy(
    estimate: Estimate | object,
    truth: object,
    measured: Sequence[int] | None = None,
    *,
    discard: int = 0,
) -> Accuracy:
    """RMS error of an estimate against the truth, for all signals and for the unmeasured ones.

    Parameters
    ----------
    estimate : Estimate or array_like
        An :class:`Estimate` (its ``field`` when it has one, else its ``states``) or an
        ``(n_signals, n_t)`` array.
    truth : array_like
        True signals ``(n_signals, n_t)``, e.g. ``snap.true_displacement`` of an independent
        simulation.
    measured : sequence of int, optional
        Rows of ``truth`` that were measured; the others are "unmeasured".
    discard : int
        Leading samples left out (the filter's transient from its prior).

    Returns
    -------
    Accuracy
        The errors.

    Raises
    ------
    InputError
        If shapes disagree, ``measured`` is out of range or ``discard`` leaves no samples.

    Examples
    --------
    >>> truth = np.array([[1.0, -1.0], [2.0, -2.0]])
    >>> acc = estimation_accuracy(truth + 0.1, truth, measured=[0])
    >>> round(acc.relative_rms_error, 4), round(acc.relative_rms_error_unmeasured, 4)
    (0.0632, 0.0632)
    """
    if isinstance(estimate, Estimate):
        values = estimate.field if estimate.field is not None else estimate.states
    else:
        values = check_array("estimate", estimate, ndim=2)
    true = check_array("truth", truth, ndim=2)
    if true.shape != values.shape:
        raise InputError(
            f"The 'truth' parameter has the wrong shape: expected {values.shape} (as the "
            f"estimate) but found {true.shape}."
        )
    discard = check_int("discard", discard, low=0, high=true.shape[1] - 1)
    error = values[:, discard:] - true[:, discard:]
    true = true[:, discard:]
    rms_truth = float(np.sqrt(np.mean(true**2)))
    if rms_truth == 0:
        raise InputError("The 'truth' parameter is identically zero; no relative error exists.")
    per_signal = np.sqrt(np.mean(error**2, axis=1))
    unmeasured_error = unmeasured_own = None
    if measured is not None:
        rows = np.zeros(true.shape[0], dtype=bool)
        # Integer row indices only: measured=[0.7] used to be read as row 0.
        index = check_indices("measured", measured, true.shape[0], allow_empty=True)
        rows[index] = True
        if (~rows).any():
            err_u = float(np.sqrt(np.mean(error[~rows] ** 2)))
            unmeasured_error = err_u / rms_truth
            own = float(np.sqrt(np.mean(true[~rows] ** 2)))
            unmeasured_own = err_u / own if own > 0 else float("inf")
    return Accuracy(
        relative_rms_error=float(np.sqrt(np.mean(error**2))) / rms_truth,
        relative_rms_error_unmeasured=unmeasured_error,
        relative_rms_error_unmeasured_own=unmeasured_own,
        rms_truth=rms_truth,
        per_signal_rms_error=read_only(per_signal),
        n_samples=int(true.shape[1]),
    )


@dataclass(frozen=True)
class Consistency:
    """NEES / NIS statistics: is the filter's covariance honest about its errors?

    Two views of the same question (design.md 4.7). The whole-record means (``mean_nis``,
    ``mean_nees``) with their 95 % bands; and the *windowed* test that
    :meth:`KalmanFilter.filter` runs on every record: the NIS averaged over consecutive windows
    of ``window`` samples, each compared with its two-sided 1 % chi-square bounds. The run is
    ``consistent`` unless more windows reject than chance allows at 1 % (a binomial bound on
    the count, so that a long record of an honest filter does not warn merely because it has
    many windows).

    Attributes
    ----------
    mean_nis : float
        Mean normalised innovation squared over the samples used.
    nis_dof : float
        Mean number of sensors per update (the expected value of ``mean_nis``).
    nis_bounds : tuple of float
        Two-sided 95 % chi-square band of ``mean_nis`` for a consistent filter (valid since the
        innovations of an optimal filter are white).
    nis_consistent : bool
        ``mean_nis`` inside ``nis_bounds``.
    mean_nees : float or None
        Mean normalised estimation error squared ``e^T P^-1 e`` (needs the truth and a
        converged gain), ``None`` otherwise.
    nees_dof : int or None
        Its expected value: the rank of the covariance used.
    nees_bounds : tuple of float or None
        95 % chi-square band of ``mean_nees`` treating samples as independent; estimation errors
        are correlated in time, so read it as a guide rather than a test.
    nees_consistent : bool or None
        ``mean_nees`` inside ``nees_bounds``.
    normalised_error : numpy.ndarray or None
        Per-signal mean of ``error^2 / variance`` ``(n_signals,)`` (1 for an honest variance).
    window : int
        Samples per window of the windowed test.
    window_start : numpy.ndarray
        First sample of each full window, ``(n_windows,)`` (a trailing partial window is left
        out).
    window_nis : numpy.ndarray
        The statistic: mean NIS of each window, ``(n_windows,)`` (NaN for a window without a
        measurement).
    window_dof : numpy.ndarray
        Degrees of freedom of each window's chi-square law: ``dof_fraction`` times the number
        of scalar innovations in it (``window * p`` without dropouts). The window's sum of NIS
        times ``dof_fraction`` is chi-square with this many degrees of freedom.
    window_bounds : numpy.ndarray
        Two-sided 1 % bounds of each window's mean NIS, ``(n_windows, 2)``.
    rejected : numpy.ndarray
        Indices of the tested windows whose mean NIS lies outside its bounds (int).
    n_tested : int
        Windows tested: every full window after the first (which holds the filter's transient
        from its prior) that has a measurement.
    consistent : bool
        False when the number of windows rejected *above* their bounds (innovations larger than
        the filter's covariance says: an overconfident estimate) exceeds the 99 % quantile of a
        binomial law with ``n_tested`` trials of probability 1 % (the run-level test at 1 %), or
        when the spectral test rejects; True when no window could be tested. Windows below
        their bounds make the run ``pessimistic`` instead.
    pessimistic : bool
        As many windows rejected *below* their bounds: the innovations are smaller than the
        filter's covariance says (a reported sigma larger than the error, the safe side; typical
        of a record still ringing up from rest, whose model error grows with the field). Not a
        reason to warn: a load the model does not know raises the innovations at some
        frequency, which the spectral test sees even when the total NIS falls.
    dof_fraction : float
        Share of the nominal degrees of freedom treated as independent (1 for the white
        innovations of an exact model; below 1 when a design measured on held-out data that its
        innovations carry fewer independent samples, see
        :func:`~powerline_control.recipe.design_estimator`).
    window_nees : numpy.ndarray or None
        Mean NEES of each window (with the truth, from the converged gain on), else ``None``.
    nees_rejected : numpy.ndarray or None
        Indices into ``window_nees`` of windows outside their 1 % chi-square bounds (estimation
        errors are correlated in time: a guide, as ``nees_bounds``).
    spectral_frequencies : numpy.ndarray or None
        Frequencies (Hz; cycles per sample without ``dt``) of the spectral test's bins, when the
        filter carries a ``spectral_reference`` (every filter
        :func:`~powerline_control.recipe.design_estimator` builds from a broadband record).
    spectral_ratio : numpy.ndarray or None
        The record's whitened innovation power in each bin over the reference's (1: like the
        held-out part of the training record; far above 1: power the model does not predict,
        a load that drives modes the training never saw).
    spectral_threshold : float or None
        The ratio above which a bin is rejected: the larger of a fixed factor (two matched
        records of an identified model differ by more than sampling) and the F quantile at 1 %
        with a Bonferroni correction over the bins.
    spectral_rejected : numpy.ndarray or None
        Indices of the rejected bins.
    spectral_consistent : bool or None
        No bin rejected (``None``: no spectral test). ``consistent`` is False when either the
        windowed NIS test or the spectral test rejects.

    Examples
    --------
    See :func:`filter_consistency`, which builds it:

    >>> import control as ct
    >>> sys = ct.ss([[0.5]], [[0.0]], [[1.0]], 0, dt=1.0)
    >>> est = KalmanFilter(sys, Q=1.0, R=1.0).filter(np.array([[1.0, -1.0, 0.5]]))
    >>> filter_consistency(est).nis_dof
    1.0
    """

    mean_nis: float
    nis_dof: float
    nis_bounds: tuple[float, float]
    nis_consistent: bool
    mean_nees: float | None = None
    nees_dof: int | None = None
    nees_bounds: tuple[float, float] | None = None
    nees_consistent: bool | None = None
    normalised_error: np.ndarray | None = None
    window: int = 0
    window_start: np.ndarray = dataclasses.field(
        default_factory=lambda: read_only(np.zeros(0, int)))
    window_nis: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0)))
    window_dof: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0)))
    window_bounds: np.ndarray = dataclasses.field(
        default_factory=lambda: read_only(np.zeros((0, 2))))
    rejected: np.ndarray = dataclasses.field(default_factory=lambda: read_only(np.zeros(0, int)))
    n_tested: int = 0
    consistent: bool = True
    pessimistic: bool = False
    dof_fraction: float = 1.0
    window_nees: np.ndarray | None = None
    nees_rejected: np.ndarray | None = None
    spectral_frequencies: np.ndarray | None = None
    spectral_ratio: np.ndarray | None = None
    spectral_threshold: float | None = None
    spectral_rejected: np.ndarray | None = None
    spectral_consistent: bool | None = None

    def __post_init__(self) -> None:
        _freeze_arrays(self)

    @property
    def message(self) -> str:
        """One sentence: what the windowed test found, for a warning or a report."""
        if not self.n_tested:
            return (f"No window of {self.window} samples could be tested (the record is shorter "
                    "than two windows): the filter's consistency is unknown.")
        tested = self.window_nis[1:][np.isfinite(self.window_nis[1:])]
        expected = self.window_dof[1:] / self.dof_fraction / self.window
        ratio = float(np.nanmedian(self.window_nis[1:] / np.where(expected > 0, expected, np.nan)))
        verdict = ("consistent" if self.consistent else
                   "INCONSISTENT: the model does not fit this record")
        if self.consistent and self.pessimistic:
            verdict += " (pessimistic: the innovations are smaller than the covariance says)"
        spectral = ""
        if self.spectral_consistent is not None:
            worst = int(np.nanargmax(np.where(np.arange(self.spectral_ratio.size) > 0,
                                              self.spectral_ratio, np.nan)))
            spectral = (" Innovation spectrum against the training's: "
                        f"{self.spectral_rejected.size} of {self.spectral_ratio.size - 1} bins "
                        f"above {self.spectral_threshold:.3g} times the reference (largest "
                        f"{self.spectral_ratio[worst]:.3g} at "
                        f"{self.spectral_frequencies[worst]:.4g} Hz).")
        return (f"Windowed NIS test ({self.window} samples per window, 1 % two-sided chi-square "
                f"bounds): {self.rejected.size} of {self.n_tested} windows rejected, mean NIS "
                f"{float(np.mean(tested)):.3g} per sample against {float(np.mean(expected)):.3g}"
                f" expected (median ratio {ratio:.3g}).{spectral} Verdict: {verdict}.")


def _window_test(sums: np.ndarray, counts: np.ndarray, used: np.ndarray, window: int,
                 dof_fraction: float) -> dict:
    """Windowed NIS fields of :class:`Consistency` from per-window sums of NIS.

    ``sums``: NIS summed over the valid samples of each window; ``counts``: valid samples;
    ``used``: scalar innovations (sensors summed over the window). The sum times
    ``dof_fraction`` is chi-square with ``dof_fraction * used`` degrees of freedom.
    """
    sums, counts, used = (np.asarray(v, dtype=float) for v in (sums, counts, used))
    n_windows = sums.size
    dof = dof_fraction * used
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(counts > 0, sums / np.where(counts > 0, counts, 1.0), np.nan)
        scale = dof_fraction * np.where(counts > 0, counts, np.nan)
        low, high = sstats.chi2.ppf([[_WINDOW_LEVEL / 2], [1 - _WINDOW_LEVEL / 2]],
                                    np.where(dof > 0, dof, np.nan)) / scale
    bounds = np.column_stack([low, high]) if n_windows else np.zeros((0, 2))
    tested = np.zeros(n_windows, dtype=bool)
    tested[1:] = counts[1:] > 0  # the first window holds the transient from the prior
    above = tested & (mean > bounds[:, 1])
    below = tested & (mean < bounds[:, 0])
    n_tested = int(tested.sum())
    allowed = int(sstats.binom.ppf(1 - _WINDOW_LEVEL, n_tested, _WINDOW_LEVEL)) if n_tested else 0
    rejected = np.flatnonzero(above | below)
    return {
        "pessimistic": bool(int(below.sum()) > allowed),
        "window": int(window),
        "window_nis": read_only(mean),
        "window_dof": read_only(dof),
        "window_bounds": read_only(bounds),
        "rejected": read_only(rejected),
        "n_tested": n_tested,
        "consistent": bool(int(above.sum()) <= allowed),
        "dof_fraction": float(dof_fraction),
    }


def _window_sums(values: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sums over valid samples, valid counts, starts) of each full window of ``values``."""
    n_windows = values.size // window
    block = values[: n_windows * window].reshape(n_windows, window)
    valid = ~np.isnan(block)
    sums = np.where(valid, block, 0.0).sum(axis=1)
    return sums, valid.sum(axis=1), np.arange(n_windows) * window


def _chi2_band(total_dof: float, n_samples: int) -> tuple[float, float]:
    low, high = sstats.chi2.ppf([0.025, 0.975], total_dof)
    return float(low / n_samples), float(high / n_samples)


def filter_consistency(
    estimate: Estimate,
    truth: object = None,
    *,
    discard: int = 0,
    field_map: object = None,
    window: int = DEFAULT_CONSISTENCY_WINDOW,
    dof_fraction: float = 1.0,
) -> Consistency:
    """NIS (always) and NEES (with the truth) of a filter run, whole-record and windowed.

    Parameters
    ----------
    estimate : Estimate
        A filter run.
    truth : array_like, optional
        True states ``(n, n_t)``, or the true field ``(n_nodes, n_t)`` when ``estimate.field``
        exists (then ``field_map`` is needed for the full NEES).
    discard : int
        Leading samples left out (the transient from the prior).
    field_map : array_like, optional
        The filter's field map ``(n_nodes, n)``, one column per state, to map the final
        covariance to the field for the NEES.
    window : int
        Samples per window of the windowed test (default 200); windows tile the record from
        ``discard`` on.
    dof_fraction : float
        Share ``0 < f <= 1`` of the nominal chi-square degrees of freedom of each window treated
        as independent (1: white innovations, the textbook test).

    Returns
    -------
    Consistency
        The statistics. NEES uses the final (converged) posterior covariance for every sample
        after ``max(discard, estimate.converged_at)``, with a pseudo-inverse on its range (pinned
        nodes have zero variance) and the rank as degrees of freedom.

    Raises
    ------
    InputError
        If shapes disagree, ``discard`` leaves no samples, ``window`` is not a positive integer
        or ``dof_fraction`` is outside ``(0, 1]``.

    Examples
    --------
    >>> import control as ct
    >>> rng = np.random.default_rng(0)
    >>> sys = ct.ss([[0.9]], [[0.0]], [[1.0]], 0, dt=1.0)
    >>> x = np.zeros(2000)
    >>> for k in range(1, 2000):
    ...     x[k] = 0.9 * x[k - 1] + rng.normal()
    >>> est = KalmanFilter(sys, Q=1.0, R=0.25).filter(x[None] + 0.5 * rng.normal(size=(1, 2000)))
    >>> c = filter_consistency(est, x[None], discard=10)
    >>> c.nis_consistent, c.nees_consistent, c.consistent, c.n_tested
    (True, True, True, 8)
    """
    if not isinstance(estimate, Estimate):
        raise InputError(
            f"The 'estimate' parameter must be an Estimate. Got {type(estimate).__name__}."
        )
    n_t = estimate.states.shape[1]
    discard = check_int("discard", discard, low=0, high=n_t - 1)
    # The map is checked when given, whether or not the truth below uses it.
    field_map = check_field_map(field_map, estimate.states.shape[0])
    window = check_int("window", window, low=1)
    dof_fraction = check_real("dof_fraction", dof_fraction, low=0.0, high=1.0)
    nis = estimate.nis[discard:]
    used = estimate.n_used[discard:]
    valid = ~np.isnan(nis)
    if not valid.any():
        raise InputError("No sample after 'discard' has a measurement; NIS is undefined.")
    mean_nis = float(np.mean(nis[valid]))
    total = float(np.sum(used[valid]))
    nis_bounds = _chi2_band(total, int(valid.sum()))
    sums, counts, starts = _window_sums(nis, window)
    used_sums = used[: starts.size * window].reshape(-1, window).sum(axis=1) if starts.size \
        else np.zeros(0)
    result = {
        "mean_nis": mean_nis,
        "nis_dof": float(total / valid.sum()),
        "nis_bounds": nis_bounds,
        "nis_consistent": bool(nis_bounds[0] <= mean_nis <= nis_bounds[1]),
        "window_start": read_only(starts + discard),
        **_window_test(sums, counts, used_sums, window, dof_fraction),
    }
    if truth is None:
        return Consistency(**result)
    true = check_array("truth", truth, ndim=2)
    if estimate.field is not None and true.shape == estimate.field.shape:
        values, variances = estimate.field, estimate.field_variances
        if field_map is None:
            covariance = None
        else:
            covariance = field_map @ estimate.covariance @ field_map.T
    elif true.shape == estimate.states.shape:
        values, variances, covariance = estimate.states, estimate.variances, estimate.covariance
    else:
        raise InputError(
            f"The 'truth' parameter has the wrong shape: expected {estimate.states.shape} "
            f"(states) or the field's shape, but found {true.shape}."
        )
    error = values[:, discard:] - true[:, discard:]
    var = np.asarray(variances)[:, discard:]
    positive = var > 0
    normalised = np.where(positive, error**2 / np.where(positive, var, 1.0), 0.0).mean(axis=1)
    result["normalised_error"] = read_only(normalised)
    if covariance is not None and estimate.converged_at is not None:
        start = max(discard, estimate.converged_at)
        if start < n_t:
            eigenvalues, vectors = np.linalg.eigh((covariance + covariance.T) / 2)
            keep = eigenvalues > eigenvalues.max() * _NEES_RANK_RTOL
            whitened = (vectors[:, keep].T @ (values[:, start:] - true[:, start:])) / np.sqrt(
                eigenvalues[keep]
            )[:, None]
            nees = np.sum(whitened**2, axis=0)
            dof = int(keep.sum())
            bounds = _chi2_band(dof * nees.size, nees.size)
            mean_nees = float(np.mean(nees))
            nees_sums, nees_counts, _ = _window_sums(nees, window)
            nees_windows = _window_test(nees_sums, nees_counts, dof * nees_counts, window, 1.0)
            # Every NEES window is tested (the converged gain already left the transient out).
            nees_mean = nees_windows["window_nis"]
            nees_bounds_w = nees_windows["window_bounds"]
            result.update(
                mean_nees=mean_nees,
                nees_dof=dof,
                nees_bounds=bounds,
                nees_consistent=bool(bounds[0] <= mean_nees <= bounds[1]),
                window_nees=nees_mean,
                nees_rejected=read_only(np.flatnonzero(
                    (nees_mean < nees_bounds_w[:, 0]) | (nees_mean > nees_bounds_w[:, 1]))),
            )
    return Consistency(**result)
