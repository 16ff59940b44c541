"""How many sensors, in a scenario: when the count study runs, the study, and its check's type.

:func:`sensor_count_skipped` says why the study does not run (the scenario gives the sensors,
or the model has more than :data:`SENSOR_COUNT_MAX_NODES` nodes). The pipeline's sensors stage
then runs the designed filter with each count's layout on the held-out record
(:func:`~powerline_control.scenario.stages.sensor_count_check`, a :class:`SensorCountCheck`), so
that the report's figure plots the table's own quantity (error at the unmeasured nodes, % of
the RMS displacement) as the filter predicts it and as it is measured; the report's "Sensor
placement" section and its JSON are :mod:`.summary_sensors`'s.
"""

from __future__ import annotations

import dataclasses

__all__ = ["SENSOR_COUNT_MAX_NODES", "SensorCountCheck", "sensor_count_skipped"]


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


def sensor_count_skipped(ident) -> str | None:
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


def _sensor_count(ident, model):
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
