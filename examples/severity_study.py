"""Aeolian severity of a Drake span and what the damping robot is worth.

1. Energy balance (CIGRE wind power, Noiseux 1991 self-damping with dohl's k) for a 300 m Drake
   span at 20 % RTS, 1-7 m/s: antinode amplitude and clamp strain with no damper, with the robot's
   damper parked at the harmonic-mean position x*, and with the robot at the antinode.
2. Over a Weibull wind climate (k = 2, c = 4 m/s): the fraction of time over the 150 microstrain
   endurance strain and the Miner's-rule damage per year of each configuration; the robot needs
   time to reach each new antinode (RobotLimits) and counts as undamped until it arrives.
3. The CIGRE TB 273 H/w check, and the time-domain check of the energy balance on a short span.

Run: python examples/severity_study.py OUTPUT_FOLDER   (writes severity_study.png there; 5 s
on 2 cores at load average 6)
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np

import powerline_control as plc
from powerline_control.output.plotting import plot_robot_value, plot_severity


def main(output: pathlib.Path) -> dict:
    output.mkdir(parents=True, exist_ok=True)
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    speeds = np.arange(1.0, 7.5, 0.5)
    # A robot of 6 kg body with a 1.5 kg absorber tuned to 15 Hz (mid band), 30 % damping ratio.
    robot = plc.MDR.tuned(0.0, body_mass=6.0, suspended_mass=1.5, frequency=15.0,
                          damping_ratio=0.3)
    limits = plc.RobotLimits(v_max=0.3, a_max=0.5)
    value = plc.severity.robot_value(span, robot, limits, speeds,
                            distribution=plc.severity.WindDistribution.weibull(shape=2.0,
                                                                               scale=4.0),
                            persistence=600.0)

    print(f"Drake, 300 m, {span.tension / 1e3:.2f} kN (20 % RTS); fixed damper at "
          f"x* = {value.fixed_position:.3f} m from the clamp")
    print(" V (m/s)  f (Hz)  loop (m) | amplitude mm: none / fixed / robot | strain ue pk-pk: "
          "none / fixed / robot")
    none, fixed, at_antinode = value.severities
    for i, v in enumerate(speeds):
        print(f"  {v:5.1f}  {none.frequency[i]:6.2f}  {none.loop_length[i]:7.3f}  |  "
              f"{none.amplitude[i] * 1e3:6.2f} {fixed.amplitude[i] * 1e3:6.2f} "
              f"{at_antinode.amplitude[i] * 1e3:6.2f}  |  {none.strain_pp[i] * 1e6:6.0f} "
              f"{fixed.strain_pp[i] * 1e6:6.0f} {at_antinode.strain_pp[i] * 1e6:6.0f}")
    print("Over the wind climate (Weibull k = 2, c = 4 m/s; robot counted undamped while it "
          "moves):")
    for row in value.table():
        print(f"  {row['configuration']:<20s} time over 150 ue: "
              f"{100 * row['fraction_over_endurance']:5.1f} %   Miner damage/year: "
              f"{row['fatigue_index_per_year']:.3g}")
    check = plc.severity.catenary_check(span)
    print(f"TB 273: H/w = {check.catenary_parameter:.0f} m against {check.limit:.0f} m "
          f"({check.source}) -> {'within' if check.within_limit else 'over'} the limit")
    short = plc.Span.at_rts_fraction(30.0, "drake", 0.20)
    td = plc.severity.time_domain_check(short, 2.0, n_elements=60)
    print(f"Time-domain check (Drake 30 m, mode {td.mode}, {td.wind_speed:.3f} m/s): EBM "
          f"{td.ebm_amplitude * 1e3:.3f} mm, simulated {td.simulated_amplitude * 1e3:.3f} mm "
          f"({100 * td.relative_error:+.2f} %), zeta_eq {td.damping_ratio:.2e}, "
          f"C_L {td.lift_coefficient:.2f}")

    fig = plot_severity(value.severities)
    fig.savefig(output / "severity_study.png", dpi=120)
    plot_robot_value(value).savefig(output / "severity_robot_value.png", dpi=120)
    print(f"Figures written to {output}")
    return {"value": value, "time_domain": td, "catenary": check}


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python examples/severity_study.py OUTPUT_FOLDER")
    main(pathlib.Path(sys.argv[1]))
