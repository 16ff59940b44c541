"""Real spans in aeolian lock-in, for the recipe's physics candidate.

Used by ``tests/test_recipe_physics.py`` and ``benchmarks/bench_physics_candidate.py``; not a
test file itself.

``draw(name, seed)`` is a pure function of the case and the seed
(``numpy.random.default_rng(seed)``): the nominal span (catalogue conductor at 20 % RTS: what
the estimator is told), the truth (the nominal with its tension off by up to +-4 %, drawn; the
estimator never sees it), a wind whose Strouhal tone sits near mode 30-60 of the truth, and a
modal damping ratio log-uniform in 0.1-0.4 %. The truth is meshed with 6 elements per loop at
1.3x the tone (graded toward clamps). ``records`` simulates the training record (20 s of that
wind from rest, 1 % sensor noise) and the test record (the same wind 1 % faster, 10 s from rest,
the training's noise std); ``judge`` filters the test record from the design's sensors and
compares the field at the unmeasured moving nodes with the noise-free truth.
"""

from __future__ import annotations

import warnings

import numpy as np

import powerline_control as plc
from powerline_control.errors import (
    EstimatorInconsistentWarning,
    TruncationWarning,
)

#: name: (conductor, length m, supports, RTS fraction)
CASES = {
    "oxlip-220-pinned": ("oxlip", 220.0, "pinned", 0.2),
    "condor-180-clamped": ("condor", 180.0, "clamped", 0.2),
}
#: Samples left out of every judgement (the filter's start).
FIRST = 500


def draw(name: str, seed: int):
    """(nominal Span, bc, truth LineModel, wind speed m/s) of ``name`` and ``seed``."""
    conductor, length, bc, rts = CASES[name]
    rng = np.random.default_rng(seed)
    nominal = plc.Span.at_rts_fraction(length, conductor, rts)
    truth = plc.Span(length, nominal.tension * rng.uniform(0.96, 1.04), nominal.conductor)
    mode = int(rng.integers(30, 60))
    f_target = float(truth.pinned_frequencies(mode + 1)[-1])
    wind = round(f_target * nominal.conductor.diameter / 0.185 * rng.uniform(0.995, 1.005), 4)
    zeta = float(np.exp(rng.uniform(np.log(1e-3), np.log(4e-3))))
    tone = plc.AeolianForce(wind).frequency_for(truth.conductor)
    model = plc.LineModel(truth, None, bc=bc, damping=plc.ModalDamping(zeta),
                          max_frequency=1.3 * tone, elements_per_loop=6)
    return nominal, bc, model, wind


def records(model, wind: float, seed: int, train_s: float = 20.0, test_s: float = 10.0,
            dt: float = 2e-3):
    """(training, test) Snapshots: the wind, then the same wind 1 % faster (module doc)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TruncationWarning)
        train = plc.simulate(model, plc.AeolianForce(wind), train_s, dt, noise_fraction=0.01,
                             seed=seed)
        test = plc.simulate(model, plc.AeolianForce(1.01 * wind), test_s, dt,
                            noise_std=train.noise_std, seed=seed + 1, start_time=7.3)
    return train, test


def judge(design, test) -> tuple[float, float]:
    """(RMS error over RMS field, reported over actual sigma) at the unmeasured moving nodes."""
    moving = np.flatnonzero(np.std(test.true_displacement, axis=1) > 0)
    unmeasured = np.setdiff1d(moving, design.sensors)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EstimatorInconsistentWarning)
        est = design.filter.filter(test.displacement[design.sensors])
    truth = test.true_displacement[unmeasured, FIRST:]
    error = float(np.sqrt(np.mean((est.field[unmeasured, FIRST:] - truth) ** 2)))
    reported = float(np.sqrt(np.mean(est.field_variances[unmeasured, FIRST:])))
    return error / float(np.sqrt(np.mean(truth**2))), reported / error
