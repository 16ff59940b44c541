"""Clamp bending amplitude and strain from an estimated field.

The fatigue engineer's quantity (design.md 4.7): the bending amplitude ``Y_b``, the peak-to-peak
displacement 89 mm from the last point of contact at the clamp relative to the clamp, and the
clamp stress and strain it gives by Poffenberger-Swart. Here it comes from the sensors through
the estimator: the estimated field at ``x_b``, its RMS as the peak-to-peak of a harmonic
(aeolian lock-in is one tone), and its sigma from the filter's field variances. The
Poffenberger-Swart conversion is the severity stage's (``aeolian_severity``'s stress and strain
per unit ``Y_b``, read from a one-wind-speed call): it is a linear map, so the relative error and
sigma of the stress and strain are those of ``Y_b``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .._validation import check_array, check_choice, check_int, check_real, read_only
from ..errors import InputError
from ..line import Span
from ._common import POFFENBERGER_SWART_DISTANCE
from .balance import aeolian_severity

__all__ = ["ClampStrainEstimate", "estimate_clamp_strain"]


@dataclass(frozen=True, eq=False)
class ClampStrainEstimate:
    """Estimated clamp bending amplitude, stress and strain with their sigma.

    Attributes
    ----------
    bending_amplitude : float
        ``Y_b``, m peak-to-peak: ``2 sqrt(2)`` times the RMS of the estimated displacement at
        ``x_b`` from the clamp (the peak-to-peak of a harmonic with that RMS).
    bending_sigma : float
        Its standard deviation, m: ``2 sqrt(2)`` times the filter's RMS sigma at ``x_b`` (an
        error of that RMS in phase with the vibration; an upper bound for one out of phase).
    stress : float
        Idealised outer-strand stress amplitude (zero-to-peak) at the clamp, Pa, by
        Poffenberger-Swart (``K Y_b``).
    stress_sigma : float
        ``K`` times ``bending_sigma``, Pa.
    strain_pp : float
        Peak-to-peak bending strain at the clamp, ``2 stress / E_a``.
    strain_sigma : float
        Its standard deviation.
    x_b : float
        Distance from the clamp, m (default 0.089, IEEE 1960).
    side : str
        "left" (x = 0) or "right" (x = L).
    displacement : numpy.ndarray
        The estimated displacement at ``x_b`` over the record, m ``(n_t,)``.

    Examples
    --------
    See :func:`estimate_clamp_strain`.
    """

    bending_amplitude: float
    bending_sigma: float
    stress: float
    stress_sigma: float
    strain_pp: float
    strain_sigma: float
    x_b: float
    side: str
    displacement: np.ndarray


def _at(values: np.ndarray, positions: np.ndarray, x: float, p: float) -> np.ndarray:
    """Rows of ``values`` (one per node) at distance ``x`` from the clamp at ``positions[0]``.

    Inside the first element the clamp's boundary layer is resolved by its shape,
    ``y ~ s (x - (1 - exp(-p x)) / p)`` with ``p = sqrt(T / EI)`` (the taut beam's static
    solution next to a clamp, design.md 4.5), scaled to the first interior node; further out,
    linear interpolation between the bracketing nodes (a mesh graded toward the clamp).
    """
    d = np.abs(positions - positions[0])
    if x <= d[1]:
        def g(s):
            return s - (-math.expm1(-p * s)) / p
        return values[1] * (g(x) / g(d[1]))
    j = int(np.searchsorted(d, x))
    w = (x - d[j - 1]) / (d[j] - d[j - 1])
    return (1 - w) * values[j - 1] + w * values[j]


def _clamped_nodes(positions: object, side: str, design_supports: object) -> object:
    """The node positions of ``positions``; the ``side`` support must be clamped, in the
    LineModel given as ``positions`` and in the line the design was trained on (when known)."""
    from ..fem import LineModel

    if design_supports is not None:
        bc = design_supports[0 if side == "left" else 1]
        if bc != "clamped":
            raise InputError(
                f"The 'design' parameter was trained on a line with supports "
                f"{tuple(design_supports)} (EstimatorDesign.supports): the {side} one is {bc}, "
                "but a clamp's bending amplitude needs a clamped support (a pinned end has no "
                "bending at it). Train the design on LineModel(span, bc='clamped'), or give "
                "the clamped side.")
    if not isinstance(positions, LineModel):
        return positions
    bc = positions.bc[0 if side == "left" else 1]
    if bc != "clamped":
        raise InputError(
            f"The 'positions' parameter is a model with supports {positions.bc}: the {side} "
            f"one is {bc}, but a clamp's bending amplitude needs a clamped support (a pinned "
            "end has no bending at it). Train the design on LineModel(span, bc='clamped'), or "
            "give the clamped side.")
    return positions.node_positions


def estimate_clamp_strain(design, measurements: object, span: Span, positions: object, *,
                          side: str = "left", x_b: float = POFFENBERGER_SWART_DISTANCE,
                          discard: int = 0, outer_strand_diameter: float | None = None
                          ) -> ClampStrainEstimate:
    """Clamp bending amplitude ``Y_b`` and strain from the sensors, with sigma.

    Parameters
    ----------
    design : EstimatorDesign
        The estimator (:func:`~powerline_control.recipe.design_estimator`), trained on the
        span's nodes at ``positions``.
    measurements : array_like, shape (n_sensors, n_t)
        A record of the design's sensors, m; finite (NaN is refused: a missing sample would be
        the filter's prediction averaged into ``Y_b``; cut the record around gaps).
    span : Span
        The span (tension and conductor for Poffenberger-Swart); its supports must be clamped.
    positions : LineModel or array_like, shape (n_nodes,)
        The line model the design was trained on (its supports are then checked: the
        ``side`` must be clamped), or its node positions, m (``model.node_positions``: from 0
        to the span's length). With bare positions the supports are checked on the design
        (``EstimatorDesign.supports``: the training Snapshots' or the nominal span's); a design
        trained on a measured array does not know them, so pass the LineModel to have them
        checked.
    side : {"left", "right"}
        The clamp: x = 0 or x = L.
    x_b : float
        Distance from the last point of contact, m (default 0.089).
    discard : int
        Leading samples left out (the filter's transient, a record ringing up).
    outer_strand_diameter : float, optional
        Outer strand diameter, m; default the severity stage's for the conductor.

    Returns
    -------
    ClampStrainEstimate

    Raises
    ------
    InputError
        Bad arguments, named: a ``design`` that is not an EstimatorDesign, a ``span`` that is
        not a Span, NaN or infinite measurements, positions of the wrong shape, not ascending
        or not from 0 to the span's length, a model (or a design's training line) whose
        ``side`` is not clamped, ``x_b``
        outside the first half of the span, ``discard`` leaving no samples.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import powerline_control as plc
    >>> span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> model = plc.LineModel(span, bc="clamped", max_frequency=8.0)
    >>> load = [plc.HarmonicForce(5.0, 3.0, 61.0), plc.RandomForce(1.0, 130.0, 6.0, seed=1)]
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     train = plc.simulate(model, load, 12.0, 4e-3, noise_fraction=0.01, seed=0)
    ...     design = plc.design_estimator(train, n_sensors=5, seed=0)
    ...     clamp = plc.severity.estimate_clamp_strain(design, train.displacement[design.sensors],
    ...                                       span, model.node_positions, discard=500)
    >>> bool(clamp.bending_amplitude > 0 and clamp.strain_sigma > 0)
    True
    """
    from ..recipe import EstimatorDesign  # recipe imports the estimator stack: import on use

    if not isinstance(design, EstimatorDesign):
        raise InputError(
            "The 'design' parameter must be an EstimatorDesign (from design_estimator). Got "
            f"{design!r:.60} of type {type(design).__name__} instead."
        )
    if not isinstance(span, Span):
        raise InputError(
            "The 'span' parameter must be a Span (e.g. Span.at_rts_fraction(300.0, 'drake', "
            f"0.2)). Got {span!r:.60} of type {type(span).__name__} instead."
        )
    side = check_choice("side", side, ("left", "right"))
    x = check_array("positions",
                    _clamped_nodes(positions, side, getattr(design, "supports", None)), ndim=1)
    if x.size != design.n_nodes or np.any(np.diff(x) <= 0):
        raise InputError(
            f"The 'positions' parameter must hold the design's {design.n_nodes} node positions "
            f"in ascending order (model.node_positions). Got {x.size} values"
            f"{'' if x.size < 2 or np.all(np.diff(x) > 0) else ', not ascending'}."
        )
    tol = 1e-9 * span.length   # round-off of a mesh's summed element lengths
    if abs(x[0]) > tol or abs(x[-1] - span.length) > tol:
        raise InputError(
            f"The 'positions' parameter must hold the span's node positions, from 0 to its "
            f"length {span.length:g} m (model.node_positions of the model the design was "
            f"trained on). Got {x[0]:g} to {x[-1]:g} m.")
    x_b = check_real("x_b", x_b, low=0.0, high=float(x[-1] - x[0]) / 2)
    # Every sample is a measurement: a NaN (a dropout) would be filled by the filter's
    # prediction and averaged into Y_b as if measured.
    y = check_array("measurements", measurements, ndim=2)
    discard = check_int("discard", discard, low=0, high=y.shape[1] - 1)
    est = design.filter.filter(y)
    field, variances = np.asarray(est.field), np.asarray(est.field_variances)
    order = slice(None) if side == "left" else slice(None, None, -1)
    p = math.sqrt(span.tension / span.conductor.ei)
    y_b = _at(field[order], x[order], x_b, p)
    # The sigma of a node's estimate scales as its value does (inside the first element by the
    # clamp shape, linearly between nodes): interpolate the standard deviation.
    sigma = _at(np.sqrt(np.maximum(variances[order], 0.0)), x[order], x_b, p)
    amplitude = 2 * math.sqrt(2) * float(np.sqrt(np.mean(y_b[discard:] ** 2)))
    amp_sigma = 2 * math.sqrt(2) * float(np.sqrt(np.mean(sigma[discard:] ** 2)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # only the conversion factors are read
        kwargs = {} if outer_strand_diameter is None else {
            "outer_strand_diameter": outer_strand_diameter}
        if span.conductor.rated_strength is None:
            # Only the ratio stress / Y_b (Poffenberger-Swart: linear) is read; the self-damping
            # law sets the amplitude only, so any k serves where the conductor has no rated
            # strength to normalise one (the paper's lab conductor).
            kwargs["self_damping_k"] = 1.0
        sev = aeolian_severity(span, wind_speeds=[3.0], x_b=x_b, bc="clamped", **kwargs)
    yb_ref = float(sev.bending_amplitude[0])
    if not yb_ref > 0:
        raise InputError("The span's severity gives no bending amplitude to convert with "
                         "(zero vibration at 3 m/s); cannot convert Y_b to stress.")
    k_stress = float(sev.stress_ps[0]) / yb_ref
    k_strain = float(sev.strain_pp[0]) / yb_ref
    return ClampStrainEstimate(
        bending_amplitude=amplitude, bending_sigma=amp_sigma,
        stress=k_stress * amplitude, stress_sigma=k_stress * amp_sigma,
        strain_pp=k_strain * amplitude, strain_sigma=k_strain * amp_sigma,
        x_b=float(x_b), side=side, displacement=read_only(y_b.copy()),
    )
