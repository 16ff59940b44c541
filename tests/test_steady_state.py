"""parked_steady_state against independent truth: dense direct solves of the full FE model with
the robot attached (LineModel(..., mdr=robot): its absorber is the last free DOF), and the modal
closed form of a pinned taut beam under a point sine."""

import dataclasses

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import powerline_control as plc
from powerline_control.errors import InputError, ModelError

LAB = plc.Span.paper_lab()
LONG = plc.Span.at_rts_fraction(400.0, "cardinal", 0.25)


def _dense_truth(bare: plc.LineModel, force, robot, position, line_c: np.ndarray):
    """Nodal amplitudes from one dense solve of (K - w^2 M + i w (C_line + C_damper)) u = f of
    the FE model with the robot attached at ``position``."""
    omega = 2 * np.pi * force.frequency
    uniform = np.allclose(np.diff(bare.node_positions), bare.element_length)
    with_robot = plc.LineModel(bare.span, bare.n_elements if uniform else None, bare.bc,
                               mdr=dataclasses.replace(robot, position=position))
    if bare.node_positions.size != with_robot.node_positions.size or not np.allclose(
            bare.node_positions, with_robot.node_positions):
        raise AssertionError("the mesh with the robot must be the bare mesh")
    n = bare.n_dofs
    c = np.zeros((with_robot.n_dofs, with_robot.n_dofs))
    c[:n, :n] = line_c
    c += with_robot.damper_matrix.toarray()
    dynamic = (with_robot.stiffness_matrix.toarray() - omega**2 * with_robot.mass_matrix.toarray()
               + 1j * omega * c)
    load = np.zeros(with_robot.n_dofs, dtype=complex)
    # sin(w t + phase) = Re(-i e^{i phase} e^{i w t})
    load[:n] = -1j * np.exp(1j * force.phase) * force.amplitude * bare.point_load(force.position)
    u = np.linalg.solve(dynamic, load)
    return bare.displacement_map() @ u[:n]


def _rms(model, field):
    x = np.asarray(model.node_positions)
    w = np.zeros_like(x)               # trapezoid weights, written out: independent of the code
    w[1:] += 0.5 * np.diff(x)
    w[:-1] += 0.5 * np.diff(x)
    return float(np.sqrt(0.5 * (w / w.sum()) @ np.abs(field) ** 2))


@threadpool_limits.wrap(limits=1, user_api="blas")
def test_lab_span_matches_dense_fe_solves_with_the_robot_attached():
    damping = plc.RayleighDamping.from_ratios((6.0, 60.0), 0.004)
    bare = plc.LineModel(LAB, 100, damping=damping)
    f3 = bare.natural_frequencies(3)[2]
    robot = plc.tune_damper(bare, 3, None, 0.04, body_mass=0.03)
    force = plc.HarmonicForce(1.0, 1.004 * f3, 1.37, phase=0.3)
    # everywhere, including 0.2 m from the load, 0.5 m and 1 cm from the clamps' ends
    positions = np.array([0.01, 0.05, 0.5, 0.93, 1.17, 1.37 - 0.2, 1.37 + 0.2, 1.37, 1.83, 2.5,
                          LAB.length - 0.5, LAB.length - 0.01])
    state = plc.simulation.parked_steady_state(bare, force, robot, positions)
    c = (damping.mass_coefficient * bare.mass_matrix
         + damping.stiffness_coefficient * bare.stiffness_matrix).toarray()
    for i, p in enumerate(positions):
        truth = _dense_truth(bare, force, robot, p, c)
        # Both are the same FE model and both solves are direct: round-off only (the dense LU of
        # a 201-square matrix with condition ~1e6 near resonance gives ~1e-10).
        np.testing.assert_allclose(state.field[i], truth, rtol=0,
                                   atol=1e-8 * np.abs(truth).max())
        assert state.rms[i] == pytest.approx(_rms(bare, truth), rel=1e-8)


@threadpool_limits.wrap(limits=1, user_api="blas")
def test_400m_clamped_span_matches_dense_fe_solves_near_a_clamp_and_a_load():
    damping = plc.RayleighDamping(0.05, 2e-6)
    bare = plc.LineModel(LONG, bc="clamped", damping=damping)    # the physics mesh, graded
    freqs = bare.natural_frequencies(150)
    mode = int(np.argmin(np.abs(freqs - 25.0))) + 1
    robot = plc.tune_damper(bare, mode, None, 3.0, body_mass=5.0)
    x_f = 151.3
    force = plc.HarmonicForce(20.0, 1.002 * freqs[mode - 1], x_f)
    positions = np.array([0.5, 1.7, x_f - 0.2, x_f + 0.2, 233.3, LONG.length - 0.5])
    state = plc.simulation.parked_steady_state(bare, force, robot, positions)
    c = (damping.mass_coefficient * bare.mass_matrix
         + damping.stiffness_coefficient * bare.stiffness_matrix).toarray()
    for i, p in enumerate(positions):
        truth = _dense_truth(bare, force, robot, p, c)
        # Direct solves of the same FE model (~2000 DOFs, condition ~1e8 near resonance): the
        # two differ by round-off, ~1e-9 of the peak.
        np.testing.assert_allclose(state.field[i], truth, rtol=0,
                                   atol=1e-7 * np.abs(truth).max())
        assert state.rms[i] == pytest.approx(_rms(bare, truth), rel=1e-7)
    # The robot changes the field: the tuned absorber near an antinode damps the span.
    assert state.best_rms < 0.5 * plc.simulation.parked_steady_state(bare, force, None).rms[0]


@threadpool_limits.wrap(limits=1, user_api="blas")
def test_modal_damping_matches_dense_solves_with_the_full_modal_damping_matrix():
    zeta = 0.003
    bare = plc.LineModel(LAB, 100, damping=plc.ModalDamping(zeta))
    f4 = bare.natural_frequencies(4)[3]
    robot = plc.tune_damper(bare, 4, None, 0.04, body_mass=0.03)
    force = plc.HarmonicForce(0.7, 0.996 * f4, 2.1)
    basis = bare.modes()
    mass = bare.mass_matrix.toarray()
    shapes = np.asarray(basis.shapes)
    c = mass @ shapes @ np.diag(2 * zeta * np.asarray(basis.omega)) @ shapes.T @ mass
    positions = np.array([0.5, 1.9, 2.3, 3.0])
    state = plc.simulation.parked_steady_state(bare, force, robot, positions)
    for i, p in enumerate(positions):
        truth = _dense_truth(bare, force, robot, p, c)
        # Modes above 2 f keep no damping in parked_steady_state: each of their terms changes by
        # < 2 zeta / 3 = 0.2 % and together they are a small part of the field: 1e-3 is ample.
        np.testing.assert_allclose(state.field[i], truth, rtol=0,
                                   atol=1e-3 * np.abs(truth).max())


def test_damper_power_is_the_absorber_dissipation_of_the_dense_solution():
    bare = plc.LineModel(LAB, 60, damping=plc.RayleighDamping(0.2, 0.0))
    f2 = bare.natural_frequencies(2)[1]
    robot = plc.tune_damper(bare, 2, None, 0.04, body_mass=0.02)
    force = plc.HarmonicForce(1.0, f2, 1.0)
    p = 2.6
    state = plc.simulation.parked_steady_state(bare, force, robot, [p])
    omega = 2 * np.pi * f2
    with_robot = plc.LineModel(LAB, 60, mdr=dataclasses.replace(robot, position=p))
    n = bare.n_dofs
    c = np.zeros((n + 1, n + 1))
    c[:n, :n] = 0.2 * bare.mass_matrix.toarray()
    c += with_robot.damper_matrix.toarray()
    dynamic = (with_robot.stiffness_matrix.toarray() - omega**2 * with_robot.mass_matrix.toarray()
               + 1j * omega * c)
    load = np.zeros(n + 1, dtype=complex)
    load[:n] = -1j * bare.point_load(1.0)
    u = np.linalg.solve(dynamic, load)
    relative = bare.shape_vector(p) @ u[:n] - u[n]          # line under the robot - absorber
    power = 0.5 * robot.damping * omega**2 * abs(relative) ** 2
    assert state.damper_power[0] == pytest.approx(power, rel=1e-9)   # round-off
    assert state.robot_displacement[0] == pytest.approx(bare.shape_vector(p) @ u[:n], rel=1e-9)


def test_pinned_beam_without_robot_matches_the_modal_closed_form():
    # Pinned taut beam: phi_n = sin(n pi x / L), modal mass m L / 2, omega_n from the closed
    # form (domain notes 3.1); a point sine F sin(w t) at x_f: amplitude -i F sum_n phi_n(x_f)
    # phi_n(x) / (m L / 2) / (omega_n^2 - w^2 + i a w) with mass-proportional damping a.
    span = LAB
    a, f0, x_f = 0.3, 1.4, 1.07
    model = plc.LineModel(span, 200, damping=plc.RayleighDamping(a, 0.0))
    frequency = 0.97 * model.natural_frequencies(3)[2]
    state = plc.simulation.parked_steady_state(model, plc.HarmonicForce(f0, frequency, x_f), None)
    n = np.arange(1, 4001)[:, None]
    m = span.conductor.mass_per_length
    omega_n = 2 * np.pi * span.pinned_frequencies(4000)[:, None]
    omega = 2 * np.pi * frequency
    x = model.node_positions[None, :]
    shapes = np.sin(n * np.pi * x_f / span.length) * np.sin(n * np.pi * x / span.length)
    truth = -1j * f0 * (shapes / (m * span.length / 2) / (omega_n**2 - omega**2 + 1j * a * omega)
                        ).sum(0)
    # 1e-4: 200 Hermite elements give the first modes to ~1e-9 in frequency (O(h^4)); the beam's
    # terms fall as 1 / n^4, so the series tail beyond 4000 modes is ~1e-11; what is left is the
    # FE's bending at the load point, measured ~1e-6 of the peak.
    np.testing.assert_allclose(state.field[0], truth, rtol=0, atol=1e-4 * np.abs(truth).max())
    assert np.isnan(state.positions[0]) and state.damper_power[0] == 0.0


def test_taut_string_without_robot_matches_the_greens_function():
    # A string (EI ~ 0): the exact steady state under a point sine at x_f is
    # F sin(k x<) sin(k (L - x>)) / (T k sin(k L)), k = w sqrt(m / T), undamped off resonance.
    cond = plc.Conductor(mass_per_length=0.2, diameter=0.01, ei=1e-9, rated_strength=1e4)
    span = plc.Span(length=2.0, tension=300.0, conductor=cond)
    model = plc.LineModel(span, 400)
    frequency, x_f, f0 = 140.0, 0.73, 2.0
    state = plc.simulation.parked_steady_state(model, plc.HarmonicForce(f0, frequency, x_f), None)
    k = 2 * np.pi * frequency * np.sqrt(cond.mass_per_length / span.tension)
    x = model.node_positions
    lo, hi = np.minimum(x, x_f), np.maximum(x, x_f)
    truth = -1j * f0 * np.sin(k * lo) * np.sin(k * (span.length - hi)) / (
        span.tension * k * np.sin(k * span.length))
    # 1e-4 of the peak away from the load: 400 cubic elements resolve the 0.36 m loops to
    # ~1e-8 in frequency. At the load a string has a kink that C1 Hermite cubics round off
    # over two elements (1.6 % of the peak measured at the load node), so 3 % there.
    far = np.abs(x - x_f) > 3 * model.element_length
    peak = np.abs(truth).max()
    np.testing.assert_allclose(state.field[0][far], truth[far], rtol=0, atol=1e-4 * peak)
    np.testing.assert_allclose(state.field[0], truth, rtol=0, atol=3e-2 * peak)


def test_aeolian_and_a_list_of_loads_are_superposed():
    model = plc.LineModel(LAB, 40, damping=plc.ModalDamping(0.01))
    robot = plc.tune_damper(model, 2, None, 0.04, body_mass=0.02)
    f = model.natural_frequencies(2)[1]
    a = plc.HarmonicForce(1.0, f, 0.7)
    b = plc.HarmonicForce(0.5, f, 2.9, phase=1.0)
    both = plc.simulation.parked_steady_state(model, [a, b], robot, [1.0, 2.0])
    one = plc.simulation.parked_steady_state(model, a, robot, [1.0, 2.0])
    two = plc.simulation.parked_steady_state(model, (b,), robot, [1.0, 2.0])
    # Linear in the load: round-off of a near-resonant solve (condition ~1e4) only.
    np.testing.assert_allclose(both.field, one.field + two.field, rtol=0,
                               atol=1e-9 * np.abs(both.field).max())
    wind = plc.simulation.parked_steady_state(model, plc.AeolianForce(wind_speed=1.0), robot)
    assert wind.frequency == pytest.approx(plc.AeolianForce(1.0).frequency_for(LAB.conductor))
    assert wind.positions.tolist() == [robot.position]
    assert both.best_position in (1.0, 2.0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(force=plc.RandomForce(std=1.0, position=1.0, bandwidth=20.0, seed=0)), "force"),
        (dict(force=3.0), "force"),
        (dict(force=[]), "force"),
        (dict(force=[plc.HarmonicForce(1.0, 10.0, 1.0), plc.HarmonicForce(1.0, 11.0, 1.0)]),
         "force"),
        (dict(positions=[-0.1]), "positions"),
        (dict(positions=[1.0, np.nan]), "positions"),
        (dict(positions=[4.0]), "positions"),
        (dict(positions=[[1.0]]), "positions"),
        (dict(robot="robot"), "robot"),
        (dict(model="model"), "model"),
    ],
)
def test_bad_arguments(kwargs, name):
    model = plc.LineModel(LAB, 20)
    args = dict(model=model, force=plc.HarmonicForce(1.0, 10.0, 1.0),
                robot=plc.MDR(1.0, 0.02, 0.01, 50.0, 0.1), positions=None)
    args.update(kwargs)
    with pytest.raises(InputError, match=name):
        plc.simulation.parked_steady_state(**args)


def test_model_with_a_robot_is_refused():
    robot = plc.MDR(1.0, 0.02, 0.01, 50.0, 0.1)
    with pytest.raises(InputError, match="mdr=None"):
        plc.simulation.parked_steady_state(plc.LineModel(LAB, 20, mdr=robot),
                                plc.HarmonicForce(1.0, 10.0, 1.0), robot)


def test_undamped_resonance_without_a_robot_is_a_model_error_not_nan():
    model = plc.LineModel(LAB, 20)
    f1 = float(model.natural_frequencies(1)[0])
    with pytest.raises(ModelError, match="Hz"):
        plc.simulation.parked_steady_state(model, plc.HarmonicForce(1.0, f1, 1.0), None)
