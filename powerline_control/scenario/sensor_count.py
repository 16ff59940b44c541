"""Sensors in a scenario's report, and how many: when the count study runs, its layouts run
on the held-out record like the estimation table's, the "Sensor placement" section and its JSON.

:func:`sensor_count_skipped` says why the study does not run (the scenario gives the sensors,
or the model has more than :data:`SENSOR_COUNT_MAX_NODES` nodes); :func:`sensor_count_check`
runs the designed filter with each count's layout on the held-out record, once per study, so
that the figure plots the table's own quantity (error at the unmeasured nodes, % of the RMS
displacement) as the filter predicts it and as it is measured.
"""

from __future__ import annotations

import dataclasses
import functools
import weakref

from .result import Identification, Records
from .stages import _held_out_discard, layout_filter

__all__ = ["SENSOR_COUNT_MAX_NODES", "SensorCountCheck", "sensor_count_check",
           "sensor_count_skipped", "sensors_section", "sensor_count_json"]


#: Largest node count for which the sensor-count study (one optimisation per count) runs.
SENSOR_COUNT_MAX_NODES = 201


@dataclasses.dataclass(frozen=True)
class SensorCountCheck:
    """The sensor-count study's layouts run like the table's: the designed filter on the
    held-out record, error at the nodes without a sensor, % of the held-out RMS displacement.

    Attributes
    ----------
    k : tuple of int
        Sensor counts (the study's).
    layouts : tuple of tuple of int
        The nodes measured at each count: the study's optimised layout, except at the recipe's
        own count, where it is the recipe's chosen layout (the table's "chosen" row).
    predicted_percent : tuple of float
        What the filter predicts: the RMS of its own error standard deviation (its covariance,
        mapped to the nodes) over the unmeasured nodes.
    measured_percent : tuple of float
        What it achieves: the RMS of (estimate - FE truth) over the unmeasured nodes; at the
        recipe's count it is the table's error at unmeasured nodes.
    chosen_k : int
        The recipe's sensor count.
    """

    k: tuple
    layouts: tuple
    predicted_percent: tuple
    measured_percent: tuple
    chosen_k: int


# id(study) -> (a weak reference to the study, its check): the study's fields are arrays, so it
# has no hash; an entry whose study is gone is dropped by the reference's callback.
_SENSOR_COUNT_CHECKS: dict = {}


def sensor_count_check(result) -> SensorCountCheck | None:
    """The sensor-count study of ``result`` run on its held-out record (None: no study).

    Computed once per study (the report, the JSON and the summary all read it).
    """
    study = getattr(result, "sensor_count", None)
    if study is None or result.records is None or result.identification is None:
        return None
    key = id(study)
    entry = _SENSOR_COUNT_CHECKS.get(key)
    if entry is None or entry[0]() is not study:
        check = _check_sensor_count(study, result.records, result.identification)
        reference = weakref.ref(study, lambda _, key=key: _SENSOR_COUNT_CHECKS.pop(key, None))
        entry = _SENSOR_COUNT_CHECKS[key] = (reference, check)
    return entry[1]


def _check_sensor_count(study, records: Records, ident: Identification) -> SensorCountCheck:
    import numpy as np

    from ..estimate import estimation_accuracy

    snap, held = records.test, slice(records.n_train, None)
    truth = snap.true_displacement[:, held]
    discard = _held_out_discard(records)
    chosen = [int(i) for i in ident.design.sensors]   # as the table's layout (_layouts)
    layouts, predicted, measured = [], [], []
    for k, nodes in zip(study.k, study.layouts, strict=True):
        nodes = chosen if k == len(chosen) else sorted(int(i) for i in nodes)
        estimate = layout_filter(ident.design, nodes).filter(snap.displacement[nodes, held])
        accuracy = estimation_accuracy(estimate.field, truth, measured=nodes, discard=discard)
        unmeasured = np.ones(truth.shape[0], dtype=bool)
        unmeasured[nodes] = False
        variance = np.asarray(estimate.field_variances)[unmeasured, discard:]
        layouts.append(tuple(nodes))
        predicted.append(100.0 * float(np.sqrt(np.mean(variance))) / accuracy.rms_truth)
        measured.append(100.0 * float(accuracy.relative_rms_error_unmeasured))
    return SensorCountCheck(k=tuple(int(k) for k in study.k), layouts=tuple(layouts),
                            predicted_percent=tuple(predicted),
                            measured_percent=tuple(measured), chosen_k=len(chosen))


def sensor_count_skipped(ident: Identification) -> str | None:
    """Why the sensor-count study does not run on this identification (None: it runs).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> big = SimpleNamespace(sensors_given=False,
    ...                       design=SimpleNamespace(model=SimpleNamespace(n_nodes=840)))
    >>> sensor_count_skipped(big)
    'the model has 840 nodes, above the 201 the study runs on, one sensor optimisation per count'
    """
    if ident.sensors_given:
        return "the scenario gives the sensor positions"
    n_nodes = int(ident.design.model.n_nodes)
    if n_nodes > SENSOR_COUNT_MAX_NODES:
        return (f"the model has {n_nodes} nodes, above the {SENSOR_COUNT_MAX_NODES} the study "
                "runs on, one sensor optimisation per count")
    return None


def _sensor_count(ident: Identification, model):
    """The predicted steady-state error against the sensor count (None when skipped: see
    :func:`sensor_count_skipped`)."""
    import numpy as np

    from ..sensors import sensor_count_study

    design = ident.design
    n_nodes = design.model.n_nodes
    if sensor_count_skipped(ident) is not None:
        return None
    dmd = design.model
    q = np.array(dmd.residual_covariance)
    q[np.diag_indices_from(q)] += design.q_floor
    scale = design.covariance_scale
    k = int(design.sensors.size)
    return sensor_count_study(dmd.to_statespace(measured=list(range(n_nodes))),
                              list(range(1, k + 3)), Q=scale * q,
                              R=scale * float(design.noise_std) ** 2,
                              positions=np.asarray(model.node_positions),
                              forbidden=ident.forbidden, n_steps=500)


def sensors_section(r) -> dict:
    """The report's "Sensor placement" section: the layout, its certificate, the count study."""
    from .summary import positions_text as _positions_text
    ident = r.identification
    d = ident.design
    x = r.records.test.x
    nodes = [int(i) for i in d.sensors]
    rows = [("sensors", _positions_text([x[i] for i in nodes], nodes), ident.sensors_how)]
    selection = d.sensor_selection
    if selection is not None and not ident.sensors_given:
        k = len(nodes)
        if selection.certificate == "exhaustive" or selection.gap == 0:
            text = f"{selection.certificate}: proved the best of all layouts of {k} sensors"
        else:
            text = (f"{selection.certificate}: the chosen layout's criterion is at most "
                    f"{100 * selection.gap:.2g} % above the best possible layout of {k} sensors")
        rows.append(("optimality certificate", text,
                     "The relaxation gives a bound no layout can beat; the gap says how far the "
                     "chosen layout can be from the best possible one, at most."))
    rows += _count_row(r)
    return {"title": "Sensor placement", "rows": rows, "figures": _count_figure(r)}


def _count_row(r) -> list:
    """The report row saying the study was not run, and why (empty when it ran)."""
    skipped = _skipped(r)
    if skipped is None:
        return []
    return [("how many sensors", f"not studied: {skipped}",
             "The sensor-count study optimises one layout per count; the chosen layout above "
             "is still optimised.")]


def _count_figure(r) -> list:
    """The "how many sensors" figure (a list of one, or empty without a study)."""
    from .summary import _figure, _plotting  # the report's figure spec and plotting module

    check = sensor_count_check(r)
    if check is None:
        return []
    draw = functools.partial(
        _plotting().plot_sensor_count, list(check.k), list(check.predicted_percent),
        list(check.measured_percent), percent=True, chosen=check.chosen_k,
        labels=("predicted by the filter (its covariance)", "measured on held-out data"),
        ylabel="RMS error at unmeasured nodes\n(% of RMS displacement over the span)")
    at = check.k.index(check.chosen_k) if check.chosen_k in check.k else None
    same = ("" if at is None else
            f" At {check.chosen_k} sensors (the recipe's layout) the measured curve is the "
            f"table's error at unmeasured nodes, {check.measured_percent[at]:.3g} %; the "
            f"filter predicted {check.predicted_percent[at]:.3g} %.")
    return [_figure("sensor_count", draw,
                    "How many sensors: for each count, the layout optimised for it (by the "
                    "filter's predicted steady-state error), and the designed filter run on the "
                    "held-out record with those sensors: its error at the nodes without a sensor "
                    "as the filter predicts it from its own covariance, and as measured against "
                    "the simulated truth, both % of the held-out RMS displacement over the span "
                    "(the estimation table's definition)." + same,
                    "where the measured curve flattens: more sensors than that buy little; and "
                    "how far the prediction sits from it")]


def sensor_count_json(r) -> dict:
    """summary.json's ``sensor_count`` entry (empty when its stage did not run)."""
    skipped = _skipped(r)
    if skipped is not None:
        return {"sensor_count": {"studied": False, "reason": skipped}}
    if r.sensor_count is None:
        return {}
    check = sensor_count_check(r)
    return {"sensor_count": {
        "studied": True, "n_sensors": [int(k) for k in r.sensor_count.k],
        # the study's criterion: the predicted RMS error per state of the model (its reduced
        # coordinates), m; the two below are the estimation table's quantity
        "predicted_rms_error_m": [float(v) for v in r.sensor_count.rms_error],
        "sensor_nodes": [list(nodes) for nodes in check.layouts],
        "predicted_error_unmeasured_percent": [float(v) for v in check.predicted_percent],
        "error_unmeasured_percent": [float(v) for v in check.measured_percent]}}


def _skipped(r) -> str | None:
    """Why the study was not run although its stage was (None: it ran, or its stage was not
    asked for or failed)."""
    if r.sensor_count is not None or r.identification is None or "sensors" not in r.stages \
            or (r.failure is not None and r.failure.stage == "sensors"):
        return None
    return sensor_count_skipped(r.identification)
