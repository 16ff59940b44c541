"""Tests of sensors.py: exact criterion against SciPy, certificate against brute force.

Truth sources: SciPy's DARE (QZ) and observability.steady_state_covariance for the Riccati solver;
closed forms for decoupled scalar states; brute force over every layout for the optimum; NumPy
for the log-det / eigenvalue criteria.
"""

from __future__ import annotations

import itertools
import math

import control as ct
import cvxpy as cp
import numpy as np
import pytest
import scipy.linalg as sla

import powerline_control as plc
from powerline_control import _riccati
from powerline_control._riccati import steady_state_batch
from powerline_control.errors import InputError, SensorSelectionError
from powerline_control.estimate import steady_state_covariance
from powerline_control.sensors.criteria import KalmanCriterion, _information

SPAN = plc.Span.paper_lab()


def random_system(seed: int, n: int = 6, m: int = 10, radius: float = 0.95):
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n, n))
    a *= radius / np.max(np.abs(np.linalg.eigvals(a)))
    c = rng.standard_normal((m, n))
    l = rng.standard_normal((n, n))
    q = l @ l.T / n + 0.01 * np.eye(n)
    return ct.ss(a, np.zeros((n, 0)), c, np.zeros((m, 0)), 1.0), q


def line_problem(seed: int, bc: str = "pinned", n_modes: int = 5):
    """A 20-element paper span, modal-truncated, forced at a seeded position with seeded noise."""
    rng = np.random.default_rng(seed)
    damping = plc.ModalDamping(float(rng.uniform(0.005, 0.05)))
    model = plc.LineModel(SPAN, n_elements=20, bc=bc, damping=damping)
    x_force = float(rng.uniform(0.2, 3.4))
    sys = model.to_statespace(dt=2e-3, force_positions=[x_force], n_modes=n_modes)
    b = np.asarray(sys.B)
    force_std = float(rng.uniform(0.1, 2.0))
    q = force_std**2 * b @ b.T + 1e-3 * force_std**2 * np.diag(np.diag(b @ b.T).mean() *
                                                                 np.ones(sys.nstates))
    noise_std = float(10 ** rng.uniform(-6, -4))
    return model, sys, q, noise_std**2


def brute_force_optimum(sys, k, criterion, **kwargs) -> float:
    """The optimum over every layout: the library's own enumeration (its brute-force baseline).

    Tests of the relaxation's certificate run without it (``brute_force_limit=0``), since with it
    the bound is the enumerated optimum itself.
    """
    sel = plc.select_sensors(sys, k=k, criterion=criterion, n_random=0, **kwargs)
    return sel.baselines["brute-force"].objective


def exact_trace(sys, q, r, layout) -> float:
    """Independent exact criterion: SciPy's DARE through estimate/observability.py."""
    return float(np.trace(steady_state_covariance(sys, q, r, list(layout))))


# --------------------------------------------------------------------------- Riccati solver
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("n", [3, 12])
def test_doubling_matches_scipy_dare(seed, n):
    sys, q = random_system(seed, n=n, m=n + 2, radius=0.999)
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    layouts = np.array([[0, 1], [2, 3], [1, n + 1]])
    prior, post, ok = steady_state_batch(a, q, _information(c, layouts))
    assert ok.all()
    for b, layout in enumerate(layouts):
        cs = c[layout]
        want = sla.solve_discrete_are(a.T, cs.T, q, np.eye(len(layout)))
        # Both are backward-stable solvers of a well-conditioned DARE: agreement to ~1e-9.
        np.testing.assert_allclose(prior[b], want, rtol=1e-8, atol=1e-10 * np.abs(want).max())
        np.testing.assert_allclose(post[b], steady_state_covariance(sys, q, 1.0, layout),
                                   rtol=1e-8, atol=1e-10 * np.abs(want).max())


def test_doubling_flags_an_invisible_marginal_mode():
    # A random walk that nobody measures: the covariance grows without bound.
    a = np.diag([1.0, 0.5])
    c = np.array([[0.0, 1.0], [1.0, 0.0]])
    _, _, ok = steady_state_batch(a, np.eye(2), _information(c, np.array([[0], [1]])))
    assert ok.tolist() == [False, True]


def test_prior_lower_bound_holds_for_every_layout():
    """P_S >= A P_all A^T + Q (the proof in KalmanCriterion's docstring), checked on all pairs."""
    sys, q = random_system(3, n=5, m=8)
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    crit = KalmanCriterion(a, q, c, np.eye(5), relaxation_rank=5)
    layouts = np.array(list(itertools.combinations(range(8), 2)))
    prior, _, ok = steady_state_batch(a, q, _information(c, layouts))
    assert ok.all()
    gaps = np.linalg.eigvalsh(prior - crit.prior_bound).min(axis=1)
    # Round-off of the two Riccati solutions (~1e-12 of their size) is the only slack allowed.
    assert gaps.min() >= -1e-10 * np.abs(prior).max()
    # ...and a smaller prior would be wrong: the bound is attained in some direction only when
    # sensors are added, so with 2 of 8 sensors the difference is positive somewhere.
    assert (np.linalg.eigvalsh(prior - crit.prior_bound).max(axis=1) > 1e-6).all()


# --------------------------------------------------------------------------- closed form
def test_decoupled_states_pick_the_largest_reductions():
    """Diagonal A, identity C: each state is a scalar filter with a closed-form variance."""
    a_diag = np.array([0.99, 0.9, 0.5, 0.0, 0.95])
    q_diag = np.array([1.0, 2.0, 5.0, 3.0, 0.2])
    r = 0.5
    sys = ct.ss(np.diag(a_diag), np.zeros((5, 0)), np.eye(5), np.zeros((5, 0)), 1.0)

    def scalar_posterior(a, q):
        # Scalar DARE p = a^2 p r / (p + r) + q, positive root; posterior p r / (p + r).
        b = r - a * a * r - q
        p = (-b + math.sqrt(b * b + 4 * q * r)) / 2
        return p * r / (p + r)

    unmeasured = q_diag / (1 - a_diag**2)
    reduction = unmeasured - np.array([scalar_posterior(a, q) for a, q in zip(a_diag, q_diag,
                                                                             strict=True)])
    best = tuple(sorted(np.argsort(-reduction)[:2].tolist()))
    sel = plc.select_sensors(sys, k=2, Q=np.diag(q_diag), R=r)
    assert sel.nodes == best
    want = unmeasured.sum() - reduction[list(best)].sum()
    assert sel.objective == pytest.approx(want, rel=1e-9)  # closed form vs doubling: round-off


# ---------------------------------------------------------------------- must show: 20 cases
INSTANCES = [(seed, "pinned" if seed % 3 else "clamped", 2 + seed % 4) for seed in range(20)]


def test_twenty_instances_match_brute_force_and_certificate_is_sound():
    matches = 0
    for seed, bc, k in INSTANCES:
        model, sys, q, r = line_problem(seed, bc)
        sel = plc.select_sensors(sys, k=k, Q=q, R=r, positions=model.node_positions,
                                 brute_force_limit=0, n_random=0)
        # Brute force over all C(21, k) layouts with the batched exact criterion (itself checked
        # against SciPy above, and here at the optimum).
        layouts = np.array(list(itertools.combinations(range(sys.noutputs), k)))
        crit = KalmanCriterion(np.asarray(sys.A), q / r, np.asarray(sys.C), np.eye(sys.nstates),
                               relaxation_rank=sys.nstates)
        values = crit.exact(layouts) * r
        optimum = float(values.min())
        best = tuple(layouts[int(np.argmin(values))].tolist())
        assert exact_trace(sys, q, r, best) == pytest.approx(optimum, rel=1e-6)
        assert exact_trace(sys, q, r, sel.nodes) == pytest.approx(sel.objective, rel=1e-6)
        # The certificate: the bound never exceeds the true optimum (so gap >= true gap).
        assert sel.bound <= optimum * (1 + 1e-9), (seed, sel.bound, optimum)
        true_gap = (sel.objective - optimum) / sel.objective
        assert sel.gap >= true_gap - 1e-12
        matches += sel.objective <= optimum * (1 + 1e-9)
    assert matches >= 19


# ------------------------------------------------------------------------- other criteria
@pytest.mark.parametrize("criterion", ["gramian", "min-eig", "reconstruction"])
def test_other_criteria_against_numpy_and_brute_force(criterion):
    model, sys, q, r = line_problem(7, "pinned", n_modes=3)
    k = 3
    sel = plc.select_sensors(sys, k=k, criterion=criterion, Q=q, R=r,
                             positions=model.node_positions, brute_force_limit=0, n_random=0)
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    if criterion == "reconstruction":
        cov = c @ sla.solve_discrete_lyapunov(a, q) @ c.T
        psi = np.linalg.eigh(cov)[1][:, ::-1][:, :k]

        def value(layout):
            sign, logdet = np.linalg.slogdet(psi[list(layout)].T @ psi[list(layout)])
            return logdet if sign > 0 else -np.inf
    else:
        horizon = 2 * sys.nstates
        obs = [c / np.sqrt(r)]
        for _ in range(horizon - 1):
            obs.append(obs[-1] @ a)
        rows = np.stack(obs)  # (t, m, n)

        def value(layout):
            w = np.einsum("tia,tib->ab", rows[:, list(layout)], rows[:, list(layout)])
            if criterion == "gramian":
                return np.linalg.slogdet(w)[1]
            return np.linalg.eigvalsh(w)[0]
    values = {lay: value(lay) for lay in itertools.combinations(range(sys.noutputs), k)}
    optimum = max(values.values())
    # Same quantity by two routes (relative scaling, slogdet vs eigh): agreement to round-off.
    assert sel.objective == pytest.approx(value(sel.nodes), rel=1e-7, abs=1e-7)
    assert sel.objective == pytest.approx(optimum, rel=1e-7, abs=1e-7)
    assert sel.bound >= optimum - 1e-9 * abs(optimum)


# --------------------------------------------------------------------------- constraints
def constrained_brute_force(sys, q, r, k, ok):
    crit = KalmanCriterion(np.asarray(sys.A), q / r, np.asarray(sys.C), np.eye(sys.nstates),
                           relaxation_rank=sys.nstates)
    layouts = np.array([c for c in itertools.combinations(range(sys.noutputs), k) if ok(c)])
    values = crit.exact(layouts) * r
    return float(values.min())


def test_constraints_are_honoured_exactly_and_optimum_found():
    model, sys, q, r = line_problem(11)
    x = model.node_positions
    zones = [(0.0, 0.4), (1.7, 2.0)]
    spacing = 0.5
    cost = 1.0 + (np.arange(21) % 3)
    budget = 8.0
    required = [12]
    sel = plc.select_sensors(sys, k=4, Q=q, R=r, positions=x, forbidden=zones,
                             min_spacing=spacing, required=required, cost=cost, budget=budget,
                             brute_force_limit=0, n_random=0)

    def ok(layout):
        pos = x[list(layout)]
        return (all(not (lo <= p <= hi) for p in pos for lo, hi in zones)
                and all(abs(p1 - p2) >= spacing for p1, p2 in itertools.combinations(pos, 2))
                and set(required) <= set(layout) and cost[list(layout)].sum() <= budget)

    assert ok(sel.nodes)
    optimum = constrained_brute_force(sys, q, r, 4, ok)
    assert sel.bound <= optimum * (1 + 1e-9)
    assert sel.objective == pytest.approx(optimum, rel=1e-9)


def test_per_candidate_noise_steers_away_from_noisy_sensors():
    model, sys, q, r = line_problem(5)
    base = plc.select_sensors(sys, k=3, Q=q, R=r, n_random=0)
    noisy = np.full(21, r)
    noisy[list(base.nodes)] = 1e4 * r  # the chosen ones become useless
    sel = plc.select_sensors(sys, k=3, Q=q, R=noisy, n_random=0)
    assert not set(sel.nodes) & set(base.nodes)
    assert exact_trace(sys, q, noisy, sel.nodes) == pytest.approx(sel.objective, rel=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(k=5, forbidden=[(0.0, 3.3)]), "exceeds the 2 candidates left"),
        (dict(k=5, min_spacing=1.0), "min_spacing=1.0 m leaves room for at most 4"),
        (dict(k=2, required=[0], forbidden=[(0.0, 0.1)]), "lie inside the forbidden zones"),
        (dict(k=2, required=[3, 4], min_spacing=0.5), "closer than min_spacing"),
        (dict(k=3, required=[1, 2, 3, 4]), "do not fit in k=3"),
        (dict(k=3, cost=np.ones(21), budget=2.5), "budget=2.5 is below 3"),
    ],
)
def test_infeasible_constraints_name_the_conflict(kwargs, message):
    model, sys, q, r = line_problem(0)
    with pytest.raises(SensorSelectionError, match=message):
        plc.select_sensors(sys, Q=q, R=r, positions=model.node_positions, **kwargs)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(k=0), "'k' parameter must be >= 1"),
        (dict(k=2.0), "'k' parameter must be an integer"),
        (dict(k=2, criterion="a-opt"), "'criterion' parameter must be one of"),
        (dict(k=2, min_spacing=0.3, positions=None), "pass positions="),
        (dict(k=2, R=np.ones(3)), "'R' parameter has the wrong shape"),
        (dict(k=2, solver="GUROBI"), "installed cvxpy solver"),
        (dict(k=2, Q=None), "needs the process-noise covariance Q"),
        (dict(k=2, forbidden=[(1.0,)]), "sequence of \\(start, end\\) intervals"),
        (dict(k=2, budget=3.0), "needs 'cost'"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, message):
    model, sys, q, r = line_problem(0)
    args = dict(Q=q, R=r, positions=model.node_positions) | kwargs
    with pytest.raises(InputError, match=message):
        plc.select_sensors(sys, **args)


def test_nan_in_the_model_is_rejected():
    model, sys, q, r = line_problem(0)
    a = np.array(sys.A)
    a[0, 1] = np.nan
    bad = ct.ss(a, sys.B, sys.C, sys.D, sys.dt)
    with pytest.raises(InputError, match="'sys' parameter has 1 NaN or infinite entries"):
        plc.select_sensors(bad, k=2, Q=q, R=r)
    with pytest.raises(InputError, match="'sys'"):
        plc.sensors.sensor_count_study(bad, [1, 2], Q=q, R=r)


def test_continuous_system_is_rejected():
    model = plc.LineModel(SPAN, n_elements=4)
    with pytest.raises(InputError, match="discrete-time"):
        plc.select_sensors(model.to_statespace(), k=1, Q=np.eye(1))


# ---------------------------------------------------------------------------------- solvers
@pytest.mark.parametrize("solver", ["CLARABEL", "SCS"])
def test_solvers_shipped_with_cvxpy_give_a_sound_certificate(solver):
    model, sys, q, r = line_problem(2)
    # Without brute force, so that the bound is the relaxation's (brute force would replace it).
    sel = plc.select_sensors(sys, k=3, Q=q, R=r, solver=solver, n_random=0, brute_force_limit=0)
    # The requested solver is tried first; if it fails on this machine another one (or the
    # exhaustive search) takes over: the certificate is checked either way, never assumed.
    assert sel.solver_attempts[0].startswith(solver)
    optimum = brute_force_optimum(sys, 3, "kalman", Q=q, R=r)
    check_certificate(sel, optimum)
    assert sel.objective == pytest.approx(optimum)


def test_solver_that_cannot_handle_the_cone_falls_back_to_another():
    model, sys, q, r = line_problem(2)
    # OSQP solves QPs only; the Kalman relaxation needs a semidefinite cone: the next installed
    # conic solver takes over and the attempts say so.
    sel = plc.select_sensors(sys, k=3, Q=q, R=r, solver="OSQP", n_random=0,
                             brute_force_limit=0)
    assert sel.solver_attempts[0].startswith("OSQP: failed")
    assert sel.solver != "OSQP" and sel.solver_attempts[-1].startswith(sel.solver)
    optimum = brute_force_optimum(sys, 3, "kalman", Q=q, R=r)
    check_certificate(sel, optimum)


def test_undetectable_model_is_reported():
    a = np.diag([1.0, 0.5])  # a random walk no candidate sees
    sys = ct.ss(a, np.zeros((2, 0)), np.array([[0.0, 1.0], [0.0, 2.0]]), np.zeros((2, 0)), 1.0)
    with pytest.raises(SensorSelectionError, match="cannot estimate the state"):
        plc.select_sensors(sys, k=1, Q=np.eye(2))


# ------------------------------------------------------------------------ exhaustive search
def test_exhaustive_search_certifies_the_optimum_with_zero_gap():
    sys, q = random_system(5)  # 10 candidates, k = 3: C(10, 3) = 120 layouts, brute force runs
    r = 0.1
    sel = plc.select_sensors(sys, k=3, Q=q, R=r, n_random=0)
    # Independent brute force: SciPy's DARE (through estimate/observability.py) on every layout.
    values = {lay: exact_trace(sys, q, r, lay) for lay in itertools.combinations(range(10), 3)}
    optimum = min(values.values())
    # Two Riccati solvers (batched doubling vs SciPy's QZ): round-off, 1e-8 relative.
    assert sel.objective == pytest.approx(optimum, rel=1e-8)
    assert values[sel.nodes] == pytest.approx(optimum, rel=1e-8)
    assert sel.certificate == "exhaustive" and sel.gap == 0 and sel.bound == sel.objective
    assert "proved optimal" in sel.summary()
    # Without the enumeration the same problem gets the relaxation's (looser) certificate.
    relaxed = plc.select_sensors(sys, k=3, Q=q, R=r, n_random=0, brute_force_limit=0)
    check_certificate(relaxed, optimum)
    if relaxed.certificate == "convexity":
        assert f"gap {100 * relaxed.gap:.3g} %: certified" in relaxed.summary()


# --------------------------------------------------------------------------- result object
def test_result_is_frozen_and_baselines_are_complete():
    model, sys, q, r = line_problem(4)
    sel = plc.select_sensors(sys, k=3, Q=q, R=r, positions=model.node_positions, n_random=5)
    with pytest.raises(AttributeError):
        sel.nodes = (0,)  # type: ignore[misc]
    assert not sel.weights.flags.writeable
    assert sel.weights.sum() == pytest.approx(3, abs=1e-5)  # sum z = k up to solver tolerance
    assert set(sel.baselines) == {"first-k", "evenly-spaced", "greedy", "qr-pivoting",
                                  "random-mean", "random-best", "brute-force"}
    assert sel.baselines["first-k"].nodes == (0, 1, 2)
    for name, base in sel.baselines.items():
        assert base.objective >= sel.objective * (1 - 1e-9) or name == "brute-force"
    assert sel.positions == tuple(model.node_positions[list(sel.nodes)])
    assert "within" in sel.summary()


# --------------------------------------------------------------------------- how many sensors
def test_sensor_count_study_simulation_agrees_with_riccati():
    model, sys, q, r = line_problem(9)
    study = plc.sensors.sensor_count_study(sys, [1, 2, 3], Q=q, R=r, n_steps=3000, seed=1,
                                   error_weight="outputs")
    assert np.all(np.diff(study.rms_error) < 0)
    # 3000 correlated steps of a lightly damped line: the sample RMS scatters by ~10 %.
    np.testing.assert_allclose(study.simulated_rms_error, study.rms_error, rtol=0.2)
    target = float(study.rms_error[1]) * 1.0001
    again = plc.sensors.sensor_count_study(sys, [1, 2, 3], Q=q, R=r, n_steps=10, seed=1,
                                   error_weight="outputs", target_error=target)
    assert again.smallest_k == 2


def test_sensor_count_study_survives_a_failing_doubling(monkeypatch):
    """The doubling solver goes first; if it gives up, SciPy's QZ takes over (same rule)."""
    model, sys, q, r = line_problem(9)
    reference = plc.sensors.sensor_count_study(sys, [1, 2], Q=q, R=r, n_steps=200, seed=1)
    calls = []

    def fail(a, q_, info):
        # solve_filter_dare's doubling gives up (the criterion keeps its own imported copy).
        calls.append(1)
        nan = np.full_like(info, np.nan)
        return nan, nan, np.zeros(len(info), dtype=bool)

    monkeypatch.setattr(_riccati, "steady_state_batch", fail)
    study = plc.sensors.sensor_count_study(sys, [1, 2], Q=q, R=r, n_steps=200, seed=1)
    assert calls and study.layouts == reference.layouts
    # Same seeded simulation, two Riccati solvers: only round-off differs.
    np.testing.assert_allclose(study.simulated_rms_error, reference.simulated_rms_error,
                               rtol=1e-6)


def test_simulated_rms_refuses_a_layout_that_cannot_estimate_the_state():
    from powerline_control.sensors.count import _simulated_rms

    a = np.diag([1.0, 0.5])  # a random walk that candidate 1 does not see
    with pytest.raises(SensorSelectionError, match=r"layout \[1\].*not detectable"):
        _simulated_rms(a, np.eye(2), np.eye(2), np.ones(2), np.eye(2), [1], 10,
                       np.random.default_rng(0))


# ------------------------------------------------------------ must show: the paper's 101 states
PAPER_SCENARIOS = [
    pytest.param(6.5, 0.5, id="near-mode1-x0.5"),
    pytest.param(10.0, 1.3, id="between-x1.3"),
    pytest.param(14.4, 0.5, id="near-mode2-x0.5"),
    pytest.param(20.0, 0.5, id="between-x0.5"),
    pytest.param(6.5, 1.3, id="near-mode1-x1.3", marks=pytest.mark.slow),
    pytest.param(10.0, 0.5, id="between-x0.5-10Hz", marks=pytest.mark.slow),
    pytest.param(14.4, 1.3, id="near-mode2-x1.3", marks=pytest.mark.slow),
    pytest.param(20.0, 1.3, id="between-x1.3-20Hz", marks=pytest.mark.slow),
]


@pytest.mark.parametrize(("frequency", "force_position"), PAPER_SCENARIOS)
def test_paper_101_state_case_needs_at_most_three_sensors(frequency, force_position):
    """Identified 101-state model (100 elements, 1 % noise): optimised k <= 3 beats first-13."""
    model = plc.LineModel(SPAN, n_elements=100, bc="pinned")
    force = plc.HarmonicForce(amplitude=1.0, frequency=frequency, position=force_position)
    snap = plc.simulate(model, force, duration=2.0, dt=1e-3, noise_fraction=0.01, seed=0)
    noise_var = float(np.var(snap.displacement - snap.true_displacement))
    dmd = plc.fit_dmd(snap.displacement, dt=snap.dt, alpha=0.1, delays=1)
    sys, q = dmd.to_statespace(), dmd.residual_covariance
    paper = exact_trace(sys, q, noise_var, range(13))  # SciPy DARE, independent of sensors.py
    for k in (1, 2, 3):
        sel = plc.select_sensors(sys, k=k, Q=q, R=noise_var, n_random=0, brute_force_limit=0)
        if sel.objective <= paper:
            break
    assert sel.objective <= paper, (k, sel.objective, paper)
    assert exact_trace(sys, q, noise_var, sel.nodes) == pytest.approx(sel.objective, rel=1e-6)


@pytest.mark.parametrize("criterion", ["kalman", "gramian", "min-eig"])
def test_cut_relaxation_still_bounds_the_optimum(criterion):
    """relaxation_rank below the state size: the cvxpy problem is cut, the bound must hold.

    Whatever the installed solvers do on this machine (a fresh machine once saw CLARABEL
    fail here), the result must carry a valid certificate, checked against brute force."""
    model, sys, q, r = line_problem(13, "clamped", n_modes=3)  # 6 states, cut to 3
    sel = plc.select_sensors(sys, k=3, criterion=criterion, Q=q, R=r, relaxation_rank=3,
                             n_random=0, brute_force_limit=0)
    optimum = brute_force_optimum(sys, 3, criterion, Q=q, R=r)  # every layout, exact criterion
    check_certificate(sel, optimum)


def _failing_solve(self, *args, **kwargs):
    raise cp.error.SolverError(f"forced failure of {kwargs.get('solver')}")


@pytest.mark.parametrize("criterion", ["kalman", "gramian", "min-eig", "reconstruction"])
def test_every_solver_failing_falls_back_to_the_exhaustive_proof(monkeypatch, criterion):
    """No conic solver works: C(21, 3) = 1330 layouts is small, so the exhaustive search
    proves the optimum even with brute_force_limit=0; never an error suggesting a solver."""
    model, sys, q, r = line_problem(21, n_modes=3)
    optimum = brute_force_optimum(sys, 3, criterion, Q=q, R=r)  # before the solvers break
    monkeypatch.setattr(cp.Problem, "solve", _failing_solve)
    sel = plc.select_sensors(sys, k=3, criterion=criterion, Q=q, R=r, n_random=0,
                             brute_force_limit=0)
    assert sel.certificate == "exhaustive" and sel.solver == "none"
    assert all("failed" in attempt for attempt in sel.solver_attempts)
    assert len(sel.solver_attempts) >= 2  # the requested solver and at least one other
    check_certificate(sel, optimum)


def test_every_solver_failing_on_a_large_problem_still_bounds_it(monkeypatch):
    """C(21, 5) = 20349 layouts over a limit of 1000: no enumeration; the Kalman bound then
    comes from Frank-Wolfe on the relaxation in numpy (no solver needed), checked against the
    brute-force optimum; the layout from greedy + swaps."""
    model, sys, q, r = line_problem(22, n_modes=3)
    optimum = brute_force_optimum(sys, 5, "kalman", Q=q, R=r)
    monkeypatch.setattr(cp.Problem, "solve", _failing_solve)
    sel = plc.select_sensors(sys, k=5, Q=q, R=r, n_random=0, brute_force_limit=1000)
    assert sel.certificate in ("convexity", "none: heuristic") and sel.solver == "none"
    assert np.isnan(sel.relaxation_value)
    check_certificate(sel, optimum)
    assert "not certified" in sel.summary() or "certified" in sel.summary()


def check_certificate(sel, optimum: float) -> None:
    """Any certificate is acceptable; each is checked for what it claims."""
    assert sel.certificate in ("exhaustive", "convexity", "solver", "none: heuristic")
    # The layout can never beat the optimum (round-off of two Riccati / eigen routes: 1e-9).
    if sel.sense == "minimize":
        assert sel.objective >= optimum * (1 - 1e-9)
        assert sel.bound <= optimum * (1 + 1e-9) + 1e-300
        want_gap = (sel.objective - sel.bound) / sel.objective if sel.objective > 0 else 0.0
    else:
        assert sel.objective <= optimum + 1e-9 * abs(optimum)
        assert sel.bound >= optimum - 1e-9 * abs(optimum)
        want_gap = None
    assert 0.0 <= sel.gap <= 1.0
    if sel.certificate == "exhaustive":
        assert sel.objective == pytest.approx(optimum, rel=1e-9, abs=1e-12)
        assert sel.bound == sel.objective and sel.gap == 0.0
    elif sel.certificate == "none: heuristic":
        assert sel.gap == 1.0
    elif want_gap is not None:
        assert sel.gap == pytest.approx(max(want_gap, 0.0), rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("criterion", ["reconstruction", "gramian"])
def test_scs_handles_the_log_det_relaxations(criterion):
    model, sys, q, r = line_problem(3, n_modes=3)
    sel = plc.select_sensors(sys, k=3, criterion=criterion, Q=q, R=r, solver="SCS", n_random=0,
                             brute_force_limit=0)
    optimum = brute_force_optimum(sys, 3, criterion, Q=q, R=r)
    assert sel.solver_attempts[0].startswith("SCS")
    check_certificate(sel, optimum)


@pytest.mark.parametrize("seed", range(6))
def test_random_constraints_feasible_iff_brute_force_finds_a_layout(seed):
    """Seeded zones / spacing / required: an error exactly when no layout exists, else the
    constrained optimum (brute force over every layout)."""
    rng = np.random.default_rng(100 + seed)
    model, sys, q, r = line_problem(seed, n_modes=3)
    x = model.node_positions
    start = rng.uniform(0, 3.0, size=2)
    zones = [(float(s0), float(s0 + rng.uniform(0.1, 0.8))) for s0 in start]
    spacing = float(rng.uniform(0.2, 1.2))
    k = int(rng.integers(2, 5))
    required = [int(rng.integers(0, 21))] if seed % 2 else []

    def ok(layout):
        pos = x[list(layout)]
        return (all(not (lo <= p <= hi) for p in pos for lo, hi in zones)
                and all(abs(a - b) >= spacing for a, b in itertools.combinations(pos, 2))
                and set(required) <= set(layout))

    exists = any(ok(c) for c in itertools.combinations(range(21), k))
    if not exists:
        with pytest.raises(SensorSelectionError):
            plc.select_sensors(sys, k=k, Q=q, R=r, positions=x, forbidden=zones,
                               min_spacing=spacing, required=required)
        return
    sel = plc.select_sensors(sys, k=k, Q=q, R=r, positions=x, forbidden=zones,
                             min_spacing=spacing, required=required, brute_force_limit=0,
                             n_random=0)
    assert ok(sel.nodes)
    optimum = constrained_brute_force(sys, q, r, k, ok)
    assert sel.bound <= optimum * (1 + 1e-9)
    assert sel.objective == pytest.approx(optimum, rel=1e-9)


# ------------------------------------------------------------------------- bad input, one table
def _problem():
    model, sys, q, r = line_problem(0, n_modes=2)
    return sys, q, r, model.node_positions


def _select(**kwargs):
    sys, q, r, x = _problem()
    args = dict(k=2, Q=q, R=r, n_random=0) | kwargs
    return plc.select_sensors(sys, **args)


_I, _S = InputError, SensorSelectionError
BAD_INPUT = [
    ("R=0", lambda: _select(R=0.0), _I, "'R'"),
    ("R nan", lambda: _select(R=float("nan")), _I, "'R'"),
    ("R str", lambda: _select(R="1e-6"), _I, "'R'"),
    ("R vector zero", lambda: _select(R=np.r_[0.0, np.ones(20)]), _I, "'R'"),
    ("R vector negative", lambda: _select(R=-np.ones(21)), _I, "'R'"),
    ("R matrix shape", lambda: _select(R=np.eye(20)), _I, "'R'"),
    ("R matrix indefinite", lambda: _select(R=-np.eye(21)), _I, "'R'"),
    ("R matrix singular", lambda: _select(R=np.ones((21, 21))), _I, "'R'"),
    ("R correlated for gramian", lambda: _select(
        criterion="gramian", R=np.eye(21) + 0.1 * np.ones((21, 21))), _I, "'R'"),
    ("Q shape", lambda: _select(Q=np.eye(3)), _I, "'Q'"),
    ("Q nan", lambda: _select(Q=np.full((4, 4), np.nan)), _I, "'Q'"),
    ("Q indefinite", lambda: _select(Q=-np.eye(4)), _I, "'Q'"),
    ("k > candidates", lambda: _select(k=22), _I, "'k'"),
    ("k bool", lambda: _select(k=True), _I, "'k'"),
    ("sys NaN", lambda: plc.select_sensors(
        ct.ss(np.diag([np.nan, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0), 1,
        Q=np.eye(2)), _I, "'sys'"),
    ("sys continuous", lambda: plc.select_sensors(
        ct.ss(-np.eye(2), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0))), 1, Q=np.eye(2)), _I,
     "'sys'"),
    ("sys not a system", lambda: plc.select_sensors(np.eye(2), 1, Q=np.eye(2)), _I, "'sys'"),
    ("required missing sensor", lambda: _select(required=[21]), _I, "'required'"),
    ("required float", lambda: _select(required=[1.0]), _I, "'required'"),
    ("positions shape", lambda: _select(positions=np.ones(5)), _I, "'positions'"),
    ("positions nan", lambda: _select(positions=np.full(21, np.nan)), _I, "'positions'"),
    ("min_spacing nan", lambda: _select(min_spacing=float("nan")), _I, "'min_spacing'"),
    ("forbidden reversed", lambda: _select(forbidden=[(2.0, 1.0)],
                                           positions=np.linspace(0, 3.66, 21)), _I,
     "'forbidden'"),
    ("cost shape", lambda: _select(cost=np.ones(3), budget=1.0), _I, "'cost'"),
    ("budget<0", lambda: _select(cost=np.ones(21), budget=-1.0), _I, "'budget'"),
    # A negative cost makes the budget meaningless; budgets are checked before use.
    ("cost negative", lambda: _select(cost=np.r_[-1.0, np.ones(20)], budget=3.0), _I, "'cost'"),
    ("budget inf", lambda: _select(cost=np.ones(21), budget=float("inf")), _I, "'budget'"),
    ("n_random over the memory budget", lambda: _select(n_random=10**15), _I, "'n_random'"),
    ("R far below Q for the Riccati", lambda: _select(R=1e-300), _I, "'R'"),
    ("error_weight None, gramian", lambda: _select(criterion="gramian", error_weight=None), _I,
     "'error_weight'"),
    ("error_weight number", lambda: _select(error_weight=1.0), _I, "'error_weight'"),
    ("count study n_steps over the work budget", lambda: plc.sensors.sensor_count_study(
        _problem()[0], [1], Q=_problem()[1], n_steps=10**15), _I, "'n_steps'"),
    ("horizon 0", lambda: _select(horizon=0), _I, "'horizon'"),
    ("horizon float", lambda: _select(horizon=10.0), _I, "'horizon'"),
    ("horizon 1e18 unstable overflows", lambda: plc.select_sensors(
        ct.ss(np.diag([1.1, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0), 1,
        "gramian", horizon=10**18), _I, "'horizon'"),
    ("horizon work over budget", lambda: plc.select_sensors(
        ct.ss(0.5 * np.eye(120), np.zeros((120, 0)), np.ones((3000, 120)) / 120,
              np.zeros((3000, 0)), 1.0), 1, "min-eig", horizon=10**9), _I, "'horizon'"),
    ("relaxation_rank 0", lambda: _select(relaxation_rank=0), _I, "'relaxation_rank'"),
    ("n_random<0", lambda: _select(n_random=-1), _I, "'n_random'"),
    ("brute_force_limit<0", lambda: _select(brute_force_limit=-1), _I, "'brute_force_limit'"),
    ("solver not a string", lambda: _select(solver=3), _I, "'solver'"),
    ("seed negative", lambda: _select(seed=-4), _I, "'seed'"),
    ("error_weight shape", lambda: _select(error_weight=np.ones((2, 3))), _I,
     "'error_weight'"),
    ("error_weight choice", lambda: _select(error_weight="nodes"), _I, "'error_weight'"),
    ("basis rows", lambda: _select(criterion="reconstruction", basis=np.ones((3, 2))), _I,
     "'basis'"),
    ("count study empty", lambda: plc.sensors.sensor_count_study(_problem()[0], [],
                                                                 Q=_problem()[1]),
     _I, "'k_values'"),
    ("count study int", lambda: plc.sensors.sensor_count_study(_problem()[0], 3, Q=_problem()[1]),
     _I, "'k_values'"),
    ("count study str", lambda: plc.sensors.sensor_count_study(_problem()[0], "12",
                                                               Q=_problem()[1]),
     _I, "'k_values'"),
    ("count study float", lambda: plc.sensors.sensor_count_study(_problem()[0], [1.5],
                                                         Q=_problem()[1]), _I, "'k_values'"),
    ("count study descending", lambda: plc.sensors.sensor_count_study(
        _problem()[0], [2, 1], Q=_problem()[1]), _I, "'k_values'"),
    ("count study n_steps", lambda: plc.sensors.sensor_count_study(
        _problem()[0], [1], Q=_problem()[1], n_steps=0), _I, "'n_steps'"),
    ("count study R", lambda: plc.sensors.sensor_count_study(
        _problem()[0], [1], Q=_problem()[1], R=-1.0), _I, "'R'"),
    ("count study target", lambda: plc.sensors.sensor_count_study(
        _problem()[0], [1], Q=_problem()[1], target_error=float("nan")), _I, "'target_error'"),
]


def test_a_budget_above_every_candidates_total_is_capped_not_sent_to_the_solver():
    # Old code: budget=1e300 reached Clarabel as a bound and ended in a Rust panic. Above the
    # total cost of all 21 candidates a budget constrains nothing: capped at that total.
    cost = 1.0 + (np.arange(21) % 3)
    huge = _select(cost=cost, budget=1e300)
    total = _select(cost=cost, budget=float(cost.sum()))
    assert huge.nodes == total.nodes
    assert huge.objective == pytest.approx(total.objective, rel=1e-9)


@pytest.mark.parametrize(("name", "call", "error", "parameter"), BAD_INPUT,
                         ids=[row[0] for row in BAD_INPUT])
def test_bad_input_table(name, call, error, parameter):
    with pytest.raises(Exception) as info:
        call()
    assert type(info.value) is error, (name, type(info.value), info.value)
    assert parameter in str(info.value), (name, str(info.value))


def test_correlated_noise_exhaustive_equals_brute_force_and_relaxation_bounds_it():
    """A full R (correlated neighbours): the exact criterion is each layout's own DARE with
    R_SS, checked on every layout with SciPy (through steady_state_covariance)."""
    sys, q = random_system(31, n=4, m=7)
    rng = np.random.default_rng(32)
    l = rng.normal(size=(7, 7))
    r = 0.1 * (l @ l.T / 7 + 0.3 * np.eye(7))
    values = {lay: exact_trace(sys, q, r, lay) for lay in itertools.combinations(range(7), 2)}
    optimum = min(values.values())
    sel = plc.select_sensors(sys, k=2, Q=q, R=r, n_random=0)
    check_certificate(sel, optimum)
    assert sel.certificate == "exhaustive" and values[sel.nodes] == pytest.approx(optimum,
                                                                                  rel=1e-8)
    relaxed = plc.select_sensors(sys, k=2, Q=q, R=r, n_random=0, brute_force_limit=0)
    check_certificate(relaxed, optimum)


def test_a_huge_horizon_costs_its_logarithm_not_its_length():
    """horizon=10**8 used to loop 1e8 times: the Gramians now double (log2 1e8 = 27 steps) and
    on a stable model equal the infinite-horizon ones (SciPy's Lyapunov solver as the truth)."""
    sys, q, r, x = _problem()
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    sel = plc.select_sensors(sys, 2, "min-eig", Q=q, R=r, horizon=10**8, n_random=0)
    cs = c[list(sel.nodes)] / np.sqrt(r)
    lyap = sla.solve_discrete_lyapunov(a.T, cs.T @ cs)
    # The finite sum to 1e8 steps of a damped model equals the Lyapunov solution to round-off.
    assert sel.objective == pytest.approx(np.linalg.eigvalsh(lyap)[0], rel=1e-6)


def test_the_fresh_machine_failure_falls_back_to_the_next_solver(monkeypatch):
    """A solver failure, reproduced: CLARABEL raises on the cut 'kalman' relaxation. The next
    installed solver takes over; the certificate is checked against brute force."""
    model, sys, q, r = line_problem(13, "clamped", n_modes=3)
    optimum = brute_force_optimum(sys, 3, "kalman", Q=q, R=r)
    original = cp.Problem.solve

    def clarabel_fails(self, *args, **kwargs):
        if kwargs.get("solver") == "CLARABEL":
            raise cp.error.SolverError("Solver 'CLARABEL' failed. Try another solver.")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(cp.Problem, "solve", clarabel_fails)
    sel = plc.select_sensors(sys, k=3, Q=q, R=r, relaxation_rank=3, n_random=0,
                             brute_force_limit=0)
    assert sel.solver_attempts[0].startswith("CLARABEL: failed") and sel.solver != "CLARABEL"
    check_certificate(sel, optimum)


# ------------------------------------------------------- log det: pruned searches, block sums
def _gramians_by_direct_sum(sys, r, horizon):
    """``sum_t (A^T)^t c_i c_i^T A^t / r`` for every candidate, one step at a time (the
    definition, independent of the library's block and doubling routes)."""
    a, c = np.asarray(sys.A), np.asarray(sys.C) / np.sqrt(r)
    mats, rows = np.zeros((c.shape[0], a.shape[0], a.shape[0])), c.copy()
    for _ in range(horizon):
        mats += np.einsum("ia,ib->iab", rows, rows)
        rows = rows @ a
    return mats


@pytest.mark.parametrize("seed", range(3))
def test_log_det_swap_bounds_hold_and_prune_to_the_same_move(seed):
    """Every lower bound of a swap's cost is below its exact cost (slogdet of the swapped sum,
    computed here), and the pruned choice is the argmin over every move while judging fewer:
    on these well-conditioned 6-state models about three quarters of the moves are skipped."""
    from powerline_control.sensors.criteria import LogDetCriterion
    from powerline_control.sensors.search import _pruned_argmin

    model, sys, q, r = line_problem(seed, n_modes=3)
    horizon = 2 * sys.nstates
    mats = _gramians_by_direct_sum(sys, r, horizon)
    crit = LogDetCriterion(mats, term_rank=min(sys.nstates, horizon))
    layout = np.random.default_rng(seed).choice(sys.noutputs, 4, replace=False)
    moves = np.array([(p, j) for p in range(4) for j in range(sys.noutputs) if j not in layout])
    swapped = np.tile(layout, (len(moves), 1))
    swapped[np.arange(len(moves)), moves[:, 0]] = moves[:, 1]
    exact = np.array([-np.linalg.slogdet(mats[s].sum(axis=0))[1] for s in swapped])
    bounds = crit.bound_swaps(layout)[moves[:, 0], moves[:, 1]]
    assert np.all(np.isfinite(bounds)) and np.all(bounds <= exact)

    def build(part):
        return swapped[[int(np.flatnonzero((moves == move).all(axis=1))[0]) for move in part]]

    best, value = _pruned_argmin(crit, moves, bounds, build, np.inf)
    assert best == int(np.argmin(exact)) and value == pytest.approx(exact.min(), rel=1e-12)
    assert crit.n_exact <= 0.5 * len(moves)


def test_rank_one_addition_bound_is_the_determinant_lemma():
    """Basis rows (reconstruction): each W_j = psi_j psi_j^T has rank 1, and the bound
    log det W + log(1 + psi_j^T W^-1 psi_j) is the exact log det (matrix determinant lemma),
    up to its round-off margin."""
    from powerline_control.sensors.criteria import LogDetCriterion

    psi = np.random.default_rng(4).standard_normal((12, 3))
    crit = LogDetCriterion(np.einsum("ia,ib->iab", psi, psi), term_rank=1)
    layout = np.array([0, 5, 9])
    bounds = crit.bound_additions(layout)
    for j in range(12):
        exact = -np.linalg.slogdet(psi[[*layout, j]].T @ psi[[*layout, j]])[1]
        assert bounds[j] <= exact and bounds[j] == pytest.approx(exact, abs=1e-9)


def test_gramian_criterion_over_several_blocks_of_steps():
    """20 states over horizon=200: the plain sum (cheaper than doubling there) adds the
    per-candidate Gramians in blocks of 128 and 72 steps; the objective equals log det of the
    direct sum (same quantity, two summation orders)."""
    from powerline_control.sensors import select

    model, sys, q, r = line_problem(5, n_modes=10)
    assert not select._gramian_work(sys.noutputs, sys.nstates, 200)[1]   # the plain route
    sel = plc.select_sensors(sys, k=3, criterion="gramian", R=r, horizon=200, n_random=0)
    mats = _gramians_by_direct_sum(sys, r, 200)
    assert sel.objective == pytest.approx(
        np.linalg.slogdet(mats[list(sel.nodes)].sum(axis=0))[1], rel=1e-9)
    # The relaxation is whitened for the solver and shifted back: its value is log det of the
    # weighted direct sum at the solver's weights (d = 20 = relaxation_rank: nothing is cut;
    # 1e-6: the conic solver's tolerance). Unwhitened, CLARABEL failed here and SCS ran 63 s
    # to an inaccurate status.
    assert sel.solver_status == "optimal"
    assert sel.relaxation_value == pytest.approx(
        np.linalg.slogdet(np.einsum("i,iab->ab", sel.weights, mats))[1], rel=1e-6)
