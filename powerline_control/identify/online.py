"""Online identification: :class:`OnlineDMD`, DMD updated one snapshot at a time.

Recursive least squares with exponential forgetting, started from the batch fit of
:func:`~powerline_control.identify.fit_dmd` (no rank truncation); each update costs O(n^2) and
:meth:`OnlineDMD.model` freezes the current fit as a
:class:`~powerline_control.identify.DMDModel`.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .._validation import check_array, check_choice, check_real, read_only
from ..errors import IdentificationError, InputError
from ._ridge import _ridge
from .fit import _absolute_alpha, _assemble, _check_common, _prepare, _Problem
from .model import DMDModel


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
        self._coef = _ridge(problem.target, problem.regressor, alpha).coef
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
