"""Benchmark of plan.py: the closed-form time-optimal move against IPOPT, and MPC steps.

Rows:
* plan_motion, minimum time: the closed form (default) against the same request solved by IPOPT
  on 100 intervals (``method="ipopt"``, NLP built once and cached) and against a plain CasADi
  Opti/IPOPT problem built and solved from scratch each time (the obvious way).
* One MPC step (MotionPlanner.step, horizon 40 and 100, IPOPT) against evaluating the
  closed-form move from the same state (what the step is seeded with), along a closed loop whose
  target (a) jumps twice, (b) jitters by 1 cm every step (as an antinode estimate does), for the
  three initial guesses: the closed form with the previous multipliers (default), the previous
  plan shifted by one period (the old warm start), none.  Median IPOPT iterations per step are
  given too: they, unlike the times, do not depend on the machine's load.

Run: /work/main/.venv/bin/python benchmarks/bench_plan.py
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import statistics  # noqa: E402
import time  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy is imported)
import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

from powerline_control.plan import (  # noqa: E402
    MotionPlanner,
    RobotLimits,
    _time_optimal_pieces,
    plan_motion,
)

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


def jumping(k: int) -> float:
    return 2.0 if k < 80 else (0.6 if k < 160 else 2.4)


_JITTER = 0.01 * np.random.default_rng(0).standard_normal(240)


def jittering(k: int) -> float:
    return (2.0 if k < 120 else 0.8) + _JITTER[k]


def mpc_run(horizon: int, warm_start: str, targets) -> tuple[list[float], list[int], list[float]]:
    """240 steps of a closed loop; per optimal step: solve time, iterations, closed-form time."""
    planner = MotionPlanner(LIMITS, dt=0.05, horizon=horizon, span_length=SPAN,
                            obstacles=[(2.6, 2.7)], warm_start=warm_start)
    state = (0.5, 0.0)
    solve, iterations, closed = [], [], []
    for k in range(240):
        step = planner.step(state, targets(k))
        if step.status == "optimal":
            solve.append(step.solve_time)
            iterations.append(step.iterations)
            started = time.perf_counter()
            _time_optimal_pieces(state[0], step.target, state[1], LIMITS)
            closed.append(time.perf_counter() - started)
        state = step.next_state
    return solve, iterations, closed


def main() -> None:
    print(_common.PINNED)
    print(f"casadi {ca.__version__}, numpy {np.__version__}; times in ms, medians; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores\n")

    plan_motion(0.2, 1.8, LIMITS, span_length=SPAN, method="ipopt")  # build the NLP once
    closed, ipopt, naive, iterations = [], [], [], []
    for d in DISTANCES:
        closed += timed(lambda d=d: plan_motion(0.3, 0.3 + d, LIMITS, span_length=SPAN), 20)
        ipopt += timed(lambda d=d: plan_motion(0.3, 0.3 + d, LIMITS, span_length=SPAN,
                                               method="ipopt"), 3)
        iterations.append(plan_motion(0.3, 0.3 + d, LIMITS, span_length=SPAN,
                                      method="ipopt").iterations)
        naive += timed(lambda d=d: naive_opti_min_time(0.3, 0.3 + d), 2)
    base = statistics.median(closed)
    print("| minimum-time move, 5 distances 0.1-3 m | median (ms) | max (ms) | n | / closed form |")
    print("|---|---:|---:|---:|---:|")
    for name, values in (("plan_motion, closed form (default)", closed),
                         (f"plan_motion, method='ipopt' (100 intervals, median "
                          f"{statistics.median(iterations):.0f} iterations)", ipopt),
                         ("fresh CasADi Opti build + IPOPT solve (peer)", naive)):
        med = statistics.median(values)
        print(f"| {name} | {med * 1e3:.3f} | {max(values) * 1e3:.3f} | {len(values)} | "
              f"{med / base:.0f} |")

    print("\n| MPC step (IPOPT) | target | guess | median step (ms) | median iterations | "
          "max iterations | closed form (ms) | step / closed form |")
    print("|---|---|---|---:|---:|---:|---:|---:|")
    for horizon in (40, 100):
        for target_name, targets in (("jumps", jumping), ("1 cm jitter", jittering)):
            for guess in ("closed_form", "previous", "none"):
                solve, its, closed_times = mpc_run(horizon, guess, targets)
                step_ms = statistics.median(solve) * 1e3
                closed_ms = statistics.median(closed_times) * 1e3
                print(f"| horizon {horizon} | {target_name} | {guess} | {step_ms:.1f} | "
                      f"{statistics.median(its):.0f} | {max(its)} | {closed_ms:.4f} | "
                      f"{step_ms / closed_ms:.0f} |")
    print("\nIterations are exact (no wall-clock budget by default); times are of a shared,"
          " loaded machine: compare ratios.")


if __name__ == "__main__":
    main()
