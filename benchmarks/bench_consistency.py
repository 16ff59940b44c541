"""Benchmark: the consistency monitor's cost, KalmanFilter.step and filter with and without it.

Issue 19 asks that the consistency monitor change ``KalmanFilter.step``'s cost by at most 20 %.
Same filter either side (the steady-state filter ``design_estimator`` builds for the paper's lab
span, 60 elements, 5 sensors, rank 30), same record (an independent simulation, 1 % noise);
the only difference is ``consistency_window=None`` and no spectral reference (monitor off)
against the default window of 200 with the design's spectral reference, field reference and
innovation growth, as ``design_estimator`` ships them (the windowed NIS in ``step`` and
``filter``, its factor on ``S`` following the field per frequency at each window's end; the
spectral test of the innovations in ``filter`` only).
Timings alternate the two sides (``_common.alternate``) and report medians per sample.

Run: python benchmarks/bench_consistency.py [--quick]
BLAS is pinned to one thread (``_common`` is imported before numpy), as on the other benchmarks.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import numpy as np  # noqa: E402

import powerline_control as plc  # noqa: E402
from powerline_control.estimate import KalmanFilter  # noqa: E402


def _filters(design):
    kf = design.filter
    sys_ = design.model.to_statespace(measured=design.sensors.tolist())

    def build(window):
        return KalmanFilter(sys_, Q=kf.Q, R=kf.R, steady_state=True,
                            field_map=design.model.field_map, consistency_window=window,
                            nis_dof_fraction=kf.nis_dof_fraction,
                            spectral_reference=None if window is None else kf.spectral_reference,
                            spectral_reference_count=kf.spectral_reference_count,
                            spectral_field_reference=(None if window is None
                                                      else kf.spectral_field_reference),
                            innovation_growth=None if window is None else kf.innovation_growth)
    return build(None), build(200)


def main(quick: bool) -> None:
    print(_common.PINNED)
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=60)
    load = [plc.HarmonicForce(1.0, 14.2, 2.3), plc.RandomForce(1.0, 1.1, 100.0, seed=17)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train = plc.simulate(model, load, duration=6.0, dt=1e-3, noise_fraction=0.01, seed=4)
        start = time.perf_counter()
        design = plc.design_estimator(train, n_sensors=5, seed=0)
        t_design = time.perf_counter() - start
        test = plc.simulate(model, load, duration=4.0, dt=1e-3, noise_fraction=0.01, seed=5,
                            start_time=2.9)
    y = np.ascontiguousarray(test.displacement[design.sensors])
    n_steps = 1000 if quick else 4000
    repeats = 3 if quick else 7
    off, on = _filters(design)

    def stepper(kf):
        def run():
            kf.reset()
            for k in range(n_steps):
                kf.step(y[:, k])
        return run

    t_off, t_on = _common.alternate(stepper(off), stepper(on), repeats)[:2]
    f_off, f_on = _common.alternate(lambda: off.filter(y), lambda: on.filter(y), repeats)[:2]
    rows = [
        ("KalmanFilter.step, per sample", t_off / n_steps, t_on / n_steps),
        ("KalmanFilter.filter, per sample", f_off / y.shape[1], f_on / y.shape[1]),
    ]
    print(f"design_estimator (60 elements, 6 s at 1 kHz, rank {design.model.n_states}): "
          f"{t_design:.2f} s")
    print(f"{'operation':34s} {'monitor off':>12s} {'monitor on':>12s} {'ratio':>7s}")
    for name, a, b in rows:
        print(f"{name:34s} {a * 1e6:10.2f}us {b * 1e6:10.2f}us {b / a:7.3f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer samples and repeats")
    main(parser.parse_args().quick)
