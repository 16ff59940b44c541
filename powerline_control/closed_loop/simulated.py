"""The simulated line of a closed-loop run: the FE model's modal plant and its loads, the
estimator calibrated with the robot parked at its start, the run's records, and the steps that
simulate, sense and filter a block of samples. :mod:`.loop` drives them. The line is the truth:
the policy never sees it, only the :class:`Measurements` it hands over (what the sensors and the
robot record); the policy predicts with its own :class:`~.belief.Belief`."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .._validation import check_indices, check_int, check_real, read_only
from ..errors import InputError
from ..estimate import KalmanFilter, windowed_consistency
from ..fem import MDR, LineModel
from ..line import Span
from ..recipe import design_estimator
from ..severity.self_limiting import SelfLimitingWind, self_limiting_wind
from ..simulation.held_damping import step_unforced
from ..simulation.plant import (
    SMALL_PLANT_MODES,
    ModalPlant,
    default_modes,
    load_histories,
    nodal_field,
    run_parked,
)
from .robot_input import RobotInputModel, process_noise_of, robot_input_filter
from .settings import Settings

#: The closed loop's estimators: the recipe's, identified with the robot parked at its start,
#: and the bare line's modal model with the robot's measured force as an input
#: (:mod:`.robot_input`).
ESTIMATORS = ("recipe", "robot_input")


def _calibrated_filter(record, dt, sensors, delays, noise_std, rank):
    """The estimator recipe (:func:`~powerline_control.recipe.design_estimator`) on the
    calibration record with the given sensors: filter, field map and state-space model."""
    options = {} if delays is None else {"delays": delays}
    if rank is not None:
        options["rank"] = rank
    design = design_estimator(record, len(sensors), dt=dt, sensors=list(sensors),
                              noise_std=noise_std if noise_std > 0 else None, **options)
    return (design.filter, np.asarray(design.model.field_map),
            design.model.to_statespace(measured=list(sensors)))


@dataclass(frozen=True, eq=False)
class SimulatedLine:
    """The simulated line (the truth): the bare FE model, the plant with and without the robot,
    the loads, and what the judge (:mod:`.evaluation`) compares on. Nothing here reaches the
    policy but the measurements (:class:`Measurements`)."""

    span: Span
    bare: LineModel
    sensors: tuple              # measured node indices, sorted (the estimator's output order)
    sensor_rows: np.ndarray     # (p, r): the plant modes' displacements at the sensors
    clamp_distance: float       # where the "near_clamp" comparison parks the robot, m
    t: np.ndarray               # (n_t,) sample times, s
    plant: ModalPlant          # with the robot
    free_plant: ModalPlant     # without it (the "no_robot" comparison)
    plant_steps: int            # samples per plant block (the robot's position held)
    modal_force: np.ndarray     # (n_t, r)
    residual: np.ndarray        # (n_nodes, n_t): the dropped modes' response to the loads
    harmonic: tuple | None      # (frequency, parts) of the last load when it is one sine
    weights: np.ndarray         # (n_nodes,) trapezoid weights: the judge's span RMS
    load_frequencies: tuple     # the loads' frequencies, Hz: the band the plants keep
    wind: SelfLimitingWind | None = None   # the self-limiting wind (None: the loads as given)

    @property
    def sensor_positions(self) -> np.ndarray:
        """Where the sensors measure, m (what the controller is told of them)."""
        return self.bare.node_positions[list(self.sensors)]


def build_line(robot, segments, settings: Settings, sensors, *, n_modes,
               clamp_distance, wind: dict | None = None) -> SimulatedLine:
    """The sensors on the FE model, the modal plant and the loads' histories. ``wind``: the
    self-limiting wind's options (:func:`~powerline_control.severity.self_limiting.checked_wind`),
    which replace the AeolianForce's lift (no load history: the wind is the plant's negative
    damping); None: the loads as given."""
    bare = settings.bare
    span = bare.span
    sensors = tuple(sorted(check_indices("sensors", sensors, bare.n_nodes).tolist()))
    fixed_nodes = [j for j in sensors if bare.displacement_map()[[j]].nnz == 0]
    if fixed_nodes:
        raise InputError(
            f"The 'sensors' parameter names support node(s) {fixed_nodes}, where the line does "
            "not move: the estimator's model has no displacement there."
        )
    clamp_distance = (
        min(0.05 * span.length, 1.5)
        if clamp_distance is None
        else check_real("clamp_distance", clamp_distance, low=0.0, high=span.length)
    )
    t = settings.dt * np.arange(settings.n_samples)
    load_frequencies = [
        float(b.frequency)
        for _, loads in segments
        for f in loads
        for b in [f.bind(bare) if hasattr(f, "bind") else f]
        if getattr(b, "frequency", None) is not None   # a user's load may say None: not a sine
    ]
    nyquist = 0.5 / settings.dt
    for frequency in load_frequencies:  # a mesh too coarse for the load: TruncationWarning
        bare.check_resolution(frequency, "load")
        if frequency >= nyquist:   # the sensors would alias it: the robot would chase the alias
            raise InputError(
                f"The 'dt' parameter ({settings.dt:g} s) cannot sample the load at "
                f"{frequency:g} Hz: it lies at or above the Nyquist frequency {nyquist:g} Hz. "
                f"Use dt < 1 / (2 x {frequency:g} Hz) = {0.5 / frequency:.6g} s."
            )
    if n_modes is None:
        n_modes = default_modes(span, bare, load_frequencies, settings.dt)
    else:
        n_modes = check_int("n_modes", n_modes, low=1, high=bare.n_dofs)
    loads = [load for _, items in segments for load in items]
    # the self-limiting wind applies no load: no Ritz vectors of it (the robot is still re-tuned
    # for the flexibility the band misses at the wind's frequency)
    plant = ModalPlant(bare, robot, n_modes, settings.dt, loads=loads, ritz=wind is None)
    plant_steps = settings.plant_steps
    if plant_steps is None:
        # 10 ms blocks, or one block per control period for a long span's band of ~100 modes
        # (each new position costs an exponential of a (4r + 2)-square matrix).
        plant_steps = (
            settings.steps_per_period
            if plant.r > SMALL_PLANT_MODES
            else max(1, min(settings.steps_per_period, int(round(0.01 / settings.dt))))
        )
    free_plant = ModalPlant(bare, None, n_modes, settings.dt, loads=loads, ritz=wind is None)
    self_limiting = None
    if wind is not None:
        # the wind acts as the plant's negative damping only: no lift, no load residual, and
        # no exact steady state of a sine to compare placements in
        modal_force, residual, harmonic = (np.zeros((t.size, plant.r)),
                                           np.zeros((bare.n_nodes, t.size)), None)
        self_limiting = self_limiting_wind(wind, plant, free_plant, plant_steps)
    else:
        modal_force, residual, harmonic = load_histories(bare, plant, segments, t)
    if wind is None and not (np.any(modal_force) or np.any(residual)):
        given = [load for _, items in segments for load in items]
        raise InputError(
            "The 'force' parameter puts no load on the line: it is empty or acts only at a "
            f"support, so there is no vibration to damp. Got {given!r}."
        )
    return SimulatedLine(
        span=span, bare=bare, sensors=sensors, sensor_rows=plant.nodal[list(sensors)],
        clamp_distance=clamp_distance, t=t, plant=plant, free_plant=free_plant,
        plant_steps=plant_steps, modal_force=modal_force, residual=residual, harmonic=harmonic,
        weights=bare.span_weights, load_frequencies=tuple(load_frequencies),
        wind=self_limiting,
    )


@dataclass(frozen=True, eq=False)
class Calibration:
    """The estimator, designed on the first window with the robot parked at its start."""

    start_states: np.ndarray    # (n_t, 2 n_q): the plant parked at the start for the whole run
    noise_std: float            # the sensors' noise, m
    record: np.ndarray          # (n_nodes, n_cal) noisy calibration field
    robot_record: np.ndarray    # (n_cal,) noisy line displacement under the robot
    estimator: Estimator        # warmed up on the record; it keeps stepping in the loop
    innovation_power: np.ndarray  # (n_cal,) its one-step errors' mean square per sample (0
    #                               for the first two)
    robot_force: np.ndarray     # (n_cal,) the robot's measured force on the line, N (zeros
    #                             for the recipe's estimator, which does not use it)
    force_noise: tuple = (0.0, None)   # (std, N; its own generator): the robot's force sensor


@dataclass(frozen=True, eq=False)
class Estimator:
    """One estimator of the run and the states it estimated.

    The run starts with the calibration's; with ``estimator="robot_input"`` a new one takes
    over when the line believed or the load's tone changes (:func:`rebuild_estimator`).
    ``states`` holds its states from sample ``first`` on (row 0: sample ``first``); it owns the
    run's estimate after ``first`` (from sample 0 for the first), until the next one's
    ``first``. Its filter's consistency windows start at sample ``windows_from``; its process
    noise was matched on the samples ``matched_on`` (start, stop).
    """

    kf: KalmanFilter
    field_map: np.ndarray       # its states -> nodal displacements
    predict_sensors: np.ndarray  # one-step sensor predictor C A (the innovation check)
    input_model: RobotInputModel | None   # the robot's force as an input, or None
    predict_inputs: np.ndarray | None     # C B of the input model (None without one)
    innovation_rms: float       # RMS one-step error of the sensors over its own record
    first: int
    windows_from: int
    states: np.ndarray          # (n_t - first, n_states)
    matched_on: tuple = (0, 0)  # (start, stop) samples


def robot_force(plant: ModalPlant, states: np.ndarray, modal_force: np.ndarray,
                x: float, line_damping: np.ndarray | None = None) -> np.ndarray:
    """The robot's force on the line (N) at each of the plant's ``states`` ``(n, 2 n_q)`` with
    the robot at ``x``: its body's inertia and its absorber's spring and damper force, what the
    robot's own accelerometer and absorber measure (the plant's accelerations, exact with the
    line's modal damping ``line_damping``, None: the plant's own)."""
    if plant.robot is None:
        return np.zeros(states.shape[0])
    mass, damp, stiff = plant.matrices(x, line_damping)
    nq, r = plant.n_q, plant.r
    load = np.zeros((states.shape[0], nq))
    load[:, :r] = modal_force
    acceleration = np.linalg.solve(
        mass, (load - states[:, nq:] @ damp.T - states[:, :nq] @ stiff.T).T).T
    n = plant.coupling(x)
    body, spring, damper = plant.robot_parameters(x)
    force = -body * (acceleration[:, :r] @ n)
    if plant.absorber:
        force -= spring * (states[:, :r] @ n - states[:, r])
        force -= damper * (states[:, nq : nq + r] @ n - states[:, nq + r])
    return force


def calibrate(line: SimulatedLine, robot: MDR, settings: Settings, rng, *,
              estimator: str = "recipe", told: LineModel | None = None) -> Calibration:
    """Simulate the parked start, add sensor noise, identify the estimator and warm it up.

    ``estimator`` is one of :data:`ESTIMATORS`; "robot_input" builds its model from ``told``
    (what the controller is told of the line; None: the simulated line's own mesh, the
    controller told the truth) and the robot's force record."""
    n_cal, sensor_list = settings.n_cal, list(line.sensors)
    start_states = (run_parked(line.plant, robot.position, line.modal_force, line.t.size)
                    if line.wind is None else line.wind.parked(robot.position, line.t.size))
    calib_true = nodal_field(line.plant, start_states[:n_cal], line.residual[:, :n_cal])
    calib_rms = float(np.sqrt(np.mean(calib_true**2)))
    noise_std = settings.noise_fraction * calib_rms
    record = calib_true + noise_std * rng.standard_normal(calib_true.shape)
    forces, force_noise, driven = np.zeros(n_cal), (0.0, None), None
    if estimator == "robot_input":
        forces, force_noise = _robot_force_record(line, start_states[:n_cal], robot.position,
                                                  settings.noise_fraction, rng)
        kf, input_model, states = robot_input_filter(
            line.bare if told is None else told, settings.dt,
            line.sensor_positions, line.bare.node_positions, record[sensor_list],
            np.full(n_cal, robot.position), forces, noise_std)
        field_map, system = input_model.field_map, input_model.system
        driven = input_model.inputs(np.full(n_cal, robot.position), forces)
    else:
        kf, field_map, system = _calibrated_filter(
            record, settings.dt, sensor_list, settings.delays, noise_std,
            settings.estimator_rank
        )
        input_model = None
        states = np.asarray(kf.filter(record[sensor_list], update_state=True).states)
    warmed, innovation_power = _warmed(kf, field_map, system, input_model, record[sensor_list],
                                       states, driven, first=0, windows_from=0,
                                       n_t=line.t.size, matched_on=(0, n_cal))
    robot_record = start_states[:n_cal, : line.plant.r] @ line.plant.coupling(robot.position) + (
        noise_std * rng.standard_normal(n_cal)
    )
    return Calibration(
        start_states=start_states, noise_std=noise_std, record=record,
        robot_record=robot_record, estimator=warmed, innovation_power=innovation_power,
        robot_force=forces, force_noise=force_noise,
    )


def _warmed(kf: KalmanFilter, field_map: np.ndarray, system, input_model, record: np.ndarray,
            states: np.ndarray, driven: np.ndarray | None, *, first: int, windows_from: int,
            n_t: int, matched_on: tuple) -> tuple[Estimator, np.ndarray]:
    """The :class:`Estimator` of a filter warmed on ``record`` ``(p, n)`` (its states over it
    ``(n_states, n)``, from sample ``windows_from``; the robot's modal forces ``driven``
    ``(m, n - 1)`` at samples 1..n-1, or None), and its one-step errors' mean square per
    sample of the record (0 for the first two)."""
    n = record.shape[1]
    warm = np.ascontiguousarray(states.T)   # C order, as the run's state history
    c = np.asarray(system.C)
    predict_sensors = c @ np.asarray(system.A)
    predict_inputs = None if driven is None else c @ np.asarray(system.B)
    innovation = record[:, 2:] - predict_sensors @ warm[1 : n - 1].T
    if driven is not None:
        innovation -= predict_inputs @ driven[:, : n - 2]
    power = np.zeros(n)
    power[2:] = np.mean(innovation**2, axis=0)
    history = np.empty((n_t - first, warm.shape[1]))
    history[: windows_from + n - first] = warm[first - windows_from :]
    return Estimator(kf=kf, field_map=field_map, predict_sensors=predict_sensors,
                     input_model=input_model, predict_inputs=predict_inputs,
                     innovation_rms=float(np.sqrt(np.mean(innovation**2))), first=first,
                     windows_from=windows_from, states=history, matched_on=matched_on), power


def rebuild_estimator(records: Records, told: LineModel, settings: Settings, k: int,
                      noise_std: float, sensor_positions, node_positions, *,
                      new_load: bool) -> None:
    """A new "robot_input" estimator on the line the controller believes (``told``) and the
    tone the sensors show, warmed on the sensors' and the robot's records of the last
    calibration window's length up to sample k (from the start of a consistency window, so
    that the run's windows stay whole); it takes over from sample k + 1 (:class:`Estimator`).

    Its process noise is matched on that record when the load is new (``new_load``: the tone
    changed, and its strength with it); else on the record the running estimator's was
    matched on, with the new model (a line believed better leaves less model error to be
    taken for load)."""
    running = records.estimators[-1]
    window = running.kf.consistency_window or 1
    start = max((k + 1 - settings.n_cal) // window * window, 0)
    record = records.measured[:, start : k + 1]
    positions, forces = records.position[start : k + 1], records.robot_force[start : k + 1]
    built = {"told": told, "dt": settings.dt, "sensor_positions": sensor_positions,
             "node_positions": node_positions, "noise_std": noise_std}
    near = process_noise_of(running.kf)
    if new_load:
        matched_on = (start, k + 1)
        kf, model, states = robot_input_filter(record=record, positions=positions,
                                               forces=forces, near=near, **built)
    else:
        matched_on = running.matched_on
        span = slice(*matched_on)
        matched, _, _ = robot_input_filter(record=records.measured[:, span],
                                           positions=records.position[span],
                                           forces=records.robot_force[span], near=near, **built)
        kf, model, states = robot_input_filter(record=record, positions=positions,
                                               forces=forces,
                                               process_noise=process_noise_of(matched), **built)
    estimator, _ = _warmed(kf, model.field_map, model.system, model, record, states,
                           model.inputs(positions, forces), first=k, windows_from=start,
                           n_t=records.position.size, matched_on=matched_on)
    records.estimators.append(estimator)


def run_estimate(estimators: list[Estimator]) -> np.ndarray:
    """The run's estimated field ``(n_nodes, n_t)``: each estimator's after its ``first``
    sample (the first's from sample 0), to the next one's."""
    n_t = estimators[0].first + estimators[0].states.shape[0]
    ends = [e.first for e in estimators[1:]] + [n_t - 1]
    pieces = []
    for i, (estimator, end) in enumerate(zip(estimators, ends, strict=True)):
        lo = 0 if i == 0 else 1
        pieces.append(estimator.field_map @ estimator.states[lo : end + 1 - estimator.first].T)
    return np.hstack(pieces)


def run_consistency(estimators: list[Estimator]):
    """The windowed NIS test over the run
    (:func:`~powerline_control.estimate.windowed_consistency`): each window from the estimator
    that owns its last sample (:class:`Estimator`)."""
    window = estimators[0].kf.consistency_window
    if window is None:
        return None
    n_t = estimators[0].first + estimators[0].states.shape[0]
    firsts = np.array([e.first for e in estimators[1:]])
    rows = []
    for j in range(n_t // window):
        owner = estimators[int(np.sum(firsts < (j + 1) * window - 1))]
        closed = owner.kf.consistency_windows
        local = j - owner.windows_from // window
        if not 0 <= local < closed.shape[0]:
            break
        rows.append(closed[local])
    return windowed_consistency(np.array(rows), window, estimators[-1].kf.nis_dof_fraction)


def _robot_force_record(line: SimulatedLine, states: np.ndarray, x: float,
                        noise_fraction: float, rng) -> tuple[np.ndarray, tuple]:
    """The robot's noisy force record over the parked calibration window, and its sensor's
    (noise std, generator): the same relative noise as the line's sensors, from a generator of
    its own (spawned: the sensors' noise stays what it is without the force)."""
    n = states.shape[0]
    # in the self-limiting wind the line's damping moves with its amplitude: the window's
    # middle's (its share of the accelerations is of the order of the damping ratio, 1e-3)
    damping = None if line.wind is None else line.wind.damping.matrix(states[n // 2])
    true = robot_force(line.plant, states, line.modal_force[:n], x, damping)
    std = noise_fraction * float(np.sqrt(np.mean(true**2)))
    force_rng = rng.spawn(1)[0]
    return true + std * force_rng.standard_normal(n), (std, force_rng)


@dataclass(frozen=True, eq=False)
class Measurements:
    """What the simulated line hands the controller: the sensors' and the robot's noisy records
    and the robot's own motion, filled in as the run goes (views of :class:`Records`' arrays).
    Nothing of the line itself (its span, model, plant or states)."""

    t: np.ndarray               # (n_t,) sample times, s
    sensor_positions: np.ndarray  # (p,) where the sensors measure, m
    sensors: np.ndarray         # (p, n_t) noisy sensor displacements, m
    robot: np.ndarray           # (n_t,) noisy line displacement under the robot, m
    position: np.ndarray        # (n_t,) the robot's position, m (its own odometry)
    velocity: np.ndarray        # (n_t,) the robot's velocity, m/s


@dataclass(eq=False)
class Records:
    """What the run records: histories over every sample (filled as it goes; the calibration
    window first) and a log of every control step."""

    plant_states: np.ndarray    # (n_t, 2 n_q) true plant states
    estimators: list            # the run's Estimators, in turn (the last one steps)
    position: np.ndarray        # (n_t,) robot position, m
    velocity: np.ndarray        # (n_t,) robot velocity, m/s
    target: np.ndarray          # (n_t,) the goal steered to (NaN before the first)
    measured: np.ndarray        # (p, n_t) noisy sensor displacements
    robot_measured: np.ndarray  # (n_t,) noisy line displacement under the robot
    innovation_power: np.ndarray  # (n_t,) mean square one-step prediction error of the sensors
    robot_force: np.ndarray     # (n_t,) the robot's measured force on the line, N (zeros
    #                             unless the estimator uses it)
    statuses: list = field(default_factory=list)
    frequencies: list = field(default_factory=list)
    innovation_ratio: list = field(default_factory=list)
    retarget_times: list = field(default_factory=list)
    target_starts: list = field(default_factory=list)   # sample index of each new target
    predictions: list = field(default_factory=list)
    decisions: list = field(default_factory=list)       # (time, what the policy decided)
    misfits: list = field(default_factory=list)   # (time, position, measured vs predicted)
    contradictions: list = field(default_factory=list)  # (time, what the policy did about it)
    estimator_updates: list = field(default_factory=list)  # (time, why) of each rebuild
    expected: tuple | None = None   # (goal, tone, the sensors' phasors predicted there)

    @classmethod
    def after_calibration(cls, line: SimulatedLine, calibration: Calibration, robot: MDR,
                          n_cal: int) -> Records:
        """Histories for the whole run, the calibration window's filled in."""
        n_t = line.t.size
        records = cls(
            plant_states=np.empty((n_t, calibration.start_states.shape[1])),
            estimators=[calibration.estimator],
            position=np.full(n_t, robot.position),
            velocity=np.zeros(n_t),
            target=np.full(n_t, np.nan),
            measured=np.zeros((len(line.sensors), n_t)),
            robot_measured=np.zeros(n_t),
            innovation_power=np.zeros(n_t),
            robot_force=np.zeros(n_t),
        )
        records.plant_states[:n_cal] = calibration.start_states[:n_cal]
        records.measured[:, :n_cal] = calibration.record[list(line.sensors)]
        records.robot_measured[:n_cal] = calibration.robot_record
        records.innovation_power[:n_cal] = calibration.innovation_power
        records.robot_force[:n_cal] = calibration.robot_force
        return records

    def measurements(self, line: SimulatedLine) -> Measurements:
        """The controller's view of these records (the same arrays, filled as the run goes)."""
        return Measurements(t=line.t, sensor_positions=read_only(line.sensor_positions),
                            sensors=self.measured, robot=self.robot_measured,
                            position=self.position, velocity=self.velocity)


def advance_plant(plant_state: np.ndarray, records: Records, line: SimulatedLine,
                  calibration: Calibration, rng, timings: dict, k: int, end: int) -> np.ndarray:
    """Simulate and sense samples k..end in blocks that hold the robot's mid-block position,
    then filter them (the filter acts on nothing before the next control step); leaves the
    loop's state at sample end."""
    j = k
    while j < end:
        block_end = min(j + line.plant_steps, end)
        x_mid = 0.5 * (records.position[j] + records.position[block_end])
        tic = time.perf_counter()
        if line.wind is None:
            maps = line.plant.discretise(x_mid)
        else:   # the self-limiting wind: the damping of the block's start, no lift
            phi = line.wind.held.transition(x_mid, plant_state)
        at_robot = line.plant.coupling(x_mid)
        timings["plant update"] += time.perf_counter() - tic
        tic = time.perf_counter()
        if line.wind is None:
            plant_state = _step_plant(plant_state, maps, records, line.modal_force, j,
                                      block_end)
        else:
            records.plant_states[j] = plant_state
            step_unforced(phi, records.plant_states, j, block_end)
            plant_state = records.plant_states[block_end].copy()
        _sense(records, line, at_robot, calibration.noise_std, rng, j, block_end)
        if calibration.estimator.input_model is not None:
            _sense_force(records, line, calibration.force_noise, x_mid, j, block_end)
        timings["plant"] += time.perf_counter() - tic
        j = block_end
    tic = time.perf_counter()
    _kalman_steps(records, records.measured[:, k + 1 : end + 1].T, k, end)
    timings["filter"] += time.perf_counter() - tic
    return plant_state


def _step_plant(z: np.ndarray, maps: tuple, records: Records, modal_force: np.ndarray,
                j: int, block_end: int) -> np.ndarray:
    """The plant's exact first-order-hold steps from sample j to block_end, recorded; the last
    state."""
    phi, g0, g1 = maps
    states = records.plant_states
    states[j] = z
    states[j + 1 : block_end + 1] = (modal_force[j:block_end] @ g0.T
                                     + modal_force[j + 1 : block_end + 1] @ g1.T)
    for i in range(j, block_end):
        states[i + 1] += phi @ states[i]   # drive first: the sums of phi @ z + drive
    return states[block_end].copy()


def _sense(records: Records, line: SimulatedLine, at_robot: np.ndarray, noise_std: float, rng,
           j: int, block_end: int) -> None:
    """The sensors' and the robot's noisy displacements over samples j+1..block_end, recorded."""
    sensor_list = list(line.sensors)
    block = records.plant_states[j + 1 : block_end + 1, : line.plant.r]
    y_block = block @ line.sensor_rows.T + line.residual[sensor_list, j + 1 : block_end + 1].T
    robot_block = block @ at_robot
    if noise_std:
        y_block = y_block + noise_std * rng.standard_normal(y_block.shape)
        robot_block = robot_block + noise_std * rng.standard_normal(robot_block.shape)
    records.measured[:, j + 1 : block_end + 1] = y_block.T
    records.robot_measured[j + 1 : block_end + 1] = robot_block


def _sense_force(records: Records, line: SimulatedLine, force_noise: tuple, x: float, j: int,
                 block_end: int) -> None:
    """The robot's noisy force on the line over samples j+1..block_end, recorded."""
    std, force_rng = force_noise
    true = robot_force(line.plant, records.plant_states[j + 1 : block_end + 1],
                       line.modal_force[j + 1 : block_end + 1], x,
                       None if line.wind is None else line.wind.held.matrix)
    records.robot_force[j + 1 : block_end + 1] = true + std * force_rng.standard_normal(
        true.size)


def _kalman_steps(records: Records, y_block: np.ndarray, j: int, block_end: int) -> None:
    """The running estimator's steps on the block's measurements (with the robot's force as an
    input when it takes it), and its one-step innovations."""
    estimator = records.estimators[-1]
    model, rows = estimator.input_model, slice(j + 1 - estimator.first,
                                               block_end + 1 - estimator.first)
    history = estimator.states
    if model is None:
        history[rows] = estimator.kf.step_block(y_block.T).T
        predicted = history[j - estimator.first : block_end - estimator.first] @ (
            estimator.predict_sensors.T)
    else:
        inputs = model.inputs(records.position[j - 1 : block_end + 1],
                              records.robot_force[j - 1 : block_end + 1])
        history[rows] = estimator.kf.step_block(y_block.T, inputs[:, 1:]).T
        predicted = (history[j - estimator.first : block_end - estimator.first]
                     @ estimator.predict_sensors.T
                     + inputs[:, :-1].T @ estimator.predict_inputs.T)   # samples j..block_end - 1
    records.innovation_power[j + 1 : block_end + 1] = np.mean((y_block - predicted) ** 2, axis=1)
