"""Benchmark: the reported sigma on new load histories, with and without ``model_error_records``.

Issue 19 asks that the filter's reported sigma at unmeasured nodes match the actual error within
a factor 1.5 on held-out runs. The held-out part of a training record continues its load
histories; this measures runs of *new* ones. Per case: a training record of two broadband
``RandomForce`` loads (at 0.31 L and 0.77 L, 1 % noise), a design with the default recipe, and
a second design given two more records of other load histories (same sensor noise) as
``model_error_records``. Both filter five runs of further load histories (in no record either
design saw, same noise, from rest); the table gives the actual RMS error at the unmeasured moving
nodes over the RMS field (truth: the simulation's noise-free field) and reported over actual
sigma, after the first 200 samples.

Run: python benchmarks/bench_new_loads.py [case ...]
BLAS is pinned to one thread (``_common`` is imported before numpy), as on the other benchmarks.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import warnings  # noqa: E402

import _common  # noqa: E402, F401  (pins BLAS to one thread before numpy loads)
import numpy as np  # noqa: E402

import powerline_control as plc  # noqa: E402


def _real(length, conductor, rts, bc):
    return lambda: plc.LineModel(plc.Span.at_rts_fraction(length, conductor, rts),
                                 n_elements=int(length), bc=bc)


#: name: (model factory, load band Hz, record duration s, dt s, sensors)
CASES = {
    "lab-pinned": (lambda: plc.LineModel(plc.Span.paper_lab(), n_elements=40, bc="pinned"),
                   100.0, 6.0, 1e-3, 5),
    "lab-clamped": (lambda: plc.LineModel(plc.Span.paper_lab(), n_elements=40, bc="clamped"),
                    100.0, 6.0, 1e-3, 5),
    "drake-300-clamped": (_real(300.0, "drake", 0.2, "clamped"), 10.0, 30.0, 4e-3, 24),
    "cardinal-400-pinned": (_real(400.0, "cardinal", 0.25, "pinned"), 10.0, 30.0, 4e-3, 8),
    "condor-350-clamped": (_real(350.0, "condor", 0.2, "clamped"), 10.0, 30.0, 4e-3, 12),
}
TRAIN, MODEL_ERROR, UNSEEN = 3, (43, 53), (13, 23, 33, 63, 73)  # load seeds


def _judge(design, run, unmeasured):
    """(actual error over field, reported over actual sigma) at ``unmeasured``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.EstimatorInconsistentWarning)
        est = design.filter.filter(run.displacement[design.sensors])
    truth = run.true_displacement[unmeasured, 200:]
    actual = np.sqrt(np.mean((est.field[unmeasured, 200:] - truth) ** 2))
    reported = np.sqrt(np.mean(est.field_variances[unmeasured, 200:]))
    return actual / np.sqrt(np.mean(truth**2)), reported / actual


def case(name):
    """(ratios without, ratios with model_error_records) over the unseen runs of ``name``."""
    make, band, duration, dt, k = CASES[name]
    model = make()
    length = model.node_positions[-1]

    def loads(seed):
        return [plc.RandomForce(1.0, 0.31 * length, band, seed=seed),
                plc.RandomForce(1.0, 0.77 * length, band, seed=seed + 1)]

    rec = plc.simulate(model, loads(TRAIN), duration, dt, noise_fraction=0.01, seed=0)
    others = [plc.simulate(model, loads(s), duration, dt, noise_std=rec.noise_std, seed=s + 100)
              for s in MODEL_ERROR]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.ExcitationWarning)
        plain = plc.design_estimator(rec, n_sensors=k, seed=0)
        learned = plc.design_estimator(rec, n_sensors=k, seed=0, model_error_records=others)
    moving = np.flatnonzero(np.std(rec.true_displacement, axis=1) > 0)
    unmeasured = np.setdiff1d(moving, plain.sensors)
    errors, before, after = [], [], []
    for s in UNSEEN:
        run = plc.simulate(model, loads(s), duration, dt, noise_std=plain.noise_std, seed=s + 100)
        error, ratio = _judge(plain, run, unmeasured)
        errors.append(error)
        before.append(ratio)
        after.append(_judge(learned, run, unmeasured)[1])
    print(f"{name:20s} {k:2d} sensors | actual {' '.join(f'{100 * e:5.1f}' for e in errors)} % "
          f"| held-out level {' '.join(f'{r:.2f}' for r in before)} | other loads "
          f"{' '.join(f'{r:.2f}' for r in after)}", flush=True)
    return before, after


def main() -> None:
    names = sys.argv[1:] or list(CASES)
    print("reported / actual sigma at unmeasured nodes on runs of new load histories")
    before, after = [], []
    for name in names:
        b, a = case(name)
        before += b
        after += a
    for label, ratios in (("level from the held-out part", before),
                          ("level from 2 records of other loads", after)):
        r = np.array(ratios)
        print(f"{label}: median {np.median(r):.2f}, range {r.min():.2f}-{r.max():.2f}, "
              f"{int(np.sum((r > 1 / 1.5) & (r < 1.5)))}/{r.size} within 1.5x")


if __name__ == "__main__":
    main()
