"""Size limits: every public entry given a huge size parameter refuses before it allocates.

No public call given the size parameters above allocates more than its budget before
refusing. Each row calls one public entry with an element count, duration, time step,
bandwidth, delay count, horizon, rank, TOML value or array length that would need gigabytes to
terabytes (or hours), and checks, with ``tracemalloc`` (numpy reports its buffers to it):

* the documented error (``InputError``) is raised,
* the peak traced allocation during the call stays under 200 MB, far below both the would-be
  size and ``_validation.MEMORY_BUDGET_BYTES`` (4 GiB): the refusal comes from an estimate, not
  from a failed allocation,
* the message names the parameter, gives its value and says how to reduce it.

A few entries have a fast path instead of a limit (the doubling Gramian over ``10**8`` steps):
for those the call must succeed within the same memory. No wall-clock assertions (results never
depend on machine load); the peaks are printed with ``-s``.
"""

from __future__ import annotations

import tracemalloc
import warnings

import control as ct
import numpy as np
import pytest

import powerline_control as plc
from powerline_control import _validation
from powerline_control import scenario as config  # the schema, its sections and files
from powerline_control.errors import InputError

LAB = plc.Span.paper_lab()
DRAKE = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
I = InputError

# 64 MB: the largest legitimate working set of these refusals is measured at 33 MB. The 100 MB
# boolean mask a finiteness check of 1e8 entries once built is gone (reductions, no
# mask), so a row that brings it back fails; a call that started to allocate its would-be size
# (>= 4 GiB) is 60x over.
PEAK_LIMIT = 64 * 2**20


@pytest.fixture(scope="module")
def small():
    """Small valid objects (built outside the traced window)."""
    rng = np.random.default_rng(12)
    X = rng.standard_normal((4, 80))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dmd = plc.fit_dmd(X, dt=1e-3, alpha=1e-3)
    return dict(model=plc.LineModel(LAB, n_elements=10), X=X, dmd=dmd,
                sys=dmd.to_statespace(), big=np.zeros((2000, 3000)),
                snapshots=rng.standard_normal((11, 400)), limits=plc.RobotLimits(0.5, 1.0),
                robot=plc.MDR(1.2, 0.02), force=plc.HarmonicForce(1.0, 9.0, 1.1),
                speeds_1e8=np.broadcast_to(3.0, (10**8,)),  # a 0-byte view of 1e8 speeds
                # 2000 states (32 MB, built here): its Gramian over 1e8 samples is 27 doubling
                # steps of six 2000^3 products, measured 0.66 s each: ~107 s on this machine.
                sys_2000=ct.ss(0.999 * np.eye(2000), np.ones((2000, 1)), np.ones((2, 2000)), 0,
                               dt=1e-3),
                # 20000 elements of Drake carrying the robot (sparse: built in ~0.5 s).
                drake_20000=plc.LineModel(DRAKE, n_elements=20000, mdr=plc.MDR(100.0, 0.02)))


def traced(call, small):
    """Run ``call(small)``; return (exception or result, peak traced bytes)."""
    tracemalloc.start()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outcome = call(small)
    except Exception as exc:  # noqa: BLE001 (the row decides what was expected)
        outcome = exc
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return outcome, peak


# (id, call, parameter named in the message, value the message must quote)
REFUSALS = [
    ("LineModel n_elements=1e7", lambda s: plc.LineModel(LAB, n_elements=10**7), "n_elements",
     "10000000"),
    ("LineModel n_elements=1e7 with mdr",
     lambda s: plc.LineModel(LAB, n_elements=10**7, mdr=s["robot"]), "n_elements", "10000000"),
    ("LineModel modes(1e7)", lambda s: s["model"].modes(10**7), "n_modes", "10000000"),
    ("simulate duration=1e6", lambda s: plc.simulate(s["model"], duration=1e6), "duration",
     "1e+06"),
    ("simulate dt=1e-9", lambda s: plc.simulate(s["model"], duration=1.0, dt=1e-9), "dt",
     "1e-09"),
    ("simulate RandomForce bandwidth=1e12",
     lambda s: plc.simulate(s["model"], plc.RandomForce(1.0, 1.1, bandwidth=1e12, seed=1),
                            duration=1.0), "bandwidth", "1000000000000"),
    ("fit_dmd delays=1e6", lambda s: plc.fit_dmd(s["X"], 1e-3, delays=10**6), "delays",
     "1000000"),
    ("fit_dmd 2000 nodes x 500 delays", lambda s: plc.fit_dmd(s["big"], 1e-3, delays=500),
     "delays", "500"),
    ("select_alpha horizon=1e9", lambda s: plc.select_alpha(s["snapshots"], 1e-3,
                                                            horizon=10**9), "horizon",
     "1000000001"),
    ("design_estimator rank=1e6",
     lambda s: plc.design_estimator(s["snapshots"], 2, dt=1e-3, rank=10**6), "rank", "1000000"),
    ("design_estimator delays=1e6",
     lambda s: plc.design_estimator(s["snapshots"], 2, dt=1e-3, delays=10**6), "delays",
     "1000000"),
    ("MotionPlanner horizon=1e7",
     lambda s: plc.MotionPlanner(s["limits"], horizon=10**7, span_length=3.66), "horizon",
     "10000000"),
    ("run_closed_loop duration=1e7",
     lambda s: plc.run_closed_loop(LAB, s["force"], s["robot"], s["limits"], sensors=[3, 7],
                                   n_elements=10, duration=1e7), "duration", "1e+07"),
    ("run_closed_loop dt=1e-9",
     lambda s: plc.run_closed_loop(LAB, s["force"], s["robot"], s["limits"], sensors=[3, 7],
                                   n_elements=10, duration=10.0, dt=1e-9), "dt", "1e-09"),
    # A Drake span of 20000 elements with the robot: the calibration record (20001 nodes x
    # 2001 samples) was simulated (9 s) before design_estimator refused it, naming a
    # 'snapshots' the caller never passed; now refused before anything is built or simulated.
    ("run_closed_loop 20000 elements with the robot",
     lambda s: plc.run_closed_loop(DRAKE, plc.HarmonicForce(1.0, 10.0, 50.0),
                                   plc.MDR(100.0, 0.02), s["limits"], sensors=[2000, 5000],
                                   n_elements=20000, duration=5.0), "n_elements", "20000"),
    ("run_closed_loop a 20000-element LineModel with the robot",
     lambda s: plc.run_closed_loop(s["drake_20000"], plc.HarmonicForce(1.0, 10.0, 50.0), None,
                                   s["limits"], sensors=[2000, 5000], duration=5.0),
     "model", "20001 nodes"),
    ("estimate.observability_gramian 2000 states horizon=1e8",
     lambda s: plc.estimate.observability_gramian(s["sys_2000"], 10**8), "horizon",
     "100000000"),
    ("run_closed_loop n_elements=1e7",
     lambda s: plc.run_closed_loop(LAB, s["force"], s["robot"], s["limits"], sensors=[3, 7],
                                   n_elements=10**7), "n_elements", "10000000"),
    ("severity.time_domain_check n_elements=1e7",
     lambda s: plc.severity.time_domain_check(DRAKE, 3.0,
                                              n_elements=10**7), "n_elements", "10000000"),
    ("load_scenario n_elements=1e9",
     lambda s: config.load_scenario(text="[model]\nn_elements = 1000000000"), "n_elements",
     "1000000000"),
    ("load_scenario duration=1e9",
     lambda s: config.load_scenario(text="[simulation]\nduration = 1e9"), "duration",
     "1000000000"),
    ("aeolian_severity 1e8 wind speeds",
     lambda s: plc.aeolian_severity(DRAKE, s["speeds_1e8"]), "wind_speeds", "100000000"),
    ("aeolian_severity 2e5 wind speeds (work)",
     lambda s: plc.aeolian_severity(DRAKE, [3.0] * 200_000), "wind_speeds", "200000"),
    ("severity.robot_value 1e8 wind speeds",
     lambda s: plc.severity.robot_value(DRAKE, s["robot"], s["limits"],
                                        wind_speeds=s["speeds_1e8"]),
     "wind_speeds", "100000000"),
    # 8 bytes x 1e10 steps x (4 states + 4 nodes) = 596 GiB (MemoryError before the budget).
    ("DMDModel.predict n_steps=1e10",
     lambda s: s["dmd"].predict(s["dmd"].initial_state, 10**10), "n_steps", "10000000000"),
    # 1e14 points x ~250 bytes per dict: 2.3e4 TiB; the axes themselves are 2.1e5 ints (~8 MB).
    ("parameter_grid 1e14 points",
     lambda s: plc.parameter_grid(a=range(10**5), b=range(10**5), c=range(10**4)), "axes",
     "a: 100000 x b: 100000 x c: 10000"),
]


def _refusal_params():
    for row in REFUSALS:
        yield pytest.param(*row[1:], id=row[0])


@pytest.mark.parametrize(("call", "parameter", "value"), list(_refusal_params()))
def test_huge_size_is_refused_before_allocating(small, call, parameter, value):
    outcome, peak = traced(call, small)
    print(f"peak {peak / 2**20:.1f} MB: {type(outcome).__name__}")
    assert isinstance(outcome, InputError), repr(outcome)
    assert peak < PEAK_LIMIT, f"{peak / 2**20:.0f} MB traced before refusing"
    message = str(outcome)
    assert parameter in message and value in message, message
    # How to reduce it: a budget refusal says "To fix", a range refusal gives the allowed bound.
    assert any(hint in message for hint in ("To fix", "<=", "Allowed", "fewer", "shorter")), \
        message


def test_budget_refusal_states_the_estimate_and_the_budget(small):
    """The budget numbers in the message are the documented defaults (4 GiB, 1e12 flops)."""
    assert _validation.MEMORY_BUDGET_BYTES == 4 * 2**30
    assert _validation.WORK_BUDGET == 10**12
    with pytest.raises(InputError) as info:
        plc.MotionPlanner(small["limits"], horizon=10**7, span_length=3.66)
    message = str(info.value)
    # 16 kB per horizon step (the planner's measured cost) x 1e7 steps = 1.6e11 B = 149 GiB.
    assert "149 GiB" in message and "budget of 4 GiB" in message, message
    with pytest.raises(InputError) as info:
        plc.aeolian_severity(DRAKE, [3.0] * 200_000)
    # 1e7 flops per energy balance x 2e5 speeds = 2e12 > 1e12.
    assert "2e+12" in str(info.value) and "1e+12" in str(info.value), str(info.value)


def test_a_refused_gramian_says_which_horizon_fits(small):
    # 12 n^3 flops per doubling step, n = 2000: 9.6e10; 1e12 affords 10 steps, N <= 2^10 - 1.
    with pytest.raises(InputError, match="horizons up to 1023 fit") as info:
        plc.estimate.observability_gramian(small["sys_2000"], 10**8)
    assert "2.6e+12" in str(info.value), str(info.value)
    # The boundary: 1024 samples need an 11th step (refused); 1023 would run (~40 s: not here).
    with pytest.raises(InputError, match="'horizon' parameter is 1024"):
        plc.estimate.observability_gramian(small["sys_2000"], 1024)
    # The fast path is unchanged where the model is small (test_huge_size_on_a_fast_path...).
    assert np.isfinite(plc.estimate.observability_gramian(small["sys"], 10**8)).all()


def test_a_raised_budget_lets_the_same_call_through(small):
    """The limit is a budget, not a wall: the documented per-call override is honoured."""
    # 2000 elements with a robot: refused under a 1 MB budget, built under the default one.
    with pytest.raises(InputError, match="n_elements"):
        plc.LineModel(LAB, n_elements=2000, mdr=small["robot"], memory_budget=2**20)
    model = plc.LineModel(LAB, n_elements=2000, mdr=small["robot"])
    assert model.n_nodes == 2001


def _entry_point(row_id: str):
    """The public callable a REFUSALS row is named after ('LineModel', 'DMDModel.predict', ...)."""
    target: object = plc if hasattr(plc, row_id.split()[0].split(".")[0]) else config
    for part in row_id.split()[0].split("."):
        target = getattr(target, part)
    return target


@pytest.mark.parametrize("row", REFUSALS, ids=lambda r: r[0])
def test_a_refusal_suggests_only_budget_arguments_the_call_has(small, row):
    """"raise the budget (memory_budget=...)" only where the signature takes memory_budget."""
    import inspect

    outcome, _ = traced(row[1], small)
    message = str(outcome)
    parameters = inspect.signature(_entry_point(row[0])).parameters
    for argument in ("memory_budget", "work_budget"):
        if f"{argument}=" in message:
            assert argument in parameters, (row[0], message)
    # Every budget refusal still says how to raise the budget: the environment variable.
    if "over the budget" in message:
        assert "POWERLINE_CONTROL_" in message, message


def test_motion_planner_takes_the_memory_budget_its_refusal_suggests(small):
    # 16 kB per step (the planner's own estimate) x 100 steps = 1.6 MB > a 1 MB budget.
    with pytest.raises(InputError, match=r"memory_budget=\.\.\.") as info:
        plc.MotionPlanner(small["limits"], horizon=100, span_length=3.66, memory_budget=2**20)
    assert "'horizon'" in str(info.value)
    planner = plc.MotionPlanner(small["limits"], horizon=100, span_length=3.66,
                                memory_budget=2**22)  # 4 MB: the same call goes through
    assert planner.horizon == 100
    with pytest.raises(InputError, match="'memory_budget'"):
        plc.MotionPlanner(small["limits"], memory_budget="big")


# Entries with a fast path: the huge size parameter is legitimate and must stay cheap.
FAST_PATHS = [
    # 20000 elements with a robot once assembled a dense 12 GiB matrix; sparse now (measured
    # peak ~100 MB: the sparse matrices and their factorisation-free assembly).
    ("LineModel 20000 elements with mdr",
     lambda s: plc.LineModel(LAB, n_elements=20000, mdr=s["robot"]).n_nodes == 20001),
    # Binary doubling of the Gramian: O(n^3 log N), a few matrices of n = 4.
    ("select_sensors gramian horizon=1e8",
     lambda s: len(plc.select_sensors(s["sys"], 2, "gramian", Q=s["dmd"].residual_covariance,
                                      horizon=10**8, n_random=0).nodes) == 2),
    ("observability_gramian horizon=1e9",
     lambda s: bool(np.all(np.isfinite(plc.estimate.observability_gramian(s["sys"], 10**9))))),
    # Closed form: a 1e9 m move is three phases, not a sampled program.
    ("plan_motion over 1e9 m",
     lambda s: plc.plan_motion(0.0, 1e9, s["limits"]).duration > 1e9 / 0.5),
]


@pytest.mark.parametrize("call", [row[1] for row in FAST_PATHS], ids=[row[0] for row in FAST_PATHS])
def test_huge_size_on_a_fast_path_stays_within_memory(small, call):
    outcome, peak = traced(call, small)
    print(f"peak {peak / 2**20:.1f} MB")
    assert outcome is True, repr(outcome)
    assert peak < PEAK_LIMIT, f"{peak / 2**20:.0f} MB traced"


# ============================================================ budgets validated first
# Each snippet prints the refusal; run in a subprocess under a 2 GiB address-space limit, where
# the old code (nan makes "estimate > budget" false, so the guard is off) died of a MemoryError
# or an allocation of the would-be size.
_REFUSE = """
import math, powerline_control as plc
try:
    {call}
except plc.InputError as error:
    print(type(error).__name__, error)
else:
    print("ANSWERED")
"""


@pytest.mark.parametrize(("call", "name"), [
    ("plc.LineModel(plc.Span.paper_lab(), n_elements=10**8, memory_budget=math.nan)",
     "'memory_budget'"),
    ("plc.LineModel(plc.Span.paper_lab(), n_elements=10**8, memory_budget='1e12')",
     "'memory_budget'"),
    ("plc.LineModel(plc.Span.paper_lab(), n_elements=10**8, memory_budget=True)",
     "'memory_budget'"),
    ("plc.LineModel(plc.Span.paper_lab(), n_elements=10**8, memory_budget=-1.0)",
     "'memory_budget'"),
    ("plc.simulate(plc.LineModel(plc.Span.paper_lab(), n_elements=10), duration=1e7, "
     "memory_budget=math.nan)", "'memory_budget'"),
    ("plc.simulate(plc.LineModel(plc.Span.paper_lab(), n_elements=10), duration=1e7, "
     "memory_budget=math.inf)", "'memory_budget'"),
    ("plc.MotionPlanner(plc.RobotLimits(0.5, 1.0), horizon=10**8, memory_budget=math.nan)",
     "'memory_budget'"),
])
def test_a_budget_is_validated_before_it_guards(call, name):
    import sweep_cases

    out = sweep_cases.guarded(_REFUSE.format(call=call))
    assert out.startswith("InputError") and name in out, out


def test_check_budget_refuses_nan_and_text_budgets_itself():
    for bad in (float("nan"), float("inf"), "1e6", True, -1.0, 0.0):
        with pytest.raises(InputError, match="'memory_budget'"):
            _validation.check_budget("x", nbytes=1e20, parameter="n", value=1, fix="less",
                                     memory_budget=bad)
        with pytest.raises(InputError, match="'work_budget'"):
            _validation.check_budget("x", flops=1e20, parameter="n", value=1, fix="less",
                                     work_budget=bad)


def test_finiteness_check_allocates_nothing_the_size_of_the_input():
    # Old code built ~np.isfinite(x): one bool per entry (100 MB here; 37 GiB for a larger
    # broadcast view) before any size check.
    view = np.broadcast_to(3.0, (10**8,))          # 0 bytes of data, 1e8 entries
    tracemalloc.start()
    try:
        _validation.check_array("x", view)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2**20, peak                      # nothing near 1e8 bytes
    with pytest.raises(InputError, match="'x' parameter contains NaN"):
        _validation.check_array("x", np.broadcast_to(np.nan, (10**8,)))
    # A conversion that would copy a broadcast view past the budget is refused by name first.
    with pytest.raises(InputError, match="'x' parameter's 1e\\+10 entries"):
        _validation.check_array("x", np.broadcast_to(3, (10**10,)))


# ------------------------------------------------ the scenario's records, before they exist
class _Simulated(Exception):
    """Raised by a stand-in ``simulate``: the records stage got as far as simulating."""


def _no_simulation(*args, **kwargs):
    raise _Simulated


@pytest.mark.parametrize(("duration", "n_train", "refused"), [
    (2.0, 1200, False),   # 2 x 20001^2 x 1200 = 0.96e12 operations: within 1e12
    (2.1, 1260, True),    # 2 x 20001^2 x 1260 = 1.008e12: over
])
def test_scenario_records_refuse_what_identification_would_before_simulating(
        monkeypatch, duration, n_train, refused):
    """The records stage applies design_estimator's own budget to the training part it will
    hand the recipe (60 % of floor(duration / dt) + 1 samples of every node), before it
    simulates: a 20000-element line was simulated for 37 s, then refused by a budget naming
    'snapshots'. The boundary is computed here by hand from the recipe's documented estimate
    (2 n_nodes^2 n_samples operations against a 1e12 budget)."""
    from types import SimpleNamespace

    import powerline_control.simulation
    from powerline_control.scenario import pipeline

    monkeypatch.setattr(_validation, "WORK_BUDGET", 1e12)
    monkeypatch.setattr(powerline_control.simulation, "simulate", _no_simulation)
    scenario = config.load_scenario(text=f"[model]\nn_elements = 20000\n[simulation]\n"
                                         f"duration = {duration}\n[robot]\nclosed_loop = 0\n")
    line = SimpleNamespace(n_nodes=20001)   # only its size is read before the refusal
    expected = 2.0 * 20001**2 * n_train
    assert (expected > 1e12) is refused
    if not refused:
        with pytest.raises(_Simulated):
            pipeline._records(scenario, line, None, identify=True)
        return
    with pytest.raises(InputError) as info:
        pipeline._records(scenario, line, None, identify=True)
    message = str(info.value)
    assert f"(20001 nodes x {n_train} samples)" in message
    assert f"about {expected:.2g} floating-point operations" in message
    assert "the 'model.n_elements' parameter is 20000" in message
    assert "simulation.duration" in message
    with pytest.raises(_Simulated):   # without identification, the same records are simulated
        pipeline._records(scenario, line, None)


@pytest.mark.parametrize(("stages", "identify"), [
    (("model", "records"), False), (("model", "records", "identification"), True)])
def test_the_pipeline_asks_the_records_for_the_check_only_when_it_identifies(
        monkeypatch, stages, identify):
    from powerline_control.scenario import pipeline

    seen = {}

    def spy(*args, **kwargs):
        seen.update(kwargs)
        raise _Simulated

    monkeypatch.setattr(pipeline, "_records", spy)
    scenario = config.load_scenario(text="[model]\nn_elements = 8\n[robot]\nclosed_loop = 0\n")
    with pytest.raises(_Simulated):
        pipeline.run_scenario(scenario, stages=stages)
    assert seen == {"identify": identify}


def test_run_scenario_refuses_a_known_mesh_before_any_stage():
    """model.n_elements = 20000 with a 3 s record (1800 training samples, 1.4e12 operations):
    refused before the model is built (the progress callback never hears of a stage); the same
    refusal as the records stage's, which checks a mesh the physics chooses."""
    from powerline_control.scenario import pipeline

    heard = []
    scenario = config.load_scenario(text="[model]\nn_elements = 20000\n[simulation]\n"
                                         "duration = 3.0\n[robot]\nclosed_loop = 0\n")
    with pytest.raises(InputError, match=r"\(20001 nodes x 1800 samples\) would need about "
                                         r"1\.4e\+12 floating-point operations \(the "
                                         r"'model\.n_elements' parameter is 20000\)"):
        pipeline.run_scenario(scenario, progress=heard.append)
    assert heard == []
