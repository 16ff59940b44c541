"""What an identified model's spectrum says: is it stable, and can each damping be trusted.

:meth:`~powerline_control.identify.DMDModel.stability_report` and
:meth:`~powerline_control.identify.DMDModel.damping_report` return the reports defined here;
the work is done by the private functions below (the model's methods call them), so that the
model's own module keeps to its state, prediction and export.  The damping check compares the
first-order eigenvalue shift that Tikhonov's alpha causes with the damping itself, and the
decay over the training record with one e-fold.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla

from .._validation import check_bool, read_only
from ..errors import IllConditionedWarning, UnstableModelWarning

if TYPE_CHECKING:
    from .model import DMDModel


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
