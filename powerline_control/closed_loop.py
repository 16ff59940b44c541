"""The whole chain in closed loop: sensors -> estimate -> target -> motion -> robot moves.

The plant
---------
The line is simulated in the modal coordinates of the *bare* line (its lowest ``r`` modes or a
band of them, plus the residual response of the dropped modes to the loads: dynamic for a sine,
so modes below a band count with 1 / (omega_k^2 - omega^2)), and the robot is coupled to them
through the shape functions at its current position: with ``n = Phi^T N(x_r)`` (the bare modes'
displacements at the robot, ``model.shape_vector(x)`` restricted to the modal basis)

    (I + m_b n n^T) q'' + (Z + c n n^T) q' + (Omega^2 + k n n^T) q - n (k y + c y') = Phi^T f(t)
    m_a y'' + c (y' - n^T q') + k (y - n^T q) = 0

(``Z`` the line's own modal damping; ``y`` the absorber's displacement). A move changes only the
rank-one terms: rebuilding the matrices costs O(r^2) and their exact discretisation an
``expm`` of a (4r + 2)-square matrix, against an eigen-solve of the whole mesh before. Each block
of samples is integrated exactly for loads linear between samples (first-order hold): with no
damping and a still robot the discrete map is the exact flow, so the mechanical energy is
conserved to round-off. The robot's position is a slowly varying parameter (its speed is < 2 % of
the wave speed, so the convective moving-mass terms are neglected, as in the domain notes) held
at its mid-block value over blocks of ``plant_period``.

The policy (docs/closed_loop.md)
--------------------------------
Chasing the antinode of the field the robot is damping is unstable: the damped loop's maximum
moves away from the robot. Here the robot targets something its damping does not move. From the
sensors' and its own motion's phasors at the dominant frequency it removes its own reaction with
the bare line's receptance,

    W_bare(x) = W(x) - H(x, x_r; omega) D_r(omega) W_r,
    D_r = omega^2 m_b + omega^2 m_a (k + i omega c) / (k + i omega c - omega^2 m_a),

(the robot-free excited shape, fitted on the bare modes), which in steady state is the same
wherever the robot is; then it predicts the span's RMS with itself parked at every p,
``W_p = W_bare + H(., p) D_r W_bare(p) / (1 - H(p, p) D_r)``, and goes to the best it can reach
spending at most half the remaining run travelling (the nearest of the near-best minima within
that reach: on a long span every loop is about as good, and a far one is not worth the trip).
The choice is confirmed once the robot has settled and the window is
steady: a refinement inside a quarter loop of the *anchor* (the gate does not move with the
goal), or at most two moves to another loop; a new target only when the dominant frequency
changes (a wind change). The motion law is the closed-form time-optimal approach of a double
integrator (or the MPC planner on request).
"""

from __future__ import annotations

import numbers
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from ._validation import (
    check_budget,
    check_indices,
    check_int,
    check_real,
    check_rng,
    read_only,
)
from .errors import InputError
from .estimate import KalmanFilter
from .fem import MDR, LineModel
from .line import Span
from .plan import MotionPlanner, RobotLimits
from .recipe import design_estimator
from .severity import damper_impedance

__all__ = ["ClosedLoopResult", "Comparison", "run_closed_loop"]

GRAVITY = 9.81
# A robot heavier than this fraction of the span's own mass is no longer a small attachment: the
# slowly-varying-parameter plant and the single-mode tuning are not credible beyond it.
MAX_ROBOT_MASS_RATIO = 0.25
# Static slope of the line under the robot's weight, W / (2 T) at midspan: beyond 0.05 rad the
# small-slope (linear taut-string) model of the line is not valid.
MAX_STATIC_SLOPE = 0.05
# The policy: a window whose two halves give excited shapes differing by more than this (relative)
# still beats with a decaying mode; wait up to MAX_WAIT s for a steady one. At most MAX_CHOICES
# loops are tried per excitation before the choice is final.
UNSTEADY_LIMIT = 0.25
MAX_WAIT = 3.0
MAX_CHOICES = 3
# The plant keeps every mode below 8x the load frequency up to this many, else a band of modes.
SMALL_PLANT_MODES = 48
# Local minima of the predicted RMS within this fraction of the lowest count as equally good:
# the robot takes the nearest (equal loops of a resonant mode need no long trip).
NEAR_OPTIMAL = 0.03
# ... but only among the minima the robot reaches spending at most this fraction of the remaining
# run travelling: a far loop predicted slightly better is not worth a trip that leaves the line
# vibrating at the start's level for most of the run (on a long span the few sensors cannot rank
# ~100 loops to 3 % anyway).
TRAVEL_FRACTION = 0.5
# The robot keeps this fraction of the span away from the supports and the obstacles.
SUPPORT_MARGIN = 0.02


@dataclass(frozen=True)
class Comparison:
    """The line's vibration over the settled window for one robot placement.

    Attributes
    ----------
    name : str
        ``"no_robot"``, ``"near_clamp"``, ``"start"`` (parked where the closed loop started),
        ``"best"`` (parked at the best position of the steady-state scan) or ``"closed_loop"``.
    position : float
        Where the robot was parked, m (NaN without a robot; the final position for the loop).
    rms : float
        RMS displacement over the span (length-weighted) and the settled window, m.
    peak : float
        Largest absolute displacement over the span and the window, m.
    damper_power : float
        Mean power dissipated in the robot's damper over the window, W.
    envelope : ndarray, shape (n_nodes,)
        Largest absolute displacement at each node over the window, m.

    Examples
    --------
    >>> import numpy as np
    >>> c = Comparison("start", 1.2, 1e-3, 2e-3, 0.0, np.zeros(3))
    >>> c.name, c.rms
    ('start', 0.001)
    """

    name: str
    position: float
    rms: float
    peak: float
    damper_power: float
    envelope: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class ClosedLoopResult:
    """What happened in :func:`run_closed_loop`.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Sample times, s (calibration window included, starting at 0).
    x : ndarray, shape (n_nodes,)
        Node positions, m.
    displacement : ndarray, shape (n_nodes, n_t)
        True (noise-free) displacement with the robot under closed-loop control.
    baseline_displacement : ndarray, shape (n_nodes, n_t)
        True displacement with the robot parked at its start for the whole run.
    estimated_field : ndarray, shape (n_nodes, n_t)
        The Kalman filter's estimate of the field (the calibration record filtered first).
    robot_position, robot_velocity : ndarray, shape (n_t,)
        Robot state, m and m/s.
    target : ndarray, shape (n_t,)
        Where the robot was steering to (NaN before the first target).
    sensors : tuple of int
        Measured node indices.
    calibration_time : float
        Length of the initial window (robot parked) used to identify the estimator's model, s.
    statuses : tuple of str
        Motion status of every control step ("closed_form", "blocked", or the MPC's status).
    wall_time : float
        Wall-clock time of the loop (after calibration), s.
    settled_window : (float, float)
        Time window (s) over which every metric is computed: from ``settle_margin`` after the robot
        last arrived (stayed within 1 % of a loop of its final position) to the end of the run.
    settled : bool
        False when the robot never stayed put long enough (the window is then the last second).
    comparisons : tuple of Comparison
        no robot, parked near a clamp, parked at the start, parked at the best position, and
        the closed loop, over the same settled window.
    scan_positions, scan_rms : ndarray
        The steady-state scan: RMS displacement over the span (m) with the robot parked at each
        position, for the last harmonic load (empty when the load is not harmonic).
    best_position : float
        Minimiser of the scan, m (NaN without a harmonic load).
    loop_length : float
        Half-wavelength of the bare line at the final dominant frequency, m.
    frequency : ndarray, shape (n_steps,)
        Dominant frequency the controller measured at each control step, Hz.
    retarget_times, settle_times : tuple of float
        When the controller chose a new target (s), and how long the robot then took to arrive
        and stay within 1 % of a loop (s; NaN if it did not).
    follow_times : tuple of float
        For every change of load in a schedule (a wind change): the time from the change until
        the robot arrived at its new target and stayed (detection, retarget and move), s; NaN
        when it did not.
    innovation_ratio : ndarray, shape (n_steps,)
        RMS one-step prediction error of the sensors over the last window, relative to its value
        on the calibration record: the estimator's model is taken as valid below 3.
    damper_power : ndarray, shape (n_t,)
        Power dissipated in the robot's damper, W.
    predictions : tuple of (float, ndarray, ndarray, ndarray)
        At each target choice and confirmation: the time (s), the positions and the steady-state
        RMS (m) the controller predicted for the robot parked there, and the robot-free excited
        shape (complex amplitude at every node, m) it predicted from.
    timings : dict
        Wall-clock seconds spent in: setup (modes, calibration, identification), plant (sample
        stepping and sensing), plant update (re-discretising after a move), filter (Kalman
        steps), policy and motion, comparisons (parked runs and the steady-state scan); and
        "loop cpu", the process time of the loop (less sensitive to the machine's load), and
        "modes", the number of bare-line modes the plant kept.

    Examples
    --------
    >>> import powerline_control as plc
    >>> robot = plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1)
    >>> result = run_closed_loop(plc.Span.paper_lab(), plc.HarmonicForce(1.0, 24.0, 0.5),
    ...                          robot, n_elements=20, sensors=[4, 9, 15], duration=2.0,
    ...                          calibration=1.0)
    >>> result.displacement.shape, len(result.statuses)      # 20 control steps of 50 ms
    ((21, 2001), 20)
    >>> [c.name for c in result.comparisons]
    ['no_robot', 'near_clamp', 'start', 'best', 'closed_loop']
    """

    t: np.ndarray
    x: np.ndarray
    displacement: np.ndarray
    baseline_displacement: np.ndarray
    estimated_field: np.ndarray
    robot_position: np.ndarray
    robot_velocity: np.ndarray
    target: np.ndarray
    sensors: tuple
    calibration_time: float
    statuses: tuple
    wall_time: float = field(repr=False)
    settled_window: tuple = (0.0, 0.0)
    settled: bool = False
    comparisons: tuple = ()
    scan_positions: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    scan_rms: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    best_position: float = float("nan")
    loop_length: float = float("nan")
    frequency: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    retarget_times: tuple = ()
    settle_times: tuple = ()
    innovation_ratio: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    damper_power: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    predictions: tuple = field(default=(), repr=False)
    timings: dict = field(default_factory=dict, repr=False)
    follow_times: tuple = ()

    def comparison(self, name: str) -> Comparison:
        """The comparison called ``name`` (see :attr:`comparisons`)."""
        for item in self.comparisons:
            if item.name == name:
                return item
        raise InputError(
            f"The 'name' parameter must be one of {[c.name for c in self.comparisons]}. "
            f"Got {name!r}."
        )

    @property
    def window_mask(self) -> np.ndarray:
        """Boolean mask of the samples in :attr:`settled_window`."""
        return (self.t >= self.settled_window[0]) & (self.t <= self.settled_window[1])

    @property
    def estimator_valid(self) -> np.ndarray:
        """Per control step: the estimator's model still fits (innovation ratio below 3)."""
        return self.innovation_ratio < 3.0

    @property
    def rms_closed_loop(self) -> float:
        """RMS displacement over the span in the settled window, m."""
        return self.comparison("closed_loop").rms

    @property
    def rms_baseline(self) -> float:
        """The same with the robot parked at its start, m."""
        return self.comparison("start").rms

    @property
    def vibration_reduction(self) -> float:
        """rms_baseline / rms_closed_loop: how many times less the line vibrates."""
        return self.rms_baseline / self.rms_closed_loop

    @property
    def real_time_factor(self) -> float:
        """Simulated loop time over its wall-clock time (> 1: faster than real time)."""
        return (self.t[-1] - self.calibration_time) / self.wall_time

    def summary(self) -> str:
        """A few lines: the settled window and every comparison."""
        lines = [
            f"settled window {self.settled_window[0]:.2f}-{self.settled_window[1]:.2f} s"
            + ("" if self.settled else " (robot did not settle)"),
        ]
        for c in self.comparisons:
            lines.append(
                f"{c.name:12s} x = {c.position:7.3f} m  rms {1e3 * c.rms:8.4f} mm  "
                f"peak {1e3 * c.peak:8.4f} mm  damper {1e3 * c.damper_power:8.4f} mW"
            )
        return "\n".join(lines)


# ---------------------------------------------------------------------------------- the plant
class _ModalPlant:
    """Bare-line modes with the robot coupled at its position (see module doc).

    ``modes``: how many of the lowest modes, or the indices (0-based) of a band of them.
    """

    def __init__(self, model: LineModel, robot: MDR | None, modes, dt: float):
        index = np.arange(modes) if np.ndim(modes) == 0 else np.asarray(modes)
        basis = model.modes(int(index.max()) + 1)
        self.model, self.dt = model, dt
        # every mode up to the top of the plant's (possibly band of) modes, for the residual
        self.lowest = basis
        active = robot is not None and (robot.body_mass > 0 or robot.has_absorber)
        self.robot = robot if active else None
        self.shapes = np.asarray(basis.shapes)[:, index]
        self.omega2 = np.asarray(basis.omega)[index] ** 2
        self.line_damping = np.asarray(basis.damping)[np.ix_(index, index)]
        self.nodal = model.displacement_map() @ self.shapes  # (n_nodes, r)
        self.r = index.size
        off_diagonal = self.line_damping - np.diag(np.diag(self.line_damping))
        self._diagonal = not np.any(off_diagonal)
        self.absorber = self.robot is not None and self.robot.has_absorber
        self.n_q = self.r + (1 if self.absorber else 0)
        self._cache: dict[float, tuple] = {}

    def coupling(self, x: float) -> np.ndarray:
        """The bare modes' displacements at x (shape functions restricted to the basis)."""
        # the <= 4 non-zero shape-function entries: O(r) per call, not O(n_dofs r)
        index, weights = self.model.shape_entries(x)
        return weights @ self.shapes[index]

    def matrices(self, x: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """M, C, K over (q, y): O(r^2) rank-one updates of the bare line's diagonal ones."""
        r, nq = self.r, self.n_q
        mass, damp, stiff = np.eye(nq), np.zeros((nq, nq)), np.zeros((nq, nq))
        stiff[:r, :r] = np.diag(self.omega2)
        damp[:r, :r] = self.line_damping
        if self.robot is None or x is None:
            return mass, damp, stiff
        n = self.coupling(x)
        robot = self.robot
        mass[:r, :r] += robot.body_mass * np.outer(n, n)
        if self.absorber:
            coupling = np.zeros(nq)
            coupling[:r], coupling[r] = n, -1.0
            stiff += robot.stiffness * np.outer(coupling, coupling)
            damp += robot.damping * np.outer(coupling, coupling)
            mass[r, r] = robot.suspended_mass
        return mass, damp, stiff

    def discretise(self, x: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact first-order-hold map z' = Phi z + G0 p_k + G1 p_{k+1} over one sample."""
        key = None if x is None else round(float(x), 6)
        if key in self._cache:
            return self._cache[key]
        mass, damp, stiff = self.matrices(x)
        nq, r = self.n_q, self.r
        inverse_mass = np.linalg.inv(mass)  # block-diagonal, rank-one off I: well conditioned
        n_z = 2 * nq
        aug = np.zeros((n_z + 2 * r, n_z + 2 * r))
        aug[:nq, nq:n_z] = np.eye(nq)
        aug[nq:n_z, :nq] = -inverse_mass @ stiff
        aug[nq:n_z, nq:n_z] = -inverse_mass @ damp
        aug[nq:n_z, n_z : n_z + r] = inverse_mass[:, :r]
        aug *= self.dt
        aug[n_z : n_z + r, n_z + r :] = np.eye(r)
        e = scipy.linalg.expm(aug)
        phi = e[:n_z, :n_z]
        f1, f2 = e[:n_z, n_z : n_z + r], e[:n_z, n_z + r :]
        result = (phi, f1 - f2, f2)
        if len(self._cache) > 4096:
            self._cache.clear()
        self._cache[key] = result
        return result

    def energy(self, z: np.ndarray, x: float | None) -> float:
        """Kinetic plus potential energy of state z = (q, y, q', y'), J."""
        mass, _, stiff = self.matrices(x)
        q, v = z[: self.n_q], z[self.n_q :]
        return float(0.5 * v @ mass @ v + 0.5 * q @ stiff @ q)

    def steady_state(self, x: float | None, omega: float, modal_force: np.ndarray) -> np.ndarray:
        """Complex modal amplitudes (q, y) under the harmonic modal force amplitude."""
        mass, damp, stiff = self.matrices(x)
        rhs = np.zeros(self.n_q, dtype=complex)
        rhs[: self.r] = modal_force
        return np.linalg.solve(stiff - omega**2 * mass + 1j * omega * damp, rhs)

    def modal_response(self, load: np.ndarray, omega: float) -> np.ndarray:
        """Bare line's modal amplitudes under a harmonic modal load (diagonal when it can)."""
        if self._diagonal:
            return load / (self.omega2 - omega**2 + 1j * omega * np.diag(self.line_damping))
        dynamic = np.diag(self.omega2 - omega**2) + 1j * omega * self.line_damping
        return np.linalg.solve(dynamic, load)

    def receptance(self, x: float, omega: float) -> np.ndarray:
        """Bare line's displacement at every node per unit harmonic force at x (modal sum)."""
        return self.nodal @ self.modal_response(self.coupling(x), omega)


def _default_modes(span: Span, bare: LineModel, frequencies: list, dt: float):
    """The plant's modes: every mode below 8x the highest load frequency when that is a few
    dozen (short spans: the robot's local flexibility converges), else the band
    [0.6 f_min, 1.4 f_max] (long spans: ~100 modes near the load; the others respond weakly and
    the loads' part of them is the quasi-static residual)."""
    f_max = max(frequencies) if frequencies else 0.125 / dt
    f_min = min(frequencies) if frequencies else 0.0
    estimate = span.pinned_frequencies(bare.n_dofs)
    below = int(np.count_nonzero(estimate <= 8 * f_max))
    if below <= SMALL_PLANT_MODES:
        return int(min(bare.n_dofs, max(12, below + 2)))
    first = int(np.count_nonzero(estimate < 0.6 * f_min))
    last = int(min(bare.n_dofs, np.count_nonzero(estimate <= 1.4 * f_max) + 1))
    return np.arange(first, last)


def _robot_dynamic_stiffness(robot: MDR, omega: float) -> complex:
    """D_r: the robot's force on the line per unit line displacement at omega (body + absorber).

    D_r = -i omega Z with Z the robot's mechanical impedance
    (:func:`~powerline_control.severity.damper_impedance`, the same physics in one place);
    zero at omega = 0 (every term carries omega^2).
    """
    if omega == 0.0:
        return 0j
    return complex(-1j * omega * damper_impedance(robot, omega / (2 * np.pi)))


def _run_parked(plant, x, modal_force, n_t, z0=None):
    """States (n_t, 2 n_q) of the plant with the robot parked at x (None: no robot)."""
    phi, g0, g1 = plant.discretise(x)
    states = np.empty((n_t, phi.shape[0]))
    z = np.zeros(phi.shape[0]) if z0 is None else z0
    states[0] = z
    drive = modal_force[:-1] @ g0.T + modal_force[1:] @ g1.T
    for k in range(n_t - 1):
        z = phi @ z + drive[k]
        states[k + 1] = z
    return states


# ---------------------------------------------------------------------------------- the loads
def _is_schedule(force: object) -> bool:
    return (
        isinstance(force, list | tuple)
        and len(force) > 0
        and all(
            isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], numbers.Real)
            for item in force
        )
    )


def _segments(force: object, duration: float) -> list[tuple[float, list]]:
    """[(start_time, [loads])]: a single load, a list of loads, or a (time, load) schedule."""
    if force is None:
        raise InputError("The 'force' parameter must be a load or a schedule. Got None.")
    raw = list(force) if _is_schedule(force) else [(0.0, force)]
    segments = []
    previous = -np.inf
    for start, loads in raw:
        start = check_real("force schedule time", start, low=0.0, low_inclusive=True)
        if start <= previous or start >= duration:
            raise InputError(
                "The times of the 'force' schedule must increase from 0 and lie inside the run "
                f"(duration {duration:g} s). Got {[s for s, _ in raw]}."
            )
        previous = start
        items = list(loads) if isinstance(loads, list | tuple) else [loads]
        for item in items:
            if not (hasattr(item, "bind") or all(
                hasattr(item, n) for n in ("values", "load_vector", "position")
            )):
                raise InputError(
                    "The 'force' parameter must hold loads (HarmonicForce, AeolianForce, ...). "
                    f"Got {type(item).__name__}."
                )
        segments.append((start, items))
    if segments[0][0] != 0.0:
        raise InputError("The 'force' schedule must start at time 0.")
    return segments


def _residual_of_load(model: LineModel, plant: _ModalPlant, vector: np.ndarray,
                      frequency: float | None) -> np.ndarray:
    """Nodal response, per unit time factor, of the bare modes the plant does not keep.

    A plant of a band of modes (long spans) leaves out modes *below* the band as well as above
    it. Under a sine those respond with 1 / (omega_k^2 - omega^2) < 0, so the residual is the
    dynamic one (exact for the undamped modes left out); the static K^-1 residual would count
    them with their static flexibility 1 / omega_k^2, on a 300 m span a spurious field ~100x
    the vibration. Other loads (or a sine exactly on a kept resonance): the static residual of
    the modes above the plant's top only (the modes below a band are then left out).
    """
    f = 0.0 if frequency is None else float(frequency)
    omega2 = (2 * np.pi * f) ** 2
    if f > 0.0 and np.min(np.abs(plant.omega2 - omega2)) >= 1e-9 * plant.omega2.max():
        dofs = model.residual_response(vector, plant.shapes, np.sqrt(plant.omega2), f)
    else:
        dofs = model.residual_response(vector, plant.lowest.shapes, plant.lowest.omega)
    return model.displacement_map() @ dofs


def _load_histories(model, plant, segments, t):
    """Modal force (n_t, r), nodal quasi-static residual (n_nodes, n_t), last harmonic load."""
    modal = np.zeros((t.size, plant.r))
    residual = np.zeros((model.n_nodes, t.size))
    harmonic = None
    bounds = [s for s, _ in segments] + [np.inf]
    for (start, loads), end in zip(segments, bounds[1:], strict=True):
        mask = (t >= start - 1e-12) & (t < end - 1e-12)
        bound_loads = [f.bind(model) if hasattr(f, "bind") else f for f in loads]
        harmonic_parts = []
        for load in bound_loads:
            if load.position is not None:
                check_real("force position", load.position, low=0.0, low_inclusive=True,
                           high=model.span.length)
            vector = np.asarray(load.load_vector(model), dtype=float)
            values = np.asarray(load.values(t[mask]), dtype=float)
            g = plant.shapes.T @ vector
            static = _residual_of_load(model, plant, vector, getattr(load, "frequency", None))
            modal[mask] += np.outer(values, g)
            residual[:, mask] += np.outer(static, values)
            harmonic_parts.append((load, g, static))
        if all(getattr(load, "frequency", None) is not None for load, _, _ in harmonic_parts):
            frequencies = {round(float(load.frequency), 9) for load, _, _ in harmonic_parts}
            if len(frequencies) == 1:
                harmonic = (float(harmonic_parts[0][0].frequency), harmonic_parts)
            else:
                harmonic = None
        else:
            harmonic = None
    return modal, residual, harmonic


def _phasor_of(load, frequency: float) -> complex:
    """A: values(t) = Re(A exp(i 2 pi f t)), fitted on one period (exact for a sine)."""
    tau = np.linspace(0.0, 1.0 / frequency, 64, endpoint=False)
    values = np.asarray(load.values(tau), dtype=float)
    w = 2 * np.pi * frequency
    return complex(2 * np.mean(values * np.cos(w * tau)), -2 * np.mean(values * np.sin(w * tau)))


# ---------------------------------------------------------------------------------- the policy
def _dominant_frequency(signals: np.ndarray, dt: float) -> float:
    """Frequency of the largest spectral peak of (n_signals, n_t), Hann window, interpolated.

    Not antinode's ``_dominant_harmonic`` (the same Hann window and log-parabola, but no zero
    padding): padding to at least 2 n bins makes the estimate ~10x closer for a tone (measured:
    errors of 2e-4 to 1.4e-3 Hz here against 3e-3 to 1.6e-2 Hz on 1-2 s windows at 1 kHz), and
    the phasors are fitted at this frequency over a window, where its error turns into phase.
    """
    n = signals.shape[1]
    window = np.hanning(n)
    n_fft = max(2 * n, 1024)  # Hann + log-parabola: bias ~1 % of a bin for a pure tone
    power = np.sum(
        np.abs(np.fft.rfft((signals - signals.mean(axis=1, keepdims=True)) * window, n_fft))
        ** 2,
        axis=0,
    )
    power[0] = 0.0
    k = int(np.argmax(power))
    if 0 < k < power.size - 1:
        a, b, c = np.log(power[k - 1 : k + 2] + 1e-300)
        denom = a - 2 * b + c
        k = k + (0.5 * (a - c) / denom if denom < 0 else 0.0)
    return float(k / (n_fft * dt))


def _fit_phasor(signals: np.ndarray, t: np.ndarray, frequency: float) -> np.ndarray:
    """Least-squares A per row: signal ~ Re(A exp(i omega t)) + constant.

    The fit antinode's ``_dominant_harmonic`` makes too, but here at a frequency given (measured
    on the longer frequency window) and on absolute time ``t``: the phasors of a window's two
    halves, compared for the unsteadiness check, share one phase reference (antinode's are
    referred to their own window's first sample, and only at the frequency it finds itself).
    """
    w = 2 * np.pi * frequency
    basis = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
    coef, *_ = np.linalg.lstsq(basis, signals.T, rcond=None)
    return coef[0] - 1j * coef[1]


def _antinodes_of(shape: np.ndarray, x: np.ndarray) -> list[tuple[float, float]]:
    """(position, loop length) of each local maximum of |shape| along the span, the loop ending
    at the nodes where |shape| is locally least.

    Not :func:`~powerline_control.antinode.locate_antinodes`: on the closed loop's shapes it
    finds the same antinodes (within 1 cm), but its loop ends are zero crossings of the
    phase-aligned shape interpolated between nodes, so its loop lengths differ from these by up to
    one element (1.22 against 1.28 m on the 20-element lab span, 3.70 against 3.58 m on a 300 m
    Drake span), and it leaves out loops below 10 % of the largest. The loop length sets the
    quarter-loop confirmation gate, so a choice near the gate's edge would go the other way with
    it (ten varied runs happened to come out bit-identical with it swapped in); kept so that the
    policy decides as it always has.
    """
    amplitude = np.abs(shape)
    found = []
    minima = [0] + [j for j in range(1, x.size - 1)
                    if amplitude[j] <= amplitude[j - 1] and amplitude[j] <= amplitude[j + 1]]
    minima.append(x.size - 1)
    for j in range(1, x.size - 1):
        if amplitude[j] > amplitude[j - 1] and amplitude[j] >= amplitude[j + 1]:
            # Parabola through the three samples (non-uniform nodes allowed).
            xs, ys = x[j - 1 : j + 2], amplitude[j - 1 : j + 2]
            a, b, _ = np.polyfit(xs - x[j], ys, 2)
            offset = -b / (2 * a) if a < 0 else 0.0
            offset = float(np.clip(offset, xs[0] - x[j], xs[2] - x[j]))
            left = max(m for m in minima if m <= j)
            right = min(m for m in minima if m >= j)
            found.append((float(x[j] + offset), float(x[right] - x[left])))
    return found


def _kernel_shape(plant, sensor_rows, sensed, robot, x_r, at_robot, omega):
    """Robot-free excited shape at every node from the sensors' and the robot's phasors.

    The robot's reaction ``D_r W_r`` is removed from every measurement with the bare line's
    receptance; the robot-free shape is then the posterior mean of a Gaussian prior over the bare
    modal amplitudes with variance ``1 / |omega_n^2 - omega^2 + i omega z_n|^2`` (what a load
    spread evenly over the modes would drive): near a resonance it is that mode, fitted; between
    two, the mix the few measurements support.
    """
    n_r = plant.coupling(x_r)
    rows = np.vstack([sensor_rows, n_r])  # (p + 1, r)
    values = np.append(sensed, at_robot)
    reaction = _robot_dynamic_stiffness(robot, omega) * at_robot
    values = values - rows @ plant.modal_response(n_r, omega) * reaction
    # A floor of 0.1 % damping keeps the prior finite on an undamped line at resonance.
    floor = 2e-3 * np.sqrt(plant.omega2) * omega
    variance = 1.0 / (np.abs(plant.omega2 - omega**2) ** 2 + floor**2)
    gram = (rows * variance) @ rows.T
    gram = gram + 1e-6 * np.trace(gram) / gram.shape[0] * np.eye(gram.shape[0])
    return (plant.nodal * variance) @ (rows.T @ np.linalg.solve(gram, values))


def _predicted_rms(bare_shape, plant, robot, omega, positions, weights):
    """RMS over the span, in steady state, with the robot parked at each of ``positions``.

    With one point attachment the parked field follows from the robot-free one exactly:
    ``W_p = W_bare + H(., p) D_r W_p(p)`` and ``W_p(p) = W_bare(p) / (1 - H(p, p) D_r)``,
    so only the bare line's receptance is needed (no modal force is inverted from the estimate).
    """
    reaction = _robot_dynamic_stiffness(robot, omega)
    out = np.empty(len(positions))
    for i, p in enumerate(positions):
        h = plant.receptance(p, omega)
        n = plant.coupling(p)
        at_robot = complex(n @ plant.modal_response(n, omega))
        w_bare_p = complex(np.interp(p, plant.model.node_positions, bare_shape.real)
                           + 1j * np.interp(p, plant.model.node_positions, bare_shape.imag))
        shape = bare_shape + h * reaction * w_bare_p / (1 - at_robot * reaction)
        out[i] = np.sqrt(0.5 * weights @ np.abs(shape) ** 2)
    return out


def _choose_target(bare_shape, plant, robot, omega, weights, robot_position, low, high,
                   reach=np.inf):
    """The predicted best parked position within reach: among the local minima of the predicted
    RMS no farther than ``reach`` from the robot, those within NEAR_OPTIMAL of the lowest of
    them, the one nearest the robot (the nearest minimum when none is within reach).

    Returns (position, loop length, grid, predicted RMS on the grid), or None without a loop.
    """
    x = plant.model.node_positions
    antinodes = _antinodes_of(bare_shape, x)
    if not antinodes:
        return None
    grid = np.linspace(low, high, max(4 * x.size, 200))
    predicted = _predicted_rms(bare_shape, plant, robot, omega, grid, weights)
    minima = [i for i in range(grid.size)
              if (i == 0 or predicted[i] <= predicted[i - 1])
              and (i == grid.size - 1 or predicted[i] <= predicted[i + 1])]
    nearest = min(minima, key=lambda i: abs(grid[i] - robot_position))
    reachable = [i for i in minima if abs(grid[i] - robot_position) <= reach] or [nearest]
    lowest = min(predicted[i] for i in reachable)
    good = [i for i in reachable if predicted[i] <= (1 + NEAR_OPTIMAL) * lowest]
    pick = min(good, key=lambda i: abs(grid[i] - robot_position))
    if 0 < pick < grid.size - 1:
        # Parabola through the grid minimum and its neighbours (uniform grid).
        a, b, c = predicted[pick - 1 : pick + 2]
        denom = a - 2 * b + c
        offset = 0.5 * (a - c) / denom if denom > 0 else 0.0
        position = float(grid[pick] + offset * (grid[1] - grid[0]))
    else:
        position = float(grid[pick])
    loop = min(antinodes, key=lambda a: abs(a[0] - position))[1]
    return position, loop, read_only(grid), read_only(predicted)


def _reach(limits: RobotLimits, time_budget: float) -> float:
    """Longest rest-to-rest move within ``time_budget`` s (triangle or trapezoid profile), m."""
    a, v = limits.a_max, limits.v_max
    if time_budget <= 0:
        return 0.0
    if time_budget <= 2 * v / a:
        return 0.25 * a * time_budget**2
    return v * (time_budget - v / a)


def _time_optimal_accel(position, velocity, goal, limits: RobotLimits, period: float) -> float:
    """Closed-form time-optimal approach of a double integrator, one constant-accel period.

    The velocity wanted is the largest that can still stop at the goal with the braking the
    limits allow, corrected for the discrete period (sqrt law with a half-period offset); the
    acceleration reaches it as fast as allowed.
    """
    error = goal - position
    a, v_max = limits.a_max, limits.v_max
    half = 0.5 * a * period
    v_stop = -half + np.sqrt(half**2 + 2 * a * abs(error))
    wanted = np.sign(error) * min(v_max, v_stop, abs(error) / period)
    return float(np.clip((wanted - velocity) / period, -a, a))


def _free_interval(position, obstacles, span_length):
    """(low, high): where the robot may go from ``position`` without crossing an obstacle,
    keeping SUPPORT_MARGIN of the span from the supports and from every obstacle."""
    margin = SUPPORT_MARGIN * span_length
    low, high = margin, span_length - margin
    for left, right in obstacles:
        if right <= position:
            low = max(low, right + margin)
        elif left >= position:
            high = min(high, left - margin)
    return low, high


def _arrival_index(position: np.ndarray, start: int, tolerance: float) -> int | None:
    """First index >= start after which the position stays within tolerance of its last value."""
    outside = np.flatnonzero(np.abs(position[start:] - position[-1]) > tolerance)
    if outside.size == 0:
        return start
    index = start + int(outside[-1]) + 1
    return index if index < position.size else None


def _trapezoid_weights(x: np.ndarray) -> np.ndarray:
    w = np.zeros_like(x)
    w[1:] += 0.5 * np.diff(x)
    w[:-1] += 0.5 * np.diff(x)
    return w / w.sum()


# ---------------------------------------------------------------------------------- validation
def _check_robot(span: Span, robot: MDR) -> None:
    if robot.position > span.length:
        raise InputError(
            f"The 'robot.position' parameter must lie on the span [0, {span.length:g}] m. "
            f"Got {robot.position:g}."
        )
    total = robot.body_mass + robot.suspended_mass
    span_mass = span.conductor.mass_per_length * span.length
    if total > MAX_ROBOT_MASS_RATIO * span_mass:
        raise InputError(
            f"The 'robot' is too heavy for this span: {total:g} kg against a span mass of "
            f"{span_mass:.3g} kg (allowed: at most {MAX_ROBOT_MASS_RATIO:g} of it, beyond which "
            "the robot is not a small attachment of the line)."
        )
    slope = GRAVITY * total / (2 * span.tension)
    if slope > MAX_STATIC_SLOPE:
        raise InputError(
            f"The 'robot' is too heavy for the tension: its weight {GRAVITY * total:.3g} N "
            f"bends the line by {slope:.3g} rad at midspan (W / 2T; allowed "
            f"<= {MAX_STATIC_SLOPE:g}, the small-slope limit of the linear line model)."
        )


def _check_multiple(name: str, value: float, dt: float) -> int:
    steps = int(round(value / dt))
    if steps < 1 or abs(steps * dt - value) > 1e-9 * max(1.0, value):
        raise InputError(
            f"The '{name}' parameter ({value:g} s) must be a positive multiple of dt ({dt:g} s)."
        )
    return steps


def _calibrated_filter(record, dt, sensors, delays, noise_std, rank):
    """The estimator recipe (:func:`~powerline_control.recipe.design_estimator`) on the
    calibration record with the given sensors: filter, field map and the one-step sensor
    predictor C A (for the innovation check)."""
    options = {} if delays is None else {"delays": delays}
    if rank is not None:
        options["rank"] = rank
    design = design_estimator(record, len(sensors), dt=dt, sensors=list(sensors),
                              noise_std=noise_std if noise_std > 0 else None, **options)
    sys = design.model.to_statespace(measured=list(sensors))
    return (design.filter, np.asarray(design.model.field_map),
            np.asarray(sys.C) @ np.asarray(sys.A))


# ------------------------------------------------------------------------------------ the run
# run_closed_loop tells the story of the run; these are its stages, in the order it calls them.


@dataclass(frozen=True)
class _Settings:
    """run_closed_loop's options after checking, with the sample counts the run works in."""

    limits: RobotLimits
    duration: float
    dt: float
    control_period: float
    steps_per_period: int       # samples per control step
    plant_steps: int | None     # samples per plant block (None: chosen once the plant is known)
    n_cal: int                  # samples of the calibration window (robot parked)
    noise_fraction: float
    planner_time_budget: float | None
    antinode_window: float
    frequency_window: float
    retarget_threshold: float
    settle_margin: float
    delays: int | None
    estimator_rank: int | None
    motion: str
    n_elements: int | None
    obstacles: tuple

    @property
    def n_samples(self) -> int:
        """Samples of the whole run (durations are floored to whole samples, as simulate does)."""
        return int(np.floor(self.duration / self.dt + 1e-9)) + 1

    @property
    def window(self) -> int:
        """Samples the excited shape is fitted on (at least two control periods)."""
        return max(int(round(self.antinode_window / self.dt)), 2 * self.steps_per_period)

    @property
    def frequency_samples(self) -> int:
        """Samples the dominant frequency is measured on (at least two control periods)."""
        return max(int(round(self.frequency_window / self.dt)), 2 * self.steps_per_period)


def _checked_settings(span, robot, limits, sensors, *, n_elements, duration, calibration, dt,
                      control_period, plant_period, noise_fraction, delays, estimator_rank,
                      antinode_window, frequency_window, retarget_threshold, settle_margin,
                      obstacles, motion, planner_time_budget) -> _Settings:
    """Every argument checked once, in a fixed order (the first bad one is the one reported)."""
    if not isinstance(span, Span):
        raise InputError(f"The 'span' parameter must be a Span. Got {type(span).__name__}.")
    if not isinstance(robot, MDR):
        raise InputError(
            f"The 'robot' parameter must be an MDR (its position is the start). "
            f"Got {type(robot).__name__}."
        )
    _check_robot(span, robot)
    limits = limits or RobotLimits(v_max=0.5, a_max=1.0)
    if not isinstance(limits, RobotLimits):
        raise InputError(
            f"The 'limits' parameter must be RobotLimits or None. Got {type(limits).__name__}."
        )
    duration, dt, control_period, steps_per_period, plant_steps, n_cal = _checked_sampling(
        duration, calibration, dt, control_period, plant_period
    )
    # < 1 as in scenarios (config): noise larger than the signal it measures is no experiment,
    # and 1e300 overflowed into a raw NumPy "infs or NaNs" error.
    noise_fraction = check_real("noise_fraction", noise_fraction, low=0.0, low_inclusive=True,
                                high=1.0, high_inclusive=False)
    if planner_time_budget is not None:  # checked even when motion="closed_form" ignores it
        planner_time_budget = check_real("planner_time_budget", planner_time_budget, low=0.0)
    antinode_window = check_real("antinode_window", antinode_window, low=0.0)
    frequency_window = check_real("frequency_window", frequency_window, low=0.0)
    retarget_threshold = check_real("retarget_threshold", retarget_threshold, low=0.0)
    settle_margin = check_real("settle_margin", settle_margin, low=0.0, low_inclusive=True)
    if delays is not None:
        delays = check_int("delays", delays, low=1)
    if estimator_rank is not None:
        estimator_rank = check_int("estimator_rank", estimator_rank, low=1)
    if motion not in ("closed_form", "mpc"):
        raise InputError(f"The 'motion' parameter must be 'closed_form' or 'mpc'. Got {motion!r}.")
    n_elements = _checked_mesh_and_sensors(n_elements, sensors, duration, dt)
    return _Settings(
        limits=limits, duration=duration, dt=dt, control_period=control_period,
        steps_per_period=steps_per_period, plant_steps=plant_steps, n_cal=n_cal,
        noise_fraction=noise_fraction, planner_time_budget=planner_time_budget,
        antinode_window=antinode_window, frequency_window=frequency_window,
        retarget_threshold=retarget_threshold, settle_margin=settle_margin, delays=delays,
        estimator_rank=estimator_rank, motion=motion, n_elements=n_elements,
        obstacles=tuple(_checked_obstacles(obstacles, robot)),
    )


def _checked_sampling(duration, calibration, dt, control_period, plant_period):
    """(duration, dt, control_period, steps per control period, steps per plant block or None,
    calibration samples): the run's times, whose rates must divide dt."""
    duration = check_real("duration", duration, low=0.0)
    calibration = check_real(
        "calibration", calibration, low=0.0, high=duration, high_inclusive=False
    )
    dt = check_real("dt", dt, low=0.0)
    # A period longer than the run would never act (1e300 was accepted and ignored).
    control_period = check_real("control_period", control_period, low=0.0, high=duration)
    if plant_period is not None:
        plant_period = check_real("plant_period", plant_period, low=0.0, high=duration)
    steps_per_period = _check_multiple("control_period", control_period, dt)
    plant_steps = (
        _check_multiple("plant_period", plant_period, dt) if plant_period is not None else None
    )
    # Durations are sampled (floored to whole samples, as simulate does); rates must divide.
    n_cal = int(np.floor(calibration / dt + 1e-9)) + 1
    if n_cal < 3:
        raise InputError(
            f"The 'calibration' parameter ({calibration:g} s) must hold at least 2 samples of "
            f"dt ({dt:g} s)."
        )
    return duration, dt, control_period, steps_per_period, plant_steps, n_cal


def _checked_mesh_and_sensors(n_elements, sensors, duration, dt):
    """The checked n_elements; the sensors and the run's memory checked before any model."""
    if n_elements is not None:  # the sensors early, before any model is built
        n_elements = check_int("n_elements", n_elements, low=2)
        check_indices("sensors", sensors, n_elements + 1)
    # The loop records ~4 node histories and ~16 scalars per sample (and the parked comparisons):
    # refuse a duration / dt that cannot fit before anything is built (n_elements=None: >= 2 nodes).
    n_samples = int(np.floor(duration / dt + 1e-9)) + 1
    check_budget(f"run_closed_loop's {n_samples}-sample histories",
                 nbytes=8.0 * n_samples * (4 * (n_elements + 1 if n_elements else 2) + 16),
                 parameter="duration", value=duration,
                 fix=f"shorten duration ({duration:g} s), increase dt ({dt:g} s) or use fewer "
                     f"elements (n_elements={n_elements})")
    if len(set(sensors)) != len(sensors):
        raise InputError(f"The 'sensors' parameter must not repeat a node. Got {list(sensors)}.")
    return n_elements


def _checked_obstacles(obstacles, robot: MDR) -> list[tuple[float, float]]:
    """(left, right) pairs, left < right, none holding the robot's start."""
    try:
        pairs = [tuple(pair) for pair in obstacles]
    except TypeError:
        pairs = [()]
    if any(len(pair) != 2 for pair in pairs):
        raise InputError("The 'obstacles' parameter must be a sequence of (left, right) pairs "
                         f"in m. Got {obstacles!r}.")
    checked = [(check_real("obstacles", a), check_real("obstacles", b)) for a, b in pairs]
    for left, right in checked:
        if not left < right:
            raise InputError(f"Each of 'obstacles' must be (left, right), left < right. Got "
                             f"{(left, right)}.")
        if left <= robot.position <= right:
            raise InputError(
                f"The 'robot.position' ({robot.position:g} m) lies inside the obstacle "
                f"{(left, right)}."
            )
    return checked


@dataclass(frozen=True)
class _Line:
    """The simulated line: the bare FE model, the plant with and without the robot, the loads."""

    span: Span
    bare: LineModel
    sensors: tuple              # measured node indices, sorted (the estimator's output order)
    sensor_rows: np.ndarray     # (p, r): the plant modes' displacements at the sensors
    clamp_distance: float       # where the "near_clamp" comparison parks the robot, m
    t: np.ndarray               # (n_t,) sample times, s
    plant: _ModalPlant          # with the robot
    free_plant: _ModalPlant     # without it (the "no_robot" comparison)
    plant_steps: int            # samples per plant block (the robot's position held)
    modal_force: np.ndarray     # (n_t, r)
    residual: np.ndarray        # (n_nodes, n_t): the dropped modes' response to the loads
    harmonic: tuple | None      # (frequency, parts) of the last load when it is one sine
    weights: np.ndarray         # (n_nodes,) trapezoid weights: RMS over the span by length


def _build_line(span, robot, segments, settings: _Settings, sensors, *, bc, damping, n_modes,
                clamp_distance) -> _Line:
    """The FE model, the sensors on it, the modal plant and the loads' histories."""
    bare = LineModel(span, settings.n_elements, bc, damping=damping)
    sensors = tuple(sorted(check_indices("sensors", sensors, bare.n_nodes).tolist()))
    fixed_nodes = [j for j in sensors if bare.displacement_map()[[j]].nnz == 0]
    if fixed_nodes:
        raise InputError(
            f"The 'sensors' parameter names support node(s) {fixed_nodes}, where the line does "
            "not move: the estimator's model has no displacement there."
        )
    clamp_distance = (
        min(0.05 * span.length, 1.5)
        if clamp_distance is None
        else check_real("clamp_distance", clamp_distance, low=0.0, high=span.length)
    )
    t = settings.dt * np.arange(settings.n_samples)
    load_frequencies = [
        float(b.frequency)
        for _, loads in segments
        for f in loads
        for b in [f.bind(bare) if hasattr(f, "bind") else f]
        if getattr(b, "frequency", None) is not None   # a user's load may say None: not a sine
    ]
    if n_modes is None:
        n_modes = _default_modes(span, bare, load_frequencies, settings.dt)
    else:
        n_modes = check_int("n_modes", n_modes, low=1, high=bare.n_dofs)
    plant = _ModalPlant(bare, robot, n_modes, settings.dt)
    plant_steps = settings.plant_steps
    if plant_steps is None:
        # 10 ms blocks, or one block per control period for a long span's band of ~100 modes
        # (each new position costs an exponential of a (4r + 2)-square matrix).
        plant_steps = (
            settings.steps_per_period
            if plant.r > SMALL_PLANT_MODES
            else max(1, min(settings.steps_per_period, int(round(0.01 / settings.dt))))
        )
    free_plant = _ModalPlant(bare, None, n_modes, settings.dt)
    modal_force, residual, harmonic = _load_histories(bare, plant, segments, t)
    return _Line(
        span=span, bare=bare, sensors=sensors, sensor_rows=plant.nodal[list(sensors)],
        clamp_distance=clamp_distance, t=t, plant=plant, free_plant=free_plant,
        plant_steps=plant_steps, modal_force=modal_force, residual=residual, harmonic=harmonic,
        weights=_trapezoid_weights(bare.node_positions),
    )


def _field(plant: _ModalPlant, states: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Nodal displacements (n_nodes, n_t) of plant states (n_t, 2 n_q) plus the loads' residual."""
    return plant.nodal @ states[:, : plant.r].T + residual


@dataclass(frozen=True)
class _Calibration:
    """The estimator, designed on the first window with the robot parked at its start."""

    start_states: np.ndarray    # (n_t, 2 n_q): the plant parked at the start for the whole run
    noise_std: float            # the sensors' noise, m
    record: np.ndarray          # (n_nodes, n_cal) noisy calibration field
    robot_record: np.ndarray    # (n_cal,) noisy line displacement under the robot
    kf: KalmanFilter            # warmed up on the record; it keeps stepping in the loop
    field_map: np.ndarray       # estimator states -> nodal displacements
    predict_sensors: np.ndarray  # one-step sensor predictor C A (the innovation check)
    warm_states: np.ndarray     # (n_cal, n_states) the filter's states over the record
    innovation_rms: float       # RMS one-step prediction error of the sensors over the record
    innovation_power: np.ndarray  # (n_cal,) its mean square per sample (0 for the first two)


def _calibrate(line: _Line, robot: MDR, settings: _Settings, rng) -> _Calibration:
    """Simulate the parked start, add sensor noise, identify the estimator and warm it up."""
    n_cal, sensor_list = settings.n_cal, list(line.sensors)
    start_states = _run_parked(line.plant, robot.position, line.modal_force, line.t.size)
    calib_true = _field(line.plant, start_states[:n_cal], line.residual[:, :n_cal])
    calib_rms = float(np.sqrt(np.mean(calib_true**2)))
    noise_std = settings.noise_fraction * calib_rms
    record = calib_true + noise_std * rng.standard_normal(calib_true.shape)
    kf, field_map, predict_sensors = _calibrated_filter(
        record, settings.dt, sensor_list, settings.delays, noise_std, settings.estimator_rank
    )
    # C order, as the run's state history it is copied into (the same BLAS calls below)
    warm_states = np.ascontiguousarray(
        np.asarray(kf.filter(record[sensor_list], update_state=True).states).T
    )
    innovation = record[sensor_list, 2:] - predict_sensors @ warm_states[1 : n_cal - 1].T
    innovation_power = np.zeros(n_cal)
    innovation_power[2:] = np.mean(innovation**2, axis=0)
    robot_record = start_states[:n_cal, : line.plant.r] @ line.plant.coupling(robot.position) + (
        noise_std * rng.standard_normal(n_cal)
    )
    return _Calibration(
        start_states=start_states, noise_std=noise_std, record=record,
        robot_record=robot_record, kf=kf, field_map=field_map, predict_sensors=predict_sensors,
        warm_states=warm_states, innovation_rms=float(np.sqrt(np.mean(innovation**2))),
        innovation_power=innovation_power,
    )


@dataclass
class _Records:
    """What the run records: histories over every sample (filled as it goes; the calibration
    window first) and a log of every control step."""

    plant_states: np.ndarray    # (n_t, 2 n_q) true plant states
    filter_states: np.ndarray   # (n_t, n_states) the Kalman filter's
    position: np.ndarray        # (n_t,) robot position, m
    velocity: np.ndarray        # (n_t,) robot velocity, m/s
    target: np.ndarray          # (n_t,) the goal steered to (NaN before the first)
    measured: np.ndarray        # (p, n_t) noisy sensor displacements
    robot_measured: np.ndarray  # (n_t,) noisy line displacement under the robot
    innovation_power: np.ndarray  # (n_t,) mean square one-step prediction error of the sensors
    statuses: list = field(default_factory=list)
    frequencies: list = field(default_factory=list)
    innovation_ratio: list = field(default_factory=list)
    retarget_times: list = field(default_factory=list)
    target_starts: list = field(default_factory=list)   # sample index of each new target
    predictions: list = field(default_factory=list)

    @classmethod
    def after_calibration(cls, line: _Line, calibration: _Calibration, robot: MDR,
                          n_cal: int) -> _Records:
        """Histories for the whole run, the calibration window's filled in."""
        n_t = line.t.size
        records = cls(
            plant_states=np.empty((n_t, calibration.start_states.shape[1])),
            filter_states=np.empty((n_t, calibration.field_map.shape[1])),
            position=np.full(n_t, robot.position),
            velocity=np.zeros(n_t),
            target=np.full(n_t, np.nan),
            measured=np.zeros((len(line.sensors), n_t)),
            robot_measured=np.zeros(n_t),
            innovation_power=np.zeros(n_t),
        )
        records.plant_states[:n_cal] = calibration.start_states[:n_cal]
        records.filter_states[:n_cal] = calibration.warm_states
        records.measured[:, :n_cal] = calibration.record[list(line.sensors)]
        records.robot_measured[:n_cal] = calibration.robot_record
        records.innovation_power[:n_cal] = calibration.innovation_power
        return records


@dataclass
class _LoopState:
    """Where the loop stands between control steps: the robot's motion and the plant's state."""

    position: float             # the robot's, m
    velocity: float             # the robot's, m/s
    steer: float                # where it was last steered to (the goal, in its free interval)
    plant_state: np.ndarray     # the plant's state z = (q, y, q', y') at this sample


@dataclass
class _Targeting:
    """The policy's memory between control steps (see the module doc)."""

    goal: float = np.nan                # where the robot is sent
    anchor: float = np.nan              # the choice the confirmation gate is anchored to
    loop: float = np.nan                # the loop length at the anchor, m
    anchor_frequency: float = np.nan    # the dominant frequency the anchor was chosen at
    pending_since: float | None = None  # when the frequency left the anchor's (a wind change)
    still_since: float | None = None    # since when the robot is still at its steer point
    choices: int = 0                    # loops tried for this excitation
    confirmed: bool = False             # the choice is final until the frequency changes

    def update_clocks(self, now: float, robot_still: bool, frequency: float,
                      threshold: float) -> None:
        """Track how long the robot has been still and the frequency away from the anchor's."""
        if not robot_still:
            self.still_since = None
        elif self.still_since is None:
            self.still_since = now
        changed = (
            not np.isnan(self.anchor_frequency)
            and abs(frequency - self.anchor_frequency) > threshold * self.anchor_frequency
        )
        if changed and self.pending_since is None:
            self.pending_since = now
        elif not changed:
            self.pending_since = None

    def due(self, now: float, robot_still: bool, window_time: float,
            settle_margin: float) -> tuple[bool, bool]:
        """(retarget, confirm): a first target or a wind change held for a window with the robot
        still; else a confirmation once the robot has been still for a window."""
        retarget = np.isnan(self.goal) or (
            self.pending_since is not None
            and now - self.pending_since >= max(window_time, 1.0)
            and robot_still
        )
        confirm = (
            not retarget
            and not self.confirmed
            and self.still_since is not None
            and now - self.still_since >= max(window_time, settle_margin)
        )
        return retarget, confirm

    def gate_unsteady(self, retarget: bool, confirm: bool, unsteady: float,
                      now: float) -> tuple[bool, bool]:
        """(retarget, confirm) once the window's unsteadiness is known."""
        since = self.pending_since if retarget else self.still_since
        waited = now - since if since is not None else 0.0
        # A window that still beats with a decaying mode misleads the prediction: wait (up to
        # MAX_WAIT s) for a steady one, except for the very first target.
        if unsteady > UNSTEADY_LIMIT and waited < MAX_WAIT and not np.isnan(self.goal):
            return False, False
        if confirm and unsteady > UNSTEADY_LIMIT:
            # Still beating after MAX_WAIT s: its steady-state prediction is no better than
            # the anchor's (a long, lightly damped span rings for tens of seconds after the
            # robot arrives). Keep the goal and stop.
            self.confirmed = True
            return retarget, False
        return retarget, confirm

    def accept(self, position: float, loop: float, frequency: float, retarget: bool) -> None:
        """Take a predicted best position as the goal (a new target, or a confirmation)."""
        if retarget:
            self.anchor, self.loop, self.goal = position, loop, position
            self.anchor_frequency, self.pending_since = frequency, None
            self.choices, self.confirmed = 1, False
        elif abs(position - self.anchor) <= 0.25 * self.loop:
            # The same minimum, better estimated from a steady window: accept it (the
            # gate is anchored to the choice, it never moves with the goal) and stop.
            self.goal, self.confirmed = position, True
        elif self.choices < MAX_CHOICES:
            # Another loop: the first choice came from a beating window. Go there.
            self.anchor, self.loop, self.goal = position, loop, position
            self.choices += 1
        else:
            self.confirmed = True


def _motion_planner(settings: _Settings, span_length: float) -> MotionPlanner | None:
    """The receding-horizon planner for motion="mpc"; None for the closed-form law."""
    if settings.motion != "mpc":
        return None
    limits, control_period = settings.limits, settings.control_period
    braking = limits.v_max / limits.a_max
    return MotionPlanner(
        limits, dt=control_period, horizon=max(40, int(np.ceil(2 * braking / control_period))),
        span_length=span_length, obstacles=list(settings.obstacles),
        **({} if settings.planner_time_budget is None
           else {"time_budget": settings.planner_time_budget}),
    )


def _observe(records: _Records, calibration: _Calibration, settings: _Settings,
             k: int) -> float:
    """The dominant frequency the sensors show up to sample k; logs it and the innovation ratio
    (the estimator's recent one-step error over its calibration value)."""
    lo = max(k + 1 - settings.window, 0)
    frequency = _dominant_frequency(
        records.measured[:, max(k + 1 - settings.frequency_samples, 0) : k + 1], settings.dt
    )
    records.frequencies.append(frequency)
    records.innovation_ratio.append(
        float(np.sqrt(np.mean(records.innovation_power[lo + 1 : k + 1])))
        / max(calibration.innovation_rms, 1e-300)
    )
    return frequency


def _bare_shape(records: _Records, line: _Line, robot: MDR, x_r: float, lo: int, end: int,
                frequency: float) -> np.ndarray:
    """The robot-free excited shape from the sensors' and the robot's own phasors on [lo, end]."""
    tt = line.t[lo : end + 1]
    sensed = _fit_phasor(records.measured[:, lo : end + 1], tt, frequency)
    at_robot = _fit_phasor(records.robot_measured[None, lo : end + 1], tt, frequency)[0]
    return _kernel_shape(line.plant, line.sensor_rows, sensed, robot, x_r, at_robot,
                         2 * np.pi * frequency)


def _excited_shape(records: _Records, line: _Line, robot: MDR, x_r: float, end: int,
                   frequency: float, window: int) -> tuple[np.ndarray, float]:
    """W_bare over the last window (estimate phasor minus the robot's own reaction), and how
    unsteady it is: the relative difference of the shapes fitted on its two halves."""
    lo = max(end + 1 - window, 0)
    mid = (lo + end) // 2
    first = _bare_shape(records, line, robot, x_r, lo, mid, frequency)
    second = _bare_shape(records, line, robot, x_r, mid, end, frequency)
    scale = np.linalg.norm(first) + np.linalg.norm(second)
    unsteady = 2 * float(np.linalg.norm(first - second)) / max(scale, 1e-300)
    return _bare_shape(records, line, robot, x_r, lo, end, frequency), unsteady


def _update_target(targeting: _Targeting, state: _LoopState, records: _Records, line: _Line,
                   robot: MDR, settings: _Settings, k: int, frequency: float) -> None:
    """The policy at control step k: choose a first target, confirm it once the robot has
    settled, or choose anew after a wind change (module doc)."""
    t = line.t
    robot_still = abs(state.velocity) < 1e-3 and abs(state.position - state.steer) < 1e-3
    targeting.update_clocks(t[k], robot_still, frequency, settings.retarget_threshold)
    retarget, confirm = targeting.due(t[k], robot_still, settings.window * settings.dt,
                                      settings.settle_margin)
    if not (retarget or confirm):
        return
    shape, unsteady = _excited_shape(records, line, robot, state.position, k, frequency,
                                     settings.window)
    retarget, confirm = targeting.gate_unsteady(retarget, confirm, unsteady, t[k])
    if not (retarget or confirm):
        return
    low, high = _free_interval(state.position, settings.obstacles, line.span.length)
    reach = _reach(settings.limits, TRAVEL_FRACTION * (t[-1] - t[k]))
    choice = _choose_target(shape, line.plant, robot, 2 * np.pi * frequency, line.weights,
                            state.position, low, high, reach)
    if choice is None:
        return
    position, loop, grid, predicted = choice
    records.predictions.append((float(t[k]), grid, predicted, read_only(shape)))
    if retarget:
        records.retarget_times.append(float(t[k]))
        records.target_starts.append(k)
    targeting.accept(position, loop, frequency, retarget)


def _move_robot(state: _LoopState, goal: float, records: _Records, settings: _Settings,
                planner: MotionPlanner | None, span_length: float, k: int, end: int) -> None:
    """Steer towards the goal (clipped to the free interval) over samples k..end and record the
    robot's motion: one constant acceleration, the limits held at every sample."""
    x_r, v_r, limits = state.position, state.velocity, settings.limits
    low, high = _free_interval(x_r, settings.obstacles, span_length)
    steer = float(np.clip(goal, low, high)) if not np.isnan(goal) else x_r
    period = (end - k) * settings.dt
    if planner is not None:
        step = planner.step((x_r, v_r), steer)
        accel, status = float(step.acceleration), step.status
    else:
        accel = _time_optimal_accel(x_r, v_r, steer, limits, period)
        status = "closed_form" if steer == goal or np.isnan(goal) else "blocked"
    records.statuses.append(status)
    # The actuator saturates: limits hold at every sample.
    accel = float(np.clip(accel, -limits.a_max, limits.a_max))
    accel = float(np.clip(accel, (-limits.v_max - v_r) / period, (limits.v_max - v_r) / period))
    tau = settings.dt * np.arange(1, end - k + 1)
    records.position[k + 1 : end + 1] = x_r + v_r * tau + 0.5 * accel * tau**2
    records.velocity[k + 1 : end + 1] = v_r + accel * tau
    records.target[k + 1 : end + 1] = goal
    state.steer = steer


def _advance_plant(state: _LoopState, records: _Records, line: _Line, calibration: _Calibration,
                   rng, timings: dict, k: int, end: int) -> None:
    """Simulate, sense and filter samples k..end in blocks that hold the robot's mid-block
    position; leaves the loop's state at sample end."""
    j = k
    while j < end:
        block_end = min(j + line.plant_steps, end)
        x_mid = 0.5 * (records.position[j] + records.position[block_end])
        tic = time.perf_counter()
        phi, g0, g1 = line.plant.discretise(x_mid)
        at_robot = line.plant.coupling(x_mid)
        timings["plant update"] += time.perf_counter() - tic
        tic = time.perf_counter()
        state.plant_state = _step_plant(state.plant_state, (phi, g0, g1), records,
                                        line.modal_force, j, block_end)
        y_block = _sense(records, line, at_robot, calibration.noise_std, rng, j, block_end)
        tac = time.perf_counter()
        _kalman_steps(records, calibration, y_block, j, block_end)
        timings["plant"] += tac - tic
        timings["filter"] += time.perf_counter() - tac
        j = block_end
    state.position, state.velocity = float(records.position[end]), float(records.velocity[end])


def _step_plant(z: np.ndarray, maps: tuple, records: _Records, modal_force: np.ndarray,
                j: int, block_end: int) -> np.ndarray:
    """The plant's exact first-order-hold steps from sample j to block_end, recorded; the last
    state."""
    phi, g0, g1 = maps
    for i in range(j, block_end):
        z = phi @ z + g0 @ modal_force[i] + g1 @ modal_force[i + 1]
        records.plant_states[i + 1] = z
    return z


def _sense(records: _Records, line: _Line, at_robot: np.ndarray, noise_std: float, rng,
           j: int, block_end: int) -> np.ndarray:
    """The sensors' and the robot's noisy displacements over samples j+1..block_end, recorded;
    the sensors' (n_samples, p)."""
    sensor_list = list(line.sensors)
    block = records.plant_states[j + 1 : block_end + 1, : line.plant.r]
    y_block = block @ line.sensor_rows.T + line.residual[sensor_list, j + 1 : block_end + 1].T
    robot_block = block @ at_robot
    if noise_std:
        y_block = y_block + noise_std * rng.standard_normal(y_block.shape)
        robot_block = robot_block + noise_std * rng.standard_normal(robot_block.shape)
    records.measured[:, j + 1 : block_end + 1] = y_block.T
    records.robot_measured[j + 1 : block_end + 1] = robot_block
    return y_block


def _kalman_steps(records: _Records, calibration: _Calibration, y_block: np.ndarray, j: int,
                  block_end: int) -> None:
    """The Kalman filter's steps on the block's measurements, and its one-step innovations."""
    for i in range(j, block_end):
        records.filter_states[i + 1] = calibration.kf.step(y_block[i - j])
    predicted = records.filter_states[j:block_end] @ calibration.predict_sensors.T
    records.innovation_power[j + 1 : block_end + 1] = np.mean((y_block - predicted) ** 2, axis=1)


@dataclass(frozen=True)
class _Settling:
    """When the robot arrived and stayed: per target, per load change, and the settled window."""

    settle_times: tuple
    follow_times: tuple
    settled: bool
    mask: np.ndarray            # (n_t,) the samples of the settled window
    window: tuple               # (start, end) of the settled window, s


def _settling(records: _Records, t: np.ndarray, segments, n_cal: int, loop_length: float,
              settle_margin: float) -> _Settling:
    """Arrival ("within 1 % of a loop of the final position, for good") after each target and
    each load change, and the settled window that starts ``settle_margin`` after the last."""
    position, target_starts, n_t = records.position, records.target_starts, t.size
    tolerance = 0.01 * loop_length
    settle_times = []
    bounds = target_starts[1:] + [n_t - 1]
    for begin, stop in zip(target_starts, bounds, strict=True):
        arrival = _arrival_index(position[: stop + 1], begin, tolerance)
        settle_times.append(float(t[arrival] - t[begin]) if arrival is not None else float("nan"))
    follow_times = []
    for change in (start for start, _ in segments[1:]):
        later = [i for i, begin in enumerate(target_starts) if t[begin] >= change]
        if not later:
            follow_times.append(float("nan"))
            continue
        begin, stop = target_starts[later[0]], bounds[later[0]]
        arrival = _arrival_index(position[: stop + 1], begin, tolerance)
        follow_times.append(float(t[arrival] - change) if arrival is not None else float("nan"))
    last_begin = target_starts[-1] if target_starts else n_cal - 1
    arrival = _arrival_index(position, last_begin, tolerance)
    window_start = t[arrival] + settle_margin if arrival is not None else np.inf
    settled = bool(window_start <= t[-1] - 1.0)
    if not settled:
        window_start = max(t[-1] - 1.0, 0.0)
    mask = t >= window_start - 1e-12
    return _Settling(tuple(settle_times), tuple(follow_times), settled, mask,
                     (float(t[mask][0]), float(t[-1])))


def _relative_velocity(plant: _ModalPlant, states: np.ndarray, positions) -> np.ndarray:
    """Velocity of the line under the robot relative to its absorber mass, per sample (zero
    without an absorber); ``positions`` one parked position or one per sample."""
    nq, r = plant.n_q, plant.r
    if not plant.absorber:
        return np.zeros(states.shape[0])
    if np.ndim(positions) == 0:
        line_velocity = states[:, nq : nq + r] @ plant.coupling(float(positions))
    else:
        coupling = np.stack([plant.coupling(float(x)) for x in positions])
        line_velocity = np.einsum("ij,ij->i", states[:, nq : nq + r], coupling)
    return line_velocity - states[:, nq + r]


def _damper_power(plant: _ModalPlant, robot: MDR, states: np.ndarray, positions) -> np.ndarray:
    """Power dissipated in the robot's damper per sample, W."""
    damping_coefficient = robot.damping if robot.has_absorber else 0.0
    return damping_coefficient * _relative_velocity(plant, states, positions) ** 2


def _comparison(name: str, position: float, states: np.ndarray, plant: _ModalPlant,
                power: np.ndarray, line: _Line, mask: np.ndarray) -> Comparison:
    """The vibration of the plant's states over the settled window (``mask``)."""
    field_window = _field(plant, states[mask], line.residual[:, mask])
    rms = float(np.sqrt(np.mean(line.weights @ field_window**2)))
    envelope = np.max(np.abs(field_window), axis=1)
    return Comparison(name, float(position), rms, float(envelope.max()),
                      float(np.mean(power[mask])) if power.size else 0.0,
                      read_only(envelope))


def _parked_comparison(name: str, x_park: float | None, line: _Line, robot: MDR,
                       mask: np.ndarray) -> Comparison:
    """The whole run with the robot parked at ``x_park`` (None: no robot on the line)."""
    n_t = line.t.size
    if x_park is None:
        states = _run_parked(line.free_plant, None, line.modal_force, n_t)
        return _comparison(name, np.nan, states, line.free_plant, np.zeros(n_t), line, mask)
    states = _run_parked(line.plant, x_park, line.modal_force, n_t)
    power = _damper_power(line.plant, robot, states, x_park)
    return _comparison(name, x_park, states, line.plant, power, line, mask)


def _steady_rms(line: _Line, x: float, omega: float, modal_amplitude: np.ndarray,
                static_amplitude: np.ndarray) -> float:
    """RMS over the span in steady state under a sine (its modal and residual amplitudes) with
    the robot parked at x."""
    plant = line.plant
    amplitude = plant.steady_state(x, omega, modal_amplitude)
    shape = plant.nodal @ amplitude[: plant.r] + static_amplitude
    return float(np.sqrt(0.5 * line.weights @ np.abs(shape) ** 2))


def _steady_state_scan(line: _Line) -> tuple[np.ndarray, np.ndarray, float]:
    """(positions, RMS, best position): the steady state with the robot parked along the span
    under the last harmonic load, a coarse grid and a fine one around its minimum (empty and
    NaN when that load is not one sine)."""
    if line.harmonic is None:
        return np.zeros(0), np.zeros(0), float("nan")
    span_length = line.span.length
    scan_frequency, parts = line.harmonic
    omega = 2 * np.pi * scan_frequency
    modal_amplitude = sum(g * _phasor_of(load, scan_frequency) for load, g, _ in parts)
    static_amplitude = sum(s * _phasor_of(load, scan_frequency) for load, _, s in parts)
    loads = (omega, modal_amplitude, static_amplitude)
    coarse = np.linspace(0.0, span_length, 4 * line.bare.n_elements + 1)[1:-1]
    coarse_rms = np.array([_steady_rms(line, x, *loads) for x in coarse])
    i = int(np.argmin(coarse_rms))
    step = coarse[1] - coarse[0]
    fine = np.linspace(max(coarse[i] - 2 * step, 1e-9),
                       min(coarse[i] + 2 * step, span_length - 1e-9), 41)
    fine_rms = np.array([_steady_rms(line, x, *loads) for x in fine])
    positions = np.concatenate([coarse, fine])
    order = np.argsort(positions)
    return (positions[order], np.concatenate([coarse_rms, fine_rms])[order],
            float(fine[int(np.argmin(fine_rms))]))


def _comparisons(line: _Line, robot: MDR, records: _Records, calibration: _Calibration,
                 mask: np.ndarray, best_position: float, loop_power: np.ndarray) -> tuple:
    """no robot, parked near a clamp, parked at the start, parked at the best position, and the
    closed loop, over the same settled window."""
    start_states, plant = calibration.start_states, line.plant
    return (
        _parked_comparison("no_robot", None, line, robot, mask),
        _parked_comparison("near_clamp", line.clamp_distance, line, robot, mask),
        _comparison("start", robot.position, start_states, plant,
                    _damper_power(plant, robot, start_states, robot.position), line, mask),
        _parked_comparison("best", best_position, line, robot, mask)
        if not np.isnan(best_position)
        else Comparison("best", np.nan, np.nan, np.nan, np.nan,
                        read_only(np.zeros(line.bare.n_nodes))),
        _comparison("closed_loop", records.position[-1], records.plant_states, plant,
                    loop_power, line, mask),
    )


# Thousands of small products per simulated second: one BLAS thread is several times faster than
# two contending ones on a shared 2-core machine. The limit applies inside this call only.
@threadpool_limits.wrap(limits=1, user_api="blas")
def run_closed_loop(
    span: Span,
    force: object,
    robot: MDR,
    limits: RobotLimits | None = None,
    *,
    sensors: Sequence[int],
    n_elements: int | None = 100,
    bc: object = "pinned",
    damping: object = None,
    duration: float = 10.0,
    calibration: float = 2.0,
    dt: float = 1e-3,
    control_period: float = 0.05,
    plant_period: float | None = None,
    noise_fraction: float = 0.01,
    delays: int | None = None,
    estimator_rank: int | None = None,
    antinode_window: float = 1.0,
    frequency_window: float = 2.0,
    retarget_threshold: float = 0.05,
    settle_margin: float = 1.0,
    n_modes: int | None = None,
    clamp_distance: float | None = None,
    obstacles: Sequence[tuple[float, float]] = (),
    motion: str = "closed_form",
    planner_time_budget: float | None = None,
    seed: int | np.random.Generator | None = 0,
) -> ClosedLoopResult:
    """Drive the damping robot to the antinode from sensor data and measure the vibration.

    Parameters
    ----------
    span : Span
        The span.
    force : load, list of loads, or list of (start_time, load)
        The excitation (e.g. :class:`~powerline_control.excitation.HarmonicForce`); a schedule
        ``[(0.0, load_a), (8.0, load_b)]`` switches loads at the given times (a wind change).
    robot : MDR
        The robot; ``robot.position`` is where it starts (and stays parked in the baseline).
    limits : RobotLimits or None
        Speed and acceleration limits (default v_max = 0.5 m/s, a_max = 1 m/s^2).
    sensors : sequence of int
        Measured node indices (not at a pinned support, where the line never moves).
    n_elements : int or None
        Elements of the FE model whose modes play the real line (None: the mesh the physics
        chooses for the aeolian band, see :class:`~powerline_control.fem.LineModel`).
    bc : str or (str, str)
        Supports.
    damping : None, ModalDamping or RayleighDamping
        The line's own damping (none by default, as in the paper).
    duration : float
        Total simulated time, s, calibration included.
    calibration : float
        Initial window with the robot parked, used to identify the estimator's model, s
        (floored to whole samples, like ``duration``).
    dt : float
        Sample interval, s.
    control_period : float
        Interval between control steps, s (a multiple of ``dt``).
    plant_period : float or None
        Interval over which the plant holds the robot's (mid-block) position, s (a multiple of
        ``dt``). None: 10 ms, or the control period when the plant keeps a band of more than 48
        modes (a long span: each new position costs a matrix exponential of the band).
    noise_fraction : float
        Sensor noise as a fraction of the RMS displacement of the calibration window (0: none;
        the filter then assumes a 1e-4 floor so that its Riccati equation stays regular).
    delays : int or None
        Time delays of the estimator's DMD model (None: the recipe's default).
    estimator_rank : int or None
        Rank of the estimator's model (None: the recipe's default). The filter's cost grows
        with it, not with the mesh.
    antinode_window : float
        Length of the window the excited shape is fitted on, s.
    frequency_window : float
        Length of the window the dominant frequency is measured on, s (its resolution is about
        1 / window: long enough to tell the load from the beating of a decaying mode).
    retarget_threshold : float
        Relative change of the dominant frequency that, held for ``antinode_window`` (and at
        least 1 s), makes the robot choose a new target (a wind change).
    settle_margin : float
        Time after the robot's arrival before the settled window starts, s.
    n_modes : int or None
        Lowest bare-line modes kept by the plant; None keeps those below 8x the highest load
        frequency (at least 12) when they are at most 48, else the band from 0.6x the lowest to
        1.4x the highest load frequency (long spans).
    clamp_distance : float or None
        Where the "near clamp" comparison parks the robot, m from the left support; default
        min(0.05 L, 1.5 m), where fixed dampers sit.
    obstacles : sequence of (left, right)
        Intervals the robot may not enter or cross, m.
    motion : {"closed_form", "mpc"}
        Motion law: the closed-form time-optimal approach, or the receding-horizon planner.
    planner_time_budget : float or None
        Wall-clock budget of one MPC step, s (``motion="mpc"`` only); None (default): the
        planner's iteration limits, so results do not depend on the machine's load.
    seed : int, Generator or None
        Sensor noise.

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    InputError
        For invalid arguments: sensors outside the model or at a support, a calibration longer
        than the run, periods that are not multiples of ``dt``, a robot off the span, inside an
        obstacle, or heavier than the line can carry (more than 25 % of the span's mass, or a
        static slope W / 2T above 0.05 rad).
    PowerlineControlError
        From the stages (identification, estimation, planning) when they report trouble.

    Examples
    --------
    See :class:`ClosedLoopResult`.
    """
    settings = _checked_settings(
        span, robot, limits, sensors, n_elements=n_elements, duration=duration,
        calibration=calibration, dt=dt, control_period=control_period, plant_period=plant_period,
        noise_fraction=noise_fraction, delays=delays, estimator_rank=estimator_rank,
        antinode_window=antinode_window, frequency_window=frequency_window,
        retarget_threshold=retarget_threshold, settle_margin=settle_margin, obstacles=obstacles,
        motion=motion, planner_time_budget=planner_time_budget,
    )
    rng = check_rng(seed)
    segments = _segments(force, settings.duration)

    # ---- the line, its loads, and the estimator calibrated with the robot parked at its start
    setup_start = time.perf_counter()
    line = _build_line(span, robot, segments, settings, sensors, bc=bc, damping=damping,
                       n_modes=n_modes, clamp_distance=clamp_distance)
    calibrated = _calibrate(line, robot, settings, rng)
    n_cal, t = settings.n_cal, line.t
    records = _Records.after_calibration(line, calibrated, robot, n_cal)

    # ---- the loop: every control period, estimate, choose a target, move (and simulate)
    state = _LoopState(robot.position, 0.0, robot.position,
                       calibrated.start_states[n_cal - 1].copy())
    targeting = _Targeting()
    planner = _motion_planner(settings, span.length)
    timings = {"setup": time.perf_counter() - setup_start, "plant": 0.0, "plant update": 0.0,
               "filter": 0.0, "modes": line.plant.r}
    wall_start, cpu_start = time.perf_counter(), time.process_time()
    k = n_cal - 1
    while k < t.size - 1:
        end = min(k + settings.steps_per_period, t.size - 1)
        frequency = _observe(records, calibrated, settings, k)
        _update_target(targeting, state, records, line, robot, settings, k, frequency)
        _move_robot(state, targeting.goal, records, settings, planner, span.length, k, end)
        _advance_plant(state, records, line, calibrated, rng, timings, k, end)
        k = end
    wall = time.perf_counter() - wall_start
    timings["loop cpu"] = time.process_time() - cpu_start
    timings["policy and motion"] = wall - timings["plant"] - timings["plant update"] - timings[
        "filter"]

    # ---- what happened, over a settled window, against the robot parked
    after_start = time.perf_counter()
    frequencies = records.frequencies
    loop_length = float(span.loop_length(frequencies[-1])) if frequencies else float("nan")
    settling = _settling(records, t, segments, n_cal, loop_length, settings.settle_margin)
    loop_power = _damper_power(line.plant, robot, records.plant_states, records.position)
    scan_positions, scan_rms, best_position = _steady_state_scan(line)
    comparisons = _comparisons(line, robot, records, calibrated, settling.mask,
                               best_position, loop_power)
    timings["comparisons"] = time.perf_counter() - after_start
    return ClosedLoopResult(
        t=read_only(t),
        x=read_only(line.bare.node_positions.copy()),
        displacement=read_only(_field(line.plant, records.plant_states, line.residual)),
        baseline_displacement=read_only(
            _field(line.plant, calibrated.start_states, line.residual)),
        estimated_field=read_only(calibrated.field_map @ records.filter_states.T),
        robot_position=read_only(records.position),
        robot_velocity=read_only(records.velocity),
        target=read_only(records.target),
        sensors=line.sensors,
        calibration_time=float(t[n_cal - 1]),
        statuses=tuple(records.statuses),
        wall_time=wall,
        settled_window=settling.window,
        settled=settling.settled,
        comparisons=comparisons,
        scan_positions=read_only(scan_positions),
        scan_rms=read_only(scan_rms),
        best_position=best_position,
        loop_length=loop_length,
        frequency=read_only(np.array(frequencies)),
        retarget_times=tuple(records.retarget_times),
        settle_times=settling.settle_times,
        innovation_ratio=read_only(np.array(records.innovation_ratio)),
        damper_power=read_only(loop_power),
        predictions=tuple(records.predictions),
        timings=timings,
        follow_times=settling.follow_times,
    )
