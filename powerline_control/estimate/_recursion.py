"""The recursion behind :class:`~powerline_control.estimate.KalmanFilter`, sample by sample and
in batches, and the frozen specification it reads.

:class:`FilterSpec` is what the filter hands the recursion: its model, noise and settings,
checked and frozen at construction (with the steady-state DARE solution computed on first use).
:class:`_Recursion` is the per-sample filter state (Joseph or information update, convergence
tracking, divergence checks, the consistency windows, the spectral test of a run) shared by
``step`` and ``filter``, and the modal batch recursion that evaluates converged NaN-free
stretches as a blocked scan over all modes at once (:func:`_recursion_tables`,
:func:`_diagonal_recursion`); ``step_block``'s short packets go through ``_packet.ModalPacket``.
Nothing here imports the filter.

Test seam: ``_recursion_tables``, ``_diagonal_recursion`` and ``_SCAN_BLOCK``: the blocked scan is
checked against a plain step-by-step recursion across block boundaries (tests/test_estimate.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg as sla

from .._riccati import (
    describe_modes,
    filter_gain,
    posterior_from_predicted,
    solve_filter_dare,
)
from .._validation import (
    read_only,
)
from ..errors import (
    EstimationError,
)
from ._adaptive import _Adaptation
from ._model_error import innovation_inflation
from ._packet import MAX_CONDITION, ModalPacket, conjugate_modes
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
from .consistency import DEFAULT_CONSISTENCY_WINDOW, _window_sums
from .result import Consistency

# The modal batch recursion is used only when the eigenvector matrix of the closed loop is this
# well conditioned (the bound of the packets' modal form, _packet.MAX_CONDITION, and why).
_MAX_MODAL_CONDITION = MAX_CONDITION
# Consecutive full samples with a gain change below gain_rtol before the gain is frozen.
_CONFIRM_SAMPLES = 10
# Block length of the vectorised diagonal recursion: in-block work grows with it, the Python
# loop over blocks shrinks with it; 16 was fastest for n = 101 on the reference machine.
_SCAN_BLOCK = 16


@dataclass(frozen=True, eq=False)
class FilterSpec:
    """What the recursion reads of a :class:`~powerline_control.estimate.KalmanFilter`: its
    model, noise and settings, checked and frozen when the filter is built.

    The filter validates its arguments and hands one of these to every :class:`_Recursion` it
    starts (with the prior ``x0``, ``P0``); the recursion and the covariance matching
    (``_adaptive._Adaptation``) read nothing else of the filter. Derived quantities (the
    steady-state DARE solution, the information-form products, the steady closed loop's modal
    form) are computed on first use and kept.

    Attributes
    ----------
    A, B, C, D : ndarray
        The model's matrices.
    Q, q_eff, r_eff : ndarray
        Process-noise covariance as given; ``Q + epsilon I`` and ``R + epsilon I``.
    n, p, m : int
        States, outputs (sensors) and used inputs (0 for a zero ``B`` and ``D``).
    epsilon, gain_rtol : float
        The paper's regulariser; the relative change below which the gain is frozen.
    steady_state : bool
        Constant steady-state gain.
    sel : ndarray or None
        The state each output selects when ``C`` only selects states.
    info_form : bool
        Information (Woodbury) form of the update (more outputs than states).
    r_diag : ndarray or None
        The diagonal of ``r_eff`` when it is diagonal.
    undetectable : ndarray
        Eigenvalues on or outside the unit circle the sensors cannot see.
    radius, diverged : float
        Spectral radius of ``A``; the covariance size that counts as divergence.
    dt : float or None
        Sample time.
    window : int or None
        Samples per consistency window (None: the test is off).
    follows_spectrum, total_growth : bool
        Whether the window's factor on ``S`` follows the field's spectrum, or its total.
    spectral_ref, spectral_count, spectral_field
        The spectral test's reference, its count and the field reference (as checked).
    innov_ref, innov_rel : float
        ``innovation_growth``'s reference and share (share 0: off).
    adapt_horizon : int or None
        Covariance matching's horizon (None: off).
    adapt_range : tuple of float
        Bounds of the matched scale on ``Q``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    Q: np.ndarray
    q_eff: np.ndarray
    r_eff: np.ndarray
    n: int
    p: int
    m: int
    epsilon: float
    gain_rtol: float
    steady_state: bool
    sel: np.ndarray | None
    info_form: bool
    r_diag: np.ndarray | None
    undetectable: np.ndarray
    radius: float
    diverged: float
    dt: float | None
    window: int | None
    follows_spectrum: bool
    total_growth: bool
    spectral_ref: np.ndarray | None
    spectral_count: int
    spectral_field: tuple | None
    innov_ref: float
    innov_rel: float
    adapt_horizon: int | None
    adapt_range: tuple

    def apply_r_inv(self, values: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """``R_uu^-1 values`` for the sensors ``index`` (all without), diagonal fast path."""
        if self.r_diag is not None:
            r = self.r_diag if index is None else self.r_diag[index]
            return values / r[:, None]
        r = self.r_eff if index is None else self.r_eff[np.ix_(index, index)]
        return sla.cho_solve(sla.cho_factor(r), values)

    @cached_property
    def r_inv_c(self) -> np.ndarray:
        """``R^-1 C`` of the information-form update."""
        return self.apply_r_inv(self.C)

    @cached_property
    def info_full(self) -> np.ndarray:
        """``C^T R^-1 C`` of the information-form update with every sensor."""
        return self.C.T @ self.r_inv_c

    def measure(self, x: np.ndarray) -> np.ndarray:
        """``C x`` (by indexing when ``C`` only selects states)."""
        return x[self.sel] if self.sel is not None else self.C @ x

    @cached_property
    def steady_solution(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(filter gain, posterior covariance, predicted covariance) from the DARE."""
        predicted = solve_filter_dare(self.A, self.C, self.q_eff, self.r_eff)
        posterior = posterior_from_predicted(predicted, self.C, self.r_eff)
        gain = filter_gain(predicted, self.C, self.r_eff, posterior)
        return gain, posterior, predicted

    @cached_property
    def steady_batch(self):
        """The modal form of the steady closed loop (:func:`_build_batch`), or False."""
        return _build_batch(self, self.steady_solution[0])

    @cached_property
    def steady_packet(self) -> ModalPacket | None:
        """The modal form of the steady closed loop for short packets (:func:`_build_packet`)."""
        return _build_packet(self, self.steady_solution[0])

    @property
    def mean_square_window(self) -> int:
        """Time constant (samples) of the running mean squares of the model-error terms: the
        consistency window, so that S and the variances follow the field as the test does."""
        return self.window or DEFAULT_CONSISTENCY_WINDOW

    def inflation(self, states: np.ndarray, start: float) -> tuple[np.ndarray, float]:
        """(factor on ``S`` per sample, running mean square after them) for ``states``."""
        return innovation_inflation(self.measure(states), self.mean_square_window,
                                    self.innov_rel, self.innov_ref, start)


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

    def __init__(self, spec: FilterSpec, x0: np.ndarray, P0: np.ndarray) -> None:
        self.spec = spec
        self.x = x0.copy()
        self.first = True  # the prior describes sample 0: no prediction before its update
        self.u_prev = np.zeros(spec.m)
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
        self.recent = (np.full((spec.p, NIS_FIELD_SPAN), np.nan) if spec.follows_spectrum
                       else None)
        self.recent_count = 0
        # Running mean square of the estimate at the sensors (KalmanFilter's innovation_growth).
        self.mean_square = 0.0
        # Scalar covariance matching of Q (KalmanFilter's adapt_horizon), None when off.
        self.adapt = _Adaptation(spec) if spec.adapt_horizon is not None else None
        if spec.steady_state:
            gain, posterior, predicted = spec.steady_solution
            self.freeze(gain, posterior, predicted)
            self.P = predicted  # prior of sample 0: the stationary predicted covariance
            self.converged_at = 0
            self.last_full_gain = gain
        else:
            self.P = P0.copy()

    def freeze(self, gain: np.ndarray, posterior: np.ndarray, predicted: np.ndarray) -> None:
        """Adopt a converged gain: from now on full samples need no covariance work."""
        spec = self.spec
        self.converged = True
        self.gain_ss, self.posterior_ss, self.predicted_ss = gain, posterior, predicted
        self.closed_loop = None   # (F, (I - K C) B) of advance_frozen, built on first use
        self.packet = False       # its modal form (packet_form), built on first use
        # the packets' modal state, C A x, and the x they describe (packet_form)
        self.modal_z = self.modal_seen = self.modal_of = None
        if spec.info_form:
            self.s_factor = None  # NIS through Woodbury with posterior_ss, O(n p)
        else:
            s = (
                predicted[np.ix_(spec.sel, spec.sel)]
                if spec.sel is not None
                else spec.C @ predicted @ spec.C.T
            )
            s = s + spec.r_eff
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
        if self.w_len == self.spec.window:
            if self.recent is not None:
                self.w_sum /= self.realtime_growth()
            self.closed.append((self.w_sum, self.w_valid, self.w_used))
            self.w_sum, self.w_valid, self.w_used, self.w_len = 0.0, 0, 0, 0

    def monitor_full(self, nis: np.ndarray, y: np.ndarray) -> None:
        """:meth:`monitor` of a block of samples with every sensor: one addition per window
        the block touches instead of one call per sample (with a field reference, per sample:
        a closing window reads the ring buffer)."""
        spec = self.spec
        if self.recent is not None:
            for k, value in enumerate(nis.tolist()):
                self.monitor(value, spec.p, y[:, k])
            return
        start = 0
        while start < nis.size:
            take = min(nis.size - start, spec.window - self.w_len)
            self.w_sum += float(nis[start : start + take].sum())
            self.w_valid += take
            self.w_used += take * spec.p
            self.w_len += take
            start += take
            if self.w_len == spec.window:
                self.closed.append((self.w_sum, self.w_valid, self.w_used))
                self.w_sum, self.w_valid, self.w_used, self.w_len = 0.0, 0, 0, 0

    def resume(self, nis: np.ndarray, raw_nis: np.ndarray, n_used: np.ndarray,
               measurements: np.ndarray) -> None:
        """Continue the real-time monitor from a record ``filter`` ran (``update_state=True``):
        its full windows closed (``nis`` with ``S_k``), the rest open. With a field reference
        the open window's factor on ``S`` is set when it closes, so it holds ``raw_nis`` (with
        ``S``), and the ring buffer the record's last measurements."""
        window, n_t = self.spec.window, nis.size
        sums, counts, _ = _window_sums(nis, window)
        used_sums = n_used[: sums.size * window].reshape(-1, window).sum(axis=1)
        self.closed = list(zip(sums.tolist(), counts.tolist(), used_sums.tolist(), strict=True))
        tail = n_t - sums.size * window
        rest_nis = (raw_nis if self.spec.follows_spectrum else nis)[n_t - tail:]
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
        spec = self.spec
        if self.s_factor is not None:
            whitened = self.whitener @ e
            return np.einsum("ij,ij->j", whitened, whitened)
        # Woodbury: S^-1 = R^-1 - R^-1 C P+ C^T R^-1 (P+ the posterior), never a p x p solve.
        r_inv_e = spec.apply_r_inv(e)
        w = spec.C.T @ r_inv_e
        return np.einsum("ij,ij->j", e, r_inv_e) - np.einsum("ij,ij->j", w, self.posterior_ss @ w)

    def check_divergence(self, what: str) -> None:
        """EstimationError when the covariance or the state stops being finite or explodes."""
        spec = self.spec
        with np.errstate(all="ignore"):
            size = float(np.max(np.abs(self.P))) if self.P.size else 0.0
        if np.isfinite(size) and size <= spec.diverged and np.all(np.isfinite(self.x)):
            return
        unseen = spec.undetectable
        cause = (
            f"the modes with eigenvalues {describe_modes(unseen)} lie on or outside the unit "
            "circle and are not detectable from the sensors"
            if unseen.size
            else f"the model has spectral radius {spec.radius:.6g} and {what}"
        )
        raise EstimationError(
            f"The Kalman filter diverged at sample {self.k - 1}: its error covariance reached "
            f"{size:.3g} (over {spec.diverged:.3g}, 1e100 times its scale): {cause}. The "
            "estimate has no meaning any more; shorten the dropout, add sensors that see those "
            "modes, or stabilise the model."
        )

    def advance(self, y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, float, int]:
        """Process one sample; return (innovation, NIS, number of sensors used)."""
        spec = self.spec
        mask = ~np.isnan(y)
        full = bool(mask.all())
        # --- prediction of the state (the covariance only when it is needed)
        if self.first:
            x_pred, p_pred = self.x, self.P
            self.first = False
        else:
            x_pred = spec.A @ self.x
            if spec.m:
                x_pred += spec.B @ self.u_prev
            p_pred = None
        self.u_prev = u
        innovation = np.full(spec.p, np.nan)
        self.k += 1
        # --- converged covariance and every sensor present: a plain linear update
        if self.converged and full:
            e = y - spec.measure(x_pred) - (spec.D @ u if spec.m else 0.0)
            self.x = x_pred + self.gain_ss @ e
            self.P = self.posterior_ss
            innovation[:] = e
            return innovation, float(self.nis_frozen(e[:, None])[0]), spec.p
        propagated = None
        if p_pred is None:
            # From the current covariance: after a frozen full sample P is the stationary
            # posterior and this is the stationary prior; during a dropout it grows as it must.
            if self.adapt is None:
                p_pred = spec.A @ self.P @ spec.A.T + spec.q_eff
            else:  # Q scaled by the matched q (estimate._adaptive)
                propagated = spec.A @ self.P @ spec.A.T
                p_pred = propagated + self.adapt.q * spec.Q + spec.epsilon * np.eye(spec.n)
        if not mask.any():
            self.x, self.P = x_pred, (p_pred + p_pred.T) / 2
            self.last_full_gain = None if not spec.steady_state else self.last_full_gain
            if not spec.steady_state:
                self.converged, self.settled, self.last_posterior = False, 0, None
            self.check_divergence("every measurement is missing (a dropout only predicts)")
            return innovation, float("nan"), 0
        # --- measurement update with the available sensors
        index = np.flatnonzero(mask)
        if spec.info_form:
            gain, nis, e = self._information_update(p_pred, x_pred, y, u, index, full)
        else:
            gain, nis, e = self._joseph_update(p_pred, x_pred, y, u, index)
        innovation[index] = e
        self.check_divergence("some sensors are missing")
        if spec.steady_state:
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
        ``F = (I - K C) A``, run in its modal form (``_packet.ModalPacket``: one product for the
        modal drives, a scan, one product for the states) or, when that form would lose
        accuracy (``_packet.MAX_CONDITION``), stepped (one product per sample); the
        innovations (``C A x[k-1] + C B u[k-1]``) in one product. Equal to :meth:`advance` per
        sample to round-off.
        """
        spec = self.spec
        if self.closed_loop is None:
            self.closed_loop = _frozen_loop(spec, self.gain_ss)
        closed, input_map, predict_output, predict_input, with_d = self.closed_loop
        n_t = y.shape[1]
        packet = self.packet_form() if n_t else None
        if packet is not None:
            p, m = spec.p, spec.m
            drivers = np.empty((n_t, packet.drive_t.shape[0]))   # time along rows
            drivers[:, :p] = y.T
            if m:
                drivers[0, p : p + m] = self.u_prev
                drivers[1:, p : p + m] = u[:, :-1].T
                if with_d:
                    drivers[:, p + m :] = u.T
            # The modal state (and C A x) carried from the last packet while x is still the
            # state they describe (x is only ever replaced, never written into), else from x.
            if self.modal_of is self.x:
                z0, seen0 = self.modal_z, self.modal_seen
            else:
                z0, seen0 = packet.modal(self.x), predict_output @ self.x
            # predicted: C A x[k-1] + C B u[k-1] + D u[k] per column
            states, modal, predicted, seen = packet.run(z0, drivers, seen0)
            x = states[:, -1].copy()
            self.modal_z, self.modal_seen, self.modal_of = modal[-1].copy(), seen.copy(), x
        else:
            u_prev = np.column_stack([self.u_prev, u[:, :-1]]) if spec.m else None
            drive = self.gain_ss @ y
            previous = np.empty((spec.n, n_t))      # x[k-1] per column
            if spec.m:
                drive += input_map @ u_prev
                if with_d:
                    drive -= self.gain_ss @ (spec.D @ u)
            states = np.empty((spec.n, n_t))
            x = self.x
            for k in range(n_t):
                previous[:, k] = x
                x = closed @ x + drive[:, k]
                states[:, k] = x
            predicted = predict_output @ previous
            if spec.m:
                predicted += predict_input @ u_prev
                if with_d:
                    predicted += spec.D @ u
        innovations = y - predicted
        self.x, self.P, self.k = x, self.posterior_ss, self.k + n_t
        if n_t:
            self.u_prev = u[:, -1]
        nis_block = self.nis_frozen(innovations)
        if spec.total_growth:
            factor, self.mean_square = spec.inflation(states, self.mean_square)
            nis_block = nis_block / factor
        if spec.window is not None:
            self.monitor_full(nis_block, y)
        return states

    def packet_form(self) -> ModalPacket | None:
        """The modal form of the frozen closed loop for :meth:`advance_frozen` (built once per
        frozen gain; for a steady-state filter once per filter), or None: step it."""
        if self.packet is False:
            self.packet = (self.spec.steady_packet if self.spec.steady_state
                           else _build_packet(self.spec, self.gain_ss))
        return self.packet

    def _joseph_update(self, p_pred, x_pred, y, u, index):
        """Covariance form (``p <= n``): gain through a Cholesky of ``S``, Joseph update."""
        spec = self.spec
        r_used = spec.r_eff[np.ix_(index, index)]
        if spec.sel is not None:
            cols = spec.sel[index]
            pht = p_pred[:, cols]  # P C^T by indexing: C only selects states
            s = pht[cols] + r_used
            hx = x_pred[cols]
        else:
            c = spec.C[index]
            pht = p_pred @ c.T
            s = c @ pht + r_used
            hx = c @ x_pred
        if spec.m:
            hx = hx + spec.D[index] @ u
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
        mht = m[:, cols] if spec.sel is not None else m @ c.T
        posterior = m - mht @ gain.T + gain @ r_used @ gain.T
        self.P = (posterior + posterior.T) / 2
        return gain, float(e @ sla.cho_solve(factor, e)), e

    def _information_update(self, p_pred, x_pred, y, u, index, full):
        """Information form (``p > n``): ``P+ = (I + P G)^-1 P``, ``K = P+ C^T R^-1``.

        Every product is ``O(n^3 + n^2 p)``; the ``p x p`` innovation covariance is never formed.
        """
        spec = self.spec
        n = spec.n
        if full:
            c, r_inv_c, info = spec.C, spec.r_inv_c, spec.info_full
        else:
            c = spec.C[index]
            r_inv_c = spec.apply_r_inv(c, index)
            info = c.T @ r_inv_c
        hx = c @ x_pred
        if spec.m:
            hx = hx + spec.D[index] @ u
        with np.errstate(all="ignore"):
            posterior = np.linalg.solve(np.eye(n) + p_pred @ info, p_pred)
        posterior = (posterior + posterior.T) / 2
        gain = posterior @ r_inv_c.T
        e = y[index] - hx
        self.x = x_pred + gain @ e
        self.P = posterior
        r_inv_e = spec.apply_r_inv(e[:, None], index)[:, 0]
        w = c.T @ r_inv_e
        return gain, float(e @ r_inv_e - w @ posterior @ w), e

    def _track_convergence(self, gain: np.ndarray) -> None:
        """Freeze the gain once the *covariance* has stopped changing (not only the gain).

        The covariance of a direction the sensors cannot see keeps growing while the gain (zero
        there) looks settled; the old gain-only test froze a small, wrong covariance. A model
        with undetectable modes on or outside the unit circle is never frozen.
        """
        spec = self.spec
        previous_gain, previous_p = self.last_full_gain, self.last_posterior
        rtol = spec.gain_rtol
        steady = (
            rtol > 0
            and not spec.undetectable.size
            and previous_gain is not None
            and previous_p is not None
            and np.max(np.abs(gain - previous_gain)) <= rtol * np.max(np.abs(gain))
            and np.max(np.abs(self.P - previous_p)) <= rtol * np.max(np.abs(self.P))
        )
        self.settled = self.settled + 1 if steady else 0
        # Freeze only after the covariance has stayed put for a few samples: the extra steps
        # shrink what is left of the geometric convergence at almost no cost.
        if self.settled >= _CONFIRM_SAMPLES:
            self.freeze(gain, self.P, spec.A @ self.P @ spec.A.T + spec.q_eff)
            if self.converged_at is None:
                self.converged_at = self.k
        self.last_full_gain, self.last_posterior = gain, self.P

    # ------------------------------------------------------------------ model error of S

    def s_growth(self, states: np.ndarray, measurements: np.ndarray) -> np.ndarray | None:
        """Factor on ``S`` per sample of a record (``S_k = S factor``), ``None`` for ``S_k = S``:
        the one place that chooses it. Per frequency with a field reference (one factor per
        consistency window, ``_spectrum.window_nis_growth``), else from the running mean
        square of the whole field at the sensors (``innovation_growth``; ``self.mean_square``
        is carried on). :meth:`KalmanFilter.filter` scales its field variances by the
        per-frequency factor too (``Estimate.field_growth``), not by the other."""
        spec = self.spec
        if spec.follows_spectrum:
            whitener = self.spectral_whitener()
            if whitener is None:
                return None
            return window_nis_growth(measurements, spec.window, whitener,
                                     spec.spectral_ref, *spec.spectral_field,
                                     converged_at=self.converged_at or 0)
        if spec.total_growth:
            factor, self.mean_square = spec.inflation(states, self.mean_square)
            return factor
        return None

    def spectral_whitener(self) -> np.ndarray | None:
        """Lower Cholesky factor of the converged ``S`` the spectral test and the windowed
        test's factor whiten by (``None`` before the gain converges)."""
        if not self.converged:
            return None
        if self.s_factor is not None:
            return np.tril(self.s_factor[0])
        s = self.spec.C @ self.predicted_ss @ self.spec.C.T + self.spec.r_eff
        return whitening_factor(s)

    def realtime_growth(self) -> float:
        """Factor on ``S`` of the window :meth:`monitor` closes (1 before the gain converges):
        ``_spectrum.nis_growth`` of the buffered measurements."""
        whitener = self.spectral_whitener()
        if whitener is None:
            return 1.0
        return nis_growth(self.recent_measurements(), whitener, self.spec.spectral_ref,
                          *self.spec.spectral_field)

    def spectral_consistency(self, consistency: Consistency, innovations: np.ndarray,
                             scaled: np.ndarray, measurements: np.ndarray) -> Consistency:
        """``consistency`` with the spectral test of the whitened innovations added.

        ``scaled`` are the innovations over ``sqrt`` of the growth factor of ``S_k`` (the
        test's innovations without a field reference); with one, the raw ``innovations``
        whitened by ``S`` are judged against the reference following the field of
        ``measurements``."""
        spec = self.spec
        factor = self.spectral_whitener()
        if factor is None:
            return consistency
        segment = 2 * (spec.spectral_ref.size - 1)
        reference = spec.spectral_ref
        if spec.spectral_field is not None:
            field = measurement_psd(measurements, factor, discard=spec.window, segment=segment)
            reference = following_reference(reference, *spec.spectral_field, field)
        else:
            innovations = scaled
        psd, n_avg = whitened_psd(innovations, factor, discard=spec.window, segment=segment)
        fields = spectral_test(psd, n_avg, reference, spec.spectral_count)
        fields["spectral_ratio"] = read_only(fields["spectral_ratio"])
        fields["spectral_rejected"] = read_only(fields["spectral_rejected"])
        dt = 1.0 if spec.dt is None else spec.dt
        fields["spectral_frequencies"] = read_only(np.fft.rfftfreq(segment, dt))
        consistent = consistency.consistent and fields["spectral_consistent"] is not False
        return dataclasses.replace(consistency, consistent=consistent, **fields)

    # ------------------------------------------------------------------ batch recursion

    def batch_ready(self) -> bool:
        """Prepare the modal form of the converged closed loop; False if too ill-conditioned."""
        if self.batch is None:
            # The steady gain never changes: its closed loop is decomposed once per filter.
            self.batch = (self.spec.steady_batch if self.spec.steady_state
                          else _build_batch(self.spec, self.gain_ss))
        return self.batch is not False

    def run_batch(self, y_all, u_all, start, end, states, innovations, nis) -> None:
        """Samples ``start:end`` (converged, NaN-free) through the diagonalised closed loop."""
        spec = self.spec
        cache = self.batch
        n_real = cache["n_real"]
        length = end - start
        y = y_all[:, start:end]
        if spec.m:
            u = u_all[:, start:end]
            u_prev = np.empty_like(u)
            u_prev[:, 0] = self.u_prev
            u_prev[:, 1:] = u[:, :-1]
            drivers = np.vstack([y, u_prev, u])
        else:
            drivers = y
        drive_re = cache["drive_re"] @ drivers
        drive_im = cache["drive_im"] @ drivers
        z0 = sla.lu_solve(cache["lu"], self.x.astype(complex))[cache["keep"]]
        drive = drive_re.astype(complex)
        drive[n_real:] += 1j * drive_im
        modal = _diagonal_recursion(cache["powers"], cache["toeplitz"], drive, z0)
        n_pairs = modal.shape[0] - n_real
        stacked = np.empty((spec.n, length))
        stacked[:n_real] = modal[:n_real].real
        stacked[n_real : n_real + n_pairs] = modal[n_real:].real
        stacked[n_real + n_pairs :] = modal[n_real:].imag
        block = np.matmul(cache["lift"], stacked, out=states[:, start:end])
        # Innovations y[k] - C (A x[k-1] + B u[k-1]) - D u[k] from the states just computed.
        seen = cache["predict_output"] @ block
        predicted = np.empty_like(y)
        predicted[:, 0] = cache["predict_output"] @ self.x
        predicted[:, 1:] = seen[:, :-1]
        if spec.m:
            predicted += cache["predict_input"] @ u_prev + spec.D @ u
        e = y - predicted
        innovations[:, start:end] = e
        nis[start:end] = self.nis_frozen(e)
        self.x = block[:, -1].copy()
        if spec.m:
            self.u_prev = u[:, -1].copy()
        self.k += length


def _frozen_loop(spec: FilterSpec, gain: np.ndarray) -> tuple:
    """The frozen filter's closed loop: ``(F, (I - K C) B, C A, C B, D nonzero)`` with
    ``F = (I - K C) A`` (the input terms None without inputs). The one-step predictions of the
    outputs come straight from the states through ``C A`` (p x n): a block's ``A x`` would cost
    n x n per sample."""
    i_kc = np.eye(spec.n) - gain @ spec.C
    return (i_kc @ spec.A, i_kc @ spec.B if spec.m else None, spec.C @ spec.A,
            spec.C @ spec.B if spec.m else None, bool(spec.m and np.any(spec.D)))


def _build_packet(spec: FilterSpec, gain: np.ndarray) -> ModalPacket | None:
    """:meth:`ModalPacket.build` of ``x[k] = (I - K C) A x[k-1] + G w[k]`` with the predicted
    outputs ``C A x[k-1] + C B u[k-1] + D u[k]``, the drivers ``w`` being ``y[k]``, ``u[k-1]``
    and (with a nonzero ``D``) ``u[k]``."""
    closed, input_map, predict_output, predict_input, with_d = _frozen_loop(spec, gain)
    drive, feedthrough = [gain], [np.zeros((spec.p, spec.p))]
    if spec.m:
        drive.append(input_map)
        feedthrough.append(predict_input)
        if with_d:
            drive.append(-gain @ spec.D)
            feedthrough.append(spec.D)
    return ModalPacket.build(closed, np.hstack(drive), predict_output, np.hstack(feedthrough))


def _build_batch(spec: FilterSpec, gain: np.ndarray):
    """Modal form of the converged posterior recursion, or False if it would lose accuracy.

    ``x[k] = F x[k-1] + K y[k] + (I - K C) B u[k-1] - K D u[k]`` with ``F = (I - K C) A``.
    With ``F = V diag(lambda) V^-1`` every mode is a first-order recursion, all evaluated
    together by :func:`_diagonal_recursion`; conjugate pairs are run once and lifted back
    with ``2 Re(.)``, so the lift is one real ``(n, n)`` product per stretch.
    """
    closed, input_map = _frozen_loop(spec, gain)[:2]
    modes = conjugate_modes(closed, _MAX_MODAL_CONDITION)
    if modes is None:
        return False  # nearly defective, or eigenvalues not in exact conjugate pairs: the loop
    eigenvalues, vectors, real, upper = modes
    keep = np.concatenate([real, upper])
    lu = sla.lu_factor(vectors)
    drive = gain if not spec.m else np.hstack([gain, input_map, -gain @ spec.D])
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
        "predict_output": spec.C @ spec.A,
        "predict_input": spec.C @ spec.B if spec.m else None,
    }


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
