"""The whole chain in closed loop on the paper's span: three sensors, the robot's own motion,
the robot-free excited shape, the predicted best parked position, the move, and the vibration
against the robot parked elsewhere (no robot, near a clamp, at its start, at the best position).

Then a wind change: the load's frequency steps from near mode 4 to near mode 3, the best
position moves, and the robot follows and settles again.

Run: python examples/closed_loop.py [out_dir]      (writes four PNG figures; 10 s on 2 cores
at load average 6)
"""

import sys
from pathlib import Path

import numpy as np

import powerline_control as plc
from powerline_control.output.plotting import (
    plot_closed_loop,
    plot_closed_loop_envelope,
    plot_closed_loop_path,
)

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out")
out.mkdir(parents=True, exist_ok=True)

span = plc.Span.paper_lab()
bare = plc.LineModel(span, 100)
f = bare.natural_frequencies(4)
# 0.03 kg body + 0.04 kg absorber, tuned (Den Hartog) to mode 4 at its first antinode, L/8; the
# robot starts at L/4, a node of mode 4, where the absorber does nothing to it.
tuned = plc.tune_damper(bare, mode=4, position=span.length / 8, mass=0.04, body_mass=0.03)
robot = plc.MDR(span.length / 4, tuned.body_mass, tuned.suspended_mass, tuned.stiffness,
                tuned.damping)
line_damping = plc.ModalDamping(0.003)
force = plc.HarmonicForce(1.0, 1.006 * f[3], 0.43 * span.length)
result = plc.run_closed_loop(span, force, robot, plc.RobotLimits(v_max=0.5, a_max=1.0),
                             sensors=[17, 41, 77], damping=line_damping, duration=12.0,
                             calibration=2.0, seed=3)
print(f"driven at {force.frequency:.2f} Hz (mode 4: {f[3]:.2f} Hz); absorber k = "
      f"{tuned.stiffness:.0f} N/m, c = {tuned.damping:.2f} N s/m")
print(f"robot: {robot.position:.3f} m -> {result.robot_position[-1]:.3f} m "
      f"(best parked: {result.best_position:.3f} m; settled after "
      f"{result.settle_times[0]:.2f} s)")
print(result.summary())
start, best = result.comparison("start"), result.comparison("best")
print(f"closed loop / best parked: {result.rms_closed_loop / best.rms:.3f}; "
      f"start / closed loop: {result.vibration_reduction:.1f}x")
last = result.t >= result.t[-1] - 3.0
print(f"position range over the last 3 s: {1e3 * np.ptp(result.robot_position[last]):.2f} mm "
      f"({100 * np.ptp(result.robot_position[last]) / result.loop_length:.2f} % of a loop)")
print(f"real-time factor {result.real_time_factor:.1f}; estimator innovation ratio (median) "
      f"{np.median(result.innovation_ratio):.2f}")
plot_closed_loop(result).savefig(out / "closed_loop.png", dpi=110)
plot_closed_loop_envelope(result).savefig(out / "closed_loop_envelope.png", dpi=110)
plot_closed_loop_path(result).savefig(out / "closed_loop_path.png", dpi=110)

# --- the wind change: near mode 4, then (at 8 s) near mode 3
schedule = [(0.0, force), (8.0, plc.HarmonicForce(1.0, 1.008 * f[2], 0.43 * span.length))]
wind = plc.run_closed_loop(span, schedule, robot, sensors=[17, 41, 77], damping=line_damping,
                           duration=18.0, calibration=2.0, seed=4)
before = (wind.t >= 7.0) & (wind.t < 8.0)
just_after = (wind.t >= 8.0) & (wind.t < 9.0)
final = wind.t >= wind.t[-1] - 2.0
rms = {name: 1e3 * np.sqrt(np.mean(wind.displacement[:, m] ** 2))
       for name, m in (("before", before), ("after", just_after), ("final", final))}
print(f"wind change at 8 s: retargeted at {wind.retarget_times[-1]:.2f} s, settled "
      f"{wind.settle_times[-1]:.2f} s later ({wind.follow_times[0]:.2f} s after the change) at "
      f"{wind.robot_position[-1]:.3f} m (best "
      f"{wind.best_position:.3f} m); RMS {rms['before']:.3f} -> {rms['after']:.3f} -> "
      f"{rms['final']:.3f} mm")
plot_closed_loop_path(wind).savefig(out / "closed_loop_wind_change.png", dpi=110)
print(f"figures: {out}/closed_loop*.png")
