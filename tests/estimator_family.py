"""A seeded family of estimator designs and new runs, to measure what the consistency test is worth.

Used by ``tests/test_estimator_detection.py`` and ``benchmarks/bench_detection.py``; not a test
file itself.

Drawing and splitting
---------------------
``design_case(seed)`` is a pure function of the seed (``numpy.random.default_rng(1000 + seed)``).
The **split is the seed's parity**: even seeds tune the spectral test's constants
(``powerline_control.estimate._spectrum``), odd seeds are held out. The case cycles with
``seed // 2`` over :data:`CASES` (the lab span and real spans from ``plc.conductors``, pinned and
clamped), so both splits cover every case.

A design is trained (``design_estimator``, 5 sensors) on a sine just below a random mode (3rd to
8th) plus a broadband load low-passed at the training band (``RandomForce``), both at random
places, 1 % sensor noise. Every run is a fresh simulation from a random start time with the
design's sensor noise:

- *matched*: the same kind of load (same sine frequency and place, new phase, a new random
  history of the broadband load);
- *mismatched*, a load that drives modes the training never saw, alternating between
  ``"above"`` (a sine at 1.5-3 x the training band at a new place) and ``"elsewhere"`` (a sine
  10 % lower at a new place plus a broadband load up to 3 x the band at a new place: a case
  whose error at the unmeasured nodes reached 102 %).
- *steady* (only with ``runs_of(..., steady=True)``): a matched load run three times as long,
  judged on its last third, when the line has rung up (an identified model's error grows with
  the field: the calibration must hold there too).

The judge of a run is the truth of the simulation: ``error`` is the RMS error at unmeasured
nodes over the RMS field there; ``sensor_snr`` the RMS, at the sensors, of what the training
never saw (the run's true sensor signal minus the part a matched load explains is not available,
so for a mismatched run the whole sensor signal) over the sensor noise: a mismatched run below
noise level at every sensor is visible to no test on the sensors.

Counting detection
------------------
:func:`rates` reports detection twice, never one without the other: over every mismatched run
(the raw rate) and over the runs whose mismatch is *visible at the sensors*, ``sensor_snr >=``
:data:`VISIBLE_SNR` (:attr:`Run.visible`, the one definition; ``docs/estimation.md`` says it).
"""

from __future__ import annotations

import dataclasses
import functools
import warnings

import numpy as np

import powerline_control as plc

#: A mismatched run is visible at the sensors when the RMS of its field there is at least this
#: many times the sensor noise RMS (``Run.sensor_snr``); below it no test of the sensors'
#: innovations can tell the run from noise, so detection is also reported over visible runs.
VISIBLE_SNR = 1.0

#: name: (span factory, bc, n_elements, dt, training duration, training band Hz, mode offset)
CASES = {
    "lab-pinned": (plc.Span.paper_lab, "pinned", 60, 1e-3, 6.0, 100.0),
    "drake-300-clamped": (lambda: plc.Span.at_rts_fraction(300.0, "drake", 0.2), "clamped",
                          300, 4e-3, 12.0, 10.0),
    "lab-clamped": (plc.Span.paper_lab, "clamped", 60, 1e-3, 6.0, 100.0),
    "cardinal-400-pinned": (lambda: plc.Span.at_rts_fraction(400.0, "cardinal", 0.25),
                            "pinned", 400, 4e-3, 12.0, 10.0),
    "condor-350-clamped": (lambda: plc.Span.at_rts_fraction(350.0, "condor", 0.2), "clamped",
                           350, 4e-3, 12.0, 10.0),
    "aster570-250-pinned": (lambda: plc.Span.at_rts_fraction(250.0, "aster570", 0.2),
                            "pinned", 250, 4e-3, 12.0, 10.0),
}


@dataclasses.dataclass(frozen=True)
class Run:
    """One filtered record and what the truth says about it."""

    case: str
    seed: int
    kind: str          # "matched", "above", "elsewhere" (or "steady": see runs_of)
    warned: bool       # EstimatorInconsistentWarning raised
    nis_ok: bool       # windowed NIS test alone passes
    spectral_ok: bool | None
    max_ratio: float   # largest spectral ratio (bins > 0)
    error: float       # RMS error / RMS field at unmeasured nodes
    reported_over_actual: float  # reported sigma / actual RMS error at unmeasured nodes
    sensor_snr: float  # RMS of the true signal at the sensors / sensor noise
    outside_share: float  # design.coverage.outside_share of the record
    design_sigma_ratio: float = float("nan")  # EstimatorDesign.held_out_sigma_ratio
    spectral_ratios: tuple = ()   # Consistency.spectral_ratio (per bin)
    reference: tuple = ()         # the filter's spectral_reference (per bin)

    @property
    def visible(self) -> bool:
        """A mismatched run whose field at the sensors stands at least :data:`VISIBLE_SNR`
        times above their noise (False for matched and steady runs)."""
        return self.kind in ("above", "elsewhere") and self.sensor_snr >= VISIBLE_SNR


def case_of(seed: int) -> str:
    return list(CASES)[(seed // 2) % len(CASES)]


def split_of(seed: int) -> str:
    return "tune" if seed % 2 == 0 else "held_out"


def _model(case: str):
    make_span, bc, n_elements, dt, duration, band = CASES[case]
    return plc.LineModel(make_span(), n_elements=n_elements, bc=bc), dt, duration, band


def runs_of(seed: int, n_runs: int = 2, steady: bool = False) -> list[Run]:
    """Design on seed's case, then ``n_runs`` matched and ``n_runs`` mismatched runs; with
    ``steady``, one more matched load run three times as long and judged on its last third
    (kind ``"steady"``: the line rung up, where an identified model's error is largest)."""
    case = case_of(seed)
    model, dt, duration, band = _model(case)
    length = model.span.length if hasattr(model, "span") else model.node_positions[-1]
    rng = np.random.default_rng(1000 + seed)
    modes = model.natural_frequencies(10)
    f_sine = modes[int(rng.integers(3, 8))] * 0.99
    if f_sine > 0.9 * band:
        f_sine = band * rng.uniform(0.4, 0.8)
    p_sine, p_random = length * rng.uniform(0.15, 0.85, size=2)
    train = plc.simulate(
        model, [plc.HarmonicForce(1.0, f_sine, p_sine),
                plc.RandomForce(1.0, p_random, band, seed=int(rng.integers(1000)))],
        duration=duration, dt=dt, noise_fraction=0.01, seed=int(rng.integers(1000)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.ExcitationWarning)
        design = plc.design_estimator(train, n_sensors=5, seed=0, warn_inconsistent=True)
    unmeasured = np.setdiff1d(np.flatnonzero(np.std(train.true_displacement, axis=1) > 0),
                              design.sensors)
    out = []
    for run in range(n_runs):
        s = int(rng.integers(10_000))
        matched = [plc.HarmonicForce(1.0, f_sine, p_sine, phase=rng.uniform(0, 6)),
                   plc.RandomForce(1.0, p_random, band, seed=s)]
        if run % 2 == 0:
            kind = "above"
            unseen = [plc.HarmonicForce(1.0, band * rng.uniform(1.5, 3.0),
                                        length * rng.uniform(0.1, 0.9))]
        else:
            kind = "elsewhere"
            unseen = [plc.HarmonicForce(1.0, f_sine * 0.9, length * rng.uniform(0.1, 0.9)),
                      plc.RandomForce(1.0, length * rng.uniform(0.1, 0.9), 3 * band, seed=s + 1)]
        start = rng.uniform(1, 5)
        for load, label in ((matched, "matched"), (unseen, kind)):
            out.append(_run(model, design, unmeasured, case, seed, load, label,
                            0.6 * duration, dt, s + 7, start, 200))
    if steady:
        s = int(rng.integers(10_000))
        load = [plc.HarmonicForce(1.0, f_sine, p_sine, phase=rng.uniform(0, 6)),
                plc.RandomForce(1.0, p_random, band, seed=s)]
        n_t = int(round(1.8 * duration / dt)) + 1
        out.append(_run(model, design, unmeasured, case, seed, load, "steady", 1.8 * duration,
                        dt, s + 7, rng.uniform(1, 5), 2 * n_t // 3))
    return out


def _run(model, design, unmeasured, case, seed, load, label, duration, dt, noise_seed, start,
         first) -> Run:
    """One new run of ``load`` through the design's filter, judged from sample ``first``."""
    test = plc.simulate(model, load, duration=duration, dt=dt, noise_std=design.noise_std,
                        seed=noise_seed, start_time=start)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        est = design.filter.filter(test.displacement[design.sensors])
    warned = any(issubclass(w.category, plc.EstimatorInconsistentWarning) for w in caught)
    c = est.consistency
    above = int(np.sum(c.window_nis[c.rejected] > c.window_bounds[c.rejected, 1]))
    ok_nis = bool(above <= _allowed(c.n_tested))
    truth = test.true_displacement[unmeasured, first:]
    err = est.field[unmeasured, first:] - truth
    rms_err = float(np.sqrt(np.mean(err**2)))
    reported = float(np.sqrt(np.mean(est.field_variances[unmeasured, first:])))
    snr = float(np.sqrt(np.mean(test.true_displacement[design.sensors] ** 2)) / design.noise_std)
    ratio = (float(np.nanmax(c.spectral_ratio[1:])) if c.spectral_ratio is not None
             else float("nan"))
    return Run(case, seed, label, warned, ok_nis, c.spectral_consistent, ratio,
               rms_err / float(np.sqrt(np.mean(truth**2))), reported / rms_err, snr,
               design.coverage.outside_share(test.displacement[design.sensors]),
               design.held_out_sigma_ratio,
               tuple(np.nan_to_num(c.spectral_ratio).tolist())
               if c.spectral_ratio is not None else (),
               tuple(design.filter.spectral_reference.tolist())
               if design.filter.spectral_reference is not None else ())


def _allowed(n_tested: int) -> int:
    import scipy.stats as sstats
    return int(sstats.binom.ppf(0.99, n_tested, 0.01)) if n_tested else 0


def rates(runs: list[Run]) -> dict:
    """Detection over all mismatched runs (raw) and over the visible ones (:attr:`Run.visible`),
    false alarms over matched runs from rest and over steady runs, and calibration."""
    matched = [r for r in runs if r.kind == "matched"]
    mismatched = [r for r in runs if r.kind in ("above", "elsewhere")]
    visible = [r for r in mismatched if r.visible]
    steady = [r for r in runs if r.kind == "steady"]
    ratios = np.array([r.reported_over_actual for r in matched])
    return {
        "detected": sum(r.warned for r in mismatched), "n_mismatched": len(mismatched),
        "detected_visible": sum(r.warned for r in visible), "n_visible": len(visible),
        "false_alarms": sum(r.warned for r in matched), "n_matched": len(matched),
        "steady_false_alarms": sum(r.warned for r in steady), "n_steady": len(steady),
        "calibration_median": float(np.median(ratios)) if ratios.size else float("nan"),
        "calibration_range": (float(ratios.min()), float(ratios.max())) if ratios.size
        else (float("nan"),) * 2,
    }


# ------------------------------------------------------------------ a broadband long span
def drake_broadband_loads(seed: int) -> list:
    """Two broadband loads to 10 Hz at 93 m and 231 m of the Drake 300 m span (a load history
    per seed): the case where one record's held-out end understates the error on new runs."""
    return [plc.RandomForce(1.0, 93.0, 10.0, seed=seed),
            plc.RandomForce(1.0, 231.0, 10.0, seed=seed + 1)]


@functools.lru_cache(maxsize=1)
def drake_broadband_record():
    """(model, training record): Drake 300 m clamped at 20 % RTS, 300 elements, 30 s of
    :func:`drake_broadband_loads` (seed 3) at 4 ms with 1 % sensor noise (simulated once per
    process: the count and calibration tests share it)."""
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    model = plc.LineModel(span, n_elements=300, bc="clamped")
    return model, plc.simulate(model, drake_broadband_loads(3), 30.0, 4e-3, noise_fraction=0.01,
                               seed=0)
