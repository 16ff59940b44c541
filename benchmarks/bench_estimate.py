"""Benchmark: Kalman filtering cost per sample, powerline_control vs filterpy vs plain numpy.

Same identified model (the paper's 100-element span, first 13 nodes measured; DMD with alpha = 0.1
relative, d = 1 -> n = 101, d = 2 -> n = 202), same data (an independent simulation, 1 % noise),
1e4 samples. Peers:

* filterpy ``KalmanFilter`` (predict + update per sample, Joseph form);
* a plain numpy loop of the same textbook equations (dense C, solve for the gain, Joseph form);
* a plain numpy loop of the steady-state filter (constant gain);
* ours: time-varying (default: selection-C indexing, gain frozen once converged, batch recursion
  afterwards), time-varying with ``gain_rtol=0`` (structure only), steady-state (batch), and the
  real-time ``step`` per sample.

Reduced coordinates (issue 10 item 3, ``--reduced`` runs only this): on rank-20 / rank-80 DMD
models with 101 / 1,001 outputs, the steady-state gain (ours: doubling in the information form,
``O(r^3 + p r^2)``; peer: SciPy's QZ ``solve_discrete_are`` on the p-output problem) and the cost
of ``KalmanFilter.step`` per sample (time-varying while converging, and frozen), with log-log
slopes. Target: the steady-state gain for 1,001 outputs under 2 s.

Run: python benchmarks/bench_estimate.py [--quick] [--reduced]
BLAS is pinned to one thread (set below, before numpy loads), as required for comparable numbers
on this shared machine.
"""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import numpy as np  # noqa: E402
import scipy.linalg as sla  # noqa: E402
from _common import CANDIDATES, RANKS, reduced_model, slope, timed  # noqa: E402

import powerline_control as plc  # noqa: E402

try:
    from filterpy.kalman import KalmanFilter as FilterpyKF  # noqa: E402
except ImportError:  # optional benchmark-only dependency
    FilterpyKF = None


def textbook_loop(a, c, q, r, y):
    n = a.shape[0]
    x, p = np.zeros(n), np.eye(n)
    eye = np.eye(n)
    out = np.empty((n, y.shape[1]))
    for k in range(y.shape[1]):
        if k:
            x = a @ x
            p = a @ p @ a.T + q
        s = c @ p @ c.T + r
        gain = np.linalg.solve(s, c @ p).T
        x = x + gain @ (y[:, k] - c @ x)
        i_kc = eye - gain @ c
        p = i_kc @ p @ i_kc.T + gain @ r @ gain.T
        out[:, k] = x
    return out


def steady_loop(a, c, gain, y):
    x = np.zeros(a.shape[0])
    out = np.empty((a.shape[0], y.shape[1]))
    for k in range(y.shape[1]):
        if k:
            x = a @ x
        x = x + gain @ (y[:, k] - c @ x)
        out[:, k] = x
    return out


def filterpy_loop(a, c, q, r, y):
    kf = FilterpyKF(dim_x=a.shape[0], dim_z=c.shape[0])
    kf.F, kf.H, kf.Q, kf.R = a, c, q, r
    kf.x, kf.P = np.zeros(a.shape[0]), np.eye(a.shape[0])
    out = np.empty((a.shape[0], y.shape[1]))
    for k in range(y.shape[1]):
        if k:  # the prior (0, I) belongs to sample 0, as in powerline_control
            kf.predict()
        kf.update(y[:, k])
        out[:, k] = kf.x
    return out


def rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ----------------------------------------------------------------------- reduced coordinates
# The rank-r models and sizes live in _common (shared with the other benchmark).


def reduced_table(repeats: int = 1) -> None:
    print("\n## Reduced coordinates: steady-state gain and step() cost in r and p\n")
    print("| rank r | outputs p | steady gain, ours (s) | SciPy QZ DARE + gain (s) | ratio | "
          "max rel. diff. | step() converging (us) | step() frozen (us) |")
    print("|---|---|---|---|---|---|---|---|")
    ours, steps, frozen = {}, {}, {}
    for r in RANKS:
        for m in CANDIDATES:
            sys_, q, noise_var = reduced_model(m, r)
            a, c = np.asarray(sys_.A), np.asarray(sys_.C)
            t_ours, gain = timed(lambda s=sys_, q=q, v=noise_var: plc.KalmanFilter(
                s, q, v, steady_state=True).steady_gain, repeats)

            def peer(a=a, c=c, q=q, v=noise_var):
                rm = v * np.eye(c.shape[0])
                p = sla.solve_discrete_are(a.T, c.T, q, rm)
                return np.linalg.solve(c @ p @ c.T + rm, c @ p).T

            t_peer, gain_peer = timed(peer, 1)
            diff = float(np.max(np.abs(gain - gain_peer)) / np.max(np.abs(gain_peer)))
            y = np.asarray(sys_.C) @ np.random.default_rng(1).normal(size=(r, 400)) * 1e-4
            kf = plc.KalmanFilter(sys_, q, noise_var, gain_rtol=0.0)
            start = time.perf_counter()
            for k in range(200):
                kf.step(y[:, k])
            t_step = (time.perf_counter() - start) / 200
            kfs = plc.KalmanFilter(sys_, q, noise_var, steady_state=True)
            start = time.perf_counter()
            for k in range(400):
                kfs.step(y[:, k])
            t_frozen = (time.perf_counter() - start) / 400
            ours[r, m], steps[r, m], frozen[r, m] = t_ours, t_step, t_frozen
            print(f"| {r} | {m} | {t_ours:.3f} | {t_peer:.3f} | {t_peer / t_ours:.1f}x | "
                  f"{diff:.1e} | {1e6 * t_step:.0f} | {1e6 * t_frozen:.0f} |")
    for name, table in (("steady gain", ours), ("step converging", steps),
                        ("step frozen", frozen)):
        parts = [f"in p (r = {r}): {slope(table[r, 101], table[r, 1001], 101, 1001):.2f}"
                 for r in RANKS]
        parts += [f"in r (p = {m}): {slope(table[20, m], table[80, m], 20, 80):.2f}"
                  for m in CANDIDATES]
        print(f"\nlog-log slopes of {name}: " + "; ".join(parts), end="")
    print()


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="2e3 samples, 1 repeat")
    parser.add_argument("--reduced", action="store_true", help="reduced-coordinates table only")
    args = parser.parse_args()
    if args.reduced:
        print(_common.PINNED)
        reduced_table()
        return
    n_t, repeats = (2000, 1) if args.quick else (10_000, 3)
    slow_repeats = 1  # filterpy and the numpy loop at n = 202 take ~10 s per run

    model = plc.LineModel(plc.Span.paper_lab(), n_elements=100)
    force = plc.HarmonicForce(amplitude=1.0, frequency=24.5, position=0.5)
    train = plc.simulate(model, force, duration=10.0, dt=1e-3, noise_fraction=0.01, seed=0)
    test = plc.simulate(model, force, duration=n_t * 1e-3, dt=1e-3, noise_fraction=0.01,
                        seed=1, start_time=3.3)
    sensors = list(range(13))
    noise_var = (0.01 * np.sqrt(np.mean(train.true_displacement**2))) ** 2
    y = test.displacement[sensors, :n_t]

    print(f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']} (set by this "
          f"script before importing numpy); {n_t} samples; median of {repeats} interleaved "
          f"repeat(s) ({slow_repeats} for the slow loops at n = 202, 1 for step())\n")
    print("| n | p | method | us / sample | speed-up vs filterpy | max rel. diff. vs filterpy |")
    print("|---|---|---|---|---|---|")
    for delays in (1, 2):
        with warnings.catch_warnings():
            # 101 x 1e4 noisy data, alpha = 1e-3 relative: well conditioned; stability is not
            # the point here (the filter corrects the model every sample).
            warnings.simplefilter("ignore", plc.UnstableModelWarning)
            dmd = plc.fit_dmd(train.displacement, dt=1e-3, alpha=1e-3, alpha_mode="relative",
                              delays=delays)
        sys = dmd.to_statespace(measured=sensors)
        a, c = np.asarray(sys.A), np.asarray(sys.C)
        q, r = dmd.residual_covariance, noise_var * np.eye(len(sensors))
        n = a.shape[0]
        reps = repeats if delays == 1 else slow_repeats
        kf = plc.KalmanFilter(sys, Q=q, R=r)
        kf0 = plc.KalmanFilter(sys, Q=q, R=r, gain_rtol=0.0)
        kfs = plc.KalmanFilter(sys, Q=q, R=r, steady_state=True)
        gain = kfs.steady_gain

        def stepping(kf=kf):
            kf.reset()
            for k in range(y.shape[1]):
                kf.step(y[:, k])

        # (name, function, repeats); run in interleaved rounds so that the load of the shared
        # machine hits every method alike, then take each method's median.
        methods = []
        if FilterpyKF is not None:
            methods.append(("filterpy KalmanFilter",
                            lambda a=a, c=c, q=q, r=r: filterpy_loop(a, c, q, r, y), reps))
        methods += [
            ("plain numpy loop (textbook)",
             lambda a=a, c=c, q=q, r=r: textbook_loop(a, c, q, r, y), reps),
            ("ours, time-varying", lambda kf=kf: kf.filter(y).states, repeats),
            ("ours, time-varying, gain_rtol=0 (structure only)",
             lambda kf0=kf0: kf0.filter(y).states, reps),
            ("plain numpy steady-state loop",
             lambda a=a, c=c, g=gain: steady_loop(a, c, g, y), repeats),
            ("ours, steady-state (batch)", lambda kfs=kfs: kfs.filter(y).states, repeats),
            ("ours, step() per sample (time-varying)", stepping, 1),
        ]
        kfs.filter(y)  # build the cached modal decomposition once, as a long-lived filter would
        times = {name: [] for name, _, _ in methods}
        outputs = {}
        for round_ in range(max(m[2] for m in methods)):
            for name, func, count in methods:
                if round_ < count:
                    start = time.perf_counter()
                    outputs[name] = func()
                    times[name].append(time.perf_counter() - start)
        seconds = {name: statistics.median(values) for name, values in times.items()}
        ref = outputs.get("filterpy KalmanFilter", outputs["plain numpy loop (textbook)"])
        t_fp = seconds.get("filterpy KalmanFilter")
        converged = kf.filter(y).converged_at
        compared = {"filterpy KalmanFilter", "plain numpy loop (textbook)", "ours, time-varying",
                    "ours, time-varying, gain_rtol=0 (structure only)"}
        for name, _, _ in methods:
            speed = "-" if t_fp is None else f"{t_fp / seconds[name]:.1f}x"
            diff = f"{rel(outputs[name], ref):.1e}" if name in compared else "-"
            label = name + (f" (gain frozen at sample {converged})"
                            if name == "ours, time-varying" else "")
            print(f"| {n} | {len(sensors)} | {label} | {1e6 * seconds[name] / n_t:.2f} | "
                  f"{speed} | {diff} |")
        # The steady-state filter is a different filter (constant gain from sample 0): compare it
        # with the plain steady-state loop rather than with filterpy.
        steady_diff = rel(outputs["ours, steady-state (batch)"],
                          outputs["plain numpy steady-state loop"])
        print(f"| {n} | {len(sensors)} | (steady-state batch vs plain steady loop: max rel. "
              f"diff. {steady_diff:.1e}) | | | |")
    reduced_table()


if __name__ == "__main__":
    main()
