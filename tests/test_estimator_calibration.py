"""Issue 19, part 1: the reported sigma on new load histories, with ``model_error_records``.

Truth is the simulation's noise-free field on runs of load histories that neither the training
record nor the model-error records hold; the filter's reported sigma is judged against it.
"""

import dataclasses
import warnings

import numpy as np
import pytest

import powerline_control as plc


def _ratio(design, run, unmeasured, skip=200):
    """Reported over actual RMS error at ``unmeasured`` (actual against the true field)."""
    est = design.filter.filter(run.displacement[design.sensors])
    truth = run.true_displacement[unmeasured, skip:]
    actual = np.sqrt(np.mean((est.field[unmeasured, skip:] - truth) ** 2))
    return float(np.sqrt(np.mean(est.field_variances[unmeasured, skip:])) / actual)


def test_drake_model_error_level_from_other_load_histories_holds_on_new_runs():
    """Drake 300 m clamped, two broadband loads to 10 Hz, 24 sensors, 30 s. With the level of
    the model-error terms from the held-out part (which continues the training loads) the
    reported sigma on new runs is 0.60-0.72 x the actual error (measured on five runs); from two
    records of other load histories (same sensor noise), 0.87-1.04. Asserted on two of those
    runs, whose loads are in no record the design saw: within the issue's factor 1.5 with the
    records, below 1 / 1.5 without."""
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    model = plc.LineModel(span, n_elements=300, bc="clamped")

    def loads(seed):
        return [plc.RandomForce(1.0, 93.0, 10.0, seed=seed),
                plc.RandomForce(1.0, 231.0, 10.0, seed=seed + 1)]

    rec = plc.simulate(model, loads(3), 30.0, 4e-3, noise_fraction=0.01, seed=0)
    others = [plc.simulate(model, loads(s), 30.0, 4e-3, noise_std=rec.noise_std, seed=s + 100)
              for s in (43, 53)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.ExcitationWarning)
        plain = plc.design_estimator(rec, n_sensors=24, seed=0)
        design = plc.design_estimator(rec, n_sensors=24, seed=0, model_error_records=others)
    assert design.model_error_records == 2 and plain.model_error_records == 0
    np.testing.assert_array_equal(design.sensors, plain.sensors)  # only the sigma changes
    assert "2 record(s) of other load histories" in design.summary()
    moving = np.flatnonzero(np.std(rec.true_displacement, axis=1) > 0)
    unmeasured = np.setdiff1d(moving, design.sensors)
    for seed in (13, 33):
        run = plc.simulate(model, loads(seed), 30.0, 4e-3, noise_std=design.noise_std,
                           seed=seed + 100)
        assert _ratio(plain, run, unmeasured) < 1 / 1.5
        assert 1 / 1.5 < _ratio(design, run, unmeasured) < 1.5


def test_model_error_level_matches_the_records_it_was_measured_on():
    """The defining property: filtering the model-error record itself, the reported variance at
    the unmeasured moving nodes, pooled over them and the samples after the first window, is
    the actual error variance there with the record's sensor noise variance removed (the field
    scale is not clipped here). Lab span, 20 elements, broadband loads."""
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)

    def loads(seed):
        return [plc.RandomForce(1.0, 0.9, 80.0, seed=seed),
                plc.RandomForce(1.0, 2.6, 80.0, seed=seed + 1)]

    rec = plc.simulate(model, loads(3), 3.0, 1e-3, noise_fraction=0.01, seed=0)
    other = plc.simulate(model, loads(23), 2.0, 1e-3, noise_std=rec.noise_std, seed=7)
    design = plc.design_estimator(rec, n_sensors=3, seed=0, delays=4, rank=12,
                                  model_error_records=other)
    assert design.model_error_records == 1
    assert 0.01 < design.field_variance_scale < 100  # not clipped
    est = design.filter.filter(other.displacement[design.sensors])
    unmeasured = np.setdiff1d(np.arange(1, 20), design.sensors)  # pinned: nodes 0, 20 still
    error2 = np.mean((est.field[unmeasured, 200:] - other.displacement[unmeasured, 200:]) ** 2)
    reported = np.mean(est.field_variances[unmeasured, 200:])
    assert reported == pytest.approx(error2 - other.noise_std**2, rel=1e-6)


def test_model_error_records_bad_input():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    rec = plc.simulate(model, plc.RandomForce(1.0, 0.9, 80.0, seed=3), 1.0, 1e-3,
                       noise_fraction=0.01, seed=0)
    with pytest.raises(plc.InputError, match="'model_error_records'.*record 0 must be a "
                                             "Snapshots"):
        plc.design_estimator(rec, model_error_records=[rec.displacement])
    moved = dataclasses.replace(rec, x=rec.x * 1.01)
    with pytest.raises(plc.InputError, match="'model_error_records'.*record 0.*node positions"):
        plc.design_estimator(rec, model_error_records=moved)
    with pytest.raises(plc.InputError, match="'model_error_records'.*same 21 nodes at the same "
                                             "dt"):
        plc.design_estimator(rec, model_error_records=dataclasses.replace(rec, dt=2e-3))
    with pytest.raises(plc.InputError, match="'model_error_records'.*sequence"):
        plc.design_estimator(rec, model_error_records=[])
