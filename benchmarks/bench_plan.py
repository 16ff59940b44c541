"""Benchmark of plan.py: minimum-time solves and receding-horizon (MPC) steps.

Rows:
* plan_motion, minimum time, 100 intervals, cold start (the NLP is built once and cached; each
  solve starts from a straight-line guess) -- against a plain CasADi Opti/IPOPT problem built and
  solved from scratch each time (the obvious way, and the issue's reference of 70-120 ms + build).
* MotionPlanner.step warm-started from the previous step, against a cold solve of the same problem
  (planner reset before the step), along a closed loop with a target that jumps twice.

Run: /work/venv/bin/python benchmarks/bench_plan.py
"""

import os

# Single-threaded BLAS before numpy is imported: timings comparable on a shared 2-core machine.
os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = "1"
os.environ["MKL_NUM_THREADS"] = "1"

import statistics  # noqa: E402
import time  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

from powerline_control.plan import MotionPlanner, RobotLimits, plan_motion  # noqa: E402

SPAN = 3.66
LIMITS = RobotLimits(v_max=0.5, a_max=1.0)
DISTANCES = [0.1, 0.5, 1.0, 2.0, 3.0]


def naive_opti_min_time(start: float, target: float, n: int = 100) -> float:
    """Build and solve a fresh Opti problem (the straightforward peer)."""
    opti = ca.Opti()
    x = opti.variable(2, n + 1)
    u = opti.variable(1, n)
    duration = opti.variable()
    h = duration / n
    p, v = x[0, :], x[1, :]
    opti.subject_to(p[1:] == p[:-1] + v[:-1] * h + u * h**2 / 2)
    opti.subject_to(v[1:] == v[:-1] + u * h)
    opti.subject_to(opti.bounded(-LIMITS.v_max, v, LIMITS.v_max))
    opti.subject_to(opti.bounded(-LIMITS.a_max, u, LIMITS.a_max))
    opti.subject_to(opti.bounded(0.0, p, SPAN))
    opti.subject_to(x[:, 0] == ca.vertcat(start, 0))
    opti.subject_to(x[:, -1] == ca.vertcat(target, 0))
    opti.subject_to(duration >= 1e-6)
    opti.minimize(duration)
    guess = abs(target - start) / LIMITS.v_max + LIMITS.v_max / LIMITS.a_max
    opti.set_initial(duration, guess)
    opti.set_initial(p, np.linspace(start, target, n + 1))
    opti.solver("ipopt", {"print_time": 0, "ipopt.print_level": 0, "ipopt.sb": "yes"})
    return float(opti.solve().value(duration))


def timed(fn, repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return times


def main() -> None:
    print("Threads: OPENBLAS_NUM_THREADS = OMP_NUM_THREADS = MKL_NUM_THREADS = 1 "
          "(set before numpy)")
    print(f"casadi {ca.__version__}, numpy {np.__version__}; times in ms, median over repeats\n")

    started = time.perf_counter()
    plan_motion(0.2, 1.8, LIMITS, span_length=SPAN)
    first_call = time.perf_counter() - started

    rows = []
    ours, naive, ours_jerk = [], [], []
    jerk_limits = RobotLimits(v_max=0.5, a_max=1.0, j_max=5.0)
    plan_motion(0.2, 1.8, jerk_limits, span_length=SPAN)  # build the jerk NLP once
    for d in DISTANCES:
        ours += timed(lambda d=d: plan_motion(0.3, 0.3 + d, LIMITS, span_length=SPAN), 5)
        naive += timed(lambda d=d: naive_opti_min_time(0.3, 0.3 + d), 2)
        ours_jerk += timed(lambda d=d: plan_motion(0.3, 0.3 + d, jerk_limits, span_length=SPAN), 3)
    med_ours = statistics.median(ours)
    rows.append(("min time, 100 intervals: plan_motion (built once, cold guess)", med_ours,
                 max(ours), len(ours)))
    rows.append(("min time, 100 intervals: fresh Opti build + solve (peer)",
                 statistics.median(naive), max(naive), len(naive)))
    rows.append(("min time, 100 intervals, jerk-limited: plan_motion",
                 statistics.median(ours_jerk), max(ours_jerk), len(ours_jerk)))
    rows.append(("first plan_motion call (includes the NLP build)", first_call, first_call, 1))

    for horizon in (40, 100):
        planner = MotionPlanner(LIMITS, dt=0.05, horizon=horizon, span_length=SPAN,
                                obstacles=[(2.6, 2.7)], time_budget=1.0)
        cold_planner = MotionPlanner(LIMITS, dt=0.05, horizon=horizon, span_length=SPAN,
                                     obstacles=[(2.6, 2.7)], time_budget=1.0)
        state = (0.5, 0.0)
        warm, cold = [], []
        for k in range(240):
            target = 2.0 if k < 80 else (0.6 if k < 160 else 2.4)
            step = planner.step(state, target)
            if step.status == "optimal" and k % 80 != 0:
                warm.append(step.solve_time)
                if k % 4 == 1:  # a cold solve of the same problem, from the same state
                    cold_planner.reset()
                    cold.append(cold_planner.step(state, target).solve_time)
            state = step.next_state
        rows.append((f"MPC step, horizon {horizon}: warm-started", statistics.median(warm),
                     max(warm), len(warm)))
        rows.append((f"MPC step, horizon {horizon}: cold solve of the same problem",
                     statistics.median(cold), max(cold), len(cold)))

    base = med_ours
    print("| case | median (ms) | max (ms) | n | median / plan_motion |")
    print("|---|---:|---:|---:|---:|")
    for name, med, worst, n in rows:
        print(f"| {name} | {med * 1e3:.1f} | {worst * 1e3:.1f} | {n} | {med / base:.2f} |")
    warm40 = rows[4][1]
    cold40 = rows[5][1]
    print(f"\nwarm / cold MPC step (horizon 40): {warm40 / cold40:.2f}")
    print("Targets: cold minimum-time solve < 200 ms; warm MPC step < 30 ms.")


if __name__ == "__main__":
    main()
