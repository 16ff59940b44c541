"""The reported sigma on new load histories, with ``model_error_records``.

Truth is the simulation's noise-free field on runs of load histories that neither the training
record nor the model-error records hold; the filter's reported sigma is judged against it.
"""

import dataclasses
import warnings

import numpy as np
import pytest
from estimator_family import drake_broadband_loads, drake_broadband_record

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
    runs, whose loads are in no record the design saw: within a factor 1.5 with the
    records, below 1 / 1.5 without."""
    model, rec = drake_broadband_record()
    loads = drake_broadband_loads
    others = [plc.simulate(model, loads(s), 30.0, 4e-3, noise_std=rec.noise_std, seed=s + 100)
              for s in (43, 53)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.ExcitationWarning)
        plain = plc.design_estimator(rec, n_sensors=24, seed=0)
        design = plc.design_estimator(rec, n_sensors=24, seed=0, model_error_records=others)
    assert design.n_model_error_records == 2 and plain.n_model_error_records == 0
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
    assert design.n_model_error_records == 1
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


# ---------------------------------------------------------------------------------------------
# The records are never silently dropped (review of the model_error_records feature).

def _lab_loads(seed):
    return [plc.RandomForce(1.0, 0.9, 80.0, seed=seed),
            plc.RandomForce(1.0, 2.6, 80.0, seed=seed + 1)]


@pytest.fixture(scope="module")
def lab_records():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    rec = plc.simulate(model, _lab_loads(3), 3.0, 1e-3, noise_fraction=0.01, seed=0)
    other = plc.simulate(model, _lab_loads(23), 2.0, 1e-3, noise_std=rec.noise_std, seed=7)
    return model, rec, other


def _assert_level_defined_by(design, other):
    """The defining property of the records' level (see the test above): on the record, the
    reported variance at the unmeasured moving nodes after the first window is the actual error
    variance less the record's noise variance."""
    est = design.filter.filter(other.displacement[design.sensors])
    unmeasured = np.setdiff1d(np.arange(1, 20), design.sensors)
    error2 = np.mean((est.field[unmeasured, 200:] - other.displacement[unmeasured, 200:]) ** 2)
    reported = np.mean(est.field_variances[unmeasured, 200:])
    assert reported == pytest.approx(error2 - other.noise_std**2, rel=1e-6)


def test_records_set_the_level_when_the_held_out_part_is_too_short(lab_records):
    """A held-out part of 150 samples (< the 200-sample window) gives no held-out level; the
    records still set it, by their defining property."""
    _, rec, other = lab_records
    with warnings.catch_warnings():
        warnings.simplefilter("error", plc.errors.ModelErrorRecordsWarning)
        design = plc.design_estimator(rec, n_sensors=3, seed=0, delays=4, rank=12,
                                      train_fraction=0.95, model_error_records=other)
        plain = plc.design_estimator(rec, n_sensors=3, seed=0, delays=4, rank=12,
                                     train_fraction=0.95)
    assert plain.n_model_error_records == 0 and plain.field_variance_scale == 1.0
    assert design.n_model_error_records == 1
    assert 0.01 < design.field_variance_scale < 100
    _assert_level_defined_by(design, other)


def test_records_set_the_level_when_the_partial_model_fails(lab_records, monkeypatch):
    """The model of the training part failing (no partial filter) still leaves the records'
    level, which needs no partial filter: it meets its defining property."""
    import sys

    from powerline_control.recipe import dmd

    _, rec, other = lab_records
    options = dict(n_sensors=3, seed=0, delays=4, rank=12, model_error_records=other)
    original = dmd._sweep_model

    def failing(*args, **kwargs):
        if sys._getframe(1).f_code.co_name == "_dmd_design":
            raise plc.IdentificationError("injected: the partial model fails")
        return original(*args, **kwargs)

    monkeypatch.setattr(dmd, "_sweep_model", failing)
    design = plc.design_estimator(rec, **options)
    assert design.n_model_error_records == 1
    # covariance_scale falls back without the partial model; the records' level is measured
    # on the shipped filter of that scale, so it still meets its defining property.
    _assert_level_defined_by(design, other)


def test_records_without_error_above_their_noise_warn_and_floor_the_terms(lab_records):
    """A record whose stated noise std is 20x its real one shows no error above it: the warning
    names the parameter and what would work; the terms go to their floor, not to (1, 0)."""
    _, rec, other = lab_records
    loud = dataclasses.replace(other, noise_std=20 * other.noise_std)
    with pytest.warns(plc.errors.ModelErrorRecordsWarning) as caught:
        design = plc.design_estimator(rec, n_sensors=3, seed=0, delays=4, rank=12,
                                      model_error_records=loud)
    messages = [str(w.message) for w in caught]
    assert any("'model_error_records'" in m and "no larger than their sensor noise" in m
               and "noise_std" in m for m in messages)
    assert any("record 0 has sensor noise std" in m and "1.5x" in m for m in messages)
    assert design.n_model_error_records == 1
    assert design.field_variance_scale == 0.01 and design.field_relative_variance == 0.0


def test_records_of_other_noise_warn(lab_records):
    """Records must carry the training record's sensor noise: 3x warns, naming the record."""
    model, rec, _ = lab_records
    noisy = plc.simulate(model, _lab_loads(23), 2.0, 1e-3, noise_std=3 * rec.noise_std, seed=7)
    with pytest.warns(plc.errors.ModelErrorRecordsWarning,
                      match="'model_error_records' parameter's record 0 has sensor noise std"):
        plc.design_estimator(rec, n_sensors=3, seed=0, delays=4, rank=12,
                             model_error_records=noisy)


def test_record_noise_std_zero_means_unknown(lab_records):
    """One rule for every record's own noise_std: 0 means unknown and is estimated (as for the
    training record), checked against the noise the simulation added."""
    from powerline_control.recipe.record import _other_records, _snapshot_matrix

    _, rec, other = lab_records
    unknown = dataclasses.replace(other, noise_std=0.0)
    _, sigmas = _other_records([unknown], "model_error_records", rec.x, 21, rec.dt)
    assert sigmas[0] == pytest.approx(other.noise_std, rel=0.2)
    assert np.isnan(_snapshot_matrix(dataclasses.replace(rec, noise_std=0.0), None)[2])
    # the parameter's 0 stays "noise-free"
    _, given = _other_records([unknown], "check", rec.x, 21, rec.dt, noise_std=0.0,
                              noise_name="check_noise_std")
    assert given == [0.0]


def test_records_with_the_modal_model():
    """method='modal' has no model-error terms: records raise InputError naming them; 'auto'
    choosing the modal model warns that they were not used."""
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    rec = plc.simulate(model, plc.HarmonicForce(1.0, 14.2, 2.3), 2.0, 1e-3,
                       noise_fraction=0.01, seed=0)
    other = plc.simulate(model, plc.HarmonicForce(1.0, 14.2, 1.1), 2.0, 1e-3,
                         noise_std=rec.noise_std, seed=1)
    with pytest.raises(plc.InputError, match="'model_error_records'.*method='modal'"):
        plc.design_estimator(rec, n_sensors=3, method="modal", model_error_records=other)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        design = plc.design_estimator(rec, n_sensors=3, seed=0, model_error_records=other)
    assert design.excitation.method == "modal"
    assert any(issubclass(w.category, plc.errors.ModelErrorRecordsWarning)
               and "'model_error_records'" in str(w.message) and "method='dmd'" in str(w.message)
               for w in caught)


@pytest.mark.slow   # six estimator designs: 70 s; the held-out level's rules run above
def test_a_2_s_record_matches_its_covariance_from_two_held_out_windows():
    """A 2 s record holds out 600 samples: two consistency windows after the first, too few
    for a spread (``nis_dof_fraction`` stays 1) but enough for the scale. Truth: on new 2 s
    records of the same load statistics (other random force and noise), the mean NIS per sensor
    should be 1 (chi-square). Measured on six seeds: matched 0.41-2.16 (median 0.87), the
    scale 1 it had before 1.30-5.36 (median 1.9)."""
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=40)

    def loads(seed):
        return [plc.HarmonicForce(1.0, 24.0, 0.5), plc.RandomForce(0.3, 1.7, 60.0, seed=seed)]

    matched, unmatched = [], []
    for seed in range(6):
        record = plc.simulate(model, loads(seed), 2.0, 1e-3, noise_fraction=0.01, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", plc.ExcitationWarning)
            design = plc.design_estimator(record, 3, seed=0)
        assert design.filter.nis_dof_fraction == 1.0 and design.covariance_scale != 1.0
        new = plc.simulate(model, loads(100 + seed), 2.0, 1e-3, noise_std=record.noise_std,
                           seed=100 + seed, start_time=3.0)
        nis = design.filter.filter(new.displacement[design.sensors]).nis[200:]
        matched.append(float(np.mean(nis)) / design.sensors.size)
        unmatched.append(matched[-1] * design.covariance_scale)
    assert 0.75 < np.median(matched) < 1.25, matched
    assert np.median(unmatched) > 1.25, unmatched
    assert np.median(np.abs(np.log(matched))) < np.median(np.abs(np.log(unmatched)))
