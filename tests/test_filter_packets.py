"""KalmanFilter.step_block of a converged filter through the closed loop's modal form
(estimate._packet.ModalPacket) against a straightforward per-sample loop.

The reference is the textbook predict-update recursion written out per sample with the filter's
steady gain (x = A x + B u[k-1]; e = y - C x - D u; x = x + K e): nothing of the closed loop,
its eigenvectors or the packets. The modal form is equal to it to round-off, which grows with the
eigenvector matrix's condition number; past ``_packet.MAX_CONDITION`` (a Jordan block) the
stepped loop is kept, and that must agree as well.
"""

from __future__ import annotations

import control as ct
import numpy as np
import pytest
import scipy.linalg as sla

import powerline_control as plc
from powerline_control.estimate._packet import MAX_CONDITION, ModalPacket


def oscillators(n_pairs, p, seed, *, n_inputs=0, radius=(0.95, 0.995), feedthrough=True):
    """A random discrete system of damped oscillators mixed by a random orthogonal basis, with
    one real pole, and a dense C."""
    rng = np.random.default_rng(seed)
    blocks = [np.array([[0.3]])]
    for _ in range(n_pairs):
        r, theta = rng.uniform(*radius), rng.uniform(0.05, 2.5)
        blocks.append(r * np.array([[np.cos(theta), -np.sin(theta)],
                                    [np.sin(theta), np.cos(theta)]]))
    n = 2 * n_pairs + 1
    basis, _ = np.linalg.qr(rng.normal(size=(n, n)))
    a = basis @ sla.block_diag(*blocks) @ basis.T
    c = rng.normal(size=(p, n))
    if n_inputs:
        b = rng.normal(size=(n, n_inputs))
        d = 0.1 * rng.normal(size=(p, n_inputs)) if feedthrough else np.zeros((p, n_inputs))
    else:
        b, d = np.zeros((n, 1)), np.zeros((p, 1))
    return ct.ss(a, b, c, d, dt=1e-3)


def record(system, n_t, seed, n_inputs):
    """Measurements of the system driven by noise (and inputs), ``(y, u)``."""
    rng = np.random.default_rng(seed)
    a, b, c, d = (np.asarray(m) for m in (system.A, system.B, system.C, system.D))
    u = rng.normal(size=(n_inputs, n_t)) if n_inputs else np.zeros((b.shape[1], n_t))
    x, y = np.zeros(a.shape[0]), np.empty((c.shape[0], n_t))
    for k in range(n_t):
        if k:
            x = a @ x + b @ u[:, k - 1] + 0.03 * rng.normal(size=x.size)
        y[:, k] = c @ x + d @ u[:, k] + 0.1 * rng.normal(size=c.shape[0])
    u = u if n_inputs else None
    return y, u


def per_sample(system, gain, y, u):
    """The textbook recursion with a constant gain, one sample at a time, from x0 = 0 (the
    prior describes sample 0: no prediction before its update)."""
    a, b, c, d = (np.asarray(m) for m in (system.A, system.B, system.C, system.D))
    u = np.zeros((b.shape[1], y.shape[1])) if u is None else u
    x, states, innovations = np.zeros(a.shape[0]), np.empty((a.shape[0], y.shape[1])), []
    for k in range(y.shape[1]):
        if k:
            x = a @ x + b @ u[:, k - 1]
        e = y[:, k] - c @ x - d @ u[:, k]
        x = x + gain @ e
        states[:, k] = x
        innovations.append(e)
    return states, np.array(innovations).T


def packets(kf, y, u, cuts):
    """``step_block`` over the record cut at ``cuts``."""
    return np.hstack([kf.step_block(y[:, a:b], None if u is None else u[:, a:b])
                      for a, b in zip(cuts[:-1], cuts[1:], strict=True)])


def rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ------------------------------------------------------------------ the packets' modal form


@pytest.mark.parametrize("length", [1, 2, 3, 10, 16, 64, 65, 300])
def test_modal_packet_is_the_recursion_it_diagonalises(length):
    # Packets of 1-64 samples take the scaled scan, longer ones the doubling scan; either is
    # the loop x[k] = F x[k-1] + G w[k] with outputs O x[k-1] + H w[k], written out here.
    rng = np.random.default_rng(length)
    system = oscillators(6, 3, seed=1)
    f = 0.9 * np.asarray(system.A)
    g, o, h = rng.normal(size=(13, 4)), rng.normal(size=(2, 13)), rng.normal(size=(2, 4))
    packet = ModalPacket.build(f, g, o, h)
    assert packet is not None
    w, x0 = rng.normal(size=(4, length)), rng.normal(size=13)
    x, states, outputs = x0, np.empty((13, length)), np.empty((2, length))
    for k in range(length):
        outputs[:, k] = o @ x + h @ w[:, k]
        x = f @ x + g @ w[:, k]
        states[:, k] = x
    got, modal, got_outputs, seen = packet.run(packet.modal(x0), w.T.copy(), o @ x0)
    assert rel(got, states) < 1e-12
    assert rel(got_outputs, outputs) < 1e-12
    assert rel(seen, o @ states[:, -1]) < 1e-12
    assert rel(packet.modal(states[:, -1]), modal[-1]) < 1e-12


def test_an_eigenvalue_at_zero_takes_the_doubling_scan():
    # lambda^-j of the scaled scan does not exist for lambda = 0 (a dead-beat mode): that packet
    # goes through the doubling scan, and it is still the loop.
    f = np.diag([0.0, 0.5, -0.8])
    g, o, h = np.eye(3), np.ones((1, 3)), np.zeros((1, 3))
    packet = ModalPacket.build(f, g, o, h)
    w = np.arange(30.0).reshape(3, 10)
    x, states = np.array([1.0, 2.0, 3.0]), np.empty((3, 10))
    z0 = packet.modal(x)
    for k in range(10):
        x = f @ x + w[:, k]
        states[:, k] = x
    got = packet.run(z0, w.T.copy(), np.zeros(1))[0]
    assert packet.scaled[10] is None
    assert rel(got, states) < 1e-14


def test_a_jordan_block_keeps_the_stepped_loop():
    # A defective closed loop has no eigenvector basis; nearly defective, a badly conditioned
    # one whose round-off would exceed the bound.
    jordan = np.array([[0.9, 1.0], [0.0, 0.9]])
    args = (np.eye(2), np.ones((1, 2)), np.zeros((1, 2)))
    assert ModalPacket.build(jordan, *args) is None
    split = jordan + np.array([[0.0, 0.0], [1e-14, 0.0]])   # eigenvalues 0.9 +- 1e-7
    assert np.linalg.cond(np.linalg.eig(split)[1]) > MAX_CONDITION
    assert ModalPacket.build(split, *args) is None
    assert ModalPacket.build(np.diag([0.9, 0.8]), *args) is not None


# ------------------------------------------------------------------ the filter's packets


@pytest.mark.parametrize("n_inputs, feedthrough", [(0, False), (2, False), (2, True)])
def test_step_block_of_a_converged_filter_against_a_per_sample_loop(n_inputs, feedthrough):
    system = oscillators(8, 3, seed=3, n_inputs=n_inputs, feedthrough=feedthrough)
    n = system.nstates
    y, u = record(system, 1200, seed=4, n_inputs=n_inputs)
    kf = plc.KalmanFilter(system, 1e-3 * np.eye(n), 1e-2 * np.eye(3), steady_state=True,
                          consistency_window=100)
    # uneven packets: 1 (the prior's sample, stepped), then the modal form from sample 1 on
    got = packets(kf, y, u, [0, 1, 11, 21, 24, 88, 89, 500, 1200])
    assert kf._running.packet_form() is not None   # the modal form was used
    states, innovations = per_sample(system, kf.steady_gain, y, u)
    assert rel(got, states) < 1e-11
    np.testing.assert_array_equal(kf.state, got[:, -1])
    # The consistency windows: the mean NIS of the loop's innovations, whitened by S.
    s = kf.innovation_covariance
    nis = np.einsum("ik,ij,jk->k", innovations, np.linalg.inv(s), innovations)
    np.testing.assert_allclose(kf.consistency.window_nis, nis.reshape(-1, 100).mean(axis=1),
                               rtol=1e-9)


def test_step_and_step_block_interleaved_stay_in_step():
    # step() replaces the state: the next packet starts its modal state from it, not from the
    # modal state the last packet carried.
    system = oscillators(6, 2, seed=5, n_inputs=1)
    y, u = record(system, 400, seed=6, n_inputs=1)
    q, r = 1e-3 * np.eye(system.nstates), 1e-2 * np.eye(2)
    mixed = plc.KalmanFilter(system, q, r, steady_state=True)
    out = []
    for start in range(0, 400, 20):
        out.append(mixed.step_block(y[:, start : start + 10], u[:, start : start + 10]))
        out.extend(mixed.step(y[:, k], u[:, k])[:, None] for k in range(start + 10, start + 20))
    states, _ = per_sample(system, mixed.steady_gain, y, u)
    assert rel(np.hstack(out), states) < 1e-11


def test_fallback_when_the_closed_loop_is_nearly_defective():
    # A Jordan block seen through a very noisy sensor: the gain is tiny, the closed loop is the
    # Jordan block split by ~sqrt(K), its eigenvectors nearly parallel (cond > MAX_CONDITION).
    a = np.array([[0.9, 1.0, 0.0], [0.0, 0.9, 0.0], [0.0, 0.0, 0.5]])
    c = np.array([[1.0, 0.0, 1.0]])
    system = ct.ss(a, np.zeros((3, 1)), c, np.zeros((1, 1)), dt=1)
    kf = plc.KalmanFilter(system, 1e-6 * np.eye(3), 1e10, steady_state=True)
    closed = (np.eye(3) - kf.steady_gain @ c) @ a
    assert np.linalg.cond(np.linalg.eig(closed)[1]) > MAX_CONDITION
    y = np.sin(0.05 * np.arange(300))[None, :] + 0.01 * np.cos(np.arange(300))[None, :]
    got = packets(kf, y, None, list(range(0, 301, 10)))
    assert kf._running.packet_form() is None   # the stepped loop
    states, _ = per_sample(system, kf.steady_gain, y, None)
    assert rel(got, states) < 1e-12


def lightly_damped_filter():
    """A closed loop with |lambda| up to 0.998 and well-conditioned eigenvectors."""
    system = oscillators(10, 3, seed=7, radius=(0.99, 0.9995))
    y, _ = record(system, 20_000, seed=8, n_inputs=0)
    kf = plc.KalmanFilter(system, 1e-8 * np.eye(system.nstates), 1e-2 * np.eye(3),
                          steady_state=True)
    return system, kf, y


def near_the_bound_filter():
    """The Jordan block of the fallback test seen through a less noisy sensor: cond(V) 2e5,
    a fifth of MAX_CONDITION, so the modal form is used."""
    a = np.array([[0.9, 1.0, 0.0], [0.0, 0.9, 0.0], [0.0, 0.0, 0.5]])
    c = np.array([[1.0, 0.0, 1.0]])
    system = ct.ss(a, np.zeros((3, 1)), c, np.zeros((1, 1)), dt=1)
    kf = plc.KalmanFilter(system, 1e-6 * np.eye(3), 1e6, steady_state=True)
    t = np.arange(20_000)
    y = (np.sin(0.05 * t) + 0.3 * np.sin(0.71 * t))[None, :]
    return system, kf, y


@pytest.mark.parametrize("make, bound", [(lightly_damped_filter, 1e-11),
                                         (near_the_bound_filter, 1e-9)])
def test_twenty_thousand_samples_do_not_drift(make, bound):
    # 20 000 samples in the loop's 10-sample packets stay at round-off of the per-sample loop
    # at the end, not only at the start: the carried modal state does not drift. The bound
    # allows for the loops' own round-off (measured: 2.4e-13 with |lambda| 0.998, 3e-15 at
    # cond(V) 2e5) and for cond(V) * eps near MAX_CONDITION.
    system, kf, y = make()
    got = packets(kf, y, None, list(range(0, 20_001, 10)))
    assert kf._running.packet_form() is not None
    states, _ = per_sample(system, kf.steady_gain, y, None)
    assert rel(got, states) < bound
    assert rel(got[:, -1000:], states[:, -1000:]) < bound
