"""Benchmark: DMD fit time against PyDMD and a plain numpy evaluation of the paper's eq. (14).

Run: python benchmarks/bench_identify.py [--quick | --recipe]

BLAS is pinned to one thread (set below, before numpy loads) so that timings on the shared
2-core machine measure the algorithms, not thread contention.

Data: damped standing waves sin(j pi x / L) of a 3.66 m span at 30 frequencies, sampled at
1 kHz, plus 0.1 % white noise, on 101 and 2,001 nodes x 5,000 snapshots.

Rows
* full rank: ``plc.fit_dmd`` (Cholesky route; it always computes the residual covariance Q, from
  Gram matrices: X X^T and Y Y^T share all but two columns, so the only data products are
  X X^T and the lag product X Y^T) with alpha = 1e-3 relative (it then also finds the largest
  singular value) and with ``alpha_mode="absolute"`` given the same absolute alpha as the peers
  (the like-for-like input), against numpy ``X1 X0^T inv(X0 X0^T + alpha I)`` (eq. 14
  literally), numpy ``solve`` (the same without the explicit inverse, A only) and numpy
  ``solve`` + Q the straightforward way (residual E = X1 - A X0, then E E^T / N: the third and
  fourth n^2 N products).  All of one size are timed round-robin (each repeat runs every
  variant once, in a shuffled order), so the machine's load falls on all of them alike; the
  bound table also gives the ratio of the fastest runs (the least disturbed by other users).
  Agreement: max |A_ours - A_numpy| / max |A_numpy| (and the same for Q).
  Flop bound: numpy's A-only flops over ours with Q, counting the data products (X X^T as a
  syrk, n^2 N; the lag product, 2 n^2 N) and the dense algebra (numpy: LU 2/3 n^3 + solve
  2 n^3; ours: Cholesky n^3/3 + solve 2 n^3 + the lower triangle of coef D by block rows,
  (1 + b/n) n^3 with b = min(n, 256) rows per block).  At equal flop rates, ``peer / ours``
  cannot exceed it.
* rank r = 30 (the 30 standing waves; cutting inside the noise floor would make the subspace,
  and so any two implementations' eigenvalues, ill-defined), alpha = 1e-3 relative:
  ``plc.fit_dmd(rank=r)`` against ``pydmd.DMD(svd_rank=r, tikhonov_regularization=alpha /
  ||X||_F)`` (PyDMD scales its lambda by the Frobenius norm of X: s -> (s^2 + lambda ||X||_F)
  / s, the same filter as eq. 14).  Agreement: largest distance to the nearest eigenvalue.
  Time includes the r x r eigenvalues for both (PyDMD computes them in fit; ours lazily, so
  they are requested inside the timed call).
"""

import os

os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = "1"
os.environ["MKL_NUM_THREADS"] = "1"

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

import powerline_control as plc  # noqa: E402

ALPHA_RELATIVE = 1e-3
RANK = 30  # the 30 standing waves: a gap of 1.6 decades to the noise floor


def timed(func, repeats):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = func()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def standing_waves(n_nodes: int, n_samples: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, n_nodes)
    t = np.arange(n_samples) * 1e-3
    X = np.zeros((n_nodes, n_samples))
    for j in range(1, 31):
        f = 6.5 * j * np.sqrt(1 + 0.02 * j**2)  # string-like with a little bending
        decay = 0.01 * 2 * np.pi * f
        phase = rng.uniform(0, 2 * np.pi)
        X += np.outer(np.sin(j * np.pi * x) / j, np.exp(-decay * t / 10) *
                      np.cos(2 * np.pi * f * t + phase))
    return X + 1e-3 * np.sqrt(np.mean(X**2)) * rng.standard_normal(X.shape)


def eig_distance(ours, theirs):
    """Largest distance from an eigenvalue of one set to the nearest of the other."""
    d = np.abs(ours[:, None] - theirs[None, :])
    return float(max(d.min(axis=0).max(), d.min(axis=1).max()))


def round_robin(funcs, repeats, seed=0):
    """Median and fastest time and the last result of each function, all timed within each
    repeat in a freshly shuffled order (a fixed order would hand whatever runs after the
    memory-hungry "+ Q" peer its page faults and cache misses, every time)."""
    order = np.random.default_rng(seed)
    times = {name: [] for name in funcs}
    results = {}
    for _ in range(repeats):
        for name in order.permutation(list(funcs)):
            start = time.perf_counter()
            results[name] = funcs[name]()
            times[name].append(time.perf_counter() - start)
    return ({name: statistics.median(t) for name, t in times.items()},
            {name: min(t) for name, t in times.items()}, results)


def flop_bound(n: int, n_pairs: int) -> float:
    """numpy eq. 14 (A only) flops over ours (A and Q); see the module docstring."""
    data = 3.0 * n**2 * n_pairs
    numpy_solve = data + (2.0 / 3.0 + 2.0) * n**3
    block = min(n, 256)  # identify._ridge._SCATTER_BLOCK: rows per block of the triangle product
    ours = data + (1.0 / 3.0 + 2.0 + 1.0 + block / n) * n**3
    return numpy_solve / ours


def full_rank_rows(X, repeats):
    X0, X1 = X[:, :-1], X[:, 1:]
    s_max = np.linalg.norm(X0, 2) if X.shape[0] <= 200 else None
    alpha = plc.fit_dmd(X, 1e-3, alpha=ALPHA_RELATIVE, alpha_mode="relative").alpha
    if s_max is not None:
        assert abs(alpha - ALPHA_RELATIVE * s_max**2) < 1e-10 * alpha

    def naive_inv():
        return X1 @ X0.T @ np.linalg.inv(X0 @ X0.T + alpha * np.eye(X.shape[0]))

    def naive_solve():
        gram = X0 @ X0.T + alpha * np.eye(X.shape[0])
        return np.linalg.solve(gram, X0 @ X1.T).T

    def naive_solve_with_q():
        A = naive_solve()
        E = X1 - A @ X0                     # the residual pass: two more n^2 N products
        return A, (E @ E.T) / X0.shape[1]

    funcs = {
        "ours, relative": lambda: plc.fit_dmd(X, 1e-3, alpha=ALPHA_RELATIVE,
                                               alpha_mode="relative"),
        "ours, absolute": lambda: plc.fit_dmd(X, 1e-3, alpha=alpha, alpha_mode="absolute"),
        "numpy eq.14 (inv)": naive_inv,
        "numpy eq.14 (solve), A only": naive_solve,
        "numpy eq.14 (solve) + Q": naive_solve_with_q,
    }
    times, fastest, results = round_robin(funcs, repeats)
    rows = []
    size = f"{X.shape[0]} x {X.shape[1]}, full rank, with Q"
    pairs = [("ours, relative", peer) for peer in list(funcs)[2:]]
    pairs += [("ours, absolute", "numpy eq.14 (solve), A only"),
              ("ours, absolute", "numpy eq.14 (solve) + Q")]
    for ours_name, peer_name in pairs:
        ours, peer = results[ours_name], results[peer_name]
        if isinstance(peer, tuple):
            peer, peer_q = peer
            q_diff = float(np.abs(ours.residual_covariance - peer_q).max()
                           / np.abs(peer_q).max())
            agreement = f"A: {np.abs(ours.A - peer).max() / np.abs(peer).max():.1e}, " \
                        f"Q: {q_diff:.1e}"
        else:
            agreement = f"A: {np.abs(ours.A - peer).max() / np.abs(peer).max():.1e}"
        alpha_label = ours_name.split(", ")[1]
        rows.append((f"{size}, alpha {alpha_label}", times[ours_name], peer_name,
                     times[peer_name], agreement))
    bound = flop_bound(X.shape[0], X0.shape[1])
    peer = "numpy eq.14 (solve), A only"
    ratios = [times[peer] / times[name] for name in ("ours, relative", "ours, absolute")]
    ratios += [fastest[peer] / fastest[name] for name in ("ours, relative", "ours, absolute")]
    return rows, (X.shape[0], X.shape[1], bound, ratios)


def rank_rows(X, repeats):
    import pydmd

    ours_t, ours = timed(
        lambda: _with_eigs(plc.fit_dmd(X, 1e-3, alpha=ALPHA_RELATIVE, alpha_mode="relative",
                                       rank=RANK)),
        repeats,
    )
    lam = ours.alpha / np.linalg.norm(X[:, :-1])

    def peer():
        dmd = pydmd.DMD(svd_rank=RANK, tikhonov_regularization=lam)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            dmd.fit(X)
        return dmd

    peer_t, peer_model = timed(peer, repeats)
    diff = eig_distance(ours.eigenvalues, np.asarray(peer_model.eigs))
    return [(f"{X.shape[0]} x {X.shape[1]}, rank {RANK}", ours_t, "PyDMD DMD", peer_t,
             f"eigs: {diff:.1e}")]


def _with_eigs(model):
    model.eigenvalues  # noqa: B018 - computed lazily; include it in the timing
    return model


def recipe_rows():
    """design_estimator on the lab span (100 elements) and on the real span (1000 elements)."""
    from powerline_control.estimate import estimation_accuracy

    cases = [
        ("lab span, 100 el., harmonic + broadband", plc.LineModel(plc.Span.paper_lab(), 100),
         [plc.HarmonicForce(1.0, 14.2, 2.3), plc.RandomForce(1.0, 1.1, 100.0, seed=17)],
         plc.RandomForce(1.0, 2.9, 100.0, seed=29), 10.0, 1e-3),
        ("Drake 300 m, 1000 el., aeolian 3 m/s",
         plc.LineModel(plc.Span.at_rts_fraction(300.0, "drake", 0.20), 1000),
         plc.AeolianForce(3.0), plc.AeolianForce(3.0), 20.0, 2e-3),
    ]
    rows = []
    for label, model, train_force, test_force, duration, dt in cases:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", plc.TruncationWarning)
            start = time.perf_counter()
            train = plc.simulate(model, train_force, duration=duration, dt=dt,
                                 noise_fraction=0.01, seed=5)
            test = plc.simulate(model, test_force, duration=8.0, dt=dt, noise_fraction=0.01,
                                seed=6, start_time=3.1)
            simulated = time.perf_counter() - start
        start = time.perf_counter()
        design = plc.design_estimator(train, n_sensors=5, seed=0)
        designed = time.perf_counter() - start
        field = design.estimate_field(test.displacement[design.sensors],
                                      noise_std=test.noise_std)
        acc = estimation_accuracy(field, test.true_displacement, measured=design.sensors,
                                  discard=500)
        rows.append((label, train.displacement.shape, simulated, designed,
                     acc.relative_rms_error_unmeasured))
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="101 nodes only, 1 repeat")
    parser.add_argument("--recipe", action="store_true",
                        help="time design_estimator on the lab and real spans instead")
    args = parser.parse_args()
    if args.recipe:
        print("BLAS pinned to 1 thread (OPENBLAS/OMP/MKL_NUM_THREADS=1, set before numpy import)")
        print("| case | training record | simulation (s) | design_estimator (s) | "
              "unmeasured-node error, new run |")
        print("|---|---|---:|---:|---:|")
        for label, shape, simulated, designed, error in recipe_rows():
            print(f"| {label} | {shape[0]} x {shape[1]} | {simulated:.1f} | {designed:.1f} | "
                  f"{100 * error:.2f} % |")
        return
    repeats = 1 if args.quick else 3
    sizes = [101] if args.quick else [101, 2001]
    print("BLAS pinned to 1 thread (OPENBLAS/OMP/MKL_NUM_THREADS=1, set before numpy import)")
    full_repeats = {101: 1 if args.quick else 10 * repeats, 2001: 5}
    print(f"alpha = {ALPHA_RELATIVE:g} relative (absolute rows: the same absolute alpha); "
          f"full rank: medians of {full_repeats[101]} runs at 101 nodes, {full_repeats[2001]} "
          f"at 2001; rank {RANK}: {repeats} and 1\n")
    rows, bounds = [], []
    for n in sizes:
        X = standing_waves(n, 5000)
        full, bound = full_rank_rows(X, full_repeats[n])
        rows += full
        bounds.append(bound)
        rows += rank_rows(X, repeats if n < 1000 else 1)
    print("| case | powerline_control (s) | peer | peer (s) | peer / ours | agreement |")
    print("|---|---:|---|---:|---:|---|")
    for case, ours_t, peer, peer_t, agreement in rows:
        print(f"| {case} | {ours_t:.4g} | {peer} | {peer_t:.4g} | {peer_t / ours_t:.2f} | "
              f"{agreement} |")
    print("\nFlop-count bound of ours (A and Q) against numpy eq. 14 solve (A only): the ratio "
          "peer / ours cannot exceed it at equal flop rates")
    print("| size | flop bound | relative alpha, medians | absolute alpha, medians | "
          "relative, fastest runs | absolute, fastest runs |")
    print("|---|---:|---:|---:|---:|---:|")
    for n, n_samples, bound, ratios in bounds:
        print(f"| {n} x {n_samples} | {bound:.3f} | " + " | ".join(f"{r:.2f}" for r in ratios)
              + " |")


if __name__ == "__main__":
    main()
