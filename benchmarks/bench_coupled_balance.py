"""The energy balance with the robot coupled to the line (``coupled_balance``) against the
time-domain run that settles by the same powers (``simulate_aeolian``) and the first-order damper
power (``aeolian_severity``): amplitudes side by side and the two computations' CPU seconds.

3 m/s, the robot tuned by ``tune_damper`` to the locked mode and parked at one of its antinodes
(docs/validation/severity.md). BLAS on one thread (``_common``). Prints a markdown table.

A second table (``--speeds``) runs the severity table's seven wind speeds on three real spans
with the drake-300m scenario's robot (3 + 5 kg, tuned at 3 m/s), parked at the antinode of each
speed's locked mode nearest tune_damper's antinode (``AtAntinode``), and with no robot.

Usage::

    .venv/bin/python benchmarks/bench_coupled_balance.py [--speeds]
"""

import dataclasses
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)

import powerline_control as plc  # noqa: E402
from powerline_control.fem import AtAntinode  # noqa: E402
from powerline_control.severity import coupled_balance, simulate_aeolian  # noqa: E402

WIND = 3.0
#: (conductor, length, supports, mode or None for the locked one at tune_damper's position,
#: absorber kg, body kg)
CASES = (("drake", 300.0, "pinned", None, 3.0, 5.0), ("drake", 300.0, "pinned", None, 0.3, 0.5),
         ("condor", 220.0, "clamped", None, 3.0, 5.0), ("condor", 220.0, "clamped", None, 0.3, 0.5),
         ("drake", 60.0, "clamped", 18, 3.0, 5.0), ("drake", 60.0, "clamped", 18, 0.3, 0.5),
         ("cardinal", 80.0, "pinned", 18, 1.0, 1.0))


def tuned_robot(case: tuple) -> tuple:
    """One case's span, supports and robot: tuned by ``tune_damper`` to the mode locked at
    3 m/s (or the case's mode) at one of its antinodes."""
    conductor, length, bc, mode, absorber, body = case
    span = plc.Span.at_rts_fraction(length, conductor, 0.2)
    model = plc.LineModel(span, bc=bc)
    if mode is None:
        tone = plc.AeolianForce(WIND).frequency_for(span.conductor)
        mode, position = round(length / float(span.loop_length(tone))), None
    else:
        position = (mode // 3 + 0.5) * length / mode
    return span, bc, plc.tune_damper(model, mode, position, absorber, body_mass=body)


def measure(case: tuple) -> tuple:
    """One span and robot: the run, the coupled balance, and each one's CPU seconds."""
    span, bc, robot = tuned_robot(case)
    start = time.process_time()
    run = simulate_aeolian(span, WIND, robot, bc=bc)
    middle = time.process_time()
    balance = coupled_balance(span, WIND, robot, bc=bc)
    return case, run, balance, middle - start, time.process_time() - middle


#: The severity table's spans: (conductor, length, supports).
SPANS = (("drake", 300.0, "pinned"), ("condor", 220.0, "clamped"), ("cardinal", 400.0, "clamped"))


def speeds_table() -> None:
    """Every wind speed 1-7 m/s on three spans, no robot and the robot at the antinode."""
    print("| span | V (m/s) | robot | simulated, mm | coupled, mm | first order, mm "
          "| coupled / simulated | settled |")
    print("|---|---|---|---|---|---|---|---|")
    worst = 0.0
    for conductor, length, bc in SPANS:
        span = plc.Span.at_rts_fraction(length, conductor, 0.2)
        model = plc.LineModel(span, bc=bc)
        tone = plc.AeolianForce(WIND).frequency_for(span.conductor)
        robot = plc.tune_damper(model, round(length / float(span.loop_length(tone))),
                                None, 3.0, body_mass=5.0)
        for speed in range(1, 8):
            for with_robot in (False, True):
                balance = coupled_balance(span, speed, AtAntinode(robot) if with_robot else None,
                                          bc=bc)
                parked = (dataclasses.replace(robot, position=balance.robot_position)
                          if with_robot else None)
                run = simulate_aeolian(span, speed, parked, bc=bc)
                ratio = balance.amplitude / run.amplitude
                worst = max(worst, abs(ratio - 1))
                print(f"| {conductor.capitalize()} {length:g} m {bc} | {speed} | "
                      f"{'at antinode' if with_robot else 'none'} | {run.amplitude * 1e3:.3f} | "
                      f"{balance.amplitude * 1e3:.3f} | "
                      f"{balance.first_order_amplitude * 1e3:.3f} | {ratio:.3f} | "
                      f"{run.settled} |", flush=True)
    print(f"\nworst |coupled / simulated - 1|: {100 * worst:.2f} %")


def main() -> None:
    print(_common.PINNED)
    if "--speeds" in sys.argv[1:]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            speeds_table()
        return
    print("| span | robot (absorber + body) | \\|Z\\| / sqrt(T m) | simulated, mm | coupled, mm "
          "| first order, mm | coupled / simulated | first order / simulated | CPU s: run "
          "| CPU s: coupled | run / coupled |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the amplitudes lie below the curves' data
        for case, run, balance, t_run, t_coupled in map(measure, CASES):
            conductor, length, bc, _, absorber, body = case
            print(f"| {conductor.capitalize()} {length:g} m {bc} | {absorber:g} + {body:g} kg | "
                  f"{balance.robot_impedance_ratio:.1f} | {run.amplitude * 1e3:.3f} | "
                  f"{balance.amplitude * 1e3:.3f} | {balance.first_order_amplitude * 1e3:.3f} | "
                  f"{balance.amplitude / run.amplitude:.3f} | "
                  f"{balance.first_order_amplitude / run.amplitude:.3f} | {t_run:.2f} | "
                  f"{t_coupled:.2f} | {t_run / t_coupled:.1f} |")


if __name__ == "__main__":
    main()
