"""KalmanFilter's adaptive process noise (``adapt_horizon``) and ``recovery_time``.

Independent truth: systems simulated here with a known process-noise covariance ``q_true Q0``;
the filter is told ``Q0`` and must find ``q_true``. The optimal filter is the covariance
matching's fixed point (``E[e^T R^-1 e] = tr(R^-1 C A P A^T C^T) + p + q tr(R^-1 C Q0 C^T)``
holds exactly at ``q = q_true``), so the matched scale converges to ``q_true`` up to its
sampling spread: about ``S / (q b sqrt(h))`` relative for a horizon of ``h`` samples (4-7 % for
the cases below), less for the median over several horizons. Tolerances are about 3 of those.
"""

import control as ct
import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import InputError


def _simulate(a, c, q_true, q0, r, n_t, seed):
    """``x[k+1] = a x[k] + w``, ``w ~ N(0, q_true q0)``; ``y = c x + v``, ``v ~ N(0, r)``."""
    rng = np.random.default_rng(seed)
    a, c, q0 = np.atleast_2d(a), np.atleast_2d(c), np.atleast_2d(q0)
    chol = np.linalg.cholesky(q_true * q0)
    x = np.zeros(a.shape[0])
    y = np.empty((c.shape[0], n_t))
    for k in range(n_t):
        y[:, k] = c @ x + rng.normal(size=c.shape[0]) * np.sqrt(r)
        x = a @ x + chol @ rng.normal(size=a.shape[0])
    return y


@pytest.mark.parametrize("q_true", [0.25, 4.0])
def test_random_walk_scale_is_recovered(q_true):
    # A random walk told Q0 = 1 with true Q = q_true: the matched q converges to q_true.
    y = _simulate(1.0, 1.0, q_true, 1.0, 1.0, 3000, seed=1)
    sys = ct.ss([[1.0]], [[0.0]], [[1.0]], 0, dt=1.0)
    est = plc.KalmanFilter(sys, Q=1.0, R=1.0, adapt_horizon=600).filter(y)
    q = est.process_noise_scale
    assert q.shape == (3000,)
    assert np.median(q[1500:]) == pytest.approx(q_true, rel=0.15)
    # ... and the filter is then consistent: mean NIS per sample near 1 (the matched S).
    assert np.nanmean(est.nis[1500:]) == pytest.approx(1.0, abs=0.1)


def test_two_state_oscillator_scale_is_recovered():
    # A lightly damped oscillator (a line's mode), position measured, Q0 a full 2x2 shape.
    theta, rho = 0.2, 0.995
    a = rho * np.array([[np.cos(theta), np.sin(theta)], [-np.sin(theta), np.cos(theta)]])
    c = np.array([[1.0, 0.0]])
    q0 = np.array([[1.0, 0.3], [0.3, 0.5]])
    y = _simulate(a, c, 0.3, q0, 0.5, 3000, seed=2)
    sys = ct.ss(a, np.zeros((2, 1)), c, 0, dt=1e-3)
    est = plc.KalmanFilter(sys, Q=q0, R=0.5, adapt_horizon=600).filter(y)
    assert np.median(est.process_noise_scale[1500:]) == pytest.approx(0.3, rel=0.2)


def test_step_follows_filter_and_default_is_unchanged():
    # The real-time recursion adapts as filter does; without a horizon nothing changes.
    y = _simulate(0.95, 1.0, 2.0, 1.0, 1.0, 300, seed=3)
    sys = ct.ss([[0.95]], [[0.0]], [[1.0]], 0, dt=1.0)
    kf = plc.KalmanFilter(sys, Q=1.0, R=1.0, adapt_horizon=50)
    est = kf.filter(y)
    stepped = np.column_stack([kf.step(y[:, k]) for k in range(y.shape[1])])
    np.testing.assert_allclose(stepped, est.states, rtol=1e-12, atol=1e-12)
    assert kf.process_noise_scale == pytest.approx(est.process_noise_scale[-1], rel=1e-12)
    assert kf.adapt_horizon == 50
    plain = plc.KalmanFilter(sys, Q=1.0, R=1.0)
    assert plain.filter(y).process_noise_scale is None and plain.process_noise_scale == 1.0


def test_recovery_after_a_step_in_the_process_noise():
    # Q jumps 100-fold at sample 2000: the adaptive filter's windowed NIS is back within its
    # bounds within two horizons, the fixed filter's never; the error's recovery is measured
    # against the truth.
    rng = np.random.default_rng(0)
    n_t, change = 4000, 2000
    w = rng.normal(size=n_t) * np.where(np.arange(n_t) < change, 0.1, 1.0)
    x = np.cumsum(w)
    y = (x + rng.normal(size=n_t))[None, :]
    sys = ct.ss([[1.0]], [[0.0]], [[1.0]], 0, dt=1e-3)
    adaptive = plc.KalmanFilter(sys, Q=0.01, R=1.0, adapt_horizon=400).filter(y)
    fixed = plc.KalmanFilter(sys, Q=0.01, R=1.0).filter(y)
    rec = adaptive.recovery(change, x[None, :])
    assert rec.nis_samples is not None and 0 < rec.nis_samples <= 800
    assert rec.error_samples is not None and rec.error_samples <= 800
    assert rec.time == max(rec.nis_time, rec.error_time)
    never = plc.estimate.recovery_time(fixed, change)
    assert never.nis_samples is None and never.nis_time == np.inf
    assert np.isnan(never.error_time)


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"adapt_horizon": 1}, ["'adapt_horizon'", ">= 2", "1"]),
    ({"adapt_horizon": 2.5}, ["'adapt_horizon'", "integer", "2.5"]),
    ({"adapt_horizon": True}, ["'adapt_horizon'", "True"]),
    ({"adapt_horizon": 10, "steady_state": True}, ["'adapt_horizon'", "steady_state=False"]),
    ({"adapt_horizon": 10, "adapt_range": (2.0, 3.0)}, ["'adapt_range[0]'", "2.0"]),
    ({"adapt_horizon": 10, "adapt_range": (0.1,)}, ["'adapt_range'", "(low, high)"]),
])
def test_bad_adaptation_arguments_are_named(kwargs, words):
    sys = ct.ss([[1.0]], [[0.0]], [[1.0]], 0, dt=1.0)
    with pytest.raises(InputError) as info:
        plc.KalmanFilter(sys, Q=1.0, R=1.0, **kwargs)
    for word in words:
        assert word in str(info.value)


def test_bad_recovery_arguments_are_named():
    sys = ct.ss([[0.9]], [[0.0]], [[1.0]], 0, dt=1.0)
    y = np.random.default_rng(0).normal(size=(1, 1000))
    est = plc.KalmanFilter(sys, Q=0.1, R=1.0).filter(y)
    for kwargs, word in (({"change_at": 1000}, "'change_at'"), ({"change_at": 0}, "'change_at'"),
                         ({"change_at": 500, "hold": 0}, "'hold'"),
                         ({"change_at": 500, "factor": 0.5}, "'factor'"),
                         ({"change_at": 500, "truth": np.zeros((2, 1000))}, "'truth'")):
        with pytest.raises(InputError, match=word):
            plc.estimate.recovery_time(est, **kwargs)
    silent = plc.KalmanFilter(sys, Q=0.1, R=1.0, consistency_window=None).filter(y)
    with pytest.raises(InputError, match="no windowed NIS test"):
        silent.recovery(500)


def test_design_estimator_rejects_a_bad_horizon_before_identifying():
    snap = np.random.default_rng(0).normal(size=(5, 400))
    with pytest.raises(InputError, match="'adapt_horizon'.*>= 2"):
        plc.design_estimator(snap, n_sensors=2, dt=1e-3, adapt_horizon=1)
