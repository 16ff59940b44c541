"""Benchmark: the self-limiting aeolian run against the fixed-lift simulation it replaces.

Per real span and wind speed, side by side in one process:

- ``simulate_aeolian``: the energy balance's own wind power and self-damping as amplitude-
  dependent modal damping, run until the amplitude settles (it simulates as long as the physics
  needs: hundreds of seconds at low wind);
- ``simulate`` with today's ``AeolianForce`` (a lift of fixed coefficient 0.3 on a line with
  0.05 % modal damping): the same span, the same simulated duration where that is affordable
  (capped at 60 s), sampled 16 times a period.

Columns: simulated seconds, CPU seconds, real-time factor (simulated / CPU, > 1 is faster than
real time), the self-limiting run's amplitude against the energy balance's, and the fixed lift's
RMS amplitude after its simulated time (it has no balance: it grows until its linear damping
holds it). CPU time from ``time.process_time``; nothing here depends on wall time.

Run: python benchmarks/bench_aeolian_run.py
BLAS is pinned to one thread (``_common`` is imported before numpy).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import time  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import numpy as np  # noqa: E402

import powerline_control as plc  # noqa: E402
from powerline_control.severity import simulate_aeolian  # noqa: E402

CASES = (("drake", 300.0, "pinned"), ("condor", 220.0, "clamped"),
         ("cardinal", 400.0, "clamped"))
WIND_SPEEDS = (1.0, 3.0, 6.0)
FIXED_LIFT_LIMIT = 60.0     # s simulated by the fixed-lift run at most (its cost grows with it)


def _fixed_lift(span, bc, wind_speed, duration):
    model = plc.LineModel(span, bc=bc, damping=plc.ModalDamping(0.0005))
    force = plc.AeolianForce(wind_speed=wind_speed)
    f = force.frequency_for(span.conductor)
    start = time.process_time()
    snap = plc.simulate(model, force, duration=duration, dt=1.0 / (16 * f))
    cpu = time.process_time() - start
    tail = snap.true_displacement[:, snap.t > duration - 1.0]
    return cpu, float(np.sqrt(2 * np.mean(tail**2, axis=1)).max())


def main():
    print(f"BLAS: {_common.PINNED}")
    print(f"{'span':28s} {'V':>4s} {'run s':>7s} {'cpu s':>7s} {'x real':>8s} "
          f"{'Y mm':>8s} {'EB mm':>8s} {'err %':>7s} | {'fixed s':>7s} {'cpu s':>7s} "
          f"{'x real':>8s} {'Y mm':>8s}")
    for name, length, bc in CASES:
        span = plc.Span.at_rts_fraction(length, name, 0.2)
        for speed in WIND_SPEEDS:
            start = time.process_time()
            run = simulate_aeolian(span, speed, bc=bc)
            cpu = time.process_time() - start
            simulated = float(run.t_envelope[-1])
            fixed_duration = min(simulated, FIXED_LIFT_LIMIT)
            fixed_cpu, fixed_amplitude = _fixed_lift(span, bc, speed, fixed_duration)
            print(f"{name} {length:g} m {bc:20s}"[:28] + f" {speed:4g} {simulated:7.0f} "
                  f"{cpu:7.2f} {simulated / cpu:8.0f} {1e3 * run.amplitude:8.3f} "
                  f"{1e3 * run.balance_amplitude:8.3f} {100 * run.relative_error:+7.2f} | "
                  f"{fixed_duration:7.0f} {fixed_cpu:7.2f} {fixed_duration / fixed_cpu:8.1f} "
                  f"{1e3 * fixed_amplitude:8.3f}", flush=True)


if __name__ == "__main__":
    main()
