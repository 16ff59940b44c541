"""The scenario pipeline's stages: each calls the package's own stage and returns its result.

The scenario's decisions that no other stage owns live here, named: the share of the record
that trains (:data:`TRAIN_FRACTION`), where the identification run's shaker acts
(:data:`SHAKER_POSITION`), the closed loop's calibration (:func:`closed_loop_timing`), the robot's
tuning (:func:`tune_robot`). Which nodes carry sensors is :mod:`.sensing`'s.

Test seam: ``_closed_loop``, called with a stand-in ``run_closed_loop`` to show which of the
scenario's keys reach it without running the stages before it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
import warnings

from ..errors import InputError, SaturationWarning
from .config import CONTROL_PERIOD, MAX_CALIBRATION, Scenario, closed_loop_timing
from .files import load_scenario  # noqa: F401 (doctests)
from .result import (
    ClosedLoop,
    Fatigue,
    Identification,
    Layout,
    MeasuredEstimate,
    Plan,
    Records,
    Severity,
    SeverityTimeDomain,
    Tuning,
)
from .sensing import closed_loop_sensors, evenly_spaced_nodes, given_sensors
from .sensor_count import SensorCountCheck
from .truth import on_nodes

__all__ = ["TRAIN_FRACTION", "SHAKER_POSITION", "CONTROL_PERIOD", "MAX_CALIBRATION",
           "ANTINODE_WINDOW", "LAB_CONDUCTOR", "closed_loop_timing", "driven_mode",
           "layout_filter", "longest_complete_run", "read_wind_record",
           "severity_assumptions", "severity_inputs", "severity_span", "support_intervals",
           "self_limiting_physics", "tune_robot", "wind_judgement"]

#: Share of the simulated record that trains the estimator; the rest tests it (held out).
TRAIN_FRACTION = 0.6
#: Where the identification run's broadband shaker acts, as a fraction of the span: off the
#: symmetry points 1/2, 1/3, 1/4, 1/5 of the low modes, so it drives every one of them.
SHAKER_POSITION = 0.31
#: Antinodes are located on the last this-many samples of the held-out estimate.
ANTINODE_WINDOW = 500


def _model(scenario: Scenario) -> dict:
    """The nominal span and model (what the engineer knows), the true ones (the line simulated:
    :func:`~powerline_control.scenario.truth.true_model`, the nominal's own objects when the
    scenario has no ``[truth]``) and the load."""
    from .truth import true_model

    span = scenario.span.build()
    model = scenario.model.build(span)
    truth = true_model(scenario, model)
    return {"span": span, "model": model, "true_span": truth.span, "true_model": truth,
            "force": scenario.forcing.build()}


def _records(scenario: Scenario, model, force, record=None, *, identify: bool = False
             ) -> Records:
    from ..excitation import RandomForce
    from ..simulation import simulate

    sim, ident = scenario.simulation, scenario.identification
    if identify:
        check_identification_work(scenario, model.n_nodes)
    start = time.perf_counter()
    if scenario.robot.wind == "self_limiting":
        # the record the estimator learns from vibrates as the closed loop's line then does:
        # the same wind's physics, the line at the energy balance's amplitude from the first
        # sample (so the record's duration and start are the fixed lift's)
        from ..severity import simulate_self_limiting

        if ident.shaker > 0:   # refused here, not at load: a closed loop alone needs no record
            raise InputError(
                f"identification.shaker = {ident.shaker:g} is not allowed with robot.wind = "
                '"self_limiting": the records are simulated in the self-limiting wind, which '
                "applies no load (the wind is a damping). Allowed: identification.shaker = 0.")
        test = simulate_self_limiting(model, force, duration=sim.duration, dt=sim.dt,
                                      wind=self_limiting_physics(scenario, model.span),
                                      noise_fraction=sim.noise_fraction, seed=sim.seed)
    else:
        test = simulate(model, force, duration=sim.duration, dt=sim.dt,
                        noise_fraction=sim.noise_fraction, seed=sim.seed)
    n_train = int(TRAIN_FRACTION * test.t.size)
    train, shaker, where = test, None, None
    if ident.shaker > 0:
        # A harmonic load alone excites the other modes only through its start-up transient:
        # the shaker makes the identification run persistently exciting; its own seed keeps
        # its noise and force independent of the test record's.
        where = SHAKER_POSITION * model.span.length
        shaker = RandomForce(ident.shaker, where, ident.shaker_bandwidth, seed=sim.seed + 1)
        train = simulate(model, [force, shaker], duration=n_train * sim.dt, dt=sim.dt,
                         noise_fraction=sim.noise_fraction, seed=sim.seed + 1)
    return Records(test=test, train=train, n_train=n_train, shaker=shaker, shaker_position=where,
                   measured=record, simulation_s=time.perf_counter() - start)


def check_identification_work(scenario: Scenario, n_nodes: int) -> None:
    """Refuse, before the line is simulated, records that the identification stage would refuse.

    The identification stage's :func:`~powerline_control.recipe.design_estimator` receives the
    training part of the record (:data:`TRAIN_FRACTION` of ``floor(duration / dt) + 1``
    samples) at every node; its own estimate (``recipe.defaults.check_record_work``) is applied
    to that size here, named in the scenario's keys (a 20 000-element line was simulated for
    37 s, then refused by a budget naming 'snapshots').

    Parameters
    ----------
    scenario : Scenario
        Its ``simulation`` and ``identification`` sections.
    n_nodes : int
        Nodes of the line the records are simulated on.

    Raises
    ------
    InputError
        The training record is over the recipe's budget; the message names
        ``model.n_elements`` and ``simulation.duration``.

    Examples
    --------
    >>> check_identification_work(load_scenario(), 21)
    >>> check_identification_work(load_scenario(text="[model]\\nn_elements = 20000\\n"
    ...                                              "[simulation]\\nduration = 3.0"), 20001)
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: The identification stage's design_estimator, on the \
training record (20001 nodes x 1800 samples) would need about 1.4e+12 floating-point \
operations...
    """
    from ..recipe.defaults import DEFAULT_DELAYS, check_record_work

    sim, ident = scenario.simulation, scenario.identification
    n_t = int(math.floor(sim.duration / sim.dt + 1e-9)) + 1   # simulate's own sample count
    n_train = int(TRAIN_FRACTION * n_t)
    n_elements = scenario.model.n_elements
    value = n_elements if n_elements != "auto" else f'"auto" ({n_nodes - 1} elements)'
    check_record_work(
        n_nodes, n_train,
        what=f"The identification stage's design_estimator, on the training record "
             f"({n_nodes} nodes x {n_train} samples)",
        parameter="model.n_elements", value=value,
        fix=f"use a coarser mesh (model.n_elements) or a shorter simulation.duration "
            f"({sim.duration:g} s now)",
        delays=DEFAULT_DELAYS if ident.delays is None else ident.delays)


def support_intervals(x) -> tuple:
    """The intervals at the supports no sensor may occupy (half an element at each end), m.

    Parameters
    ----------
    x : array_like
        Node positions, m.

    Returns
    -------
    tuple of (float, float)

    Examples
    --------
    >>> support_intervals([0.0, 1.0, 2.0])
    ((0.0, 0.5), (1.5, 2.0))
    """
    import numpy as np

    x = np.asarray(x, dtype=float)
    half = 0.5 * float(min(x[1] - x[0], x[-1] - x[-2]))
    return ((0.0, half), (float(x[-1] - half), float(x[-1])))


def longest_complete_run(values) -> slice:
    """The longest stretch of columns without a NaN, as a slice.

    Parameters
    ----------
    values : array_like, shape (n_channels, n_t)
        A record; NaN = missing.

    Returns
    -------
    slice

    Examples
    --------
    >>> import numpy as np
    >>> longest_complete_run([[1.0, np.nan, 1.0, 2.0, 3.0, np.nan]])
    slice(2, 5, None)
    """
    import numpy as np

    ok = ~np.isnan(np.asarray(values, dtype=float)).any(axis=0)
    best, start, run = slice(0, 0), None, 0
    for k, good in enumerate([*ok, False]):
        if good and start is None:
            start = k
        elif not good and start is not None:
            if k - start > run:
                best, run = slice(start, k), k - start
            start = None
    return best


def _record_model(record, design):
    from ..identify import fit_dmd

    run = longest_complete_run(record.values)
    data = record.values[:, run]
    delays = int(design.model.delays)
    needed = 10 * (delays * data.shape[0] + 1)
    if data.shape[1] < needed:
        has_gaps = data.shape[1] < record.values.shape[1]
        stretch = ("its longest stretch without a missing sample has" if has_gaps else "it has")
        raise InputError(f"{record.source}: {stretch} {data.shape[1]} samples, too few to "
                         f"identify a model with {delays} delays (at least {needed}); give "
                         + ("a record with fewer gaps." if has_gaps else "a longer record."))
    return fit_dmd(data, record.dt, alpha=float(design.model.alpha_relative), delays=delays,
                   alpha_mode="relative")


def _identification(scenario: Scenario, records: Records, model, *,
                    choose_sensors: bool) -> Identification:
    import numpy as np

    from ..identify import fit_dmd
    from ..recipe import design_estimator

    cfg = scenario.identification
    snap = records.train
    train = snap.displacement[:, :records.n_train]
    x = np.asarray(snap.x)
    k = scenario.estimation.n_sensors
    forbidden = support_intervals(x)
    given, how = given_sensors(scenario, x)
    if given is None and not choose_sensors:
        given = evenly_spaced_nodes(x, k)
        how = "evenly spaced (this verb does not optimise them)"
    options = {key: value for key, value in (("delays", cfg.delays), ("rank", cfg.rank))
               if value is not None}
    if cfg.alpha != "auto":
        options["alphas"] = [float(cfg.alpha)]
    design = design_estimator(
        train, n_sensors=k, dt=snap.dt, noise_std=snap.noise_std or None, sensors=given,
        positions=x, forbidden=forbidden, seed=scenario.simulation.seed, **options)
    if given is None:
        how = "optimised (steady-state Kalman criterion)"
    with warnings.catch_warnings(record=True) as caught:
        # On noise-free data plain DMD inverts round-off and says so; here that is the point.
        warnings.simplefilter("always")
        plain = fit_dmd(train, snap.dt, alpha=0.0, delays=1)
    record_model = None
    if records.measured is not None:
        record_model = _record_model(records.measured, design)
    return Identification(design=design, plain=plain, plain_ill_conditioned=bool(caught),
                          sensors_given=given is not None, sensors_how=how, forbidden=forbidden,
                          record_model=record_model)


def layout_filter(design, nodes):
    """A steady-state filter of ``design``'s model on other sensors, built as the recipe does.

    The recipe's own :meth:`~powerline_control.EstimatorDesign.filter_on`: the noise model,
    the covariance scale and the model-error terms of the reported sigma are the design's; only
    the measured rows differ, so baselines are judged with the same model as the chosen layout.

    Parameters
    ----------
    design : EstimatorDesign
        The recipe's design.
    nodes : sequence of int
        The sensors.

    Returns
    -------
    KalmanFilter

    Examples
    --------
    >>> import powerline_control as plc
    >>> snap = plc.simulate(plc.LineModel(plc.Span.paper_lab(), n_elements=12),
    ...                     plc.RandomForce(0.1, 0.8, 100.0, seed=1), duration=1.0,
    ...                     noise_fraction=0.01, seed=1)
    >>> design = plc.design_estimator(snap, n_sensors=2, seed=1)
    >>> layout_filter(design, [3, 9]).n_outputs
    2
    """
    return design.filter_on([int(i) for i in nodes])


def driven_mode(model, load_frequency: float) -> int:
    """The line's mode (1-based) whose natural frequency is nearest the load's.

    Parameters
    ----------
    model : LineModel
        The line.
    load_frequency : float
        Hz.

    Returns
    -------
    int

    Examples
    --------
    >>> import powerline_control as plc
    >>> driven_mode(plc.LineModel(plc.Span.paper_lab(), n_elements=20), 24.0)
    3
    """
    import numpy as np

    n = min(400, model.n_dofs)
    frequencies = np.asarray(model.natural_frequencies(n))
    return int(np.argmin(np.abs(frequencies - load_frequency))) + 1


def _held_out_discard(records: Records) -> int:
    """Samples at the start of the held-out record left out of the errors (filter transient)."""
    return min(200, (records.test.t.size - records.n_train) // 4)



def sensor_count_check(study, records: Records, ident: Identification) -> SensorCountCheck:
    """The sensor-count study's layouts run like the estimation table's: the designed filter
    with each count's layout on the held-out record (what the report's "how many sensors" figure
    and the JSON show; the pipeline's sensors stage runs it once, after the study).

    Parameters
    ----------
    study : SensorCountStudy
        The study (:func:`~powerline_control.sensors.sensor_count_study`).
    records : Records
        The records stage's result (its held-out part is used).
    ident : Identification
        The identification stage's result (the designed filter, the recipe's layout).

    Returns
    -------
    SensorCountCheck
    """
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


def _layouts(scenario: Scenario, records: Records, ident: Identification, model) -> dict:
    import numpy as np

    from ..estimate import estimation_accuracy

    snap, n_train = records.test, records.n_train
    x = np.asarray(snap.x)
    design = ident.design
    chosen = [int(i) for i in design.sensors]
    k = len(chosen)
    # the baselines are placed as an engineer would: off the nodes of the nominal model's mode
    mode = driven_mode(model, scenario.forcing.load_frequency(model.span))
    shape = on_nodes(model.mode_shapes(mode)[:, mode - 1], model.node_positions, x)
    candidates = {"chosen": (chosen, ident.sensors_how)}
    plain_even = evenly_spaced_nodes(x, k)
    fair_even = evenly_spaced_nodes(x, k, shape)
    phi = np.abs(shape) / np.abs(shape).max()
    on_node = float(phi[plain_even].min())
    if fair_even != plain_even:
        candidates[f"evenly spaced ({k})"] = (
            plain_even, f"{k} sensors at equal spacing L/{k + 1}; the smallest relative "
            f"amplitude of the driven mode {mode} at them is {on_node:.2g} (0: on a node).")
        candidates[f"evenly spaced, off mode {mode}'s nodes ({k})"] = (
            fair_even, f"The same spacing shifted so that no sensor sits on a node of the driven "
            f"mode {mode} (smallest relative amplitude {float(phi[fair_even].min()):.2g}).")
    else:
        candidates[f"evenly spaced ({k})"] = (
            plain_even, f"{k} sensors at equal spacing L/{k + 1}, none on a node of the driven "
            f"mode {mode} (smallest relative amplitude {on_node:.2g}).")
    # The paper measured its first 10 states on 20 elements and its first 13 on 100 (Figs. 7-8);
    # node 0 sits on the support, so the first measured node is node 1.
    n_first = 10 if x.size == 21 else 13
    first = list(range(1, min(n_first, x.size - 2) + 1))
    covered = x[first[-1]]
    candidates[f"the paper's layout: first {len(first)} nodes"] = (
        first, f"The paper's own layout (its first {n_first} states): {len(first)} sensors, "
        f"not {k}, covering only x <= {covered:.3g} m ({100 * covered / x[-1]:.2g} % of the "
        "span).")
    held = slice(n_train, None)
    truth = snap.true_displacement[:, held]
    span_rms = float(np.sqrt(np.mean(truth**2)))
    discard = _held_out_discard(records)
    out = {}
    for name, (nodes, note) in candidates.items():
        if name != "chosen" and nodes == chosen:
            continue
        estimate = layout_filter(design, nodes).filter(snap.displacement[nodes, held])
        accuracy = estimation_accuracy(estimate.field, truth, measured=nodes, discard=discard)
        along = np.sqrt(np.mean((estimate.field - truth) ** 2, axis=1)) / span_rms
        out[name] = Layout(name=name, nodes=tuple(nodes),
                           positions=tuple(float(x[i]) for i in nodes), note=note,
                           estimate=estimate, accuracy=accuracy, error_along_span=along)
    return out


def tune_robot(scenario: Scenario, model) -> Tuning:
    """The scenario's robot with its absorber tuned to the mode the load drives.

    Tuned (Den Hartog, or the scenario's damping ratio at Den Hartog's frequency) for the
    antinode of that mode nearest the robot's start (the modal mass seen at a node is
    infinite), found by :func:`~powerline_control.antinode.locate_antinodes` on the mode shape;
    then placed at its start.

    Parameters
    ----------
    scenario : Scenario
        Its ``robot`` and ``forcing`` sections.
    model : LineModel
        The line.

    Returns
    -------
    Tuning

    Examples
    --------
    >>> import powerline_control as plc
    >>> s = load_scenario(text="[model]\\nn_elements = 30")
    >>> tuning = tune_robot(s, plc.LineModel(s.span.build(), n_elements=30))
    >>> tuning.mode, tuning.robot.position
    (3, 1.2)
    """
    import numpy as np

    from ..antinode import locate_antinodes, nearest_antinode
    from ..fem import tune_damper

    cfg = scenario.robot
    load_frequency = float(scenario.forcing.load_frequency(model.span))
    mode = driven_mode(model, load_frequency)
    frequency = float(model.natural_frequencies(mode)[mode - 1])
    # The mode shape where its loops span at least 3 samples: at the nodes, or between them on
    # a mesh too coarse for that (the FE's own shape functions; its antinodes fall between).
    loop = float(model.span.loop_length(frequency))
    x = np.asarray(model.node_positions)
    if loop < 3 * model.element_length:
        x = np.linspace(0.0, model.span.length, int(np.ceil(8 * model.span.length / loop)) + 1)
    antinodes = locate_antinodes(model.displacement_map(x) @ model.modes(mode).shapes[:, mode - 1],
                                 x)
    antinode = float(nearest_antinode(antinodes, cfg.start).position) if antinodes else cfg.start
    mdr = tune_damper(model, mode, antinode, cfg.suspended_mass, body_mass=cfg.body_mass)
    how = "Den Hartog"
    if cfg.damping_ratio > 0:
        omega = np.sqrt(mdr.stiffness / mdr.suspended_mass)
        mdr = dataclasses.replace(mdr, damping=2 * cfg.damping_ratio * mdr.suspended_mass * omega)
        how = f"Den Hartog frequency, damping ratio {cfg.damping_ratio:g} from the scenario"
    mdr = dataclasses.replace(mdr, position=cfg.start)
    return Tuning(robot=mdr, mode=mode, mode_frequency=frequency, load_frequency=load_frequency,
                  antinode=antinode, how=how)


def _plan(scenario: Scenario, records: Records, layouts: dict, model, tuning: Tuning) -> Plan:
    import numpy as np

    from ..antinode import locate_antinodes, nearest_antinode
    from ..closed_loop.policy import choose_parked_position, travel_budget
    from ..plan import RobotLimits, plan_motion

    snap, n_train = records.test, records.n_train
    estimate = layouts["chosen"].estimate
    window = slice(-min(ANTINODE_WINDOW, estimate.field.shape[1]), None)
    held_truth = snap.true_displacement[:, n_train:]
    estimated = locate_antinodes(estimate.field[:, window], snap.x, dt=snap.dt)
    true = locate_antinodes(held_truth[:, window], snap.x, dt=snap.dt)
    robot = scenario.robot
    limits = RobotLimits(v_max=robot.v_max, a_max=robot.a_max)
    travel = float("inf")
    if robot.closed_loop > 0:
        travel = travel_budget(closed_loop_timing(scenario)[1], 0.0, robot.closed_loop)
    # The closed loop's own targeting rule on the whole held-out estimate (its resolution,
    # 1 / length, must tell the load's line from a natural frequency's ringing next to it).
    # predicted with the nominal model (what the engineer knows), from the estimated field
    field = on_nodes(estimate.field, snap.x, model.node_positions)
    # in the self-limiting wind the closed loop judges positions by the robot's coupling to
    # the locked standing wave: the plan applies the same rule
    choice = choose_parked_position(model, field, snap.dt, tuning.robot, robot.start,
                                    limits, travel_time=travel,
                                    objective=("antinode" if robot.wind == "self_limiting"
                                               else "response"))
    target = nearest_antinode(estimated, choice.position)
    truth = nearest_antinode(true, choice.position)
    trajectory = plan_motion(robot.start, choice.position, limits, span_length=model.span.length)
    return Plan(antinodes=estimated, true_antinodes=true, choice=choice, target=target,
                truth=truth, trajectory=trajectory, envelope=np.abs(held_truth).max(axis=1))


def _closed_loop(scenario: Scenario, model, force, tuning: Tuning, identification=None,
                 nominal=None) -> ClosedLoop:
    """The closed loop on the true line (``model``, the plant), its controller told the nominal
    model (``nominal``; None: ``model``), which it calibrates from its records; its sensors
    from :func:`closed_loop_sensors`."""
    from ..closed_loop import run_closed_loop
    from ..plan import RobotLimits

    cfg = scenario.robot
    sensors, how = closed_loop_sensors(scenario, model.node_positions, identification)
    dt, calibration = closed_loop_timing(scenario)
    steady, unjudged = wind_judgement(scenario, model.span)
    result = run_closed_loop(
        model, force, tuning.robot, RobotLimits(cfg.v_max, cfg.a_max), sensors=list(sensors),
        duration=cfg.closed_loop, calibration=calibration, dt=dt,
        noise_fraction=scenario.simulation.noise_fraction, seed=scenario.simulation.seed,
        nominal=model if nominal is None else nominal, calibrate=True,
        aeolian_steady=steady, estimator=cfg.estimator,
        wind=(self_limiting_physics(scenario, model.span) if cfg.wind == "self_limiting"
              else "fixed_lift"))
    return ClosedLoop(tuning=tuning, sensors=tuple(int(i) for i in sensors), result=result,
                      calibration=calibration, sensors_how=how, unjudged=unjudged)


def wind_judgement(scenario: Scenario, span) -> tuple[dict | bool, str]:
    """(``aeolian_steady``, why not): ``run_closed_loop``'s ``aeolian_steady`` for the
    scenario, and, when it is False, why the closed loop is not judged in the self-limiting wind,
    in words ("" when it is). In the aeolian wind, with the severity study's time-domain check
    on, the closed loop's robot is judged again in the self-limiting wind with the severity
    study's power curve and self-damping law (its k from the severity study's rated strength,
    :func:`severity_span`), unless that physics cannot settle the line
    (:func:`~powerline_control.severity.self_limiting.settling_balance`).

    Parameters
    ----------
    scenario : Scenario
        Its ``forcing`` and ``severity`` sections.
    span : Span
        The line the closed loop simulates (the truth).

    Returns
    -------
    (dict or bool, str)

    Examples
    --------
    >>> wind_judgement(load_scenario(), None)     # the lab span's shaker: no wind
    (False, 'the [forcing] is harmonic, not the wind')
    """
    forcing, sev = scenario.forcing, scenario.severity
    if forcing.kind != "aeolian":
        return False, f"the [forcing] is {forcing.kind}, not the wind"
    if not (sev.enabled and sev.time_domain):
        return False, "the [forcing] is aeolian, but [severity] time_domain is off"
    unsettled = _unsettled(scenario, span)
    return (False, unsettled) if unsettled else (wind_physics(scenario, span), "")


def self_limiting_physics(scenario: Scenario, span) -> dict:
    """``run_closed_loop``'s and ``simulate_self_limiting``'s ``wind`` for a scenario with
    ``robot.wind = "self_limiting"`` (:func:`wind_physics`), refused where that wind cannot
    settle the line ``span`` (:func:`_unsettled`), by the scenario's own names.

    Parameters
    ----------
    scenario : Scenario
        Its ``forcing``, ``model`` and ``severity`` sections.
    span : Span
        The line simulated (the truth).

    Returns
    -------
    dict

    Raises
    ------
    InputError
        Where the self-limiting wind cannot hold the energy balance.

    Examples
    --------
    >>> import powerline_control as plc
    >>> oxlip = plc.Span.at_rts_fraction(40.0, "oxlip", 0.2)
    >>> self_limiting_physics(load_scenario("drake-300m"), oxlip)
    Traceback (most recent call last):
      ...
    powerline_control.errors.InputError: robot.wind = "self_limiting" cannot simulate this \
line: the [forcing] wind speed 3 m/s sustains only ...
    """
    unsettled = _unsettled(scenario, span)
    if unsettled:
        raise InputError(f'robot.wind = "self_limiting" cannot simulate this line: {unsettled}, '
                         'or set robot.wind = "fixed_lift".')
    return wind_physics(scenario, span)


def _unsettled(scenario: Scenario, span) -> str:
    """Why the self-limiting wind of the scenario's aeolian forcing, with the severity
    section's physics, cannot settle ``span`` in a simulation
    (:func:`~powerline_control.severity.self_limiting.settling_balance`), in words; "" when it
    can."""
    from ..severity.self_limiting import settling_balance

    forcing = scenario.forcing
    _, problem = settling_balance(span, forcing.build(), scenario.model.bc,
                                  wind_physics(scenario, span))
    if problem is None:
        return ""
    return f"the [forcing] wind speed {forcing.wind_speed:g} m/s {problem}"


def wind_physics(scenario: Scenario, span) -> dict:
    """The self-limiting wind's physics the scenario sets: the severity section's power curve
    and self-damping law, its k from the severity study's rated strength
    (:func:`severity_span`): ``run_closed_loop``'s ``wind`` (with ``robot.wind =
    "self_limiting"``) and its ``aeolian_steady`` judgement alike.

    Parameters
    ----------
    scenario : Scenario
        Its ``severity`` section.
    span : Span
        The line the closed loop simulates (the truth).

    Returns
    -------
    dict
        ``wind_curve``, ``self_damping`` and ``self_damping_k``.

    Examples
    --------
    >>> import powerline_control as plc
    >>> drake = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> physics = wind_physics(load_scenario("drake-300m"), drake)
    >>> physics["wind_curve"], physics["self_damping"]
    ('cigre', 'noiseux1991')
    """
    from ..severity import SELF_DAMPING_LAWS

    sev = scenario.severity
    law = SELF_DAMPING_LAWS[sev.self_damping]
    return {"wind_curve": sev.wind_curve, "self_damping": sev.self_damping,
            "self_damping_k": law.coefficient(severity_span(scenario, span))}


def severity_inputs(scenario: Scenario, span) -> tuple[dict, str]:
    """The keyword arguments of ``aeolian_severity`` the scenario sets, and the strand source.

    Parameters
    ----------
    scenario : Scenario
        Its ``severity`` section.
    span : Span
        The span.

    Returns
    -------
    (dict, str)

    Examples
    --------
    >>> import powerline_control as plc
    >>> kwargs, source = severity_inputs(load_scenario(), plc.Span.paper_lab())
    >>> "outer_strand_diameter" in kwargs, source  # the lab conductor carries Oxlip's 3.5 mm
    (False, "assumed: the stranding of 'oxlip', the catalogue conductor Table 1 matches (the \
paper gives none)")
    """
    sev = scenario.severity
    kwargs = {"outer_strand_modulus": sev.outer_strand_modulus, "x_b": sev.clamp_distance,
              "wind_curve": sev.wind_curve, "self_damping": sev.self_damping}
    if sev.outer_strand_diameter is not None:
        kwargs["outer_strand_diameter"] = sev.outer_strand_diameter
        source = "severity.outer_strand_diameter"
    elif scenario.span.preset == "paper_lab":
        source = (f"assumed: the stranding of {LAB_CONDUCTOR!r}, the catalogue conductor "
                  "Table 1 matches (the paper gives none)")
    else:
        source = f"the conductor's stranding ({span.conductor.name})"
    return kwargs, source


def severity_assumptions(scenario: Scenario, span) -> tuple:
    """What the severity study assumes where the span gives no data, in words.

    Only the lab span (Table 1) lacks data: it takes the family, the outer strands and the rated
    strength of the catalogue conductor it matches (:data:`LAB_CONDUCTOR`), unless the
    scenario's ``[severity]`` section gives them.

    Parameters
    ----------
    scenario : Scenario
        Its ``span`` and ``severity`` sections.
    span : Span
        The span as the scenario builds it (before :func:`severity_span`).

    Returns
    -------
    tuple of str

    Examples
    --------
    >>> import powerline_control as plc
    >>> severity_assumptions(load_scenario(), plc.Span.paper_lab())[0]
    "family AAC: Table 1's 10.5 mm conductor matches the catalogue's 'oxlip' (AAC)"
    """
    from ..line import conductors

    if scenario.span.preset != "paper_lab":
        return ()
    sev, match, cond = scenario.severity, conductors[LAB_CONDUCTOR], span.conductor
    out = [f"family {cond.family}: Table 1's {1e3 * cond.diameter:g} mm conductor matches the "
           f"catalogue's {LAB_CONDUCTOR!r} ({match.family})"]
    if sev.outer_strand_diameter is None:
        out.append(f"outer strands of {1e3 * cond.outer_strand_diameter:g} mm, those of "
                   f"{LAB_CONDUCTOR!r} (the paper gives no stranding)")
    if sev.rated_strength is None and cond.rated_strength is None:
        out.append(f"rated strength {match.rated_strength / 1e3:.3g} kN, the approximate "
                   f"catalogue value of {LAB_CONDUCTOR!r} (the paper gives none)")
    return tuple(out)


def severity_span(scenario: Scenario, span):
    """The span the severity study uses: the scenario's EI and rated strength, when set.

    The lab span's conductor (Table 1) has no rated strength; the severity study takes the
    catalogue value of AAC 2/0 Oxlip, the conductor Table 1 matches (:data:`LAB_CONDUCTOR`).

    Parameters
    ----------
    scenario : Scenario
        Its ``severity`` and ``span`` sections.
    span : Span
        The span.

    Returns
    -------
    Span

    Examples
    --------
    >>> import powerline_control as plc
    >>> span = severity_span(load_scenario(), plc.Span.paper_lab())
    >>> span.conductor.rated_strength == plc.conductors[LAB_CONDUCTOR].rated_strength
    True
    """
    from ..line import conductors

    sev = scenario.severity
    changes = {}
    if sev.ei is not None:
        changes["ei"] = sev.ei
    if sev.rated_strength is not None:
        changes["rated_strength"] = sev.rated_strength
    elif span.conductor.rated_strength is None and scenario.span.preset == "paper_lab":
        changes["rated_strength"] = conductors[LAB_CONDUCTOR].rated_strength
    if not changes:
        return span
    return dataclasses.replace(span, conductor=dataclasses.replace(span.conductor, **changes))


#: The catalogue conductor the paper's lab span (Table 1) matches.
LAB_CONDUCTOR = "oxlip"


def _severity(scenario: Scenario, span, tuning: Tuning) -> Severity:
    import numpy as np

    from ..severity import ENDURANCE_FAMILY, AtAntinode, aeolian_severity

    assumptions = severity_assumptions(scenario, span)
    span = severity_span(scenario, span)
    sev = scenario.severity
    kwargs, source = severity_inputs(scenario, span)
    speeds = np.asarray(sev.wind_speeds, dtype=float)
    bare = aeolian_severity(span, wind_speeds=speeds, **kwargs)
    robot = tuning.robot
    # the robot's power from the line and robot coupled: its impedance on a real span is many
    # times the line's wave impedance, where the first-order power overstates it several-fold
    with_robot = aeolian_severity(span, wind_speeds=speeds, dampers=[AtAntinode(robot)],
                                  damper_model="coupled", **kwargs)
    strand = kwargs.get("outer_strand_diameter", span.conductor.outer_strand_diameter)
    time_domain, skipped = _time_domain(scenario, span, tuning)
    return Severity(bare=bare, robot=with_robot, outer_strand_diameter=float(strand),
                    strand_source=source, assumptions=assumptions,
                    endurance_applies=span.conductor.family == ENDURANCE_FAMILY,
                    rated_strength=float(span.conductor.rated_strength or float("nan")),
                    time_domain=time_domain, time_domain_skipped=skipped,
                    robot_frequency=float(np.sqrt(robot.stiffness / robot.suspended_mass)
                                          / (2 * np.pi)))


def _time_domain(scenario: Scenario, span,
                 tuning: Tuning) -> tuple[SeverityTimeDomain | None, str]:
    """The energy balance at the scenario's aeolian wind speed, checked in the time domain with
    the same powers: no damper, the robot parked at the antinode, and parked near the clamp as
    a fixed damper would be; None when not asked for or the forcing is not the wind, and None
    with the reason (else "") where the simulated wind cannot settle the line
    (:func:`_unsettled`)."""
    import dataclasses

    from ..severity import harmonic_mean_position, simulate_aeolian

    sev, forcing = scenario.severity, scenario.forcing
    if not sev.time_domain or forcing.kind != "aeolian":
        return None, ""
    unsettled = _unsettled(scenario, span)
    if unsettled:
        return None, unsettled
    settings = {"bc": scenario.model.bc, "wind_curve": sev.wind_curve,
                "self_damping": sev.self_damping}
    speed = forcing.wind_speed
    parked = functools.partial(dataclasses.replace, tuning.robot)
    return SeverityTimeDomain(
        bare=simulate_aeolian(span, speed, **settings),
        at_antinode=simulate_aeolian(span, speed, parked(position=tuning.antinode), **settings),
        near_clamp=simulate_aeolian(span, speed, parked(position=harmonic_mean_position(span)),
                                    **settings)), ""


def read_wind_record(wind_record) -> tuple:
    """A wind record and where it came from: a :class:`~powerline_control.WindRecord` as is,
    or a CSV file read with :meth:`WindRecord.from_csv` (its errors name the file).

    Parameters
    ----------
    wind_record : WindRecord, str or Path
        The record or its CSV file.

    Returns
    -------
    (WindRecord, str)

    Raises
    ------
    InputError
        A file that cannot be read, or a bad column or row (named with the file).

    Examples
    --------
    >>> import powerline_control as plc
    >>> record, source = read_wind_record(plc.WindRecord.constant(3.0, n_records=2))
    >>> record.n_records, source   # a record's own source, or "a WindRecord given to ..."
    (2, 'constant 3 m/s')
    """
    import os

    from ..severity import WindRecord

    if isinstance(wind_record, WindRecord):
        return wind_record, wind_record.source or "a WindRecord given to run_scenario"
    if not isinstance(wind_record, str | os.PathLike):
        raise InputError(f"The 'wind_record' parameter must be a WindRecord or the path of its "
                         f"CSV file. Got {type(wind_record).__name__}.")
    path = os.fspath(wind_record)
    try:
        return WindRecord.from_csv(path), path
    except InputError as exc:
        message = " ".join(str(exc).split())
        if path in message:
            raise
        raise InputError(f"The wind record {path!r}: {message}") from None


def _fatigue(scenario: Scenario, span, tuning: Tuning, record, source: str) -> Fatigue:
    """``fatigue_over_record`` on the severity study's span, with the scenario's tuned robot,
    its limits and the severity study's clamp and strand inputs."""
    from ..plan import RobotLimits
    from ..severity import fatigue_over_record

    span = severity_span(scenario, span)
    kwargs, _ = severity_inputs(scenario, span)
    cfg = scenario.robot
    life = fatigue_over_record(span, record, tuning.robot, RobotLimits(cfg.v_max, cfg.a_max),
                               **kwargs)
    return Fatigue(life=life, record=record, source=source)


def _with_record_sensors(scenario: Scenario, record) -> tuple:
    """The scenario measuring where the record's channels are (its sample interval checked),
    and the record without its channels on a support (they carry no information)."""
    import math

    from ..output.records import Record

    if not isinstance(record, Record):
        raise InputError(f"The 'record' parameter must be a Record (load_record). Got "
                         f"{type(record).__name__}.")
    record = record.without_supports(scenario.span_length())
    record.check_span(scenario.span_length())
    if not math.isclose(record.dt, scenario.simulation.dt, rel_tol=1e-6):
        raise InputError(f"{record.source}: sampled at dt = {record.dt:g} s, but the scenario's "
                         f"model runs at simulation.dt = {scenario.simulation.dt:g} s: set "
                         f"simulation.dt = {record.dt:g} or resample the record.")
    est = dataclasses.replace(scenario.estimation, sensors=None,
                              sensor_positions=tuple(float(x) for x in record.positions))
    return dataclasses.replace(scenario, estimation=est), record


def _measured(record, ident: Identification, x) -> MeasuredEstimate:
    import numpy as np

    x = np.asarray(x)
    nearest = [int(np.argmin(np.abs(x - p))) for p in record.positions]
    order = sorted(range(len(nearest)), key=lambda i: nearest[i])
    nodes, rows = [], []
    for i in order:
        if nearest[i] not in nodes:
            nodes.append(nearest[i])
            rows.append(i)
    y = np.asarray(record.values)[rows]
    with warnings.catch_warnings():
        # the Record named its saturated channels by column when it was made
        warnings.simplefilter("ignore", SaturationWarning)
        estimate = layout_filter(ident.design, nodes).filter(y)
    return MeasuredEstimate(record=record, nodes=tuple(nodes), estimate=estimate)
