"""Tests of estimate/observability.py: rank, Gramian, Riccati covariance, reports.

Independent truths: closed forms (string mode shapes vanish at their nodes; scalar Riccati
equations), brute-force sums, SciPy's Lyapunov solver, python-control's ``dlqe`` and the plain
Riccati recursion iterated to convergence.
"""

from __future__ import annotations

import ast
import dataclasses
import pathlib
import re

import control as ct
import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import given, settings
from hypothesis import strategies as st

import powerline_control as plc
from powerline_control import _riccati
from powerline_control.errors import EstimationError, InputError
from powerline_control.estimate import (
    analyze_observability,
    compare_sensor_sets,
    observability_gramian,
    observability_rank,
    steady_state_covariance,
)


def string_modal_system(n_modes: int, n_nodes: int, *, dt=1e-3, zeta=0.01, f1=6.5):
    """Exact ZOH-discretised modal model of a taut string; outputs: displacement at every node.

    Mode n has shape sin(n pi x / L) and frequency n f1; states [q_n, qdot_n] per mode.
    """
    x = np.linspace(0.0, 1.0, n_nodes)
    blocks, c = [], np.zeros((n_nodes, 2 * n_modes))
    for k in range(n_modes):
        omega = 2 * np.pi * f1 * (k + 1)
        cont = np.array([[0.0, 1.0], [-(omega**2), -2 * zeta * omega]])
        blocks.append(sla.expm(cont * dt))
        c[:, 2 * k] = np.sin((k + 1) * np.pi * x)
    a = sla.block_diag(*blocks)
    return ct.ss(a, np.zeros((2 * n_modes, 1)), c, 0, dt=dt)


# ------------------------------------------------------------------------------------ rank


@pytest.mark.parametrize(
    "node, expected_rank",
    [
        (6, 2 * 3),  # x = 1/2: modes 2, 4, 6 have a node there
        (4, 2 * 4),  # x = 1/3: modes 3 and 6 vanish
        (3, 2 * 5),  # x = 1/4: mode 4 vanishes
        (1, 2 * 6),  # x = 1/12: no mode up to 6 vanishes
        (0, 0),  # the support: every mode shape vanishes
    ],
)
def test_rank_loss_at_mode_nodes(node, expected_rank):
    # dt = 0.01 s (Nyquist 50 Hz > 39 Hz) keeps the powers of A in obsv well separated, so the
    # numerical rank equals the structural one.
    sys = string_modal_system(6, 13, dt=0.01)
    assert observability_rank(sys, [node]) == expected_rank


def test_rank_full_with_two_generic_sensors():
    sys = string_modal_system(6, 11, dt=0.01)
    assert observability_rank(sys, [2, 3]) == 12
    assert observability_rank(sys, [5]) < 12  # midspan alone misses the even modes


def test_rank_tolerance_argument():
    # Two modes 1e-9 apart seen through one sensor: observable in theory (sigma_min ~ 4e-10,
    # far above round-off), not in practice (a tolerance of 1e-6 says so).
    sys = ct.ss(np.diag([0.5, 0.5 + 1e-9]), np.zeros((2, 1)), np.ones((1, 2)), 0, dt=1.0)
    assert observability_rank(sys) == 2
    assert observability_rank(sys, tol=1e-6) == 1
    with pytest.raises(InputError, match="tol"):
        observability_rank(sys, tol=-1.0)


# --------------------------------------------------------------------------------- Gramian


def brute_gramian(a, c, horizon):
    total, power = np.zeros_like(a), np.eye(a.shape[0])
    for _ in range(horizon):
        total += power.T @ c.T @ c @ power
        power = a @ power
    return total


@pytest.mark.parametrize("horizon", [1, 2, 3, 7, 64, 100])
def test_gramian_equals_brute_force_sum(horizon):
    sys = string_modal_system(3, 7)
    a, c = np.asarray(sys.A), np.asarray(sys.C)[[1, 4]]
    brute = brute_gramian(a, c, horizon)
    # Doubling reorders the sums: agreement to round-off, 1e-12 relative.
    np.testing.assert_allclose(
        observability_gramian(sys, horizon, [1, 4]), brute, rtol=0, atol=1e-12 * np.abs(brute).max()
    )


def test_gramian_of_a_rotation_is_finite_and_exact():
    """Marginally stable (|lambda| = 1): the infinite Gramian diverges, the finite one grows ~N."""
    theta = 0.3
    a = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    sys = ct.ss(a, np.zeros((2, 1)), [[1.0, 0.0]], 0, dt=1.0)
    gram = observability_gramian(sys, 1000)
    np.testing.assert_allclose(gram, brute_gramian(a, np.array([[1.0, 0.0]]), 1000), atol=1e-9)
    # Sum of cos^2 and sin^2 over 1000 angles: trace = 1000 exactly.
    assert np.trace(gram) == pytest.approx(1000.0, rel=1e-12)


def test_gramian_converges_to_lyapunov_solution_for_stable_models():
    sys = string_modal_system(2, 5, zeta=0.2)
    a, c = np.asarray(sys.A), np.asarray(sys.C)[[1]]
    infinite = sla.solve_discrete_lyapunov(a.T, c.T @ c)
    # zeta 0.2 at 6.5 Hz and 1 kHz: |lambda|^(2*2^15) ~ 1e-70, so the tail is negligible; the
    # Lyapunov solver and the sum agree to round-off (1e-9 relative for this conditioning).
    np.testing.assert_allclose(observability_gramian(sys, 2**15, [1]), infinite,
                               rtol=1e-9, atol=1e-9 * np.abs(infinite).max())


# ------------------------------------------------------------------------------- Riccati


def test_scalar_riccati_closed_form():
    """AR(1) x' = a x + w, y = x + v: P = a^2 P R / (P + R) + q, a quadratic in P."""
    a, q, r = 0.9, 0.5, 2.0
    sys = ct.ss([[a]], [[0.0]], [[1.0]], 0, dt=1.0)
    # P^2 + P (r - a^2 r - q) - q r = 0 (predicted form).
    b = r - a**2 * r - q
    predicted = (-b + np.sqrt(b**2 + 4 * q * r)) / 2
    assert steady_state_covariance(sys, q, r, form="predicted")[0, 0] == pytest.approx(
        predicted, rel=1e-12
    )
    posterior = predicted * r / (predicted + r)
    assert steady_state_covariance(sys, q, r)[0, 0] == pytest.approx(posterior, rel=1e-12)


def test_riccati_matches_dlqe_and_the_iterated_recursion():
    sys = string_modal_system(4, 9, zeta=0.02)
    sensors = [2, 7]
    n = sys.nstates
    q = 1e-4 * np.eye(n)
    r = np.full(9, 1e-3)  # one variance per candidate output
    posterior = steady_state_covariance(sys, q, r, sensors)
    a, c = np.asarray(sys.A), np.asarray(sys.C)[sensors]
    _, predicted, _ = ct.dlqe(a, np.eye(n), c, q, 1e-3 * np.eye(2))
    np.testing.assert_allclose(
        steady_state_covariance(sys, q, r, sensors, form="predicted"), predicted, rtol=1e-8,
        atol=1e-10 * np.abs(predicted).max(),
    )
    # Brute force: iterate the filter's covariance recursion until it stops changing.
    p = np.eye(n)
    for _ in range(20000):
        p_pred = a @ p @ a.T + q
        s = c @ p_pred @ c.T + 1e-3 * np.eye(2)
        p = p_pred - p_pred @ c.T @ np.linalg.solve(s, c @ p_pred)
    np.testing.assert_allclose(posterior, p, rtol=1e-7, atol=1e-9 * np.abs(p).max())


def test_adding_a_sensor_never_hurts():
    sys = string_modal_system(4, 9, zeta=0.02)
    q = 1e-4 * np.eye(sys.nstates)
    few = steady_state_covariance(sys, q, 1e-3, [2])
    more = steady_state_covariance(sys, q, 1e-3, [2, 6])
    # More information: P_more <= P_few in the PSD order (eigenvalues of the difference >= 0 up
    # to round-off of the DARE solutions, 1e-9 of the scale).
    assert np.linalg.eigvalsh(few - more).min() > -1e-9 * np.abs(few).max()
    assert np.trace(more) < np.trace(few)


def test_unobservable_unstable_mode_is_reported():
    sys = ct.ss(np.diag([1.1, 0.5]), np.zeros((2, 1)), [[0.0, 1.0]], 0, dt=1.0)
    with pytest.raises(EstimationError, match="detectable"):
        steady_state_covariance(sys, np.eye(2), 1.0)


def test_singular_r_is_refused_by_the_one_rule():
    sys = string_modal_system(2, 5)
    with pytest.raises(InputError, match="'R' parameter must be a finite positive variance"):
        steady_state_covariance(sys, np.eye(4), 0.0, [1])
    with pytest.raises(InputError, match="'R' parameter must be positive definite"):
        steady_state_covariance(sys, np.eye(4), np.ones((5, 5)), [1, 2])


def test_full_correlated_r_matches_scipy():
    """The one rule for R: a full matrix is used with its correlations (SciPy's DARE on it)."""
    sys = string_modal_system(3, 7, zeta=0.03)
    rng = np.random.default_rng(77)
    l = rng.normal(size=(7, 7))
    r = 1e-3 * (l @ l.T / 7 + 0.2 * np.eye(7))
    sensors = [1, 3, 4]
    q = 1e-4 * np.eye(6)
    a, c = np.asarray(sys.A), np.asarray(sys.C)[sensors]
    want = sla.solve_discrete_are(a.T, c.T, q, r[np.ix_(sensors, sensors)])
    got = steady_state_covariance(sys, q, r, sensors, form="predicted")
    # Two backward-stable solvers of a well-conditioned DARE: 1e-9 relative.
    np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-10 * np.abs(want).max())


# -------------------------------------------------------------------------------- reports


def test_report_node_std_with_field_map():
    sys = string_modal_system(3, 11)
    n = sys.nstates
    field_map = np.asarray(sys.C)  # modal state -> displacement at all 11 nodes
    q = 1e-4 * np.eye(n)
    report = analyze_observability(sys, [3, 8], Q=q, R=1e-3, field_map=field_map)
    p = steady_state_covariance(sys, q, 1e-3, [3, 8])
    np.testing.assert_allclose(report.node_std, np.sqrt(np.diag(field_map @ p @ field_map.T)),
                               rtol=1e-12)
    # Pinned supports: sin(n pi) is round-off (1e-16), so the std is 1e-15 of the largest.
    assert report.node_std[[0, -1]].max() < 1e-15 * report.node_std.max()
    assert report.observable and report.horizon == 2 * n
    assert report.max_std == pytest.approx(report.node_std.max())


def test_report_unseen_state_has_its_stationary_std():
    sys = ct.ss(np.diag([0.5, 0.9]), np.zeros((2, 1)), np.eye(2), 0, dt=1.0)
    report = analyze_observability(sys, [1], Q=np.eye(2), R=1.0)
    assert not report.observable and report.rank == 1
    assert report.node_std[0] == pytest.approx(1 / np.sqrt(1 - 0.25), rel=1e-10)
    assert report.gramian_condition_number == np.inf


def test_comparison_table():
    sys = string_modal_system(4, 21, zeta=0.02)
    q = 1e-4 * np.eye(sys.nstates)
    table = compare_sensor_sets(
        sys,
        {"first 3": [1, 2, 3], "spread 3": [3, 8, 13]},
        Q=q,
        R=1e-4,
        field_map=np.asarray(sys.C),
    )
    first, spread = table.reports
    # Sensors clustered at a support see the span worse than spread ones.
    assert spread.mean_std < first.mean_std
    text = table.to_markdown(unit_scale=1e3, unit="mm")
    assert text.count("\n") == 3 and "spread 3" in text and "[mm]" in text


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda s: observability_rank(s, [25]), "sensors"),
        (lambda s: observability_rank(s, [1, 1]), "repeat"),
        (lambda s: observability_rank(s, []), "at least one"),
        (lambda s: observability_rank(s, [1.0]), "integer"),
        (lambda s: observability_gramian(s, 0), "horizon"),
        (lambda s: steady_state_covariance(s, np.eye(3), 1.0), "wrong shape"),
        (lambda s: steady_state_covariance(s, np.eye(4), 1.0, form="x"), "form"),
        (lambda s: analyze_observability(s, Q=np.eye(4)), "together"),
        (lambda s: analyze_observability(s, field_map=np.ones((3, 5))), "field_map"),
        (lambda s: observability_rank(ct.ss(-np.eye(2), np.zeros((2, 1)), np.eye(2), 0)),
         "discrete-time"),
    ],
)
def test_bad_input(call, match):
    with pytest.raises(InputError, match=match):
        call(string_modal_system(2, 11))


def test_public_names_exported():
    assert plc.estimate.steady_state_covariance is steady_state_covariance
    assert plc.estimate.compare_sensor_sets is compare_sensor_sets


@pytest.mark.parametrize("radius", [0.99, 1.0, 1.3])
@pytest.mark.parametrize("route", ["doubling", "qz-fallback"])
def test_solve_filter_dare_matches_scipy_by_both_routes(radius, route, monkeypatch):
    """The doubling solver (first) and the QZ fallback give SciPy's stabilising solution."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(10, 10))
    a *= radius / np.abs(np.linalg.eigvals(a)).max()
    c, q, r = rng.normal(size=(3, 10)), 0.1 * np.eye(10), np.eye(3)
    reference = sla.solve_discrete_are(a.T, c.T, q, r)
    if route == "qz-fallback":
        monkeypatch.setattr(_riccati, "_doubling", lambda a_, q_, g: np.full_like(g, np.nan))
    # Two different algorithms on a well-conditioned problem: 1e-10 relative.
    np.testing.assert_allclose(_riccati.solve_filter_dare(a, c, q, r), reference, rtol=0,
                               atol=1e-10 * np.abs(reference).max())


def test_many_outputs_cost_what_the_states_cost():
    """1,001 outputs of a 6-state model: the information form gives SciPy's answer (SciPy
    itself on the full p x p problem is the independent truth here)."""
    sys = string_modal_system(3, 1001, zeta=0.02)
    q = 1e-6 * np.eye(6)
    r = np.linspace(1e-4, 3e-4, 1001)
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    want = sla.solve_discrete_are(a.T, c.T, q, np.diag(r))
    got = steady_state_covariance(sys, q, r, form="predicted")
    np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-9 * np.abs(want).max())
    s = c @ want @ c.T + np.diag(r)
    gain = plc.KalmanFilter(sys, q, r, steady_state=True).steady_gain
    np.testing.assert_allclose(gain, np.linalg.solve(s, c @ want).T, rtol=1e-6,
                               atol=1e-9 * np.abs(gain).max())


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(
    n=st.integers(2, 6),
    seed=st.integers(0, 2**31 - 1),
    radius=st.floats(0.1, 0.999),
)
def test_property_more_sensors_never_hurt(n, seed, radius):
    """Invariant: for any stable model, adding an output cannot increase the Riccati covariance."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    a *= radius / max(np.abs(np.linalg.eigvals(a)).max(), 1e-12)
    sys = ct.ss(a, np.zeros((n, 1)), rng.normal(size=(3, n)), 0, dt=1.0)
    q = np.diag(rng.uniform(0.1, 1.0, n))
    few = steady_state_covariance(sys, q, 0.5, [0])
    more = steady_state_covariance(sys, q, 0.5, [0, 2])
    assert np.allclose(few, few.T) and np.linalg.eigvalsh(few).min() > -1e-9 * np.abs(few).max()
    # PSD order up to the round-off of two DARE solutions (1e-8 of the scale).
    assert np.linalg.eigvalsh(few - more).min() > -1e-8 * np.abs(few).max()


def test_undetectable_random_walk_has_no_steady_state_even_through_the_fallback(monkeypatch):
    # x1 is a random walk nobody measures; x2 is stable and measured. No stabilising Riccati
    # solution exists: the doubling fallback must say so instead of returning ~1e60.
    import scipy.linalg

    def refuse(*args, **kwargs):
        raise np.linalg.LinAlgError("forced: use the fallback")

    monkeypatch.setattr(scipy.linalg, "solve_discrete_are", refuse)
    sys = ct.ss(np.diag([1.0, 0.5]), np.zeros((2, 1)), [[0.0, 1.0]], [[0.0]], dt=1.0)
    with pytest.raises(EstimationError, match=r"stabilising.*\[1\+0j\]"):
        steady_state_covariance(sys, Q=np.eye(2), R=1.0)
    monkeypatch.undo()  # and with SciPy's QZ available: the same refusal by the same rule
    with pytest.raises(EstimationError, match=r"stabilising.*\[1\+0j\]"):
        steady_state_covariance(sys, Q=np.eye(2), R=1.0)


# ----------------------------------------------------------------- overflow and NaN are reported


def test_rank_of_a_strongly_unstable_model_does_not_overflow():
    """A = 1e20 x (an orthogonal matrix), n = 30: A^29 ~ 1e580 overflows the observability
    matrix; the rank is a property of the pair, unchanged by scaling A, and the orthogonal pair
    with a generic C is well-conditioned: full rank (SVD of obsv(R, C) as the truth)."""
    n = 30
    rng = np.random.default_rng(8)
    rotation = np.linalg.qr(rng.normal(size=(n, n)))[0]
    c = rng.normal(size=(2, n))
    truth = np.linalg.matrix_rank(ct.obsv(rotation, c))
    assert truth == n
    with np.errstate(all="ignore"):
        assert not np.all(np.isfinite(ct.obsv(1e20 * rotation, c)))  # the naive route fails
    sys = ct.ss(1e20 * rotation, np.zeros((n, 1)), c, 0, dt=1.0)
    assert plc.estimate.observability_rank(sys) == truth
    report = plc.estimate.analyze_observability(sys, horizon=1)
    assert report.observable and report.rank == n
    assert np.isfinite(report.gramian_min_singular_value)


def test_gramian_over_a_long_horizon_of_an_unstable_model_is_refused():
    sys = ct.ss([[1.5]], [[0.0]], [[1.0]], 0, dt=1.0)
    # 1.5^(2N) passes 1e300 near N = 852: N = 10**6 must not silently return inf.
    with pytest.raises(EstimationError, match="horizon=1000000 overflows.*up to about 85"):
        observability_gramian(sys, 10**6)
    with pytest.raises(EstimationError, match="horizon"):
        analyze_observability(sys, horizon=10**6)
    # A short horizon is the exact finite sum: 1 + 1.5^2 + 1.5^4.
    assert observability_gramian(sys, 3)[0, 0] == pytest.approx(1 + 2.25 + 5.0625)


def test_analyze_observability_never_reports_observable_with_nan():
    # 1e200 overflows any Gramian beyond one step; the report must refuse rather than claim.
    sys = ct.ss(np.diag([1e200, 0.5]), np.zeros((2, 1)), np.eye(2), 0, dt=1.0)
    with pytest.raises(EstimationError):
        analyze_observability(sys)
    report = analyze_observability(sys, horizon=1)
    assert report.observable and np.isfinite(report.gramian_min_singular_value)


# --------------------------------------------------------------------- architecture
PACKAGE = pathlib.Path(plc.__file__).parent


def _private_imports(path: pathlib.Path) -> list[tuple[str, str]]:
    """(module, name) pairs of private names imported from another module of the package."""
    tree = ast.parse(path.read_text())
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level == 1 and node.module:
            module = node.module.split(".")[0]
        elif node.module and node.module.startswith("powerline_control."):
            module = node.module.split(".")[1]
        else:
            continue
        if module == path.stem:
            continue
        found += [(module, alias.name) for alias in node.names
                  if alias.name.startswith("_") and not alias.name.startswith("__")]
    return found


# Imports of other modules' private names that exist in code owned by other engineers (reported
# to the lead); the test fails on any new one, and on these too once they are gone from the list.
KNOWN_PRIVATE_IMPORTS = {"cli": {("config", "_toml_value"), ("config", "_resolve")}}


@pytest.mark.parametrize("path", sorted(PACKAGE.glob("*.py")), ids=lambda p: p.stem)
def test_no_module_imports_another_modules_private_names(path):
    """Shared helpers live in _validation (checks) or _riccati (the filter Riccati solver)."""
    found = set(_private_imports(path)) - KNOWN_PRIVATE_IMPORTS.get(path.stem, set())
    assert not found, f"{path.name} imports private names of other modules: {sorted(found)}"


def test_the_private_import_walker_would_catch_one(tmp_path):
    bad = tmp_path / "estimate.py"
    bad.write_text("from .observability import _solve_filter_dare\nfrom ._riccati import x\n")
    assert _private_imports(bad) == [("observability", "_solve_filter_dare")]


def _arrays_of(result):
    for field in dataclasses.fields(result):
        value = getattr(result, field.name)
        if isinstance(value, np.ndarray):
            yield field.name, value


def test_every_result_array_of_the_estimation_modules_is_read_only():
    sys = string_modal_system(2, 6, zeta=0.05)
    n = sys.nstates
    q = 1e-4 * np.eye(n)
    report = analyze_observability(sys, [1, 4], Q=q, R=1e-3, field_map=np.asarray(sys.C))
    table = compare_sensor_sets(sys, {"a": [1], "b": [2, 4]}, Q=q, R=1e-3)
    selection = plc.select_sensors(sys, 2, Q=q, R=1e-3, n_random=2)
    study = plc.sensors.sensor_count_study(sys, [1, 2], Q=q, R=1e-3, n_steps=20)
    y = np.random.default_rng(1).normal(size=(6, 40)) * 1e-3
    est = plc.KalmanFilter(sys, q, 1e-3, field_map=np.asarray(sys.C)).filter(y)
    acc = plc.estimation_accuracy(est.field, est.field + 1.0, measured=[0])
    cons = plc.estimate.filter_consistency(est, est.states)
    results = [report, *table.reports, selection, study, est, acc, cons,
               *selection.baselines.values()]
    seen = 0
    for result in results:
        for name, value in _arrays_of(result):
            assert not value.flags.writeable, (type(result).__name__, name)
            seen += 1
    assert seen >= 20
    for array in (steady_state_covariance(sys, q, 1e-3), observability_gramian(sys, 4)):
        assert not array.flags.writeable


# ------------------------------------------------------------------------- bad input, one table
def _sys():
    return string_modal_system(2, 5)


_Q = 1e-4 * np.eye(4)
_NAN_A = ct.ss(np.diag([np.nan, 0.5, 0.5, 0.5]), np.zeros((4, 1)), np.eye(4), 0, dt=1.0)
I, E = InputError, EstimationError

BAD_INPUT = [
    # observability_rank / gramian
    ("rank.sys type", lambda: observability_rank(np.eye(2)), I, "'sys'"),
    ("rank.sys NaN", lambda: observability_rank(_NAN_A), I, "'sys'"),
    ("rank.tol<0", lambda: observability_rank(_sys(), tol=-1.0), I, "'tol'"),
    ("rank.tol nan", lambda: observability_rank(_sys(), tol=float("nan")), I, "'tol'"),
    ("rank.tol str", lambda: observability_rank(_sys(), tol="1e-9"), I, "'tol'"),
    ("rank.sensors str", lambda: observability_rank(_sys(), "01"), I, "'sensors'"),
    ("rank.sensors bool", lambda: observability_rank(_sys(), [True]), I, "'sensors'"),
    ("rank.sensors missing output", lambda: observability_rank(_sys(), [5]), I, "'sensors'"),
    ("gramian.horizon float", lambda: observability_gramian(_sys(), 2.0), I, "'horizon'"),
    ("gramian.horizon<1", lambda: observability_gramian(_sys(), -3), I, "'horizon'"),
    ("gramian.sensors", lambda: observability_gramian(_sys(), 3, [7]), I, "'sensors'"),
    ("gramian.sys NaN", lambda: observability_gramian(_NAN_A, 3), I, "'sys'"),
    ("gramian.overflow", lambda: observability_gramian(
        ct.ss([[3.0]], [[0.0]], [[1.0]], 0, dt=1.0), 10**8), E, "'horizon'|horizon="),
    # steady_state_covariance: the one rule for Q and R
    ("ssc.R<0", lambda: steady_state_covariance(_sys(), _Q, -1.0), I, "'R'"),
    ("ssc.R=0", lambda: steady_state_covariance(_sys(), _Q, 0.0), I, "'R'"),
    ("ssc.R nan", lambda: steady_state_covariance(_sys(), _Q, float("nan")), I, "'R'"),
    ("ssc.R vector shape", lambda: steady_state_covariance(_sys(), _Q, np.ones(3)), I, "'R'"),
    ("ssc.R vector zero", lambda: steady_state_covariance(
        _sys(), _Q, np.array([1.0, 0.0, 1.0, 1.0, 1.0])), I, "'R'"),
    ("ssc.R matrix shape", lambda: steady_state_covariance(_sys(), _Q, np.eye(4)), I, "'R'"),
    ("ssc.R nonsymmetric", lambda: steady_state_covariance(
        _sys(), _Q, np.eye(5) + np.triu(np.ones((5, 5)), 1)), I, "'R'"),
    ("ssc.R indefinite", lambda: steady_state_covariance(_sys(), _Q, -np.eye(5)), I, "'R'"),
    ("ssc.R 3-d", lambda: steady_state_covariance(_sys(), _Q, np.ones((5, 5, 1))), I, "'R'"),
    ("ssc.R str", lambda: steady_state_covariance(_sys(), _Q, "0.1"), I, "'R'"),
    ("ssc.R bool", lambda: steady_state_covariance(_sys(), _Q, True), I, "'R'"),
    ("ssc.Q<0", lambda: steady_state_covariance(_sys(), -_Q, 1.0), I, "'Q'"),
    ("ssc.Q nan", lambda: steady_state_covariance(_sys(), _Q * np.nan, 1.0), I, "'Q'"),
    ("ssc.Q inf", lambda: steady_state_covariance(_sys(), float("inf"), 1.0), I, "'Q'"),
    ("ssc.sensors", lambda: steady_state_covariance(_sys(), _Q, 1.0, [9]), I, "'sensors'"),
    ("ssc.sys continuous", lambda: steady_state_covariance(
        ct.ss(-np.eye(2), np.zeros((2, 1)), np.eye(2), 0), np.eye(2), 1.0), I, "'sys'"),
    ("ssc.undetectable", lambda: steady_state_covariance(
        ct.ss(np.diag([1.2, 0.5]), np.zeros((2, 1)), [[0.0, 1.0]], 0, dt=1.0), np.eye(2), 1.0),
     E, "1.2"),
    # analyze_observability / compare_sensor_sets
    ("analyze.horizon 0", lambda: analyze_observability(_sys(), horizon=0), I, "'horizon'"),
    ("analyze.field_map 1-d", lambda: analyze_observability(_sys(), field_map=np.ones(4)), I,
     "'field_map'"),
    ("analyze.field_map nan", lambda: analyze_observability(
        _sys(), field_map=np.full((3, 4), np.nan)), I, "'field_map'"),
    ("analyze.R only", lambda: analyze_observability(_sys(), R=1.0), I, "'Q' and 'R'"),
    ("analyze.sys NaN", lambda: analyze_observability(_NAN_A), I, "'sys'"),
    ("compare.empty", lambda: compare_sensor_sets(_sys(), {}), I, "'sensor_sets'"),
    ("compare.bad set", lambda: compare_sensor_sets(_sys(), [[0, 0]]), I,
     r"'sensor_sets\[0\]'.*repeat"),
    ("compare.int", lambda: compare_sensor_sets(_sys(), 3), I, "'sensor_sets'"),
    ("compare.str", lambda: compare_sensor_sets(_sys(), "ab"), I, "'sensor_sets'"),
    ("compare.set of str", lambda: compare_sensor_sets(_sys(), ["ab"]), I,
     r"'sensor_sets\[0\]'"),
    ("compare.named set out of range", lambda: compare_sensor_sets(_sys(), {"far": [9]}), I,
     r"'sensor_sets\[\"far\"\]'"),
    ("compare.sys", lambda: compare_sensor_sets("sys", [[0]]), I, "'sys'"),
    ("ssc.form array", lambda: steady_state_covariance(_sys(), _Q, 1.0, form=np.empty(0)), I,
     "'form'"),
    ("ssc.form None", lambda: steady_state_covariance(_sys(), _Q, 1.0, form=None), I,
     "'form'"),
    ("ssc.Q complex", lambda: steady_state_covariance(_sys(), _Q * (1 + 1j), 1.0), I,
     "'Q'.*must be real"),
    ("ssc.R complex", lambda: steady_state_covariance(_sys(), _Q, 1.0 + 0j), I,
     "'R'.*must be real"),
]


@pytest.mark.parametrize(("name", "call", "error", "parameter"), BAD_INPUT,
                         ids=[row[0] for row in BAD_INPUT])
def test_bad_input_table(name, call, error, parameter):
    with pytest.raises(Exception) as info:
        call()
    assert type(info.value) is error, (name, type(info.value), info.value)
    assert re.search(parameter, str(info.value)), (name, str(info.value))
