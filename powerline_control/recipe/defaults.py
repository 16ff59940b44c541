"""The recipe's defaults and thresholds, each with the reason for its value.

The public defaults of :func:`~powerline_control.recipe.design_estimator` (delays, ranks,
process noise) and the private thresholds its steps share: what counts as narrowband, as
round-off, as a motionless node, and the bounds of the noise and of the learned scales.
"""

from __future__ import annotations

import numpy as np

from .._validation import check_budget

#: Default number of stacked snapshots (the model state spans delays * dt of history).
DEFAULT_DELAYS = 8
#: Default POD rank of the delay-embedded model.
DEFAULT_RANK = 30
#: Default fraction of the record the model is fitted on (the rest is held out for alpha).
DEFAULT_TRAIN_FRACTION = 0.7
#: Largest number of spatial POD coordinates kept before delay embedding.
DEFAULT_SPATIAL_RANK = 24
#: Modal model: process noise per step and line coordinate, in sensor-noise variances.
DEFAULT_PROCESS_NOISE = 1.0
#: A record is narrowband when fewer than this fraction of its frequency bins rise above the
#: noise (spectral lines occupy a few bins each; broadband excitation tens of %).
_NARROWBAND_OCCUPANCY = 0.05
#: ... and when removing its lines leaves at most this multiple of the noise variance.
_NARROWBAND_RESIDUAL = 1.5
#: Most spectral lines extracted (each costs a few DTFTs of the record).
_MAX_LINES = 60
#: Modal model: smooth directions outside the lines' shapes, appended as white states with this
#: many sensor-noise variances (what a narrowband record never showed, fitted to each sample).
_UNSEEN_COUNT = 8
_UNSEEN_NOISE = 100.0
#: Relative alphas of the held-out sweep (0 first: exact on clean data, no damping bias).
_DEFAULT_ALPHAS = np.array([0.0, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2])
#: Factor between the alphas appended when the best one sits at the top of the sweep, and the
#: largest relative alpha the widening reaches.
_ALPHA_WIDEN = 100.0
_ALPHA_CAP = 1.0
#: Process-noise floor of the filter, as a fraction of the data's mean square (see _steady_filter).
_Q_FLOOR_FRACTION = 1e-10
# A sensor noise a million times the record's RMS carries no information, and its square (R)
# would overflow long before the bound (noise_std=1e300 raised a raw OverflowError).
_NOISE_TO_RMS_MAX = 1e6
_NOISE_STD_MAX = 1e100  # without a record's RMS to compare with: R = noise_std**2 stays finite
#: Radius that eigenvalues outside the unit circle are pulled to (see _stabilise).
_STABLE_RADIUS = 1.0 - 1e-6
#: Spatial POD coordinates below this fraction of the largest singular value are round-off.
_ROUND_OFF_FRACTION = 1e-7
#: Nodes whose training RMS is below this fraction of the largest never move (supports).
_MOTIONLESS_FRACTION = 1e-6


# Bounds of the field-variance scale of the model-error fit (dmd._field_error_model): a factor
# 10 on the sigma either way.
_FIELD_SCALE_MIN, _FIELD_SCALE_MAX = 1e-2, 1e2


def record_parts(n_samples: int, train_fraction: float) -> tuple[int, int]:
    """(training, held-out) samples of a record of ``n_samples``."""
    n_fit = int(round(train_fraction * n_samples))
    return n_fit, n_samples - n_fit


def parts_too_short(n_samples: int, delays: int, train_fraction: float) -> bool:
    """True when a part of the record holds fewer than 4 x delays samples (the delay embedding
    of each needs a few times its depth to fit or score a model)."""
    return min(record_parts(n_samples, train_fraction)) < 4 * delays


def shortest_record(delays: int = DEFAULT_DELAYS,
                    train_fraction: float = DEFAULT_TRAIN_FRACTION) -> int:
    """Fewest samples :func:`~powerline_control.recipe.design_estimator` accepts.

    Examples
    --------
    >>> shortest_record()
    106
    """
    if not 0.0 < train_fraction < 1.0:
        raise ValueError(f"train_fraction must lie in (0, 1), got {train_fraction!r}")
    n = 8 * delays
    while parts_too_short(n, delays, train_fraction):
        n += 1
    return n


def check_record_work(n_nodes: int, n_samples: int, *, parameter: str, value: object, fix: str,
                      what: str = "design_estimator's spatial Gram matrix and projection",
                      spatial_rank: int = DEFAULT_SPATIAL_RANK,
                      delays: int = DEFAULT_DELAYS) -> None:
    """Refuse a record of ``n_nodes`` x ``n_samples`` that the recipe's budget would refuse.

    The one estimate of :func:`~powerline_control.recipe.design_estimator`'s first step (the
    spatial Gram matrix of the record, ``2 n_nodes^2 n_samples`` operations, and its
    projection), checked by :func:`design_estimator` itself and, before the record exists, by
    whoever would simulate a record only to hand it to the recipe (the closed loop's calibration
    run, the scenario's records), each naming its own parameter.

    Parameters
    ----------
    n_nodes, n_samples : int
        The record's size: nodes (rows) and samples (columns) the recipe will receive.
    parameter, value, fix : str, object, str
        The caller's parameter that sets the size, its value, and how to reduce it.
    what : str
        What would do the work, for the message.
    spatial_rank, delays : int
        The recipe's ``spatial_rank`` and ``delays`` (its defaults unless given).

    Raises
    ------
    InputError
        The estimate exceeds the memory or work budget (see ``docs/conventions.md``).

    Examples
    --------
    >>> check_record_work(101, 2000, parameter="snapshots", value="shape (101, 2000)",
    ...                   fix="use fewer nodes or a shorter record")
    >>> check_record_work(20001, 1800, parameter="n_elements", value=20000,
    ...                   fix="use a coarser mesh")
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: design_estimator's spatial Gram matrix and projection \
would need about 1.4e+12 floating-point operations (the 'n_elements' parameter is 20000), over \
the budget of 1e+12. To fix: use a coarser mesh, or raise the budget (the environment variable \
POWERLINE_CONTROL_WORK_BUDGET, set before importing powerline_control).
    """
    check_budget(
        what,
        nbytes=8.0 * (min(n_nodes, n_samples) ** 2 + 3 * spatial_rank * delays * n_samples),
        flops=2.0 * n_nodes * n_nodes * n_samples,
        parameter=parameter, value=value, fix=fix,
    )
