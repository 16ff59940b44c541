"""The energy balance's damper power against ``simulate_aeolian`` with a robot parked at an
antinode, first order and with the damper's reaction on an infinite string
(docs/validation/severity.md, "A damper's reaction on an infinite string").

The corrected power is the first-order one times 1 / |1 + Z / (2 sqrt(T m))|^2, applied here as
an ``ImpedanceDamper`` whose resistance is Re Z times that factor at each frequency of a table
around the tone (the balance reads only Re Z). 3 m/s, the robot tuned by ``tune_damper`` to the
locked mode at one of its antinodes. Prints a markdown table; BLAS on one thread (``_common``).

Usage::

    .venv/bin/python benchmarks/measure_damper_reaction.py
"""

import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import numpy as np  # noqa: E402
from bench_coupled_balance import CASES, WIND, tuned_robot  # noqa: E402

from powerline_control.fem.damper import ImpedanceDamper, damper_impedance  # noqa: E402
from powerline_control.severity import aeolian_severity, simulate_aeolian  # noqa: E402


def measure(case: tuple) -> tuple:
    """One span and robot: simulated amplitude, first-order and corrected balance, |Z|/Z0."""
    span, bc, robot = tuned_robot(case)
    run = simulate_aeolian(span, WIND, robot, bc=bc)
    wave = np.sqrt(span.tension * span.conductor.mass_per_length)
    frequencies = np.linspace(0.5, 1.5, 201) * run.frequency
    impedance = np.array([damper_impedance(robot, f) for f in frequencies])
    reaction = 1.0 / np.abs(1.0 + impedance / (2.0 * wave)) ** 2
    corrected = ImpedanceDamper(robot.position, list(frequencies),
                                list(impedance.real * reaction))
    first = float(aeolian_severity(span, [WIND], [robot], bc=bc).amplitude[0])
    second = float(aeolian_severity(span, [WIND], [corrected], bc=bc).amplitude[0])
    ratio = abs(damper_impedance(robot, run.frequency)) / wave
    return case, run.amplitude, first, second, ratio


def main() -> None:
    print(_common.PINNED)
    print("| span | robot (absorber + body) | \\|Z\\| / sqrt(T m) | simulated, mm "
          "| first order, mm | corrected, mm | simulated / first order | simulated / corrected |")
    print("|---|---|---|---|---|---|---|---|")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the balance's amplitudes lie below the curves' data
        for case, simulated, first, second, ratio in map(measure, CASES):
            conductor, length, bc, _, absorber, body = case
            print(f"| {conductor.capitalize()} {length:g} m {bc} | {absorber:g} + {body:g} kg | "
                  f"{ratio:.1f} | {simulated * 1e3:.3f} | {first * 1e3:.3f} | {second * 1e3:.3f} "
                  f"| {simulated / first:.2f} | {simulated / second:.2f} |")


if __name__ == "__main__":
    main()
