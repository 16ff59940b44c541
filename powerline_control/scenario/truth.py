"""The line's truth: how the simulated line differs from the span the engineer knows.

A scenario's ``[span]`` and ``[model]`` sections are the nominal: what an engineer is told of the
line (catalogue conductor, length, supports, the stringing tension) and models it with. The
``[truth]`` section says how the line really is on the day simulated: the conductor's
temperature moves the tension by several per cent (the change of state,
:func:`~powerline_control.line.tension_at_temperature`), a stranded conductor's bending
stiffness is known only to a factor, its mass and damping differ from the catalogue's. Every
key is optional; without the section the truth is the nominal.

Which stage uses which (design.md 4.7): every stage that simulates (the records, the
identification run, the closed loop's plant) runs on the true line (:func:`true_model`); the
stages that predict from what is known (the model's natural frequencies reported as nominal, the
robot's tuning, the plan, the severity study's energy balance, the closed loop's controller,
which calibrates the span from its records) use the nominal. The true span of a scenario has one
home, :func:`true_span`.

The ``[truth]`` section itself (:class:`TruthConfig`) is part of the schema in
:mod:`~powerline_control.scenario.config`; :func:`check_truth`, its cross-checks against the
nominal span, runs when a file is read (:mod:`.files`). Standard library only at import time.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from ..errors import InputError
from .config import Scenario, TruthConfig

if TYPE_CHECKING:  # pragma: no cover
    from ..fem import LineModel
    from ..line import Span

__all__ = ["TruthConfig", "true_span", "true_model", "on_nodes"]   # TruthConfig: the schema's

#: The conductor properties the change of state needs (a ``truth.temperature`` needs them all).
CHANGE_OF_STATE = ("area", "elastic_modulus", "thermal_expansion")


def _check_scenario(scenario: object, where: str) -> None:
    if not isinstance(scenario, Scenario):
        hint = (f" (load it first: {where}(load_scenario({scenario!r}), ...))"
                if isinstance(scenario, str) else "")
        raise InputError(f"The 'scenario' parameter of {where} must be a Scenario "
                         f"(load_scenario). Got {type(scenario).__name__}{hint}.")


def _check_own_span(scenario: Scenario, span: Span, where: str, what: str) -> None:
    """``span`` must be the scenario's own ``[span]`` as built: [truth] changes that one."""
    built = scenario.span.build()
    if span != built:
        raise InputError(
            f"The 'nominal' parameter of {where} must be the scenario's own {what} (its span: "
            f"scenario.span.build(), {built.length:g} m at {built.tension:.6g} N), which "
            f"[truth] changes. Got one of another span ({span.length:g} m at "
            f"{span.tension:.6g} N): build it from the scenario, or change its [span] section.")


def true_span(scenario: Scenario, nominal: Span | None = None) -> Span:
    """The span the scenario's line really is: the nominal ``[span]`` changed by ``[truth]``.

    The one home of a scenario's true span. Its tension is the nominal span's change of state
    to ``truth.temperature`` from ``truth.stringing_temperature``
    (:func:`~powerline_control.line.tension_at_temperature`), or ``truth.tension_factor`` times
    the nominal; its conductor's EI and mass are the catalogue's times ``truth.ei_factor`` and
    ``truth.mass_factor``. Without a change it is the nominal span itself.

    Parameters
    ----------
    scenario : Scenario
        Its ``span`` and ``truth`` sections.
    nominal : Span or None
        The nominal span when already built (``scenario.span.build()``; None builds it).

    Returns
    -------
    Span

    Raises
    ------
    InputError
        If ``scenario`` is not a Scenario, or ``nominal`` is neither None nor the scenario's
        own span (a span of another line has no truth here).

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> warm = load_scenario(text="[span]\\npreset = 'conductor'\\n[truth]\\ntemperature = 35.0")
    >>> round(true_span(warm).tension), round(warm.span.build().tension)   # 35 against 15 degC
    (25003, 28020)
    >>> lab = load_scenario(text="[truth]\\ntension_factor = 0.97")
    >>> round(true_span(lab).tension, 2)
    383.15
    """
    _check_scenario(scenario, "true_span")
    from ..line import Span

    if nominal is None:
        nominal = scenario.span.build()
    elif not isinstance(nominal, Span):
        raise InputError(
            "The 'nominal' parameter of true_span must be None or the scenario's span as built "
            f"(scenario.span.build()). Got {type(nominal).__name__}.")
    else:
        _check_own_span(scenario, nominal, "true_span", "span")
    truth = scenario.truth
    tension = nominal.tension
    if truth.temperature is not None:
        from ..line import tension_at_temperature

        tension = float(tension_at_temperature(
            nominal, truth.temperature, reference_temperature=truth.stringing_temperature))
    elif truth.tension_factor is not None:
        tension = truth.tension_factor * nominal.tension
    conductor = nominal.conductor
    if truth.ei_factor != 1.0 or truth.mass_factor != 1.0:
        conductor = dataclasses.replace(
            conductor, ei=truth.ei_factor * conductor.ei,
            mass_per_length=truth.mass_factor * conductor.mass_per_length)
    if tension == nominal.tension and conductor is nominal.conductor:
        return nominal
    return dataclasses.replace(nominal, tension=tension, conductor=conductor)


def true_model(scenario: Scenario, nominal: LineModel) -> LineModel:
    """The line simulated: the true span meshed as the nominal model is, with the true damping.

    The same number of equal elements when the nominal mesh is uniform (so the two share their
    nodes, and a node index means one place on both), else the physics mesh of the true span
    for the nominal's band (graded toward clamps); the same supports; the modal damping
    ``truth.damping_ratio`` (unset: the nominal model's). Without a change it is ``nominal``
    itself.

    Parameters
    ----------
    scenario : Scenario
        Its ``truth`` section.
    nominal : LineModel
        The nominal model (``scenario.model.build(scenario.span.build())``).

    Returns
    -------
    LineModel

    Raises
    ------
    InputError
        If ``scenario`` is not a Scenario, or ``nominal`` is not a LineModel of the scenario's
        own span.

    Examples
    --------
    >>> import numpy as np
    >>> from powerline_control.scenario import load_scenario
    >>> s = load_scenario(text="[model]\\nn_elements = 20\\n[truth]\\ntension_factor = 1.05")
    >>> nominal = s.model.build(s.span.build())
    >>> truth = true_model(s, nominal)
    >>> bool(np.array_equal(truth.node_positions, nominal.node_positions))
    True
    >>> # 5 % more tension: sqrt(1.05) = 1.025 on a string, a little less with EI's share
    >>> round(float(truth.natural_frequencies(1)[0] / nominal.natural_frequencies(1)[0]), 3)
    1.023
    """
    import warnings

    import numpy as np

    from ..errors import TruncationWarning
    from ..fem import LineModel

    _check_scenario(scenario, "true_model")
    if not isinstance(nominal, LineModel):
        raise InputError(
            "The 'nominal' parameter of true_model must be the scenario's nominal LineModel "
            "(scenario.model.build(scenario.span.build())). Got "
            f"{type(nominal).__name__}.")
    _check_own_span(scenario, nominal.span, "true_model", "nominal LineModel")
    span = true_span(scenario, nominal.span)
    ratio = scenario.truth.damping_ratio
    if span == nominal.span and (ratio is None or ratio == scenario.model.damping_ratio):
        return nominal
    damping = nominal.damping if ratio is None else scenario.model.damping(ratio)
    with warnings.catch_warnings():
        # the nominal model gave the mesh's warnings when it was built
        warnings.simplefilter("ignore", TruncationWarning)
        if np.ptp(np.asarray(nominal.element_lengths)) <= 1e-12 * nominal.span.length:
            return LineModel(span, nominal.n_elements, nominal.bc, damping=damping)
        return LineModel(span, None, nominal.bc, damping=damping,
                         max_frequency=nominal.max_frequency,
                         frequency_tolerance=nominal.frequency_tolerance)


def check_truth(check, scenario: Scenario, given: dict) -> None:
    """Cross-checks of the ``[truth]`` section that need the nominal span (``check``: the file's
    checker, which collects every problem): the temperature and the tension factor are
    alternatives; the change of state needs the conductor's properties; the true tension must
    stay below the rated strength."""
    truth = scenario.truth
    if truth.temperature is not None and truth.tension_factor is not None:
        check.note("truth.temperature conflicts with truth.tension_factor: the true tension "
                   "comes from the day's conductor temperature (the change of state from "
                   "truth.stringing_temperature) or from a factor on the nominal tension, not "
                   "both. Remove one of them.")
        return
    if truth.temperature is None and truth.tension_factor is None:
        return
    try:
        nominal = scenario.span.build()
    except (InputError, KeyError):
        return   # the [span] section's own problem, already reported
    rated = nominal.conductor.rated_strength
    if truth.temperature is not None:
        missing = [name for name in CHANGE_OF_STATE if getattr(nominal.conductor, name) is None]
        if missing:
            check.refuse("truth.temperature", truth.temperature,
                         "truth.tension_factor instead, or a conductor preset (span.preset = "
                         "\"conductor\")",
                         f"The change of state needs the conductor's {' and '.join(missing)}, "
                         f"which the conductor {nominal.conductor.name!r} does not carry.")
            return
        try:
            true_span(scenario, nominal)
        except InputError as error:
            check.refuse("truth.temperature", truth.temperature,
                         "a temperature at which the line keeps below its rated strength",
                         " ".join(str(error).split()))
        return
    if rated is not None and truth.tension_factor * nominal.tension >= rated:
        check.refuse("truth.tension_factor", truth.tension_factor,
                     f"below {rated / nominal.tension:.4g} (the rated strength {rated:g} N over "
                     f"the nominal tension {nominal.tension:.6g} N)", "The conductor would break.")


def on_nodes(values, x_from, x_to):
    """Nodal values (rows: nodes at ``x_from``) read at the nodes ``x_to``: the same array when
    the two meshes agree (the true line shares the nominal's uniform mesh), else by linear
    interpolation along the span (a graded true mesh differs from the nominal's).

    Parameters
    ----------
    values : array_like, shape (n_from,) or (n_from, n_t)
        Values at the nodes ``x_from`` (a shape, or a field with time in columns).
    x_from, x_to : array_like
        Node positions, m, ascending.

    Returns
    -------
    ndarray, shape (n_to,) or (n_to, n_t)

    Examples
    --------
    >>> import numpy as np
    >>> on_nodes(np.array([0.0, 2.0, 0.0]), [0.0, 1.0, 2.0], [0.0, 0.5, 1.5, 2.0]).tolist()
    [0.0, 1.0, 1.0, 0.0]
    """
    import numpy as np

    x_from, x_to = np.asarray(x_from, dtype=float), np.asarray(x_to, dtype=float)
    values = np.asarray(values)
    if x_from.shape == x_to.shape and np.allclose(x_from, x_to, rtol=0.0,
                                                   atol=1e-12 * float(x_from[-1])):
        return values
    right = np.clip(np.searchsorted(x_from, x_to, side="right"), 1, x_from.size - 1)
    left = right - 1
    weight = (x_to - x_from[left]) / (x_from[right] - x_from[left])
    if values.ndim == 2:
        weight = weight[:, None]
    return (1.0 - weight) * values[left] + weight * values[right]
