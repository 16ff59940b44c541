"""The policy in the self-limiting wind on the closed-loop family's real aeolian runs
(docs/validation/closed_loop.md, "The policy in the self-limiting wind").

Each run is ``closed_loop_family.off_nominal(seed)`` (the truth off the nominal, the controller
calibrating) with ``wind="self_limiting"`` and ``aeolian_steady=True``: the amplitude
``simulate_aeolian`` settles at with the robot parked where the loop ended, over that with it
parked at the locked mode's antinode nearest there, over the fixed damper near the clamp and over
the robot parked where it started.
``--forced-response`` runs the policy as it ranks positions under the fixed lift (the predicted
span RMS of a load of fixed amplitude) in place of the standing wave's coupling: the comparison's
"before". Runs whose energy balance stays below 0.01 D (the wind cannot sustain the vibration)
are listed apart. Two worker processes, BLAS on one thread (``_common``).

Usage::

    .venv/bin/python benchmarks/measure_policy_self_limiting.py 1017 1255 [--forced-response]
"""

import argparse
import json
import statistics
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)

#: Below this antinode amplitude (in diameters) the wind cannot sustain the vibration.
SUSTAINED = 0.01


def _forced_response() -> None:
    """Make the loop rank positions by the forced response whatever the wind."""
    from powerline_control.closed_loop import loop

    choose = loop.choose_target

    def forced(*args, **kwargs):
        kwargs.pop("objective", None)
        return choose(*args[:11], **kwargs, objective="response")

    loop.choose_target = forced


def measure(job: tuple) -> dict:
    """One seed: where the loop ended against the antinode and the clamp damper."""
    seed, forced = job
    import closed_loop_family as fam
    from threadpoolctl import threadpool_limits

    import powerline_control as plc

    if forced:
        _forced_response()
    with threadpool_limits(limits=1):
        scenario = fam.off_nominal(seed)
        args = scenario.run_arguments()
        wind = scenario.force if isinstance(scenario.force, plc.AeolianForce) \
            else scenario.force[0]
        balance = float(plc.aeolian_severity(scenario.span, [wind.wind_speed],
                                             bc=scenario.bc).amplitude[0])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")   # short runs warn that they have not settled
                result = plc.run_closed_loop(args.pop("span"), args.pop("force"),
                                             args.pop("robot"), args.pop("limits"),
                                             aeolian_steady=True, wind="self_limiting", **args)
        except plc.errors.PowerlineControlError as error:
            return dict(seed=seed, error=f"{type(error).__name__}: {error}")
    steady = result.aeolian_steady
    return dict(seed=seed, conductor=scenario.span.conductor.name,
                sustained=balance / scenario.span.conductor.diameter >= SUSTAINED,
                end=float(result.robot_position[-1]),
                antinode=float(steady.at_antinode.robot_position),
                over_antinode=steady.closed_loop.amplitude / steady.at_antinode.amplitude,
                over_clamp=steady.closed_loop.amplitude / steady.near_clamp.amplitude,
                over_start=1 / steady.start_reduction,
                decisions=[decision for _, decision in result.decisions])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", type=int)
    parser.add_argument("last", type=int)
    parser.add_argument("--forced-response", action="store_true")
    parser.add_argument("--json", help="write the rows to this file")
    options = parser.parse_args()
    import closed_loop_family as fam

    seeds = [seed for seed in range(options.first, options.last + 1, 2)
             if fam.CATEGORIES[(seed // 2) % len(fam.CATEGORIES)] == "real/aeolian"]
    print(_common.PINNED)
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(measure, [(seed, options.forced_response) for seed in seeds]))
    print("| seed | conductor | end, m | antinode, m | end/antinode | end/clamp damper | "
          "end/start |")
    print("|---|---|---|---|---|---|---|")
    for row in rows:
        if "error" in row:
            print(f"| {row['seed']} | error: {row['error'][:80]} | | | | | |")
            continue
        note = "" if row["sustained"] else " (not sustained)"
        print(f"| {row['seed']} | {row['conductor']}{note} | {row['end']:.2f} | "
              f"{row['antinode']:.2f} | {row['over_antinode']:.3f} | {row['over_clamp']:.3f} | "
              f"{row['over_start']:.3f} |")
    kept = sorted(row["over_antinode"] for row in rows if row.get("sustained"))
    if kept:
        rank = kept[min(len(kept) - 1, round(0.9 * (len(kept) - 1)))]
        print(f"\nsustained runs {len(kept)}: median {statistics.median(kept):.3f}, p90 (nearest "
              f"rank) {rank:.3f}, worst {kept[-1]:.3f}, within 1.5x "
              f"{sum(value <= 1.5 for value in kept)}/{len(kept)}, below the clamp damper "
              f"{sum(row['over_clamp'] < 1 for row in rows if row.get('sustained'))}/{len(kept)}, "
              f"above 1.05x the start "
              f"{sum(row['over_start'] > 1.05 for row in rows if row.get('sustained'))}/"
              f"{len(kept)}")
    if options.json:
        Path(options.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
