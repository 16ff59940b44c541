"""The moving-robot plant: the bare line's modes, the loads' Ritz vectors, the robot at x.

The line is simulated in the modal coordinates of the *bare* line (its lowest modes or, on a
long span, a band of them around the load) plus, for each sine load, the Ritz vectors of what
those modes miss of its response (the modes below a band and above the top, one vector each:
with them the basis holds the load's exact response at its frequency, so the robot feels the
load's local field too). The robot is coupled through the shape functions at its position:
with ``n = Phi^T N(x_r)`` (the basis' displacements at the robot)

    (I + m_b n n^T) q'' + (Z + c n n^T) q' + (Omega^2 + k n n^T) q - n (k y + c y') = Phi^T f(t)
    m_a y'' + c (y' - n^T q') + k (y - n^T q) = 0

(``Z`` the line's own modal damping; ``y`` the absorber's displacement). What the basis leaves
out still flexes under the robot's own force: a flexibility h(x) at the load frequency between
the basis and the robot (mode acceleration), which the plant folds into the robot (the
parameters m_b, k, c above are the robot's re-tuned so that its dynamic stiffness on the basis
is exactly D_r / (1 - h D_r) there, :meth:`ModalPlant.robot_parameters`) and whose field the
robot's force drives is added to the output (:func:`nodal_field` given the positions). The
parked steady state is then exact at the load frequency (up to the undamped residual):
measured within 0.11 % of span RMS of the full FE solution at 50 positions on a 400 m clamped
span, 0.01 % on the lab span (tests/test_closed_loop_plant.py).

A move changes only the rank-one terms: rebuilding the matrices costs O(r^2) plus one sparse
solve for h(x), and their exact discretisation an ``expm`` of the (2 n_q)-square system matrix
(the first-order hold's integrals follow from it with a Cholesky solve). Each block of samples
is integrated exactly for loads linear between samples (first-order hold): with no damping and
a still robot the discrete map is the exact flow, so the mechanical energy is conserved to
round-off. The robot's position is a slowly varying parameter (its speed is < 2 % of the wave
speed, so the convective moving-mass terms are neglected, as in the domain notes).
"""

from __future__ import annotations

import numbers

import numpy as np
import scipy.linalg
import scipy.sparse

from .._spectral import load_phasor
from .._validation import check_real, read_only
from ..errors import InputError, ModelError
from ..fem import MDR, LineModel, ModalDamping, RayleighDamping, damper_impedance
from ..line import Span

# The plant keeps every mode below 8x the load frequency up to this many, else a band of modes.
SMALL_PLANT_MODES = 48

# ---------------------------------------------------------------------------------- the plant
class ModalPlant:
    """Bare-line modes, the loads' Ritz vectors, and the robot coupled at its position.

    ``modes``: how many of the lowest modes, or the indices (0-based) of a band of them.
    ``loads``: the loads the plant will be driven by; each sine adds the Ritz vectors of what
    the kept modes miss of its response (see the module doc), and the frequency of the last
    sine is where the robot's residual flexibility is evaluated (None: no sine, no correction).
    ``ritz``: False keeps the loads' frequency for the robot but adds no Ritz vectors (a wind
    that acts as a damping, not a load: vectors of a load it does not apply would only hold
    what the robot scatters into them, undamped).
    """

    def __init__(self, model: LineModel, robot: MDR | None, modes, dt: float, *,
                 loads=(), ritz: bool = True):
        index = np.arange(modes) if np.ndim(modes) == 0 else np.asarray(modes)
        basis = model.modes(int(index.max()) + 1)
        self.model, self.dt = model, dt
        # every mode up to the top of the plant's (possibly band of) modes, for the residual
        self.lowest = basis
        active = robot is not None and (robot.body_mass > 0 or robot.has_absorber)
        self.robot = robot if active else None
        sines = _sines(model, loads)
        self.frequency = sines[-1][0] if sines else None
        ritz, ritz_omega2, ritz_damping, n_above = _load_ritz_vectors(
            model, basis, index, sines if ritz else [])
        self.n_ritz = ritz_omega2.size
        self.n_ritz_above = n_above       # the last columns: Ritz vectors above the top mode
        self.n_band = index.size          # the first n_band columns are bare eigenmodes
        self.shapes = np.hstack([np.asarray(basis.shapes)[:, index], ritz])
        self.omega2 = np.concatenate([np.asarray(basis.omega)[index] ** 2, ritz_omega2])
        self.line_damping = scipy.linalg.block_diag(
            np.asarray(basis.damping)[np.ix_(index, index)], ritz_damping)
        self._node_map = model.displacement_map()
        self.nodal = self._node_map @ self.shapes  # (n_nodes, r)
        self.r = self.omega2.size
        off_diagonal = self.line_damping - np.diag(np.diag(self.line_damping))
        self._diagonal = not np.any(off_diagonal)
        self.absorber = self.robot is not None and self.robot.has_absorber
        self.n_q = self.r + (1 if self.absorber else 0)
        self._cache: dict[float, tuple] = {}
        self._robot_cache: dict[float, tuple] = {}
        self._attachment_cache: dict[float, tuple] = {}
        self._coupling_cache: dict[float, np.ndarray] = {}
        self._mass_band = model.mass_matrix @ self.shapes[:, : self.n_band]

    def coupling(self, x: float) -> np.ndarray:
        """The plant's basis displacements at x (shape functions restricted to the basis)."""
        # Kept per exact position: the policy's candidate grid and a parked robot ask for the
        # same positions at every decision and every block.
        key = float(x)
        if key not in self._coupling_cache:
            # the <= 4 non-zero shape-function entries: O(r) per call, not O(n_dofs r)
            index, weights = self.model.shape_entries(x)
            if len(self._coupling_cache) > 8192:
                self._coupling_cache.clear()
            self._coupling_cache[key] = read_only(weights @ self.shapes[index])
        return self._coupling_cache[key]

    def couplings(self, positions: np.ndarray) -> np.ndarray:
        """:meth:`coupling` at each of ``positions`` (K,): (K, r)."""
        index, weights = self.model.shape_rows(positions)
        return _combine(weights, self.shapes, index)

    def attachment(self, x: float) -> tuple[float, np.ndarray]:
        """(h, rho): what the basis leaves out of a unit force at x, at the plant's frequency.

        ``h`` is the displacement at x (the robot's residual flexibility, m/N) and ``rho`` the
        nodal field (n_nodes,), undamped mode acceleration: (K - omega^2 M)^-1 N(x) minus the
        basis' own terms. Zero without a frequency. :meth:`attachments` at one position, kept
        per position.
        """
        if self.frequency is None:
            return 0.0, np.zeros(self.model.n_nodes)
        key = round(float(x), 6)
        if key not in self._attachment_cache:
            index, weights = self.model.shape_entries(x)
            h, rho = self._attachments(index[None, :], weights[None, :])
            if len(self._attachment_cache) > 1024:
                self._attachment_cache.clear()
            self._attachment_cache[key] = (float(h[0]), rho[0])
        return self._attachment_cache[key]

    def attachments(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`attachment` at each of ``positions`` (K,): h (K,) and rho (K, n_nodes)."""
        positions = np.asarray(positions, dtype=float)
        if self.frequency is None or positions.size == 0:
            return np.zeros(positions.size), np.zeros((positions.size, self.model.n_nodes))
        last = self.__dict__.get("_last_attachments")
        if last is not None and np.array_equal(last[0], positions):
            return last[1]   # a record's corrections ask three times for the same positions
        result = self._attachments(*self.model.shape_rows(positions))
        self._last_attachments = (positions.copy(), result)
        return result

    def _attachments(self, index: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray,
                                                                              np.ndarray]:
        """h (K,) and rho (K, n_nodes) of unit forces given by their shape rows (K, m): free-DOF
        ``index`` (-1 with weight 0 for a constrained DOF) and ``weights``.

        Linear in the load: a unit force at x is the shape-function combination of <= 4 unit
        DOF loads, whose responses (one sparse solve each) are kept per DOF (a moving robot takes
        a new position every step but stays on a few elements).
        """
        omega2 = (2 * np.pi * self.frequency) ** 2
        # a constrained entry (weight 0) points at its row's last free DOF: no solve of its own
        index = np.where(index >= 0, index, index.max(axis=1, keepdims=True))
        dofs, local = np.unique(index, return_inverse=True)
        local = local.reshape(index.shape)
        at_nodes, at_dofs = (np.stack(parts) for parts in zip(
            *(self._dof_response(int(dof)) for dof in dofs), strict=True))
        n_ritz = _combine(weights, self.shapes[:, self.n_band :], index)
        # A Ritz frequency on the load's (it sits on one side of it by construction) would make
        # its term singular; 1e-9 relative keeps it finite at a negligible change.
        gaps = self.omega2[self.n_band :] - omega2
        gaps = np.where(np.abs(gaps) < 1e-9 * omega2, 1e-9 * omega2, gaps)
        ritz_part = n_ritz / gaps
        # h = sum_jl w_j w_l R_l[dof_j]: the responses at the DOFs themselves
        among = at_dofs[:, dofs][local[:, :, None], local[:, None, :]]     # (K, m, m)
        h = np.einsum("kj,kl,klj->k", weights, weights, among) - np.einsum(
            "kj,kj->k", n_ritz, ritz_part)
        rho = _combine(weights, at_nodes, local) - ritz_part @ self.nodal[:, self.n_band :].T
        return read_only(h), read_only(rho)

    def _dof_response(self, dof: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_beyond_band` of a unit load on free DOF ``dof`` at the nodes (n_nodes,) and
        at every free DOF (n_dofs,), kept per DOF."""
        cache = self.__dict__.setdefault("_dof_cache", {})
        if dof not in cache:
            unit = np.zeros(self.model.n_dofs)
            unit[dof] = 1.0
            response = self._beyond_band(unit, self.shapes[dof, : self.n_band])
            cache[dof] = (self._node_map @ response, response)
        return cache[dof]

    def _beyond_band(self, load: np.ndarray, projection: np.ndarray) -> np.ndarray:
        """sum over the modes outside the band of phi_k phi_k^T load / (omega_k^2 - omega^2) at
        the plant's frequency (``projection``: the band's share, shapes^T load)."""
        return _complement_response(self.model, load, self.shapes[:, : self.n_band],
                                    self._mass_band, self.frequency, projection)

    def residual_flexibility(self, x: float) -> float:
        """h(x): displacement at x per unit force at x of what the basis leaves out (m/N)."""
        return self.attachment(x)[0]

    def robot_force(self, states: np.ndarray, positions) -> np.ndarray:
        """The robot's force on the line per sample (N), for the residual field it drives.

        The absorber's spring and damper force from the states, and the body's inertia at the
        plant's frequency (omega^2 m_b a: exact in steady state, where the residual is); the
        robot's position per sample on the grid of :func:`_position_keys`.
        """
        if self.robot is None or self.frequency is None:
            return np.zeros(states.shape[0])
        nq, r = self.n_q, self.r
        xs = np.broadcast_to(np.asarray(positions, dtype=float), (states.shape[0],))
        keys, group = _position_keys(self, xs)
        body, spring, damper = self.robot_parameters_at(keys)[group].T
        rows = self.couplings(keys)
        a = _along(states[:, :r], rows, group)
        force = (2 * np.pi * self.frequency) ** 2 * body * a
        if self.absorber:
            force -= spring * (a - states[:, r])
            force -= damper * (_along(states[:, nq : nq + r], rows, group) - states[:, nq + r])
        return force

    def robot_field(self, x: float, amplitude: np.ndarray) -> np.ndarray:
        """Nodal steady-state field (n_nodes,) the robot's force drives in what the basis
        leaves out, for plant amplitudes ``amplitude`` (q, y) from :meth:`steady_state`."""
        if self.robot is None or self.frequency is None or x is None:
            return np.zeros(self.model.n_nodes)
        omega = 2 * np.pi * self.frequency
        n = self.coupling(x)
        body, spring, damper = self.robot_parameters(x)
        a = n @ amplitude[: self.r]
        force = omega**2 * body * a
        if self.absorber:
            force -= (spring + 1j * omega * damper) * (a - amplitude[self.r])
        return self.attachment(x)[1] * force

    def robot_parameters(self, x: float) -> tuple[float, float, float]:
        """(body mass, absorber stiffness, absorber damping) the plant gives the robot at x.

        The robot is attached to the line through the flexibility h(x) the basis leaves out
        (:meth:`residual_flexibility`): at the plant's frequency it acts on the basis with
        D_eff = D_r / (1 - h D_r). The plant's robot reproduces D_eff exactly there: its body
        keeps its mass and its absorber (same suspended mass) is re-tuned to carry the rest, the
        spring and damper of the complex stiffness s' with
        omega^2 m_a s' / (s' - omega^2 m_a) = D_eff - omega^2 m_b. Its damper is then never
        negative (Im D_eff <= 0 for a dissipative robot), and an undamped robot stays undamped.
        A robot without absorber gets the body mass m_b / (1 - h omega^2 m_b). Without a
        frequency, or when no such robot is passive (a negative spring or mass), the robot's
        own parameters.
        """
        robot = self.robot
        if self.frequency is None:
            return (robot.body_mass, robot.stiffness, robot.damping)
        key = round(float(x), 6)
        if key not in self._robot_cache:
            if len(self._robot_cache) > 4096:
                self._robot_cache.clear()
            self._robot_cache[key] = tuple(
                float(v) for v in self._retuned(np.array([self.residual_flexibility(x)]))[0])
        return self._robot_cache[key]

    def robot_parameters_at(self, positions: np.ndarray) -> np.ndarray:
        """:meth:`robot_parameters` at each of ``positions`` (K,): (K, 3)."""
        positions = np.asarray(positions, dtype=float)
        if self.frequency is None:
            robot = self.robot
            return np.tile([robot.body_mass, robot.stiffness, robot.damping], (positions.size, 1))
        return self._retuned(self.attachments(positions)[0])

    def _retuned(self, h: np.ndarray) -> np.ndarray:
        """(body mass, absorber stiffness, absorber damping) per residual flexibility ``h``
        (K,): the rule of :meth:`robot_parameters`, (K, 3)."""
        robot = self.robot
        omega = 2 * np.pi * self.frequency
        result = np.tile([robot.body_mass, robot.stiffness, robot.damping], (h.size, 1))
        dynamic = robot_dynamic_stiffness(robot, omega)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if not self.absorber:
                body_share = 1.0 - h * omega**2 * robot.body_mass
                alone = body_share > 0    # the body alone behind h
                result[alone, 0] = robot.body_mass / body_share[alone]
                result[alone, 1:] = 0.0
                return result
            # The body keeps its mass and the absorber carries the whole correction: continuous
            # in x (the body alone behind h, m_b / (1 - h omega^2 m_b), is singular at its local
            # resonance on h, which 0.5 m from a clamp of a long span sits at the load).
            effective = dynamic / (1.0 - h * dynamic)
            absorber = effective - omega**2 * robot.body_mass
            spring = absorber * omega**2 * robot.suspended_mass / (
                absorber - omega**2 * robot.suspended_mass)
        passive = np.isfinite(spring) & (spring.real > 0)
        result[passive, 1] = spring.real[passive]
        result[passive, 2] = (np.maximum(spring.imag[passive] / omega, 0.0)
                              if robot.damping > 0 else 0.0)
        return result

    def matrices(self, x: float | None, line_damping: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """M, C, K over (q, y): O(r^2) rank-one updates of the bare line's diagonal ones, with
        the robot's parameters of :meth:`robot_parameters` at x. ``line_damping`` (r, r), if
        given, replaces the line's own modal damping (an amplitude-dependent one)."""
        r, nq = self.r, self.n_q
        mass, damp, stiff = np.eye(nq), np.zeros((nq, nq)), np.zeros((nq, nq))
        stiff[:r, :r] = np.diag(self.omega2)
        damp[:r, :r] = self.line_damping if line_damping is None else line_damping
        if self.robot is None or x is None:
            return mass, damp, stiff
        n = self.coupling(x)
        body, spring, damper = self.robot_parameters(x)
        mass[:r, :r] += body * np.outer(n, n)
        if self.absorber:
            coupling = np.zeros(nq)
            coupling[:r], coupling[r] = n, -1.0
            stiff += spring * np.outer(coupling, coupling)
            damp += damper * np.outer(coupling, coupling)
            mass[r, r] = self.robot.suspended_mass
        return mass, damp, stiff

    def discretise(self, x: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact first-order-hold map z' = Phi z + G0 p_k + G1 p_{k+1} over one sample.

        Phi = expm(A dt) of the (2 n_q)-square system matrix; the hold's integrals follow from
        it without a larger exponential, P0 = A^-1 (Phi - I) and P1 = A^-1 (Phi - P0 / dt)
        (A is invertible: the stiffness is positive definite), G0 = P1 B, G1 = (P0 - P1) B.
        """
        key = None if x is None else round(float(x), 6)
        if key in self._cache:
            return self._cache[key]
        mass, damp, stiff = self.matrices(x)
        nq, r, dt = self.n_q, self.r, self.dt
        inverse_mass, a = _first_order(mass, damp, stiff)
        n_z = 2 * nq
        phi = scipy.linalg.expm(a * dt)
        stiffness_factor = scipy.linalg.cho_factor(stiff)

        def solve_a(rhs: np.ndarray) -> np.ndarray:
            # A [u; v] = [b1; b2]:  v = b1,  K u = -(M b2 + C b1)
            top, bottom = rhs[:nq], rhs[nq:]
            u = -scipy.linalg.cho_solve(stiffness_factor, mass @ bottom + damp @ top)
            return np.vstack([u, top])

        b = np.zeros((n_z, r))
        b[nq:] = inverse_mass[:, :r]
        phi_b = phi @ b
        p0 = solve_a(phi_b - b)
        p1 = solve_a(phi_b - p0 / dt)
        result = (phi, p1, p0 - p1)
        if len(self._cache) > 4096:
            self._cache.clear()
        self._cache[key] = result
        return result

    def state_matrix(self, x: float | None, line_damping: np.ndarray | None = None
                     ) -> np.ndarray:
        """A of z' = A z, z = (q, y, q', y'), with the robot at x (and ``line_damping`` as in
        :meth:`matrices`)."""
        return _first_order(*self.matrices(x, line_damping))[1]

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
        """Bare line's modal amplitudes under a harmonic modal load, (r,) or one per column of
        (r, m) (diagonal when it can)."""
        if self._diagonal:
            dynamic = self.omega2 - omega**2 + 1j * omega * np.diag(self.line_damping)
            return load / dynamic.reshape(dynamic.shape + (1,) * (np.ndim(load) - 1))
        dynamic = np.diag(self.omega2 - omega**2) + 1j * omega * self.line_damping
        return np.linalg.solve(dynamic, load)

    def receptance(self, x: float, omega: float) -> np.ndarray:
        """Bare line's displacement at every node per unit harmonic force at x (modal sum)."""
        return self.nodal @ self.modal_response(self.coupling(x), omega)


def _first_order(mass: np.ndarray, damp: np.ndarray, stiff: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(M^-1, A) of M q'' + C q' + K q = 0 written as z' = A z, z = (q, q')."""
    inverse_mass = np.linalg.inv(mass)  # block-diagonal, rank-one off I: well conditioned
    nq = mass.shape[0]
    a = np.zeros((2 * nq, 2 * nq))
    a[:nq, nq:] = np.eye(nq)
    a[nq:, :nq] = -inverse_mass @ stiff
    a[nq:, nq:] = -inverse_mass @ damp
    return inverse_mass, a


def _sines(model: LineModel, loads) -> list[tuple[float, np.ndarray]]:
    """(frequency Hz, load vector) of each load that declares a frequency > 0."""
    sines = []
    for load in loads:
        bound = load.bind(model) if hasattr(load, "bind") else load
        frequency = getattr(bound, "frequency", None)
        if getattr(bound, "position", None) is not None:   # named as load_histories names it
            check_real("force position", bound.position, low=0.0, low_inclusive=True,
                       high=model.span.length)
        if frequency is not None and float(frequency) > 0:
            sines.append((float(frequency), np.asarray(bound.load_vector(model), dtype=float)))
    return sines


def _complement_response(model: LineModel, load: np.ndarray, shapes: np.ndarray,
                         mass_shapes: np.ndarray, frequency: float,
                         projection: np.ndarray | None = None) -> np.ndarray:
    """(K - omega^2 M)^-1 of the part of ``load`` that the M-orthonormal eigenmodes ``shapes``
    do not take: sum over the other modes of phi_k phi_k^T load / (omega_k^2 - omega^2).

    Deflated: the load's share of ``shapes`` is removed before the sparse solve and what the
    solve puts back along them (its round-off, amplified by the near-singular
    K - omega^2 M when the frequency is on a kept mode) is removed after; the direct form,
    full solve minus the kept terms, loses every digit on a resonance.
    """
    if projection is None:
        projection = shapes.T @ load
    try:
        response = model.solve_flexibility(load - mass_shapes @ projection, frequency)
    except ModelError:   # exactly on an FE frequency: a 1e-9 shift, negligible off it
        response = model.solve_flexibility(load - mass_shapes @ projection,
                                           frequency * (1.0 + 1e-9))
    return response - shapes @ (mass_shapes.T @ response)


def _rayleigh_ritz(gram: np.ndarray, stiffness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients T (columns: gram-orthonormal, stiffness-diagonal) and eigenvalues of the
    projected problem; directions the gram cannot tell apart (dependent vectors) dropped."""
    if gram.size == 0:
        return np.zeros((gram.shape[0], 0)), np.zeros(0)
    s, u = np.linalg.eigh(gram)
    keep = s > 1e-10 * max(s.max(), 0.0)
    if not np.any(keep):
        return np.zeros((gram.shape[0], 0)), np.zeros(0)
    t = u[:, keep] / np.sqrt(s[keep])
    values, vectors = np.linalg.eigh(t.T @ stiffness @ t)
    return t @ vectors, values


def _load_ritz_vectors(model: LineModel, basis, index: np.ndarray, sines):
    """Ritz vectors, their omega^2 and damping for what the kept modes miss of each sine.

    For a sine at omega the exact response is sum_k phi_k g_k / (omega_k^2 - omega^2) over
    every mode; the kept band misses the modes below it (known: ``basis``) and above the top
    (the mode-acceleration residual). Each missed part, as one vector, is a Ritz vector whose
    single mode answers the load at omega *exactly* (its Rayleigh quotient makes
    psi^T (K - omega^2 M) psi = psi^T f). Below and above are kept apart: apart, each Ritz
    frequency stays on its side of the load (one vector of both would sit near the load and
    ring there). Damping: Rayleigh's is exact (a + b omega_psi^2); ModalDamping's for the
    below part from its modes, for the above part the top kept mode's ratio at omega_psi.
    """
    n_dofs = model.n_dofs
    empty = (np.zeros((n_dofs, 0)), np.zeros(0), np.zeros((0, 0)), 0)
    if not sines:
        return empty
    shapes, omega = np.asarray(basis.shapes), np.asarray(basis.omega)
    first = int(index.min())
    below, above = [], []
    mass_shapes = model.mass_matrix @ shapes
    for frequency, vector in sines:
        projection = shapes.T @ vector
        if first > 0:
            gaps = omega[:first] ** 2 - (2 * np.pi * frequency) ** 2   # below the band: < 0
            below.append(projection[:first] / gaps)
        above.append(_complement_response(model, vector, shapes, mass_shapes, frequency,
                                          projection))
    vectors, omega2, damping, n_above = [], [], [], 0
    if below:
        a = np.stack(below, axis=1)                       # modal coordinates of the low modes
        t, values = _rayleigh_ritz(a.T @ a, a.T @ (omega[:first, None] ** 2 * a))
        coefficients = a @ t
        vectors.append(shapes[:, :first] @ coefficients)
        omega2.append(values)
        damping.append(coefficients.T @ np.asarray(basis.damping)[:first, :first] @ coefficients)
    if above:
        psi = np.stack(above, axis=1)
        t, values = _rayleigh_ritz(psi.T @ (model.mass_matrix @ psi),
                                   psi.T @ (model.stiffness_matrix @ psi))
        vectors.append(psi @ t)
        omega2.append(values)
        n_above = values.size
        damping.append(np.diag(_line_damping_at(model, basis, np.sqrt(values))))
    if not vectors:
        return empty
    return (np.hstack(vectors), np.concatenate(omega2), scipy.linalg.block_diag(*damping),
            n_above)


def _line_damping_at(model: LineModel, basis, omega: np.ndarray) -> np.ndarray:
    """The line's own modal damping coefficient at the given omega (Ritz vectors above the
    kept modes): Rayleigh a + b omega^2, ModalDamping 2 zeta omega with the top mode's zeta."""
    damping = model.damping
    if isinstance(damping, RayleighDamping):
        return damping.mass_coefficient + damping.stiffness_coefficient * omega**2
    if isinstance(damping, ModalDamping):
        return 2 * float(damping.ratios(basis.n_modes)[-1]) * omega
    return np.zeros_like(omega)


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
    (:func:`~powerline_control.fem.damper_impedance`, the same physics in one place);
    zero at omega = 0 (every term carries omega^2).
    """
    if omega == 0.0:
        return 0j
    return complex(-1j * omega * damper_impedance(robot, omega / (2 * np.pi)))


def run_parked(plant, x, modal_force, n_t, z0=None):
    """States (n_t, 2 n_q) of the plant with the robot parked at x (None: no robot)."""
    phi, g0, g1 = plant.discretise(x)
    states = np.empty((n_t, phi.shape[0]))
    states[0] = 0.0 if z0 is None else z0
    np.matmul(modal_force[:-1], g0.T, out=states[1:])
    states[1:] += modal_force[1:] @ g1.T
    _propagate(phi, states)
    return states


def _propagate(phi: np.ndarray, states: np.ndarray) -> None:
    """z[k+1] = phi z[k] + drive[k] in place: ``states[0]`` the start, ``states[k + 1]`` the
    drive of step k on entry and the state on return.

    A small system (<= 64 states, a short span's plant) runs ``b`` steps per Python iteration:
    the drives' share of a block is one product with the block-Toeplitz matrix of phi^0..phi^b-1
    for every block at once, and the carried state adds [phi; ...; phi^b] z. The same sums
    regrouped: equal to the step-by-step recursion to round-off (measured 3e-15 relative, 12k
    steps), twice as fast for 32 states; a larger system steps one sample at a time (its
    products cost more than the loop).
    """
    n, n_steps = phi.shape[0], states.shape[0] - 1
    block = 8 if n <= 40 else 4 if n <= 64 else 1
    blocks = n_steps // block if block > 1 else 0
    if blocks:
        powers = [np.eye(n)]
        for _ in range(block):
            powers.append(phi @ powers[-1])
        carry = np.vstack(powers[1:])                       # (b n, n): phi^1 .. phi^b
        toeplitz = np.zeros((block * n, block * n))
        for i in range(block):
            for j in range(i + 1):
                toeplitz[i * n : (i + 1) * n, j * n : (j + 1) * n] = powers[i - j]
        body = states[1 : blocks * block + 1].reshape(blocks, block * n)
        body[:] = body @ toeplitz.T
        z = states[0]
        for k in range(blocks):
            body[k] += carry @ z
            z = body[k, -n:]
    for k in range(blocks * block, n_steps):
        states[k + 1] += phi @ states[k]


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
    if f > 0.0:
        # exact minus what the plant's basis gives (the band's modes and the Ritz vectors):
        # zero for a load whose Ritz vectors the plant holds, well conditioned on a resonance
        band = plant.shapes[:, : plant.n_band]
        dofs = _complement_response(model, vector, band, plant._mass_band, f)
        ritz = plant.shapes[:, plant.n_band :]
        gaps = plant.omega2[plant.n_band :] - (2 * np.pi * f) ** 2
        if ritz.shape[1] and np.min(np.abs(gaps)) > 1e-9 * (2 * np.pi * f) ** 2:
            dofs = dofs - ritz @ ((ritz.T @ vector) / gaps)
    else:
        # the static residual of the modes above the top, less what the plant's Ritz vectors
        # above the top (M- and K-orthogonal to every mode below it) already carry
        first_above = plant.r - plant.n_ritz_above
        dofs = model.residual_response(
            vector, np.hstack([plant.lowest.shapes, plant.shapes[:, first_above:]]),
            np.concatenate([plant.lowest.omega, np.sqrt(plant.omega2[first_above:])]))
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
    """A: values(t) = Re(A exp(i 2 pi f t)) (:func:`~powerline_control._spectral.load_phasor`)."""
    return load_phasor(load, frequency)


def nodal_field(plant: ModalPlant, states: np.ndarray, residual: np.ndarray,
                positions=None) -> np.ndarray:
    """Nodal displacements (n_nodes, n_t) of plant states (n_t, 2 n_q) plus the loads' residual
    and, given the robot's ``positions`` (one, or one per sample), the field its force drives in
    what the basis leaves out (:func:`robot_correction`)."""
    field = plant.nodal @ states[:, : plant.r].T + residual
    correction = robot_correction(plant, states, positions)
    if correction is not None:
        field += correction
    return field


def robot_correction(plant: ModalPlant, states: np.ndarray, positions) -> np.ndarray | None:
    """The field (n_nodes, n_t) the robot's force drives in what the plant's basis leaves out
    (:meth:`ModalPlant.attachment`), the robot at ``positions`` (one, or one per sample); None
    when there is none (no robot, no plant frequency, no position)."""
    if positions is None or plant.robot is None or plant.frequency is None:
        return None
    xs = np.broadcast_to(np.asarray(positions, dtype=float), (states.shape[0],))
    if np.all(np.isnan(xs)):
        return None
    force = plant.robot_force(states, xs)
    keys, group = _position_keys(plant, xs)
    rho = plant.attachments(keys)[1]                         # (groups, n_nodes)
    if keys.size == 1:
        return np.outer(rho[0], force)
    # rho^T @ (each sample's force in its group's row): one sparse product
    spread = scipy.sparse.csc_array((force, (group, np.arange(xs.size))),
                                    shape=(keys.size, xs.size))
    return (spread.T @ rho).T


# The robot's residual corrections of a record (its force's field, its re-tuned damper) are
# evaluated on a grid of this fraction of the load's loop: a moving robot takes a new position
# every sample, each a sparse solve; on the grid a move costs 2000 per loop, and the
# corrections (a few % of the field, smooth in x) change by < 0.1 % of themselves per step.
CORRECTION_GRID_PER_LOOP = 2000


def _combine(weights: np.ndarray, rows: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Per k, ``sum_j weights[k, j] rows[index[k, j]]``: (K, row length); a weight 0 entry's
    index must only be valid."""
    out = weights[:, :1] * rows[index[:, 0]]
    for j in range(1, weights.shape[1]):
        out += weights[:, j : j + 1] * rows[index[:, j]]
    return out


def _position_keys(plant: ModalPlant, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct positions of a record on the grid of ``CORRECTION_GRID_PER_LOOP``
    (positions to 1 um without a plant frequency), and each sample's index among them."""
    keys = np.round(positions, 6)
    if plant.frequency is not None:
        step = float(plant.model.span.loop_length(plant.frequency)) / CORRECTION_GRID_PER_LOOP
        keys = np.clip(np.round(np.round(positions / step) * step, 6), 0.0,
                       plant.model.span.length)
    distinct, group = np.unique(keys, return_inverse=True)
    return distinct, group.ravel()


def _along(states: np.ndarray, rows: np.ndarray, group: np.ndarray) -> np.ndarray:
    """Per sample, ``states[i] @ rows[group[i]]`` (one product when there is one row)."""
    if rows.shape[0] == 1:
        return states @ rows[0]
    return np.einsum("ij,ij->i", states, rows[group])


def relative_velocity(plant: ModalPlant, states: np.ndarray, positions) -> np.ndarray:
    """Velocity of the line under the robot relative to its absorber mass, per sample (zero
    without an absorber); ``positions`` one parked position or one per sample."""
    nq, r = plant.n_q, plant.r
    if not plant.absorber:
        return np.zeros(states.shape[0])
    if np.ndim(positions) == 0:
        line_velocity = states[:, nq : nq + r] @ plant.coupling(float(positions))
    else:
        # one coupling per distinct position: the robot is parked most of a run
        distinct, which = np.unique(np.asarray(positions, dtype=float), return_inverse=True)
        line_velocity = _along(states[:, nq : nq + r], plant.couplings(distinct),
                               which.ravel())
    return line_velocity - states[:, nq + r]


def damper_power(plant: ModalPlant, robot: MDR, states: np.ndarray, positions) -> np.ndarray:
    """Power dissipated in the robot's damper per sample, W.

    The plant's damper (:meth:`ModalPlant.robot_parameters`: the robot's own, re-tuned for the
    flexibility the basis leaves out) on the plant's relative velocity: in steady state at the
    plant's frequency, the power the real damper dissipates.
    """
    if not robot.has_absorber or plant.robot is None:
        return np.zeros(states.shape[0])
    xs = np.broadcast_to(np.asarray(positions, dtype=float), (states.shape[0],))
    keys, group = _position_keys(plant, xs)
    coefficient = plant.robot_parameters_at(keys)[group, 2]
    return coefficient * relative_velocity(plant, states, positions) ** 2


