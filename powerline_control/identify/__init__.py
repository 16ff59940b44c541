"""Identification, data -> model: DMDModel and its stability and damping reports, fit_dmd and its
ridge routes, alpha selection (select_alpha, AlphaCurve), OnlineDMD and OscillatorModel.

The paper identifies a discrete-time linear model ``x_{k+1} = A x_k`` of the nodal displacements
by Dynamic Mode Decomposition, ``A = X' X^+`` (its eq. 11), and stabilises it by Tikhonov
regularisation, ``A = X' X^T (X X^T + alpha I)^{-1}`` (eq. 14).  This subpackage computes both
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

* :class:`OscillatorModel`: the model of a narrowband record, one undamped oscillator per
  spectral line (built, not fitted; a DMDModel subclass, so every consumer takes it).

Every model keeps :attr:`DMDModel.field_map`, the map from its state to the *current* nodal
displacements, and exports itself as a discrete :class:`control.StateSpace`.

Modules: :mod:`.model` (DMDModel), :mod:`.stability` (StabilityReport, DampingReport),
:mod:`.fit` (fit_dmd), :mod:`._ridge` (the ridge solve), :mod:`.alpha` (select_alpha,
AlphaCurve), :mod:`.online` (OnlineDMD), :mod:`.oscillator` (OscillatorModel),
:mod:`.calibration` (calibrate_span, SpanCalibration: the physics model's tension and EI from a
record), :mod:`.span_model` (span_model, SpanModel: the calibrated span's modes as a model).
"""

from .alpha import AlphaCurve, select_alpha
from .calibration import SpanCalibration, calibrate_span
from .fit import fit_dmd
from .model import DMDModel
from .online import OnlineDMD
from .oscillator import OscillatorModel
from .span_model import SpanModel, span_model
from .stability import DampingReport, StabilityReport

__all__ = [
    "DMDModel",
    "OscillatorModel",
    "StabilityReport",
    "DampingReport",
    "AlphaCurve",
    "OnlineDMD",
    "fit_dmd",
    "select_alpha",
    "SpanCalibration",
    "calibrate_span",
    "SpanModel",
    "span_model",
]
