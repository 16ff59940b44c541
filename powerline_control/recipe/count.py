"""How many sensors a span needs, measured on held-out data.

:func:`~powerline_control.sensors.sensor_count_study` answers from a model: the Kalman
criterion's predicted error, which is only as honest as the model. On a real span under a
broadband load the identified model is the weak part (a rank-30 model of hundreds of modes), so
the answer here is measured: for every sensor count, the whole recipe
(:func:`~powerline_control.recipe.design_estimator`) is trained on the first part of a record of
every node and judged on the rest, by the RMS error at the nodes it does not measure.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._validation import check_int, check_real, check_rng, read_only
from ..errors import ExcitationWarning, InputError
from .design import design_estimator

__all__ = ["EstimatorCountStudy", "estimator_count_study"]


@dataclass(frozen=True)
class EstimatorCountStudy:
    """Held-out error of the estimator against the number of sensors.

    Attributes
    ----------
    k : tuple of int
        Sensor counts studied.
    held_out_error : numpy.ndarray
        Per ``k``: RMS error at unmeasured moving nodes over the held-out part of the record,
        relative to the RMS displacement there, both with the sensor noise variance removed.
    reported_error : numpy.ndarray
        Per ``k``: the filter's reported RMS sigma at the same nodes, relative the same way.
    sensors : tuple of numpy.ndarray
        The layout chosen for each ``k`` (node indices).
    target_error : float
        The relative error asked for.
    smallest_k : int or None
        The smallest ``k`` whose held-out error is below ``target_error``; ``None`` when no
        count studied reaches it.
    message : str
        The answer in words: the count, or that the estimator cannot reach the target with
        these counts and this record (and the best it reached).

    Examples
    --------
    See :func:`estimator_count_study`.
    """

    k: tuple[int, ...]
    held_out_error: np.ndarray
    reported_error: np.ndarray
    sensors: tuple[np.ndarray, ...]
    target_error: float
    smallest_k: int | None
    message: str


def estimator_count_study(snapshots, k_values: Sequence[int], *, target_error: float = 0.1,
                          held_out_fraction: float = 0.3,
                          seed: int | np.random.Generator | None = 0,
                          **design_options: object) -> EstimatorCountStudy:
    """How many sensors for a target error, measured on the held-out end of a record.

    Parameters
    ----------
    snapshots : Snapshots
        A record of every node (simulated or measured), long enough to split.
    k_values : sequence of int
        Sensor counts to try, ascending.
    target_error : float, default 0.1
        Relative RMS error at unmeasured nodes to reach (0.1: 10 %).
    held_out_fraction : float, default 0.3
        Share of the record (its end) that judges each design; the rest trains it.
    seed : int, numpy.random.Generator or None, default 0
        Seed of :func:`~powerline_control.recipe.design_estimator` (its sensor selection's
        random baseline), as everywhere in the package: an int or a Generator, ``None`` for
        fresh entropy (the layouts and errors do not depend on it).
    **design_options
        Passed to :func:`~powerline_control.recipe.design_estimator` (``delays``, ``rank``,
        ``forbidden``, ...).

    Returns
    -------
    EstimatorCountStudy
        The error curve and the answer. A narrowband record warns as ``design_estimator``
        does (once).

    Raises
    ------
    InputError
        Bad arguments (named): counts not ascending, a target outside (0, 1], a split leaving
        either part too short.

    Examples
    --------
    >>> import warnings
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    >>> snap = plc.simulate(model, plc.RandomForce(1.0, 1.3, 80.0, seed=2), 4.0, 1e-3,
    ...                     noise_fraction=0.01, seed=0)
    >>> study = plc.estimator_count_study(snap, [2, 4], delays=4, rank=12)
    >>> study.k, study.held_out_error.shape
    ((2, 4), (2,))
    """
    # None is fresh entropy (check_rng's rule), drawn once and shared by every count's design;
    # an int is passed on as given, so each count's design sees the same seed.
    rng = check_rng(seed)
    if seed is None:
        seed = rng
    try:
        x_all = np.asarray(snapshots.displacement, dtype=float)
        dt = float(snapshots.dt)
        noise = float(getattr(snapshots, "noise_std", math.nan))
    except AttributeError:
        raise InputError("The 'snapshots' parameter must be a Snapshots record of every node "
                         f"(with .displacement and .dt). Got {type(snapshots).__name__}."
                         ) from None
    if isinstance(k_values, str) or not isinstance(k_values, Sequence | np.ndarray):
        raise InputError(f"The 'k_values' parameter must be a sequence of sensor counts. Got "
                         f"{k_values!r}.")
    ks = [check_int("k_values", k, low=1, high=x_all.shape[0]) for k in list(k_values)]
    if not ks or sorted(set(ks)) != ks:
        raise InputError("The 'k_values' parameter must be a non-empty ascending sequence of "
                         f"distinct integers. Got {list(k_values)!r}.")
    target_error = check_real("target_error", target_error, low=0.0, high=1.0)
    held_out_fraction = check_real("held_out_fraction", held_out_fraction, low=0.0, high=1.0,
                                   high_inclusive=False)
    n = x_all.shape[1]
    n_fit = int(round((1 - held_out_fraction) * n))
    if n_fit < 200 or n - n_fit < 200:
        raise InputError(f"The record of {n} samples split at held_out_fraction="
                         f"{held_out_fraction} leaves fewer than 200 samples in one part.")
    train = x_all[:, :n_fit]
    held = x_all[:, n_fit:]
    positions = getattr(snapshots, "x", None)
    given_noise = {"noise_std": noise} if math.isfinite(noise) and noise > 0 else {}
    errors, reported, layouts = [], [], []
    warned = False
    for k in ks:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ExcitationWarning)
            design = design_estimator(train, n_sensors=k, dt=dt, seed=seed,
                                      positions=positions, **given_noise, **design_options)
        if not warned:
            for w in caught:
                warnings.warn(w.message, w.category, stacklevel=2)
                warned = True
        sigma = noise if given_noise else design.noise_std
        est = design.filter.filter(held[design.sensors])
        rms = np.sqrt(np.mean(held**2, axis=1))
        moving = np.flatnonzero(rms > 1e-6 * rms.max())
        unmeasured = np.setdiff1d(moving, design.sensors)
        skip = min(200, held.shape[1] // 4)  # the filter's transient from its prior
        truth = held[unmeasured, skip:]
        err2 = float(np.mean((est.field[unmeasured, skip:] - truth) ** 2)) - sigma**2
        sig2 = float(np.mean(truth**2)) - sigma**2
        scale = math.sqrt(max(sig2, 1e-300))
        errors.append(math.sqrt(max(err2, 0.0)) / scale)
        reported.append(float(np.sqrt(np.mean(est.field_variances[unmeasured, skip:]))) / scale)
        layouts.append(read_only(np.array(design.sensors)))
    reached = [k for k, e in zip(ks, errors, strict=True) if e <= target_error]
    smallest = reached[0] if reached else None
    if smallest is not None:
        message = (f"{smallest} sensors reach {100 * errors[ks.index(smallest)]:.3g} % at the "
                   f"unmeasured nodes of the held-out record (target {100 * target_error:.3g} %).")
    else:
        best = int(np.argmin(errors))
        message = (f"No count studied ({ks[0]}-{ks[-1]} sensors) reaches {100 * target_error:.3g}"
                   f" %: the best is {100 * errors[best]:.3g} % with {ks[best]} sensors. This "
                   "record and recipe cannot give that accuracy; more sensors, a longer record or "
                   "a richer model (rank, delays) are needed.")
    return EstimatorCountStudy(k=tuple(ks), held_out_error=read_only(np.array(errors)),
                               reported_error=read_only(np.array(reported)),
                               sensors=tuple(layouts), target_error=float(target_error),
                               smallest_k=smallest, message=message)
