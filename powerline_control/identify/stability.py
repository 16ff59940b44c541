"""What an identified model's spectrum says: is it stable, and can each damping be trusted.

:meth:`~powerline_control.identify.DMDModel.stability_report` and
:meth:`~powerline_control.identify.DMDModel.damping_report` return the reports defined here
(the model computes them: this module knows nothing of the model, so the two do not import each
other).  The damping check compares the first-order eigenvalue shift that Tikhonov's alpha causes
with the damping itself, and the decay over the training record with one e-fold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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



def _spectral_order(values: np.ndarray) -> np.ndarray:
    """Decreasing magnitude; a conjugate pair with positive imaginary part first."""
    return np.lexsort((-values.imag, -np.round(np.abs(values), 12)))
