"""The report's "Sensor placement" section and its JSON: the layout, its certificate, and how
many sensors (the count study and its check on the held-out record, as the pipeline ran them).

Used by :func:`~.summary.result_sections` and :func:`~.summary_json.result_json`.
"""

from __future__ import annotations

import functools

from .sensor_count import sensor_count_skipped
from .summary_format import _figure, _plotting, positions_text

__all__ = ["sensors_section", "sensor_count_json"]


def sensors_section(r) -> dict:
    """The report's "Sensor placement" section: the layout, its certificate, the count study."""
    ident = r.identification
    d = ident.design
    x = r.records.test.x
    nodes = [int(i) for i in d.sensors]
    rows = [("sensors", positions_text([x[i] for i in nodes], nodes), ident.sensors_how)]
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
    check = r.sensor_count_check
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
    check = r.sensor_count_check
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
