"""Benchmark: detection and false-alarm rates of the estimator's consistency test (issue 19).

The family is ``tests/estimator_family.py`` (lab span and real spans of every shape there,
pinned and clamped; even seeds tune the spectral test's constants, odd seeds are held out). For
each split: mismatched runs that warn (``EstimatorInconsistentWarning``; all of them, and those
visible at the sensors, ``estimator_family.VISIBLE_SNR``), matched runs that warn (from rest, and
with ``--steady`` the steady runs),
the reported / actual sigma at unmeasured nodes on matched runs (all; lab and real spans; runs
whose actual error is under 10 %, i.e. an adequate model; with ``--steady`` also one matched run
per design judged once the line has rung up), and the coverage check's share of power outside
the training band. Targets: >= 95 % detection, <= 5 % false alarms, reported / actual within
a factor 1.5.

Run: python benchmarks/bench_detection.py [--designs N] [--split tune|held_out|both] [--steady]
BLAS is pinned to one thread (``_common`` is imported before numpy), as on the other benchmarks.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

import argparse  # noqa: E402

import _common  # noqa: E402, F401  (pins BLAS to one thread before numpy loads)
import estimator_family as family  # noqa: E402
import numpy as np  # noqa: E402


def calibration(label: str, runs) -> None:
    """Median, range and share within a factor 1.5 of reported / actual sigma over ``runs``."""
    ratio = np.array([r.reported_over_actual for r in runs])
    if ratio.size == 0:
        return
    within = int(np.sum((ratio > 1 / 1.5) & (ratio < 1.5)))
    print(f"  reported/actual sigma, {label} ({ratio.size}): median {np.median(ratio):.2f}, "
          f"range {ratio.min():.2f}-{ratio.max():.2f}, {within}/{ratio.size} within 1.5x")


def table(split: str, n_designs: int, steady: bool = False) -> None:
    first = 0 if split == "tune" else 1
    runs = []
    for seed in range(first, first + 2 * n_designs, 2):
        runs += family.runs_of(seed, steady=steady)
    print(f"\n{split}: seeds {first}..{first + 2 * n_designs - 2} step 2, {n_designs} designs")
    print(f"{'case':22s} {'seed':>4s} {'run':9s} {'warn':5s} {'NIS ok':6s} {'max ratio':>9s} "
          f"{'outside':>7s} {'error':>6s} {'rep/act':>7s} {'SNR':>6s}")
    for r in runs:
        print(f"{r.case:22s} {r.seed:4d} {r.kind:9s} {str(r.warned):5s} {str(r.nis_ok):6s} "
              f"{r.max_ratio:9.3g} {r.outside_share:7.3f} {r.error:6.3f} "
              f"{r.reported_over_actual:7.2f} {r.sensor_snr:6.3g}")
    rates = family.rates(runs)
    print(f"detected {rates['detected']}/{rates['n_mismatched']} (raw), "
          f"{rates['detected_visible']}/{rates['n_visible']} of the mismatches visible at the "
          f"sensors (SNR >= {family.VISIBLE_SNR:g}); false alarms "
          f"{rates['false_alarms']}/{rates['n_matched']} from rest"
          + (f", {rates['steady_false_alarms']}/{rates['n_steady']} steady" if rates['n_steady']
             else "") + "; reported/actual sigma on matched runs "
          f"median {rates['calibration_median']:.2f}, range {rates['calibration_range'][0]:.2f}-"
          f"{rates['calibration_range'][1]:.2f}")
    matched = [r for r in runs if r.kind == "matched"]
    calibration("matched, lab span", [r for r in matched if r.case.startswith("lab")])
    calibration("matched, real spans", [r for r in matched if not r.case.startswith("lab")])
    calibration("matched, actual error < 10 % (adequate model)",
                [r for r in matched if r.error < 0.1])
    calibration("matched, actual error >= 10 %", [r for r in matched if r.error >= 0.1])
    calibration("steady (last third of a 3x longer matched run)",
                [r for r in runs if r.kind == "steady"])
    runs = [r for r in runs if r.kind != "steady"]
    missed = [r for r in runs if r.kind != "matched" and not r.warned]
    if missed:
        print("missed: " + ", ".join(f"{r.case} seed {r.seed} {r.kind} (SNR {r.sensor_snr:.2g}, "
                                     f"reported/actual sigma {r.reported_over_actual:.2f})"
                                     for r in missed))
    hidden = [r for r in runs if r.kind != "matched" and r.reported_over_actual < 1 / 1.5]
    print(f"mismatched runs whose actual error exceeds 1.5 x the reported sigma (wrong without "
          f"the sigma saying so): {sum(r.warned for r in hidden)}/{len(hidden)} warn")
    share = np.array([r.outside_share for r in runs if r.kind != "matched"])
    print(f"coverage check: {int(np.sum(share > 0.05))}/{share.size} mismatched and "
          f"{sum(r.outside_share > 0.05 for r in runs if r.kind == 'matched')}/"
          f"{rates['n_matched']} matched runs above 5 % of their power outside the band")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", type=int, default=24, help="designs per split")
    parser.add_argument("--split", default="both", choices=("tune", "held_out", "both"))
    parser.add_argument("--steady", action="store_true",
                        help="one more matched run per design, judged once rung up")
    args = parser.parse_args()
    for split in (("tune", "held_out") if args.split == "both" else (args.split,)):
        table(split, args.designs, args.steady)


if __name__ == "__main__":
    main()
