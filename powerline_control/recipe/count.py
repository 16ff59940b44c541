"""How many sensors a span needs, measured on held-out data.

:func:`~powerline_control.sensors.sensor_count_study` answers from a model: the Kalman
criterion's predicted error, which is only as honest as the model. On a real span under a
broadband load the identified model is the weak part (a rank-30 model of hundreds of modes), so
the answer here is measured: for every sensor count, the whole recipe
(:func:`~powerline_control.recipe.design_estimator`) is trained on the first part of a record of
every node and judged on the rest, by the RMS error at the nodes it does not measure.

The rest of one record is the continuation of the load histories the model was fitted on: a
line whose modes ring longer than the record (real spans; the simulated ones are undamped) keeps
the same modal amplitudes into it, so it understates the error on a new load history (Drake
300 m, 24 sensors: 9.5 % held out, 16-30 % on three new runs). ``check`` records of other load
histories judge the design that ships (trained on the whole record) where that matters.

Two designs per count, then: the one trained on the first part of the record (its layout is
``sensors``; ``held_out_error`` and ``reported_error`` judge it) and, with check records, the one
trained on the whole record (its layout is ``shipped_sensors``; ``check_error`` judges it). Each
error has the noise variance of the record it is measured on removed: the training record's for
the held-out part, each check record's own for that record.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._validation import (
    check_forwarded_options,
    check_int,
    check_real,
    check_rng,
    read_only,
)
from ..errors import ExcitationWarning, InputError
from .design import design_estimator
from .record import _other_records

__all__ = ["EstimatorCountStudy", "estimator_count_study"]


@dataclass(frozen=True, eq=False)
class EstimatorCountStudy:
    """Held-out error of the estimator against the number of sensors.

    Attributes
    ----------
    k : tuple of int
        Sensor counts studied.
    held_out_error : numpy.ndarray
        Per ``k``: RMS error at unmeasured moving nodes over the held-out part of the record,
        relative to the RMS displacement there, both with the sensor noise variance removed, of
        the design trained on the first part of the record (layout ``sensors``).
    reported_error : numpy.ndarray
        Per ``k``: that design's reported RMS sigma at the same nodes, relative the same way.
    sensors : tuple of numpy.ndarray
        Per ``k``: the layout (node indices) of the design trained on the first part of the
        record, the one ``held_out_error`` and ``reported_error`` judge. The design trained on
        the whole record may choose another (``shipped_sensors``).
    target_error : float
        The relative error asked for.
    smallest_k : int or None
        The smallest ``k`` whose held-out error, and every ``check_error`` when there are check
        records, is below ``target_error``; ``None`` when no count studied reaches it.
    message : str
        The answer in words: the count, or that the estimator cannot reach the target with
        these counts and this record (and the best it reached); without check records, that
        the count is measured on the training record's own continuation only.
    check_error : numpy.ndarray or None
        ``(len(k), n_check)``: per ``k``, the error of the design trained on the whole record
        (the one :func:`~powerline_control.recipe.design_estimator` would ship, layout
        ``shipped_sensors``) on each check record, measured as ``held_out_error`` with that
        check record's own noise variance (``check_noise_std``) removed; ``None`` without check
        records.
    shipped_sensors : tuple of numpy.ndarray or None
        Per ``k``: the layout of the design trained on the whole record, the one
        ``check_error`` judges (what ``design_estimator(snapshots, n_sensors=k)`` returns with
        the same options); ``None`` without check records.
    check_noise_std : tuple of float or None
        The sensor noise std (m) removed from each check record's error: given, the record's
        own ``noise_std``, or estimated from its singular values; ``None`` without check
        records.

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
    check_error: np.ndarray | None = None
    shipped_sensors: tuple[np.ndarray, ...] | None = None
    check_noise_std: tuple[float, ...] | None = None


def estimator_count_study(snapshots, k_values: Sequence[int], *, target_error: float = 0.1,
                          held_out_fraction: float = 0.3, check=None, check_noise_std=None,
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
    check : Snapshots or sequence of Snapshots, optional
        Records of every node under other load histories (independent runs: new random loads,
        another day), at the same node positions and sample time. Each count's design trained
        on the whole of ``snapshots`` is also judged on each, and a count is named only if it
        reaches the target on all of them and on the held-out part. Without them the answer
        rests on the continuation of the training record, which on a line that rings longer than
        the record understates the error on new loads (module docstring).
    check_noise_std : float or sequence of float, optional
        Sensor noise std (m) of the check records, one for all or one per record; its variance
        is removed from each record's error. Default: each record's own ``noise_std`` when it
        has one (a :class:`~powerline_control.simulation.Snapshots`), else estimated from the
        noise floor of its singular values (as the recipe estimates the training record's).
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
        either part too short, a check record that is not a record of the same node positions
        and sample time, check noise levels that are not one non-negative number per record.

    Examples
    --------
    >>> import warnings
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    >>> snap = plc.simulate(model, plc.RandomForce(1.0, 1.3, 80.0, seed=2), 4.0, 1e-3,
    ...                     noise_fraction=0.01, seed=0)
    >>> study = plc.recipe.estimator_count_study(snap, [2, 4], delays=4, rank=12)
    >>> study.k, study.held_out_error.shape
    ((2, 4), (2,))
    """
    design_options = check_forwarded_options(
        estimator_count_study, design_options, design_estimator,
        set_here=("snapshots", "n_sensors", "dt", "positions"),
        why="the training part of 'snapshots', each count of 'k_values', the record's dt and "
            "positions")
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
    if given_noise and "noise_std" in design_options:
        raise InputError(
            f"The 'noise_std' option cannot be passed to estimator_count_study with a record "
            f"that states its own noise_std ({noise:g}): the record's is used. Drop the option, "
            "or pass a record without noise_std.")
    checks, check_sigmas = _other_records(check, "check", positions, x_all.shape[0], dt,
                                          noise_std=check_noise_std,
                                          noise_name="check_noise_std")
    errors, reported, layouts, shipped_layouts, check_errors = [], [], [], [], []
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
        error, sigma_reported = _judge(design, held, sigma)
        errors.append(error)
        reported.append(sigma_reported)
        layouts.append(read_only(np.array(design.sensors)))
        if checks:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ExcitationWarning)  # warned once above
                shipped = design_estimator(x_all, n_sensors=k, dt=dt, seed=seed,
                                           positions=positions, **given_noise,
                                           **design_options)
            shipped_layouts.append(read_only(np.array(shipped.sensors)))
            check_errors.append([_judge(shipped, rec, rec_sigma)[0]
                                 for rec, rec_sigma in zip(checks, check_sigmas, strict=True)])
    passed = [e <= target_error and all(c <= target_error for c in (check_errors[i]
                                                                     if checks else []))
              for i, e in enumerate(errors)]
    smallest = next((k for k, ok in zip(ks, passed, strict=True) if ok), None)
    worst = [max([e, *(check_errors[i] if checks else [])]) for i, e in enumerate(errors)]
    where = (f"the held-out record and {len(checks)} check record(s) of other load histories"
             if checks else "the held-out record")
    if smallest is not None:
        i = ks.index(smallest)
        message = (f"{smallest} sensors reach {100 * worst[i]:.3g} % at the unmeasured nodes of "
                   f"{where} (target {100 * target_error:.3g} %).")
        if not checks:
            message += (" Measured on the continuation of the training record only, which "
                        "understates the error on new load histories when the line's modes ring "
                        "longer than the record: pass check= records of other loads to confirm "
                        "the count.")
    else:
        best = int(np.argmin(worst))
        message = (f"No count studied ({ks[0]}-{ks[-1]} sensors) reaches {100 * target_error:.3g}"
                   f" % on {where}: the best is {100 * worst[best]:.3g} % with {ks[best]} "
                   "sensors. This record and recipe cannot give that accuracy; more sensors, a "
                   "longer record or a richer model (rank, delays) are needed.")
    return EstimatorCountStudy(k=tuple(ks), held_out_error=read_only(np.array(errors)),
                               reported_error=read_only(np.array(reported)),
                               sensors=tuple(layouts), target_error=float(target_error),
                               smallest_k=smallest, message=message,
                               check_error=read_only(np.array(check_errors)) if checks
                               else None,
                               shipped_sensors=tuple(shipped_layouts) if checks else None,
                               check_noise_std=tuple(check_sigmas) if checks else None)


def _judge(design, record: np.ndarray, sigma: float) -> tuple[float, float]:
    """(actual, reported) RMS error of ``design`` filtering ``record`` (every node) at its
    unmeasured moving nodes, relative to the RMS field there, the noise variance ``sigma^2``
    removed from both, after the filter's transient from its prior."""
    est = design.filter.filter(record[design.sensors])
    rms = np.sqrt(np.mean(record**2, axis=1))
    moving = np.flatnonzero(rms > 1e-6 * rms.max())
    unmeasured = np.setdiff1d(moving, design.sensors)
    skip = min(200, record.shape[1] // 4)  # the filter's transient from its prior
    truth = record[unmeasured, skip:]
    err2 = float(np.mean((est.field[unmeasured, skip:] - truth) ** 2)) - sigma**2
    scale = math.sqrt(max(float(np.mean(truth**2)) - sigma**2, 1e-300))
    return (math.sqrt(max(err2, 0.0)) / scale,
            float(np.sqrt(np.mean(est.field_variances[unmeasured, skip:]))) / scale)
