"""The cost of the robot in the estimator's model: ``KalmanFilter.step`` of the closed loop's
filter with ``estimator="robot_input"`` (the bare line's modes, the load's oscillators and the
robot's force as an input) against today's ``"recipe"`` filter, on the same run.

Both filters are the ones ``run_closed_loop`` builds (kept by a hook on the loop), each stepped
on the run's own sensor record: one sample per call (``step``, with the robot's modal forces as
the input) and in the loop's 10-sample packets (``step_block``, which for a converged filter runs
the closed loop's modal form, ``estimate/_packet.py``). The issue's bound: at most 1.5x today's
cost per step. Both filters are timed in turn within each of the repeats (the shared machine's
load drifts between repeats): ``step`` as the median per sample, a packet as the minimum and
the median over the repeats, and the ratios of those and the median of the per-repeat ratios.
BLAS is pinned to one thread (``_common`` is imported before numpy). Results:
docs/validation/closed_loop.md (the estimator's cost).

Usage::

    .venv/bin/python benchmarks/bench_robot_input.py [seed ...]   # tests/closed_loop_family
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

import time  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import closed_loop_family as fam  # noqa: E402
import numpy as np  # noqa: E402

SAMPLES = 2000
PACKET = 10
REPEATS = 9


def captured(scenario, estimator):
    """The run's calibration (its filter) and records."""
    _, kept = _common.run_captured(scenario, estimator=estimator)
    return kept["calibration"], kept["records"]


def _timed(calibration, records):
    """One timing of step and of step_block per sample on the run's record after its
    calibration window: (step s, step_block s, states)."""
    kf, model = calibration.estimator.kf, calibration.estimator.input_model
    n_cal = calibration.record.shape[1]
    y = records.measured[:, n_cal : n_cal + SAMPLES]
    u = (None if model is None else
         model.inputs(records.position[n_cal - 1 : n_cal + SAMPLES],
                      records.robot_force[n_cal - 1 : n_cal + SAMPLES]))
    start = time.perf_counter()
    for k in range(y.shape[1]):
        kf.step(y[:, k]) if u is None else kf.step(y[:, k], u[:, k])
    step = (time.perf_counter() - start) / y.shape[1]
    start = time.perf_counter()
    for k in range(0, y.shape[1], PACKET):
        block = slice(k, k + PACKET)
        kf.step_block(y[:, block]) if u is None else kf.step_block(y[:, block], u[:, block])
    return step, (time.perf_counter() - start) / y.shape[1], kf.n_states


def per_sample(*runs):
    """Seconds per sample of step and of step_block for each run's filter, the runs timed in
    turn within each repeat (a shared machine's load drifts between repeats): per run, the
    medians of step and step_block, the minimum of step_block, its states, and the
    step_block time of each repeat (for the ratios within a repeat)."""
    timings = [[_timed(*run) for run in runs] for _ in range(REPEATS)]
    return [(float(np.median([t[i][0] for t in timings])),
             float(np.median([t[i][1] for t in timings])),
             float(np.min([t[i][1] for t in timings])), timings[0][i][2],
             np.array([t[i][1] for t in timings]))
            for i in range(len(runs))]


def main(seeds):
    print(_common.PINNED)
    print(f"step: per sample, median of {REPEATS} repeats; step_block: per {PACKET}-sample "
          "packet, min / median of the repeats, and the median of the per-repeat ratios")
    print(f"{'scenario':40s} {'n today':>7s} {'n robot':>7s} {'step us':>15s} {'ratio':>6s} "
          f"{'packet us (min / median)':>32s} {'ratio min/med/rep':>18s}")
    for seed in seeds:
        scenario = fam.scenario(seed)
        today, robot = per_sample(captured(scenario, "recipe"),
                                  captured(scenario, "robot_input"))
        us = 1e6 * PACKET
        print(f"{scenario.description[:40]:40s} {today[3]:7d} {robot[3]:7d} "
              f"{1e6 * today[0]:6.1f} -> {1e6 * robot[0]:6.1f} {robot[0] / today[0]:6.2f} "
              f"{us * today[2]:6.1f}/{us * today[1]:6.1f} -> {us * robot[2]:6.1f}/"
              f"{us * robot[1]:6.1f}   {robot[2] / today[2]:4.2f}/{robot[1] / today[1]:4.2f}/"
              f"{float(np.median(robot[4] / today[4])):4.2f}")


if __name__ == "__main__":
    main([int(s) for s in sys.argv[1:]] or [1, 3, 7])
