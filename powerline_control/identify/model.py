"""Data-driven identification: DMD with Tikhonov regularisation, delays, inputs, online updates.

The paper identifies a discrete-time linear model ``x_{k+1} = A x_k`` of the nodal displacements
by Dynamic Mode Decomposition, ``A = X' X^+`` (its eq. 11), and stabilises it by Tikhonov
regularisation, ``A = X' X^T (X X^T + alpha I)^{-1}`` (eq. 14).  This module computes both
through an SVD or a Cholesky solve (never an explicit inverse) and adds what the paper leaves
open:

* time-delay embedding (``delays=d``): the state is the stacked window
  ``z_k = [x_k; x_{k-1}; ...; x_{k-d+1}]``.  A line is second order, so displacements alone are
  not a state; with ``d >= 2`` the linear model can be exact on noise-free data.  Without rank
  truncation only the first block row of ``A`` is fitted; the shift rows are the exact identity.
* rank truncation (``rank=r``): the state is the vector of the ``r`` leading POD coordinates of
  the (delayed) data, so the cost follows ``r`` rather than the number of nodes;
* known inputs (DMD with control): ``z_{k+1} = A z_k + B u_k``;
* :class:`OnlineDMD`: recursive least squares with exponential forgetting;
* :func:`select_alpha`: the whole alpha curve with its two choices (the smallest stable
  alpha, the best held-out one).

Every model keeps :attr:`DMDModel.field_map`, the map from its state to the *current* nodal
displacements, and exports itself as a discrete :class:`control.StateSpace`.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import control as ct
import numpy as np
import scipy.linalg as sla
from scipy.linalg.blas import dsyr as _syr
from scipy.linalg.lapack import dpotrf as _potrf
from scipy.linalg.lapack import dpotrs as _potrs

from .._validation import (
    check_array,
    check_bool,
    check_budget,
    check_choice,
    check_indices,
    check_int,
    check_real,
    check_snapshot_matrix,
    read_only,
)
from ..errors import IdentificationError, IllConditionedWarning, InputError, UnstableModelWarning

__all__ = [
    "DMDModel",
    "StabilityReport",
    "DampingReport",
    "AlphaCurve",
    "OnlineDMD",
    "fit_dmd",
    "select_alpha",
]

#: alpha = 0 and a kept singular value below this fraction of the largest: the fit inverts noise
#: or round-off, and fit_dmd says so.
_ILL_CONDITIONED_RATIO = 1e-8
#: The Gram/Cholesky route loses about eps * (1 + s_max**2 / alpha) relative accuracy; it is used
#: only when that is below ~1e-10, i.e. alpha >= 1e-6 * trace(G) >= 1e-6 * s_max**2.
_GRAM_ALPHA_FRACTION = 1e-6
#: The Gram-eigh + Rayleigh-Ritz route for a rank-r POD basis is used when s_r >= this * s_max
#: (subspace-iteration steps recover the accuracy the Gram matrix loses above that).
_GRAM_RANK_RATIO = 1e-6
#: Models with at most this many regressors (states + inputs) keep their Gram matrix for
#: DMDModel.damping_report (2 MB at the limit).
_KEEP_GRAM_LIMIT = 500
#: to_statespace checks detectability of unit-circle modes for models up to this size.
_DETECTABILITY_CHECK_LIMIT = 1000
#: |lambda| above 1 + this counts as outside the unit circle (round-off of a marginal mode).
_UNIT_CIRCLE_TOL = 1e-9


# ----------------------------------------------------------------------------------------------
# Results
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class StabilityReport:
    """Stability of an identified model, with advice.

    Attributes
    ----------
    spectral_radius : float
        Largest eigenvalue magnitude of ``A``.
    n_unstable : int
        Number of eigenvalues outside the unit circle (``|lambda| > 1 + 1e-9``).
    n_states : int
        Size of ``A``.
    alpha : float
        Absolute Tikhonov parameter the model was fitted with.
    is_stable : bool
        ``n_unstable == 0``.
    message : str
        One paragraph in words, with the fix when unstable.

    Examples
    --------
    >>> import numpy as np, powerline_control as plc
    >>> X = np.array([[1.1 ** k for k in range(10)]])
    >>> report = plc.fit_dmd(X, dt=0.1).stability_report(warn=False)
    >>> report.n_unstable, round(report.spectral_radius, 6)
    (1, 1.1)
    """

    spectral_radius: float
    n_unstable: int
    n_states: int
    alpha: float
    is_stable: bool
    message: str


@dataclass(frozen=True, eq=False)
class DampingReport:
    """Whether each identified damping ratio can be trusted (:meth:`DMDModel.damping_report`).

    Attributes
    ----------
    damping_ratio : ndarray, shape (n_states,)
        ``DMDModel.damping_ratios``.
    regularisation_shift : ndarray, shape (n_states,)
        First-order change of each damping ratio if alpha were 0 (0 for alpha = 0; NaN when the
        model is too large to have kept its Gram matrix, or was loaded from a file).
    decay_over_record : ndarray, shape (n_states,)
        ``|Re s| T``: e-folds of decay over the training record.
    trusted : ndarray of bool, shape (n_states,)
        Shift at most half the damping and at least one e-fold over the record.
    message : str
        In words, with what to change.

    Examples
    --------
    >>> import numpy as np, powerline_control as plc
    >>> X = np.array([[0.9 ** k for k in range(40)]])
    >>> plc.fit_dmd(X, dt=0.1).damping_report().trusted.tolist()
    [True]
    """

    damping_ratio: np.ndarray
    regularisation_shift: np.ndarray
    decay_over_record: np.ndarray
    trusted: np.ndarray
    message: str


@dataclass(frozen=True, eq=False)
class DMDModel:
    """A discrete-time linear model identified from snapshots, ``z_{k+1} = A z_k + B u_k``.

    Build it with :func:`fit_dmd` (or :meth:`OnlineDMD.model`); every field is set and read-only.

    The model state ``z_k`` is the stacked window ``[x_k; x_{k-1}; ...; x_{k-d+1}]`` of nodal
    displacements (``d = delays``) or, with rank truncation, its POD coordinates
    ``basis.T @ window``.  :attr:`field_map` lifts the state back to the current nodal
    displacements ``x_k = field_map @ z_k``.

    Attributes
    ----------
    A : ndarray, shape (n_states, n_states)
        State-transition matrix.
    B : ndarray, shape (n_states, n_inputs) or None
        Input matrix (DMD with control), ``None`` when no inputs were given.
    dt : float
        Sample time in seconds.
    alpha : float
        Absolute Tikhonov parameter used (eq. 14 of the paper).
    alpha_relative : float
        The same, as a fraction of the largest squared singular value of the state data.
    delays : int
        Number of stacked snapshots ``d``.
    rank : int or None
        Number of POD coordinates kept, ``None`` for no truncation.
    n_nodes : int
        Number of rows of the snapshot matrix (nodal displacements).
    field_map : ndarray, shape (n_nodes, n_states)
        Maps the state to the current nodal displacements (the full-field output matrix).
    basis : ndarray, shape (n_nodes * delays, rank) or None
        Orthonormal POD basis of the window (``None`` without rank truncation).
    residual_covariance : ndarray, shape (n_states, n_states)
        Covariance of the one-step training residuals ``z_{k+1} - A z_k - B u_k``, divided by
        the number of pairs: a data-driven process-noise covariance ``Q`` in the model's state
        coordinates.  Without rank truncation and with delays only its first
        ``n_nodes x n_nodes`` block is non-zero (the shift rows are exact).
    n_pairs : int
        Number of snapshot pairs used for the fit.
    initial_state : ndarray, shape (n_states,)
        The first training state, used for the mode amplitudes.
    regressor_gram : ndarray, shape (n_states + n_inputs, n_states + n_inputs) or None
        Gram matrix of the regressor (states and inputs) when alpha > 0 and it has at most 500
        rows, kept for :meth:`damping_report`; ``None`` otherwise and for loaded models.

    Examples
    --------
    One damped 5 Hz mode seen at two nodes, sampled at 100 Hz:

    >>> import numpy as np, powerline_control as plc
    >>> t = np.arange(300) * 0.01
    >>> X = np.outer([1.0, 0.5], np.exp(-0.3 * t) * np.cos(2 * np.pi * 5 * t))
    >>> dmd = plc.fit_dmd(X, dt=0.01, delays=2, rank=2)
    >>> dmd.A.shape, dmd.field_map.shape
    ((2, 2), (2, 2))
    >>> np.round(dmd.damped_frequencies, 6)
    array([5., 5.])
    >>> sys = dmd.to_statespace(measured=[1])
    >>> sys.nstates, sys.noutputs, sys.dt
    (2, 1, 0.01)
    """

    A: np.ndarray
    B: np.ndarray | None
    dt: float
    alpha: float
    alpha_relative: float
    delays: int
    rank: int | None
    n_nodes: int
    field_map: np.ndarray
    basis: np.ndarray | None
    residual_covariance: np.ndarray
    n_pairs: int
    initial_state: np.ndarray = field(repr=False)
    #: Gram matrix ``R R^T`` of the regressor (states and inputs), kept for small models so that
    #: :meth:`damping_report` can tell how far alpha moved the eigenvalues; not saved to files.
    regressor_gram: np.ndarray | None = field(default=None, repr=False)

    # --- sizes --------------------------------------------------------------------------------

    @property
    def n_states(self) -> int:
        """Size of the model state."""
        return int(self.A.shape[0])

    @property
    def n_inputs(self) -> int:
        """Number of known inputs (0 without DMDc)."""
        return 0 if self.B is None else int(self.B.shape[1])

    # --- spectrum -----------------------------------------------------------------------------

    @cached_property
    def eigenvalues(self) -> np.ndarray:
        """Discrete-time eigenvalues of ``A``, by decreasing magnitude (complex, (n_states,))."""
        values = sla.eigvals(self.A)  # no eigenvectors: several times cheaper than eig
        return read_only(values[_spectral_order(values)])

    @cached_property
    def modes(self) -> np.ndarray:
        """Eigenvectors of ``A`` in state coordinates (unit norm), ordered as :attr:`eigenvalues`.

        Computed by a separate ``eig`` call; their eigenvalues equal :attr:`eigenvalues` up to
        round-off.
        """
        values, vectors = sla.eig(self.A)
        return read_only(vectors[:, _spectral_order(values)])

    @property
    def mode_shapes(self) -> np.ndarray:
        """Nodal mode shapes ``field_map @ modes``, shape (n_nodes, n_states), complex."""
        return read_only(self.field_map @ self.modes)

    @cached_property
    def amplitudes(self) -> np.ndarray:
        """Mode amplitudes ``b`` with ``modes @ b = initial_state`` (least squares), complex."""
        b, *_ = sla.lstsq(self.modes, self.initial_state.astype(complex))
        return read_only(b)

    @property
    def spectral_radius(self) -> float:
        """Largest eigenvalue magnitude."""
        return float(np.abs(self.eigenvalues).max()) if self.n_states else 0.0

    @property
    def n_unstable(self) -> int:
        """Number of eigenvalues outside the unit circle (beyond 1e-9 round-off)."""
        return int(np.count_nonzero(np.abs(self.eigenvalues) > 1.0 + _UNIT_CIRCLE_TOL))

    @property
    def is_stable(self) -> bool:
        """True when no eigenvalue lies outside the unit circle (beyond 1e-9 round-off)."""
        return self.n_unstable == 0

    @cached_property
    def continuous_eigenvalues(self) -> np.ndarray:
        """``s = log(lambda) / dt`` (rad/s).  An eigenvalue at 0 maps to ``log(tiny)/dt``."""
        magnitude = np.maximum(np.abs(self.eigenvalues), np.finfo(float).tiny)
        s = (np.log(magnitude) + 1j * np.angle(self.eigenvalues)) / self.dt
        return read_only(s)

    @property
    def frequencies(self) -> np.ndarray:
        """Undamped natural frequency ``|s| / 2 pi`` of each eigenvalue, Hz (0 for lambda = 0)."""
        f = np.abs(self.continuous_eigenvalues) / (2 * np.pi)
        return read_only(np.where(self._at_origin, 0.0, f))

    @property
    def damped_frequencies(self) -> np.ndarray:
        """Damped frequency ``|Im s| / 2 pi`` of each eigenvalue, Hz."""
        return read_only(np.abs(self.continuous_eigenvalues.imag) / (2 * np.pi))

    @property
    def damping_ratios(self) -> np.ndarray:
        """Damping ratio ``-Re(s) / |s|`` of each eigenvalue (1 for real decaying, 1 at 0).

        Whether a value can be trusted (regularisation bias, record length) is said by
        :meth:`damping_report`.
        """
        s = self.continuous_eigenvalues
        magnitude = np.abs(s)
        safe = np.where(magnitude > 0, magnitude, 1.0)
        zeta = np.where(magnitude > 0, -s.real / safe, 0.0)
        return read_only(np.where(self._at_origin, 1.0, zeta))

    @property
    def _at_origin(self) -> np.ndarray:
        return np.abs(self.eigenvalues) <= np.finfo(float).tiny

    def damping_report(self, *, warn: bool = False) -> DampingReport:
        """Say, per eigenvalue, whether the identified damping ratio can be trusted.

        Two things make an identified damping untrustworthy:

        * **regularisation**: Tikhonov's alpha shrinks the operator, ``A_0 = A_alpha (I + alpha
          G^-1)`` with ``G`` the regressor's Gram matrix, so to first order each eigenvalue
          moves by ``delta lambda_i = alpha lambda_i (w_i^H G^-1 v_i) / (w_i^H v_i)`` (``v``,
          ``w`` right and left eigenvectors).  The implied change of the damping ratio,
          ``regularisation_shift``, is compared with the damping itself;
        * **record length**: a decay of less than one e-fold over the training record
          (``|Re s| T < 1``, ``T = n_pairs dt``) cannot be told from noise or from an undamped
          mode; ``decay_over_record`` holds ``|Re s| T``.

        Parameters
        ----------
        warn : bool, default False
            Warn :class:`~powerline_control.errors.IllConditionedWarning` when an oscillatory
            eigenvalue's damping is not trusted.

        Returns
        -------
        DampingReport
            Damping ratios, shifts, decays over the record, the ``trusted`` flags and a message.

        Examples
        --------
        A 3 Hz mode with damping ratio 0.02, 8 s of clean data, alpha = 0: exact and trusted.

        >>> import numpy as np, powerline_control as plc
        >>> t = np.arange(800) * 0.01
        >>> w = 2 * np.pi * 3.0
        >>> X = np.exp(-0.02 * w * t) * np.cos(w * np.sqrt(1 - 0.02**2) * t)
        >>> report = plc.fit_dmd(X[None, :], dt=0.01, delays=2).damping_report()
        >>> np.round(report.damping_ratio, 6).tolist(), report.trusted.tolist()
        ([0.02, 0.02], [True, True])
        """
        warn = check_bool("warn", warn)
        zeta = np.asarray(self.damping_ratios, dtype=float)
        s = np.asarray(self.continuous_eigenvalues)
        decay = np.abs(s.real) * self.n_pairs * self.dt
        shift = self._regularisation_shift(s)
        oscillatory = (np.abs(self.eigenvalues.imag) > 0) & ~self._at_origin
        shift_ok = np.where(np.isnan(shift), self.alpha == 0, shift <= 0.5 * np.abs(zeta))
        trusted = shift_ok & (decay >= 1.0)
        trusted = np.where(self._at_origin, False, trusted)
        bad = oscillatory & ~trusted
        if not bad.any():
            message = (f"All {int(oscillatory.sum())} oscillatory eigenvalues have a damping ratio "
                       "that neither alpha nor the record length limits.")
        else:
            reasons = []
            if np.any(bad & ~shift_ok):
                reasons.append(
                    f"alpha = {self.alpha:.3g} moves the damping of {int(np.sum(bad & ~shift_ok))} "
                    "of them by more than half its value (refit with a smaller alpha, e.g. 0 on "
                    "clean data, or compare with the alpha = 0 model)"
                )
            if np.any(bad & (decay < 1.0)):
                reasons.append(
                    f"{int(np.sum(bad & (decay < 1.0)))} decay by less than one e-fold over the "
                    f"{self.n_pairs * self.dt:.3g} s record (use a longer record: the damping "
                    "ratio resolvable is about 1 / (omega T))"
                )
            message = (f"{int(bad.sum())} of {int(oscillatory.sum())} oscillatory eigenvalues have "
                       "an untrustworthy damping ratio: " + "; ".join(reasons) + ".")
            if warn:
                warnings.warn(message, IllConditionedWarning, stacklevel=2)
        return DampingReport(
            damping_ratio=read_only(zeta),
            regularisation_shift=read_only(shift),
            decay_over_record=read_only(decay),
            trusted=read_only(trusted),
            message=message,
        )

    def _regularisation_shift(self, s: np.ndarray) -> np.ndarray:
        """First-order change of each damping ratio when alpha goes to 0 (NaN: unknown)."""
        n = self.n_states
        if self.alpha == 0:
            return np.zeros(n)
        if self.regressor_gram is None:
            return np.full(n, np.nan)
        structured = self.basis is None and self.delays > 1
        k = self.n_nodes if structured else n
        coef = self.A[:k] if self.B is None else np.hstack([self.A[:k], self.B[:k]])
        gram = np.asarray(self.regressor_gram)
        # A_0 = A_alpha (I + alpha G^+): the pseudo-inverse, as plain DMD on rank-deficient data.
        delta_top = self.alpha * (coef @ sla.pinvh(gram))[:, :n]
        delta = np.zeros((n, n))
        delta[:k] = delta_top
        values, right = sla.eig(self.A)
        order = _spectral_order(values)
        values, right = values[order], right[:, order]
        try:
            left = sla.inv(right).conj().T  # rows of V^-1 are the left eigenvectors
        except (np.linalg.LinAlgError, ValueError):
            return np.full(n, np.nan)
        numerator = np.einsum("ij,ik,kj->j", left.conj(), delta, right)
        denominator = np.einsum("ij,ij->j", left.conj(), right)
        d_lambda = numerator / np.where(denominator == 0, 1.0, denominator)
        with np.errstate(divide="ignore", invalid="ignore"):
            d_s = d_lambda / np.where(values == 0, 1.0, values) / self.dt
            magnitude = np.abs(s)
            shift = np.where(magnitude > 0, np.abs(d_s.real) / np.where(magnitude > 0,
                                                                        magnitude, 1.0), 0.0)
        return np.where(np.isfinite(shift), shift, np.nan)

    def stability_report(self, *, warn: bool = True) -> StabilityReport:
        """Summarise stability; warn with :class:`UnstableModelWarning` when unstable.

        Parameters
        ----------
        warn : bool, default True
            Emit an :class:`~powerline_control.errors.UnstableModelWarning` for an unstable model.

        Returns
        -------
        StabilityReport
            Spectral radius, count outside the unit circle and a message with the fix.

        Examples
        --------
        >>> import numpy as np, powerline_control as plc
        >>> X = np.array([[0.9 ** k for k in range(20)]])
        >>> plc.fit_dmd(X, dt=0.1).stability_report().is_stable
        True
        """
        warn = check_bool("warn", warn)
        rho, unstable = self.spectral_radius, self.n_unstable
        if unstable == 0:
            message = (
                f"Stable: all {self.n_states} eigenvalues inside the unit circle "
                f"(spectral radius {rho:.6g}, alpha {self.alpha:.3g})."
            )
        else:
            message = (
                f"Unstable: {unstable} of {self.n_states} eigenvalues lie outside the unit circle "
                f"(spectral radius {rho:.6g}, alpha {self.alpha:.3g}). On noise-free or nearly "
                "rank-deficient data plain DMD fits round-off; regularise with alpha > 0 (see "
                "select_alpha), truncate with rank=..., or use noisy/longer data."
            )
            if warn:
                warnings.warn(message, UnstableModelWarning, stacklevel=2)
        return StabilityReport(rho, unstable, self.n_states, self.alpha, unstable == 0, message)

    # --- states, prediction -------------------------------------------------------------------

    def window_to_state(self, window: np.ndarray) -> np.ndarray:
        """Model state from the last ``delays`` snapshots.

        Parameters
        ----------
        window : array_like, shape (n_nodes, delays) or (n_nodes,) when ``delays == 1``
            Snapshots ``x_{k-d+1}, ..., x_k`` as columns, oldest first (the layout of the data).

        Returns
        -------
        ndarray, shape (n_states,)
            ``z_k``.

        Raises
        ------
        InputError
            Wrong shape or non-finite values.

        Examples
        --------
        >>> import numpy as np, powerline_control as plc
        >>> X = np.array([[0.9 ** k for k in range(20)]])
        >>> plc.fit_dmd(X, dt=0.1, delays=2).window_to_state([[2.0, 1.0]])
        array([1., 2.])
        """
        return self._state_of("window", window)

    def _state_of(self, name: str, window: object) -> np.ndarray:
        """:meth:`window_to_state`, naming the caller's parameter in its refusals."""
        window = check_array(name, window, ndim=(1, 2))
        if window.ndim == 1:
            window = window[:, None]
        if window.shape != (self.n_nodes, self.delays):
            raise InputError(
                f"The {name!r} parameter has the wrong shape: expected ({self.n_nodes}, "
                f"{self.delays}) (n_nodes, delays) but found {window.shape}."
            )
        stacked = window[:, ::-1].T.reshape(-1)
        return stacked if self.basis is None else self.basis.T @ stacked

    def predict(
        self, initial: np.ndarray, n_steps: int, inputs: np.ndarray | None = None
    ) -> np.ndarray:
        """Free-run prediction of the nodal displacements.

        Parameters
        ----------
        initial : array_like, shape (n_nodes, delays)
            The last ``delays`` measured snapshots, oldest first (see :meth:`window_to_state`).
        n_steps : int
            Number of steps to predict (>= 1).
        inputs : array_like, shape (n_inputs, n_steps), optional
            Known inputs ``u_k, ..., u_{k+n_steps-1}``; required when the model has inputs.

        Returns
        -------
        ndarray, shape (n_nodes, n_steps)
            Predicted ``x_{k+1}, ..., x_{k+n_steps}``.

        Raises
        ------
        InputError
            Wrong shapes, missing or unexpected inputs.
        IdentificationError
            The free run of an unstable model overflows (never NaN or inf results).

        Warns
        -----
        UnstableModelWarning
            The model is unstable (its free run grows).

        Examples
        --------
        >>> import numpy as np, powerline_control as plc
        >>> X = np.array([[0.5 ** k for k in range(10)]])
        >>> plc.fit_dmd(X, dt=1.0).predict([[1.0]], 3).round(6)
        array([[0.5  , 0.25 , 0.125]])
        """
        n_steps = check_int("n_steps", n_steps, low=1)
        z0 = self._state_of("initial", initial)
        u = self._check_prediction_inputs(inputs, n_steps)
        # The state run (n_states, n_steps) and its nodal image (n_nodes, n_steps), before the
        # loop allocates them (n_steps=10**10 asked for 298 GiB and ended in MemoryError).
        check_budget(
            "predict's free run", nbytes=8.0 * n_steps * (self.n_states + self.n_nodes),
            flops=2.0 * n_steps * self.n_states * (self.n_states + self.n_nodes),
            parameter="n_steps", value=n_steps,
            fix="predict fewer steps (in chunks: restart from the last predicted window)",
        )
        if not self.is_stable:
            warnings.warn(
                f"predict: the model is unstable (spectral radius {self.spectral_radius:.6g}); "
                "the free run grows without bound. Refit with alpha > 0 or a rank.",
                UnstableModelWarning, stacklevel=2,
            )
        with np.errstate(over="ignore", invalid="ignore"):
            field_run = self._free_run(z0, n_steps, u)
        bad = ~np.isfinite(field_run).all(axis=0)
        if bad.any():
            raise IdentificationError(
                f"predict: the free run of this unstable model overflows at step "
                f"{int(np.argmax(bad)) + 1} of {n_steps}. Predict fewer steps or refit a stable "
                "model (alpha > 0, see select_alpha)."
            )
        return field_run

    def _free_run(self, z: np.ndarray, n_steps: int, u: np.ndarray | None) -> np.ndarray:
        states = np.empty((self.n_states, n_steps))
        for k in range(n_steps):
            z = self.A @ z if u is None else self.A @ z + self.B @ u[:, k]
            states[:, k] = z
        return self.field_map @ states

    def _check_prediction_inputs(self, inputs: object, n_steps: int) -> np.ndarray | None:
        if self.B is None:
            if inputs is not None:
                raise InputError(
                    "The 'inputs' parameter must be None: this model was fitted without inputs."
                )
            return None
        if inputs is None:
            raise InputError(
                f"The 'inputs' parameter is required: this model has {self.n_inputs} input(s)."
            )
        u = check_array("inputs", inputs, ndim=(1, 2))
        u = u[None, :] if u.ndim == 1 else u
        if u.shape != (self.n_inputs, n_steps):
            raise InputError(
                f"The 'inputs' parameter has the wrong shape: expected ({self.n_inputs}, "
                f"{n_steps}) but found {u.shape}."
            )
        return u

    # --- export -------------------------------------------------------------------------------

    def _warn_if_python_control_refuses(self, C: np.ndarray, nodes: list[int]) -> None:
        message = _python_control_trouble(self, C)
        if message is not None:
            warnings.warn(f"to_statespace(measured={_short_list(nodes)}): {message}",
                          UnstableModelWarning, stacklevel=3)

    @property
    def state_names(self) -> list[str]:
        """Names of the states: ``x{node}_lag{l}`` for a window, ``pod{i}`` for POD coordinates."""
        if self.basis is not None:
            return [f"pod{i}" for i in range(self.n_states)]
        return [f"x{j}_lag{lag}" for lag in range(self.delays) for j in range(self.n_nodes)]

    def to_statespace(
        self,
        measured: Sequence[int] | np.ndarray | None = None,
        *,
        inputs: Sequence[str] | None = None,
    ) -> ct.StateSpace:
        """Discrete :class:`control.StateSpace` whose outputs are measured nodal displacements.

        Parameters
        ----------
        measured : sequence of int, optional
            Node indices (rows of the snapshot matrix) to output; ``None`` outputs every node, so
            ``C`` is :attr:`field_map`.  Output ``i`` is named ``node{measured[i]}``.
        inputs : sequence of str, optional
            Names of the known inputs (default ``u0, u1, ...``).  A model without inputs gets a
            ``B`` with zero columns (with a single measured node, one all-zero input named
            "unused": python-control 0.10.2 cannot build a 1-output, 0-input system).  For
            process noise use ``G = I`` with ``Q =`` :attr:`residual_covariance`
            (e.g. ``control.dlqe(A, I, C, Q, R)``).

        Returns
        -------
        control.StateSpace
            ``(A, B, C = field_map[measured], D = 0, dt)`` with named states/inputs/outputs.

        Raises
        ------
        InputError
            Node indices out of range, repeated or not integers; wrong number of input names.

        Warns
        -----
        UnstableModelWarning
            The model is one python-control's Riccati functions (``dlqe``, ``dlqr``) will
            refuse: unstable, or a unit-circle mode invisible to the measured nodes; the message
            says what to change.

        Examples
        --------
        >>> import numpy as np, powerline_control as plc
        >>> rng = np.random.default_rng(0)
        >>> X = rng.standard_normal((3, 50))
        >>> sys = plc.fit_dmd(X, dt=0.01).to_statespace(measured=[0, 2])
        >>> sys.noutputs, sys.nstates, sys.dt, sys.output_labels
        (2, 3, 0.01, ['node0', 'node2'])
        """
        nodes = _check_nodes("measured", measured, self.n_nodes)
        C = self.field_map[nodes]
        self._warn_if_python_control_refuses(C, nodes)
        B = np.zeros((self.n_states, 0)) if self.B is None else self.B
        if inputs is not None and (isinstance(inputs, str) or not isinstance(inputs, Sequence)
                                   or not all(isinstance(n, str) for n in inputs)):
            raise InputError(
                "The 'inputs' parameter must be None or a sequence of input names (str). Got "
                f"{inputs!r:.60} of type {type(inputs).__name__}."
            )
        if inputs is None:
            input_names = [f"u{i}" for i in range(self.n_inputs)]
        elif self.B is None and len(list(inputs)) == 0:
            input_names = []
        else:
            input_names = [str(name) for name in inputs]
            if len(input_names) != self.n_inputs:
                raise InputError(
                    f"The 'inputs' parameter must name {self.n_inputs} input(s). "
                    f"Got {len(input_names)} name(s) instead."
                )
        if B.shape[1] == 0 and len(nodes) == 1:
            # python-control 0.10.2 cannot build a (1 output, 0 input) system (its D check sees
            # (0, 0) for (1, 0)): give it one all-zero input instead.
            B, input_names = np.zeros((self.n_states, 1)), ["unused"]
        return ct.ss(
            self.A,
            B,
            C,
            np.zeros((len(nodes), B.shape[1])),
            self.dt,
            states=self.state_names,
            inputs=input_names,
            outputs=[f"node{j}" for j in nodes],
        )


def _python_control_trouble(model: DMDModel, C: np.ndarray) -> str | None:
    """Why python-control's Riccati-based functions would refuse this model, or None."""
    if model.n_states == 0:
        return None
    advice = ("Refit with a larger alpha (select_alpha's stable_alpha / best_stable_alpha), a "
              "rank, or more delays; or use plc.KalmanFilter / plc.steady_state_covariance, "
              "whose Riccati solver handles it.")
    if not model.is_stable:
        return (f"The model is unstable (spectral radius {model.spectral_radius:.6g} >= 1): "
                "python-control's dlqe / dlqr / dare may refuse it (SciPy: 'Reordering of "
                "(A, B) failed') or return a non-stabilising gain. " + advice)
    if model.n_states > _DETECTABILITY_CHECK_LIMIT or C.shape[0] == 0:
        return None
    marginal = np.abs(model.eigenvalues) >= 1.0 - 1e-9
    if not marginal.any():
        return None
    seen = np.linalg.norm(C @ model.modes[:, marginal], axis=0)
    scale = max(float(np.abs(C).max()), np.finfo(float).tiny)
    if np.any(seen <= 1e-10 * scale):
        return ("The model is undetectable from these outputs: a mode on the unit circle is "
                "invisible to every measured node, so no Kalman filter converges and "
                "python-control's dlqe fails. Measure other nodes, or " + advice[0].lower() +
                advice[1:])
    return None


def _spectral_order(values: np.ndarray) -> np.ndarray:
    """Decreasing magnitude; a conjugate pair with positive imaginary part first."""
    return np.lexsort((-values.imag, -np.round(np.abs(values), 12)))


def _short_list(items: list[int]) -> str:
    return str(items) if len(items) <= 8 else f"[{items[0]}, ..., {items[-1]}] ({len(items)})"


def _check_nodes(name: str, nodes: object, n_nodes: int) -> list[int]:
    if nodes is None:
        return list(range(n_nodes))
    return check_indices(name, nodes, n_nodes, allow_empty=True).tolist()


# ----------------------------------------------------------------------------------------------
# Fitting
# ----------------------------------------------------------------------------------------------


def _hankel(X: np.ndarray, delays: int) -> np.ndarray:
    """Columns ``[x_k; x_{k-1}; ...; x_{k-d+1}]`` for ``k = d-1 .. N-1``."""
    if delays == 1:
        return X  # no copy: callers only read it
    n_samples = X.shape[1]
    return np.vstack([X[:, delays - 1 - i : n_samples - i] for i in range(delays)])


def _largest_singular_value(M: np.ndarray, gram: np.ndarray | None = None) -> float:
    """Largest singular value, from the smaller Gram matrix (``gram`` if already computed).

    The top eigenvalue of a Gram matrix is accurate to relative round-off, and it costs far less
    than an SVD: a partial symmetric eigensolver for small Gram matrices, Lanczos for large
    ones.  Lanczos starts from a pseudo-random vector with a fixed seed (reproducible, and never
    orthogonal to the top eigenvector by a symmetry of the data, as a vector of ones is to an
    antisymmetric mode).
    """
    if M.size == 0:
        return 0.0
    if gram is None:
        gram = M @ M.T if M.shape[0] <= M.shape[1] else M.T @ M
    k = gram.shape[0]
    if k <= 500:
        try:
            top = sla.eigvalsh(gram, subset_by_index=[k - 1, k - 1])[0]
        except np.linalg.LinAlgError:  # syevr can fail on a tight cluster (G = c I)
            top = np.linalg.eigvalsh(gram)[-1]
    else:
        from scipy.sparse.linalg import eigsh

        start = np.random.default_rng(0).standard_normal(k)
        top = eigsh(gram, k=1, which="LA", v0=start, tol=0, return_eigenvectors=False)[0]
    return math.sqrt(max(float(top), 0.0))


@dataclass(frozen=True, eq=False)
class _Problem:
    """A prepared regression ``target ~ coef @ regressor`` in model coordinates."""

    target: np.ndarray  # (n_out, n_pairs): next states (first block only when `structured`)
    regressor: np.ndarray  # (n_states + n_inputs, n_pairs)
    n_states: int
    n_inputs: int
    n_nodes: int
    delays: int
    basis: np.ndarray | None
    s_max: float  # largest singular value of the state data, for relative alpha
    structured: bool  # True: delays without rank; only the first block row is fitted


def _prepare(
    X: np.ndarray, delays: int, rank: int | None, inputs: np.ndarray | None
) -> _Problem:
    """Embed the snapshots (and project them on the POD basis) into a regression problem."""
    n_nodes = X.shape[0]
    Z = _hankel(X, delays)
    Z0, Z1 = Z[:, :-1], Z[:, 1:]
    U0 = None if inputs is None else inputs[:, delays - 1 : delays - 1 + Z0.shape[1]]
    if rank is None:
        target = Z1[:n_nodes] if delays > 1 else Z1
        regressor = Z0 if U0 is None else np.vstack([Z0, U0])
        problem = _Problem(
            target, regressor, Z0.shape[0], 0 if U0 is None else U0.shape[0], n_nodes, delays,
            None, float("nan"), delays > 1,
        )
        return problem
    basis, s_max = _pod_basis(Z0, rank)
    A0, A1 = basis.T @ Z0, basis.T @ Z1
    regressor = A0 if U0 is None else np.vstack([A0, U0])
    problem = _Problem(
        A1, regressor, rank, 0 if U0 is None else U0.shape[0], n_nodes, delays, basis, s_max,
        False,
    )
    return problem


def _numerical_rank(s: np.ndarray, shape: tuple[int, int]) -> int:
    if s.size == 0 or s[0] == 0:
        return 0
    tol = s[0] * max(shape) * np.finfo(float).eps
    return int(np.count_nonzero(s > tol))


def _pod_basis(Z0: np.ndarray, rank: int) -> tuple[np.ndarray, float]:
    """Leading ``rank`` left singular vectors of ``Z0`` and its largest singular value.

    For ``rank`` well below the number of rows, a partial eigensolver of the Gram matrix gives an
    approximate subspace; two subspace-iteration steps on the data itself and a Rayleigh-Ritz SVD
    of the small projection ``Q^T Z0`` then give singular values and vectors without the
    squared condition number of the Gram matrix.  Otherwise (or when the spectrum falls below
    what that can resolve) a full thin SVD.
    """
    n_rows, n_cols = Z0.shape
    if n_rows <= n_cols and n_rows > 4 * rank:
        gram = Z0 @ Z0.T
        _, approx = sla.eigh(gram, subset_by_index=[n_rows - rank, n_rows - 1])
        Q = approx
        for _ in range(2):  # each step shrinks the error by (s_{r+1} / s_r)^2
            Q, _ = np.linalg.qr(Z0 @ (Z0.T @ Q))
        U_small, s, _ = sla.svd(Q.T @ Z0, full_matrices=False, lapack_driver="gesdd")
        if s[0] > 0 and s[-1] >= _GRAM_RANK_RATIO * s[0]:
            return _sign_fixed(Q @ U_small), float(s[0])
    U, s, _ = sla.svd(Z0, full_matrices=False, lapack_driver="gesdd")
    data_rank = _numerical_rank(s, Z0.shape)
    if rank > data_rank:
        raise InputError(
            f"The 'rank' parameter must not exceed the numerical rank of the data "
            f"({data_rank}). Got {rank} instead; pass rank <= {data_rank} or rank=None."
        )
    return _sign_fixed(U[:, :rank]), float(s[0])


def _sign_fixed(U: np.ndarray) -> np.ndarray:
    """Make the largest entry of each basis vector positive, so results are reproducible."""
    signs = np.sign(U[np.argmax(np.abs(U), axis=0), np.arange(U.shape[1])])
    return U * np.where(signs == 0, 1.0, signs)


def _ridge_gram(
    target: np.ndarray, regressor: np.ndarray, alpha: float, gram: np.ndarray | None
) -> tuple[np.ndarray, _GramScatter] | None:
    """Cholesky route of :func:`_ridge`: ``(coef, scatter)``, or None when not accurate.

    Solving ``(G + alpha I) coef^T = C`` (``G = R R^T``, ``C = R Y^T``) loses about
    ``eps (1 + s_max^2 / alpha)``; it is taken only when that is below ~1e-10 (and when
    ``R R^T`` is the smaller Gram matrix).  ``gram`` (``R R^T``, C-ordered) is overwritten by
    the factor.  Everything is laid out for LAPACK without transposed copies: a symmetric
    C-ordered matrix is itself in Fortran order, and ``Y R^T`` (C-ordered) is ``C`` in Fortran
    order, so ``potrs`` returns ``coef^T`` in Fortran order, i.e. ``coef`` in C order.
    """
    n_reg, n_pairs = regressor.shape
    if gram is None or alpha <= 0 or n_reg > n_pairs:
        return None
    diagonal = gram.diagonal().copy()
    if alpha < _GRAM_ALPHA_FRACTION * diagonal.sum():
        return None
    gram = np.ascontiguousarray(gram)  # (it is: fit_dmd's syrk) the flat view below needs it
    cross_t = target @ regressor.T  # C^T, C-ordered: C in Fortran order
    flat_diagonal = gram.reshape(-1)[:: n_reg + 1]  # a view (gram is C-contiguous)
    flat_diagonal += alpha
    # Fortran 'lower' is C-order 'upper': the factor fills gram's upper triangle and leaves
    # G in its strict lower one (read back by _GramScatter).
    factor, info = _potrf(gram.T, lower=1, overwrite_a=1, clean=0)
    if info != 0:  # not positive definite in floating point (cannot happen for alpha > 0
        return None  # above the threshold, but the SVD route is the safe answer)
    coef_t, info = _potrs(factor, cross_t.T, lower=1, overwrite_b=0)
    if info != 0:  # pragma: no cover - potrs fails only on bad arguments
        return None
    k = target.shape[0]
    scatter = _GramScatter(gram, diagonal, cross_t, regressor[:k, 0].copy(), target[:, -1].copy())
    return coef_t.T, scatter


@dataclass(frozen=True, eq=False)
class _GramScatter:
    """What :func:`_residual_covariance_from_gram` needs to form ``E E^T`` without a data pass.

    ``gram`` holds ``G = R R^T`` in its strict lower triangle (the Cholesky factor of
    ``G + alpha I`` is in the upper one) and ``diagonal`` its diagonal.  The target is the
    regressor's state rows shifted by one sample, so ``Y Y^T = G[:k, :k] - r_0 r_0^T +
    y_N y_N^T``.  ``cross_t`` is ``C^T = Y R^T`` (overwritten by the scatter computation).
    """

    gram: np.ndarray
    diagonal: np.ndarray
    cross_t: np.ndarray
    first: np.ndarray
    last: np.ndarray

    def target_trace(self) -> float:
        k = self.first.size
        return float(self.diagonal[:k].sum() - self.first @ self.first + self.last @ self.last)


#: Block rows of the lower-triangle product in _residual_covariance_from_gram: the blocks above
#: the diagonal cost (1 + block / k) / 2 of the full product.
_SCATTER_BLOCK = 256


def _residual_covariance_from_gram(
    coef: np.ndarray, alpha: float, parts: _GramScatter, n_states: int, n_pairs: int
) -> np.ndarray | None:
    """``E E^T / n_pairs`` (``E = Y - coef R``) from Gram matrices, or None when cancellation bites.

    With the normal equations ``coef (G + alpha I) = C^T``,
    ``E E^T = Y Y^T - 2 coef C + coef G coef^T = Y Y^T - coef D`` with
    ``D = C + alpha coef^T`` (``coef G coef^T = coef C - alpha coef coef^T``).  ``coef D`` is
    symmetric, so only its lower triangle is formed, by block rows: about ``k^3`` flops
    (half a product) and no pass over the data.  The difference of large terms is accurate to
    about ``eps ||Y||^2``, so the result is used only when the residual is at least 1e-8 of the
    data (checked on the trace, in O(k^2), before the product is formed).  Returns the
    symmetric ``(n_states, n_states)`` covariance (zero outside the leading ``k x k`` block).
    """
    k = coef.shape[0]
    d_t = parts.cross_t
    d_t += alpha * coef  # D^T = C^T + alpha coef, in place
    total = parts.target_trace()
    trace = total - _dot(coef, d_t)  # trace(coef D) = sum(coef * D^T)
    if not trace >= 1e-8 * total:
        return None
    scatter = np.zeros((k, k))  # contiguous: BLAS updates it in place
    for start in range(0, k, _SCATTER_BLOCK):
        stop = min(start + _SCATTER_BLOCK, k)
        np.matmul(coef[start:stop], d_t[:stop].T, out=scatter[start:stop, :stop])
    gram = parts.gram
    # G's diagonal back over the factor's (no longer needed): gram's lower triangle is G's
    gram.reshape(-1)[:: gram.shape[0] + 1] = parts.diagonal
    np.subtract(gram[:k, :k], scatter, out=scatter)  # lower triangle: G - coef D
    # rank-one corrections of Y Y^T, on the lower triangle only (Fortran 'upper' of the
    # transposed view, updated in place; the returned array is used in case BLAS copied)
    updated = _syr(-1.0, parts.first, lower=0, a=scatter.T, overwrite_a=1)
    scatter = _syr(1.0, parts.last, lower=0, a=updated, overwrite_a=1).T
    _mirror_lower(scatter)
    scatter *= 1.0 / n_pairs
    if n_states == k:
        return read_only(scatter)
    Q = np.zeros((n_states, n_states))
    Q[:k, :k] = scatter
    return read_only(Q)


def _mirror_lower(M: np.ndarray) -> None:
    """Copy the lower triangle of the square ``M`` onto its upper one, in place, by blocks."""
    k = M.shape[0]
    for start in range(0, k, _SCATTER_BLOCK):
        stop = min(start + _SCATTER_BLOCK, k)
        M[:start, start:stop] = M[start:stop, :start].T
        block = M[start:stop, start:stop]
        # only upper entries are written, from lower ones, so the overlap is harmless
        np.copyto(block, block.T, where=np.tri(stop - start, k=-1, dtype=bool).T)


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """``sum(a * b)`` of two arrays of the same shape (no temporaries when C-contiguous)."""
    return float(np.vdot(a, b))


def _ridge(
    target: np.ndarray,
    regressor: np.ndarray,
    alpha: float,
    svd: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, float | None]:
    """``coef = target R^T (R R^T + alpha I)^{-1}`` through an SVD (alpha = 0: pseudo-inverse).

    ``svd`` is a precomputed ``(target @ V, s, U)`` of the regressor ``R = U diag(s) V^T``
    (for alpha curves).  Returns the coefficients and, for alpha = 0, the smallest kept
    singular value as a fraction of the largest.
    """
    target_V, s, U = _ridge_svd(target, regressor) if svd is None else svd
    if alpha > 0:
        keep = s > 0
        gain = s[keep] / (s[keep] ** 2 + alpha)
        ratio = None
    else:
        keep = np.zeros(s.shape, dtype=bool)
        keep[: _numerical_rank(s, regressor.shape)] = True
        gain = 1.0 / s[keep]
        ratio = float(s[keep][-1] / s[0]) if keep.any() else None
    coef = (target_V[:, keep] * gain) @ U[:, keep].T
    return coef, ratio


def _covariance(scatter: np.ndarray, n_states: int, n_pairs: int) -> np.ndarray:
    """``scatter / n_pairs`` in the leading block of a symmetric (n_states, n_states) matrix."""
    Q = np.zeros((n_states, n_states))
    k = scatter.shape[0]
    Q[:k, :k] = scatter / n_pairs
    return read_only((Q + Q.T) / 2)


def _ridge_svd(
    target: np.ndarray, regressor: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    U, s, Vt = sla.svd(regressor, full_matrices=False, lapack_driver="gesdd")
    return target @ Vt.T, s, U


def _assemble(problem: _Problem, coef: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Split the coefficients into A and B (adding the exact shift rows when structured)."""
    n, m = problem.n_states, problem.n_inputs
    top_A, top_B = coef[:, :n], coef[:, n:]
    if not problem.structured:
        return top_A, (top_B if m else None)
    A = np.zeros((n, n))
    A[: problem.n_nodes] = top_A
    block = problem.n_nodes * (problem.delays - 1)
    A[problem.n_nodes :, :block] = np.eye(block)
    B = None
    if m:
        B = np.zeros((n, m))
        B[: problem.n_nodes] = top_B
    return A, B


def _fit_problem(
    problem: _Problem,
    alpha: float,
    dt: float,
    *,
    warn: bool = True,
    svd: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    gram: np.ndarray | None = None,
) -> DMDModel:
    n_reg, n_pairs = problem.regressor.shape
    kept_gram = None
    if alpha > 0 and n_reg <= _KEEP_GRAM_LIMIT and gram is not None:
        kept_gram = gram.copy()  # the Cholesky route overwrites it
    gram_route = None if svd is not None else _ridge_gram(
        problem.target, problem.regressor, alpha, gram
    )
    kept_ratio, covariance = None, None
    if gram_route is not None:
        coef, parts = gram_route
        covariance = _residual_covariance_from_gram(
            coef, alpha, parts, problem.n_states, n_pairs
        )
    else:
        if svd is None:
            svd = _ridge_svd(problem.target, problem.regressor)
        coef, kept_ratio = _ridge(problem.target, problem.regressor, alpha, svd)
        if alpha > 0 and n_reg <= _KEEP_GRAM_LIMIT and kept_gram is None:
            U, sv = svd[2], svd[1]
            kept_gram = (U * sv**2) @ U.T
    if (
        warn
        and alpha == 0
        and kept_ratio is not None
        and kept_ratio < _ILL_CONDITIONED_RATIO
    ):
        warnings.warn(
            f"Plain DMD (alpha=0) inverts singular values down to {kept_ratio:.2g} of the largest: "
            "the operator fits noise or round-off and is likely unstable. Use alpha > 0 "
            "(e.g. alpha_mode='relative', alpha=1e-8..1e-4; see select_alpha) or rank=...",
            IllConditionedWarning,
            stacklevel=3,
        )
    A, B = _assemble(problem, coef)
    if covariance is None:  # the residual pass: exact whatever the cancellation
        residual = problem.target - coef @ problem.regressor
        covariance = _covariance(residual @ residual.T, problem.n_states, n_pairs)
    n_states, n_nodes = problem.n_states, problem.n_nodes
    if problem.basis is None:
        field_map = np.eye(n_nodes, n_states)
    else:
        field_map = problem.basis[:n_nodes]
    s_max = problem.s_max
    return DMDModel(
        A=read_only(A),
        B=None if B is None else read_only(B),
        dt=dt,
        alpha=alpha,
        alpha_relative=alpha / s_max**2 if s_max**2 > 0 else 0.0,  # squares can underflow
        delays=problem.delays,
        rank=None if problem.basis is None else n_states,
        n_nodes=n_nodes,
        field_map=read_only(field_map),
        basis=None if problem.basis is None else read_only(problem.basis),
        residual_covariance=covariance,
        n_pairs=n_pairs,
        initial_state=read_only(problem.regressor[:n_states, 0].copy()),
        regressor_gram=None if kept_gram is None else read_only(kept_gram),
    )


def _check_snapshots(X: object) -> np.ndarray:
    # Refuses complex (the imaginary part would be lost), boolean (a mask) and transposed data.
    return check_snapshot_matrix("X", X)


def _check_inputs(inputs: object, n_samples: int) -> np.ndarray | None:
    if inputs is None:
        return None
    u = check_array("inputs", inputs, ndim=(1, 2))
    u = u[None, :] if u.ndim == 1 else u
    if u.shape[1] not in (n_samples, n_samples - 1):
        raise InputError(
            f"The 'inputs' parameter must have one column per snapshot ({n_samples}) or per "
            f"snapshot pair ({n_samples - 1}); u[:, k] drives x_k -> x_(k+1). Got shape "
            f"{u.shape} instead."
        )
    return u


#: Largest data magnitude: Gram matrices sum its squares, which beyond ~1e154 overflow to inf.
#: (Tiny data are accepted: their squares underflow to zero, which the fit copes with.)
_SCALE_LIMIT = 1e150


def _check_scale(name: str, values: np.ndarray) -> None:
    """Refuse data whose squares overflow (max/min: no temporary array)."""
    if values.size == 0:
        return
    peak = max(abs(float(values.max())), abs(float(values.min())))
    if peak > _SCALE_LIMIT:
        raise InputError(
            f"The {name!r} parameter has largest magnitude {peak:.3g}, above {_SCALE_LIMIT:g}: "
            "its squares overflow in floating point. Rescale it (e.g. to km or Mm)."
        )


def _check_common(
    X: object, dt: object, delays: object, rank: object, inputs: object
) -> tuple[np.ndarray, float, int, int | None, np.ndarray | None]:
    X = _check_snapshots(X)
    _check_scale("X", X)
    dt = check_real("dt", dt, low=0.0)
    n_samples = X.shape[1]
    delays = check_int("delays", delays, low=1, high=max(1, n_samples - 2))
    if rank is not None:
        rank = check_int("rank", rank, low=1, high=X.shape[0] * delays)
    rows = X.shape[0] * delays
    # The delay-embedded data (a copy, plus shifted views and a projection) and the Gram matrix
    # of its rows: estimated before anything is allocated.
    check_budget(
        "The DMD fit", nbytes=8.0 * (2 * rows * n_samples + rows**2),
        flops=2.0 * rows**2 * n_samples, parameter="delays", value=delays,
        fix=(f"use fewer delays or nodes ({X.shape[0]} nodes x {delays} delays = {rows} rows; "
             "design_estimator first projects the nodes on a few spatial POD modes), or a "
             "shorter record"),
    )
    u = _check_inputs(inputs, n_samples)
    if u is not None:
        _check_scale("inputs", u)
    return X, dt, delays, rank, u


def _refuse_all_zero(X: np.ndarray) -> None:
    if not np.any(X):
        raise IdentificationError(
            "The 'X' parameter is all zeros: there are no dynamics to identify."
        )


def _absolute_alpha(
    alpha: float, alpha_mode: str, problem: _Problem, gram: np.ndarray | None = None
) -> tuple[float, _Problem]:
    """Absolute alpha, computing the largest singular value of the state data when needed.

    ``gram`` is ``regressor @ regressor.T`` when already computed (its leading block is the
    Gram matrix of the state data).
    """
    if math.isnan(problem.s_max):
        n = problem.n_states
        block = None if gram is None else gram[:n, :n]
        s_max = _largest_singular_value(problem.regressor[:n], block)
        problem = dataclasses.replace(problem, s_max=s_max)
    if alpha_mode == "relative":
        return alpha * problem.s_max**2, problem
    return alpha, problem


def fit_dmd(
    X: np.ndarray,
    dt: float,
    alpha: float = 0.0,
    delays: int = 1,
    rank: int | None = None,
    inputs: np.ndarray | None = None,
    alpha_mode: str = "absolute",
) -> DMDModel:
    """Identify ``z_{k+1} = A z_k (+ B u_k)`` from snapshots by (Tikhonov-regularised) DMD.

    With ``alpha = 0`` this is exact DMD, ``A = X' X^+`` (the paper's eq. 11, minimum-norm least
    squares with the usual numerical-rank cut); with ``alpha > 0`` it is
    ``A = X' X^T (X X^T + alpha I)^{-1}`` (eq. 14).  Both are computed through an SVD or a
    Cholesky solve, never an explicit inverse.  Identically zero rows (pinned supports) are
    handled: they give zero rows and columns of ``A``.

    Parameters
    ----------
    X : array_like, shape (n_nodes, n_samples)
        Snapshots, one column per sample (the paper's and python-control's layout).
    dt : float
        Sample time in seconds (> 0).
    alpha : float, default 0.0
        Tikhonov parameter (>= 0), interpreted according to ``alpha_mode``.
    delays : int, default 1
        Number of stacked snapshots ``d``; the state is ``[x_k; ...; x_{k-d+1}]``.  A line is
        second order, so ``d >= 2`` is needed for an exact linear model of displacements.
    rank : int, optional
        Keep this many POD coordinates of the (delayed) data as the state; must not exceed the
        numerical rank of the data.  ``None``: no truncation.
    inputs : array_like, shape (n_inputs, n_samples) or (n_inputs, n_samples - 1), optional
        Known inputs (DMD with control); ``inputs[:, k]`` drives ``x_k -> x_{k+1}``.  A 1-d
        array is one input.
    alpha_mode : {"absolute", "relative"}, default "absolute"
        "absolute": ``alpha`` as in eq. 14 (not scale-invariant: data scaled by c needs
        ``alpha c**2``).  "relative": ``alpha`` times the largest squared singular value of the
        (delayed) state data, which transfers between spans and units.

    Returns
    -------
    DMDModel
        The identified model.

    Raises
    ------
    InputError
        Non-finite data, ``dt <= 0``, ``alpha < 0``, a bad ``delays``/``rank``, a rank above the
        data rank, inputs of the wrong length, or (with ``alpha = 0`` and no rank) fewer snapshot
        pairs than states.
    IdentificationError
        The data are all zero.

    Warns
    -----
    IllConditionedWarning
        ``alpha = 0`` and the fit inverts singular values below 1e-8 of the largest.

    Examples
    --------
    Two damped oscillation modes sampled at 100 Hz; two delays make the model exact:

    >>> import numpy as np, powerline_control as plc
    >>> t = np.arange(400) * 0.01
    >>> X = np.vstack([np.exp(-0.5 * t) * np.cos(2 * np.pi * 3 * t),
    ...                np.exp(-0.2 * t) * np.sin(2 * np.pi * 7 * t)])
    >>> dmd = plc.fit_dmd(X, dt=0.01, delays=2)
    >>> np.round(np.sort(dmd.damped_frequencies)[::2], 6)
    array([3., 7.])
    >>> dmd.is_stable, dmd.A.shape
    (True, (4, 4))
    """
    X, dt, delays, rank, u = _check_common(X, dt, delays, rank, inputs)
    alpha = check_real("alpha", alpha, low=0.0, low_inclusive=True)
    alpha_mode = check_choice("alpha_mode", alpha_mode, ("absolute", "relative"))
    n_pairs = X.shape[1] - delays
    n_states = X.shape[0] * delays
    n_reg = n_states + (0 if u is None else u.shape[0])
    # The Gram matrix serves the relative-alpha scale and the Cholesky route (computed once),
    # and its trace tells whether the data are all zero without another pass over them.
    with_gram = alpha > 0 and n_reg <= n_pairs
    if not (with_gram and rank is None):
        _refuse_all_zero(X)
    if alpha == 0 and rank is None and n_pairs < n_reg:
        raise InputError(
            f"Plain DMD (alpha=0, rank=None) needs at least as many snapshot pairs as states "
            f"(+ inputs): got {n_pairs} pairs for {n_states} states. Pass alpha > 0 "
            "(e.g. alpha_mode='relative', alpha=1e-6), a rank, or more samples."
        )
    problem = _prepare(X, delays, rank, u)
    gram = problem.regressor @ problem.regressor.T if with_gram else None
    if gram is not None and rank is None and not gram.diagonal()[:n_states].sum() > 0:
        # the state rows cover every sample but the last; squares can underflow: ask the data
        _refuse_all_zero(X)
    alpha, problem = _absolute_alpha(alpha, alpha_mode, problem, gram)
    return _fit_problem(problem, alpha, dt, gram=gram)


# ----------------------------------------------------------------------------------------------
# Choosing alpha
# ----------------------------------------------------------------------------------------------


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


# ----------------------------------------------------------------------------------------------
# Online DMD
# ----------------------------------------------------------------------------------------------


class OnlineDMD:
    """DMD updated one snapshot at a time: recursive least squares with exponential forgetting.

    Started from a batch of snapshots (the same fit as :func:`fit_dmd` without rank truncation),
    each :meth:`update` costs O(n^2) for n = ``n_nodes * delays + n_inputs`` (Zhang, Rowley,
    Deem and Cattafesta, SIAM J. Appl. Dyn. Syst. 18(3), 2019).  It minimises
    ``sum_i rho^(k-i) ||x_{i+1} - [A B] w_i||^2 + rho^k alpha ||[A B]||^2``, so with
    ``forgetting = 1`` its ``A`` (and ``B``) equal batch DMD on all data seen; with ``rho < 1``
    the memory is about ``dt / (1 - rho)`` seconds, and the model follows a line whose tension or
    excitation changes.  Its ``residual_covariance`` is not the batch one: it averages each
    update's a-priori residual (before that sample was learnt), so it is larger than
    :func:`fit_dmd`'s after-the-fact residuals (measured: 3-5 % at alpha = 0, more with delays
    and a small alpha), i.e. a more cautious process noise for a Kalman filter.

    Parameters
    ----------
    X : array_like, shape (n_nodes, n_samples)
        Initial snapshots.  With ``alpha = 0`` they must have full rank (at least
        ``n_nodes * delays + n_inputs`` pairs).
    dt : float
        Sample time in seconds (> 0).
    delays : int, default 1
        Number of stacked snapshots (as in :func:`fit_dmd`).
    inputs : array_like, shape (n_inputs, n_samples) or (n_inputs, n_samples - 1), optional
        Known inputs of the initial data.
    forgetting : float, default 1.0
        Per-sample forgetting factor ``rho`` in (0, 1].
    alpha : float, default 0.0
        Tikhonov parameter (absolute, or relative to the initial data with ``alpha_mode``).
    alpha_mode : {"absolute", "relative"}, default "absolute"
        As in :func:`fit_dmd`.

    Attributes
    ----------
    n_updates : int
        Samples added with :meth:`update` since the batch start.
    n_windup_clips : int
        Updates at which the covariance ``P`` had wound up (``forgetting < 1`` and directions
        the data no longer excite) and its eigenvalues were capped at 1e8 times its initial
        trace, so ``A`` stays finite instead of drifting to NaN.

    Raises
    ------
    InputError
        Bad arguments (as for :func:`fit_dmd`), or ``forgetting`` outside (0, 1].
    IdentificationError
        ``alpha = 0`` and the initial data do not have full rank.

    Examples
    --------
    >>> import numpy as np, powerline_control as plc
    >>> X = np.array([[0.9 ** k for k in range(30)]])
    >>> online = plc.OnlineDMD(X[:, :10], dt=0.1)
    >>> for k in range(10, 30):
    ...     online.update(X[:, k])
    >>> round(float(online.eigenvalues[0].real), 9)
    0.9
    """

    def __init__(
        self,
        X: np.ndarray,
        dt: float,
        *,
        delays: int = 1,
        inputs: np.ndarray | None = None,
        forgetting: float = 1.0,
        alpha: float = 0.0,
        alpha_mode: str = "absolute",
    ) -> None:
        X, dt, delays, _, u = _check_common(X, dt, delays, None, inputs)
        alpha = check_real("alpha", alpha, low=0.0, low_inclusive=True)
        alpha_mode = check_choice("alpha_mode", alpha_mode, ("absolute", "relative"))
        self.forgetting = check_real("forgetting", forgetting, low=0.0, high=1.0)
        problem = _prepare(X, delays, None, u)
        alpha, problem = _absolute_alpha(alpha, alpha_mode, problem)
        self.dt, self.delays, self.alpha = dt, delays, alpha
        self._n_nodes, self._n_states, self._n_inputs = (
            problem.n_nodes, problem.n_states, problem.n_inputs,
        )
        self._s_max = problem.s_max
        gram = problem.regressor @ problem.regressor.T
        gram[np.diag_indices_from(gram)] += alpha
        lam, vec = sla.eigh(gram)
        if lam[0] <= lam[-1] * gram.shape[0] * np.finfo(float).eps:
            raise IdentificationError(
                f"OnlineDMD needs initial data of full rank {gram.shape[0]} (states + inputs) "
                f"when alpha = 0; got {problem.regressor.shape[1]} pairs of numerical rank below "
                "that. Pass alpha > 0 or more (richer) initial snapshots."
            )
        # RLS needs the inverse information matrix itself; eigh keeps it symmetric and exact.
        self._P = (vec / lam) @ vec.T
        # Wind-up cap: 1e8 times the initial uncertainty, far beyond what excited data reach.
        self._p_cap = 1e8 * float(np.trace(self._P))
        self.n_windup_clips = 0
        self._coef, _ = _ridge(problem.target, problem.regressor, alpha)
        residual = problem.target - self._coef @ problem.regressor
        self._residual_sum = residual @ residual.T
        self._weight = float(problem.regressor.shape[1])
        self._initial_pairs = problem.regressor.shape[1]
        self._window = X[:, X.shape[1] - delays :].copy()
        self._first_state = problem.regressor[: problem.n_states, 0].copy()
        self.n_updates = 0

    @property
    def n_states(self) -> int:
        """Size of the model state (``n_nodes * delays``)."""
        return self._n_states

    def update(self, x: np.ndarray, u: np.ndarray | float | None = None) -> None:
        """Add one snapshot: the pair (last window, ``x``) updates the model.

        Parameters
        ----------
        x : array_like, shape (n_nodes,)
            The new snapshot ``x_{k+1}``.
        u : array_like, shape (n_inputs,), optional
            The input ``u_k`` that drove the previous snapshot to ``x``; required with inputs.

        Raises
        ------
        InputError
            Wrong shapes or non-finite values.
        IdentificationError
            The recursion diverged (non-finite covariance or coefficients).
        """
        x = check_array("x", x, shape=(self._n_nodes,))
        w = self._window[:, ::-1].T.reshape(-1)
        if self._n_inputs:
            if u is None:
                raise InputError(
                    f"The 'u' parameter is required: this model has {self._n_inputs} input(s)."
                )
            w = np.concatenate([w, check_array("u", np.atleast_1d(u), shape=(self._n_inputs,))])
        elif u is not None:
            raise InputError("The 'u' parameter must be None: this model has no inputs.")
        Pw = self._P @ w
        gain = 1.0 / (1.0 + w @ Pw)
        error = x - self._coef @ w
        self._coef += gain * np.outer(error, Pw)
        rho = self.forgetting
        P = (self._P - gain * np.outer(Pw, Pw)) / rho
        P = (P + P.T) / 2
        if rho < 1 and np.trace(P) > self._p_cap:
            # Covariance wind-up: with forgetting, directions the data stop exciting grow like
            # rho^-k until they overflow. Cap P's eigenvalues (an information floor of
            # 1 / cap per direction, i.e. a constant Tikhonov term): the estimate of excited
            # directions is untouched, unexcited ones stop drifting.
            lam, vec = sla.eigh(P)
            P = (vec * np.minimum(lam, self._p_cap / lam.size)) @ vec.T
            self.n_windup_clips += 1
        if not (np.all(np.isfinite(P)) and np.all(np.isfinite(self._coef))):
            raise IdentificationError(
                f"OnlineDMD diverged at update {self.n_updates + 1} (non-finite covariance or "
                "coefficients): the data are not finite-energy or far from the model. Restart "
                "from a new batch, or use forgetting closer to 1 and alpha > 0."
            )
        self._P = P
        self._residual_sum = rho * self._residual_sum + np.outer(error, error)
        self._weight = rho * self._weight + 1.0
        self._window = np.column_stack([self._window[:, 1:], x])
        self.n_updates += 1

    def _problem_shell(self) -> _Problem:
        n_reg = self._n_states + self._n_inputs
        return _Problem(
            np.zeros((self._coef.shape[0], 0)), np.zeros((n_reg, 0)), self._n_states,
            self._n_inputs, self._n_nodes, self.delays, None, self._s_max, self.delays > 1,
        )

    @property
    def A(self) -> np.ndarray:
        """Current state-transition matrix (a copy)."""
        return _assemble(self._problem_shell(), self._coef)[0]

    @property
    def B(self) -> np.ndarray | None:
        """Current input matrix (a copy), ``None`` without inputs."""
        return _assemble(self._problem_shell(), self._coef)[1]

    @property
    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of the current ``A``, by decreasing magnitude."""
        values = sla.eigvals(self.A)
        return values[np.lexsort((-values.imag, -np.abs(values)))]

    def model(self) -> DMDModel:
        """A frozen :class:`DMDModel` of the current state of the online fit.

        Its ``residual_covariance`` is the forgetting-weighted mean of the a-priori one-step
        residuals (prediction error before each update), in the first ``n_nodes`` block.

        Returns
        -------
        DMDModel
            The current model (``rank`` None, ``n_pairs`` = initial pairs + updates, although
            with forgetting the old pairs weigh less).
        """
        A, B = self.A, self.B
        Q = np.zeros((self._n_states, self._n_states))
        k = self._residual_sum.shape[0]
        Q[:k, :k] = self._residual_sum / self._weight
        s_max = self._s_max
        return DMDModel(
            A=read_only(A),
            B=None if B is None else read_only(B),
            dt=self.dt,
            alpha=self.alpha,
            alpha_relative=self.alpha / s_max**2 if s_max > 0 else 0.0,
            delays=self.delays,
            rank=None,
            n_nodes=self._n_nodes,
            field_map=read_only(np.eye(self._n_nodes, self._n_states)),
            basis=None,
            residual_covariance=read_only((Q + Q.T) / 2),
            n_pairs=self._initial_pairs + self.n_updates,
            initial_state=read_only(self._first_state),
        )
