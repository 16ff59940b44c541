"""Benchmark: the closed loop's real-time factor against mesh size, and where the time goes.

Run: python benchmarks/bench_closed_loop.py [--quick]
BLAS is pinned to one thread (set in _common, before numpy loads): on this shared 2-core machine
multi-threaded BLAS was measured 15-50x slower under load. The real-time factor is simulated loop
time over wall-clock time at a 1 kHz line rate (dt = 1 ms) with a 20 Hz control rate; the CPU
column is the process time of the same run (less sensitive to other users of the machine).

Before this plant (issue 10): every 1 cm move re-solved all modes of the FE line with the robot,
real-time factor 0.42 at 100 elements and 0.011 at 400 (measured there, same machine).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse  # noqa: E402
import time  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import numpy as np  # noqa: E402

import powerline_control as plc  # noqa: E402


def lab_case(n_elements: int, duration: float):
    span = plc.Span.paper_lab()
    bare = plc.LineModel(span, n_elements)
    f4 = bare.natural_frequencies(4)[3]
    tuned = plc.tune_damper(bare, 4, span.length / 8, 0.04, body_mass=0.03)
    robot = plc.MDR(span.length / 4, tuned.body_mass, tuned.suspended_mass, tuned.stiffness,
                    tuned.damping)
    sensors = [int(round(n_elements * q)) for q in (0.17, 0.41, 0.77)]
    return dict(span=span, force=plc.HarmonicForce(1.0, 1.006 * f4, 0.43 * span.length),
                robot=robot, sensors=sensors, n_elements=n_elements, duration=duration,
                damping=plc.ModalDamping(0.003))


def drake_case(n_elements: int, duration: float):
    # ACSR Drake, 300 m at 20 % RTS, driven near a mode about 10 Hz (loops ~6.6 m).
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    bare = plc.LineModel(span, n_elements)
    freqs = bare.natural_frequencies(120)
    mode = int(np.argmin(np.abs(freqs - 10.0))) + 1
    loop = span.length / mode
    tuned = plc.tune_damper(bare, mode, 2.5 * loop, 1.0, body_mass=2.0)
    robot = plc.MDR(2 * loop, tuned.body_mass, tuned.suspended_mass, tuned.stiffness,
                    tuned.damping)
    sensors = [int(round(n_elements * q)) for q in (0.013, 0.021, 0.034)]
    return dict(span=span, force=plc.HarmonicForce(50.0, 1.002 * freqs[mode - 1], 3.3 * loop),
                robot=robot, sensors=sensors, n_elements=n_elements, duration=duration,
                damping=plc.ModalDamping(0.003), n_modes=min(2 * mode, 3 * n_elements))


def measure(case):
    args = dict(case)
    span, force, robot = args.pop("span"), args.pop("force"), args.pop("robot")
    cpu = time.process_time()
    wall = time.perf_counter()
    result = plc.run_closed_loop(span, force, robot, calibration=2.0, seed=1, **args)
    return result, time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs, fewer sizes")
    options = parser.parse_args()
    print(_common.PINNED)
    duration = 6.0 if options.quick else 12.0
    cases = [(f"lab span, {n} el", lab_case(n, duration)) for n in
             ((100,) if options.quick else (100, 200, 400))]
    if not options.quick:
        cases.append(("Drake 300 m, 1000 el", drake_case(1000, 6.0)))
    header = (f"{'case':24s} {'modes':>5s} {'RTF':>6s} {'RTFcpu':>6s} {'loop s':>7s} "
              f"{'total s':>8s} {'cpu s':>7s}  where the loop's time goes")
    print(header)
    print("-" * len(header))
    for name, case in cases:
        result, wall, cpu = measure(case)
        timings = result.timings
        loop = result.wall_time
        share = ", ".join(
            f"{key} {100 * timings[key] / loop:.0f} %"
            for key in ("plant", "plant update", "filter", "policy and motion")
        )
        modes = case.get("n_modes") or "auto"
        simulated = result.t[-1] - result.calibration_time
        rtf_cpu = simulated / timings["loop cpu"]
        print(f"{name:24s} {modes!s:>5s} {result.real_time_factor:6.1f} {rtf_cpu:6.1f} "
              f"{loop:7.2f} {wall:8.2f} "
              f"{cpu:7.2f}  {share}; setup {timings['setup']:.2f} s, comparisons "
              f"{timings['comparisons']:.2f} s")


if __name__ == "__main__":
    main()
