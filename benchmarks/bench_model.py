"""Benchmark: FE assembly + modal analysis, and simulation, against scipy / python-control peers.

Run: python benchmarks/bench_model.py [--quick]
BLAS is pinned to one thread (set below, before numpy loads): on this shared 2-core machine
multi-threaded BLAS was measured 15-50x slower under load.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import control as ct  # noqa: E402
import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402
from _common import timed  # noqa: E402

import powerline_control as plc  # noqa: E402


def modal_rows(sizes, repeats):
    rows = []
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    for n_el in sizes:
        ours_t, freqs = timed(
            lambda n=n_el: plc.LineModel(span, n).natural_frequencies(50), repeats
        )
        model = plc.LineModel(span, n_el)
        if model.n_dofs <= 2000:
            k, m = model.stiffness_matrix.toarray(), model.mass_matrix.toarray()
            peer_t, peer = timed(lambda k=k, m=m: scipy.linalg.eigh(k, m, eigvals_only=True), 1)
            diff = float(np.max(np.abs(freqs - np.sqrt(peer[:50]) / (2 * np.pi)) / freqs))
            rows.append(
                (
                    f"assembly + 50 modes, {n_el} el",
                    ours_t,
                    "scipy dense eigh (all)",
                    peer_t,
                    f"{diff:.1e}",
                )
            )
        else:
            rows.append(
                (
                    f"assembly + 50 modes, {n_el} el",
                    ours_t,
                    "scipy dense eigh",
                    float("nan"),
                    "skipped: dense 10^4 x 10^4 takes minutes",
                )
            )
    return rows


def default_mesh_rows(repeats):
    """The physics mesh of Drake 300 m (pinned and clamped): build + every mode up to 50 Hz."""
    rows = []
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    for bc in ("pinned", "clamped"):
        seconds, basis = timed(lambda bc=bc: plc.LineModel(span, bc=bc).modes_below(50.0),
                               repeats)
        model = plc.LineModel(span, bc=bc)
        rows.append((f"Drake 300 m default mesh, {bc}: {model.n_elements} el, "
                     f"build + {basis.n_modes} modes <= 50 Hz", seconds, "-", float("nan"),
                     "see tests/test_fem.py"))
    return rows


def cost_slopes(sizes, repeats):
    """Cost of build + 50 modes against elements on the Drake span, and its log-log slope."""
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    times = [timed(lambda n=n: plc.LineModel(span, n).natural_frequencies(50), repeats)[0]
             for n in sizes]
    slope = np.polyfit(np.log(sizes), np.log(times), 1)[0]
    return times, slope


def simulation_rows(repeats):
    rows = []
    lab = plc.Span.paper_lab()
    force = plc.HarmonicForce(1.0, 24.0, 0.5)
    ours_t, snap = timed(lambda: plc.simulate(plc.LineModel(lab, 100), force, 10.0, 1e-3), repeats)
    sys = plc.LineModel(lab, 100).to_statespace(force_positions=[0.5])
    peer_t, peer = timed(lambda: ct.forced_response(sys, snap.t, snap.force), 1)
    diff = float(np.abs(peer.outputs - snap.displacement).max() / np.abs(snap.displacement).max())
    rows.append(
        (
            "paper span 100 el, 10 s at 1 kHz",
            ours_t,
            "control.forced_response",
            peer_t,
            f"{diff:.1e} (FOH vs exact sine)",
        )
    )
    drake = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    aeolian = plc.AeolianForce(wind_speed=3.0)
    for label, model in (("1000 el", plc.LineModel(drake, 1000, damping=plc.ModalDamping(0.005))),
                         ("default mesh", plc.LineModel(drake,
                                                        damping=plc.ModalDamping(0.005)))):
        drake_t, snap = timed(lambda model=model: plc.simulate(model, aeolian, 5.0, 1e-3), 1)
        rows.append(
            (
                f"Drake 300 m, {label} ({model.n_elements}), aeolian 3 m/s, 5 s "
                f"({snap.n_modes} modes + quasi-static rest)",
                drake_t,
                "-",
                float("nan"),
                "no peer (sparse modal model)",
            )
        )
    return rows


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="smaller sizes, one repeat")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    sizes = (100, 1000) if args.quick else (100, 1000, 5000)
    rows = modal_rows(sizes, repeats) + default_mesh_rows(repeats) + simulation_rows(repeats)
    print(f"{_common.PINNED}; median of {repeats} runs\n")
    print("| workload | ours (s) | peer | peer (s) | peer / ours | agreement |")
    print("|---|---|---|---|---|---|")
    for name, ours, peer, peer_t, agree in rows:
        ratio = f"{peer_t / ours:.1f}x" if np.isfinite(peer_t) else "-"
        peer_s = f"{peer_t:.3f}" if np.isfinite(peer_t) else "-"
        print(f"| {name} | {ours:.3f} | {peer} | {peer_s} | {ratio} | {agree} |")
    times, slope = cost_slopes(sizes, repeats)
    print("\nDrake 300 m, build + 50 modes against elements (sparse shift-invert above "
          f"{plc.fem.DENSE_EIGEN_LIMIT} DOFs):")
    print(" | ".join(f"{n} el: {t:.3f} s" for n, t in zip(sizes, times, strict=True)))
    print(f"log-log slope of cost against elements: {slope:.2f}")


if __name__ == "__main__":
    main()
