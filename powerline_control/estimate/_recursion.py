"""The recursion behind :class:`~powerline_control.estimate.KalmanFilter`, sample by sample and
in batches.

:class:`_Recursion` is the per-sample filter state (Joseph or information update, convergence
tracking, divergence checks) shared by ``step`` and ``filter``; :class:`_FilterInternals` holds
the filter's private helpers: the steady-state DARE solution, the spectral test of a run, and the
modal batch recursion that evaluates converged NaN-free stretches as a blocked scan over all
modes at once (:func:`_recursion_tables`, :func:`_diagonal_recursion`).

Test seam: ``_recursion_tables``, ``_diagonal_recursion`` and ``_SCAN_BLOCK``: the blocked scan is
checked against a plain step-by-step recursion across block boundaries (tests/test_estimate.py).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla

from .._riccati import (
    describe_modes,
    filter_gain,
    posterior_from_predicted,
    solve_filter_dare,
)
from .._validation import (
    check_array,
    read_only,
)
from ..errors import (
    EstimationError,
)
from ._adaptive import _Adaptation
from ._spectrum import (
    NIS_FIELD_SPAN,
    following_reference,
    measurement_psd,
    nis_growth,
    spectral_test,
    whitened_psd,
    whitening_factor,
    window_nis_growth,
)
from .consistency import _window_sums

if TYPE_CHECKING:  # annotations only: both modules import this one
    from .filter import KalmanFilter
    from .result import Consistency

# The modal batch recursion is used only when the eigenvector matrix of the closed loop is this
# well conditioned; its round-off grows with cond(V), and beyond this it could differ from the
# loop by more than 1e-9 relative.
_MAX_MODAL_CONDITION = 1e6
# Consecutive full samples with a gain change below gain_rtol before the gain is frozen.
_CONFIRM_SAMPLES = 10
# Block length of the vectorised diagonal recursion: in-block work grows with it, the Python
# loop over blocks shrinks with it; 16 was fastest for n = 101 on the reference machine.
_SCAN_BLOCK = 16


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
        # With a field reference the window's factor on S follows the spectrum of the last
        # NIS_FIELD_SPAN measurements: a ring buffer of them (``recent_count`` stored so far).
        self.recent = (np.full((kf._p, NIS_FIELD_SPAN), np.nan) if kf._follows_spectrum
                       else None)
        self.recent_count = 0
        # Running mean square of the estimate at the sensors (KalmanFilter's innovation_growth).
        self.mean_square = 0.0
        # Scalar covariance matching of Q (KalmanFilter's adapt_horizon), None when off.
        self.adapt = _Adaptation(kf) if kf._adapt_horizon is not None else None
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
        self.closed_loop = None   # (F, (I - K C) B) of advance_frozen, built on first use
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

    def monitor(self, nis: float, used: int, y: np.ndarray) -> None:
        """Add one sample's NIS (and its measurement ``y``) to the open consistency window,
        closing it when full: with a field reference its NIS sum is then divided by the
        window's factor on ``S`` (``_spectrum.nis_growth``)."""
        if self.recent is not None:
            self.recent[:, self.recent_count % NIS_FIELD_SPAN] = y
            self.recent_count += 1
        if used:
            self.w_sum += nis
            self.w_valid += 1
            self.w_used += used
        self.w_len += 1
        if self.w_len == self.kf._window:
            if self.recent is not None:
                self.w_sum /= self.kf._realtime_growth(self)
            self.closed.append((self.w_sum, self.w_valid, self.w_used))
            self.w_sum, self.w_valid, self.w_used, self.w_len = 0.0, 0, 0, 0

    def resume(self, nis: np.ndarray, raw_nis: np.ndarray, n_used: np.ndarray,
               measurements: np.ndarray) -> None:
        """Continue the real-time monitor from a record ``filter`` ran (``update_state=True``):
        its full windows closed (``nis`` with ``S_k``), the rest open. With a field reference
        the open window's factor on ``S`` is set when it closes, so it holds ``raw_nis`` (with
        ``S``), and the ring buffer the record's last measurements."""
        window, n_t = self.kf._window, nis.size
        sums, counts, _ = _window_sums(nis, window)
        used_sums = n_used[: sums.size * window].reshape(-1, window).sum(axis=1)
        self.closed = list(zip(sums.tolist(), counts.tolist(), used_sums.tolist(), strict=True))
        tail = n_t - sums.size * window
        rest_nis = (raw_nis if self.kf._follows_spectrum else nis)[n_t - tail:]
        ok = ~np.isnan(rest_nis)
        self.w_sum, self.w_valid = float(rest_nis[ok].sum()), int(ok.sum())
        self.w_used, self.w_len = int(n_used[n_t - tail:].sum()), tail
        self.remember(measurements)

    def remember(self, measurements: np.ndarray) -> None:
        """Fill the ring buffer of :meth:`monitor` with the end of a record (``filter(...,
        update_state=True)``)."""
        if self.recent is None:
            return
        tail = measurements[:, -NIS_FIELD_SPAN:]
        self.recent[:, :tail.shape[1]] = tail
        self.recent_count = tail.shape[1]

    def recent_measurements(self) -> np.ndarray:
        """The buffered measurements, oldest first ``(p, min(count, NIS_FIELD_SPAN))``."""
        if self.recent_count < NIS_FIELD_SPAN:
            return self.recent[:, :self.recent_count]
        return np.roll(self.recent, -(self.recent_count % NIS_FIELD_SPAN), axis=1)

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
        propagated = None
        if p_pred is None:
            # From the current covariance: after a frozen full sample P is the stationary
            # posterior and this is the stationary prior; during a dropout it grows as it must.
            if self.adapt is None:
                p_pred = kf._A @ self.P @ kf._A.T + kf._q_eff
            else:  # Q scaled by the matched q (estimate._adaptive)
                propagated = kf._A @ self.P @ kf._A.T
                p_pred = propagated + self.adapt.q * kf._Q + kf._epsilon * np.eye(kf._n)
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
        if self.adapt is not None:  # q changes every sample: the gain is never frozen
            if propagated is not None:
                self.adapt.update(nis, propagated)
            self.last_full_gain = gain
            return innovation, nis, index.size
        self._track_convergence(gain)
        return innovation, nis, index.size

    def advance_frozen(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Samples ``y`` ``(p, L)`` (inputs ``u`` ``(m, L)``) through the frozen update: states
        ``(n, L)``; the windows' NIS as :meth:`advance` then :meth:`monitor` per sample.

        For a converged recursion and NaN-free samples only. Each sample is then the linear
        closed loop ``x[k] = F x[k-1] + K y[k] + (I - K C) B u[k-1] - K D u[k]`` with
        ``F = (I - K C) A`` (the batch form of :meth:`_FilterInternals._build_batch`, stepped
        here, not diagonalised): one product per sample, the drives of the block and its
        innovations in one product each; equal to :meth:`advance` per sample to round-off.
        """
        kf = self.kf
        if self.closed_loop is None:
            i_kc = np.eye(kf._n) - self.gain_ss @ kf._C
            self.closed_loop = (i_kc @ kf._A, i_kc @ kf._B if kf._m else None)
        closed, input_map = self.closed_loop
        n_t = y.shape[1]
        drive = self.gain_ss @ y
        previous = np.empty((kf._n, n_t))      # x[k-1] per column
        if kf._m:
            u_prev = np.column_stack([self.u_prev, u[:, :-1]])
            drive += input_map @ u_prev - self.gain_ss @ (kf._D @ u)
        states = np.empty((kf._n, n_t))
        x = self.x
        for k in range(n_t):
            previous[:, k] = x
            x = closed @ x + drive[:, k]
            states[:, k] = x
        predicted = kf._A @ previous
        if kf._m:
            predicted += kf._B @ u_prev
        innovations = y - (predicted[kf._sel] if kf._sel is not None else kf._C @ predicted)
        if kf._m:
            innovations -= kf._D @ u
        self.x, self.P, self.k = x, self.posterior_ss, self.k + n_t
        if n_t:
            self.u_prev = u[:, -1]
        nis_block = self.nis_frozen(innovations)
        if kf._total_growth:
            factor, self.mean_square = kf._inflation(states, self.mean_square)
            nis_block = nis_block / factor
        if kf._window is not None:
            for k, nis in enumerate(nis_block.tolist()):
                self.monitor(nis, kf._p, y[:, k])
        return states

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



class _FilterInternals:
    """Private helpers of :class:`~powerline_control.estimate.KalmanFilter` (mixed into it)."""

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

    def _measure(self, x: np.ndarray) -> np.ndarray:
        return x[self._sel] if self._sel is not None else self._C @ x

    def _check_input_sample(self, u_k: object) -> np.ndarray:
        if u_k is None:
            return np.zeros(self._m)
        u = check_array("u_k", u_k, shape=(self.n_inputs,))
        return u if self._m else np.zeros(0)

    def _check_input_block(self, inputs: object, n_t: int) -> np.ndarray:
        """Known inputs ``(m, n_t)`` of a block or record (zeros when not given)."""
        if inputs is None:
            return np.zeros((self._m, n_t))
        u = check_array("inputs", inputs, shape=(self.n_inputs, n_t))
        return u if self._m else np.zeros((0, n_t))

    def _s_growth(self, states: np.ndarray, measurements: np.ndarray,
                  run: _Recursion) -> np.ndarray | None:
        """Factor on ``S`` per sample of a record (``S_k = S factor``), ``None`` for ``S_k = S``:
        the one place that chooses it. Per frequency with a field reference (one factor per
        consistency window, ``_spectrum.window_nis_growth``), else from the running mean
        square of the whole field at the sensors (``innovation_growth``; ``run.mean_square``
        is carried on). :meth:`KalmanFilter.filter` scales its field variances by the
        per-frequency factor too (``Estimate.field_growth``), not by the other."""
        if self._follows_spectrum:
            whitener = self._spectral_whitener(run)
            if whitener is None:
                return None
            return window_nis_growth(measurements, self._window, whitener,
                                     self._spectral_ref, *self._spectral_field,
                                     converged_at=run.converged_at or 0)
        if self._total_growth:
            factor, run.mean_square = self._inflation(states, run.mean_square)
            return factor
        return None

    def _spectral_whitener(self, run: _Recursion) -> np.ndarray | None:
        """Lower Cholesky factor of the converged ``S`` the spectral test and the windowed
        test's factor whiten by (``None`` before the gain converges)."""
        if not run.converged:
            return None
        if run.s_factor is not None:
            return np.tril(run.s_factor[0])
        s = self._C @ run.predicted_ss @ self._C.T + self._r_eff
        return whitening_factor(s)

    def _realtime_growth(self, run: _Recursion) -> float:
        """Factor on ``S`` of the window :meth:`_Recursion.monitor` closes (1 before the gain
        converges): ``_spectrum.nis_growth`` of the buffered measurements."""
        whitener = self._spectral_whitener(run)
        if whitener is None:
            return 1.0
        return nis_growth(run.recent_measurements(), whitener, self._spectral_ref,
                          *self._spectral_field)

    def _spectral_consistency(self, consistency: Consistency, innovations: np.ndarray,
                              scaled: np.ndarray, measurements: np.ndarray,
                              run: _Recursion) -> Consistency:
        """``consistency`` with the spectral test of the whitened innovations added.

        ``scaled`` are the innovations over ``sqrt`` of the growth factor of ``S_k`` (the
        test's innovations without a field reference); with one, the raw ``innovations``
        whitened by ``S`` are judged against the reference following the field of
        ``measurements``."""
        factor = self._spectral_whitener(run)
        if factor is None:
            return consistency
        segment = 2 * (self._spectral_ref.size - 1)
        reference = self._spectral_ref
        if self._spectral_field is not None:
            field = measurement_psd(measurements, factor, discard=self._window, segment=segment)
            reference = following_reference(reference, *self._spectral_field, field)
        else:
            innovations = scaled
        psd, n_avg = whitened_psd(innovations, factor, discard=self._window, segment=segment)
        fields = spectral_test(psd, n_avg, reference, self._spectral_count)
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
