"""The scenario pipeline: one scenario, stage by stage, into one frozen :class:`ScenarioResult`.

Stages (each calls the package's own stage; none re-derives another's result)::

    model           the nominal Span and LineModel (what the engineer knows), the true ones
                    (the line simulated: :mod:`.truth`), the load
    records         the simulated record (and the identification run with its shaker) of the
                    true line (the scenario's [truth]), or a measured record given by the user
    identification  design_estimator: the identified model, the sensors, the filter
    sensors         (the sensor choice is part of the recipe; this stage marks that it chooses)
    estimation      the design's filter on held-out data, against fair baseline layouts
    plan            antinodes of the estimated field, the closed loop's target, the move
    closed_loop     run_closed_loop on the true line, its controller told the nominal span
                    (which it calibrates from its records): the robot against it parked
    severity        aeolian_severity without and with the robot
    fatigue         fatigue_over_record over a wind record (only when one is given): no damper,
                    a fixed damper and the scenario's robot on the severity study's span

The scenario's decisions that no other stage owns live here, named: the share of the record
that trains (:data:`TRAIN_FRACTION`), where the identification run's shaker acts
(:data:`SHAKER_POSITION`), the closed loop's calibration (:func:`closed_loop_timing`).
A stage that fails leaves the finished stages' results in the returned (or attached) result
with the failure recorded (:class:`StageFailure`).

Test seam: ``_records``, ``_plan`` and ``_closed_loop``, the stage functions as the pipeline
calls them: tests replace one to make its stage fail (exit codes, the partial result).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .._validation import checked_keywords
from ..errors import InputError
from .config import Scenario
from .files import load_scenario
from .result import ScenarioResult, StageFailure, Tuning
from .sensing import evenly_spaced_nodes, given_sensors  # noqa: F401  (re-exported)
from .sensor_count import (  # noqa: F401  (re-exported, as before it had its own module)
    SENSOR_COUNT_MAX_NODES,
    _sensor_count,
    sensor_count_skipped,
)
from .stages import (  # noqa: F401  (re-exported: the pipeline's stage helpers)
    ANTINODE_WINDOW,
    CONTROL_PERIOD,
    LAB_CONDUCTOR,
    MAX_CALIBRATION,
    SHAKER_POSITION,
    TRAIN_FRACTION,
    _closed_loop,
    _fatigue,
    _identification,
    _layouts,
    _measured,
    _model,
    _plan,
    _records,
    _severity,
    _with_record_sensors,
    check_identification_work,
    closed_loop_timing,
    driven_mode,
    layout_filter,
    longest_complete_run,
    read_wind_record,
    sensor_count_check,
    severity_inputs,
    severity_span,
    support_intervals,
    tune_robot,
)

__all__ = [
    "STAGES",
    "VERB_STAGES",
    "ScenarioResult",
    "StageFailure",
    "run_scenario",
]

#: Every stage, in order.
STAGES = ("model", "records", "identification", "sensors", "estimation", "plan",
          "closed_loop", "severity", "fatigue")
#: The stages each verb of the command runs.
VERB_STAGES = {
    "simulate": ("model", "records"),
    "identify": ("model", "records", "identification"),
    "sensors": ("model", "records", "identification", "sensors"),
    "estimate": ("model", "records", "identification", "sensors", "estimation"),
    "plan": ("model", "records", "identification", "sensors", "estimation", "plan"),
    "closed-loop": ("model", "closed_loop"),
    "severity": ("model", "severity", "fatigue"),
    "run": STAGES,
}


# ----------------------------------------------------------------------------- the pipeline

def _check_stages(stages) -> tuple:
    if stages is None:
        return STAGES
    if isinstance(stages, str) or not isinstance(stages, Sequence):
        raise InputError(f"The 'stages' parameter must be a sequence of stage names from "
                         f"{list(STAGES)}. Got {stages!r:.60}.")
    if len(stages) == 0:   # would return an "ok" result in which every stage is None
        raise InputError(f"The 'stages' parameter must name at least one stage from "
                         f"{list(STAGES)}, or be None for all. Got {stages!r:.60}.")
    unknown = [s for s in stages if s not in STAGES]
    if unknown:
        raise InputError(f"The 'stages' parameter names unknown stages {unknown}; the stages "
                         f"are {list(STAGES)}.")
    return tuple(s for s in STAGES if s in stages)


def stage_plan(scenario: Scenario, stages=None, *, wind_record=None) -> tuple:
    """The stages that will run for ``scenario`` (closed loop and severity only when on, the
    fatigue stage only with a wind record).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    stages : sequence of str or None
        Asked for (default: all).
    wind_record : WindRecord, str, Path or None
        The wind record the fatigue stage runs on (None: the scenario's
        ``severity.wind_record``; without either, no fatigue stage).

    Returns
    -------
    tuple of str

    Examples
    --------
    >>> stage_plan(load_scenario(text="[robot]\\nclosed_loop = 0"))
    ('model', 'records', 'identification', 'sensors', 'estimation', 'plan')
    """
    stages = _check_stages(stages)
    if wind_record is None:
        wind_record = scenario.severity.wind_record
    alone = stages in (("model", "severity"), VERB_STAGES["severity"])
    out = []
    for stage in stages:
        if stage == "closed_loop" and scenario.robot.closed_loop <= 0:
            continue
        if stage == "fatigue" and wind_record is None:
            continue
        if stage == "severity" and not (scenario.severity.enabled or alone):
            continue
        if stage == "sensors" and given_sensors_declared(scenario):
            continue
        out.append(stage)
    return tuple(out)


def given_sensors_declared(scenario: Scenario) -> bool:
    """True when the scenario lists its sensors (no sensor choice to make).

    Parameters
    ----------
    scenario : Scenario
        The scenario.

    Returns
    -------
    bool

    Examples
    --------
    >>> given_sensors_declared(load_scenario())
    False
    """
    est = scenario.estimation
    return est.sensors is not None or est.sensor_positions is not None


@checked_keywords
def run_scenario(scenario: Scenario | str | Path | None = None, *, stages=None, record=None,
                 wind_record=None, progress=None, keep_partial: bool = False) -> ScenarioResult:
    """Run a scenario's stages and return everything they produced as one frozen result.

    Stages: model -> records (simulated, plus the identification run) -> identification and
    sensor choice (``design_estimator``) -> Kalman estimation on held-out data, against fair
    baselines -> antinodes, target and minimum-time move -> closed loop -> severity (each
    when the scenario asks for it) -> fatigue over a wind record (when one is given).

    Parameters
    ----------
    scenario : Scenario, str, Path or None
        A scenario, a TOML file or a shipped name (loaded with
        :func:`~powerline_control.scenario.load_scenario`); None: the default scenario.
    stages : sequence of str or None
        The stages to run (default: all, see :data:`STAGES`); the ones they need must be in it.
    record : Record or None
        A measured record (:func:`~powerline_control.output.records.load_record`): the
        estimation stage also runs the designed filter on it, at the sensors nearest its positions.
    wind_record : WindRecord, str, Path or None
        A wind record, or its CSV file (:meth:`~powerline_control.WindRecord.from_csv`): the
        fatigue stage runs ``fatigue_over_record`` over it on the severity study's span
        (:func:`severity_span`) with the scenario's tuned robot and its ``RobotLimits``
        (default: the scenario's ``severity.wind_record``, when the fatigue stage is asked
        for). The file is read before any stage runs.
    progress : callable or None
        Called with a sentence as each stage starts (e.g. a progress line).
    keep_partial : bool
        When a stage fails, return the finished stages' result with ``failure`` set instead of
        raising (the exception raised otherwise carries it as ``exc.scenario_result``).

    Returns
    -------
    ScenarioResult

    Raises
    ------
    InputError
        Bad scenario or stages, a bad wind record (the message names the file, the column
        and the row), or records the identification stage's estimator would refuse as over its
        budget (before any stage runs when ``model.n_elements`` is a number).
    PowerlineControlError
        The failing stage's own error (unless ``keep_partial``).

    Examples
    --------
    >>> small = load_scenario(text="[model]\\nn_elements = 16\\n[simulation]\\nduration = 2.0\\n"
    ...                            "[estimation]\\nn_sensors = 2\\n[robot]\\nclosed_loop = 0")
    >>> result = run_scenario(small, stages=("model", "records", "identification", "sensors",
    ...                                      "estimation"))
    >>> len(result.sensors), result.layouts["chosen"].error_unmeasured_percent < 10
    (2, True)
    """
    if progress is not None and not callable(progress):
        raise InputError(f"The 'progress' parameter must be None or a callable taking one "
                         f"sentence (e.g. print). Got {progress!r:.60} of type "
                         f"{type(progress).__name__}.")
    if not isinstance(keep_partial, bool):
        raise InputError(f"The 'keep_partial' parameter must be True or False. Got "
                         f"{keep_partial!r:.60} of type {type(keep_partial).__name__}.")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if record is not None:
        scenario, record = _with_record_sensors(scenario, record)
    asked = _check_stages(stages)
    if wind_record is None and "fatigue" in asked:
        wind_record = scenario.severity.wind_record
    wind = None if wind_record is None else read_wind_record(wind_record)
    plan = stage_plan(scenario, asked, wind_record=wind)
    if {"records", "identification"} <= set(plan) and scenario.model.n_elements != "auto":
        # The mesh is known before it is built (the true line is meshed alike): refuse records
        # the identification would refuse before any stage (a mesh the physics chooses is
        # checked by the records stage, before it simulates).
        check_identification_work(scenario, scenario.model.n_elements + 1)
    state: dict[str, Any] = {"scenario": scenario, "stages": asked, "elapsed": {},
                             "_wind": wind}
    say = progress or (lambda text: None)
    for stage in plan:
        words = _STAGE_WORDS[stage](scenario)
        if stage == "sensors" and state.get("identification") is not None:
            skipped = sensor_count_skipped(state["identification"])
            if skipped is not None:   # not printed as if it ran
                words = f"how many sensors: skipped ({skipped})"
        say(words)
        start = time.perf_counter()
        try:
            _run_stage(stage, scenario, state, record, plan)
        except Exception as exc:  # noqa: BLE001 (recorded, then re-raised or returned)
            state["elapsed"][stage] = round(time.perf_counter() - start, 3)
            failure = StageFailure(stage=stage, kind=type(exc).__name__,
                                   message=" ".join(str(exc).split()), error=exc)
            result = _result(state, failure)
            if keep_partial:
                return result
            exc.scenario_result = result
            raise
        state["elapsed"][stage] = round(time.perf_counter() - start, 3)
    return _result(state, None)


def _result(state: dict, failure) -> ScenarioResult:
    names = {f.name for f in dataclasses.fields(ScenarioResult)}
    return ScenarioResult(**{k: v for k, v in state.items() if k in names}, failure=failure)


def _need(state: dict, key: str, stage: str):
    if state.get(key) is None:
        raise InputError(f"The stage {stage!r} needs the stage that makes {key!r}; add it to "
                         "'stages'.")
    return state[key]


def _run_stage(stage: str, scenario: Scenario, state: dict, record, plan) -> None:
    if stage == "model":
        state.update(_model(scenario))
    elif stage == "records":
        # the data are the true line's (the nominal's own model without a [truth] section)
        state["records"] = _records(scenario, _need(state, "true_model", stage), state["force"],
                                    record, identify="identification" in plan)
    elif stage == "identification":
        state["identification"] = _identification(
            scenario, _need(state, "records", stage), state["model"],
            choose_sensors="sensors" in state["stages"])
    elif stage == "sensors":
        state["sensor_count"] = _sensor_count(_need(state, "identification", stage),
                                              state["true_model"])   # the records' mesh
        if state["sensor_count"] is not None:   # its layouts on the held-out record
            state["sensor_count_check"] = sensor_count_check(
                state["sensor_count"], state["records"], state["identification"])
    elif stage == "estimation":
        state["layouts"] = _layouts(scenario, _need(state, "records", stage),
                                    _need(state, "identification", stage), state["model"])
        if record is not None:
            state["measured"] = _measured(record, state["identification"],
                                          state["true_model"].node_positions)   # its mesh
    elif stage == "plan":
        state["plan"] = _plan(scenario, state["records"], _need(state, "layouts", stage),
                              state["model"], _tuning(state, scenario))
    elif stage == "closed_loop":
        # the plant is the true line; the controller is told the nominal model and calibrates
        state["closed_loop"] = _closed_loop(scenario, _need(state, "true_model", stage),
                                            state["force"], _tuning(state, scenario),
                                            state.get("identification"), nominal=state["model"])
    elif stage == "severity":
        _need(state, "model", stage)
        state["severity"] = _severity(scenario, state["span"], _tuning(state, scenario))
    elif stage == "fatigue":
        _need(state, "model", stage)
        wind, source = state["_wind"]
        state["fatigue"] = _fatigue(scenario, state["span"], _tuning(state, scenario), wind,
                                    source)


def _tuning(state: dict, scenario: Scenario) -> Tuning:
    """The tuned robot, computed once per run, on the nominal model (what the engineer knows)."""
    if state.get("_tuning") is None:
        state["_tuning"] = tune_robot(scenario, state["model"])
    return state["_tuning"]


_STAGE_WORDS = {
    "model": lambda s: "building the finite-element model",
    "records": lambda s: (f"simulating {s.simulation.duration:g} s of motion"
                          + (" of the true line" if s.truth.differs else "") + " at dt = "
                          f"{s.simulation.dt:g} s"
                          + (" and the identification run" if s.identification.shaker > 0
                             else "")),
    "identification": lambda s: (
        "identifying the model" + ("" if given_sensors_declared(s) else
                                   f" and choosing {s.estimation.n_sensors} sensor positions "
                                   "(Kalman criterion)")
        + " (the recipe's choices judged on held-out data)"),
    "sensors": lambda s: (f"how many sensors: the predicted error of 1 to "
                          f"{s.estimation.n_sensors + 2} sensors, each count optimised"),
    "estimation": lambda s: "Kalman estimation of the whole span on held-out data",
    "plan": lambda s: "locating antinodes and planning the robot's move",
    "closed_loop": lambda s: (f"closed loop: {s.robot.closed_loop:g} s of the robot seeking "
                              "the best parked position, and the same run parked"),
    "severity": lambda s: "aeolian severity by the energy balance method",
    "fatigue": lambda s: ("fatigue over the wind record: no damper, a fixed damper and the "
                          "robot moving as the wind changes"),
}
