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

import control as ct
import numpy as np

from .._riccati import (
    describe_modes,
    undetectable_modes,
)
from .._riccati import (
    field_variances as mapped_variances,
)
from .._validation import (
    check_array,
    check_covariance,
    check_discrete_system,
    check_field_map,
    check_int,
    check_real,
    read_only,
    warn_if_saturated,
)
from ..errors import (
    EstimatorInconsistentWarning,
    InputError,
    UndetectableModeWarning,
)
from ._adaptive import DEFAULT_ADAPT_RANGE, check_adaptation
from ._model_error import (
    check_innovation_growth,
    growth_factor,
    next_mean_square,
    running_mean_square,
)
from ._recursion import FilterSpec, _Recursion, _selection_indices
from ._spectrum import check_spectral_arguments
from .consistency import (
    DEFAULT_CONSISTENCY_WINDOW,
    Consistency,
    filter_consistency,
    windowed_consistency,
)
from .result import Estimate

__all__ = ["KalmanFilter"]

# Stretches of converged, NaN-free samples shorter than this are run by the per-sample loop: below
# it the set-up of the modal batch recursion costs more than it saves.
_MIN_BATCH = 256


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
    spectral_field_reference : tuple, optional
        ``(power, noise)``: the whitened measurement power per bin of the reference record and
        the sensor noise's (flat) share of it. With it the reference follows the field: where
        the reference record's field stood above its noise, the model-error part of a bin's
        reference grows with the record's field power there (``estimate._spectrum.
        following_reference``), and the test whitens by ``S`` rather than ``S_k``. The windowed
        NIS test follows the field alike, in :meth:`filter` and :meth:`step`: a window's ``S_k``
        is ``S`` times the mean following reference over the mean reference on the 1024
        samples up to its end (``estimate._spectrum.nis_growth``; ``innovation_growth`` unused).
        :meth:`filter` scales its field variances (both model-error terms) by the same factor
        (``Estimate.field_growth``): the model error grows at unseen nodes as at the sensors.
    field_variance_scale : float
        Factor ``> 0`` on the field variances the filter reports (``Estimate.field_variances``;
        the state covariance, the gain and the NIS are unchanged): the model error at nodes
        the sensors do not see, which the innovations cannot show.
        :func:`~powerline_control.recipe.design_estimator` fits it on its training record at the
        unmeasured nodes. Default 1.
    field_relative_variance : float
        Factor ``>= 0`` on the running mean square of each node's estimate (time constant
        ``consistency_window`` samples, or 200 without a window), added to that node's reported
        variance: model error that grows with the field, as an identified model's does while
        the line rings up. Default 0 (none). The gain, the states and the NIS are unchanged.
    innovation_growth : tuple of float, optional
        ``(reference, share)``: the running mean square at the sensors (m^2) of the record
        ``Q`` and ``R`` were matched on, and the model error's share ``0 <= share <= 1`` of
        ``S`` there. An identified model's one-step error grows with the field, so once the
        line rings up beyond that level the consistency test uses
        ``S_k = S (1 + share * max(m[k-1] / reference - 1, 0))`` (``m`` the running mean square
        of the filtered estimate at the sensors, time constant ``consistency_window``;
        ``estimate._model_error.innovation_inflation``). ``Estimate.nis`` and the spectral test
        use ``S_k``; the gain and the states are unchanged. Needs ``steady_state=True``.
        Unused with a ``spectral_field_reference``. Default ``None`` (``S_k = S``).
    adapt_horizon : int, optional
        Process noise that follows the record: ``Q`` becomes ``q_k Q``, the scalar ``q_k``
        matched to the innovations over a fading horizon of this many samples (time constant
        ``>= 2``; covariance matching after Myers and Tapley, ``estimate._adaptive``), so the
        gain, ``P``, the NIS (with the predicted ``S_k``) and the reported variances follow the
        excitation; ``Estimate.process_noise_scale`` holds ``q_k``. Needs
        ``steady_state=False`` (start from the stationary covariance with ``P0``); the spectral
        test and the field-following factor need a frozen gain and are not run. A change
        faster than the horizon still lifts the windowed NIS until ``q`` catches up
        (:func:`~powerline_control.estimate.recovery_time`). Default ``None``: ``Q`` as given.
    adapt_range : tuple of float
        ``(low, high)`` bounds of ``q_k``, ``0 < low <= 1 <= high`` (default ``(1e-3, 1e3)``).

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
        spectral_field_reference: tuple[object, float] | None = None,
        field_variance_scale: float = 1.0,
        field_relative_variance: float = 0.0,
        innovation_growth: tuple[float, float] | None = None,
        adapt_horizon: int | None = None,
        adapt_range: tuple[float, float] = DEFAULT_ADAPT_RANGE,
    ) -> None:
        sys = check_discrete_system("sys", sys)
        adapt_horizon, adapt_range = check_adaptation(adapt_horizon, adapt_range, steady_state)
        if not isinstance(warn_inconsistent, bool):
            raise InputError("The 'warn_inconsistent' parameter must be True or False. Got "
                             f"{warn_inconsistent!r}.")
        self._warn = warn_inconsistent
        window = (None if consistency_window is None
                  else check_int("consistency_window", consistency_window, low=1))
        self._dof_fraction = check_real("nis_dof_fraction", nis_dof_fraction, low=0.0, high=1.0)
        self._fv_scale = check_real("field_variance_scale", field_variance_scale, low=0.0)
        self._fv_relative = check_real("field_relative_variance", field_relative_variance,
                                       low=0.0, low_inclusive=True)
        innov_ref, innov_rel = check_innovation_growth(innovation_growth, steady_state)
        spectral_ref, spectral_count, spectral_field = check_spectral_arguments(
            spectral_reference, spectral_reference_count, spectral_field_reference)
        A = np.array(sys.A, dtype=float)  # noqa: N806 - the model's conventional names
        B = np.array(sys.B, dtype=float)  # noqa: N806
        C = np.array(sys.C, dtype=float)  # noqa: N806
        D = np.array(sys.D, dtype=float)  # noqa: N806
        self._dims = (sys.nstates, sys.noutputs, sys.ninputs)
        n, p = sys.nstates, sys.noutputs
        # A zero B (an autonomous model built with a dummy input) is skipped entirely.
        has_input = sys.ninputs > 0 and (np.any(B) or np.any(D))
        if not isinstance(steady_state, bool):
            raise InputError(
                f"The 'steady_state' parameter must be True or False. Got {steady_state!r}."
            )
        epsilon = check_real("epsilon", epsilon, low=0.0, low_inclusive=True)
        gain_rtol = check_real("gain_rtol", gain_rtol, low=0.0, low_inclusive=True)
        if p == 0:
            raise InputError("The 'sys' parameter must have at least one output (sensor).")
        Q = read_only(check_covariance("Q", Q, n))  # noqa: N806
        self._R = read_only(check_covariance("R", R, p))
        q_eff = Q + epsilon * np.eye(n)
        r_eff = self._R + epsilon * np.eye(p)
        try:  # the one rule for R: positive definite (here with the paper's epsilon added)
            np.linalg.cholesky(r_eff)
        except np.linalg.LinAlgError:
            raise InputError(
                "The 'R' parameter plus epsilon * I must be positive definite: every sensor "
                "needs measurement noise (a noise-free sensor makes the innovation covariance "
                f"singular). Got smallest eigenvalue {np.linalg.eigvalsh(r_eff).min():.3g}"
                f" with epsilon={epsilon!r}; give R > 0 or use epsilon > 0."
            ) from None
        self._x0 = (
            np.zeros(n) if x0 is None else check_array("x0", x0, shape=(n,)).astype(float)
        )
        self._P0 = np.eye(n) if P0 is None else check_covariance("P0", P0, n)
        self._field_map = check_field_map(field_map, n)
        sel = _selection_indices(C)
        diagonal = not np.any(r_eff - np.diag(np.diag(r_eff)))
        undetectable = read_only(undetectable_modes(A, C))
        # Divergence: a covariance 1e100 times its natural scale has lost all meaning.
        scale = max(float(np.max(np.abs(self._P0))), float(np.max(np.abs(q_eff))),
                    float(np.max(np.abs(r_eff))), 1e-300)
        self._spec = FilterSpec(
            A=A, B=B, C=C, D=D, Q=Q, q_eff=q_eff, r_eff=r_eff, n=n, p=p,
            m=sys.ninputs if has_input else 0, epsilon=epsilon, gain_rtol=gain_rtol,
            steady_state=steady_state, sel=sel,
            # Information (Woodbury) form when there are more outputs than states: every update
            # then costs O(n^3 + n^2 p) instead of the O(p^3) of a p x p innovation covariance.
            info_form=p > n and sel is None,
            r_diag=np.diag(r_eff).copy() if diagonal else None, undetectable=undetectable,
            radius=float(np.max(np.abs(np.linalg.eigvals(A)))), diverged=1e100 * scale,
            dt=None if sys.dt is True else float(sys.dt), window=window,
            # S's factor in the windowed test: per window and frequency, or of the whole field.
            follows_spectrum=spectral_field is not None and window is not None,
            total_growth=innov_rel > 0 and spectral_field is None,
            spectral_ref=spectral_ref, spectral_count=spectral_count,
            spectral_field=spectral_field, innov_ref=innov_ref, innov_rel=innov_rel,
            adapt_horizon=adapt_horizon, adapt_range=adapt_range,
        )
        if steady_state:
            self._steady_solution()  # fail early (EstimationError) if no steady state exists
        elif undetectable.size:
            warnings.warn(
                f"The sensors cannot see the modes with eigenvalues "
                f"{describe_modes(undetectable)} (on or outside the unit circle): their "
                "estimation error grows without bound. The filter keeps propagating their "
                "covariance honestly (never frozen) and Estimate.undetectable_modes names them.",
                UndetectableModeWarning,
                stacklevel=2,
            )
        self._running = _Recursion(self._spec, self._x0, self._P0)

    # ------------------------------------------------------------------ read-only parameters

    @property
    def Q(self) -> np.ndarray:  # noqa: N802 - the covariance's conventional name
        """Process-noise covariance ``(n, n)`` given at construction (read-only)."""
        return self._spec.Q

    @property
    def R(self) -> np.ndarray:  # noqa: N802 - the covariance's conventional name
        """Measurement-noise covariance ``(p, p)`` given at construction (read-only)."""
        return self._R

    @property
    def epsilon(self) -> float:
        """The paper's regulariser added to ``Q`` and ``R``."""
        return self._spec.epsilon

    @property
    def gain_rtol(self) -> float:
        """Relative change of the covariance and gain below which the gain is frozen."""
        return self._spec.gain_rtol

    @property
    def steady_state(self) -> bool:
        """Whether the gain is the constant steady-state one."""
        return self._spec.steady_state

    @property
    def dt(self) -> float | None:
        """Sample time (``None`` for an unspecified timebase)."""
        return self._spec.dt

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
        return self._spec.undetectable

    @property
    def consistency_window(self) -> int | None:
        """Samples per consistency window (``None``: the test is off)."""
        return self._spec.window

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
        if self._spec.window is None or not self._running.closed:
            return None
        return windowed_consistency(self.consistency_windows, self._spec.window,
                                    self._dof_fraction)

    @property
    def consistency_windows(self) -> np.ndarray:
        """The closed windows of :attr:`consistency`, ``(n_windows, 3)``: per window the NIS
        summed over its valid samples, the valid samples and the scalar innovations (what
        :func:`windowed_consistency` tests; filters that follow one another in a run are
        tested as one from their windows)."""
        return read_only(np.array(self._running.closed, dtype=float).reshape(-1, 3))

    @property
    def steady_gain(self) -> np.ndarray:
        """Filter-form steady-state gain ``K = P C^T (C P C^T + R)^-1``, ``(n, p)``.

        ``control.dlqe`` returns the predictor-form gain, which equals ``A @ steady_gain``.
        """
        return read_only(self._spec.steady_solution[0].copy())

    @property
    def steady_covariance(self) -> np.ndarray:
        """Steady-state posterior covariance ``P[k|k]`` from the Riccati equation, ``(n, n)``."""
        return read_only(self._spec.steady_solution[1].copy())

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
        predicted = self._spec.steady_solution[2]
        s = self._spec.C @ predicted @ self._spec.C.T + self._spec.r_eff
        return read_only((s + s.T) / 2)

    @property
    def spectral_reference(self) -> np.ndarray | None:
        """Reference whitened innovation power per bin of the spectral test (``None``: off)."""
        return self._spec.spectral_ref

    @property
    def spectral_reference_count(self) -> int:
        """Segments times channels averaged in :attr:`spectral_reference` (as given)."""
        return self._spec.spectral_count

    @property
    def spectral_field_reference(self) -> tuple[np.ndarray, float] | None:
        """``(power, noise)`` the spectral reference follows the field by (as given)."""
        return self._spec.spectral_field

    @property
    def field_variance_scale(self) -> float:
        """Factor on the reported field variances (as given)."""
        return self._fv_scale

    @property
    def field_relative_variance(self) -> float:
        """Factor on the running mean square of the field added to its variances (as given)."""
        return self._fv_relative

    @property
    def innovation_growth(self) -> tuple[float, float] | None:
        """``(reference, share)`` of the innovation covariance's growth (as given)."""
        spec = self._spec
        return (spec.innov_ref, spec.innov_rel) if spec.innov_rel > 0 else None

    @property
    def adapt_horizon(self) -> int | None:
        """Time constant (samples) of the covariance matching of ``Q`` (``None``: off)."""
        return self._spec.adapt_horizon

    @property
    def process_noise_scale(self) -> float:
        """Current scale ``q`` on ``Q`` of the real-time recursion (1 without adaptation)."""
        return 1.0 if self._running.adapt is None else self._running.adapt.q

    def _steady_solution(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(filter gain, posterior covariance, predicted covariance) from the DARE, cached."""
        return self._spec.steady_solution

    def _check_input_sample(self, u_k: object) -> np.ndarray:
        if u_k is None:
            return np.zeros(self._spec.m)
        u = check_array("u_k", u_k, shape=(self.n_inputs,))
        return u if self._spec.m else np.zeros(0)

    def _check_input_block(self, inputs: object, n_t: int) -> np.ndarray:
        """Known inputs ``(m, n_t)`` of a block or record (zeros when not given)."""
        if inputs is None:
            return np.zeros((self._spec.m, n_t))
        u = check_array("inputs", inputs, shape=(self.n_inputs, n_t))
        return u if self._spec.m else np.zeros((0, n_t))

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
            self._x0 = check_array("x0", x0, shape=(self._spec.n,)).astype(float)
        if P0 is not None:
            self._P0 = check_covariance("P0", P0, self._spec.n)
        self._running = _Recursion(self._spec, self._x0, self._P0)

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
        y = check_array("y_k", y_k, shape=(self._spec.p,), allow_nan=True)
        return self._advance(y, self._check_input_sample(u_k)).copy()

    def _advance(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One checked sample through the real-time recursion and its consistency window."""
        run = self._running
        spec = self._spec
        _, nis, used = run.advance(y, u)
        if spec.total_growth:  # one sample of FilterSpec.inflation, without the array set-up
            nis = nis / float(growth_factor(run.mean_square, spec.innov_rel, spec.innov_ref))
            run.mean_square = next_mean_square(run.mean_square, spec.measure(run.x),
                                               spec.mean_square_window)
        if spec.window is not None:
            run.monitor(nis, used, y)
        return run.x

    def step_block(self, measurements: object, inputs: object = None) -> np.ndarray:
        """Process a block of samples in real time: :meth:`step` on each column, in order.

        The same recursion, state and consistency windows as calling :meth:`step` once per
        sample, with the arguments checked once for the block instead of once per sample (a
        controller that receives its sensors in packets). Once the gain is frozen, a NaN-free
        block runs through the closed loop's modal form (one product for the drives, one for
        the states, no Python loop over samples), equal to :meth:`step` to round-off; a closed
        loop whose eigenvectors are too ill-conditioned for that is stepped.

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
        y_all = check_array("measurements", measurements, shape=(self._spec.p, None),
                            allow_nan=True)
        n_t = y_all.shape[1]
        u_all = self._check_input_block(inputs, n_t)
        run = self._running
        if run.converged and not run.first and not np.isnan(y_all).any():
            return run.advance_frozen(y_all, u_all)   # no covariance work, no checks
        states = np.empty((self._spec.n, n_t))
        for k in range(n_t):
            states[:, k] = self._advance(y_all[:, k], u_all[:, k])
        return states

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
        SaturationWarning
            A row of ``measurements`` is clipped at its sensor's range
            (``_validation.warn_if_saturated``).
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
        if y_all.shape[0] != self._spec.p:
            raise InputError(
                "The 'measurements' parameter has the wrong shape: expected "
                f"({self._spec.p}, n_t) (one row per model output, time along columns) but found "
                f"{y_all.shape}."
            )
        if y_all.shape[1] == 0:   # numpy's "zero-size array" error otherwise, from deep inside
            raise InputError(
                f"The 'measurements' parameter must hold at least one sample (column). Got "
                f"shape {y_all.shape}: an empty record.")
        warn_if_saturated("The 'measurements' parameter", y_all, stacklevel=2)
        n_t = y_all.shape[1]
        u_all = self._check_input_block(inputs, n_t)
        n, p = self._spec.n, self._spec.p
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

        run = _Recursion(self._spec, self._x0, self._P0)
        scales = None if run.adapt is None else np.empty(n_t)
        k = 0
        while k < n_t:
            if run.converged and not run.first and not missing_rows[k]:
                nxt = np.searchsorted(nan_positions, k)
                end = int(nan_positions[nxt]) if nxt < nan_positions.size else n_t
                if end - k >= _MIN_BATCH and run.batch_ready():
                    run.run_batch(y_all, u_all, k, end, states, innovations, nis)
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
            if scales is not None:
                scales[k] = run.adapt.q
            k += 1
        if variance_constant:
            variances = np.broadcast_to(np.diag(run.P)[:, None], (n, n_t))
        whitened_innovations = innovations
        raw_nis = nis
        factor = run.s_growth(states, y_all)
        if factor is not None:  # S_k = S * factor_k: the model error that grows with the field
            nis = nis / factor
            whitened_innovations = innovations / np.sqrt(factor)
        field_growth = factor if factor is not None and self._spec.follows_spectrum else None
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
            if self._fv_relative > 0:
                field_variances = field_variances + self._fv_relative * running_mean_square(
                    field, self._spec.mean_square_window)
            if field_growth is not None:
                # The model error at nodes no sensor sees grows as the innovations' does: the
                # window's factor on S (per frequency) scales the field variances too.
                field_variances = field_variances * field_growth
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
            field_growth=field_growth,
            undetectable_modes=tuple(complex(v) for v in self._spec.undetectable),
            process_noise_scale=scales,
        )
        if update_state and self._spec.window is not None:
            run.resume(nis, raw_nis, n_used, y_all)  # the real-time monitor continues from here
        if self._spec.window is None or not np.any(n_used):
            return estimate
        consistency = filter_consistency(estimate, window=self._spec.window,
                                         dof_fraction=self._dof_fraction)
        if self._spec.spectral_ref is not None:
            consistency = run.spectral_consistency(consistency, innovations,
                                                    whitened_innovations, y_all)
        if self._warn and not consistency.consistent:
            warnings.warn(
                consistency.message + " Neither the estimate nor its variances describe this "
                "record (a load that drives modes the training never saw, or a changed line): "
                "retrain on a record with this excitation, add sensors, or do not act on it.",
                EstimatorInconsistentWarning,
                stacklevel=2,
            )
        return dataclasses.replace(estimate, consistency=consistency)
