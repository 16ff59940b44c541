"""Tests of antinode.py: analytic standing waves (antinodes of sin(n pi x / L) at (2k-1) L / (2n),
nodes at k L / n), sub-sample refinement, windows with noise and other modes, the propagated
uncertainty against Monte Carlo, the FE simulation, and (when estimation has landed) Kalman
estimates of the paper's span near resonance."""

from __future__ import annotations

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.antinode import (
    Antinode,
    largest_antinode,
    locate_antinodes,
    nearest_antinode,
)
from powerline_control.errors import InputError

L = 3.66  # the paper's span, m


def true_antinodes(n: int, length: float = L) -> np.ndarray:
    return (2 * np.arange(1, n + 1) - 1) * length / (2 * n)


def true_nodes(n: int, length: float = L) -> np.ndarray:
    return np.arange(n + 1) * length / n


@pytest.mark.parametrize("n_elements", [20, 100])
@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 7])
def test_mode_of_a_string_cosine_interpolation_is_exact(n, n_elements):
    x = np.linspace(0.0, L, n_elements + 1)
    found = locate_antinodes(np.sin(n * np.pi * x / L), x)
    assert len(found) == n
    # The cosine interpolation is exact for a sinusoid: only round-off remains.
    np.testing.assert_allclose([a.position for a in found], true_antinodes(n), atol=1e-9)
    np.testing.assert_allclose([a.amplitude for a in found], 1.0, atol=1e-9)
    nodes = true_nodes(n)
    # Loop ends from linear interpolation of zero crossings: error <= h^2 k / 8 * (curvature
    # ~ 0 at a zero of a sine), so round-off level; 1e-9 m.
    np.testing.assert_allclose([a.loop_start for a in found], nodes[:-1], atol=1e-9)
    np.testing.assert_allclose([a.loop_end for a in found], nodes[1:], atol=1e-9)
    # Without variances the uncertainty comes from the estimated noise of an exact sine, which
    # is its discretisation misfit of local parabolas, (k h)^4 / 24 of the amplitude at most
    # (2e-3 for mode 7 on 20 elements): the std is a small fraction of the sample spacing.
    assert all(a.uncertainty == "estimated" for a in found)
    assert all(0.0 <= a.position_std < 0.1 * L / n_elements for a in found)


@pytest.mark.parametrize("shift", [0.0, 0.013, 0.0247, 0.05])
def test_sub_sample_accuracy_off_grid(shift):
    # Antinodes between samples: |sin(k (x - shift))| with loop 0.61 m on a 0.0366 m grid.
    x = np.linspace(0.0, L, 101)
    k = 6 * np.pi / L
    field = np.sin(k * (x - shift))
    expected = shift + (2 * np.arange(1, 6) - 1) * np.pi / (2 * k)
    cosine = locate_antinodes(field, x)
    np.testing.assert_allclose([a.position for a in cosine][:5], expected, atol=1e-9)
    parabolic = locate_antinodes(field, x, interpolation="parabolic")
    # A parabola through 3 samples of a cosine peak is biased by at most about
    # (k h)^2 h / 24 ~ 2e-5 m here (Taylor's quartic term); 1e-4 m bounds it, and the nearest
    # sample alone would be up to h / 2 = 0.018 m off, so the test does discriminate.
    errors = np.abs(np.array([a.position for a in parabolic][:5]) - expected)
    assert np.all(errors < 1e-4)


def test_complex_mode_shape_with_arbitrary_phase():
    x = np.linspace(0.0, L, 101)
    mode = np.exp(0.7j) * np.sin(3 * np.pi * x / L)
    found = locate_antinodes(mode, x)
    np.testing.assert_allclose([a.position for a in found], true_antinodes(3), atol=1e-9)
    np.testing.assert_allclose([a.loop_end for a in found], true_nodes(3)[1:], atol=1e-9)


@pytest.mark.parametrize("envelope, tol", [("harmonic", 0.002), ("rms", 0.012), ("peak", 0.05)])
def test_window_with_second_mode_and_noise(envelope, tol):
    # Mode 3 at 24.5 Hz dominates; mode 1 at 6.5 Hz (30 %) and 5 % white noise disturb it.  The
    # harmonic fit rejects both; RMS keeps mode 1's power (a smooth bias on the outer loops) and
    # the peak keeps the noise maxima.  Tolerances, as fractions of the 1.22 m loop, are the
    # measured errors (5e-4, 6e-3, 2.3e-2) with a 2-4x margin: they rank the envelopes.
    rng = np.random.default_rng(0)
    x = np.linspace(0.0, L, 101)
    t = np.arange(2000) * 1e-3
    window = np.outer(np.sin(3 * np.pi * x / L), np.sin(2 * np.pi * 24.5 * t))
    window += 0.3 * np.outer(np.sin(np.pi * x / L), np.sin(2 * np.pi * 6.5 * t + 1.0))
    window += 0.05 * rng.standard_normal(window.shape)
    found = locate_antinodes(window, x, envelope=envelope, dt=1e-3)
    assert len(found) == 3
    errors = np.abs([a.position for a in found] - true_antinodes(3))
    assert np.all(errors < tol * L / 3)
    if envelope == "harmonic":
        # Hann-window peak interpolation: a small fraction of the 0.5 Hz bin.
        assert found[0].frequency == pytest.approx(24.5, abs=0.02)
        # fitted amplitude: the noise adds ~0.05 * sqrt(2 / 2000) = 1.6e-3 per node, and the sine
        # fit over the loop averages ~20 nodes
        assert found[0].amplitude == pytest.approx(1.0, abs=0.005)


def test_propagated_std_matches_monte_carlo():
    # Independent truth: the scatter of positions over 400 noisy realisations (sine fit, the
    # default).  The first-order propagation should agree within 15 % (sampling error of a std
    # from 400 draws is ~4 %; measured 4 %).  The 3-point "cosine" interpolation is not held to
    # this: with noise its peak sample wanders, and its scatter (measured 38 mm) is 11x the sine
    # fit's (3.3 mm) and 4x its own linearised std.
    rng = np.random.default_rng(1)
    x = np.linspace(0.0, L, 101)
    clean = np.sin(3 * np.pi * x / L)
    sigma = 0.02
    positions, stds = [], []
    for _ in range(400):
        noisy = clean + sigma * rng.standard_normal(x.size)
        found = locate_antinodes(noisy, x, variances=np.full(x.size, sigma**2), min_prominence=0.5)
        assert len(found) == 3
        positions.append(found[1].position)
        stds.append(found[1].position_std)
    empirical = np.std(positions)
    assert np.median(stds) == pytest.approx(empirical, rel=0.15)
    assert abs(np.mean(positions) - L / 2) < 3 * empirical / np.sqrt(400) + 1e-4


def test_window_variances_reduce_with_window_length():
    rng = np.random.default_rng(2)
    x = np.linspace(0.0, L, 51)
    t = np.arange(4000) * 1e-3
    window = np.outer(np.sin(2 * np.pi * x / L), np.sin(2 * np.pi * 14.4 * t))
    window += 0.01 * rng.standard_normal(window.shape)
    short = locate_antinodes(window[:, :1000], x, variances=np.full((51, 1000), 1e-4))
    long = locate_antinodes(window, x, variances=np.full((51, 4000), 1e-4))
    # amplitude variance 2 s^2 / n_t: four times the samples halve the std
    assert long[0].position_std == pytest.approx(short[0].position_std / 2, rel=0.05)


def test_simulated_span_near_resonance():
    # The lead's FE simulation (exact modal integration) forced at 24 Hz, near mode 3 (24.53 Hz).
    # Truth: antinodes located on the noise-free field; the noisy field (5 % noise) must agree to
    # 2 % of the loop length, and both lie near the mode's antinodes (the force at 0.5 m mixes in
    # other modes, which moves them by a few cm: 5 % of the loop).
    span = plc.Span.paper_lab()
    model = plc.LineModel(span, n_elements=100, bc="pinned", damping=plc.ModalDamping(0.01))
    force = plc.HarmonicForce(amplitude=1.0, frequency=24.0, position=0.5)
    snap = plc.simulate(model, force, duration=2.0, dt=1e-3, noise_fraction=0.05, seed=0)
    window = slice(-1000, None)
    truth = locate_antinodes(snap.true_displacement[:, window], snap.x, dt=snap.dt)
    noisy = locate_antinodes(snap.displacement[:, window], snap.x, dt=snap.dt)
    assert len(truth) == len(noisy) == 3
    for a, b in zip(truth, noisy, strict=True):
        assert abs(a.position - b.position) < 0.02 * a.loop_length
    assert truth[0].frequency == pytest.approx(24.0, abs=0.05)
    mode = locate_antinodes(model.mode_shapes(3)[:, 2], snap.x)
    np.testing.assert_allclose([a.position for a in truth], [a.position for a in mode],
                               atol=0.05 * L / 3)


def test_zero_field_has_no_antinodes():
    assert locate_antinodes(np.zeros(11), np.linspace(0, 1, 11)) == []


def test_helpers_pick_nearest_and_largest():
    x = np.linspace(0.0, L, 201)
    u = np.pi * x / L
    field = np.sin(2 * u) + 0.3 * np.sin(u)  # left loop 1.2, right loop 0.8 in magnitude
    found = locate_antinodes(field, x)
    assert len(found) == 2
    assert largest_antinode(found) is found[0]
    assert nearest_antinode(found, 3.0) is found[1]
    assert nearest_antinode(found, 0.0) is found[0]
    assert found[0].loop_end == found[1].loop_start  # the loops share their node


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: nearest_antinode([], 1.0), "empty"),
        (lambda: largest_antinode([]), "empty"),
        (lambda: nearest_antinode(["a"], 1.0), "Antinode"),
        (lambda: locate_antinodes(np.ones(5), np.arange(4.0)), "shape"),
        (lambda: locate_antinodes(np.ones(5), np.array([0, 1, 1, 2, 3.0])), "increasing"),
        (lambda: locate_antinodes(np.ones((5, 3)), np.arange(5.0)), "4 time samples"),
        (lambda: locate_antinodes(np.ones((5, 3, 2)), np.arange(5.0)), "1 or 2-d"),
        (lambda: locate_antinodes(np.ones(2), np.arange(2.0)), "at least 3"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), envelope="max"), "'envelope'"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), min_prominence=0.0),
         "'min_prominence'"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), variances=np.ones(4)), "variances"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), variances=-np.ones(5)),
         "non-negative"),
        (lambda: locate_antinodes(np.ones((5, 8)) * 1j, np.arange(5.0)), "real"),
        (lambda: locate_antinodes(np.array([0, 1, np.nan, 1, 0]), np.arange(5.0)), "NaN"),
        (lambda: locate_antinodes(np.array([0, 1, np.inf, 1, 0]), np.arange(5.0)), "'field'"),
        (lambda: locate_antinodes(np.ones(5), np.array([0, 1, np.nan, 3, 4.0])), "'x'"),
        (lambda: locate_antinodes(np.ones((5, 8)), np.arange(6.0)), "'x'"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), variances=np.full(5, np.nan)),
         "'variances'"),
        (lambda: locate_antinodes(np.ones((5, 8)), np.arange(5.0), variances=np.ones((5, 7))),
         "'variances'"),
        (lambda: locate_antinodes(np.ones((5, 8)), np.arange(5.0), dt=0.0), "'dt'"),
        (lambda: locate_antinodes(np.ones((5, 8)), np.arange(5.0), dt=-1e-3), "'dt'"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), interpolation="spline"),
         "'interpolation'"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), min_prominence=1.5),
         "'min_prominence'"),
        (lambda: locate_antinodes(np.ones(5), np.arange(5.0), min_prominence=np.nan),
         "'min_prominence'"),
        (lambda: locate_antinodes("field", np.arange(5.0)), "'field'"),
    ],
)
def test_bad_input(call, words):
    with pytest.raises(InputError, match=words):
        call()


def test_antinode_is_frozen():
    a = Antinode(1.0, 1.0, 0.0, 2.0, None, None, 10)
    assert a.loop_length == 2.0
    with pytest.raises(AttributeError):
        a.position = 2.0


def test_kalman_estimate_of_the_paper_span_near_resonance():
    # The paper's span (Table 1, 100 elements, pinned, 1 % modal damping)
    # forced at 24 Hz near mode 3 (24.53 Hz) plus a weak broadband force (so that identification
    # sees more than one frequency), 5 % measurement noise.  A DMD model (delays 2: a line is second
    # order; rank 10; relative Tikhonov 1e-3) is identified from the first 2 s of noisy snapshots;
    # a Kalman filter on it measures only 13 evenly spaced interior nodes and estimates the whole
    # field; the antinodes found on the last second of that estimate (data the model never saw)
    # must lie within 2 % of the loop length of those of the true (noise-free) simulated field.
    # Measured: 0.06-0.12 % of the loop.
    span = plc.Span.paper_lab()
    model = plc.LineModel(span, n_elements=100, bc="pinned", damping=plc.ModalDamping(0.01))
    forces = [
        plc.HarmonicForce(amplitude=1.0, frequency=24.0, position=0.5),
        plc.RandomForce(std=0.2, position=1.3, bandwidth=100.0, seed=1),
    ]
    snap = plc.simulate(model, forces, duration=4.0, dt=1e-3, noise_fraction=0.05, seed=0)
    dmd = plc.fit_dmd(snap.displacement[:, :2000], dt=snap.dt, alpha=1e-3, alpha_mode="relative",
                      delays=2, rank=10)
    measured = np.linspace(4, 96, 13).round().astype(int)
    noise_variance = float(np.var(snap.displacement - snap.true_displacement))
    kf = plc.KalmanFilter(dmd.to_statespace(measured=measured), Q=dmd.residual_covariance,
                          R=noise_variance, field_map=dmd.field_map)
    est = kf.filter(snap.displacement[measured])
    window = slice(-1000, None)
    truth = locate_antinodes(snap.true_displacement[:, window], snap.x, dt=snap.dt)
    found = locate_antinodes(est.field[:, window], snap.x, dt=snap.dt,
                             variances=est.field_variances[:, window])
    assert len(found) == len(truth) == 3
    for a, b in zip(truth, found, strict=True):
        assert abs(a.position - b.position) < 0.02 * a.loop_length
        # The reported std is the noise's share, small against the loop: measured 0.007-0.04 %
        # of it (it does not cover the model's bias: the errors above are 0.01-0.1 %).
        assert 0 < b.position_std < 1e-3 * a.loop_length
    assert found[0].frequency == pytest.approx(24.0, abs=0.1)  # 1 s window: 1 Hz bins, refined


# ------------------------------------------------------------------------------ off resonance
# Independent truth: the exact steady response of the lab span (a pinned taut beam,
# m w^2 y + EI y'''' - T y'' = F delta(x - x0) with y = y'' = 0 at both ends) to a harmonic
# point load, in closed form.  Away from the load y is a sum of sin(k .) and sinh(kappa .)
# terms with k^2, kappa^2 = (sqrt(T^2 + 4 EI m w^2) -/+ T) / (2 EI); the pinned ends leave one
# sine and one sinh on each side, and continuity of y, y', y'' plus the jump EI [y'''] = F at
# the load fix their four coefficients.


def pinned_beam_response(span, frequency, load):
    """y(x) of the pinned lab span under a unit harmonic point load at ``load`` (undamped)."""
    length, tension = span.length, span.tension
    ei, mass = span.conductor.ei, span.conductor.mass_per_length
    omega = 2 * np.pi * frequency
    root = np.sqrt(tension**2 + 4 * ei * mass * omega**2)
    k, kappa = np.sqrt((root - tension) / (2 * ei)), np.sqrt((root + tension) / (2 * ei))
    s_left, s_right = np.sinh(kappa * load), np.sinh(kappa * (length - load))

    def derivatives(u, side):  # y, y', y'', y''' of sin(k u) and sinh(kappa u) / norm
        norm = s_left if side == "left" else s_right
        sign = 1.0 if side == "left" else -1.0  # u = length - x on the right
        return np.array([
            [np.sin(k * u), sign * k * np.cos(k * u), -k**2 * np.sin(k * u),
             -sign * k**3 * np.cos(k * u)],
            [np.sinh(kappa * u) / norm, sign * kappa * np.cosh(kappa * u) / norm,
             kappa**2 * np.sinh(kappa * u) / norm, sign * kappa**3 * np.cosh(kappa * u) / norm],
        ])

    left, right = derivatives(load, "left"), derivatives(length - load, "right")
    system = np.zeros((4, 4))
    system[:3, :2], system[:3, 2:] = left[:, :3].T, -right[:, :3].T
    system[3, :2], system[3, 2:] = -ei * left[:, 3], ei * right[:, 3]
    a, c, b, d = np.linalg.solve(system, [0.0, 0.0, 0.0, 1.0])

    def y(x):
        x = np.asarray(x, dtype=float)
        xl, xr = np.minimum(x, load), length - np.maximum(x, load)
        return np.where(x <= load, a * np.sin(k * xl) + c * np.sinh(kappa * xl) / s_left,
                        b * np.sin(k * xr) + d * np.sinh(kappa * xr) / s_right)

    return y


def exact_largest_antinode(y, length):
    """Position of the largest |y| and the length of its loop (between zeros of y), exactly."""
    from scipy.optimize import brentq, minimize_scalar

    fine = np.linspace(0.0, length, 36601)
    values = y(fine)
    i = int(np.argmax(np.abs(values)))
    best = minimize_scalar(lambda s: -abs(float(y(s))), method="bounded",
                           bounds=(fine[max(i - 1, 0)], fine[min(i + 1, fine.size - 1)]),
                           options={"xatol": 1e-10})
    crossings = np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)[0]
    zeros = [0.0] + [brentq(y, fine[j], fine[j + 1]) for j in crossings] + [length]
    return best.x, min(z for z in zeros if z > best.x) - max(z for z in zeros if z < best.x)


LAB = plc.Span.paper_lab()
# Natural frequencies of the lab span: 6.53, 14.39, 24.53, 37.52, 53.66 Hz.  These lie between.
OFF_RESONANCE = [(11.2, 0.63), (20.7, 1.71), (31.0, 0.9), (31.0, 3.18), (43.9, 2.37),
                 (58.4, 1.12)]


def graded_mesh(n):
    """Nodes graded toward both ends (spacing 0.4x the mean there, 1.6x mid-span)."""
    s = np.linspace(0.0, 1.0, n)
    return LAB.length * (s - 0.6 * np.sin(2 * np.pi * s) / (2 * np.pi))


def test_closed_form_response_matches_modal_sum():
    # The truth itself, checked against a second independent form: the modal sum with the
    # pinned beam's modes sin(n pi x / L) (modal mass m L / 2) and w_n^2 = (EI k^4 + T k^2) / m.
    # 20000 modes: the tail is below 1e-6 of the response (terms fall as 1 / n^2).
    y = pinned_beam_response(LAB, 43.9, 2.37)
    x = np.linspace(0.0, LAB.length, 9)
    n = np.arange(1, 20001)
    k = n * np.pi / LAB.length
    c = LAB.conductor
    w2 = (c.ei * k**4 + LAB.tension * k**2) / c.mass_per_length
    modal = (2 / (c.mass_per_length * LAB.length)) * np.sin(np.outer(x, k)) @ (
        np.sin(k * 2.37) / (w2 - (2 * np.pi * 43.9) ** 2))
    np.testing.assert_allclose(y(x), modal, atol=1e-6 * np.max(np.abs(modal)))


@pytest.mark.parametrize("mesh", ["uniform", "graded"])
@pytest.mark.parametrize("kind", ["window", "snapshot"])
def test_largest_antinode_of_exact_off_resonance_fields(kind, mesh):
    # Exact steady fields of the lab span at frequencies between its
    # resonances and several load positions (a loop next to the load is not a sine), sampled on a
    # uniform (101 nodes) or graded (121 nodes, finer near the ends) mesh, as a 0.4 s window
    # y(x) cos(w t + 0.4) sampled at 1 kHz or as one snapshot y(x), plus white noise of 0.3, 1
    # and 3 % of the largest amplitude (seed 2026).  Requirement: the largest antinode within 2 %
    # of its loop length of the exact maximum of |y| up to 1 % noise.  Measured worst: 0.6 %
    # (window), 1.6 % (snapshot); at 3 % noise 0.9 % and 2.0 %.
    x = np.linspace(0.0, LAB.length, 101) if mesh == "uniform" else graded_mesh(121)
    t = np.arange(400) * 1e-3
    errors = {0.0: [], 0.003: [], 0.01: [], 0.03: []}
    stds = {level: [] for level in errors}
    for frequency, load in OFF_RESONANCE:
        y = pinned_beam_response(LAB, frequency, load)
        where, loop = exact_largest_antinode(y, LAB.length)
        shape = y(x)
        clean = np.outer(shape, np.cos(2 * np.pi * frequency * t + 0.4)) if kind == "window" \
            else shape
        rng = np.random.default_rng(2026)
        unit = rng.standard_normal(clean.shape)
        for level in errors:
            noisy = clean + level * np.max(np.abs(shape)) * unit
            found = largest_antinode(locate_antinodes(noisy, x, dt=1e-3))
            errors[level].append(abs(found.position - where) / loop)
            stds[level].append(found.position_std / loop)
    for level in (0.0, 0.003, 0.01):
        assert max(errors[level]) < 0.02, (level, errors[level])
    # Beyond the requirement (3 % noise): within 5 % of the loop (measured 2 %).
    assert max(errors[0.03]) < 0.05
    # The uncertainty grows with the noise.  At low noise it is the estimated bias of loops that
    # are not sines (and a window averages the noise over 400 samples, so its noise stays below
    # that bias up to 1 %): the median over the fields may stay flat there (5 % allowed for the
    # change of fit window), and then rises: at 3 % it is at least 1.5x the noise-free one, and
    # snapshots (noise not averaged) rise at every level.
    medians = [float(np.median(stds[level])) for level in (0.0, 0.003, 0.01, 0.03)]
    assert all(b > 0.95 * a for a, b in zip(medians[:-1], medians[1:], strict=True)), medians
    assert medians[-1] > 1.5 * medians[0], medians
    if kind == "snapshot":
        assert all(b > a for a, b in zip(medians[:-1], medians[1:], strict=True)), medians


def test_small_loop_between_resonances_keeps_its_own_ends():
    # A hard case: 31 Hz, here with the load at 1.1 m, where the exact response has a small
    # loop of 0.13 m between two large ones.  Its ends must be the zeros of the exact response
    # (a node-finding error of less than a sample spacing, 3.7 cm), and the large loops keep
    # theirs (the old code stretched one over the small loop).
    y = pinned_beam_response(LAB, 31.0, 1.1)
    from scipy.optimize import brentq

    fine = np.linspace(0.0, LAB.length, 36601)
    values = y(fine)
    crossings = np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)[0]
    zeros = np.array([brentq(y, fine[j], fine[j + 1]) for j in crossings])
    x = np.linspace(0.0, LAB.length, 101)
    t = np.arange(500) * 1e-3
    window = np.outer(y(x), np.sin(2 * np.pi * 31.0 * t))
    window += 0.01 * np.max(np.abs(window)) * np.random.default_rng(7).standard_normal(window.shape)
    found = locate_antinodes(window, x, min_prominence=0.01)
    ends = sorted({a.loop_start for a in found} | {a.loop_end for a in found})
    interior = np.array([e for e in ends if 0.0 < e < LAB.length])
    assert interior.size == zeros.size
    # Linear / sine interpolation of the harmonic's zero crossing with 1 % noise averaged over
    # 500 samples: a few mm (measured < 2 mm); 1 cm.
    np.testing.assert_allclose(interior, zeros, atol=0.01)


def test_uncertainty_of_a_sine_loop_scales_with_noise():
    # Without variances the std comes from the estimated noise: for a pure sine loop (no bias)
    # it must scale with the noise (linear propagation), and match the scatter over draws.
    x = graded_mesh(81)
    clean = np.sin(2 * np.pi * x / LAB.length)
    rng = np.random.default_rng(31)
    unit = rng.standard_normal((200, x.size))
    results = {}
    for sigma in (0.003, 0.03):
        found = [locate_antinodes(clean + sigma * u, x)[0] for u in unit]
        results[sigma] = (np.std([a.position for a in found]),
                          np.median([a.position_std for a in found]))
    (scatter_low, std_low), (scatter_high, std_high) = results[0.003], results[0.03]
    # 10x noise, 10x std (within 30 %: the fit window can change between draws)
    assert 7 < std_high / std_low < 13
    # the reported std covers the actual scatter to within a factor of 2 (it adds the shift to a
    # narrower fit as a bias estimate, so it is conservative; sampling error of 200 draws ~5 %)
    for scatter, std in ((scatter_low, std_low), (scatter_high, std_high)):
        assert 0.8 < std / scatter < 2.0


@pytest.mark.parametrize("bc", ["clamped", "pinned"])
def test_modes_on_the_models_own_graded_mesh(bc):
    # The physics model's default mesh (n_elements=None) is graded toward clamped supports, with
    # few nodes (about 35 on the lab span): locate_antinodes gets only model.node_positions.
    # Truth: the maximum of each loop of the same FE mode evaluated densely through its Hermite
    # shape functions (model.displacement_map at 36601 points, 0.1 mm apart), a computation
    # independent of the sampled nodes.  Requirement 2 % of the loop; measured 0.7 % (clamped:
    # the loops next to a clamp are not sines), 0.05 % (pinned).
    model = plc.LineModel(LAB, bc=bc)
    x = model.node_positions
    basis = model.modes(6)
    dense = np.linspace(0.0, LAB.length, 36601)
    on_dense, on_nodes = model.displacement_map(dense), model.displacement_map()
    for j in range(6):
        exact, sampled = on_dense @ basis.shapes[:, j], on_nodes @ basis.shapes[:, j]
        found = locate_antinodes(sampled, x)
        signs = np.sign(exact)
        zeros = dense[np.nonzero(signs[:-1] * signs[1:] < 0)[0]]
        ends = np.concatenate([[0.0], zeros, [LAB.length]])
        assert len(found) == j + 1
        for a, lo, hi in zip(found, ends[:-1], ends[1:], strict=True):
            inside = (dense > lo) & (dense < hi)
            peak = dense[inside][np.argmax(np.abs(exact[inside]))]
            assert abs(a.position - peak) < 0.02 * (hi - lo)
            # the loop ends are the exact zeros to within a fraction of the node spacing
            assert abs(a.loop_start - lo) < 0.02 and abs(a.loop_end - hi) < 0.02
