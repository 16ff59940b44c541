"""The oscillator model of a narrowband record: :class:`OscillatorModel`, one undamped oscillator
per spectral line.

A record driven at a few frequencies (a harmonic load, a locked-in wind) shows a few spectral
lines; its model is then not fitted by DMD but written down: each line of frequency ``f`` and
nodal shape ``phi`` is an oscillator whose amplitude obeys the two-step recursion
``a_{k+1} = 2 rho cos(2 pi f dt) a_k - rho^2 a_{k-1}`` (``rho`` just below 1, so that a Kalman
filter's Riccati equation has a solution), and the smooth directions the lines leave out become
white states (a new load is still tracked).  The type subclasses :class:`DMDModel`: every stage
that takes a model (the Kalman filter, observability, sensor selection, the closed loop) reads the
same fields (``A``, ``field_map``, ``basis``, ``residual_covariance``, ...), while the model's own
text and the files it is saved to say what it is.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from .._validation import check_array, check_bool, check_int, check_real, read_only
from ..errors import IllConditionedWarning, InputError, UnstableModelWarning
from .model import DMDModel
from .stability import DampingReport, StabilityReport

#: Default radius of the lines' eigenvalues: undamped, held just inside the unit circle.
DEFAULT_RADIUS = 1.0 - 1e-6
#: How many line frequencies a text lists before it says "... (N in all)".
_LISTED_LINES = 6
#: Tolerance of the unseen directions' orthonormality (round-off of an SVD or QR is ~1e-15).
_ORTHO_TOL = 1e-8


@dataclass(frozen=True, eq=False, repr=False)
class OscillatorModel(DMDModel):
    """One undamped oscillator per spectral line of a narrowband record, plus white states.

    Build it with :meth:`from_lines`.  The state is ``[b_k; b_{k-1}; w_k]``: ``b = Q^T x`` the
    coordinates of the field on the orthonormalised line shapes ``Q`` (two steps, since each
    line is second order) and ``w`` the coordinates on the unseen directions, white noise
    states with no dynamics.  Every line's amplitude obeys
    ``a_{k+1} = 2 rho cos(2 pi f dt) a_k - rho^2 a_{k-1}``, so ``A`` has the eigenvalues
    ``rho exp(+-i 2 pi f dt)`` for each line frequency ``f`` and 0 for each unseen direction.
    It is a :class:`DMDModel` (every consumer of one takes it unchanged) but not a DMD fit: it
    has no Tikhonov alpha (``alpha = alpha_relative = 0``) and ``delays = 2`` is the order of
    the recursion, not a delay embedding chosen by a fit.

    Attributes
    ----------
    A : ndarray, shape (n_states, n_states)
        State-transition matrix, ``n_states = 2 n_lines + n_unseen``.
    B : None
        No known inputs.
    dt : float
        Sample time in seconds.
    alpha, alpha_relative : float
        0: the model is built, not fitted, so it has no Tikhonov alpha.
    delays : int
        2: the two steps of each line's recursion.
    rank : int
        ``n_states``.
    n_nodes : int
        Number of nodes.
    field_map : ndarray, shape (n_nodes, n_states)
        Maps the state to the current nodal displacements, ``[Q, 0, unseen]``.
    basis : ndarray, shape (2 n_nodes, n_states)
        Orthonormal basis of the two-snapshot window: ``Q`` on each snapshot, the unseen
        directions on the current one.
    residual_covariance : ndarray, shape (n_states, n_states)
        Process noise: ``process_noise`` on every current line coordinate, ``unseen_noise`` on
        every unseen state, 0 on the lagged coordinates.
    n_pairs : int
        Number of snapshot pairs of the record the lines came from.
    initial_state : ndarray, shape (n_states,)
        Zeros: the model starts at rest.
    regressor_gram : None
        No regressor: nothing was fitted.
    line_frequencies : ndarray, shape (n_lines,)
        Frequency of each line, Hz.  (Not ``frequencies``: that inherited property gives one
        frequency per eigenvalue, as for every DMDModel.)
    line_shapes : ndarray, shape (n_nodes, n_lines)
        Nodal shape of each line as given (independent columns; ``Q`` is their QR basis).
    unseen : ndarray, shape (n_nodes, n_unseen)
        Orthonormal directions outside the lines' span, tracked as white states (may be empty).
    process_noise : float
        Variance added per step to each current line coordinate, m^2.
    unseen_noise : float
        Variance of each unseen state, m^2.
    radius : float
        Magnitude ``rho`` of the lines' eigenvalues (at most 1).

    Examples
    --------
    One 5 Hz line seen at three nodes, sampled at 100 Hz:

    >>> import numpy as np
    >>> from powerline_control.identify import OscillatorModel
    >>> model = OscillatorModel.from_lines([5.0], [[0.5], [1.0], [0.5]], dt=0.01, n_pairs=100,
    ...                                    process_noise=1e-8)
    >>> model
    OscillatorModel(oscillator model, 1 line at 5 Hz; 2 states, 3 nodes, dt = 0.01 s)
    >>> np.round(np.angle(model.eigenvalues[0]) / (2 * np.pi * model.dt), 9)
    np.float64(5.0)
    >>> model.to_statespace(measured=[1]).nstates
    2
    """

    line_frequencies: np.ndarray = field(kw_only=True)
    line_shapes: np.ndarray = field(kw_only=True, repr=False)
    unseen: np.ndarray = field(kw_only=True, repr=False)
    process_noise: float = field(kw_only=True)
    unseen_noise: float = field(kw_only=True)
    radius: float = field(kw_only=True)

    @classmethod
    def from_lines(cls, frequencies: object, shapes: object, dt: float, *, n_pairs: int,
                   process_noise: float, unseen: object = None, unseen_noise: float = 0.0,
                   radius: float = DEFAULT_RADIUS) -> OscillatorModel:
        """Build the model of the given lines (and unseen directions).

        Parameters
        ----------
        frequencies : array_like, shape (n_lines,)
            Line frequencies, Hz, each in ``[0, 1 / (2 dt)]``.
        shapes : array_like, shape (n_nodes, n_lines)
            Nodal shape of each line; the columns must be linearly independent.
        dt : float
            Sample time, s (> 0).
        n_pairs : int
            Snapshot pairs of the record the lines came from (>= 1).
        process_noise : float
            Variance added per step to each current line coordinate, m^2 (>= 0).
        unseen : array_like, shape (n_nodes, n_unseen), optional
            Orthonormal directions orthogonal to the shapes' span, tracked as white states.
        unseen_noise : float, default 0
            Variance of each unseen state, m^2 (>= 0).
        radius : float, default 1 - 1e-6
            Magnitude of the lines' eigenvalues, in (0, 1].

        Returns
        -------
        OscillatorModel
            The model, with read-only arrays.

        Raises
        ------
        InputError
            Wrong shapes, non-finite values, no line, dependent shapes, unseen directions that
            are not orthonormal and orthogonal to the shapes, values out of range.

        Examples
        --------
        >>> from powerline_control.identify import OscillatorModel
        >>> m = OscillatorModel.from_lines([3.0, 7.0], [[1.0, 0.0], [0.0, 1.0]], dt=0.01,
        ...                                n_pairs=50, process_noise=0.0)
        >>> m.n_lines, m.n_states, m.delays, m.alpha
        (2, 4, 2, 0.0)
        """
        dt = check_real("dt", dt, low=0.0, low_inclusive=False)
        f = check_array("frequencies", frequencies, ndim=1)
        phi = check_array("shapes", shapes, ndim=2)
        if f.size == 0:
            raise InputError("The 'frequencies' parameter must name at least one line: a model "
                             "of no line tracks nothing. Got none.")
        if phi.shape[1] != f.size:
            raise InputError(f"The 'shapes' parameter must have one column per line ({f.size});"
                             f" it has shape {phi.shape}.")
        if np.any(f < 0) or np.any(f > 0.5 / dt):
            raise InputError(f"The 'frequencies' parameter must lie in [0, {0.5 / dt:g}] Hz "
                             f"(the Nyquist band of dt = {dt:g} s); got {f.tolist()}.")
        n = phi.shape[0]
        u = (np.zeros((n, 0)) if unseen is None
             else check_array("unseen", unseen, ndim=2))
        if u.shape[0] != n:
            raise InputError(f"The 'unseen' parameter must have {n} rows (one per node); it "
                             f"has shape {u.shape}.")
        return cls._build(f, phi, u, dt,
                          n_pairs=check_int("n_pairs", n_pairs, low=1),
                          process_noise=check_real("process_noise", process_noise, low=0.0,
                                                   low_inclusive=True),
                          unseen_noise=check_real("unseen_noise", unseen_noise, low=0.0,
                                                  low_inclusive=True),
                          radius=check_real("radius", radius, low=0.0, high=1.0,
                                            low_inclusive=False))

    @classmethod
    def _build(cls, frequencies: np.ndarray, shapes: np.ndarray, unseen: np.ndarray, dt: float,
               *, n_pairs: int, process_noise: float, unseen_noise: float,
               radius: float) -> OscillatorModel:
        """:meth:`from_lines` on checked arguments (also the check of a loaded file)."""
        n, r = shapes.shape
        u = unseen.shape[1]
        q, upper = sla.qr(shapes, mode="economic")
        if r and np.abs(np.diag(upper)).min() <= 1e-12 * np.abs(upper).max():
            raise InputError("The 'shapes' parameter must have linearly independent columns: "
                             "two lines with one shape make the filter's Riccati equation "
                             "singular. Keep one of them.")
        if u:   # the field map [Q, 0, U] is a projection only for orthonormal [Q, U]
            gram_error = np.abs(unseen.T @ unseen - np.eye(u)).max()
            overlap = np.abs(q.T @ unseen).max() if r else 0.0
            if gram_error > _ORTHO_TOL or overlap > _ORTHO_TOL:
                raise InputError(
                    "The 'unseen' parameter must hold orthonormal directions orthogonal to the "
                    f"shapes' span (U^T U = I, Q^T U = 0 to {_ORTHO_TOL:g}). Got |U^T U - I| = "
                    f"{gram_error:.3g} and |Q^T U| = {overlap:.3g}; orthonormalise them against "
                    "the shapes first (e.g. scipy.linalg.null_space(shapes.T)).")
        # Each line's recursion acts on its own amplitude; in the orthonormal coordinates
        # b = Q^T x the amplitudes are R^-1 b, hence R diag(c1) R^-1 (a triangular solve).
        c1 = 2 * radius * np.cos(2 * np.pi * frequencies * dt)
        inv = sla.solve_triangular(upper, np.eye(r))
        lines = np.block([[upper @ (c1[:, None] * inv), -(radius**2) * np.eye(r)],
                          [np.eye(r), np.zeros((r, r))]])
        A = np.block([[lines, np.zeros((2 * r, u))], [np.zeros((u, 2 * r + u))]])
        basis = np.zeros((2 * n, 2 * r + u))
        basis[:n, :r] = q
        basis[n:, r:2 * r] = q
        basis[:n, 2 * r:] = unseen
        cov = np.zeros((2 * r + u, 2 * r + u))
        cov[:r, :r] = process_noise * np.eye(r)
        cov[2 * r:, 2 * r:] = unseen_noise * np.eye(u)
        return cls(
            A=read_only(A), B=None, dt=dt, alpha=0.0, alpha_relative=0.0, delays=2,
            rank=2 * r + u, n_nodes=n, field_map=read_only(np.hstack([q, np.zeros((n, r)),
                                                                      unseen])),
            basis=read_only(basis), residual_covariance=read_only(cov), n_pairs=n_pairs,
            initial_state=read_only(np.zeros(2 * r + u)),
            line_frequencies=read_only(np.array(frequencies, dtype=float)),
            line_shapes=read_only(np.array(shapes, dtype=float)),
            unseen=read_only(np.array(unseen, dtype=float)),
            process_noise=float(process_noise), unseen_noise=float(unseen_noise),
            radius=float(radius),
        )

    # --- what it is --------------------------------------------------------------------------

    @property
    def n_lines(self) -> int:
        """Number of spectral lines (oscillators)."""
        return int(self.line_frequencies.size)

    @property
    def n_unseen(self) -> int:
        """Number of unseen directions (white states)."""
        return int(self.unseen.shape[1])

    @property
    def state_names(self) -> list[str]:
        """``line{j}``, ``line{j}_lag1`` for each line, then ``unseen{i}``."""
        return ([f"line{j}" for j in range(self.n_lines)]
                + [f"line{j}_lag1" for j in range(self.n_lines)]
                + [f"unseen{i}" for i in range(self.n_unseen)])

    def describe(self) -> str:
        """The model in a few words: "oscillator model, N lines at ... Hz".

        Returns
        -------
        str
            One clause, no trailing period.

        Examples
        --------
        >>> from powerline_control.identify import OscillatorModel
        >>> OscillatorModel.from_lines([12.0, 18.25], [[1.0, 0.0], [0.0, 1.0]], dt=0.01,
        ...                            n_pairs=50, process_noise=0.0).describe()
        'oscillator model, 2 lines at 12 and 18.25 Hz'
        """
        count = f"{self.n_lines} line{'' if self.n_lines == 1 else 's'}"
        return f"oscillator model, {count} at {_hz_list(self.line_frequencies)}"

    def summary(self) -> str:
        """A few sentences: the lines, the white states, the noise, and what the model is not.

        Returns
        -------
        str
            Plain text.

        Examples
        --------
        >>> from powerline_control.identify import OscillatorModel
        >>> m = OscillatorModel.from_lines([5.0], [[1.0], [1.0]], dt=0.01, n_pairs=99,
        ...                                process_noise=1e-8)
        >>> print(m.summary())  # doctest: +NORMALIZE_WHITESPACE
        Oscillator model, 1 line at 5 Hz: one undamped oscillator per spectral line (eigenvalues
        at radius 1 - 1e-06), 0 white states for directions the lines leave out; 2 states,
        2 nodes, dt = 0.01 s, process noise 1e-08 m^2 per step on each line. Built from the
        record's spectral lines, not fitted.
        """
        text = self.describe()
        return (f"{text[0].upper()}{text[1:]}: one undamped oscillator per spectral line "
                f"(eigenvalues at radius 1 - {1.0 - self.radius:.3g}), {self.n_unseen} white "
                f"states for directions the lines leave out; {self.n_states} states, "
                f"{self.n_nodes} nodes, dt = {self.dt:g} s, process noise "
                f"{self.process_noise:.3g} m^2 per step on each line. Built from the record's "
                "spectral lines, not fitted.")

    def __repr__(self) -> str:
        return (f"OscillatorModel({self.describe()}; {self.n_states} states, {self.n_nodes} "
                f"nodes, dt = {self.dt:g} s)")

    # --- reports ------------------------------------------------------------------------------

    def stability_report(self, *, warn: bool = True) -> StabilityReport:
        """Stability of the oscillators, in words that say what the model is.

        Parameters
        ----------
        warn : bool, default True
            Emit an :class:`~powerline_control.errors.UnstableModelWarning` if it is unstable
            (only a hand-built radius above 1 could make it so).

        Returns
        -------
        StabilityReport
            Spectral radius, count outside the unit circle, ``alpha = 0`` and a message.

        Examples
        --------
        >>> from powerline_control.identify import OscillatorModel
        >>> m = OscillatorModel.from_lines([5.0], [[1.0]], dt=0.01, n_pairs=99,
        ...                                process_noise=0.0)
        >>> print(m.stability_report().message)  # doctest: +NORMALIZE_WHITESPACE
        Stable oscillator model, 1 line at 5 Hz: its 2 line eigenvalues lie on the circle of
        radius 1 - 1e-06 (undamped lines held just inside the unit circle, so that the filter's
        Riccati equation has a solution) and its 0 white states at 0.
        """
        rho, unstable = self.spectral_radius, self.n_unstable
        message = (f"its {2 * self.n_lines} line eigenvalues lie on the circle of radius "
                   f"1 - {1.0 - self.radius:.3g} (undamped lines held just inside the unit "
                   "circle, so that the filter's Riccati equation has a solution) and its "
                   f"{self.n_unseen} white states at 0.")
        if unstable == 0:
            message = f"Stable {self.describe()}: {message}"
        else:
            message = (f"Unstable {self.describe()}: {unstable} of {self.n_states} eigenvalues "
                       f"lie outside the unit circle (spectral radius {rho:.6g}); rebuild it "
                       "with a radius below 1.")
            if check_bool("warn", warn):
                warnings.warn(message, UnstableModelWarning, stacklevel=2)
        return StabilityReport(rho, unstable, self.n_states, 0.0, unstable == 0, message)

    def damping_report(self, *, warn: bool = False) -> DampingReport:
        """Say that the damping of the lines is assumed (zero), not identified.

        Parameters
        ----------
        warn : bool, default False
            Warn :class:`~powerline_control.errors.IllConditionedWarning` when the model has
            lines (their damping is never trusted: it was not measured).

        Returns
        -------
        DampingReport
            The (tiny) damping ratios of ``A``, zero regularisation shifts, the decays over the
            record, ``trusted`` all False, and a message.

        Examples
        --------
        >>> from powerline_control.identify import OscillatorModel
        >>> m = OscillatorModel.from_lines([5.0], [[1.0]], dt=0.01, n_pairs=99,
        ...                                process_noise=0.0)
        >>> report = m.damping_report()
        >>> report.trusted.tolist(), report.message.startswith("Oscillator model, 1 line at 5 Hz")
        ([False, False], True)
        """
        s = np.asarray(self.continuous_eigenvalues)
        message = (f"{self.describe()[0].upper()}{self.describe()[1:]}: undamped by "
                   "construction (eigenvalues at radius "
                   f"1 - {1.0 - self.radius:.3g}); its damping ratios are assumed, not "
                   "identified from the record. Fit a DMD model (method='dmd') on a record with "
                   "free decays to measure damping.")
        if check_bool("warn", warn) and self.n_lines:
            warnings.warn(message, IllConditionedWarning, stacklevel=2)
        return DampingReport(
            damping_ratio=read_only(np.asarray(self.damping_ratios, dtype=float)),
            regularisation_shift=read_only(np.zeros(self.n_states)),
            decay_over_record=read_only(np.abs(s.real) * self.n_pairs * self.dt),
            trusted=read_only(np.zeros(self.n_states, dtype=bool)),
            message=message,
        )


def _hz_list(frequencies: np.ndarray) -> str:
    """``"12, 18.3 and 25 Hz"``; a long list ends with "... (N in all)"."""
    values = [f"{float(f):.4g}" for f in frequencies]
    if not values:
        return "no frequency"
    if len(values) > _LISTED_LINES:
        return ", ".join(values[:_LISTED_LINES]) + f", ... Hz ({len(values)} in all)"
    if len(values) == 1:
        return f"{values[0]} Hz"
    return ", ".join(values[:-1]) + f" and {values[-1]} Hz"
