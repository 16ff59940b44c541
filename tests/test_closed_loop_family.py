"""The closed loop on a family of scenarios nobody tuned for, and its judge.

The family and the judge are in ``tests/closed_loop_family.py`` (odd seeds held out, even seeds
for tuning). The judge's truth is checked here against a closed form (a pinned taut beam without
the robot: the modal sum of sin(n pi x / L)) and against dense solves with the robot's matrices
built by hand, so that the verdicts do not rest on the closed loop's plant nor on the judge's
own sparse/Woodbury route.
"""

import itertools
from concurrent.futures import ProcessPoolExecutor

import closed_loop_family as fam
import numpy as np
import pytest
import scipy.linalg

import powerline_control as plc

LAB = plc.Span.paper_lab()


# ------------------------------------------------------------------------- the judge's truth
def _pinned_modal_sum(span, x, x0, frequency, damping, n_modes=4000):
    """Exact steady amplitude of a pinned taut Euler-Bernoulli beam under a unit point force at
    x0: sum_n sin(k_n x) sin(k_n x0) / (m L / 2 (w_n^2 - w^2 + i w c_n)), k_n = n pi / L,
    m w_n^2 = EI k_n^4 + T k_n^2 (design 4.1); c_n = 2 zeta w_n (modal) or a + b w_n^2."""
    cond = span.conductor
    n = np.arange(1, n_modes + 1)
    k = n * np.pi / span.length
    omega_n = np.sqrt((cond.ei * k**4 + span.tension * k**2) / cond.mass_per_length)
    w = 2 * np.pi * frequency
    if isinstance(damping, plc.ModalDamping):
        c = 2 * damping.ratio * omega_n
    else:
        c = damping.mass_coefficient + damping.stiffness_coefficient * omega_n**2
    modal_mass = cond.mass_per_length * span.length / 2
    gain = np.sin(k * x0) / (modal_mass * (omega_n**2 - w**2 + 1j * w * c))
    return np.sin(np.outer(x, k)) @ gain


@pytest.mark.parametrize("damping", [plc.ModalDamping(0.004),
                                     plc.RayleighDamping.from_ratios((10.0, 60.0), 0.004)],
                         ids=["modal", "rayleigh"])
@pytest.mark.parametrize("frequency", [20.0, 31.0])   # between modes 2-3 and 3-4
def test_truth_matches_the_pinned_beam_modal_sum(damping, frequency):
    force = plc.HarmonicForce(2.0, frequency, 1.3)
    robot = plc.MDR(1.0, 0.03, 0.04, 200.0, 1.0)
    truth = fam.SteadyState(LAB, 100, "pinned", damping, robot, force)
    nodal, model = truth.response(None)
    x = model.node_positions
    exact = 2.0 * _pinned_modal_sum(LAB, x, 1.3, frequency, damping)
    # 100 Hermite-cubic elements: the modes that carry the response (up to ~10) are exact to
    # < 1e-8; the series is converged to < 1e-9 at 4000 terms (terms fall as n^-4). A modal
    # damping is applied to all 200 FE modes; the FE's top modes (wrong by O(1)) carry 1e-7.
    np.testing.assert_allclose(nodal, exact, rtol=0, atol=2e-6 * np.abs(exact).max())
    rms = np.sqrt(0.5 * truth.weights @ np.abs(exact) ** 2)
    assert truth.rms(None) == pytest.approx(rms, rel=1e-5)


def _dense_rms(span, n_elements, bc, zeta, robot, position, force):
    """Span RMS of the steady state by a dense solve: bare FE matrices, every bare mode damped
    (M Phi 2 zeta Omega Phi^T M), the robot's body mass N N^T and its absorber DOF with spring
    and damper on (N, -1), assembled here by hand from the shape vector at ``position``."""
    bare = plc.LineModel(span, n_elements, bc)
    m, k = bare.mass_matrix.toarray(), bare.stiffness_matrix.toarray()
    omega2, shapes = scipy.linalg.eigh(k, m)
    c_line = m @ shapes @ np.diag(2 * zeta * np.sqrt(omega2)) @ shapes.T @ m
    w = 2 * np.pi * force.frequency
    n = m.shape[0]
    s = bare.shape_vector(position)
    coupling = np.append(s, -1.0)
    a = np.zeros((n + 1, n + 1), dtype=complex)
    a[:n, :n] = k - w**2 * (m + robot.body_mass * np.outer(s, s)) + 1j * w * c_line
    a[n, n] = -w**2 * robot.suspended_mass
    a += (robot.stiffness + 1j * w * robot.damping) * np.outer(coupling, coupling)
    f = np.append(force.amplitude * bare.point_load(force.position), 0.0)
    u = np.linalg.solve(a, f)[:n]
    nodal = bare.displacement_map() @ u
    x = bare.node_positions
    weights = np.zeros_like(x)
    weights[1:] += 0.5 * np.diff(x)
    weights[:-1] += 0.5 * np.diff(x)
    return float(np.sqrt(0.5 * (weights / span.length) @ np.abs(nodal) ** 2))


@pytest.mark.parametrize("bc", ["pinned", "clamped"])
def test_truth_matches_dense_solves_with_the_robot(bc):
    bare = plc.LineModel(LAB, 100, bc)
    f3 = bare.natural_frequencies(3)[2]
    robot = plc.tune_damper(bare, 3, None, 0.04, body_mass=0.03)
    force = plc.HarmonicForce(1.0, 1.004 * f3, 0.43 * LAB.length)
    truth = fam.SteadyState(LAB, 100, bc, plc.ModalDamping(0.003), robot, force)
    for p in (0.37, 1.02, 1.83, 2.71, 3.5):
        # same matrices, another route (dense LU, no Woodbury): agreement to round-off
        assert truth.rms(p) == pytest.approx(
            _dense_rms(LAB, 100, bc, 0.003, robot, p, force), rel=1e-8), p


def test_truth_on_a_long_span_truncates_the_damped_modes_harmlessly():
    # 600 DOFs: the judge damps the bare modes up to 3x the load only (the others undamped);
    # a dense solve with every mode damped agrees to O(zeta^2) of the quasi-static part.
    span = plc.Span.at_rts_fraction(150.0, "drake", 0.2)
    bare = plc.LineModel(span, 300, "clamped")
    f = 1.002 * bare.natural_frequencies(30)[29]
    robot = plc.tune_damper(bare, 30, None, 3.0, body_mass=5.0)
    force = plc.HarmonicForce(5.0, f, 61.0)
    truth = fam.SteadyState(span, 300, "clamped", plc.ModalDamping(0.002), robot, force)
    assert truth._lowrank[0].shape[1] < bare.n_dofs / 2   # the truncated route is exercised
    for p in (robot.position, 40.3, 97.7):
        assert truth.rms(p) == pytest.approx(
            _dense_rms(span, 300, "clamped", 0.002, robot, p, force), rel=1e-4), p


def test_scenarios_are_deterministic_and_split_by_parity():
    a, b = fam.scenario(7), fam.scenario(7)
    assert a.description == b.description and a.sensors == b.sensors
    assert fam.split_of(7) == "held_out" and fam.split_of(8) == "tune"
    held = fam.family("held_out", 14)
    assert all(s % 2 == 1 for s in held)
    assert {fam.CATEGORIES[(s // 2) % len(fam.CATEGORIES)] for s in held} == set(fam.CATEGORIES)


# ------------------------------------------------------------------------- the policy, judged
def _assert_run_meets_criteria(outcome):
    assert outcome.error is None, outcome.error
    context = f"seed {outcome.seed}: {outcome.description}"
    assert outcome.settled, f"not settled ({outcome.range_fraction:.3f} loop); {context}"
    assert outcome.closed_over_best <= 1.5, f"{outcome.closed_over_best:.3f}x best; {context}"
    assert outcome.closed_over_start <= 1.05, \
        f"{outcome.closed_over_start:.3f}x the start; {context}"


# The first held-out seed of lab/mode, lab/between and lab/aeolian (a rule, not a pick). Seed 3
# checks that the frequency is measured on the sensors' velocities: by displacement the
# fundamental's start-up ringing outweighs the load, and the robot moves 0.98 loop in the last
# quarter of the run.
QUICK_LAB = [1, 3, 7]


@pytest.mark.parametrize("seed", QUICK_LAB)
def test_quick_lab_held_out_scenario_meets_the_criteria(seed):
    scenario = fam.scenario(seed)
    assert scenario.split == "held_out" and scenario.category.startswith("lab/")
    _assert_run_meets_criteria(fam.run(scenario))


def test_a_record_smeared_by_a_move_gives_way_to_the_stretch_the_robot_stood_still():
    # Seed 213 (lab span, a sine between two modes; the truth's tension -8 %): the robot
    # moves at 2 s. At 6.15 s the whole record, over which it moved 1.3 m, reads a tension more
    # than two combined stds from the first 2 s it stood still in; the belief follows that
    # stretch, whose reading holds the tension the line shows (the truth's, scaled by the
    # nominal mass: what a taut string's wavelength tells) within 1.5 std.
    scenario = fam.off_nominal(213)
    truth, told = scenario.span, scenario.nominal
    shown = truth.tension * told.conductor.mass_per_length / truth.conductor.mass_per_length
    args = scenario.run_arguments()
    result = plc.run_closed_loop(args.pop("span"), args.pop("force"), args.pop("robot"),
                                 args.pop("limits"), **args)
    moved = [(time, calibration) for time, calibration in result.calibrations
             if np.ptp(result.robot_position[result.t <= time + 1e-9]) > 0.0]
    time, calibration = moved[0]
    path = result.robot_position[result.t <= time + 1e-9]
    still = max(len(list(same)) for _, same in itertools.groupby(path))
    dt = float(result.t[1] - result.t[0])
    assert calibration.duration == pytest.approx((still - 1) * dt, abs=1.5 * dt)
    assert calibration.duration < time - 1.0
    assert abs(calibration.tension - shown) < 1.5 * calibration.tension_std
    assert result.belief.tension != told.tension


def test_a_move_the_measurements_contradict_is_undone_and_the_truth_agrees():
    # Seed 214 (lab span, a sine at 14.5 Hz, then 37.2 Hz from 4.8 s; the truth's tension
    # +3.6 %, EI x1.21, which the record's tone does not tell): after the change the belief
    # sends the robot to 2.163 m, predicted 63 % lower; the sensors measure 2.2x the power
    # there. The robot goes back, says so, and the truth (the full FE model's exact steady
    # state, not the loop's plant) ranks the return as the judge does: within 1.5x of the best
    # position, not above its start.
    scenario = fam.off_nominal(214)
    args = scenario.run_arguments()
    with pytest.warns(plc.errors.BeliefContradictedWarning, match="contradict its belief"):
        result = plc.run_closed_loop(args.pop("span"), args.pop("force"), args.pop("robot"),
                                     args.pop("limits"), **args)
    (when, what), = result.contradictions
    assert what.startswith("return to") and when < scenario.duration
    went_back = float(what.split()[2])
    assert abs(result.robot_position[-1] - went_back) < 1e-3   # the message rounds to 4 digits
    outcome = fam.evaluate(scenario, result)
    assert outcome.closed_over_best <= 1.5 and outcome.closed_over_start <= 1.05


@pytest.mark.slow
def test_held_out_family_keeps_its_measured_pass_rate_and_quantiles():
    """The 42 held-out scenarios (odd seeds 1-83, controller told the truth), judged on the
    exact steady state. Measured (2 workers, BLAS on one thread, 16 min wall on a loaded 2-core
    machine): no errors, settled 42/42, closed/best median 1.008, p90 1.139, worst 2.381, worst
    closed/start 1.012, 41/42 runs pass (settled, closed/best <= 1.5, closed/start <= 1.05);
    every lab run passes (24/24, worst 1.168). The one miss is seed 53 (Cardinal 249 m clamped,
    zeta 0.064 %, a sine between modes whose parked RMS minimum is 0.25 m wide): it ends 2.4x the
    best, 0.4 m from it, an information limit of four sensors on a still-ringing line
    (docs/validation/closed_loop.md). The bounds leave a modest margin over the measured values,
    so that a regression of the policy (a run lost, the median or tail moving) fails here."""
    seeds = fam.family("held_out", 42)
    with ProcessPoolExecutor(2, initializer=fam.pin_threads) as pool:
        outcomes = list(pool.map(fam.run_seed, seeds))
    summary = fam.summarise("held out", outcomes)
    lab = fam.summarise("lab", [o for o in outcomes if o.category.startswith("lab/")])
    report = fam.format_table(outcomes)
    assert summary.errors == 0, report
    assert summary.settled_fraction >= 0.95, report           # measured 1.00
    assert summary.median_best <= 1.03, report                 # measured 1.008
    assert summary.p90_best <= 1.25, report                    # measured 1.139
    assert summary.worst_best <= 3.0, report                   # measured 2.381 (seed 53)
    assert summary.worst_start <= 1.05, report                 # measured 1.012
    assert summary.passed >= 40, report                        # measured 41 of 42
    assert lab.passed == lab.n == 24 and lab.worst_best <= 1.3, report   # measured 1.168
