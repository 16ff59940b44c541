"""The physics model of a calibrated span: :class:`SpanModel` and :func:`span_model`.

A narrowband record (aeolian lock-in: one tone, a standing wave) teaches a data-driven model the
field it saw at the places it was measured, and little of the field between them or of the same
wind a little faster: the standing wave's wavelength moves with the tone. The line's own modes
carry it: the forced field at any frequency in the band is a combination of the modes near it,
with the shapes the tension and bending stiffness give. :func:`span_model` writes that model down
from a :class:`~powerline_control.identify.SpanCalibration` (the span the record explains, from
:func:`~powerline_control.identify.calibrate_span`): the modes of the calibrated span nearest each
of the record's spectral lines, one lightly damped oscillator each, their shapes at the record's
node positions. It is an :class:`~powerline_control.identify.OscillatorModel` (every consumer
takes it unchanged) that also says which span and modes it holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .._validation import check_array, check_int, check_real, read_only
from ..errors import InputError
from ..fem import LineModel
from .calibration import SpanCalibration
from .oscillator import OscillatorModel, _hz_list

#: Modal damping ratio of the model's modes when none is given: a light line (conductor
#: self-damping is 0.05-0.5 % in the aeolian band, ``docs/validation/physics_candidate.md``).
DEFAULT_DAMPING_RATIO = 1e-3
#: Modes kept on each side of the mode nearest each spectral line by default.
DEFAULT_MODES_PER_SIDE = 2
#: Relative frequency accuracy of the model's mesh at its band top: the standing wave's phase
#: over a span of a hundred loops must not drift by the mesh (1 % would move it by a loop).
MESH_TOLERANCE = 1e-4
#: Band top of the mesh, over the highest mode kept.
MESH_MARGIN = 1.3
#: The lift in lock-in follows the standing wave at the tone (``AeolianForce``: ``sin(k x +
#: offset)``, ``k`` the taut beam's wavenumber at the tone); the model's process noise is that
#: load with its wavenumber anywhere within this share of ``k`` (a wind a few per cent faster or
#: slower), on LOCK_IN_PATTERNS wavenumbers.
LOCK_IN_BAND = 0.02
LOCK_IN_PATTERNS = 9


@dataclass(frozen=True, eq=False, repr=False)
class SpanModel(OscillatorModel):
    """The modes of a calibrated span near a record's spectral lines, one oscillator each.

    Build it with :func:`span_model`. An :class:`OscillatorModel` whose lines are the natural
    frequencies of the calibrated span's modes and whose line shapes are those modes at the
    record's nodes; every mode shares one eigenvalue radius, ``exp(-zeta omega_c dt)`` at the
    modes' mean angular frequency ``omega_c``.

    Attributes
    ----------
    calibration : SpanCalibration
        The span the model was built from (tension, EI and their uncertainty).
    mode_numbers : ndarray of int
        The modes kept (1 = the fundamental), ascending.
    damping_ratio : float
        Modal damping ratio the radius was set from.

    Other attributes are those of :class:`OscillatorModel` (``line_frequencies``: the modes'
    natural frequencies, Hz; ``line_shapes``: their shapes at the nodes, unit peak).

    Examples
    --------
    See :func:`span_model`.
    """

    calibration: SpanCalibration | None = field(kw_only=True, default=None)
    mode_numbers: np.ndarray | None = field(kw_only=True, default=None, repr=False)
    damping_ratio: float = field(kw_only=True, default=DEFAULT_DAMPING_RATIO)

    def describe(self) -> str:
        """The model in a few words: "physics model of the calibrated span (...), N modes at ...".

        Returns
        -------
        str
            One clause, no trailing period.

        Examples
        --------
        See :func:`span_model`.
        """
        modes = "" if self.mode_numbers is None else (
            f" {int(self.mode_numbers[0])}-{int(self.mode_numbers[-1])}")
        told = "" if self.calibration is None else (
            f" ({self.calibration.span.length:g} m, tension {self.calibration.tension:.6g} N)")
        return (f"physics model of the calibrated span{told}, modes{modes} at "
                f"{_hz_list(self.line_frequencies)}")

    def __repr__(self) -> str:
        return (f"SpanModel({self.describe()}; {self.n_states} states, {self.n_nodes} nodes, "
                f"dt = {self.dt:g} s)")


def span_model(calibration: SpanCalibration, positions: object, dt: float, *, n_pairs: int,
               process_noise: float, modes_per_side: int = DEFAULT_MODES_PER_SIDE,
               damping_ratio: float = DEFAULT_DAMPING_RATIO,
               lock_in: float | None = None) -> SpanModel:
    """The calibrated span's modes near the record's lines, as a discrete-time model.

    Meshes the calibrated span (its supports, a mesh accurate to :data:`MESH_TOLERANCE` up to
    :data:`MESH_MARGIN` times the highest mode kept), keeps for each spectral line of the
    calibration the mode nearest it and ``modes_per_side`` on either side, and builds one
    oscillator per mode (:meth:`OscillatorModel.from_lines`) with the modes' shapes at
    ``positions`` as its field map. The process noise (the unknown load) drives each mode alike
    and independently; with ``lock_in`` it is the lift of a wind in lock-in at that tone
    instead, a load along the span shaped as the standing wave at the tone, ``sin(kappa x)``
    and ``cos(kappa x)`` with ``kappa`` within :data:`LOCK_IN_BAND` of the calibrated span's
    wavenumber there: the modes it drives move together, so that a few sensors tell the
    standing wave between them from the modes' other combinations.

    Parameters
    ----------
    calibration : SpanCalibration
        From :func:`calibrate_span` on the record (never the true span of a simulation: the
        nominal span corrected by what the record shows).
    positions : array_like, shape (n_nodes,)
        Positions (m) of the nodes the model's field is given at, on the span.
    dt : float
        Sample time, s.
    n_pairs : int
        Snapshot pairs of the record the calibration read (>= 1).
    process_noise : float
        Variance added per step to each mode's coordinate, m^2 (>= 0).
    modes_per_side : int, default 2
        Modes kept on each side of the mode nearest each line (>= 0).
    damping_ratio : float, default 1e-3
        Modal damping ratio of every mode, in [0, 0.5).
    lock_in : float, optional
        The tone of a wind in lock-in, Hz (> 0): the process noise follows its standing wave
        (above); its trace per mode stays ``process_noise``.

    Returns
    -------
    SpanModel

    Raises
    ------
    InputError
        A calibration that is not one, positions off the span, or values out of range.

    Examples
    --------
    The lab span, its tension calibrated from a record of three sensors under a sine at
    18.3 Hz (with the start-up ringing of the modes beside it: several lines); the model holds
    each line's nearest mode and one on either side, its field at 21 nodes:

    >>> import warnings, numpy as np, powerline_control as plc
    >>> from powerline_control.errors import CalibrationWarning
    >>> from powerline_control.identify import span_model
    >>> line = plc.LineModel(plc.Span.paper_lab(), 40, damping=plc.ModalDamping(0.005))
    >>> snap = plc.simulate(line, plc.HarmonicForce(1.0, 18.3, 1.1), 10.0, 1e-3,
    ...                     noise_fraction=0.01, seed=1)
    >>> rec = plc.Record(snap.t, snap.x[[7, 16, 29]], snap.displacement[[7, 16, 29]])
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", CalibrationWarning)
    ...     cal = plc.calibrate_span(rec, plc.Span.paper_lab())
    >>> model = span_model(cal, np.linspace(0, 3.66, 21), 1e-3, n_pairs=9999,
    ...                    process_noise=1e-12, modes_per_side=1)
    >>> model.mode_numbers.tolist(), model.n_nodes
    ([1, 2, 3, 4, 5], 21)
    >>> model.describe()[:44]
    'physics model of the calibrated span (3.66 m'
    """
    if not isinstance(calibration, SpanCalibration):
        raise InputError("The 'calibration' parameter must be a SpanCalibration (from "
                         f"calibrate_span). Got {type(calibration).__name__}.")
    x = check_array("positions", positions, ndim=1)
    dt = check_real("dt", dt, low=0.0, low_inclusive=False)
    n_pairs = check_int("n_pairs", n_pairs, low=1)
    process_noise = check_real("process_noise", process_noise, low=0.0, low_inclusive=True)
    modes_per_side = check_int("modes_per_side", modes_per_side, low=0, high=50)
    damping_ratio = check_real("damping_ratio", damping_ratio, low=0.0, high=0.5,
                               low_inclusive=True, high_inclusive=False)
    if lock_in is not None:
        lock_in = check_real("lock_in", lock_in, low=0.0)
    span = calibration.span
    if x.size == 0 or np.any(x < 0) or np.any(x > span.length):
        raise InputError(f"The 'positions' parameter must hold positions on the span, 0 to "
                         f"{span.length:g} m. Got {x.size} positions from "
                         f"{x.min() if x.size else math.nan:g} to "
                         f"{x.max() if x.size else math.nan:g} m.")
    lines = np.asarray(calibration.line_frequencies, dtype=float)
    numbers = np.asarray(calibration.mode_numbers, dtype=int)
    top_mode = int(numbers.max()) + modes_per_side
    top = MESH_MARGIN * float(span.pinned_frequencies(top_mode + 1)[-1])
    top = min(top, 0.5 / dt)
    line = LineModel(span, None, bc=calibration.bc, max_frequency=top,
                     frequency_tolerance=MESH_TOLERANCE)
    basis = line.modes_below(top)
    f = basis.frequencies
    kept: set[int] = set()
    for frequency in lines:
        j = int(np.argmin(np.abs(f - frequency)))
        kept.update(range(max(0, j - modes_per_side), min(f.size, j + modes_per_side + 1)))
    idx = np.array(sorted(kept))
    shapes = np.asarray(basis.shapes)[:, idx]
    index, weights = line.shape_rows(x)
    rows = np.einsum("pk,pkr->pr", weights, np.where(index[..., None] >= 0,
                                                      shapes[np.maximum(index, 0)], 0.0))
    rows = rows / np.abs(rows).max(axis=0)
    omega_c = float(np.mean(2 * np.pi * f[idx]))
    radius = math.exp(-damping_ratio * omega_c * dt)
    model = SpanModel.from_lines(f[idx], rows, dt, n_pairs=n_pairs, process_noise=process_noise,
                                 radius=min(radius, 1.0 - 1e-6))
    extra = {}
    if lock_in is not None:
        extra["residual_covariance"] = read_only(_lock_in_noise(model, span, x, lock_in,
                                                                process_noise))
    return replace(model, calibration=calibration, mode_numbers=read_only(idx + 1),
                   damping_ratio=float(damping_ratio), **extra)


def _lock_in_noise(model: SpanModel, span, x: np.ndarray, tone: float,
                   process_noise: float) -> np.ndarray:
    """The model's process-noise covariance when the load is a wind in lock-in at ``tone`` Hz
    (:func:`span_model`): the modes' generalised forces from the standing-wave patterns
    (trapezoid weights over ``x``), in the model's line coordinates ``Q^T x``, scaled to a
    trace of ``process_noise`` per mode."""
    k = float(span.wavenumber(tone))
    kappa = k * np.linspace(1 - LOCK_IN_BAND, 1 + LOCK_IN_BAND, LOCK_IN_PATTERNS)
    order = np.argsort(x, kind="stable")
    weights = np.zeros(x.size)
    if x.size > 1:
        weights[order] = np.gradient(x[order])
    patterns = np.hstack([np.sin(np.outer(x, kappa)), np.cos(np.outer(x, kappa))])
    forces = model.line_shapes.T @ (patterns * weights[:, None])       # (r, patterns)
    _, upper = np.linalg.qr(model.line_shapes)
    lines = upper @ forces
    cov_lines = lines @ lines.T
    r = model.n_lines
    trace = float(np.trace(cov_lines))
    cov = np.array(model.residual_covariance)
    cov[:r, :r] = (process_noise * r / trace) * cov_lines if trace > 0 else 0.0
    return cov
