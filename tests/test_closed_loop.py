"""The closed loop: the robot settles where the line vibrates least, from three sensors.

Truth comes from outside the closed loop's own plant: the full finite-element model (dense
complex solves of K - w^2 M + i w C with the robot attached) for steady states, plc.simulate for
transients, and conservation of energy for the integrator.
"""

import re

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import powerline_control as plc
from powerline_control.closed_loop import run_closed_loop
from powerline_control.closed_loop.policy import reach_within as _reach
from powerline_control.fem import tune_damper
from powerline_control.simulation.plant import ModalPlant as _ModalPlant

LAB = plc.Span.paper_lab()
N_EL = 60
ZETA = 0.003  # lightly damped line: start-up transients of undriven modes die out in ~2-4 s
BARE = plc.LineModel(LAB, N_EL)
FREQS = BARE.natural_frequencies(6)
SENSORS = [11, 23, 47]


def _robot(mode, start):
    """0.03 kg body + 0.04 kg absorber tuned (Den Hartog) to `mode` at its first antinode."""
    tuned = tune_damper(BARE, mode, LAB.length / (2 * mode), 0.04, body_mass=0.03)
    return plc.MDR(start, tuned.body_mass, tuned.suspended_mass, tuned.stiffness, tuned.damping)


def _fe_line_matrices():
    """Dense bare-line M, K and its modal damping (2 zeta omega per mode) as M Phi Z Phi^T M."""
    basis = BARE.modes()
    mass = BARE.mass_matrix.toarray()
    mode_damping = np.diag(2 * ZETA * np.asarray(basis.omega))
    shapes = np.asarray(basis.shapes)
    return mass, BARE.stiffness_matrix.toarray(), mass @ shapes @ mode_damping @ shapes.T @ mass


M_LINE, K_LINE, C_LINE = _fe_line_matrices()
NODAL = BARE.displacement_map().toarray()
_x = BARE.node_positions
WEIGHTS = np.zeros_like(_x)
WEIGHTS[1:] += 0.5 * np.diff(_x)
WEIGHTS[:-1] += 0.5 * np.diff(_x)
WEIGHTS /= WEIGHTS.sum()


def _fe_steady_rms(robot, position, force):
    """Steady-state RMS over the span (length-weighted) with the robot parked at `position`:
    the full FE line plus the robot's body mass and its absorber DOF (spring k, damper c)."""
    omega = 2 * np.pi * force.frequency
    n = M_LINE.shape[0]
    s = BARE.shape_vector(position)
    dynamic = np.zeros((n + 1, n + 1), dtype=complex)
    dynamic[:n, :n] = K_LINE - omega**2 * (M_LINE + robot.body_mass * np.outer(s, s))
    dynamic[:n, :n] += 1j * omega * C_LINE
    spring = robot.stiffness + 1j * omega * robot.damping
    coupling = np.append(s, -1.0)
    dynamic += spring * np.outer(coupling, coupling)
    dynamic[n, n] -= omega**2 * robot.suspended_mass
    load = np.zeros(n + 1, dtype=complex)
    load[:n] = force.amplitude * BARE.point_load(force.position)  # |phasor| of a sine
    response = np.linalg.solve(dynamic, load)
    return float(np.sqrt(0.5 * WEIGHTS @ np.abs(NODAL @ response[:n]) ** 2))


@threadpool_limits.wrap(limits=1, user_api="blas")  # thousands of small solves: one thread
def _fe_best(robot, force, low=0.02, high=LAB.length - 0.02):
    grid = np.linspace(low, high, 91)
    rms = np.array([_fe_steady_rms(robot, p, force) for p in grid])
    i = int(np.argmin(rms))
    fine = np.linspace(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)], 11)
    fine_rms = np.array([_fe_steady_rms(robot, p, force) for p in fine])
    return float(fine[np.argmin(fine_rms)]), float(fine_rms.min())


def _rms_over(result, t0, t1):
    mask = (result.t >= t0) & (result.t <= t1)
    return float(np.sqrt(np.mean(WEIGHTS @ result.displacement[:, mask] ** 2)))


# (mode, frequency / natural frequency, force position / L, seed): on and off resonance (within
# the band where a tuned absorber at the antinode beats the bare node by > 3x), two modes.
CASES = [(3, 1.0, 0.41, 21), (3, 0.988, 0.29, 5), (4, 1.012, 0.63, 8), (4, 0.995, 0.41, 3)]


@pytest.fixture(scope="module", params=CASES, ids=lambda c: f"mode{c[0]}-{c[1]}-seed{c[3]}")
def settled_case(request):
    mode, ratio, where, seed = request.param
    node = LAB.length / mode  # the first interior node of the driven mode: the worst start
    robot = _robot(mode, node)
    force = plc.HarmonicForce(1.0, ratio * FREQS[mode - 1], where * LAB.length)
    result = run_closed_loop(LAB, force, robot, sensors=SENSORS, n_elements=N_EL,
                             damping=plc.ModalDamping(ZETA), duration=12.0, calibration=2.0,
                             seed=seed)
    return mode, robot, force, result


def test_robot_settles(settled_case):
    mode, _, _, result = settled_case
    last = result.t >= result.t[-1] - 3.0  # the test's own window: the last 3 s
    loop = LAB.length / mode
    assert np.ptp(result.robot_position[last]) < 0.02 * loop
    # The goal itself does not drift (the old policy's goal wandered with the damped field).
    assert np.ptp(result.target[last]) < 0.01 * loop
    assert result.settled


def test_line_ends_near_the_best_parked_position_and_far_below_the_start(settled_case):
    _, robot, force, result = settled_case
    best_x, best_rms = _fe_best(robot, force)
    closed = _rms_over(result, result.t[-1] - 3.0, result.t[-1])
    # 25 %: the bar the closed loop must meet. The time-domain RMS also holds what is left of the
    # start-up transients of undriven modes (zeta 0.3 %) and the plant's first-order hold (~0.5 %).
    assert closed <= 1.25 * best_rms
    start_rms = _fe_steady_rms(robot, robot.position, force)
    assert start_rms >= 3.0 * closed
    # The result's own "best" comparison is parked where the FE scan finds the minimum (2 % of
    # a loop: the scan grids), and it and the loop are both far below the start.
    mode = settled_case[0]
    assert abs(result.comparison("best").position - best_x) < 0.02 * LAB.length / mode
    assert result.comparison("start").rms > 3 * max(result.comparison("best").rms,
                                                    result.rms_closed_loop)


def test_steady_state_scan_matches_the_finite_element_model():
    mode = 4
    robot = _robot(mode, LAB.length / mode)
    force = plc.HarmonicForce(0.8, 1.007 * FREQS[mode - 1], 0.53 * LAB.length)
    result = run_closed_loop(LAB, force, robot, sensors=SENSORS, n_elements=N_EL,
                             damping=plc.ModalDamping(ZETA), duration=3.0, calibration=1.0,
                             seed=2)
    picks = np.linspace(5, result.scan_positions.size - 6, 7).astype(int)
    fe = [_fe_steady_rms(robot, result.scan_positions[i], force) for i in picks]
    # 2 %: the plant keeps the bare line's modes below 8x the load frequency; the robot couples
    # to the dropped ones only quasi-statically (measured ~0.3 %).
    np.testing.assert_allclose(result.scan_rms[picks], fe, rtol=0.02)
    # the scan covers what the robot could reach in the run (half the 2 s after calibration)
    best_x, _ = _fe_best(robot, force, result.scan_positions[0], result.scan_positions[-1])
    assert abs(result.best_position - best_x) < 0.02 * LAB.length / mode


@pytest.mark.filterwarnings("ignore::powerline_control.errors.ReachWarning")  # a short run: no trip
def test_parked_plant_matches_full_fe_simulation():
    # The baseline (robot parked at its start) against plc.simulate on the full FE model with the
    # robot attached: exact modal propagation of every mode, closed form for the harmonic load.
    robot = _robot(3, 0.9)
    force = plc.HarmonicForce(1.3, 0.97 * FREQS[2], 1.7)
    result = run_closed_loop(LAB, force, robot, sensors=SENSORS, n_elements=N_EL,
                             duration=1.5, calibration=0.5, seed=4)
    full = plc.simulate(plc.LineModel(LAB, N_EL, mdr=robot), force, duration=1.5, dt=1e-3)
    error = result.baseline_displacement - full.true_displacement
    relative = np.sqrt(np.mean(error**2) / np.mean(full.true_displacement**2))
    # 2 %: first-order hold of a 24 Hz sine at 1 kHz (~(omega dt)^2 / 12 = 0.2 %) and the modes
    # the plant drops; measured ~0.5 %.
    assert relative < 0.02


def test_energy_is_conserved_with_no_damping_and_a_still_robot():
    robot = plc.MDR(1.1, body_mass=0.03, suspended_mass=0.04, stiffness=1500.0, damping=0.0)
    plant = _ModalPlant(BARE, robot, 15, 1e-3)
    rng = np.random.default_rng(17)
    z = np.concatenate([1e-3 * rng.standard_normal(plant.n_q),
                        0.1 * rng.standard_normal(plant.n_q)])
    phi, _, _ = plant.discretise(1.1)
    e0 = plant.energy(z, 1.1)
    energies = []
    for _ in range(10_000):
        z = phi @ z
        energies.append(plant.energy(z, 1.1))
    # The discrete map is the exact flow (matrix exponential), so energy drifts only by
    # round-off: 1e-9 relative over 1e4 steps leaves room for ~1e-13 per step.
    assert np.max(np.abs(np.array(energies) - e0)) / e0 < 1e-9


def test_wind_change_robot_follows_to_the_new_best_position():
    # Mode 4 then mode 3 (a frequency step at 8 s, as a wind change would make): the robot,
    # tuned to mode 4, leaves the mode-4 position and settles where the line now vibrates least.
    robot = _robot(4, LAB.length / 4)
    first = plc.HarmonicForce(1.0, 0.99 * FREQS[3], 0.37 * LAB.length)
    second = plc.HarmonicForce(1.0, 1.01 * FREQS[2], 0.37 * LAB.length)
    result = run_closed_loop(LAB, [(0.0, first), (8.0, second)], robot, sensors=SENSORS,
                             n_elements=N_EL, damping=plc.ModalDamping(ZETA), duration=16.0,
                             calibration=2.0, seed=9)
    assert len(result.retarget_times) == 2 and result.retarget_times[1] > 8.0
    assert np.isfinite(result.settle_times[1])
    # Detection (2 s frequency window, held 1 s), retarget and the move: reported, and finite.
    assert len(result.follow_times) == 1 and 0 < result.follow_times[0] < 8.0
    assert not np.all(result.estimator_valid)  # the model was seen not to fit after the change
    last = result.t >= result.t[-1] - 2.0
    assert np.ptp(result.robot_position[last]) < 0.02 * LAB.length / 3
    _, best_rms = _fe_best(robot, second)
    after_change = _rms_over(result, 8.0, 9.0)
    final = _rms_over(result, result.t[-1] - 2.0, result.t[-1])
    assert final <= 1.25 * best_rms
    assert final < 0.5 * after_change  # the RMS falls again once the robot has moved


@pytest.mark.filterwarnings("ignore::powerline_control.errors.ReachWarning")  # a short run: no trip
def test_noise_free_sensors_work():
    robot = _robot(2, LAB.length / 2)
    result = run_closed_loop(LAB, plc.HarmonicForce(1.0, FREQS[1], 1.0), robot, sensors=[5, 9, 14],
                             n_elements=20, duration=2.0, calibration=1.0, noise_fraction=0.0)
    assert np.all(np.isfinite(result.estimated_field))
    assert result.robot_position[-1] != robot.position


def test_robot_respects_its_limits_and_the_obstacle():
    robot = _robot(3, 1.2)
    result = run_closed_loop(LAB, plc.HarmonicForce(1.0, FREQS[2], 0.5), robot,
                             plc.RobotLimits(v_max=0.3, a_max=0.8), sensors=[7, 16, 28],
                             n_elements=40, duration=4.0, calibration=1.0,
                             obstacles=[(1.5, 1.6)], seed=1)
    # Constant acceleration per period: sampled velocity is exact, so the limit holds at samples.
    assert np.abs(result.robot_velocity).max() <= 0.3 + 1e-9
    accel = np.diff(result.robot_velocity) / np.diff(result.t)
    assert np.abs(accel).max() <= 0.8 + 1e-6
    assert not np.any((result.robot_position > 1.5) & (result.robot_position < 1.6))


def _jerk(result):
    """Peak jerk (m/s^3) of the sampled path: third differences of the exact polynomials."""
    acceleration = np.diff(result.robot_velocity) / np.diff(result.t)
    return float(np.abs(np.diff(acceleration) / np.diff(result.t)[1:]).max())


@pytest.mark.parametrize("motion", ["closed_form", "mpc"])
def test_every_limit_holds_jerk_and_body_length_included(motion):
    # The case: j_max and length were once ignored by the closed-form law (peak jerk
    # 1415 m/s^3) and the MPC stopped with a state-shape error. Bounds: the planner's own
    # (IPOPT meets them to ~1e-8 relative; the closed form exactly, to round-off).
    limits = plc.RobotLimits(v_max=0.3, a_max=0.8, j_max=0.5, length=0.3)
    obstacle = (1.5, 1.6)
    result = run_closed_loop(LAB, plc.HarmonicForce(1.0, FREQS[2], 0.5), _robot(3, 1.2), limits,
                             sensors=[7, 16, 28], n_elements=40, duration=10.0, calibration=1.0,
                             obstacles=[obstacle], seed=1, motion=motion)
    assert np.ptp(result.robot_position) > 0.1                    # it did move
    assert np.abs(result.robot_velocity).max() <= 0.3 * (1 + 1e-6)
    assert _jerk(result) <= 0.5 * (1 + 1e-5)
    half = limits.length / 2
    body_low, body_high = result.robot_position - half, result.robot_position + half
    assert body_low.min() >= -1e-12 and body_high.max() <= LAB.length + 1e-12
    assert not np.any((body_high > obstacle[0] + 1e-9) & (body_low < obstacle[1] - 1e-9))


def test_body_length_keeps_the_robot_off_the_clamp():
    # A target at the very support: the body (0.4 m) must stop with its end at the support,
    # its centre at 0.2 m (plan.free_interval's rule, shared with plan_motion).
    limits = plc.RobotLimits(v_max=0.5, a_max=1.0, length=0.4)
    result = run_closed_loop(LAB, plc.HarmonicForce(1.0, FREQS[0], 0.3), _robot(1, 1.0), limits,
                             sensors=[10, 30, 50], n_elements=N_EL, bc="clamped", duration=6.0,
                             calibration=1.0, seed=2)
    assert result.robot_position.min() >= 0.2 - 1e-12
    assert result.robot_position.max() <= LAB.length - 0.2 + 1e-12


def test_a_line_model_is_run_on_its_own_mesh_and_supports():
    # The graded clamped mesh of the physics (nodes not uniform) and the model's damping: the
    # loop runs on that line, not on a uniform copy. Truth: the no-robot field of the loop is
    # the model's own, so its node positions and a parked steady state agree with the model's.
    model = plc.LineModel(LAB, bc="clamped", damping=plc.ModalDamping(ZETA), max_frequency=60.0)
    assert not np.allclose(np.diff(model.node_positions), model.element_lengths[0])  # graded
    robot = _robot(3, 1.2)
    sensors = [model.n_nodes // 4, model.n_nodes // 2, 3 * model.n_nodes // 4]
    result = run_closed_loop(model, plc.HarmonicForce(1.0, FREQS[2], 0.5), robot,
                             sensors=sensors, duration=2.0, calibration=1.0, seed=3)
    np.testing.assert_array_equal(result.x, model.node_positions)
    # the robot a model carries is the robot (and a conflicting one is refused)
    carried = run_closed_loop(model.with_robot(robot), plc.HarmonicForce(1.0, FREQS[2], 0.5),
                              None, sensors=sensors, duration=2.0, calibration=1.0, seed=3)
    np.testing.assert_array_equal(carried.displacement, result.displacement)
    with pytest.raises(plc.InputError, match="'robot'"):
        run_closed_loop(model.with_robot(robot), plc.HarmonicForce(1.0, FREQS[2], 0.5),
                        plc.MDR(1.0, 0.01), sensors=sensors, duration=2.0, calibration=1.0)
    with pytest.raises(plc.InputError, match="'bc'"):
        run_closed_loop(model, plc.HarmonicForce(1.0, FREQS[2], 0.5), robot, sensors=sensors,
                        bc="pinned", duration=2.0, calibration=1.0)


def test_estimate_tracks_the_true_field(settled_case):
    _, _, _, result = settled_case
    after = result.t > result.calibration_time + 0.5
    error = result.estimated_field[:, after] - result.displacement[:, after]
    relative = np.sqrt(np.mean(error**2)) / np.sqrt(np.mean(result.displacement[:, after] ** 2))
    # The model was identified with the robot parked at a node; once it damps the loop the
    # line's dynamics differ from the model's and the (much smaller) field is estimated less
    # well. 60 % still tells the loops apart; the policy does not rely on it (see the docs).
    assert relative < 0.6
    assert result.innovation_ratio.size == len(result.statuses)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(sensors=[]), "sensors"),
        (dict(sensors=[50]), "sensors"),
        (dict(sensors=[0, 5]), "sensors"),  # a pinned support: the model has no displacement
        (dict(sensors=[5, 5]), "sensors"),
        (dict(calibration=10.0), "calibration"),
        (dict(calibration=0.001), "calibration"),
        (dict(control_period=0.0015), "control_period"),
        (dict(plant_period=0.0025), "plant_period"),
        (dict(dt=0.0007), "control_period"),  # 50 ms is not a multiple of 0.7 ms
        (dict(noise_fraction=-0.1), "noise_fraction"),
        (dict(motion="fast"), "motion"),
        (dict(obstacles=[(1.0, 1.5)]), "robot.position"),
        (dict(robot=plc.MDR(4.0, 0.02)), "robot.position"),
        (dict(robot=plc.MDR(1.2, 0.3)), "robot"),  # 0.3 kg > 25 % of the span's 0.68 kg
        (dict(force=[(0.0, plc.HarmonicForce(1.0, 24.0, 0.5)), (5.0, "gust")]), "force"),
        (dict(force=[(1.0, plc.HarmonicForce(1.0, 24.0, 0.5))]), "force"),
        (dict(force="wind"), "force"),
        (dict(force=None), "force"),
        (dict(force=plc.HarmonicForce(1.0, 24.0, 5.0)), "force position"),  # off the 3.66 m span
        (dict(span="lab"), "model"),
        (dict(robot="robot"), "robot"),
        (dict(limits=(0.5, 1.0)), "limits"),
        (dict(duration=-1.0), "duration"),
        (dict(duration=float("nan")), "duration"),
        (dict(duration=1e9), "duration"),  # 1e12 samples: over the memory budget, before building
        (dict(dt=0.0), "dt"),
        (dict(control_period=10.0), "control_period"),  # longer than the run: it would never act
        (dict(plant_period=0.0), "plant_period"),
        (dict(noise_fraction=1.0), "noise_fraction"),
        (dict(antinode_window=0.0), "antinode_window"),
        (dict(frequency_window=-2.0), "frequency_window"),
        (dict(retarget_threshold=-0.1), "retarget_threshold"),
        (dict(settle_margin=-1.0), "settle_margin"),
        (dict(delays=0), "delays"),
        (dict(delays=1.5), "delays"),
        (dict(estimator_rank=0), "estimator_rank"),
        (dict(n_elements=1), "n_elements"),
        (dict(n_elements=20.0), "n_elements"),
        (dict(n_elements=None, sensors=[5, 10_000]), "sensors"),  # checked on the default mesh
        (dict(sensors=[5.5, 10]), "sensors"),
        (dict(obstacles=[(1.0,)]), "obstacles"),
        (dict(obstacles=5), "obstacles"),
        (dict(obstacles=[(2.0, 1.9)]), "obstacles"),
        (dict(n_modes=0), "n_modes"),
        (dict(n_modes=10_000), "n_modes"),  # 20 elements have 40 free DOFs
        (dict(clamp_distance=-0.1), "clamp_distance"),
        (dict(clamp_distance=10.0), "clamp_distance"),
        (dict(planner_time_budget=-1.0), "planner_time_budget"),
        (dict(seed="x"), "seed"),
        # Several bad arguments: the first in the signature's order of checks is the one named.
        (dict(duration=-1.0, motion="fast"), "duration"),
        (dict(motion="fast", obstacles=[(2.0, 1.9)]), "motion"),
        (dict(limits="fast", dt=0.0), "limits"),
    ],
)
def test_bad_arguments(kwargs, name):
    args = {"sensors": [5, 10], "n_elements": 20, "duration": 3.0, "calibration": 1.0,
            "force": plc.HarmonicForce(1.0, 24.0, 0.5), "robot": plc.MDR(1.2, 0.02), **kwargs}
    span = args.pop("span", LAB)
    with pytest.raises(plc.InputError, match=f"'{re.escape(name)}'"):  # the name, quoted
        run_closed_loop(span, args.pop("force"), args.pop("robot"), **args)


@pytest.mark.parametrize(
    ("kwargs", "warning", "words"),
    [
        # 0.01 m/s and 0.01 m/s^2 cover 5.6 mm in 1.5 s: not a quarter of the 1.22 m loop
        (dict(limits=plc.RobotLimits(0.01, 0.01)), plc.errors.ReachWarning, "v_max=0.01"),
        # the loops at 0.46 and 1.83 m lie beyond the obstacles around the start
        (dict(obstacles=[(0.9, 1.0), (1.5, 1.6)]), plc.errors.ReachWarning, "'obstacles'"),
        # 6 elements cannot hold the 24.5 Hz load's 1.22 m loops
        (dict(n_elements=6, sensors=[1, 3, 5]), plc.TruncationWarning, "'n_elements'"),
    ],
    ids=["slow-limits", "obstacles-everywhere", "coarse-model"],
)
# A robot kept from every loop ends above a damper parked near the clamp, and says that too.
@pytest.mark.filterwarnings("ignore::powerline_control.errors.ShortfallWarning")
def test_what_keeps_the_robot_from_the_loops_is_named(kwargs, warning, words):
    args = dict(sensors=[7, 16, 28], n_elements=40, duration=4.0, calibration=1.0, seed=1)
    args.update(kwargs)
    limits = args.pop("limits", None)
    with pytest.warns(warning, match=re.escape(words)):
        run_closed_loop(LAB, plc.HarmonicForce(1.0, FREQS[2], 0.5), _robot(3, 1.2), limits,
                        **args)


def test_robot_too_heavy_for_the_tension():
    # A slack line (10 N) under a 0.1 kg robot: W / 2T = 0.049 ... at 5 N it is 0.098 rad.
    slack = plc.Span(length=3.66, tension=5.0, conductor=LAB.conductor)
    with pytest.raises(plc.InputError, match="tension"):
        run_closed_loop(slack, plc.HarmonicForce(1.0, 5.0, 0.5), plc.MDR(1.2, 0.1),
                        sensors=[5, 10], n_elements=20, duration=3.0, calibration=1.0)


# a 0.5 s loop: no trip
@pytest.mark.filterwarnings("ignore::powerline_control.errors.ReachWarning")
def test_aeolian_load_and_mpc_motion_run():
    # A distributed lock-in load (bound to the model: it has a frequency) and the MPC planner:
    # the loop runs, the planner reports its statuses, the scan exists (the load is a sine).
    span = plc.Span.paper_lab()
    wind = plc.AeolianForce(wind_speed=1.5)
    robot = plc.MDR(1.0, 0.03, 0.04, 1500.0, 2.0)
    result = run_closed_loop(span, wind, robot, sensors=[5, 9, 14], n_elements=20,
                             duration=1.5, calibration=1.0, motion="mpc", seed=6)
    assert len(result.statuses) == 10 and "closed_form" not in result.statuses
    assert result.scan_rms.size > 0 and np.isfinite(result.best_position)


@pytest.mark.filterwarnings("ignore::powerline_control.errors.ReachWarning")  # a short run: no trip
def test_results_do_not_depend_on_the_machine_load():
    # No wall-clock budget anywhere in the loop (closed-form motion, no timed solver): the same
    # seed gives bit-identical results with a CPU-burning process running alongside.
    import subprocess
    import sys

    def run():
        return run_closed_loop(LAB, plc.HarmonicForce(1.0, FREQS[2], 1.0), _robot(3, 1.22),
                               sensors=[5, 9, 14], n_elements=20, duration=2.0, calibration=1.0,
                               seed=12)

    idle = run()
    burner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        loaded = run()
    finally:
        burner.kill()
        burner.wait()
    np.testing.assert_array_equal(idle.robot_position, loaded.robot_position)
    np.testing.assert_array_equal(idle.displacement, loaded.displacement)
    assert idle.statuses == loaded.statuses


@pytest.mark.parametrize(("v_max", "a_max", "budget"),
                         [(1.0, 2.0, 5.0), (0.5, 1.0, 0.7), (0.3, 0.8, 0.75), (2.0, 0.5, 3.0)])
def test_reach_is_the_longest_rest_to_rest_move_in_the_budget(v_max, a_max, budget):
    # Brute force: bisect on the distance, each tried by integrating the bang-coast-bang profile
    # (accelerate, cruise at v_max if reached, brake) at 1e-4 s; the move fits when it stops
    # within the budget. 3e-3 relative: one integration step of overshoot at the braking point
    # (~v dt / distance, < 1e-3 here) and the bisection (2^-25).
    def stop_time(distance):
        dt, x, v, t = 1e-4, 0.0, 0.0, 0.0
        while True:
            braking = v * v / (2 * a_max)
            accel = -a_max if x + braking >= distance else (a_max if v < v_max else 0.0)
            v = min(max(v + accel * dt, 0.0), v_max)
            x += v * dt
            t += dt
            if v == 0.0 and accel < 0:
                return t

    low, high = 0.0, v_max * budget
    for _ in range(25):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if stop_time(mid) <= budget else (low, mid)
    limits = plc.RobotLimits(v_max=v_max, a_max=a_max)
    assert _reach(limits, budget) == pytest.approx(low, rel=3e-3)
    assert _reach(limits, 0.0) == 0.0


# ---------------------------------------------------------------------------- a long real span
def _long_span_case(length, wind_speed, where):
    """ACSR Drake at 20 % RTS in aeolian lock-in, the robot starting a tenth of a loop past a
    node near ``where`` (fraction of the span). Truth: dense FE steady states of the whole
    default mesh, all its modes damped at the same 0.05 %."""
    import scipy.linalg

    span = plc.Span.at_rts_fraction(length, plc.conductors["drake"], 0.2)
    model = plc.LineModel(span)
    mass, stiffness = model.mass_matrix.toarray(), model.stiffness_matrix.toarray()
    omega2, shapes = scipy.linalg.eigh(stiffness, mass)
    damping = mass @ shapes @ np.diag(2 * 0.0005 * np.sqrt(omega2)) @ shapes.T @ mass
    wind = plc.AeolianForce(wind_speed=wind_speed)
    bound = wind.bind(model)
    omega = 2 * np.pi * bound.frequency

    def steady(robot=None, position=None):
        """FE DOF amplitudes: the bare line, or the robot (body + absorber DOF) parked."""
        n = mass.shape[0]
        dynamic = np.zeros((n + 1, n + 1), dtype=complex)
        dynamic[:n, :n] = stiffness - omega**2 * mass + 1j * omega * damping
        load = np.append(bound.load, 0.0).astype(complex)
        if robot is None:
            return np.linalg.solve(dynamic[:n, :n], load[:n])
        s = model.shape_vector(position)
        dynamic[:n, :n] -= omega**2 * robot.body_mass * np.outer(s, s)
        coupling = np.append(s, -1.0)
        dynamic += (robot.stiffness + 1j * omega * robot.damping) * np.outer(coupling, coupling)
        dynamic[n, n] -= omega**2 * robot.suspended_mass
        return np.linalg.solve(dynamic, load)[:n]

    def amplitude_at(dofs, points):
        return np.abs(np.array([model.shape_vector(p) @ dofs for p in points]))

    x = model.node_positions
    weights = np.zeros_like(x)
    weights[1:] += 0.5 * np.diff(x)
    weights[:-1] += 0.5 * np.diff(x)
    weights /= weights.sum()
    nodal = model.displacement_map().toarray()

    def rms(dofs):
        return float(np.sqrt(0.5 * weights @ np.abs(nodal @ dofs) ** 2))

    loop = float(np.pi / span.wavenumber(bound.frequency))
    bare = steady()
    # Start a tenth of a loop past a node of the robot-free excited shape.
    near = np.linspace(where * span.length - loop, where * span.length + loop, 801)
    node = float(near[np.argmin(amplitude_at(bare, near))])
    start = node + 0.1 * loop
    around = np.linspace(start - 0.6 * loop, start + 0.6 * loop, 801)
    antinode = float(around[np.argmax(amplitude_at(bare, around))])
    frequencies = model.natural_frequencies(200)
    mode = int(np.argmin(np.abs(frequencies - bound.frequency))) + 1
    robot = tune_damper(model, mode, antinode, 3.0, body_mass=5.0)  # 5 kg body + 3 kg absorber
    robot = plc.MDR(start, robot.body_mass, robot.suspended_mass, robot.stiffness, robot.damping)
    return span, model, wind, robot, loop, bare, steady, amplitude_at, rms


LONG_SPANS = [
    # Drake 300 m at 2.5 m/s (16.4 Hz, loops ~4 m; the shipped scenario is 3 m/s, 19.7 Hz, from
    # midspan), starting near 0.62 L: measured 4.4x (FE steady state), 2.7x over the window.
    pytest.param(300.0, 2.5, 0.62, 4, id="drake300-2.5ms-0.62L", marks=pytest.mark.slow),
    # Drake 250 m at 2.5 m/s from near 0.41 L: the robot's 8 kg detunes the 0.05 %-damped span,
    # so the parked RMS is steep across the loop (2.4e-5 m at 0.7 loop past the node, 1.6e-4 m
    # at 0.3). The robot settles 2.05x below its start in steady state; the window ratio was ~1x
    # (the arrival's transient outlasts the 12 s run), which is why vibration_reduction is now
    # the steady-state ratio at the final position.
    pytest.param(250.0, 2.5, 0.41, 4, id="drake250-2.5ms-0.41L", marks=pytest.mark.slow),
]


@pytest.mark.parametrize(("length", "wind_speed", "where", "seed"), LONG_SPANS)
def test_long_span_robot_goes_to_a_near_antinode_and_beats_its_start(length, wind_speed, where,
                                                                      seed):
    span, model, wind, robot, loop, bare, steady, amplitude_at, rms = _long_span_case(
        length, wind_speed, where)
    x = model.node_positions
    sensors = sorted({int(np.argmin(np.abs(x - f * span.length)))
                      for f in (0.13, 0.31, 0.52, 0.68, 0.9)})
    result = run_closed_loop(span, wind, robot, plc.RobotLimits(v_max=1.0, a_max=2.0),
                             sensors=sensors, n_elements=model.n_elements,
                             damping=plc.ModalDamping(0.0005), duration=12.0, calibration=2.0,
                             dt=0.002, seed=seed)
    final = float(result.robot_position[-1])
    assert result.settled
    last = result.t >= result.t[-1] - 2.0
    assert np.ptp(result.robot_position[last]) < 0.02 * loop
    # A near loop, not a trip across the span: within two loops of the start.
    assert abs(final - robot.position) < 2 * loop
    # Near an antinode of the robot-free excited shape (dense FE): within 15 % of a loop, where
    # the absorber still sees sin^2 > 0.8 of the loop's motion (the five sensors 30-60 m away
    # fix the local phase of the standing wave only to ~10 % of a loop).
    around = np.linspace(final - 0.6 * loop, final + 0.6 * loop, 601)
    envelope = amplitude_at(bare, around)
    peaks = [around[i] for i in range(1, around.size - 1)
             if envelope[i] >= envelope[i - 1] and envelope[i] >= envelope[i + 1]]
    assert min(abs(p - final) for p in peaks) < 0.15 * loop
    # More than 2x below the robot parked at its start, in steady state (dense FE). The run's own
    # window ratio (result.vibration_reduction) also holds the start-up transient of a
    # 0.05 %-damped span (time constant ~20 s), so it is asserted at the same bar but not
    # used as the truth.
    assert rms(steady(robot, robot.position)) > 2.0 * rms(steady(robot, final))
    assert result.vibration_reduction > 2.0


@pytest.mark.parametrize(("j_max", "budget"), [(0.5, 2.0), (3.0, 0.7), (40.0, 0.25)])
def test_reach_under_a_jerk_limit_is_the_pure_jerk_move(j_max, budget):
    # Far from v_max and a_max a rest-to-rest move is four jerk phases of T/4 (+j, -j, -j, +j):
    # it covers d = 2 j (T/4)^3 = j T^3 / 32 (the closed form; reach ignored j_max before).
    limits = plc.RobotLimits(v_max=1e3, a_max=1e3, j_max=j_max)
    assert _reach(limits, budget) == pytest.approx(j_max * budget**3 / 32, rel=1e-9)


def test_band_plant_field_of_a_long_span_matches_the_modal_sum():
    # A long span's plant keeps a band of modes around the load (here modes 19-66 of a 100 m
    # Drake span at 20 % RTS, load 15.2 Hz). Review finding: the quasi-static residual was the
    # static K^-1 minus the band, which counted the ~18 modes BELOW the band with their static
    # flexibility 1 / omega_k^2 (a static-sag-shaped field ~100x the true vibration). Truth: the
    # closed-form steady state of the pinned taut beam, 3000 modes sin(n pi x / L) of modal mass
    # m L / 2, mass-proportional damping C = a M (the same i a omega in every mode).
    from powerline_control.simulation import plant as cl

    span = plc.Span.at_rts_fraction(100.0, "drake", 0.20)
    a, f0, freq, x_f = 0.4, 1.5, 15.2, 31.7
    bare = plc.LineModel(span, 300, damping=plc.RayleighDamping(a, 0.0))
    modes = cl.default_modes(span, bare, [freq], 1e-3)
    assert np.ndim(modes) == 1 and modes[0] > 10        # a band: modes below it are left out
    plant = _ModalPlant(bare, None, modes, 1e-3)
    force = plc.HarmonicForce(f0, freq, x_f)
    t = 1e-3 * np.arange(5)
    _, _, (frequency, parts) = cl.load_histories(bare, plant, cl.load_segments(force, 1.0), t)
    omega = 2 * np.pi * frequency
    phasor = cl.phasor_of(force, frequency)
    field = sum((plant.nodal @ plant.modal_response(g, omega) + static) * phasor
                for _, g, static in parts)
    n = np.arange(1, 3001)[:, None]
    omega_n = 2 * np.pi * span.pinned_frequencies(3000)[:, None]
    x = bare.node_positions[None, :]
    modal_mass = span.conductor.mass_per_length * span.length / 2
    shapes = np.sin(n * np.pi * x_f / span.length) * np.sin(n * np.pi * x / span.length)
    truth = -1j * f0 * (shapes / modal_mass / (omega_n**2 - omega**2 + 1j * a * omega)).sum(0)
    # 1 %: 300 elements resolve the 7 m loops to ~1e-6 in frequency; the FE cannot bend
    # sharply at the load inside an element (~1e-3 of the peak, as in test_simulate) and the
    # series tail beyond 3000 terms is ~1e-4. The static residual was off by ~100x.
    assert np.abs(field - truth).max() < 1e-2 * np.abs(truth).max()


@pytest.mark.filterwarnings("ignore::powerline_control.errors.ReachWarning")  # a short run: no trip
def test_long_span_no_robot_rms_matches_the_closed_form_steady_state():
    # The public path of the finding above: run_closed_loop on a 100 m Drake span (a band plant)
    # with a point load; its "no robot" comparison against the closed-form steady state of the
    # pinned taut beam (3000 modes, modal damping 2 zeta omega_n). Before the fix it was 13x too
    # large, and the robot's reduction read 1.0006 whatever it did.
    span = plc.Span.at_rts_fraction(100.0, "drake", 0.20)
    freq, x_f, zeta = 15.2, 31.7, 0.01
    robot = plc.MDR.tuned(5.0, 2.0, 1.5, frequency=freq, damping_ratio=0.2)
    result = run_closed_loop(span, plc.HarmonicForce(1.5, freq, x_f), robot,
                             sensors=[40, 97, 151, 230, 277], n_elements=300,
                             damping=plc.ModalDamping(zeta), duration=6.0, calibration=3.0,
                             seed=5)
    n = np.arange(1, 3001)[:, None]
    omega_n = 2 * np.pi * span.pinned_frequencies(3000)[:, None]
    omega = 2 * np.pi * freq
    x = result.x[None, :]
    shapes = np.sin(n * np.pi * x_f / span.length) * np.sin(n * np.pi * x / span.length)
    modal_mass = span.conductor.mass_per_length * span.length / 2
    steady = 1.5 * (shapes / modal_mass / (omega_n**2 - omega**2 + 2j * zeta * omega_n * omega)
                    ).sum(0)
    weights = np.zeros(result.x.size)
    weights[1:] += 0.5 * np.diff(result.x)
    weights[:-1] += 0.5 * np.diff(result.x)
    expected = np.sqrt(0.5 * (weights / weights.sum()) @ np.abs(steady) ** 2)
    # 3 %: start-up transients of the band's modes (zeta omega >= 0.57 /s) have decayed to
    # e^-2.9 of their start by the 5-6 s window and are driven off resonance; measured 0.7 %.
    assert result.comparison("no_robot").rms == pytest.approx(expected, rel=0.03)


class _UserLoad:
    """A user's own load (the protocol simulate accepts) that declares no frequency."""

    frequency = None
    position = 1.0

    def values(self, t):
        return np.sin(2 * np.pi * 11.0 * np.asarray(t))

    def load_vector(self, model):
        return model.point_load(self.position)


# a 0.5 s loop: no trip
@pytest.mark.filterwarnings("ignore::powerline_control.errors.ReachWarning")
def test_user_load_without_a_frequency_runs():
    # Review finding: float(load.frequency) raised a raw TypeError for frequency = None.
    result = run_closed_loop(LAB, _UserLoad(), plc.MDR(1.0, 0.03, 0.04, 1500.0, 2.0),
                             sensors=[5, 9, 14], n_elements=20, duration=1.5, calibration=1.0,
                             seed=6)
    assert np.all(np.isfinite(result.displacement))
    assert result.scan_rms.size == 0          # not declared a sine: no steady-state scan
