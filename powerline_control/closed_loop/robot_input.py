"""The closed loop's estimator with the robot in its model: the bare line's modes (the span the
controller is told) driven by the robot's measured force at its current position, and the load
as one slowly decaying oscillator per mode at the tone the sensors measured.

The recipe's estimator (:func:`~powerline_control.recipe.design_estimator`) learns the line
with the robot parked at its start; once the robot moves, its model is wrong. Here the robot is
not part of the learned dynamics at all: its force on the line ``f`` (its absorber's spring and
damper force and its body's inertia, the robot's own measurements) enters the bare line's model
as a known input through the modes' shapes at its position, ``B n(x_r) f``. The input matrix
``B`` is fixed (one column per mode) and the robot's position moves only the input vector
``n(x_r) f``, so the Kalman filter's gain converges as it does for a fixed model and a step costs
one extra matrix-vector product. docs/validation/closed_loop.md measures it against the recipe's
estimator while parked, moving and settled.

Test seam: ``_matched_decades``, the process noise's search, checked on a known crossing.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import control as ct
import numpy as np

from .._constants import NOISE_FLOOR_FRACTION
from .._spectral import dominant_frequency
from ..errors import EstimationError, EstimatorInconsistentWarning
from ..estimate import KalmanFilter
from ..fem import LineModel
from ..simulation.plant import ModalPlant, default_modes
from .belief import ASSUMED_DAMPING, meshed_like

#: Time constant of the load's oscillators, s: a load that holds its tone for seconds (a
#: sine, a wind in lock-in) is carried; a stable pole keeps the filter's steady state defined
#: when a mode lies at every sensor's node.
LOAD_MEMORY = 5.0
#: Decades of the process noise over the sensors' noise variance the matching searches, and the
#: steps of its bisection (0.02 decade).
MATCHING_RANGE = (-12.0, 6.0)
MATCHING_STEPS = 11
#: Bisection steps within the decade found by stepping from an earlier match (0.03 decade).
NEAR_STEPS = 5


@dataclass(frozen=True, eq=False)
class RobotInputModel:
    """The bare line's modal model with the robot's force as a measured input.

    States ``(q, q', p_c, p_s)``: the modal coordinates and velocities of the told span's modes
    in the band, and each mode's load as an oscillator at ``tone``. Inputs: the robot's modal
    forces at this sample and the previous one (``inputs`` maps the robot's record of its
    position and force to them).
    """

    plant: ModalPlant           # the told bare line's modes (no robot, no load Ritz vectors)
    system: ct.StateSpace       # discrete, outputs the sensors, inputs the modal forces
    field_map: np.ndarray       # (n_nodes, n_states): states -> nodal displacements
    tone: float                 # Hz, the load's oscillators

    def inputs(self, positions: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """The model's inputs ``(2 r, n_t - 1)`` at samples 1..n_t-1 of the robot's record of
        its position ``positions`` (m) and its force ``forces`` (N), ``(n_t,)`` each: each
        sample's modal forces ``n(x_r) f`` over the previous sample's."""
        modal = (self.plant.couplings(np.asarray(positions, dtype=float))
                 * np.asarray(forces, dtype=float)[:, None])
        return np.hstack([modal[1:], modal[:-1]]).T


def robot_input_model(told: LineModel, modes, dt: float, sensor_positions, node_positions,
                      tone: float) -> RobotInputModel:
    """The model of :class:`RobotInputModel`: its outputs the sensors at ``sensor_positions``,
    its field at ``node_positions`` (m; the told mesh may differ from the line's)."""
    plant = ModalPlant(told, None, modes, dt)
    r = plant.r
    phi, g0, g1 = plant.discretise(None)
    n_z = phi.shape[0]
    g = g0 + g1                      # the load held over the sample (a slow envelope)
    decay = np.exp(-dt / LOAD_MEMORY)
    c, s = decay * np.cos(2 * np.pi * tone * dt), decay * np.sin(2 * np.pi * tone * dt)
    n = n_z + 2 * r
    a = np.zeros((n, n))
    a[:n_z, :n_z] = phi
    # this sample's load drives the line; the load's states in units of the displacement one
    # sample of it makes (a well-scaled Riccati equation: a force in N is ~1/dt^2 larger)
    a[:n_z, n_z : n_z + r] = g / np.max(np.abs(g))
    eye = np.eye(r)
    a[n_z:, n_z:] = np.block([[c * eye, s * eye], [-s * eye, c * eye]])
    # The robot's force is the line's own motion (it turns with the tone): held over a sample
    # it would lag by half a sample (8 % of a 24 Hz force's increment at 1 ms). First-order
    # hold, G0 f_k + G1 f_k+1, with f_k+1 extrapolated from f_k and f_k-1 (second order).
    b = np.zeros((n, 2 * r))
    b[:n_z, :r] = g0 + 2 * g1
    b[:n_z, r:] = -g1
    field_map = np.zeros((len(node_positions), n))
    field_map[:, :r] = plant.couplings(np.asarray(node_positions, dtype=float))
    c_rows = np.zeros((len(sensor_positions), n))
    c_rows[:, :r] = plant.couplings(np.asarray(sensor_positions, dtype=float))
    system = ct.ss(a, b, c_rows, np.zeros((len(sensor_positions), 2 * r)), dt)
    return RobotInputModel(plant=plant, system=system, field_map=field_map, tone=float(tone))


def robot_input_filter(told: LineModel, dt: float, sensor_positions, node_positions,
                       record: np.ndarray, positions: np.ndarray, forces: np.ndarray,
                       noise_std: float, *, process_noise: float | None = None,
                       near: float | None = None):
    """The filter on the calibration record: (filter, model, its states over the record).

    A ``told`` line without damping is given ``belief.ASSUMED_DAMPING``. The tone is the
    sensors' dominant one over the record (their velocities' spectrum); the
    modes those the simulated line's plant keeps for a load at that tone
    (:func:`~powerline_control.simulation.plant.default_modes`). The process noise drives the
    load's oscillators alike, scaled (covariance matching, once) so that the mean NIS over the
    record's last three quarters equals the number of sensors. The gain is the steady-state one
    (a fixed model: the robot moves only the input).
    ``record`` is the sensors' noisy record ``(p, n_cal)``, ``positions`` and ``forces`` the
    robot's own record of its position (m) and its force on the line (N).
    ``process_noise``: the load's process noise over the sensors' noise variance, instead of
    matching it on the record (:func:`process_noise_of` reads it from a filter). ``near``: one
    matched before on the same sensors, from which the matching searches
    (:func:`_matched_decades`).
    """
    if told.damping is None:
        # A real line always has self-damping, and the filter needs every mode stable: an
        # undamped mode at every sensor's node would be undetectable (no steady-state gain).
        told = meshed_like(told.span, told, damping=ASSUMED_DAMPING)
    tone = dominant_frequency(np.diff(record, axis=1), dt)
    modes = default_modes(told.span, told, [tone], dt)   # the plant's rule, at the tone seen
    model = robot_input_model(told, modes, dt, sensor_positions, node_positions, tone)
    n, r, p = model.system.nstates, model.plant.r, len(sensor_positions)
    shape = np.zeros((n, n))
    shape[2 * r :, 2 * r :] = np.eye(2 * r)
    rms = float(np.sqrt(np.mean(record**2)))
    noise = max(noise_std, NOISE_FLOOR_FRACTION * rms, 1e-300) ** 2
    u = model.inputs(np.r_[positions[0], positions], np.r_[forces[0], forces])
    head = record.shape[1] // 4

    def build(scale: float) -> KalmanFilter:
        return KalmanFilter(model.system, scale * shape, noise * np.eye(p), steady_state=True,
                            field_map=model.field_map, P0=np.eye(n) * noise)

    def mean_nis(scale: float) -> float:
        try:
            with warnings.catch_warnings():   # the matching's own trials test nothing
                warnings.simplefilter("ignore", EstimatorInconsistentWarning)
                nis = np.asarray(build(scale).filter(record, u).nis)
        except EstimationError:   # too little process noise for a steady state: more
            return math.inf
        return float(np.mean(nis[head:]))

    scale = process_noise
    if scale is None:
        def too_little(decades: float) -> bool:
            return mean_nis(noise * 10.0**decades) > p

        scale = 10.0 ** _matched_decades(too_little, near)
    kf = build(noise * scale)
    states = np.asarray(kf.filter(record, u, update_state=True).states)
    return kf, model, states


def _matched_decades(too_little, near: float | None) -> float:
    """The process noise's decades (over the sensors' noise variance) at which the mean NIS
    crosses the number of sensors, ``too_little(decades)`` telling the side. Without ``near``
    a bisection of :data:`MATCHING_RANGE`; from an earlier match ``near``, whole decades up or
    down until the side changes (a line believed better leaves less model error to match, a new
    load may be decades stronger), then a bisection of that decade: a few Riccati solutions
    instead of eleven."""
    bottom, top = MATCHING_RANGE
    if near is None:
        lo, hi, steps = bottom, top, MATCHING_STEPS
    else:
        start = min(max(math.log10(near), bottom), top)
        if too_little(start):
            lo, hi = start, start + 1.0
            while hi < top and too_little(hi):
                lo, hi = hi, hi + 1.0
        else:
            lo, hi = start - 1.0, start
            while lo > bottom and not too_little(lo):
                lo, hi = lo - 1.0, lo
        steps = NEAR_STEPS
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if too_little(mid) else (lo, mid)
    return 0.5 * (lo + hi)


def process_noise_of(kf: KalmanFilter) -> float:
    """The load's process noise of a :func:`robot_input_filter` over its sensors' noise
    variance (what ``process_noise`` takes)."""
    return float(np.max(np.diag(kf.Q))) / float(kf.R[0, 0])
