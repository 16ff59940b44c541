"""Benchmark of sensor selection: speed targets of issue 5 and PySensors side by side.

Run: ``/work/venv/bin/python benchmarks/bench_sensors.py``  (about a minute).

Cases
-----
1. Paper 101-state case (100-element span, DMD, alpha = 0.1, 1 % noise, harmonic force at
   14.4 Hz): ``select_sensors(k=13, criterion="kalman")`` in total (relaxation, certificate,
   rounding, greedy, swap search, baselines); target < 5 s.
2. The exact criterion per layout: batched doubling (ours) against SciPy's
   ``solve_discrete_are`` (QZ), n = 101.
3. n = 1,001 candidates (1000-element span, 10-mode reduced model, error of the whole
   displacement field): ``select_sensors(k=13)``; target < 60 s.
4. Reconstruction (log det Psi_S^T Psi_S, k = r = 13) on the same basis as PySensors' QR
   (SSPOR): objective reached and time, n = 101 and n = 1,001.
5. Reduced coordinates (issue 10 item 3): ``select_sensors(k=5)`` on rank-20 / rank-80 DMD models
   with 101 / 1,001 candidate outputs; target < 20 s at 1,001 candidates; log-log slopes.
6. The Gramian criterion on 200-state models, this tree against an earlier commit (``--before
   REV``, default 76b7399, the last one before the per-candidate Gramians became matrix
   products and the Frank-Wolfe line search a Cholesky per point): ``select_sensors(k,
   "gramian")`` on the 20- and 100-mode modal models of the lab span (40 and 200 states, 101
   candidates) and, with ``--large``, on a rank-200 DMD model of 1,001 candidates; each side in
   its own process (``git archive REV`` on the path), alternately, with the layouts compared
   (and the earlier commit's own layout with R scaled by 1 + 1e-12, to show where round-off
   decides it) and ``"kalman"`` on the same model for scale.

``--reduced`` runs section 5 only, ``--gramian`` section 6 only.
"""

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import numpy as np  # noqa: E402
import scipy.linalg as sla  # noqa: E402
from _common import CANDIDATES, RANKS, reduced_model, slope
from _common import timed as _timed  # noqa: E402

import powerline_control as plc  # noqa: E402
from powerline_control._riccati import steady_state_batch  # noqa: E402
from powerline_control.sensors.criteria import _information  # noqa: E402

REPEATS = 3


def timed(fn, repeats=REPEATS):
    return _timed(fn, repeats)


def paper_model():
    span = plc.Span.paper_lab()
    model = plc.LineModel(span, n_elements=100, bc="pinned")
    force = plc.HarmonicForce(amplitude=1.0, frequency=14.4, position=0.5)
    snap = plc.simulate(model, force, duration=2.0, dt=1e-3, noise_fraction=0.01, seed=0)
    noise_var = float(np.var(snap.displacement - snap.true_displacement))
    dmd = plc.fit_dmd(snap.displacement, dt=snap.dt, alpha=0.1, delays=1)
    return model, snap, dmd, noise_var


# ----------------------------------------------------------------------- reduced coordinates
# The rank-r models and sizes live in _common (shared with the other benchmark).


def reduced_table(repeats: int = 1) -> None:
    print("\n## 5. Reduced coordinates: select_sensors(k=5, 'kalman') on a rank-r DMD model "
          "with m candidate outputs (target < 20 s at m = 1,001)\n")
    print("| rank r | candidates m | seconds | certificate | gap | exact evaluations |")
    print("|---|---|---|---|---|---|")
    seconds = {}
    for r in RANKS:
        for m in CANDIDATES:
            sys_, q, noise_var = reduced_model(m, r)
            t, sel = timed(lambda s=sys_, q=q, v=noise_var: plc.select_sensors(
                s, 5, Q=q, R=v, n_random=0), repeats)
            seconds[r, m] = t
            print(f"| {r} | {m} | {t:.2f} | {sel.certificate} | {100 * sel.gap:.1f} % | "
                  f"{sel.n_exact_evaluations} |")
    for r in RANKS:
        print(f"\nlog-log slope in m (r = {r}): "
              f"{slope(seconds[r, 101], seconds[r, 1001], 101, 1001):.2f}", end="")
    for m in CANDIDATES:
        print(f"\nlog-log slope in r (m = {m}): "
              f"{slope(seconds[20, m], seconds[80, m], 20, 80):.2f}", end="")
    print()


# ------------------------------------------------------------- the Gramian criterion, 200 states
def gramian_model(name: str):
    """(sys, Q, R): the lab span's 20- or 100-mode modal model (40 or 200 states, 101
    candidates) or a rank-200 DMD model of 1,001 candidates (``_common.reduced_model``)."""
    if name.startswith("modal-"):
        model = plc.LineModel(plc.Span.paper_lab(), n_elements=100, bc="pinned",
                              damping=plc.ModalDamping(0.01))
        n_modes = int(name.split()[0].removeprefix("modal-")) // 2
        sys_ = model.to_statespace(dt=1e-3, force_positions=[0.5], n_modes=n_modes)
        b = np.asarray(sys_.B)
        return sys_, b @ b.T + 1e-6 * np.trace(b @ b.T) * np.eye(sys_.nstates), 1e-10
    return reduced_model(1001, 200)


def gramian_child(name: str, k: int, criterion: str, r_factor: float) -> None:
    """One timed select_sensors call, printed as JSON (run in a child process)."""
    sys_, q, r = gramian_model(name)
    t, sel = timed(lambda: plc.select_sensors(sys_, k=k, criterion=criterion, Q=q,
                                              R=r * r_factor), 1)
    print(json.dumps({"seconds": t, "nodes": list(sel.nodes), "objective": sel.objective,
                      "exact": sel.n_exact_evaluations, "package": plc.__file__}))


def _child(path: str | None, name: str, k: int, criterion: str, r_factor: float = 1.0) -> dict:
    env = dict(os.environ)
    if path is not None:
        env["PYTHONPATH"] = path + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, __file__, "--child", name, str(k), criterion,
                          repr(r_factor)],
                         env=env, capture_output=True, text=True, check=True, cwd="/")
    return json.loads(out.stdout.strip().splitlines()[-1])


def gramian_table(before: str, large: bool) -> None:
    root = Path(__file__).resolve().parents[1]
    cases = [("modal-40 / 101", 3), ("modal-40 / 101", 5), ("modal-200 / 101", 3),
             ("modal-200 / 101", 5)]
    if large:
        cases.append(("DMD-200 / 1001", 5))
    print(f"\n## 6. select_sensors(criterion='gramian') on 200-state models: {before} against "
          f"this tree ({_common.code_version()}), one run each, alternately\n")
    print("'before, R x (1 + 1e-12)': the earlier commit again with every noise variance scaled "
          "by 1 + 1e-12, which shifts every log det by one constant: where its layout changes, "
          "the layout is decided by round-off (the Gramians' condition numbers reach 1e15-1e50 "
          "at 200 states).\n")
    print("| model / candidates | k | before (s) | after (s) | before / after | same layout | "
          "before, R x (1 + 1e-12) | 'kalman' (s) | gramian / kalman |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "archive", before, "powerline_control"], cwd=root,
                                 capture_output=True, check=True).stdout
        with tarfile.open(fileobj=__import__("io").BytesIO(archive)) as tar:
            tar.extractall(tmp, filter="data")
        for name, k in cases:
            old = _child(tmp, name, k, "gramian")
            new = _child(None, name, k, "gramian")
            assert old["package"].startswith(tmp) and not new["package"].startswith(tmp)
            shifted = _child(tmp, name, k, "gramian", 1.0 + 1e-12)
            kalman = _child(None, name, k, "kalman")

            def same(other, reference=old):
                return "yes" if other["nodes"] == reference["nodes"] else (
                    f"no: {reference['nodes']} ({reference['objective']:.6g}) -> "
                    f"{other['nodes']} ({other['objective']:.6g})")

            print(f"| {name} | {k} | {old['seconds']:.2f} | {new['seconds']:.2f} | "
                  f"{old['seconds'] / new['seconds']:.1f}x | {same(new)} | {same(shifted)} | "
                  f"{kalman['seconds']:.2f} | {new['seconds'] / kalman['seconds']:.2f} |",
                  flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reduced", action="store_true", help="section 5 only")
    parser.add_argument("--gramian", action="store_true", help="section 6 only")
    parser.add_argument("--before", default="76b7399",
                        help="commit the Gramian section compares with (default 76b7399)")
    parser.add_argument("--large", action="store_true",
                        help="section 6 also on 1,001 candidates (minutes before the fix)")
    parser.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        gramian_child(args.child[0], int(args.child[1]), args.child[2], float(args.child[3]))
        return
    print(f"{_common.PINNED}; median of {REPEATS} runs (1 in sections 5 and 6)\n")
    if args.reduced:
        reduced_table()
        return
    if args.gramian:
        gramian_table(args.before, args.large)
        return
    model, snap, dmd, noise_var = paper_model()
    sys, q = dmd.to_statespace(), dmd.residual_covariance

    # 1. the 101-state case, k = 13
    t_total, sel = timed(lambda: plc.select_sensors(sys, k=13, Q=q, R=noise_var,
                                                   positions=model.node_positions))
    print("## 1. Paper 101-state DMD model, k = 13, criterion 'kalman' (target < 5 s)\n")
    print(f"select_sensors total: {t_total:.2f} s; exact evaluations: "
          f"{sel.n_exact_evaluations}; gap {100 * sel.gap:.1f} % (bound {sel.bound:.3e})\n")
    print("| layout | trace P (m^2) | ratio to optimised |")
    print("|---|---|---|")
    print(f"| optimised {list(sel.nodes)} | {sel.objective:.3e} | 1.00 |")
    for base in sel.baselines.values():
        print(f"| {base.name} | {base.objective:.3e} | {base.objective / sel.objective:.2f} |")

    # 2. exact criterion per layout
    rng = np.random.default_rng(0)
    a, c = np.asarray(sys.A), np.asarray(sys.C)
    layouts = np.array([rng.choice(101, 13, replace=False) for _ in range(32)])
    qs, g = q / noise_var, c
    t_ours, _ = timed(lambda: steady_state_batch(a, qs, _information(g, layouts)))

    def scipy_all():
        for layout in layouts[:8]:
            sla.solve_discrete_are(a.T, g[layout].T, qs, np.eye(13))

    t_scipy, _ = timed(scipy_all)
    per_ours, per_scipy = t_ours / len(layouts), t_scipy / 8
    print("\n## 2. Exact criterion (steady-state DARE) per layout, n = 101, k = 13\n")
    print("| method | ms per layout | ratio |")
    print("|---|---|---|")
    print(f"| scipy.linalg.solve_discrete_are | {1e3 * per_scipy:.1f} | 1.00 |")
    print(f"| batched doubling (ours) | {1e3 * per_ours:.1f} | "
          f"{per_scipy / per_ours:.1f}x faster |")

    # 3. n = 1001 candidates with a reduced-order model
    big = plc.LineModel(plc.Span.paper_lab(), n_elements=1000, bc="pinned",
                        damping=plc.ModalDamping(0.01))
    big_sys = big.to_statespace(dt=1e-3, force_positions=[0.5], n_modes=10)
    b = np.asarray(big_sys.B)
    big_q = b @ b.T + 1e-6 * np.trace(b @ b.T) * np.eye(big_sys.nstates)
    t_big, big_sel = timed(lambda: plc.select_sensors(
        big_sys, k=13, Q=big_q, R=1e-10, positions=big.node_positions,
        error_weight="outputs"), repeats=1)
    print("\n## 3. n = 1,001 candidates, 20-state modal model, k = 13 (target < 60 s)\n")
    print(f"select_sensors total: {t_big:.1f} s; gap {100 * big_sel.gap:.1f} %; objective "
          f"{big_sel.objective:.3e} vs first-13 {big_sel.baselines['first-k'].objective:.3e}, "
          f"evenly {big_sel.baselines['evenly-spaced'].objective:.3e}, "
          f"QR {big_sel.baselines['qr-pivoting'].objective:.3e}")

    # 4. reconstruction vs PySensors on the same basis
    print("\n## 4. Reconstruction log det(Psi_S^T Psi_S), k = r = 13, same basis as PySensors\n")
    try:
        import pysensors as ps
    except ImportError:
        ps = None
        print("PySensors not installed (pip install python-sensors): peer column skipped\n")
    print("| n | method | log det | bound | time (ms) | time / PySensors |")
    print("|---|---|---|---|---|---|")
    u, _, _ = np.linalg.svd(snap.displacement - snap.displacement.mean(axis=1, keepdims=True),
                            full_matrices=False)
    bases = {101: (sys, u[:, :13]), 1001: (big_sys, big.mode_shapes(13))}
    for n, (model_sys, psi) in bases.items():
        t_rec, rec = timed(lambda s=model_sys, p=psi: plc.select_sensors(
            s, k=13, criterion="reconstruction", basis=p, n_random=0, brute_force_limit=0))
        rows = [("select_sensors (relaxation + swaps)", rec.objective, f"{rec.bound:.2f}",
                 t_rec)]
        if ps is not None:
            def pysensors_qr(p=psi):
                model = ps.SSPOR(basis=ps.basis.Identity(n_basis_modes=13), n_sensors=13)
                model.fit(p.T)
                return model.get_selected_sensors()

            t_ps, chosen = timed(pysensors_qr)
            logdet = np.linalg.slogdet(psi[chosen].T @ psi[chosen])[1]
            rows.append(("PySensors SSPOR (QR)", logdet, "-", t_ps))
        for name, value, bound, t in rows:
            ratio = f"{t / rows[-1][3]:.0f}" if len(rows) > 1 else "-"
            print(f"| {n} | {name} | {value:.2f} | {bound} | {1e3 * t:.1f} | {ratio} |")
    reduced_table()
    gramian_table(args.before, args.large)


if __name__ == "__main__":
    main()
