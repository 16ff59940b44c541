"""FE model against closed forms: taut beam, clamped beam, string, modal sums, Rayleigh quotient."""

import control as ct
import numpy as np
import pytest
import scipy.linalg

import powerline_control as plc
from powerline_control.errors import InputError

LAB = plc.Span.paper_lab()


def beam(
    tension=LAB.tension, ei=LAB.conductor.ei, mass=LAB.conductor.mass_per_length, length=LAB.length
):
    cond = plc.Conductor(mass_per_length=mass, diameter=0.0105, ei=ei)
    return plc.Span(length=length, tension=tension, conductor=cond)


def test_pinned_frequencies_match_taut_beam_closed_form():
    model = plc.LineModel(LAB, n_elements=100, bc="pinned")
    n = np.arange(1, 11)
    cond = LAB.conductor
    omega = (
        (n * np.pi / LAB.length) ** 2
        * np.sqrt(cond.ei / cond.mass_per_length)
        * np.sqrt(1 + LAB.tension * LAB.length**2 / (cond.ei * n**2 * np.pi**2))
    )
    # The issue asks for 0.1 %; Hermite cubics at h = L/100 are far better (O(h^4), ~1e-6 at n=10).
    np.testing.assert_allclose(model.natural_frequencies(10), omega / (2 * np.pi), rtol=1e-3)
    np.testing.assert_allclose(model.natural_frequencies(10), omega / (2 * np.pi), rtol=2e-5)


def test_pinned_error_falls_at_fourth_order():
    exact = LAB.pinned_frequencies(4)[3]
    errors = [
        abs(plc.LineModel(LAB, n_elements=ne).natural_frequencies(4)[3] - exact) / exact
        for ne in (8, 16, 32)
    ]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # Hermite cubics converge in eigenvalue as h^4 (Strang & Fix); allow pre-asymptotic slack.
    assert np.all((orders > 3.6) & (orders < 4.4)), orders


@pytest.mark.parametrize("mass", [0.68, plc.line.PAPER_LAB_MASS_PER_LENGTH])
def test_clamped_with_tension_matches_root_finder_values(mass):
    # domain.md 3.3: analytic clamped-clamped roots (rad/s) for both readings of Table 1's mass.
    reference = {
        0.68: [25.9797068829, 56.8026664933, 95.6505264534, 144.1436150811, 203.0727261280],
        plc.line.PAPER_LAB_MASS_PER_LENGTH: [
            49.7021058024,
            108.6698996499,
            182.9902318474,
            275.7629729918,
            388.5010006103,
        ],
    }[mass]
    model = plc.LineModel(beam(mass=mass), n_elements=100, bc="clamped")
    # FE error at ne=100 is <= 5e-7 on modes 1-5 (domain.md convergence table).
    np.testing.assert_allclose(2 * np.pi * model.natural_frequencies(5), reference, rtol=1e-6)


def test_clamped_beam_without_tension_gives_classic_roots():
    span = beam(tension=0.0)
    model = plc.LineModel(span, n_elements=60, bc="clamped")
    beta_l = np.array([4.7300407, 7.8532046, 10.9956078])
    cond = span.conductor
    omega = (beta_l / span.length) ** 2 * np.sqrt(cond.ei / cond.mass_per_length)
    np.testing.assert_allclose(2 * np.pi * model.natural_frequencies(3), omega, rtol=1e-6)


def test_string_limit_without_bending_stiffness():
    span = beam(ei=0.0)
    model = plc.LineModel(span, n_elements=200, bc="pinned")
    n = np.arange(1, 6)
    # Cubic interpolation of a string still converges as h^4; 200 elements give ~1e-8.
    np.testing.assert_allclose(
        model.natural_frequencies(5), n * span.wave_speed / (2 * span.length), rtol=1e-7
    )


def test_mixed_supports_lie_between_pinned_and_clamped():
    f_pp = plc.LineModel(LAB, 40, "pinned").natural_frequencies(4)
    f_pc = plc.LineModel(LAB, 40, ("pinned", "clamped")).natural_frequencies(4)
    f_cc = plc.LineModel(LAB, 40, "clamped").natural_frequencies(4)
    # Rayleigh's constraint theorem: each added constraint raises every frequency.
    assert np.all(f_pp < f_pc) and np.all(f_pc < f_cc)


def test_stiffness_positive_definite_and_tension_sign():
    model = plc.LineModel(LAB, 20)
    scipy.linalg.cholesky(model.stiffness_matrix.toarray())  # raises if not positive definite
    # The paper's printed "+T y''" would subtract the tension stiffness: with T = 13x the Euler
    # load the matrix then has a negative eigenvalue (domain.md takeaway 1).
    bending_only = plc.LineModel(beam(tension=0.0), 20).stiffness_matrix.toarray()
    tension_part = model.stiffness_matrix.toarray() - bending_only
    assert np.linalg.eigvalsh(bending_only - tension_part).min() < 0


def test_sparse_shift_invert_agrees_with_dense():
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    big = plc.LineModel(span, n_elements=700)  # 1400 DOFs: above the dense limit
    assert big.n_dofs > plc.fem.DENSE_EIGEN_LIMIT
    # domain.md: Drake 300 m at 20 % RTS, f1 = 0.21865311 Hz, f10 = 2.18654979 Hz (closed form)
    f = big.natural_frequencies(10)
    np.testing.assert_allclose(f[[0, 9]], [0.21865311, 2.18654979], rtol=1e-7)


def test_steady_state_harmonic_response_matches_modal_sum():
    model = plc.LineModel(LAB, 100, damping=plc.ModalDamping(0.02))
    f0, freq, x_f = 1.0, 10.0, 0.7
    snap = plc.simulate(model, plc.HarmonicForce(f0, freq, x_f), duration=25.0, dt=1e-3)
    # Closed-form damped steady state: sum over analytic modes sin(n pi x/L), modal mass mL/2.
    n = np.arange(1, 401)[:, None]
    omega_n = 2 * np.pi * LAB.pinned_frequencies(400)[:, None]
    omega = 2 * np.pi * freq
    x = snap.x[None, :]
    phi = lambda pos: np.sin(n * np.pi * pos / LAB.length)  # noqa: E731
    modal_mass = LAB.conductor.mass_per_length * LAB.length / 2
    h = (
        phi(x_f) * phi(x) / modal_mass / (omega_n**2 - omega**2 + 2j * 0.02 * omega_n * omega)
    ).sum(0)
    t = snap.t[-500:]
    expected = f0 * (h[:, None] * np.exp(1j * omega * t)).imag
    # Transients decay as exp(-0.02 * 41 * 25) ~ 1e-9; FE frequency error near 10 Hz ~1e-9; the
    # analytic series tail beyond 400 terms is ~1e-9 relative. 1e-5 leaves room for all three.
    scale = np.abs(expected).max()
    assert np.abs(snap.true_displacement[:, -500:] - expected).max() < 1e-5 * scale


def test_stiff_absorber_acts_as_added_mass_rayleigh_estimate():
    x_r, mass = 0.9, 0.01
    plain = plc.LineModel(LAB, 60)
    basis = plain.modes(3)
    stiff = plc.LineModel(
        LAB, 60, mdr=plc.MDR(x_r, body_mass=0.0, suspended_mass=mass, stiffness=1e9)
    )
    # Rayleigh quotient with the unchanged mass-normalised mode: omega^2 / (1 + m phi(x_r)^2).
    phi = plain.shape_vector(x_r) @ basis.shapes
    rayleigh = basis.frequencies / np.sqrt(1 + mass * phi**2)
    got = stiff.natural_frequencies(3)
    drop = basis.frequencies - rayleigh
    # The quotient is exact to first order in the mass ratio; the remaining error is second order.
    np.testing.assert_allclose(got, rayleigh, atol=0.05 * drop.max())
    assert np.all(got < basis.frequencies)


def _frf_peaks(model, x_force, x_out, freqs):
    sys = model.to_statespace(force_positions=[x_force], outputs=[x_out])
    # |C (i w - A)^-1 B| through the eigen-decomposition of A: one eig instead of a solve per
    # frequency (control.frequency_response takes ~30 ms per point at this size).
    lam, vec = np.linalg.eig(sys.A)
    left = (sys.C @ vec).ravel() * np.linalg.solve(vec, sys.B).ravel()
    response = np.abs((left[None, :] / (2j * np.pi * freqs[:, None] - lam[None, :])).sum(1))
    interior = (response[1:-1] > response[:-2]) & (response[1:-1] > response[2:])
    return freqs[1:-1][interior], response


def test_tuned_absorber_at_antinode_splits_resonance():
    f1 = plc.LineModel(LAB, 40).natural_frequencies(1)[0]
    freqs = np.linspace(0.7 * f1, 1.3 * f1, 3001)
    damped = plc.ModalDamping(0.002)
    peaks_plain, resp_plain = _frf_peaks(plc.LineModel(LAB, 40, damping=damped), 0.5, 1.83, freqs)
    robot = plc.MDR.tuned(LAB.length / 2, 0.0, 0.02, f1, damping_ratio=0.01)
    peaks_mdr, resp_mdr = _frf_peaks(
        plc.LineModel(LAB, 40, damping=damped, mdr=robot), 0.5, 1.83, freqs
    )
    assert len(peaks_plain) == 1 and abs(peaks_plain[0] - f1) < 1e-3 * f1
    assert len(peaks_mdr) == 2 and peaks_mdr[0] < f1 < peaks_mdr[1]
    # mass ratio 0.02 / (m L / 2) = 0.059: Den Hartog splitting ~ +/- sqrt(mu)/2 ~ 12 %.
    assert 0.05 < (peaks_mdr[1] - peaks_mdr[0]) / f1 < 0.4


def test_tuned_absorber_at_a_node_leaves_that_mode_unchanged():
    plain = plc.LineModel(LAB, 40)
    f2 = plain.natural_frequencies(2)[1]
    robot = plc.MDR.tuned(LAB.length / 2, 0.05, 0.02, f2)  # midspan: a node of mode 2
    with_robot = plc.LineModel(LAB, 40, mdr=robot).natural_frequencies(6)
    assert np.min(np.abs(with_robot - f2)) < 1e-9 * f2


def test_statespace_poles_are_modal_frequencies():
    model = plc.LineModel(LAB, 10)
    sys = model.to_statespace()
    omega = 2 * np.pi * model.natural_frequencies(model.n_dofs)
    poles = np.sort_complex(sys.poles())
    np.testing.assert_allclose(np.sort(np.abs(poles.imag)), np.sort(np.r_[omega, omega]), rtol=1e-9)
    np.testing.assert_allclose(poles.real, 0.0, atol=1e-9 * omega.max())


def test_forced_response_agrees_with_simulate():
    model = plc.LineModel(LAB, 10, mdr=plc.MDR.tuned(0.9, 0.05, 0.02, 6.5, 0.05))
    sys = model.to_statespace(force_positions=[0.5])
    force = plc.RandomForce(std=1.0, position=0.5, bandwidth=100.0, seed=3)
    snap = plc.simulate(model, force, duration=1.0, dt=1e-4)
    response = ct.forced_response(sys, snap.t, snap.force)
    # Both integrate a load that is linear between samples exactly: round-off level agreement.
    scale = np.abs(snap.displacement).max()
    assert np.abs(response.outputs - snap.displacement).max() < 1e-9 * scale


def test_discrete_statespace_matches_continuous_step():
    model = plc.LineModel(LAB, 8)
    dt = 1e-3
    sysd = model.to_statespace(dt=dt, force_positions=[1.0])
    sysc = model.to_statespace(force_positions=[1.0])
    reference = ct.sample_system(sysc, dt, method="zoh")
    np.testing.assert_allclose(sysd.A, reference.A, atol=1e-10)
    np.testing.assert_allclose(sysd.B, reference.B, atol=1e-12)
    assert sysd.dt == dt


def test_displacement_at_arbitrary_position_interpolates_mode():
    model = plc.LineModel(LAB, 50)
    x = np.array([0.123, 1.0, 2.777])
    phi_full = model.modes(1).shapes[:, 0]
    at_x = model.displacement_map(x) @ phi_full
    nodal = model.displacement_map() @ phi_full
    # Mode 1 is close to sin(pi x / L); cubic interpolation error at h = L/50 is ~1e-7.
    np.testing.assert_allclose(at_x / nodal.max(), np.sin(np.pi * x / LAB.length), atol=2e-3)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(n_elements=0), "n_elements"),
        (dict(n_elements=10.0), "n_elements"),
        (dict(bc="free"), "bc"),
        (dict(bc=("pinned", "hinged")), "bc[1]"),
        (dict(mdr=plc.MDR(position=5.0)), "mdr.position"),
        (dict(damping=0.01), "damping"),
    ],
)
def test_bad_model_arguments(kwargs, name):
    with pytest.raises(InputError, match=name.replace("[", r"\[").replace("]", r"\]")):
        plc.LineModel(LAB, **{"n_elements": 10, **kwargs})


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: plc.Conductor(mass_per_length=-1, diameter=0.01, ei=1), "mass_per_length"),
        (lambda: plc.Conductor(mass_per_length=1, diameter=float("nan"), ei=1), "diameter"),
        (lambda: plc.Conductor(mass_per_length=1, diameter=0.01, ei=float("inf")), "ei"),
        (lambda: plc.Span(length=0.0, tension=1.0, conductor=LAB.conductor), "length"),
        (lambda: plc.Span(length=1.0, tension=-5.0, conductor=LAB.conductor), "tension"),
        (lambda: plc.Span(length=1.0, tension=5.0, conductor="drake"), "conductor"),
        (lambda: plc.conductors["unobtainium"], "unobtainium"),
        (lambda: plc.conductors["drake"].tension_at(1.5), "fraction_of_rts"),
        (lambda: plc.Span.paper_lab(mass_reading="kg"), "mass_reading"),
        (lambda: plc.MDR(position=1.0, suspended_mass=0.1, stiffness=0.0), "stiffness"),
        (lambda: plc.LineModel(LAB, 10).shape_vector(-0.1), "position"),
        (lambda: plc.LineModel(LAB, 10).modes(0), "n_modes"),
        (lambda: plc.LineModel(LAB, 10).to_statespace(dt=0.0), "dt"),
        (lambda: plc.LineModel(LAB, 10).to_statespace(force_positions=[4.0]), "force_positions"),
    ],
)
def test_bad_parameters_name_the_parameter(make, name):
    with pytest.raises(InputError, match=name):
        make()


def test_modes_are_cached_per_model_and_read_only():
    model = plc.LineModel(LAB, 20)
    basis = model.modes(3)
    assert model.modes(n_modes=3) is basis
    with pytest.raises(ValueError, match="read-only"):
        basis.omega[:] = 0.0
    # Another model's cache is its own.
    assert plc.LineModel(LAB, 20).modes(3) is not basis
