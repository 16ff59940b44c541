"""Fatigue life of a Drake span over a wind record, and what the robot is worth.

Reads the shipped synthetic record examples/data/wind_record_28d.csv (four weeks of 10-minute
means, made by examples/make_wind_record.py with seed 2026) and, for a 300 m Drake ruling span at
20 % RTS at 15 degC on a north-south line:

1. tension per record from the change of state at the air temperature, wind normal to the line,
   turbulence per record; the energy balance, clamp strain and Miner damage on the safe border
   line for no damper, the robot's damper fixed at its best position for the record (searched
   around the harmonic-mean x*), and the robot moving to the nearest
   antinode whenever the loop pattern changes (6 kg body, 1.5 kg absorber at 15 Hz, zeta 0.3;
   v_max 0.3 m/s, a_max 0.5 m/s^2);
2. how the robot's life changes with its speed limit;
3. the figure (plotting.plot_fatigue_record): damage by wind speed, and the robot's positions
   over the first week.

Run: python examples/wind_record_fatigue.py OUTPUT_FOLDER   (36 s on 2 cores at load average 6;
writes wind_record_fatigue.png there)
"""

from __future__ import annotations

import pathlib
import sys

import powerline_control as plc
from powerline_control.output.plotting import plot_fatigue_record

RECORD = pathlib.Path(__file__).resolve().parent / "data" / "wind_record_28d.csv"
SPEED_LIMITS = (0.003, 0.01, 0.03, 0.1, 0.3, 1.0)


def main(output: pathlib.Path) -> dict:
    output.mkdir(parents=True, exist_ok=True)
    record = plc.WindRecord.from_csv(RECORD)
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    robot = plc.MDR.tuned(0.0, body_mass=6.0, suspended_mass=1.5, frequency=15.0,
                          damping_ratio=0.3)
    limits = plc.RobotLimits(v_max=0.3, a_max=0.5)
    # the fixed damper at its best position for this record (13 candidates around x*)
    life = plc.fatigue_over_record(span, record, robot, limits, line_azimuth=0.0,
                                   fixed_position="best")
    print(f"Record: {record.n_records} x {record.step:g} s; tension "
          f"{life.tension.min() / 1e3:.2f}-{life.tension.max() / 1e3:.2f} kN over "
          f"{record.temperature.min():.1f}-{record.temperature.max():.1f} degC")
    print(life.summary())
    search = life.parameters["fixed_search"]
    x_star = life.parameters["harmonic_mean_position"]
    print(f"Fixed damper life against its position (x* = {x_star:.3f} m, the harmonic-mean "
          "rule for the record's band):")
    for x, damage in zip(search["positions"], search["damages"], strict=True):
        mark = "  <- best" if x == life.fixed_position else ("  <- x*" if x == x_star else "")
        print(f"  {x:6.3f} m   life {life.years / damage:9.3g} years{mark}")

    print("Robot's life against its speed limit (a_max 0.5 m/s^2):")
    print("  v_max (m/s)  mean move time per record (s)  damage/year  life (years)")
    sweep = {}
    for v_max in SPEED_LIMITS:
        other = life.with_limits(plc.RobotLimits(v_max=v_max, a_max=0.5))
        sweep[v_max] = other["robot"].life_years
        print(f"  {v_max:10.3f}  {other.move_time[other.vibrating].mean():29.1f}  "
              f"{other['robot'].damage_per_year:11.3g}  {other['robot'].life_years:12.3g}")

    # Damage by normal wind speed (0.5 m/s bins) per configuration, and the robot's positions
    # over the first week: the package's figure (the report of `powerline-control severity
    # --wind-record` draws the same one).
    fig = plot_fatigue_record(life)
    fig.savefig(output / "wind_record_fatigue.png", dpi=110)
    return {"life": {name: life[name].life_years for name in life}, "speed_limit": sweep}


if __name__ == "__main__":
    main(pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else pathlib.Path("."))
