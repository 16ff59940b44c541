"""The moving-robot plant: the bare line's modes with the robot coupled at its position.

The line is simulated in the modal coordinates of the *bare* line (its lowest ``r`` modes or a
band of them, plus the residual response of the dropped modes to the loads: dynamic for a sine,
so modes below a band count with 1 / (omega_k^2 - omega^2)), and the robot is coupled to them
through the shape functions at its current position: with ``n = Phi^T N(x_r)`` (the bare modes'
displacements at the robot, ``model.shape_vector(x)`` restricted to the modal basis)

    (I + m_b n n^T) q'' + (Z + c n n^T) q' + (Omega^2 + k n n^T) q - n (k y + c y') = Phi^T f(t)
    m_a y'' + c (y' - n^T q') + k (y - n^T q) = 0

(``Z`` the line's own modal damping; ``y`` the absorber's displacement). A move changes only the
rank-one terms: rebuilding the matrices costs O(r^2) and their exact discretisation an
``expm`` of a (4r + 2)-square matrix. Each block of samples is integrated exactly for loads
linear between samples (first-order hold): with no damping and a still robot the discrete map is
the exact flow, so the mechanical energy is conserved to round-off. The robot's position is a
slowly varying parameter (its speed is < 2 % of the wave speed, so the convective moving-mass
terms are neglected, as in the domain notes).
"""

from __future__ import annotations

import numbers

import numpy as np
import scipy.linalg

from .._validation import check_real
from ..errors import InputError
from ..fem import MDR, LineModel
from ..line import Span
from ..severity import damper_impedance

# The plant keeps every mode below 8x the load frequency up to this many, else a band of modes.
SMALL_PLANT_MODES = 48

# ---------------------------------------------------------------------------------- the plant
class ModalPlant:
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


def default_modes(span: Span, bare: LineModel, frequencies: list, dt: float):
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


def robot_dynamic_stiffness(robot: MDR, omega: float) -> complex:
    """D_r: the robot's force on the line per unit line displacement at omega (body + absorber).

    D_r = -i omega Z with Z the robot's mechanical impedance
    (:func:`~powerline_control.severity.damper_impedance`, the same physics in one place);
    zero at omega = 0 (every term carries omega^2).
    """
    if omega == 0.0:
        return 0j
    return complex(-1j * omega * damper_impedance(robot, omega / (2 * np.pi)))


def run_parked(plant, x, modal_force, n_t, z0=None):
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
def is_schedule(force: object) -> bool:
    return (
        isinstance(force, list | tuple)
        and len(force) > 0
        and all(
            isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], numbers.Real)
            for item in force
        )
    )


def load_segments(force: object, duration: float) -> list[tuple[float, list]]:
    """[(start_time, [loads])]: a single load, a list of loads, or a (time, load) schedule."""
    if force is None:
        raise InputError("The 'force' parameter must be a load or a schedule. Got None.")
    raw = list(force) if is_schedule(force) else [(0.0, force)]
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


def residual_of_load(model: LineModel, plant: ModalPlant, vector: np.ndarray,
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


def load_histories(model, plant, segments, t):
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
            static = residual_of_load(model, plant, vector, getattr(load, "frequency", None))
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


def phasor_of(load, frequency: float) -> complex:
    """A: values(t) = Re(A exp(i 2 pi f t)), fitted on one period (exact for a sine)."""
    tau = np.linspace(0.0, 1.0 / frequency, 64, endpoint=False)
    values = np.asarray(load.values(tau), dtype=float)
    w = 2 * np.pi * frequency
    return complex(2 * np.mean(values * np.cos(w * tau)), -2 * np.mean(values * np.sin(w * tau)))

def nodal_field(plant: ModalPlant, states: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Nodal displacements (n_nodes, n_t) of plant states (n_t, 2 n_q) plus the loads' residual."""
    return plant.nodal @ states[:, : plant.r].T + residual


def relative_velocity(plant: ModalPlant, states: np.ndarray, positions) -> np.ndarray:
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


def damper_power(plant: ModalPlant, robot: MDR, states: np.ndarray, positions) -> np.ndarray:
    """Power dissipated in the robot's damper per sample, W."""
    damping_coefficient = robot.damping if robot.has_absorber else 0.0
    return damping_coefficient * relative_velocity(plant, states, positions) ** 2


