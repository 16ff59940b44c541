"""Tests of recipe.py: design_estimator and EstimatorDesign.

Independent truths: python-control's ``dlqe`` (the steady-state predictor gain of the same model
and sensors), a plain-numpy filter loop written here, and independent FE simulations of new runs
(never the identified model) for the accuracy claims.
"""

from __future__ import annotations

import dataclasses
import warnings

import control as ct
import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import InputError
from powerline_control.estimate import estimation_accuracy


@pytest.fixture(scope="module")
def small_design():
    """20-element lab span, broadband training record, 1 % noise."""
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    snap = plc.simulate(model, plc.RandomForce(1.0, 1.3, 90.0, seed=4), duration=4.0, dt=1e-3,
                        noise_fraction=0.01, seed=2)
    design = plc.design_estimator(snap, n_sensors=3, delays=4, rank=12, seed=0)
    return model, snap, design


def test_filter_gain_equals_python_control_dlqe(small_design):
    _, _, design = small_design
    m = design.model
    C = np.asarray(m.field_map)[design.sensors]
    R = design.noise_std**2 * np.eye(design.sensors.size)
    Q = np.asarray(m.residual_covariance) + design.q_floor * np.eye(m.n_states)
    # dlqe returns the predictor gain L = A P C^T (C P C^T + R)^-1 = A K (filter form K).
    L, P, _ = ct.dlqe(np.asarray(m.A), np.eye(m.n_states), C, Q, R)
    K = design.filter.steady_gain
    # Both solve the same DARE; agreement to ~1e-8 relative allows for the two solvers' round-off.
    assert np.allclose(np.asarray(m.A) @ K, L, rtol=1e-6, atol=1e-8 * np.abs(L).max())


def test_estimate_field_equals_a_plain_filter_loop(small_design):
    _, snap, design = small_design
    m = design.model
    y = snap.displacement[design.sensors, :300]
    A, C = np.asarray(m.A), np.asarray(m.field_map)[design.sensors]
    K = design.filter.steady_gain
    x = np.zeros(m.n_states)
    fields = []
    for k in range(y.shape[1]):
        prior = x if k == 0 else A @ x                     # prior of sample 0: x0 = 0
        x = prior + K @ (y[:, k] - C @ prior)
        fields.append(np.asarray(m.field_map) @ x)
    expected = np.array(fields).T
    got = design.estimate_field(y)
    # Same recursion in a different order of operations: round-off only.
    assert np.allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())


def test_sensors_avoid_the_supports_and_summary_names_them(small_design):
    _, snap, design = small_design
    assert design.sensors.size == 3
    assert 0 not in design.sensors and snap.x.size - 1 not in design.sensors  # pinned ends
    text = design.summary()
    assert str(design.sensors.tolist()) in text and "delays" in text


def test_small_span_estimates_a_new_broadband_run(small_design):
    model, snap, design = small_design
    test = plc.simulate(model, plc.RandomForce(1.0, 1.3, 90.0, seed=9), duration=3.0, dt=1e-3,
                        noise_fraction=0.01, seed=7, start_time=1.1)
    field = design.estimate_field(test.displacement[design.sensors])
    acc = estimation_accuracy(field, test.true_displacement, measured=design.sensors,
                              discard=300)
    print(f"small span, new broadband run: {acc.relative_rms_error_unmeasured:.2%}")
    # A different seed and load history than training, same sensors' noise fraction (1 %):
    # the 20-element span has only 19 moving nodes and 3 sensors; 10 % is a loose ceiling.
    assert acc.relative_rms_error_unmeasured < 0.10


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(n_sensors=0), InputError, "n_sensors"),
        (dict(n_sensors=2.5), InputError, "n_sensors"),
        (dict(delays=0), InputError, "delays"),
        (dict(rank=0), InputError, "rank"),
        (dict(spatial_rank=0), InputError, "spatial_rank"),
        (dict(criterion="best"), InputError, "criterion"),
        (dict(noise_std=-1.0), InputError, "noise_std"),
        (dict(noise_std=float("nan")), InputError, "noise_std"),
        (dict(sensors=[0, 0]), InputError, "sensors"),
        (dict(sensors=[99]), InputError, "sensors"),
        (dict(dt=0.5), InputError, "dt"),
        (dict(method="best"), InputError, "'method'"),
        (dict(method=None), InputError, "'method'"),
        (dict(process_noise=-1.0), InputError, "'process_noise'"),
        (dict(process_noise=float("nan")), InputError, "'process_noise'"),
        (dict(process_noise=1e7), InputError, "'process_noise'"),
        (dict(process_noise="1"), InputError, "'process_noise'"),
        (dict(positions=[0.0, 1.0]), InputError, "'positions'"),
    ],
)
def test_design_estimator_rejects_bad_input(small_design, kwargs, error, match):
    _, snap, _ = small_design
    with pytest.raises(error, match=match):
        plc.design_estimator(snap, **{"n_sensors": 3, "delays": 4, "rank": 12, **kwargs})


@pytest.mark.parametrize(
    "snapshots, kwargs, match",
    [
        (np.ones((3, 50)), {}, "dt"),                       # an array needs dt
        (np.zeros((4, 200)), {"dt": 1e-3}, "all zeros"),
        (np.full((4, 200), np.nan), {"dt": 1e-3}, "NaN"),
        (np.ones(200), {"dt": 1e-3}, "2-d"),
        # the shared rules of fit_dmd: transposed, complex, a boolean mask
        (np.ones((400, 4)), {"dt": 1e-3}, "'snapshots' parameter .* looks transposed"),
        (np.ones((4, 200)) * 1j, {"dt": 1e-3}, "'snapshots' parameter must be real"),
        (np.ones((4, 200)) > 0, {"dt": 1e-3}, "'snapshots' .* boolean"),
        # noise over 1e6 x the record's RMS (here RMS 1): no information, and R overflowed
        (np.ones((4, 200)), {"dt": 1e-3, "noise_std": 2e6}, "'noise_std' .* <= 1e\\+06"),
        (np.ones((4, 200)), {"dt": 1e-3, "noise_std": 1e300}, "'noise_std'"),
    ],
)
def test_design_estimator_rejects_bad_snapshots(snapshots, kwargs, match):
    with pytest.raises((InputError, plc.IdentificationError), match=match):
        plc.design_estimator(snapshots, n_sensors=1, delays=2, rank=2, **kwargs)


def test_estimate_field_rejects_wrong_shape(small_design):
    _, _, design = small_design
    with pytest.raises(InputError, match="measurements"):
        design.estimate_field(np.zeros((design.sensors.size + 1, 10)))


def test_summary_sigma_is_the_sigma_the_filter_reports(small_design):
    """The summary's sigma is the RMS, over the nodes and the training record (after the first
    consistency window, the filter's start-up), of what ``filter`` reports there, model-error
    terms included; recomputed here from the filter's own output on that record."""
    import re

    _, snap, design = small_design
    assert design.field_relative_variance > 0 and design.field_variance_scale != 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.EstimatorInconsistentWarning)
        reported = design.filter.filter(snap.displacement[design.sensors]).field_variances
    expected = float(np.sqrt(np.mean(np.mean(reported[:, 200:], axis=1))))
    line = next(t for t in design.summary().splitlines() if t.startswith("Reported field sigma"))
    assert "running mean square" in line
    # Printed to 3 significant digits: within half a unit of the third.
    assert float(re.search(r"RMS ([0-9.e+-]+) m", line).group(1)) == pytest.approx(expected,
                                                                                 rel=5e-3)


def test_filter_on_other_sensors_is_the_recipe_s_filter_with_its_model_error_terms(small_design):
    """Another layout's filter reports its sigma as the design's does. Truth: the Riccati
    equation solved here by python-control (``dlqe``) for the same model on the other sensors,
    and the running mean square written as a plain loop: field variance = field scale *
    diag(M P M^T) + relative share * running mean square of the estimate."""
    _, snap, design = small_design
    m = design.model
    design = dataclasses.replace(design, field_variance_scale=1.7,
                                 field_relative_variance=0.05)
    nodes = [4, 10, 16]
    kf = design.filter_on(nodes)
    y = snap.displacement[nodes, :400]
    est = kf.filter(y)
    C = np.asarray(m.field_map)[nodes]
    q = design.covariance_scale * (np.asarray(m.residual_covariance)
                                   + design.q_floor * np.eye(m.n_states))
    r = design.covariance_scale * design.noise_std**2 * np.eye(len(nodes))
    _, predicted, _ = ct.dlqe(np.asarray(m.A), np.eye(m.n_states), C, q, r)
    posterior = predicted - predicted @ C.T @ np.linalg.solve(C @ predicted @ C.T + r,
                                                              C @ predicted)
    M = np.asarray(m.field_map)
    riccati = np.einsum("ij,jk,ik->i", M, posterior, M)
    window = kf.consistency_window
    mean_square = np.empty_like(est.field)
    mean_square[:, 0] = est.field[:, 0] ** 2
    for k in range(1, est.field.shape[1]):
        mean_square[:, k] = (mean_square[:, k - 1] * (1 - 1 / window)
                             + est.field[:, k] ** 2 / window)
    expected = 1.7 * riccati[:, None] + 0.05 * mean_square
    # Two DARE solvers and two orders of summation: round-off, relative to the variances' scale.
    assert np.allclose(est.field_variances, expected, rtol=1e-6, atol=1e-9 * expected.max())
    assert kf.spectral_reference is None       # measured on the design's own sensors only
    assert design.innovation_growth is not None  # measured on the held-out part of the record
    assert kf.innovation_growth == design.innovation_growth == design.filter.innovation_growth
    assert design.filter_on(design.sensors) is design.filter
    with pytest.raises(InputError, match="'sensors'.*repeat"):
        design.filter_on([4, 4])
    with pytest.raises(InputError, match="'sensors'.*\\[0, 20\\]"):
        design.filter_on([4, 21])


# ------------------------------------------------------------------ generalisation
# Lab span, 100 elements, 1 % noise. The training run is a harmonic load near mode 2
# (14.39 Hz) plus a broadband load elsewhere on the span: richer excitation than the harmonic
# alone (with the harmonic alone the record holds every other mode only as a free transient at
# about the noise level per node, and no recipe can estimate what it never saw; see
# docs/identification.md, "The estimator recipe"). The new runs shift the harmonic by -/+10 %
# or are broadband with other seeds, start from rest at another time and have their own noise.

LAB_HARMONIC = plc.HarmonicForce(1.0, 14.2, 2.3)


@pytest.fixture(scope="module")
def lab_design():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=100)
    train = plc.simulate(model, [LAB_HARMONIC, plc.RandomForce(1.0, 1.1, 100.0, seed=17)],
                         duration=10.0, dt=1e-3, noise_fraction=0.01, seed=4)
    return model, plc.design_estimator(train, n_sensors=5, seed=0)


def _new_run_error(model, design, force, seed):
    test = plc.simulate(model, force, duration=4.0, dt=1e-3, noise_fraction=0.01, seed=seed,
                        start_time=2.9)
    field = design.estimate_field(test.displacement[design.sensors], noise_std=test.noise_std)
    acc = estimation_accuracy(field, test.true_displacement, measured=design.sensors,
                              discard=500)
    return acc.relative_rms_error_unmeasured


@pytest.mark.parametrize("shift", [0.9, 1.1], ids=["-10%", "+10%"])
def test_lab_design_generalises_to_shifted_harmonic_forcing(lab_design, shift):
    model, design = lab_design
    assert design.excitation.method == "dmd" and not design.excitation.narrowband  # broadband
    force = plc.HarmonicForce(1.0, LAB_HARMONIC.frequency * shift, LAB_HARMONIC.position)
    error = _new_run_error(model, design, force, seed=11)
    print(f"harmonic x{shift}: unmeasured-node error {error:.2%}")
    # Under 2 % on a new run with the frequency shifted by 10 %.
    assert error < 0.02


@pytest.mark.parametrize("position, seed", [(1.1, 23), (2.9, 29)])
def test_lab_design_generalises_to_new_broadband_forcing(lab_design, position, seed):
    model, design = lab_design
    error = _new_run_error(model, design, plc.RandomForce(1.0, position, 100.0, seed=seed),
                           seed=seed)
    print(f"broadband at {position} m: unmeasured-node error {error:.2%}")
    # Under 5 % for broadband forcing (a new load history, at the training
    # position and at another one).
    assert error < 0.05


@pytest.mark.slow
def test_real_span_design_estimates_a_new_aeolian_run():
    """Drake 300 m at 20 % RTS, 1000 elements, 5 sensors, 1 % noise, aeolian wind 3 m/s."""
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    model = plc.LineModel(span, n_elements=1000)
    wind = plc.AeolianForce(3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.TruncationWarning)  # the modes kept are reported
        train = plc.simulate(model, wind, duration=20.0, dt=2e-3, noise_fraction=0.01, seed=5)
        test = plc.simulate(model, wind, duration=8.0, dt=2e-3, noise_fraction=0.01, seed=6,
                            start_time=3.1)
    design = plc.design_estimator(train, n_sensors=5, seed=0)
    field = design.estimate_field(test.displacement[design.sensors], noise_std=test.noise_std)
    acc = estimation_accuracy(field, test.true_displacement, measured=design.sensors,
                              discard=500)
    print(f"real span: unmeasured-node error {acc.relative_rms_error_unmeasured:.2%}")
    # Under 3 % on held-out data (the time is in bench_identify.py).
    assert acc.relative_rms_error_unmeasured < 0.03


def test_reported_sigma_follows_the_model_error_from_rest_and_in_steady_state():
    """The reported sigma on a real span whose model is poor (70-75 % error at unmeasured nodes):
    Drake 300 m clamped, trained 12 s from rest on a sine near mode 6 plus a broadband load,
    then a new load history of the same kind run 7.2 s from rest and 21.6 s (judged on its
    last third, steady). The truth is the simulation's field. The error there grows 1.7x in
    sigma as the line rings up; the reported sigma (a scale of the Riccati variance plus
    a share of the estimate's running mean square, fitted on the training record and levelled
    on its held-out part) follows it: measured 0.96 from rest and 0.73 steady. With the
    previous constant rule (the held-out tail's ratio) the from-rest run read about 2x; a
    constant cannot be within 1.5x of both."""
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    model = plc.LineModel(span, n_elements=300, bc="clamped")
    rng = np.random.default_rng(1)
    f_sine = model.natural_frequencies(10)[5] * 0.99
    p_sine, p_random = span.length * rng.uniform(0.15, 0.85, size=2)

    def load(seed, phase):
        return [plc.HarmonicForce(1.0, f_sine, p_sine, phase=phase),
                plc.RandomForce(1.0, p_random, 10.0, seed=seed)]

    train = plc.simulate(model, load(1, 0.0), duration=12.0, dt=4e-3, noise_fraction=0.01,
                         seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.ExcitationWarning)
        design = plc.design_estimator(train, n_sensors=5, seed=0)
    assert design.field_relative_variance > 0
    assert "running mean square" in design.summary()
    unmeasured = np.setdiff1d(np.arange(1, model.node_positions.size - 1), design.sensors)
    ratios, errors = [], []
    for duration, judged_from in ((7.2, 0.0), (21.6, 2 / 3)):
        run = plc.simulate(model, load(11, 1.0), duration=duration, dt=4e-3,
                           noise_std=design.noise_std, seed=12, start_time=2.0)
        est = design.filter.filter(run.displacement[design.sensors])
        first = max(200, int(judged_from * run.t.size))  # 200: the filter's start-up
        truth = run.true_displacement[unmeasured, first:]
        error2 = np.mean((est.field[unmeasured, first:] - truth) ** 2)
        ratios.append(float(np.sqrt(np.mean(est.field_variances[unmeasured, first:]) / error2)))
        errors.append(float(np.sqrt(error2)))
    coverage = float(np.sqrt(np.mean(design.coverage.node_sigma[unmeasured] ** 2)))
    print(f"reported / actual sigma from rest, steady: {ratios}; errors {errors}; coverage "
          f"sigma {coverage}")
    assert errors[1] > 1.5 * errors[0]  # the error does grow as the line rings up
    assert all(1 / 1.5 < ratio < 1.5 for ratio in ratios)
    # Coverage.node_sigma is what the filter reports on a record like the training one (12 s
    # from rest): within 1.5x of the from-rest run's error (measured 1.08x).
    assert 1 / 1.5 < coverage / errors[0] < 1.5


def test_noise_level_is_estimated_from_an_array_without_metadata(small_design):
    """An array carries no noise_std: the Marchenko-Pastur bulk of its spectrum gives it."""
    _, snap, _ = small_design
    rng = np.random.default_rng(8)
    sigma = 3e-4
    X = snap.true_displacement + sigma * rng.standard_normal(snap.true_displacement.shape)
    design = plc.design_estimator(X, n_sensors=3, dt=snap.dt, delays=4, rank=12, seed=0)
    assert design.noise_source == "estimated"
    # 21 x 4001 noise samples: the median singular value scatters by a few %; signal occupies
    # about 8 of the 21 directions and lifts the median, hence the one-sided 15 % allowance.
    assert sigma * 0.95 < design.noise_std < sigma * 1.15


def test_noise_free_record_gives_a_working_estimator():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    force = plc.RandomForce(1.0, 2.2, 70.0, seed=12)
    train = plc.simulate(model, force, duration=4.0, dt=1e-3, seed=1)
    design = plc.design_estimator(train, n_sensors=4, delays=4, rank=16, seed=0)
    test = plc.simulate(model, plc.RandomForce(1.0, 2.2, 70.0, seed=13), duration=2.0,
                        dt=1e-3, seed=2, start_time=0.7)
    acc = estimation_accuracy(design.estimate_field(test.displacement[design.sensors]),
                              test.true_displacement, measured=design.sensors, discard=300)
    print(f"noise-free: {acc.relative_rms_error_unmeasured:.2%}")
    # Exact data, R floored at (1e-4 RMS)^2: errors of a few per mille are model truncation.
    assert acc.relative_rms_error_unmeasured < 0.03


# ------------------------------------------------------ harmonic-only training (narrowband)
# The main job trains on a harmonic load alone. Such a record holds the forced response and the
# free start-up transients of the undamped span: a sum of spectral lines. design_estimator then
# builds one oscillator per line (method "modal") and warns ExcitationWarning (the record is not
# persistently exciting). None of these loads, positions, meshes or seeds was used to tune the
# recipe (tuned on 24 Hz at 0.5 m, 14.2 Hz at 2.3 m and 33 Hz at 1.4 m, 100 elements, seed 4).

HARMONIC_ONLY = [  # (frequency Hz, position m, elements, training noise seed)
    (21.5, 1.9, 100, 13),
    (31.0, 0.8, 60, 14),
    (45.0, 2.6, 100, 15),
]


@pytest.fixture(scope="module", params=HARMONIC_ONLY, ids=lambda c: f"{c[0]}Hz@{c[1]}m-{c[2]}el")
def harmonic_design(request):
    frequency, position, n_elements, seed = request.param
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=n_elements)
    train = plc.simulate(model, plc.HarmonicForce(1.0, frequency, position), duration=10.0,
                         dt=1e-3, noise_fraction=0.01, seed=seed)
    with pytest.warns(plc.ExcitationWarning, match="not persistently exciting"):
        design = plc.design_estimator(train, n_sensors=5, seed=0)
    return model, frequency, position, design


def test_harmonic_record_is_reported_narrowband_with_the_span_s_own_frequencies(harmonic_design):
    model, frequency, _, design = harmonic_design
    ex = design.excitation
    assert ex.narrowband and ex.method == "modal"
    assert "not persistently exciting" in design.summary()
    # Independent truth: the load's frequency and the FE model's natural frequencies. A line of
    # a 10 s record is located to far better than its bin (0.1 Hz); 0.01 Hz allows for the
    # bias of a close neighbouring line.
    assert np.min(np.abs(ex.frequencies - frequency)) < 0.01
    for f in model.natural_frequencies(4):        # the start-up excites the lowest modes
        assert np.min(np.abs(ex.frequencies - f)) < 0.01
    # The lines explain the record down to the noise (residual ~ noise variance).
    assert 0.9 < ex.residual_ratio < 1.5


@pytest.mark.parametrize("shift", [0.9, 1.1], ids=["-10%", "+10%"])
def test_harmonic_only_design_generalises_to_shifted_harmonic_forcing(harmonic_design, shift):
    model, frequency, position, design = harmonic_design
    error = _new_run_error(model, design, plc.HarmonicForce(1.0, frequency * shift, position),
                           seed=31 if shift < 1 else 37)
    print(f"{frequency} Hz x{shift}: unmeasured-node error {error:.2%}")
    # Under 2 % on a new run with the frequency shifted by 10 %.
    assert error < 0.02


@pytest.mark.parametrize("bb_position, seed", [(None, 41), (1.3, 43)], ids=["same", "1.3m"])
def test_harmonic_only_design_generalises_to_broadband_when_the_record_saw_its_modes(
        harmonic_design, bb_position, seed):
    model, frequency, position, design = harmonic_design
    # A 100 Hz-band RandomForce excites the span's modes up to about 125 Hz (the lab span's
    # 8th mode is 122 Hz). The claim holds for records whose lines include all of them (FE
    # truth); a record that missed one is what ExcitationWarning is for.
    below = model.natural_frequencies(8)
    seen = all(np.min(np.abs(design.excitation.frequencies - f)) < 0.01 for f in below)
    force = plc.RandomForce(1.0, position if bb_position is None else bb_position, 100.0,
                            seed=seed)
    error = _new_run_error(model, design, force, seed=seed)
    print(f"{frequency} Hz record, broadband at {force.position} m: {error:.2%}"
          f" (record saw modes 1-8: {seen})")
    # These three records do (checked, so the claim below is never skipped silently).
    assert seen, "the record does not excite every mode the broadband load does"
    # Under 5 % for broadband forcing.
    assert error < 0.05


def test_smooth_basis_is_the_discrete_sine_basis_on_a_uniform_pinned_mesh():
    """Closed form: the Dirichlet second difference on a uniform grid has eigenvectors
    sin(j pi x / L) sampled at the nodes (the DST-I), eigenvalues ascending in j."""
    from powerline_control.recipe.modal import _smooth_basis

    x = np.linspace(0.0, 2.7, 31)
    moving = np.ones(x.size, dtype=bool)
    moving[[0, -1]] = False
    basis = _smooth_basis(x, moving, 6)
    for j in range(6):
        sine = np.sin((j + 1) * np.pi * x / x[-1])
        sine /= np.linalg.norm(sine)
        # Same unit vector up to sign; round-off of a 29 x 29 tridiagonal eigen-solve.
        assert abs(abs(float(basis[:, j] @ sine)) - 1.0) < 1e-10
    assert np.all(basis[[0, -1]] == 0.0)                 # nothing at the motionless supports


def test_spectral_lines_are_found_at_their_frequencies_and_nothing_else():
    """Three sinusoids (one 100x stronger, two 0.5 Hz apart, the weakest at half the noise std)
    in six coordinates with white noise: the extraction finds exactly them."""
    from powerline_control.recipe.modal import _extract_lines

    rng = np.random.default_rng(21)
    dt, n = 1e-3, 8000
    t = np.arange(n) * dt
    lines = [(7.3, 50.0), (19.1, 1.0), (19.6, 0.5)]   # (Hz, amplitude in noise std)
    shapes = rng.standard_normal((6, 3))
    shapes /= np.linalg.norm(shapes, axis=0)
    coords = sum(a * np.outer(shapes[:, i], np.sin(2 * np.pi * f * t + i))
                 for i, (f, a) in enumerate(lines)) + rng.standard_normal((6, n))
    freqs, found_shapes, residual = _extract_lines(coords, dt, 10)
    assert freqs.size == 3
    # Cramer-Rao: the weakest line's frequency std is sqrt(12 / (A^2 N^3)) / (2 pi dt) = 1.5 mHz;
    # 10 mHz is about 6 of them.
    assert np.allclose(freqs, [f for f, _ in lines], atol=0.01)
    for i in range(3):      # shapes up to sign; the weakest (SNR 0.5/sample) within a few %
        assert abs(float(found_shapes[:, i] @ shapes[:, i])) > 0.95
    # What is left is the noise: unit variance within the scatter of 48,000 samples.
    assert abs(float(np.mean(residual**2)) - 1.0) < 0.05


def test_method_dmd_on_a_harmonic_record_does_not_warn_and_modal_names_its_lines():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    train = plc.simulate(model, plc.HarmonicForce(1.0, 18.3, 1.6), duration=4.0, dt=1e-3,
                         noise_fraction=0.01, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # no ExcitationWarning asked for
        dmd = plc.design_estimator(train, n_sensors=3, delays=4, rank=12, seed=0,
                                   method="dmd")
    assert dmd.excitation.method == "dmd" and dmd.excitation.occupancy < 0.05
    with pytest.warns(plc.ExcitationWarning, match="18.3"):   # the load's line is named
        modal = plc.design_estimator(train, n_sensors=3, seed=0)
    assert modal.excitation.method == "modal"
    # Modal model: two states (now, one step ago) per line, plus at most 8 white states for
    # smooth directions the record never excited (eigenvalue 0). The lines' eigenvalues are
    # those of a_{k+1} = 2 rho cos(w dt) a_k - rho^2 a_{k-1}: rho exp(+/- i w dt), rho = 1 - 1e-6.
    r = modal.excitation.n_lines
    assert 2 * r <= modal.model.n_states <= 2 * r + 8
    eig = np.linalg.eigvals(np.asarray(modal.model.A))
    for f in modal.excitation.frequencies:
        expected = (1 - 1e-6) * np.exp(2j * np.pi * f * train.dt)
        assert np.min(np.abs(eig - expected)) < 1e-6     # round-off of a 2r-state eigen-solve
    assert np.sum(np.abs(eig) < 1e-9) == modal.model.n_states - 2 * r
    assert f"({r} lines, {2 * r} states)" in modal.summary()
    assert modal.estimate_field(train.displacement[modal.sensors]).shape == train.x.shape + (
        train.t.size,)


# ------------------------------------------------------------- review: edge cases of the recipe
@pytest.mark.parametrize("beta", [1.0, 0.999, 0.37])
def test_marchenko_pastur_median_matches_quadrature(beta):
    """Independent truth: the median of the Marchenko-Pastur density by adaptive quadrature and
    root finding (beta = 1 has a 1/x pole at x = 0, which a uniform grid in x cannot take)."""
    from scipy import integrate, optimize

    from powerline_control.recipe.record import _marchenko_pastur_median

    lo, hi = (1 - beta**0.5) ** 2, (1 + beta**0.5) ** 2

    def density(x):
        return np.sqrt(max((hi - x) * (x - lo), 0.0)) / (2 * np.pi * beta * x)

    def cdf(m):
        return integrate.quad(density, lo, m, limit=200)[0]

    median = optimize.brentq(lambda m: cdf(m) - 0.5, lo + 1e-12, hi, xtol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        value = _marchenko_pastur_median(beta)
    # 4000-point midpoint rule in the angle variable: ~1e-7 at beta = 1 and 0.37; just below 1
    # the pole sits at lo ~ 2.5e-7, a transition of width sqrt(lo) narrower than the grid step,
    # which costs ~3e-5 (the former grid in x was 3 % off there). 1e-4 of a median ~0.65.
    assert abs(value - median) < 1e-4


def test_noise_floor_of_a_square_white_noise_matrix():
    """A square record (n_nodes == n_samples, beta = 1) used to give NaN and a RuntimeWarning.
    Truth: the std of the white noise itself."""
    from powerline_control.recipe.record import _noise_floor

    rng = np.random.default_rng(2718)
    X = 0.3 * rng.standard_normal((150, 150))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sigma, threshold = _noise_floor(np.linalg.svd(X, compute_uv=False), X.shape)
    # The median singular value of a 150 x 150 Gaussian matrix scatters by ~1 %: 5 % is wide.
    assert abs(sigma / 0.3 - 1.0) < 0.05 and np.isfinite(threshold)


def test_smooth_basis_of_a_single_moving_node_is_that_node():
    from powerline_control.recipe.modal import _smooth_basis

    one = _smooth_basis(np.array([0.4]), np.array([True]), 3)     # a one-node record
    assert one.shape == (1, 1) and one[0, 0] == 1.0
    field = _smooth_basis(np.array([0.0, 0.5, 1.5]), np.array([False, True, False]), 2)
    assert np.array_equal(field, [[0.0], [1.0], [0.0]])


@pytest.mark.parametrize("frequency, amplitude, phase", [(11.7, 0.7, 0.4), (17.3, 1.0, 0.0)])
@pytest.mark.parametrize("method", ["auto", "modal", "dmd"])
def test_one_node_record_gives_a_working_estimator(method, frequency, amplitude, phase):
    """One node (used to raise IndexError in _smooth_basis for every method, and a 'Mean of
    empty slice' RuntimeWarning in the DMD held-out score with no unmeasured node). At 17.3 Hz
    the extraction also finds a weak spurious neighbour a bin below; with one node both have
    the same shape and the stronger (the record's own line) must be the one kept."""
    dt, n = 1e-3, 3000
    t = np.arange(n) * dt
    clean = amplitude * np.sin(2 * np.pi * frequency * t + phase)
    rng = np.random.default_rng(606)
    X = clean[None] + 0.01 * rng.standard_normal((1, n))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", plc.ExcitationWarning)   # one line: narrowband
        design = plc.design_estimator(X, dt=dt, n_sensors=1, noise_std=0.01, delays=2, rank=2,
                                      method=method)
    if design.excitation.method == "modal":
        # A 3 s line at SNR 70 per sample is located to well under 1 mHz; 10 mHz is generous.
        assert np.allclose(design.excitation.frequencies, [frequency], atol=0.01)
    estimate = design.estimate_field(X)
    # The filter averages the 0.01 m measurement noise: its error must be below that noise.
    error = float(np.sqrt(np.mean((estimate[0, 200:] - clean[200:]) ** 2)))
    assert error < 0.01


def test_modal_method_on_a_broadband_record_says_what_it_built():
    """Two lines on top of a white field in three smooth shapes (broadband, 50x the sensor
    noise): every bin is above the noise, so the record is not narrowband."""
    rng = np.random.default_rng(77)
    x = np.linspace(0.0, 1.0, 12)
    t = np.arange(3000) * 1e-3
    shapes = np.array([np.sin((j + 1) * np.pi * x) for j in range(3)])
    X = (np.outer(shapes[0], np.sin(2 * np.pi * 13.1 * t))
         + np.outer(shapes[1], np.sin(2 * np.pi * 27.4 * t + 1.0))
         + 0.05 * shapes.T @ rng.standard_normal((3, t.size))
         + 0.001 * rng.standard_normal((12, t.size)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")              # not narrowband: no ExcitationWarning
        design = plc.design_estimator(X, dt=1e-3, n_sensors=4, delays=4, rank=8,
                                      method="modal")
    ex = design.excitation
    assert ex.method == "modal" and not ex.narrowband and ex.residual_ratio > 1.5
    # The message used to read "Broadband record ...: time-delay DMD model." for this model.
    assert "DMD" not in ex.message and "method='modal'" in ex.message
    assert "time-delay DMD" not in design.summary()


def test_modal_method_without_spectral_lines_is_refused():
    rng = np.random.default_rng(88)
    with pytest.raises(plc.IdentificationError, match="'method'"):  # used to fall back to DMD
        plc.design_estimator(rng.standard_normal((10, 2000)), dt=1e-3, n_sensors=2,
                             delays=4, rank=8, method="modal")


@pytest.mark.parametrize("occupancy, expected", [(0.31, "Broadband record (31 %"),
                                                 (0.027, "Not a line spectrum: 2.7 %")])
def test_excitation_message_of_a_record_the_lines_do_not_explain(occupancy, expected):
    """Few bins above the noise but lines that leave much more than it (the real span's wind):
    not called broadband; many bins: broadband. Both get the DMD model."""
    from powerline_control.recipe import ExcitationReport

    report = ExcitationReport(narrowband=False, occupancy=occupancy,
                              frequencies=np.zeros(0), residual_ratio=float("nan"), method="dmd")
    assert report.message.startswith(expected) and "time-delay DMD" in report.message


# ------------------------------------------------------------------ fixes

def test_sensors_on_supports_are_refused(small_design):
    """Node 0 and 20 are the pinned supports: with 1 % noise they read noise and nothing else."""
    _, snap, _ = small_design
    for sensors in ([0, 5, 10], [5, 10, 20]):
        with pytest.raises(InputError, match=r"'sensors'.*do not move"):
            plc.design_estimator(snap, sensors=sensors, delays=4, rank=12)


@pytest.mark.parametrize("record", [
    np.ones((21, 2000)),                                                   # constant
    np.outer(np.arange(21.0), np.ones(2000)),                              # a constant shape
    np.outer(np.sin(np.linspace(0, np.pi, 21)), np.arange(2000) == 5.0),   # rank 1, one event
], ids=["constant", "constant-shape", "rank-1-impulse"])
def test_constant_and_rank_deficient_records_raise_identification_error(record):
    with pytest.raises(plc.IdentificationError):
        plc.design_estimator(record, dt=1e-3, n_sensors=3, delays=4, rank=12)


@pytest.mark.parametrize("method", ["dmd", "modal"])
def test_every_design_model_round_trips_save_and_load_bit_exact(small_design, method, tmp_path):
    _, snap, design = small_design
    if method == "modal":
        design = plc.design_estimator(snap, n_sensors=3, method="modal", seed=0)
    path = tmp_path / f"{method}.npz"
    plc.save_model(path, design.model)
    loaded = plc.load_model(path)
    for field in dataclasses.fields(design.model):
        ours, theirs = getattr(design.model, field.name), getattr(loaded, field.name)
        if isinstance(ours, np.ndarray):
            np.testing.assert_array_equal(theirs, ours, err_msg=field.name)
        else:
            assert theirs == ours, field.name


def test_alpha_sweep_widens_when_its_best_value_is_at_the_top(small_design):
    """A grid of one tiny alpha: the best is its edge, so the sweep must grow until the held-out
    minimum lies inside it (or the relative cap 1 is reached)."""
    _, snap, _ = small_design
    design = plc.design_estimator(snap, n_sensors=3, delays=4, rank=12, seed=0, alphas=[1e-14])
    sweep = design.alpha_sweep
    assert sweep.alphas.size > 1
    np.testing.assert_allclose(sweep.alphas[1:] / sweep.alphas[:-1], 100.0)
    best = int(np.argmin(sweep.held_out_error))
    assert best < sweep.alphas.size - 1 or sweep.alphas[-1] == 1.0
    assert design.model.alpha_relative == pytest.approx(sweep.alphas[best], rel=1e-12)


# ------------------------------------------------------------------ detection

# A design is trained on a sine near a low mode plus a broadband load band-limited to `band`;
# a *matched* run repeats that kind of load (new random history, phase, noise, start time); a
# *mismatched* run drives modes the training never saw: a sine at 1.5-3 x the band at a new
# place, or a sine 10 % lower elsewhere with a broadband load up to 3 x the band. The test
# runs carry the design's own sensor noise (a property of the sensors, not of the run).
RATE_CASES = {
    "lab-pinned": (plc.Span.paper_lab, "pinned", 60, 1e-3, 6.0, 100.0),
    "lab-clamped": (plc.Span.paper_lab, "clamped", 60, 1e-3, 6.0, 100.0),
    "cardinal-pinned": (lambda: plc.Span.at_rts_fraction(400.0, "cardinal", 0.25), "pinned",
                        400, 4e-3, 12.0, 10.0),
    "cardinal-clamped": (lambda: plc.Span.at_rts_fraction(400.0, "cardinal", 0.25), "clamped",
                         400, 4e-3, 12.0, 10.0),
}


def _warnings_on_new_runs(case: str, seed: int, n_designs: int, n_runs: int):
    """(matched warned, mismatched warned) lists of booleans over designs x runs, and on the
    matched runs the ratio of the reported to the actual RMS error at unmeasured nodes."""
    make_span, bc, n_elements, dt, duration, band = RATE_CASES[case]
    span = make_span()
    model = plc.LineModel(span, n_elements=n_elements, bc=bc)
    rng = np.random.default_rng(seed)
    length = span.length
    matched_warned, mismatched_warned, calibration = [], [], []
    for _ in range(n_designs):
        modes = model.natural_frequencies(10)
        f_sine = (modes[int(rng.integers(3, 8))] * 0.99 if case.startswith("lab")
                  else band * 0.6)
        p_sine, p_random = length * rng.uniform(0.15, 0.85, size=2)
        train = plc.simulate(
            model, [plc.HarmonicForce(1.0, f_sine, p_sine),
                    plc.RandomForce(1.0, p_random, band, seed=int(rng.integers(1000)))],
            duration=duration, dt=dt, noise_fraction=0.01, seed=int(rng.integers(1000)))
        design = plc.design_estimator(train, n_sensors=5, seed=0, warn_inconsistent=True)
        for run in range(n_runs):
            s = int(rng.integers(10_000))
            matched = [plc.HarmonicForce(1.0, f_sine, p_sine, phase=rng.uniform(0, 6)),
                       plc.RandomForce(1.0, p_random, band, seed=s)]
            if run % 2 == 0:
                unseen = [plc.HarmonicForce(1.0, band * rng.uniform(1.5, 3.0),
                                            length * rng.uniform(0.1, 0.9))]
            else:
                unseen = [plc.HarmonicForce(1.0, f_sine * 0.9, length * rng.uniform(0.1, 0.9)),
                          plc.RandomForce(1.0, length * rng.uniform(0.1, 0.9), 3 * band,
                                          seed=s + 1)]
            for load, warned in ((matched, matched_warned), (unseen, mismatched_warned)):
                test = plc.simulate(model, load, duration=0.6 * duration, dt=dt,
                                    noise_std=design.noise_std, seed=s + 7,
                                    start_time=rng.uniform(1, 5))
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    est = design.filter.filter(test.displacement[design.sensors])
                said = any(issubclass(w.category, plc.EstimatorInconsistentWarning)
                           for w in caught)
                assert said == (not est.consistency.consistent)  # the warning is the verdict
                warned.append(said)
                if warned is matched_warned:  # simulation truth against the reported sigma
                    unmeasured = np.setdiff1d(np.arange(test.x.size), design.sensors)
                    error = est.field[unmeasured, 200:] - test.true_displacement[unmeasured, 200:]
                    reported = np.sqrt(np.mean(est.field_variances[unmeasured, 200:]))
                    calibration.append(float(reported / np.sqrt(np.mean(error**2))))
    return matched_warned, mismatched_warned, calibration


def test_consistency_warning_on_a_handful_of_lab_runs():
    """Clamped lab span, one design, two matched and two mismatched runs (seeded).

    Measured: neither matched run warns; the broadband run above the training band warns; the
    sine at 1.5-3 x the band does not: its response at the sensors stays below their noise, so
    no innovation test can see it (its relative error is large on a field smaller than the
    sensor noise). The full family is in the slow test below.
    """
    matched, mismatched, calibration = _warnings_on_new_runs("lab-clamped", seed=21,
                                                             n_designs=1, n_runs=2)
    print(f"matched warned {matched}, mismatched warned {mismatched}, "
          f"reported / actual error {calibration}")
    assert matched == [False, False]
    assert mismatched[1]
    # On the lab span: the reported sigma at unmeasured nodes within a factor
    # 1.5 of the actual error (measured 1.1-1.2 on 12 matched lab runs, 0.86-1.19).
    assert all(1 / 1.5 < ratio < 1.5 for ratio in calibration)


# Measured on this family (seeds 40-43), windowed NIS alone (before the spectral test): lab-pinned
# 3/6 false alarms and 5/6 detected, lab-clamped 0/6 and 5/6, Cardinal pinned 0/6 and 2/6,
# Cardinal clamped 3/6 and 3/6 (15/24, 6/24). With the spectral test of the innovations and the
# low-side NIS no longer a rejection: every case 6/6 detected; false alarms lab-pinned 3/6, the
# others 0/6 (24/24, 3/24). With the spectral reference following the field
# (KalmanFilter(spectral_field_reference=...)): false alarms 0/24, detection 23/24 (a Cardinal
# clamped sine above the band, seed 43, now 3.0 x its reference against a threshold of 5.25: it
# landed where the training's field stood above the noise). The held-out family of
# tests/estimator_family.py is the main measure.
RATE_DETECTED, RATE_FALSE_ALARMS = 23, 0


@pytest.mark.slow
def test_consistency_warning_rates_on_lab_and_real_spans():
    """Detection and false-alarm rates, 24 runs each.

    Lab span and Cardinal 400 m at 25 % RTS, pinned and clamped, two designs per case, three
    matched and three mismatched runs per design. Targets >= 95 % detection and <= 5 % false
    alarms; measured 23/24 and 0/24 (before the spectral reference followed the field 24/24 and
    3/24, all on the lab-pinned designs), asserted as measured so that a change that makes them
    worse fails.
    """
    matched, mismatched = [], []
    for i, case in enumerate(RATE_CASES):
        m, u, ratios = _warnings_on_new_runs(case, seed=40 + i, n_designs=2, n_runs=3)
        print(f"{case}: matched warned {sum(m)}/{len(m)}, mismatched warned {sum(u)}/{len(u)}"
              f", reported / actual error on matched runs {np.round(ratios, 2).tolist()}")
        matched += m
        mismatched += u
    print(f"false alarms {sum(matched)}/{len(matched)}, detection {sum(mismatched)}/"
          f"{len(mismatched)}")
    assert len(matched) == len(mismatched) == 24
    assert sum(mismatched) >= RATE_DETECTED and sum(matched) <= RATE_FALSE_ALARMS

