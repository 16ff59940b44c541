"""Design study: for each wind speed, which mode locks in, where its antinodes are, and how long
the robot needs to get from its parking spot to the nearest one.

Run: python examples/wind_speed_study.py [out_dir] [--workers N]   (default out/; 3 s on 2
cores at load average 6; writes wind_speed_study.csv and wind_speed_study.json)

Uses a process pool through powerline_control.studies (any concurrent.futures executor works,
Dask's included).
"""

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import powerline_control as plc
from powerline_control.excitation import strouhal_frequency

SPAN = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
PARKING = 20.0          # m from the left clamp
LIMITS = plc.RobotLimits(v_max=0.5, a_max=0.5)


def robot_travel(wind_speed: float) -> dict:
    """Lock-in mode, nearest antinode to the parking spot and the minimum-time move to it."""
    frequency = strouhal_frequency(wind_speed, SPAN.conductor.diameter)
    # A 300 m span is string-like (bending adds < 0.5 % up to mode 200): use the closed form
    # for the mode number, and the mode's antinodes (2k - 1) L / 2n.
    closed_form = SPAN.pinned_frequencies(400)
    mode = int(np.argmin(np.abs(closed_form - frequency))) + 1
    antinodes = (2 * np.arange(1, mode + 1) - 1) * SPAN.length / (2 * mode)
    target = float(antinodes[np.argmin(np.abs(antinodes - PARKING))])
    plan = plc.plan_motion(PARKING, target, LIMITS, span_length=SPAN.length)
    return {"frequency_hz": frequency, "mode": mode, "loop_length_m": SPAN.length / mode,
            "target_m": target, "travel_m": abs(target - PARKING), "move_time_s": plan.duration}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", nargs="?", default="out", type=Path,
                        help="output folder (default: ./out)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    arguments = parser.parse_args()
    out = arguments.out
    out.mkdir(parents=True, exist_ok=True)
    grid = plc.parameter_grid(wind_speed=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    with ProcessPoolExecutor(max_workers=arguments.workers) as pool:
        study = plc.run_study(robot_travel, grid, pool, description="wind speeds")
    print("V (m/s)  f (Hz)  mode  loop (m)  target (m)  move (s)")
    for row in study.rows():
        print(f"{row['wind_speed']:7.1f} {row['frequency_hz']:7.2f} {row['mode']:5d} "
              f"{row['loop_length_m']:9.2f} {row['target_m']:11.2f} {row['move_time_s']:9.2f}")
    print(f"table: {study.to_csv(out / 'wind_speed_study.csv')}, "
          f"{study.to_json(out / 'wind_speed_study.json')}")
