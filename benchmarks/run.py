"""All benchmarks side by side with their peers, in one run, plus a scaling table.

Run: ``python benchmarks/run.py [--quick] [--json PATH]`` (or ``python -m benchmarks``).

For each workload this toolbox and the peer that does the same job run alternately (ours, peer,
ours, peer, ...) with repeats on the same inputs; the table gives the median wall times, the ratio
``peer / ours`` (above 1: we are faster) and the agreement of the results (max abs difference of
eigenvalues, estimates or objectives, relative where the column says so). Peers are optional
benchmark-only dependencies (``pip install powerline_control[bench]``: pydmd, filterpy,
python-sensors); a missing one is skipped with a message. The scaling table gives time and peak
traced memory against problem size with the fitted log-log growth exponent.

BLAS is pinned to one thread before numpy is imported (see ``_common.py``). Timings are of this
shared, loaded 2-core machine: compare ratios, not absolute numbers, across runs.
"""

import os
import sys

# Single-threaded BLAS, set before numpy is imported by anything below (_common does the same;
# repeated here so that no import re-ordering can move numpy first).
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_name] = "1"
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import argparse  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import _common  # noqa: E402  (pins BLAS before numpy loads)
import control as ct  # noqa: E402
import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.linalg  # noqa: E402
from _common import alternate, peak_memory, timed  # noqa: E402

# Workloads of the per-module benchmarks, reused as they are (their owners keep them).
from bench_estimate import filterpy_loop, textbook_loop  # noqa: E402
from bench_identify import standing_waves  # noqa: E402
from bench_plan import naive_opti_min_time  # noqa: E402
from scipy.optimize import linear_sum_assignment  # noqa: E402

import powerline_control as plc  # noqa: E402
from powerline_control.estimate import steady_state_covariance  # noqa: E402

try:
    import pydmd
except ImportError:  # optional benchmark-only peer
    pydmd = None
try:
    import filterpy.kalman  # noqa: F401
except ImportError:
    FILTERPY = False
else:
    FILTERPY = True
try:
    import pysensors  # the python-sensors distribution (not PySensors, the libsensors bindings)
except ImportError:
    pysensors = None

LAB = plc.Span.paper_lab()
ROWS: list[dict] = []
SKIPPED: list[str] = []


def row(workload, ours_s, peer, peer_s, agreement, note=""):
    ratio = peer_s / ours_s if np.isfinite(peer_s) and ours_s > 0 else float("nan")
    ROWS.append({"workload": workload, "ours_s": ours_s, "peer": peer, "peer_s": peer_s,
                 "ratio_peer_over_ours": ratio, "agreement": agreement, "note": note})
    print(f"  {workload} | ours {ours_s:.4f} s | {peer} {peer_s:.4f} s | {agreement}", flush=True)


def skip(workload, reason):
    SKIPPED.append(f"{workload}: {reason}")
    ROWS.append({"workload": workload, "ours_s": float("nan"), "peer": "-",
                 "peer_s": float("nan"), "ratio_peer_over_ours": float("nan"),
                 "agreement": f"skipped: {reason}", "note": ""})
    print(f"  {workload}: SKIPPED ({reason})", flush=True)


def matched_distance(a, b) -> float:
    """Max distance between two eigenvalue sets after optimal matching (robust to ordering)."""
    cost = np.abs(np.asarray(a)[:, None] - np.asarray(b)[None, :])
    i, j = linear_sum_assignment(cost)
    return float(cost[i, j].max())


# ------------------------------------------------------------------------------ workloads
def bench_modal(sizes, repeats):
    """Assembly + 50 lowest modes (ours, sparse) vs scipy dense eigh on the same K, M."""
    drake = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    for n_el in sizes:
        model = plc.LineModel(drake, n_el)
        k, m = model.stiffness_matrix.toarray(), model.mass_matrix.toarray()

        def ours(n_el=n_el):
            return plc.LineModel(drake, n_el).natural_frequencies(50)

        def peer(k=k, m=m):
            return scipy.linalg.eigh(k, m, subset_by_index=[0, 49], eigvals_only=True)

        t_ours, t_peer, freqs, lam = alternate(ours, peer, repeats)
        peer_freqs = np.sqrt(lam) / (2 * np.pi)
        diff = float(np.max(np.abs(freqs - peer_freqs) / peer_freqs))
        row(f"FE modal: Drake 300 m, {n_el} el ({model.n_dofs} dofs), 50 modes", t_ours,
            "scipy.linalg.eigh dense (50 of them; assembly not timed)", t_peer,
            f"freq rel {diff:.1e}")


def bench_dmd(n_nodes, n_samples, repeats):
    """Tikhonov DMD (eq. 14) vs plain numpy and PyDMD on the same data, alpha and rank."""
    X = standing_waves(n_nodes, n_samples)
    X0, X1 = X[:, :-1], X[:, 1:]

    def ours_full():
        return plc.fit_dmd(X, 1e-3, alpha=1e-3, alpha_mode="relative")

    alpha = ours_full().alpha

    def numpy_solve():
        gram = X0 @ X0.T + alpha * np.eye(n_nodes)
        return np.linalg.solve(gram, X0 @ X1.T).T

    t_ours, t_peer, model, a_peer = alternate(ours_full, numpy_solve, repeats)
    diff = float(np.abs(model.A - a_peer).max() / np.abs(a_peer).max())
    row(f"DMD fit {n_nodes} x {n_samples}, full rank, alpha 1e-3 rel.", t_ours,
        "numpy eq. 14 (solve)", t_peer, f"A rel {diff:.1e}",
        "ours also computes the residual covariance")
    rank = 60

    def ours_rank():
        fitted = plc.fit_dmd(X, 1e-3, alpha=1e-3, alpha_mode="relative", rank=rank)
        fitted.eigenvalues  # noqa: B018 - lazy; PyDMD computes them in fit, so time them here
        return fitted

    if pydmd is None:
        skip(f"DMD fit {n_nodes} x {n_samples}, rank {rank}", "pydmd not installed")
        return
    # PyDMD scales its Tikhonov lambda by ||X||_F (s -> (s^2 + lambda ||X||_F) / s): same filter.
    lam = alpha / np.linalg.norm(X0)

    def peer_rank():
        dmd = pydmd.DMD(svd_rank=rank, exact=True, tikhonov_regularization=lam)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # PyDMD warns about its own internals
            dmd.fit(X)
        return dmd

    t_ours, t_peer, model, peer_model = alternate(ours_rank, peer_rank, repeats)
    diff = matched_distance(model.eigenvalues, peer_model.eigs)
    row(f"DMD fit {n_nodes} x {n_samples}, rank {rank}, alpha 1e-3 rel.", t_ours,
        "PyDMD DMD (exact, tikhonov)", t_peer, f"eigs abs {diff:.1e}")


def kalman_problem(n_t):
    """The paper span identified by DMD (13 measured nodes, 1 % noise), fresh test data."""
    model = plc.LineModel(LAB, n_elements=100)
    force = plc.HarmonicForce(amplitude=1.0, frequency=24.5, position=0.5)
    train = plc.simulate(model, force, duration=5.0, dt=1e-3, noise_fraction=0.01, seed=0)
    test = plc.simulate(model, force, duration=n_t * 1e-3, dt=1e-3, noise_fraction=0.01,
                        seed=1, start_time=3.3)
    sensors = list(range(13))
    with warnings.catch_warnings():
        # Stability is not the point: the filter corrects the model every sample.
        warnings.simplefilter("ignore", plc.UnstableModelWarning)
        dmd = plc.fit_dmd(train.displacement, dt=1e-3, alpha=1e-3, alpha_mode="relative")
    sys = dmd.to_statespace(measured=sensors)
    noise_var = (0.01 * np.sqrt(np.mean(train.true_displacement**2))) ** 2
    q, r = dmd.residual_covariance, noise_var * np.eye(len(sensors))
    return sys, q, r, test.displacement[sensors, :n_t]


def bench_kalman(n_t, repeats):
    sys, q, r, y = kalman_problem(n_t)
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    n, p = c.shape[1], c.shape[0]

    def ours():
        return plc.KalmanFilter(sys, Q=q, R=r).filter(y).states

    peer_name = "filterpy KalmanFilter (predict+update loop)"
    if FILTERPY:
        t_ours, t_peer, x_ours, x_peer = alternate(ours, lambda: filterpy_loop(a, c, q, r, y),
                                                   repeats)
        diff = float(np.abs(x_ours - x_peer).max() / np.abs(x_peer).max())
        row(f"Kalman filter n={n}, p={p}, {n_t} samples", t_ours, peer_name, t_peer,
            f"states rel {diff:.1e}")

        def ours_textbook():
            return plc.KalmanFilter(sys, Q=q, R=r, gain_rtol=0.0).filter(y).states

        t_ours, t_peer, x_ours, x_peer = alternate(ours_textbook,
                                                   lambda: filterpy_loop(a, c, q, r, y), repeats)
        diff = float(np.abs(x_ours - x_peer).max() / np.abs(x_peer).max())
        row(f"Kalman filter n={n}, p={p}, {n_t} samples, gain_rtol=0 (Riccati every step)",
            t_ours, peer_name, t_peer, f"states rel {diff:.1e}")
    else:
        skip(f"Kalman filter n={n}, p={p}, {n_t} samples", "filterpy not installed")
    t_ours, t_peer, x_ours, x_peer = alternate(ours, lambda: textbook_loop(a, c, q, r, y),
                                               repeats)
    diff = float(np.abs(x_ours - x_peer).max() / np.abs(x_peer).max())
    row(f"Kalman filter n={n}, p={p}, {n_t} samples", t_ours, "plain numpy textbook loop",
        t_peer, f"states rel {diff:.1e}")

    def ours_gain():
        return plc.KalmanFilter(sys, Q=q, R=r, steady_state=True).steady_gain

    def peer_gain():
        return ct.dlqe(a, np.eye(n), c, q, r)[0]

    try:
        t_ours, t_peer, gain, dlqe_gain = alternate(ours_gain, peer_gain, repeats)
    except Exception as exc:  # noqa: BLE001 - report whichever side failed, keep the run going
        skip(f"steady-state gain n={n}, p={p}", f"{type(exc).__name__}: {exc}")
        return
    # dlqe returns the predictor-form gain L = A K.
    diff = float(np.abs(a @ gain - dlqe_gain).max() / np.abs(dlqe_gain).max())
    row(f"steady-state Kalman gain n={n}, p={p}", t_ours, "control.dlqe", t_peer,
        f"gain rel {diff:.1e}")


def sensor_problem(n_elements=20, n_modes=5):
    """A damped paper span, modal-truncated (2 n_modes states), every node a candidate."""
    model = plc.LineModel(LAB, n_elements=n_elements, damping=plc.ModalDamping(0.02))
    sys = model.to_statespace(dt=2e-3, force_positions=[1.3], n_modes=n_modes)
    b = np.asarray(sys.B)
    q = b @ b.T + 1e-3 * np.diag(b @ b.T).mean() * np.eye(sys.nstates)
    r = 1e-10  # (10 um)^2
    return sys, q, r


def pod_basis(sys, q, rank):
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    sigma = scipy.linalg.solve_discrete_lyapunov(a, q)
    vals, vecs = np.linalg.eigh(c @ sigma @ c.T)
    return vecs[:, ::-1][:, :rank]


def logdet_objective(psi, layouts):
    sub = psi[np.asarray(layouts)]  # (n_layouts, k, r)
    return np.linalg.slogdet(np.swapaxes(sub, 1, 2) @ sub)[1]


def bench_sensors(k, repeats, brute_kalman):
    sys, q, r = sensor_problem()
    m = sys.noutputs
    psi = pod_basis(sys, q, k)
    options = dict(R=r, brute_force_limit=0, n_random=0)

    def ours_rec():
        return plc.select_sensors(sys, k, "reconstruction", Q=q, basis=psi, **options)

    def peer_qr():
        model = pysensors.SSPOR(basis=pysensors.basis.Identity(n_basis_modes=k), n_sensors=k)
        model.fit(psi.T)  # rows: basis vectors over the m candidates
        return tuple(sorted(int(i) for i in model.get_selected_sensors()[:k]))

    name = f"sensors: {m} candidates, k={k}, reconstruction (log det)"
    if pysensors is None:
        skip(name, "python-sensors (import pysensors) not installed")
        sel = ours_rec()
        qr_nodes = None
    else:
        t_ours, t_peer, sel, qr_nodes = alternate(ours_rec, peer_qr, repeats)
        gap = float(sel.objective - logdet_objective(psi, [qr_nodes])[0])
        row(name, t_ours, "PySensors SSPOR (QR pivoting)", t_peer,
            f"log det ours - QR {gap:.2e} (QR {qr_nodes}, ours {sel.nodes})")
    layouts = list(itertools.combinations(range(m), k))
    t_brute, values = timed(lambda: logdet_objective(psi, layouts), 1)
    t_ours, sel = timed(ours_rec, repeats)
    row(name, t_ours, f"brute force numpy ({len(layouts)} layouts)", t_brute,
        f"log det optimum - ours {float(values.max() - sel.objective):.1e}")

    def ours_kalman():
        return plc.select_sensors(sys, k, "kalman", Q=q, **options)

    name = f"sensors: {m} candidates, k={k}, Kalman trace"
    t_ours, sel = timed(ours_kalman, repeats)
    if qr_nodes is not None:
        qr_trace = float(np.trace(steady_state_covariance(sys, q, r, list(qr_nodes))))
        row(name, t_ours, "PySensors QR layout, scored by DARE", float("nan"),
            f"trace QR / ours {qr_trace / sel.objective:.3f}", "QR ignores the dynamics")
    if brute_kalman:
        def brute():
            return min(float(np.trace(steady_state_covariance(sys, q, r, list(lay))))
                       for lay in layouts)

        t_brute, optimum = timed(brute, 1)
        row(name, t_ours, f"brute force SciPy DARE ({len(layouts)} layouts)", t_brute,
            f"trace rel ours - optimum {(sel.objective - optimum) / optimum:.1e}")
    else:
        skip(name + " vs brute force", "--quick: C(m, k) DAREs take tens of seconds")


def bench_planning(distances, repeats):
    limits = plc.RobotLimits(v_max=0.5, a_max=1.0)
    plc.plan_motion(0.2, 1.8, limits, span_length=3.66)  # the NLP is built once per process
    ours_t, peer_t, diffs = [], [], []
    for d in distances:
        t_o, t_p, traj, peer_duration = alternate(
            lambda d=d: plc.plan_motion(0.3, 0.3 + d, limits, span_length=3.66),
            lambda d=d: naive_opti_min_time(0.3, 0.3 + d), repeats)
        ours_t.append(t_o)
        peer_t.append(t_p)
        diffs.append(abs(traj.duration - peer_duration))
    row(f"min-time move, 100 intervals, {len(distances)} distances (median)",
        float(np.median(ours_t)), "CasADi Opti built + solved cold", float(np.median(peer_t)),
        f"duration abs {max(diffs):.1e} s", "ours: NLP built once per process")


def bench_closed_loop(duration):
    f3 = plc.LineModel(LAB, 40).natural_frequencies(3)[2]
    robot = plc.MDR.tuned(1.2, body_mass=0.02, suspended_mass=0.05, frequency=f3,
                          damping_ratio=0.1)
    start = time.perf_counter()
    result = plc.run_closed_loop(LAB, plc.HarmonicForce(1.0, 24.0, 0.5), robot,
                                 plc.RobotLimits(v_max=0.5, a_max=1.0), sensors=[6, 16, 28],
                                 n_elements=40, duration=duration, calibration=2.0, seed=1)
    wall = time.perf_counter() - start
    row(f"closed loop, 40 el, {duration:g} s simulated (1 kHz, MPC 20 Hz)", wall,
        "real time (simulated seconds)", duration,
        f"real-time factor {duration / wall:.2f} (above 1: faster than real time)",
        f"steps: {len(result.statuses)}")


# ------------------------------------------------------------------------------ scaling
SCALING: list[dict] = []


def growth(sizes, values) -> float:
    """Slope of log(value) against log(size): the exponent p in value ~ size^p."""
    return float(np.polyfit(np.log(sizes), np.log(values), 1)[0])


def add_series(name, unit, sizes, seconds, memory):
    """Store a series with two exponents: over every size, and over the largest three.

    Fixed costs (solver set-up, Python overhead) flatten the small sizes, and the FE series
    switches from a dense all-mode eigensolver to sparse Lanczos above 1,200 DOFs
    (``fem.DENSE_EIGEN_LIMIT``): the largest three sizes show the asymptotic growth.
    """
    SCALING.append({"series": name, "unit": unit, "sizes": list(sizes), "seconds": seconds,
                    "peak_mib": memory, "time_exponent": growth(sizes, seconds),
                    "memory_exponent": growth(sizes, memory),
                    "time_exponent_largest3": growth(sizes[-3:], seconds[-3:]),
                    "memory_exponent_largest3": growth(sizes[-3:], memory[-3:])})


def scaling_series(name, unit, sizes, make_call, repeats):
    seconds, memory = [], []
    for size in sizes:
        call = make_call(size)
        seconds.append(timed(call, repeats)[0])
        memory.append(peak_memory(call))
        print(f"  scaling {name}: {unit}={size}: {seconds[-1]:.4f} s, {memory[-1]:.1f} MiB",
              flush=True)
    add_series(name, unit, sizes, seconds, memory)


def run_scaling(quick):
    drake = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    scaling_series("FE assembly + 20 modes (Drake 300 m)", "elements",
                   (100, 300, 1000, 2000, 5000),
                   lambda n: lambda: plc.LineModel(drake, n).natural_frequencies(20), 3)
    X = standing_waves(101, 8000 if quick else 16000)
    sizes = (1000, 2000, 4000, 8000) if quick else (1000, 2000, 4000, 8000, 16000)
    scaling_series("DMD fit, 101 nodes, full rank", "snapshots", sizes,
                   lambda s: lambda: plc.fit_dmd(X[:, :s], 1e-3, alpha=1e-3,
                                                 alpha_mode="relative"), 3)

    def sensors_call(n_el):
        sys, q, r = sensor_problem(n_elements=n_el)
        return lambda: plc.select_sensors(sys, 3, "kalman", Q=q, R=r, brute_force_limit=0,
                                          n_random=0)

    scaling_series("sensor selection, Kalman, k=3, 10 states", "candidates",
                   (11, 21, 41) if quick else (11, 21, 41, 81, 161), sensors_call, 1)

    def mpc_call(horizon):
        def call():
            planner = plc.MotionPlanner(plc.RobotLimits(v_max=0.5, a_max=1.0), dt=0.05,
                                        horizon=horizon, span_length=3.66, time_budget=5.0)
            state, times = (0.5, 0.0), []
            for k in range(12):
                step = planner.step(state, 2.0 if k < 6 else 1.0)
                if k:  # the first step builds the NLP
                    times.append(step.solve_time)
                state = step.next_state
            return float(np.median(times))
        return call

    seconds, memory = [], []
    sizes = (20, 40, 80) if quick else (20, 40, 80, 160)
    for horizon in sizes:
        # Time per warm MPC step (the planner's own solve_time), not the whole loop.
        seconds.append(mpc_call(horizon)())
        memory.append(peak_memory(mpc_call(horizon)))
        print(f"  scaling MPC: horizon={horizon}: {seconds[-1]:.4f} s/step, {memory[-1]:.1f} MiB",
              flush=True)
    add_series("MPC step, warm (median of 11 steps)", "horizon", sizes, seconds, memory)


# ------------------------------------------------------------------------------ output
def fmt(value, digits=4):
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}g}"


def markdown() -> str:
    lines = ["| workload | ours median (s) | peer | peer median (s) | peer / ours | agreement |",
             "|---|---:|---|---:|---:|---|"]
    for r in ROWS:
        ratio = r["ratio_peer_over_ours"]
        lines.append(f"| {r['workload']} | {fmt(r['ours_s'])} | {r['peer']} | "
                     f"{fmt(r['peer_s'])} | {'-' if not math.isfinite(ratio) else f'{ratio:.2f}'}"
                     f" | {r['agreement']} |")
    lines += ["", "| series | size | time (s) | peak traced memory (MiB) |", "|---|---:|---:|---:|"]
    for s in SCALING:
        for size, sec, mib in zip(s["sizes"], s["seconds"], s["peak_mib"], strict=True):
            lines.append(f"| {s['series']} | {s['unit']} = {size} | {sec:.4g} | {mib:.3g} |")
        lines.append(f"| {s['series']} | **growth exponent, all sizes** | "
                     f"**{s['time_exponent']:.2f}** | **{s['memory_exponent']:.2f}** |")
        lines.append(f"| {s['series']} | **growth exponent, largest 3** | "
                     f"**{s['time_exponent_largest3']:.2f}** | "
                     f"**{s['memory_exponent_largest3']:.2f}** |")
    return "\n".join(lines)


def _finite(value):
    """NaN/inf -> None so that the JSON is standard (json.dump would write bare NaN)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes, fewer repeats "
                        "(under 2 minutes)")
    parser.add_argument("--json", default="benchmarks/results.json", help="where to write the "
                        "rows as JSON (default: %(default)s)")
    parser.add_argument("--no-scaling", action="store_true", help="skip the scaling table")
    args = parser.parse_args(argv)
    quick = args.quick
    repeats = 3 if quick else 5
    started = time.perf_counter()
    print(_common.PINNED)
    print(f"numpy {np.__version__}, scipy {scipy.__version__}, control {ct.__version__}, "
          f"python {platform.python_version()}; {'quick' if quick else 'full'} run, "
          f"median of {repeats} alternating repeats unless stated\n", flush=True)
    for name, present in (("pydmd", pydmd is not None), ("filterpy", FILTERPY),
                          ("python-sensors", pysensors is not None)):
        if not present:
            print(f"peer {name} is not installed: its rows are skipped "
                  "(pip install powerline_control[bench])")
    bench_modal((100, 1000) if quick else (100, 1000, 2000), repeats)
    bench_dmd(101, 2000 if quick else 5000, repeats)
    if not quick:
        bench_dmd(401, 5000, 3)
    bench_kalman(1000 if quick else 5000, 1 if quick else 3)
    bench_sensors(4 if not quick else 3, repeats, brute_kalman=True)
    bench_planning((0.5, 2.0) if quick else (0.1, 0.5, 1.0, 2.0, 3.0), 2 if quick else 3)
    bench_closed_loop(3.0 if quick else 6.0)
    if not args.no_scaling:
        run_scaling(quick)
    elapsed = time.perf_counter() - started
    table = markdown()
    print("\n" + _common.PINNED + f"; total {elapsed:.0f} s\n")
    print(table)
    if SKIPPED:
        print("\nSkipped:\n" + "\n".join(f"- {s}" for s in SKIPPED))
    payload = {"blas": _common.PINNED, "quick": quick, "repeats": repeats,
               "elapsed_s": elapsed, "versions": {"numpy": np.__version__,
                                                  "scipy": scipy.__version__,
                                                  "control": ct.__version__},
               "rows": ROWS, "scaling": SCALING, "skipped": SKIPPED}
    with open(args.json, "w") as handle:
        json.dump(_finite(payload), handle, indent=1)
    print(f"\nJSON written to {args.json}")


if __name__ == "__main__":
    main()
