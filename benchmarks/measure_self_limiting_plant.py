"""The closed loop's plant in the self-limiting wind on real spans, without the robot, against
``severity.simulate_aeolian`` and the energy balance (docs/validation/closed_loop.md, "Real
spans without the robot").

Drake 300 m pinned, Condor 220 m clamped and Cardinal 400 m clamped at 20 % RTS on their physics
mesh (the spans of docs/validation/severity.md), winds 1-7 m/s: ``run_closed_loop(...,
wind="self_limiting")`` for 20 s with the robot held by limits of 1 um/s (four sensors), its
``comparison("no_robot").amplitude`` beside ``simulate_aeolian`` and ``aeolian_severity`` on the
same span. Prints a markdown table; two worker processes, BLAS on one thread (``_common``).
Usage::

    .venv/bin/python benchmarks/measure_self_limiting_plant.py
"""

import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402, F401  (pins BLAS to one thread before numpy loads)

SPANS = (("drake", 300.0, "pinned"), ("condor", 220.0, "clamped"), ("cardinal", 400.0, "clamped"))
WINDS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0)


def measure(case: tuple) -> dict:
    """One span and wind: the loop's no-robot amplitude, simulate_aeolian's and the balance's."""
    import powerline_control as plc
    from powerline_control.severity import aeolian_severity, simulate_aeolian

    conductor, length, bc, wind = case
    span = plc.Span.at_rts_fraction(length, conductor, 0.2)
    model = plc.LineModel(span, None, bc=bc)
    tone = plc.AeolianForce(wind).frequency_for(span.conductor)
    mode = max(1, round(span.length / float(span.loop_length(tone))))
    robot = plc.tune_damper(model, mode, None, wind, body_mass=5.0)
    n = model.n_nodes
    started = time.process_time()
    with warnings.catch_warnings():
        # the robot is held on purpose, and its parked line needs minutes to settle
        warnings.simplefilter("ignore")
        result = plc.run_closed_loop(model, plc.AeolianForce(wind), robot,
                                     plc.RobotLimits(1e-6, 1e-6),
                                     sensors=[n // 5, 2 * n // 5, 3 * n // 5 + 3, 4 * n // 5],
                                     duration=20.0, calibration=2.0, wind="self_limiting")
    cpu = time.process_time() - started
    bare = result.comparison("no_robot")
    return dict(span=f"{conductor} {length:g} m {bc}", wind=wind, loop=bare.amplitude,
                simulated=simulate_aeolian(span, wind, bc=bc).amplitude,
                balance=float(aeolian_severity(span, [wind], bc=bc).amplitude[0]),
                settled=not bare.transient, cpu=cpu)


def main() -> None:
    print(_common.PINNED)
    cases = [(*span, wind) for span in SPANS for wind in WINDS]
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(measure, cases))
    print("| span | V (m/s) | loop's plant, no robot (mm) | simulate_aeolian (mm) | balance (mm) "
          "| loop vs simulate_aeolian | loop vs balance | settled | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['span']} | {r['wind']:g} | {1e3 * r['loop']:.3f} | "
              f"{1e3 * r['simulated']:.3f} | {1e3 * r['balance']:.3f} | "
              f"{100 * (r['loop'] / r['simulated'] - 1):+.2f} % | "
              f"{100 * (r['loop'] / r['balance'] - 1):+.2f} % | "
              f"{'yes' if r['settled'] else 'no'} | {r['cpu']:.0f} |")
    worst = max(rows, key=lambda r: abs(r["loop"] / r["simulated"] - 1))
    print(f"\nworst against simulate_aeolian: {worst['span']} in {worst['wind']:g} m/s, "
          f"{100 * (worst['loop'] / worst['simulated'] - 1):+.2f} %")


if __name__ == "__main__":
    main()
