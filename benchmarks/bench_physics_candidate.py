"""Benchmark: the recipe's physics candidate on real spans in aeolian lock-in.

Per case and seed (``tests/lockin_family.py``: Oxlip 220 m pinned and Condor 180 m clamped at
20 % RTS, the truth's tension off the nominal by up to +-4 %, a wind locked in near mode 30-60,
0.1-0.4 % modal damping), ``design_estimator`` with 5 sensors on 20 s of the wind from rest, twice:
today's recipe (no nominal) and the recipe told the nominal span (``nominal=``, ``bc=``: the
physics candidate beside DMD and the oscillator model). Each design filters the same wind 1 %
faster, 10 s from rest; the table gives the family chosen, the held-out error it was chosen on,
the RMS error at the unmeasured moving nodes over the RMS field there, and the reported over the
actual sigma there (truth: the noise-free simulation), after the first 500 samples.

Run: python benchmarks/bench_physics_candidate.py [n_seeds] [first]   (default 3 seeds from 1)
BLAS is pinned to one thread (``_common`` is imported before numpy). Nothing depends on wall time.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

import warnings  # noqa: E402

import _common  # noqa: E402,F401  (pins BLAS to one thread before numpy loads)
import lockin_family as family  # noqa: E402
import numpy as np  # noqa: E402

import powerline_control as plc  # noqa: E402
from powerline_control.errors import ExcitationWarning  # noqa: E402


def main(n_seeds: int = 3, first: int = 1) -> None:
    print("| case | seed | tension off | recipe | chosen | held-out | error | sigma/actual |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for seed in range(first, first + n_seeds):
        for name in family.CASES:
            nominal, bc, model, wind = family.draw(name, seed)
            train, test = family.records(model, wind, seed)
            off = model.span.tension / nominal.tension - 1
            for label, told in (("today", {}), ("with nominal", {"nominal": nominal, "bc": bc})):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", ExcitationWarning)
                    design = plc.design_estimator(train, n_sensors=5, seed=0, **told)
                error, ratio = family.judge(design, test)
                held = np.asarray(design.alpha_sweep.held_out_error)
                held_text = f"{np.nanmin(held):.2%}" if held.size else "-"
                rows.append((label, error, ratio))
                print(f"| {name} | {seed} | {off:+.2%} | {label} | {design.excitation.method} | "
                      f"{held_text} | {error:.2%} | {ratio:.2f} |", flush=True)
    for label in ("today", "with nominal"):
        errors = [e for lab, e, _ in rows if lab == label]
        ratios = [r for lab, _, r in rows if lab == label]
        print(f"{label}: error median {np.median(errors):.2%} (max {np.max(errors):.2%}), "
              f"sigma/actual median {np.median(ratios):.2f} "
              f"({np.min(ratios):.2f}-{np.max(ratios):.2f})")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
