"""The identified model: :class:`DMDModel`, its spectrum, prediction and export to python-control.

A :class:`DMDModel` is the frozen result of :func:`~powerline_control.identify.fit_dmd` (or of
:meth:`OnlineDMD.model <powerline_control.identify.OnlineDMD.model>`): ``z_{k+1} = A z_k + B
u_k`` with the map :attr:`~DMDModel.field_map` from its state back to the current nodal
displacements.  Its eigenvalues give frequencies and damping ratios; :meth:`~DMDModel.predict`
free-runs it and :meth:`~DMDModel.to_statespace` exports it as a discrete
:class:`control.StateSpace`, warning when python-control's Riccati functions would refuse it.
Its stability and damping reports (computed here) are defined in
:mod:`powerline_control.identify.stability`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import control as ct
import numpy as np
import scipy.linalg as sla

from .._results import Result
from .._validation import (
    check_array,
    check_bool,
    check_budget,
    check_indices,
    check_int,
    read_only,
)
from ..errors import (
    IdentificationError,
    IllConditionedWarning,
    InputError,
    UnstableModelWarning,
)
from .stability import DampingReport, StabilityReport, _spectral_order

#: to_statespace checks detectability of unit-circle modes for models up to this size.
_DETECTABILITY_CHECK_LIMIT = 1000
#: |lambda| above 1 + this counts as outside the unit circle (round-off of a marginal mode).
_UNIT_CIRCLE_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class DMDModel(Result):
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
        return _damping_report(self, warn=warn)

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
        return _stability_report(self, warn=warn)

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
              "rank, or more delays; or use plc.KalmanFilter / "
              "plc.estimate.steady_state_covariance, whose Riccati solver handles it.")
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

def _short_list(items: list[int]) -> str:
    return str(items) if len(items) <= 8 else f"[{items[0]}, ..., {items[-1]}] ({len(items)})"


def _check_nodes(name: str, nodes: object, n_nodes: int) -> list[int]:
    if nodes is None:
        return list(range(n_nodes))
    return check_indices(name, nodes, n_nodes, allow_empty=True).tolist()


def _damping_report(model: DMDModel, *, warn: bool) -> DampingReport:
    """The work of :meth:`DMDModel.damping_report` (its warning names the caller's line)."""
    warn = check_bool("warn", warn)
    zeta = np.asarray(model.damping_ratios, dtype=float)
    s = np.asarray(model.continuous_eigenvalues)
    decay = np.abs(s.real) * model.n_pairs * model.dt
    shift = _regularisation_shift(model, s)
    oscillatory = (np.abs(model.eigenvalues.imag) > 0) & ~model._at_origin
    shift_ok = np.where(np.isnan(shift), model.alpha == 0, shift <= 0.5 * np.abs(zeta))
    trusted = shift_ok & (decay >= 1.0)
    trusted = np.where(model._at_origin, False, trusted)
    bad = oscillatory & ~trusted
    if not bad.any():
        message = (f"All {int(oscillatory.sum())} oscillatory eigenvalues have a damping ratio "
                   "that neither alpha nor the record length limits.")
    else:
        reasons = []
        if np.any(bad & ~shift_ok):
            reasons.append(
                f"alpha = {model.alpha:.3g} moves the damping of {int(np.sum(bad & ~shift_ok))} "
                "of them by more than half its value (refit with a smaller alpha, e.g. 0 on "
                "clean data, or compare with the alpha = 0 model)"
            )
        if np.any(bad & (decay < 1.0)):
            reasons.append(
                f"{int(np.sum(bad & (decay < 1.0)))} decay by less than one e-fold over the "
                f"{model.n_pairs * model.dt:.3g} s record (use a longer record: the damping "
                "ratio resolvable is about 1 / (omega T))"
            )
        message = (f"{int(bad.sum())} of {int(oscillatory.sum())} oscillatory eigenvalues have "
                   "an untrustworthy damping ratio: " + "; ".join(reasons) + ".")
        if warn:
            warnings.warn(message, IllConditionedWarning, stacklevel=3)
    return DampingReport(
        damping_ratio=read_only(zeta),
        regularisation_shift=read_only(shift),
        decay_over_record=read_only(decay),
        trusted=read_only(trusted),
        message=message,
    )


def _regularisation_shift(model: DMDModel, s: np.ndarray) -> np.ndarray:
    """First-order change of each damping ratio when alpha goes to 0 (NaN: unknown)."""
    n = model.n_states
    if model.alpha == 0:
        return np.zeros(n)
    if model.regressor_gram is None:
        return np.full(n, np.nan)
    structured = model.basis is None and model.delays > 1
    k = model.n_nodes if structured else n
    coef = model.A[:k] if model.B is None else np.hstack([model.A[:k], model.B[:k]])
    gram = np.asarray(model.regressor_gram)
    # A_0 = A_alpha (I + alpha G^+): the pseudo-inverse, as plain DMD on rank-deficient data.
    delta_top = model.alpha * (coef @ sla.pinvh(gram))[:, :n]
    delta = np.zeros((n, n))
    delta[:k] = delta_top
    values, right = sla.eig(model.A)
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
        d_s = d_lambda / np.where(values == 0, 1.0, values) / model.dt
        magnitude = np.abs(s)
        shift = np.where(magnitude > 0, np.abs(d_s.real) / np.where(magnitude > 0,
                                                                    magnitude, 1.0), 0.0)
    return np.where(np.isfinite(shift), shift, np.nan)


def _stability_report(model: DMDModel, *, warn: bool) -> StabilityReport:
    """The work of :meth:`DMDModel.stability_report` (its warning names the caller's line)."""
    warn = check_bool("warn", warn)
    rho, unstable = model.spectral_radius, model.n_unstable
    if unstable == 0:
        message = (
            f"Stable: all {model.n_states} eigenvalues inside the unit circle "
            f"(spectral radius {rho:.6g}, alpha {model.alpha:.3g})."
        )
    else:
        message = (
            f"Unstable: {unstable} of {model.n_states} eigenvalues lie outside the unit circle "
            f"(spectral radius {rho:.6g}, alpha {model.alpha:.3g}). On noise-free or nearly "
            "rank-deficient data plain DMD fits round-off; regularise with alpha > 0 (see "
            "select_alpha), truncate with rank=..., or use noisy/longer data."
        )
        if warn:
            warnings.warn(message, UnstableModelWarning, stacklevel=3)
    return StabilityReport(rho, unstable, model.n_states, model.alpha, unstable == 0, message)
