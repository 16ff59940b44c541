"""Benchmark: the closed loop judged on a family of scenarios nobody tuned for (issue 18).

Run: python benchmarks/bench_closed_loop_family.py [--split tune] [--quick] [--n N]
     [--seeds 1,3,5] [--json rows.json] [--workers 2]
     [--off-nominal [--no-calibration | --told-truth]]

``--off-nominal`` runs each scenario with the line off what the controller is told
(``closed_loop_family.off_nominal``: tension +-10 %, EI x0.7-1.3, damping x0.3-3, mass +-2 %),
the controller calibrating its span from its records (``--no-calibration``: predicting with the
nominal as told; ``--told-truth``: told the true line itself, so the two controllers face the
same lines and the difference is what not knowing the line costs).

The scenarios and the judge are ``tests/closed_loop_family.py`` (even seeds: the tuning split,
odd seeds: held out). Each scenario runs ``run_closed_loop`` in a worker of a
``ProcessPoolExecutor`` (2 by default) with BLAS pinned to one thread (set in ``_common`` before
numpy loads, inherited by the workers); the verdict is the exact steady state of the full FE
model with the robot parked (sparse direct solves), independent of the loop's own plant.

Printed: per category and overall, the median / 90th percentile / worst of closed/best (steady
RMS at the final position over the best parked position within reach), the settled fraction
(position range over the last quarter <= 2 % of a loop), the worst closed/start, the runs that
pass every per-run criterion, the median CPU time per run (run_closed_loop's process time) and
the median real-time factor (simulated time / that CPU time). A run that raises is a failure row
with its message. ``--json`` writes every row.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import closed_loop_family as fam  # noqa: E402


def _seeds(options) -> list[int]:
    if options.seeds:
        return [int(s) for s in options.seeds.split(",") if s.strip()]
    if options.quick:
        # a handful: 3 lab scenarios and 2 real spans of the split
        seeds = fam.family(options.split, len(fam.CATEGORIES))
        lab = [s for s in seeds if fam.CATEGORIES[(s // 2) % len(fam.CATEGORIES)]
               .startswith("lab/")][:3]
        real = [s for s in seeds if s not in lab][:2]
        return lab + real
    return fam.family(options.split, options.n)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("held_out", "tune"), default="held_out")
    parser.add_argument("--quick", action="store_true", help="a handful of scenarios")
    parser.add_argument("--n", type=int, default=42, help="scenarios of the split (default 42)")
    parser.add_argument("--seeds", default="", help="comma-separated seeds (overrides the split)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", default=None, help="write the per-scenario rows here")
    parser.add_argument("--off-nominal", action="store_true",
                        help="the truth off the nominal the controller is told")
    parser.add_argument("--no-calibration", action="store_true",
                        help="with --off-nominal: the controller predicts with the nominal")
    parser.add_argument("--told-truth", action="store_true",
                        help="with --off-nominal: the controller is told the true line")
    options = parser.parse_args()
    print(_common.PINNED)
    options.version = _common.code_version()
    print(f"code: {options.version} (started {time.strftime('%H:%M:%S')})")
    seeds = _seeds(options)
    mode = ("truth off the nominal, " + ("nominal as told" if options.no_calibration
                                         else "controller told the true line"
                                         if options.told_truth
                                         else "calibrated from the records")
            if options.off_nominal else "controller told the truth")
    print(f"split {options.split}: {len(seeds)} scenarios ({mode}), seeds {seeds}", flush=True)
    outcomes = []
    wall = time.perf_counter()
    with ProcessPoolExecutor(options.workers) as pool:
        futures = {pool.submit(fam.run_seed, seed, options.off_nominal,
                               not options.no_calibration, options.told_truth): seed
                   for seed in seeds}
        for future in as_completed(futures):
            seed = futures[future]
            try:
                outcome = future.result()
            except Exception as exc:  # noqa: BLE001 - a dead worker is a failure row too
                outcome = fam.failure(fam.scenario(seed), f"worker: {type(exc).__name__}: {exc}")
            outcomes.append(outcome)
            status = "ERROR " + outcome.error if outcome.error else (
                f"c/b {outcome.closed_over_best:.3f} c/s {outcome.closed_over_start:.3f} "
                f"range {outcome.range_fraction:.3f} loop "
                f"{'pass' if outcome.passed else 'FAIL'}")
            print(f"  seed {seed:3d} {outcome.category:17s} cpu {outcome.cpu_time:6.1f} s  "
                  f"{status}", flush=True)
            if options.json:  # rewritten as rows arrive: a killed run keeps what finished
                _write(options.json, options, outcomes)
    outcomes.sort(key=lambda o: o.seed)
    print(f"\n{len(outcomes)} runs in {time.perf_counter() - wall:.0f} s wall "
          f"({options.workers} workers)\n")
    print(fam.format_table(outcomes))
    overall = fam.summarise("overall", outcomes)
    problems = fam.criteria_failures(overall)
    print("\ncriteria (issue 18): " + ("all met" if not problems else "; ".join(problems)))
    real = [o for o in outcomes if o.error is None and o.category.startswith("real/")]
    if real:
        better = sum(o.rms_closed < o.rms_clamp for o in real)
        print(f"better than a fixed damper near the clamp: {better} of {len(real)} real-span "
              "runs")
    worst = sorted(outcomes, key=lambda o: -(o.closed_over_best if o.error is None
                                             else float("inf")))[:5]
    print("\nworst runs (closed/best):")
    for o in worst:
        extra = o.error if o.error else (
            f"c/b {o.closed_over_best:.3f}, c/s {o.closed_over_start:.3f}, final "
            f"{o.final_position:.3f} m, best {o.best_position:.3f} m "
            f"({o.loops_from_best:.2f} loops), range {o.range_fraction:.3f} loop")
        print(f"  seed {o.seed}: {extra}\n    {o.description}")
    unsettled = [o for o in outcomes if not o.settled and o.error is None]
    if unsettled:
        print("\nnot settled: " + ", ".join(f"seed {o.seed} ({o.range_fraction:.2f} loop)"
                                           for o in unsettled))
    if options.json:
        _write(options.json, options, outcomes)
        print(f"\nrows written to {options.json}")


def _write(path, options, outcomes) -> None:
    payload = {"split": options.split, "format": 1, "code": options.version,
               "rows": [o.row() for o in sorted(outcomes, key=lambda o: o.seed)]}
    Path(path).write_text(json.dumps(payload, indent=1))


if __name__ == "__main__":
    main()
