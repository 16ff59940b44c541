"""Which nodes of a scenario carry sensors: the scenario's own, evenly spaced baselines (moved
off a mode's nodes where that is fairer), and the closed loop's, each with where it came from.

Used by the pipeline's stages (:mod:`.stages`) and the calibration verb (:mod:`.calibrate`).
"""

from __future__ import annotations

from ..errors import InputError
from .config import Scenario
from .files import load_scenario  # noqa: F401 (doctests)

__all__ = ["closed_loop_sensors", "evenly_spaced_nodes", "given_sensors", "scenario_sensors"]


def given_sensors(scenario: Scenario, x) -> tuple[list | None, str]:
    """The scenario's own sensors as node indices (None when they are to be chosen).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    x : array_like
        Node positions, m.

    Returns
    -------
    (list of int or None, str)
        The nodes and where they came from.

    Examples
    --------
    >>> s = load_scenario(text="[model]\\nn_elements = 4\\n[estimation]\\n"
    ...                        "sensor_positions = [1.0]")
    >>> given_sensors(s, [0.0, 0.915, 1.83, 2.745, 3.66])
    ([1], 'from the scenario (positions, nearest nodes)')
    """
    import numpy as np

    est = scenario.estimation
    x = np.asarray(x, dtype=float)
    if est.sensors is not None:
        return sorted(int(i) for i in est.sensors), "from the scenario (node indices)"
    if est.sensor_positions is not None:
        return _nearest_distinct_nodes(est.sensor_positions, x), \
            "from the scenario (positions, nearest nodes)"
    return None, ""


def scenario_sensors(scenario: Scenario, x) -> list:
    """The scenario's own sensors as node indices, or evenly spaced ones
    (``estimation.n_sensors`` of them) when it lists none: the closed loop's and the
    calibration's sensors when no sensor choice ran.

    Parameters
    ----------
    scenario : Scenario
        Its ``estimation`` section.
    x : array_like
        Node positions, m.

    Returns
    -------
    list of int

    Examples
    --------
    >>> import numpy as np
    >>> scenario_sensors(load_scenario(text="[estimation]\\nn_sensors = 2"),
    ...                  np.linspace(0.0, 3.0, 31))
    [10, 20]
    """
    import numpy as np

    x = np.asarray(x, dtype=float)
    given, _ = given_sensors(scenario, x)
    return given if given is not None else evenly_spaced_nodes(x, scenario.estimation.n_sensors)


def closed_loop_sensors(scenario: Scenario, x, identification=None) -> tuple[list, str]:
    """The closed loop's sensors as node indices, and where they came from, in words.

    The estimator's sensors when the identification stage ran (optimised, or the scenario's
    own); else the scenario's own, or evenly spaced ones: the ``closed-loop`` verb runs no
    identification, so it has no optimised layout to read (``run`` has).

    Parameters
    ----------
    scenario : Scenario
        Its ``estimation`` section.
    x : array_like
        Node positions, m.
    identification : Identification or None
        The identification stage's result, when it ran.

    Returns
    -------
    (list of int, str)

    Examples
    --------
    >>> import numpy as np
    >>> nodes, how = closed_loop_sensors(load_scenario(text="[estimation]\\nn_sensors = 2"),
    ...                                  np.linspace(0.0, 3.0, 31))
    >>> nodes, how.split(":")[0]
    ([10, 20], 'evenly spaced')
    """
    if identification is not None:
        return ([int(i) for i in identification.design.sensors],
                f"the estimator's sensors, {identification.sensors_how}")
    given, how = given_sensors(scenario, x)
    if given is not None:
        return given, how
    return (scenario_sensors(scenario, x),
            "evenly spaced: this verb runs no sensor choice (the run verb gives the closed loop "
            "the optimised sensors)")


def _nearest_distinct_nodes(positions, x) -> list:
    """Each position's nearest node, refusing two positions on one node.

    Merging them would silently give the user one sensor fewer than asked for.
    """
    import numpy as np

    nodes: dict[int, float] = {}
    for p in positions:
        node = int(np.argmin(np.abs(x - p)))
        if node in (0, x.size - 1):   # a support: the line never moves there
            raise InputError(
                f"'estimation.sensor_positions': {p:g} m falls on the support node at "
                f"{x[node]:g} m (the element beside it is {_spacing_beside(x, node)} long), "
                "where the line never moves; give a position at least half an element inside "
                "the span or a finer mesh ('model.n_elements').")
        if node in nodes:
            raise InputError(
                f"'estimation.sensor_positions': {nodes[node]:g} m and {p:g} m both fall on "
                f"the node at {x[node]:g} m (the elements beside it are "
                f"{_spacing_beside(x, node)} long); give positions on different nodes or a "
                f"finer mesh ('model.n_elements').")
        nodes[node] = float(p)
    return sorted(nodes)


def _spacing_beside(x, node: int) -> str:
    """The lengths of the elements on either side of ``node``, in words."""
    lengths = [x[j + 1] - x[j] for j in (node - 1, node) if 0 <= j < len(x) - 1]
    return " and ".join(f"{length:.3g} m" for length in lengths)


def evenly_spaced_nodes(x, k: int, shape=None) -> list:
    """k sensors evenly spaced between the supports, optionally moved off a mode's nodes.

    With ``shape`` (a mode shape at the nodes) the whole evenly spaced layout is shifted, by
    less than half its spacing, to the offset whose smallest |shape| at the sensors is largest:
    the layout stays evenly spaced but no sensor sits on a vibration node of that mode.

    Parameters
    ----------
    x : array_like
        Node positions, m.
    k : int
        Number of sensors.
    shape : array_like or None
        A mode shape at the nodes.

    Returns
    -------
    list of int
        Node indices, ascending.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.linspace(0.0, 3.0, 31)
    >>> evenly_spaced_nodes(x, 2)
    [10, 20]
    >>> evenly_spaced_nodes(x, 2, np.sin(3 * np.pi * x / 3.0))   # mode 3's nodes: 1 m, 2 m
    [15, 25]
    """
    import numpy as np

    x = np.asarray(x, dtype=float)
    length = x[-1]
    base = length * np.arange(1, k + 1) / (k + 1)
    if shape is None:
        offsets = [0.0]
    else:
        spacing = length / (k + 1)
        offsets = np.linspace(-0.5 * spacing, 0.5 * spacing, 41)
        offsets = offsets[np.argsort(np.abs(offsets), kind="stable")]
        shape = np.abs(np.asarray(shape, dtype=float))
    best, best_score = None, -1.0
    for offset in offsets:
        nodes = np.clip(np.searchsorted(x, base + offset), 1, x.size - 2)
        nodes = [int(i) if abs(x[i] - p) <= abs(x[i - 1] - p) else int(i - 1)
                 for i, p in zip(nodes, base + offset, strict=True)]
        nodes = sorted(set(min(max(i, 1), x.size - 2) for i in nodes))
        if len(nodes) < k:
            continue
        score = 1.0 if shape is None else float(shape[nodes].min() / max(shape.max(), 1e-300))
        if score > best_score + 1e-9:
            best, best_score = nodes, score
    return best if best is not None else list(range(1, k + 1))
