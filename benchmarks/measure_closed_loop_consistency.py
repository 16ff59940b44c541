"""The closed loop's "robot_input" estimator on the family: the share of consistency windows
(200 samples) inside their two-sided 1 % bounds, above and below, per phase of the run (parked at
the start, moving, settled; ``scenario.summary.consistency_by_phase``), on
``closed_loop_family.off_nominal`` runs (the truth off the nominal, the controller calibrating),
with its rebuilds and the loop's real-time factor (docs/validation/closed_loop.md, "The robot in
the estimator's model"). ``--self-limiting`` runs the family's real aeolian runs in the
self-limiting wind. Two worker processes, BLAS on one thread (``_common``).

Usage::

    .venv/bin/python benchmarks/measure_closed_loop_consistency.py 1 41 [--step 2]
        [--self-limiting]
"""

import argparse
import statistics
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)

PHASES = ("calibration", "moving", "settled")


def measure(job: tuple) -> dict:
    """One seed: (above, below, tested) per phase, the rebuilds and the real-time factor."""
    seed, self_limiting = job
    import closed_loop_family as fam
    from threadpoolctl import threadpool_limits

    import powerline_control as plc
    from powerline_control.scenario.summary import consistency_by_phase

    with threadpool_limits(limits=1):
        scenario = fam.off_nominal(seed)
        args = scenario.run_arguments()
        args["estimator"] = "robot_input"
        if self_limiting:
            args["wind"] = "self_limiting"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = plc.run_closed_loop(args.pop("span"), args.pop("force"),
                                             args.pop("robot"), args.pop("limits"), **args)
        except plc.errors.PowerlineControlError as error:
            return dict(seed=seed, error=f"{type(error).__name__}: {error}")
    return dict(seed=seed, category=fam.CATEGORIES[(seed // 2) % len(fam.CATEGORIES)],
                phases=consistency_by_phase(result),
                rebuilds=[why for _, why in result.estimator_updates],
                real_time=float(result.real_time_factor))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", type=int)
    parser.add_argument("last", type=int)
    parser.add_argument("--step", type=int, default=2)
    parser.add_argument("--self-limiting", action="store_true")
    options = parser.parse_args()
    import closed_loop_family as fam

    seeds = [seed for seed in range(options.first, options.last + 1, options.step)
             if not options.self_limiting
             or fam.CATEGORIES[(seed // 2) % len(fam.CATEGORIES)] == "real/aeolian"]
    print(_common.PINNED)
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(measure, [(seed, options.self_limiting) for seed in seeds]))
    print("| seed | category | " + " | ".join(f"{p}: in/above/below" for p in PHASES)
          + " | rebuilds | x real time |")
    print("|---" * (4 + len(PHASES)) + "|")
    totals = {p: [0, 0, 0] for p in PHASES}
    for row in rows:
        if "error" in row:
            print(f"| {row['seed']} | error: {row['error'][:80]} |")
            continue
        cells = []
        for phase in PHASES:
            above, below, tested = row["phases"].get(phase, (0, 0, 0))
            cells.append(f"{tested - above - below}/{above}/{below}")
            totals[phase] = [a + b for a, b in zip(totals[phase], (above, below, tested),
                                                   strict=True)]
        print(f"| {row['seed']} | {row['category']} | " + " | ".join(cells)
              + f" | {', '.join(row['rebuilds']) or 'none'} | "
              f"{row['real_time']:.2f} |")
    tested = sum(t[2] for t in totals.values())
    above = sum(t[0] for t in totals.values())
    below = sum(t[1] for t in totals.values())
    print(f"\nall phases: inside {100 * (tested - above - below) / max(tested, 1):.1f} % of "
          f"{tested}, above {above}, below {below}; "
          + "; ".join(f"{p} inside {100 * (t[2] - t[0] - t[1]) / max(t[2], 1):.1f} %"
                      for p, t in totals.items())
          + f"; median x real time "
          f"{statistics.median(r['real_time'] for r in rows if 'error' not in r):.2f}")


if __name__ == "__main__":
    main()
