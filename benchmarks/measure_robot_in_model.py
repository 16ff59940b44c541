"""Issue 37 item 2, measured: is the closed loop's estimator consistent while the robot moves?

Runs the closed loop (``plc.run_closed_loop``) on a few scenarios of ``tests/closed_loop_family``
and, on the run's own records (the sensors' noisy record, the robot's position, the plant's true
states for the robot's own force), compares three estimators by their windowed NIS: the share
of consistency windows (200 samples) inside their two-sided 1 % chi-square bounds, split by the
robot's phase (parked at its start, moving, settled after a move):

* ``today``: the recipe's estimator identified on the calibration window with the robot parked
  at its start (the run's ``estimator_consistency``);
* ``(b) force input``: the bare line's modal model (the span the controller is told, its modes in
  the band) with the robot's force on the line as a measured input, ``B n(x_r) f``, and the load
  as one undamped oscillator per mode at the tone the sensors measured in the calibration window;
* ``(a) robot in A``: the same modal model with the robot (body and absorber, at its own
  parameters) coupled into the state matrix at its current position, ``A(x_r)``.

Both (a) and (b) scale their process noise once, on the calibration window (covariance
matching: the mean NIS there equals the number of sensors), and never again. Usage::

    .venv/bin/python benchmarks/measure_robot_in_model.py [seed ...]

This is a measurement, not a controller: (a) and (b) are filtered offline on records the run
made; the robot's force is computed from the plant's true states (what its absorber's load
cell and body accelerometer would measure, plus their noise).
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))


import _common  # noqa: E402  (pins BLAS to one thread before numpy loads)
import closed_loop_family as fam  # noqa: E402
import numpy as np  # noqa: E402
import scipy.stats  # noqa: E402

from powerline_control.simulation.plant import ModalPlant  # noqa: E402

WINDOW = 200
LEVEL = 0.01


def phases(result, n_t, n_cal):
    """Per window start: 'start', 'moving', 'settled' (or None inside the calibration)."""
    moving = np.abs(np.asarray(result.robot_velocity)) > 1e-6   # m/s: arrived below
    first_move = int(np.argmax(moving)) if moving.any() else n_t
    out = []
    for start in range(0, n_t - WINDOW + 1, WINDOW):
        window = slice(start, start + WINDOW)
        if start < n_cal + WINDOW:       # calibration and the first window after it
            out.append(None)
        elif moving[window].any():
            out.append("moving")
        elif start + WINDOW <= first_move:
            out.append("start")
        else:
            out.append("settled")
    return out


def in_bounds_by_phase(nis, p, labels):
    """Share of windows inside their 1 % bounds per phase, from per-sample NIS."""
    lo, hi = (scipy.stats.chi2.ppf([LEVEL / 2, 1 - LEVEL / 2], WINDOW * p) / WINDOW)
    table = {}
    for phase in ("start", "moving", "settled"):
        means = [float(np.mean(nis[i * WINDOW:(i + 1) * WINDOW]))
                 for i, label in enumerate(labels) if label == phase]
        table[phase] = (np.mean([lo <= m <= hi for m in means]) if means else np.nan,
                        len(means), np.median(means) if means else np.nan)
    return table


def today(result, labels):
    """The run's own windowed test, by phase."""
    c = result.estimator_consistency
    ok = ~np.isin(np.arange(c.window_start.size), c.rejected)
    table = {}
    for phase in ("start", "moving", "settled"):
        idx = [i for i, s in enumerate(c.window_start) if s // WINDOW < len(labels)
               and labels[s // WINDOW] == phase]
        table[phase] = (float(np.mean(ok[idx])) if idx else np.nan, len(idx),
                        float(np.median(c.window_nis[idx])) if idx else np.nan)
    return table


def robot_force(line, states, positions):
    """The robot's force on the line per sample (N): body inertia, absorber spring and damper,
    with the plant's parameters at the robot's position (what its own sensors measure)."""
    plant = line.plant
    r, nq, dt = plant.r, plant.n_q, line.t[1] - line.t[0]
    n = plant.couplings(positions)
    a = np.einsum("ij,ij->i", states[:, :r], n)
    a_dot = np.einsum("ij,ij->i", states[:, nq:nq + r], n)
    a_ddot = np.gradient(a_dot, dt)
    params = plant.robot_parameters_at(positions)
    force = -params[:, 0] * a_ddot
    if plant.absorber:
        force -= params[:, 1] * (a - states[:, r]) + params[:, 2] * (a_dot - states[:, nq + r])
    return force


def modal_filter_model(line, robot, with_robot):
    """The bare line's modes in the plant's band (the controller told the truth: the family's
    scenarios here carry no nominal), with the robot coupled in for (a)."""
    return ModalPlant(line.bare, robot if with_robot else None, line.plant.n_band, line.plant.dt)


def augmented(phi, g, n_z, r, omega, dt):
    """State (z, p, p'/omega): the line's states and an undamped oscillator per modal load."""
    c, s = np.cos(omega * dt), np.sin(omega * dt)
    rot = np.block([[c * np.eye(r), s * np.eye(r)], [-s * np.eye(r), c * np.eye(r)]])
    a = np.zeros((n_z + 2 * r, n_z + 2 * r))
    a[:n_z, :n_z] = phi
    a[:n_z, n_z:n_z + r] = g        # the load this sample drives the line (hold)
    a[n_z:, n_z:] = rot
    return a


def run_filter(kind, line, records, robot, n_cal, tone, q_scale=None):
    """Filter the run's sensor record with (a) or (b); per-sample NIS."""
    mp = modal_filter_model(line, robot, with_robot=kind == "a")
    r, nq = mp.r, mp.n_q
    n_z = 2 * nq
    dt = line.plant.dt
    omega = 2 * np.pi * tone
    sensors = list(line.sensors)
    c_line = np.zeros((len(sensors), n_z + 2 * r))
    c_line[:, :r] = mp.nodal[sensors]
    y = records.measured
    n_t = y.shape[1]
    positions = records.position
    r_cov = np.eye(len(sensors)) * line_noise_std(records, line, n_cal) ** 2
    force = robot_force(line, records.plant_states, positions) if kind == "b" else None
    force_noise = 0.01 * np.std(force) if force is not None else 0.0
    rng = np.random.default_rng(0)
    if force is not None:
        force = force + force_noise * rng.standard_normal(force.shape)
    q_base = np.zeros((n_z + 2 * r,) * 2)
    q_base[n_z:, n_z:] = np.eye(2 * r)
    x = np.zeros(n_z + 2 * r)
    P = np.eye(n_z + 2 * r) * 1e-6
    nis = np.zeros(n_t)
    cache = {}
    for k in range(n_t):
        key = round(float(positions[k]), 6) if kind == "a" else None
        if key not in cache:
            phi, g0, g1 = mp.discretise(key)
            cache[key] = (augmented(phi, g0 + g1, n_z, r, omega, dt), g0 + g1)
        a, g = cache[key]
        if k:
            x = a @ x
            if kind == "b":
                x[:n_z] += g @ (mp.coupling(positions[k - 1]) * force[k - 1])
            P = a @ P @ a.T + q_scale * q_base
        innovation = y[:, k] - c_line @ x
        s = c_line @ P @ c_line.T + r_cov
        gain = np.linalg.solve(s, c_line @ P).T
        nis[k] = innovation @ np.linalg.solve(s, innovation)
        x = x + gain @ innovation
        i_kc = np.eye(x.size) - gain @ c_line
        P = i_kc @ P @ i_kc.T + gain @ r_cov @ gain.T
    return nis


def line_noise_std(records, line, n_cal):
    """The sensors' noise the run added (what the operator knows of the sensors), m."""
    r = line.plant.r
    truth = records.plant_states[:n_cal, :r] @ line.sensor_rows.T + line.residual[
        list(line.sensors), :n_cal].T
    return float(np.std(records.measured[:, :n_cal] - truth.T))


def matched(kind, line, records, robot, n_cal, tone):
    """Process-noise scale whose mean NIS on the calibration window is the sensor count."""
    p = len(line.sensors)
    lo, hi = -30.0, 5.0
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        nis = run_filter(kind, line, _head(records, n_cal), robot, n_cal, tone, 10**mid)
        if np.mean(nis[n_cal // 4:]) > p:
            lo = mid
        else:
            hi = mid
    return 10 ** (0.5 * (lo + hi))


class _head:
    """The calibration window's part of the records."""

    def __init__(self, records, n):
        self.measured = records.measured[:, :n]
        self.position = records.position[:n]
        self.plant_states = records.plant_states[:n]


def main(seeds):
    for seed in seeds:
        scenario = fam.scenario(seed)
        result, kept = _common.run_captured(scenario)
        records, line = kept["records"], kept["line"]
        n_t = line.t.size
        n_cal = int(round(scenario.calibration / scenario.dt)) + 1
        labels = phases(result, n_t, n_cal)
        p = len(line.sensors)
        tone = float(result.frequency[0])
        print(f"seed {seed}: {scenario.description}; {p} sensors, plant r={line.plant.r}, "
              f"tone {tone:.3g} Hz, consistent today: {result.estimator_consistency.consistent}")
        rows = {"today": today(result, labels)}
        for kind in ("b", "a"):
            q = matched(kind, line, records, scenario.robot, n_cal, tone)
            nis = run_filter(kind, line, records, scenario.robot, n_cal, tone, q)
            rows[f"({kind})"] = in_bounds_by_phase(nis, p, labels)
        for name, table in rows.items():
            print(f"  {name:8s} " + "  ".join(
                f"{ph}: {share:5.2f} of {count:3d} (median NIS/p {med / p:6.3g})"
                for ph, (share, count, med) in table.items()))


if __name__ == "__main__":
    main([int(s) for s in sys.argv[1:]] or [1, 3])
