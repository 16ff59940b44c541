"""Tests of recipe.py: design_estimator and EstimatorDesign.

Independent truths: python-control's ``dlqe`` (the steady-state predictor gain of the same model
and sensors), a plain-numpy filter loop written here, and independent FE simulations of new runs
(never the identified model) for the accuracy claims.
"""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import InputError
from powerline_control.estimate import estimation_accuracy


@pytest.fixture(scope="module")
def small_design():
    """20-element lab span, broadband training record, 1 % noise."""
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    snap = plc.simulate(model, plc.RandomForce(1.0, 1.3, 90.0, seed=4), duration=4.0, dt=1e-3,
                        noise_fraction=0.01, seed=2)
    design = plc.design_estimator(snap, n_sensors=3, delays=4, rank=12, seed=0)
    return model, snap, design


def test_filter_gain_equals_python_control_dlqe(small_design):
    _, _, design = small_design
    m = design.model
    C = np.asarray(m.field_map)[design.sensors]
    R = design.noise_std**2 * np.eye(design.sensors.size)
    Q = np.asarray(m.residual_covariance)
    # dlqe returns the predictor gain L = A P C^T (C P C^T + R)^-1 = A K (filter form K).
    L, P, _ = ct.dlqe(np.asarray(m.A), np.eye(m.n_states), C, Q, R)
    K = design.filter.steady_gain
    # Both solve the same DARE; agreement to ~1e-8 relative allows for the two solvers' round-off.
    assert np.allclose(np.asarray(m.A) @ K, L, rtol=1e-6, atol=1e-8 * np.abs(L).max())


def test_estimate_field_equals_a_plain_filter_loop(small_design):
    _, snap, design = small_design
    m = design.model
    y = snap.displacement[design.sensors, :300]
    A, C = np.asarray(m.A), np.asarray(m.field_map)[design.sensors]
    K = design.filter.steady_gain
    x = np.zeros(m.n_states)
    fields = []
    for k in range(y.shape[1]):
        prior = x if k == 0 else A @ x                     # prior of sample 0: x0 = 0
        x = prior + K @ (y[:, k] - C @ prior)
        fields.append(np.asarray(m.field_map) @ x)
    expected = np.array(fields).T
    got = design.estimate_field(y)
    # Same recursion in a different order of operations: round-off only.
    assert np.allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())


def test_sensors_avoid_the_supports_and_summary_names_them(small_design):
    _, snap, design = small_design
    assert design.sensors.size == 3
    assert 0 not in design.sensors and snap.x.size - 1 not in design.sensors  # pinned ends
    text = design.summary()
    assert str(design.sensors.tolist()) in text and "delays" in text


def test_small_span_estimates_a_new_broadband_run(small_design):
    model, snap, design = small_design
    test = plc.simulate(model, plc.RandomForce(1.0, 1.3, 90.0, seed=9), duration=3.0, dt=1e-3,
                        noise_fraction=0.01, seed=7, start_time=1.1)
    field = design.estimate_field(test.displacement[design.sensors])
    acc = estimation_accuracy(field, test.true_displacement, measured=design.sensors,
                              discard=300)
    print(f"small span, new broadband run: {acc.relative_rms_error_unmeasured:.2%}")
    # A different seed and load history than training, same sensors' noise fraction (1 %):
    # the 20-element span has only 19 moving nodes and 3 sensors; 10 % is a loose ceiling.
    assert acc.relative_rms_error_unmeasured < 0.10


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(n_sensors=0), InputError, "n_sensors"),
        (dict(n_sensors=2.5), InputError, "n_sensors"),
        (dict(delays=0), InputError, "delays"),
        (dict(rank=0), InputError, "rank"),
        (dict(spatial_rank=0), InputError, "spatial_rank"),
        (dict(criterion="best"), InputError, "criterion"),
        (dict(noise_std=-1.0), InputError, "noise_std"),
        (dict(noise_std=float("nan")), InputError, "noise_std"),
        (dict(sensors=[0, 0]), InputError, "sensors"),
        (dict(sensors=[99]), InputError, "sensors"),
        (dict(dt=0.5), InputError, "dt"),
    ],
)
def test_design_estimator_rejects_bad_input(small_design, kwargs, error, match):
    _, snap, _ = small_design
    with pytest.raises(error, match=match):
        plc.design_estimator(snap, **{"n_sensors": 3, "delays": 4, "rank": 12, **kwargs})


@pytest.mark.parametrize(
    "snapshots, kwargs, match",
    [
        (np.ones((3, 50)), {}, "dt"),                       # an array needs dt
        (np.zeros((4, 200)), {"dt": 1e-3}, "all zeros"),
        (np.full((4, 200), np.nan), {"dt": 1e-3}, "NaN"),
        (np.ones(200), {"dt": 1e-3}, "2-d"),
    ],
)
def test_design_estimator_rejects_bad_snapshots(snapshots, kwargs, match):
    with pytest.raises((InputError, plc.IdentificationError), match=match):
        plc.design_estimator(snapshots, n_sensors=1, delays=2, rank=2, **kwargs)


def test_estimate_field_rejects_wrong_shape(small_design):
    _, _, design = small_design
    with pytest.raises(InputError, match="measurements"):
        design.estimate_field(np.zeros((design.sensors.size + 1, 10)))
