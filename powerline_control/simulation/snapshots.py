"""Displacement snapshots of a span: exact modal propagation, optional seeded sensor noise.

The model is taken to (damped, possibly non-proportionally) modal coordinates, where the state
equation splits into independent complex first-order modes ``z' = lambda z + b u(t)``. Each mode is
propagated exactly:

* harmonic loads: closed form (homogeneous plus particular solution), no time stepping at all;
* other loads: exact integration of ``u`` interpolated linearly between samples (first-order
  hold), one complex recursion per mode run by ``scipy.signal.lfilter``.

No small-step explicit integration is involved, so the only approximations are the modal
truncation (none for models up to :data:`~powerline_control.fem.DENSE_EIGEN_LIMIT` DOFs; above,
the dropped modes' quasi-static response is added back by sparse factorisation, so only their
dynamic part is lost) and, for non-harmonic loads, the linear interpolation of the load between
samples.
"""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.signal

from .._results import Result
from .._spectral import load_phasor
from .._threads import on_one_blas_thread
from .._validation import (
    check_array,
    check_budget,
    check_budget_value,
    check_int,
    check_real,
    check_rng,
    checked_keywords,
    read_only,
)
from ..errors import InputError, ModelError, TruncationWarning
from ..excitation import BoundAeolianForce, HarmonicForce, RandomForce
from ..fem import LineModel

__all__ = ["Snapshots", "simulate"]


@dataclass(frozen=True, eq=False)
class Snapshots(Result):
    """Displacement data of a simulated span; columns are time, as in the paper.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Sample times, s.
    dt : float
        Sample interval, s.
    x : ndarray, shape (n_nodes,)
        Node positions, m (or the ``outputs`` positions asked of simulate).
    displacement : ndarray, shape (n_nodes, n_t)
        Measured nodal displacements, m (noise included).
    true_displacement : ndarray, shape (n_nodes, n_t)
        Noise-free nodal displacements, m.
    final_state : tuple of ndarray
        (displacement, velocity) over the model's free DOFs at the last sample, to continue from.
    inputs : ndarray, shape (n_forces, n_t)
        Time factor of each applied load (N for point forces): the known input for DMDc.
    force_positions : tuple of float or None
        Position of each point force (None for distributed loads).
    noise_std : float
        Standard deviation of the added sensor noise, m.
    mode_frequencies : ndarray
        Undamped frequencies (Hz) of the modes kept in the simulation.
    supports : (str, str) or None
        The simulated model's supports, left and right (``LineModel.bc``): what a design trained
        on these snapshots records (``EstimatorDesign.supports``); None when not known.

    Examples
    --------
    >>> from powerline_control import Span, LineModel, HarmonicForce, simulate
    >>> snap = simulate(LineModel(Span.paper_lab(), 20), HarmonicForce(1.0, 12.0, 0.5), 0.1, 1e-3)
    >>> snap.t.shape, snap.displacement.shape, snap.force.shape
    ((101,), (21, 101), (101,))
    """

    t: np.ndarray
    dt: float
    x: np.ndarray
    displacement: np.ndarray
    true_displacement: np.ndarray
    final_state: tuple = field(repr=False)
    inputs: np.ndarray
    force_positions: tuple
    noise_std: float
    mode_frequencies: np.ndarray = field(repr=False)
    supports: tuple[str, str] | None = field(default=None, repr=False)

    @property
    def force(self) -> np.ndarray:
        """The single load's time history, shape (n_t,); an error if there are several."""
        if self.inputs.shape[0] != 1:
            raise InputError(
                f"These snapshots have {self.inputs.shape[0]} loads; use "
                "'inputs' (n_forces, n_t) instead of 'force'."
            )
        return self.inputs[0]

    @property
    def n_modes(self) -> int:
        """Number of modes kept in the simulation."""
        return self.mode_frequencies.size


def _as_force_list(force: object) -> list:
    if force is None:
        return []
    forces = list(force) if isinstance(force, list | tuple) else [force]
    for item in forces:
        is_load = all(hasattr(item, name) for name in ("values", "load_vector", "position"))
        if not (is_load or hasattr(item, "bind")):
            raise InputError(
                "The 'force' parameter must be a load (HarmonicForce, AeolianForce, RandomForce, "
                "or an object with values(t), load_vector(model) and position), a list of them "
                f"or None. Got {type(item).__name__}."
            )
    return forces


def _sine_frequency(force: object) -> float | None:
    """Frequency of a load that is exactly amplitude * sin(2 pi f t + phase), else None.

    Only those are integrated in closed form; any other load (a user's own included) goes
    through its ``values(t)``, whatever attributes it carries.
    """
    return force.frequency if isinstance(force, HarmonicForce | BoundAeolianForce) else None


def _load_top_frequency(force: object) -> float | None:
    """Highest frequency (Hz) a load drives: a sine's frequency, a random load's bandwidth."""
    frequency = _sine_frequency(force)
    if frequency is not None:
        return frequency
    if isinstance(force, RandomForce):
        return force.bandwidth
    return None


def _initial_dofs(model: LineModel, name: str, value: object) -> np.ndarray:
    """Free-DOF vector (displacement and slope) from nodal values or a callable of x.

    Slopes come from finite differences; an absorber starts level with the line under it, so its
    spring starts relaxed.
    """
    x = model.node_positions
    if callable(value):
        w = check_array(f"{name}(x)", value(x), shape=(model.n_nodes,))
        step = 1e-6 * model.span.length
        left, right = np.clip(x - step, 0, x[-1]), np.clip(x + step, 0, x[-1])
        slope = check_array(f"{name}(x)", value(right), shape=(model.n_nodes,)) - check_array(
            f"{name}(x)", value(left), shape=(model.n_nodes,))
        slope = slope / (right - left)
    else:
        w = check_array(name, value, shape=(model.n_nodes,))
        slope = np.gradient(w, x, edge_order=2)
    full = np.zeros(model._n_total)
    full[0 : 2 * model.n_nodes : 2], full[1 : 2 * model.n_nodes : 2] = w, slope
    dofs = full[model._free]
    if model.mdr is not None and model.mdr.has_absorber:
        dofs[-1] = model.shape_vector(model.mdr.position)[:-1] @ dofs[:-1]
    return dofs


@checked_keywords
def simulate(
    model: LineModel,
    force: object = None,
    duration: float = 10.0,
    dt: float = 1e-3,
    *,
    noise_std: float = 0.0,
    noise_fraction: float | None = None,
    seed: int | np.random.Generator | None = None,
    initial_displacement: np.ndarray | Callable | None = None,
    initial_velocity: np.ndarray | Callable | None = None,
    initial_modes: dict[int, float] | None = None,
    initial_state: tuple[np.ndarray, np.ndarray] | None = None,
    start_time: float = 0.0,
    n_modes: int | None = None,
    quasi_static: bool = True,
    memory_budget: float | None = None,
    outputs: Sequence[float] | np.ndarray | None = None,
) -> Snapshots:
    """Simulate nodal displacement snapshots, (n_nodes, n_samples).

    Parameters
    ----------
    model : LineModel
        The span (with its damping and robot, if any).
    force : load, list of loads or None
        :class:`~powerline_control.excitation.HarmonicForce`, ``AeolianForce``, ``RandomForce``.
    duration : float
        Simulated time, s (> 0); samples at 0, dt, ..., <= duration.
    dt : float
        Sample interval, s (> 0).
    noise_std : float
        Standard deviation of white Gaussian sensor noise added to every node, m.
    noise_fraction : float or None
        Alternative to ``noise_std``: noise as a fraction of the RMS noise-free displacement
        (e.g. 0.01 for "1 % noise").
    seed : int, Generator or None
        Randomness of the noise.
    initial_displacement, initial_velocity : array (n_nodes,), callable of x, or None
        Initial field (slopes from finite differences).
    initial_modes : dict or None
        ``{mode_index: amplitude}``: initial displacement as a sum of undamped mode shapes
        (0-based index, shapes scaled to unit peak nodal displacement); excites exactly those modes.
    initial_state : (displacement, velocity) over the free DOFs, or None
        Full FE state, e.g. ``final_state`` of an earlier run, to continue a simulation.
    start_time : float
        Time of the first sample, s; loads are evaluated at ``start_time + k dt``.
    n_modes : int or None
        Modes kept; None keeps all of them on models up to
        :data:`~powerline_control.fem.DENSE_EIGEN_LIMIT` DOFs (exact), otherwise those below the
        smaller of the Nyquist frequency and 4x the highest load frequency (a sine's frequency,
        a random load's bandwidth).
    quasi_static : bool
        True (default): add the quasi-static response of the modes not kept (mode acceleration /
        residual flexibility): for a sine at omega, ``[(K - omega^2 M)^-1 - sum_kept phi phi^T /
        (omega_k^2 - omega^2)] F`` times the load's time factor (exact for the undamped dropped
        modes); for other loads the static ``[K^-1 - sum_kept phi phi^T / omega_k^2] F``. Both by
        sparse LU factorisation, so truncation costs accuracy only for dropped modes that respond
        dynamically (those near the load, which the default cut-off keeps) and for their own
        transients (ringing from initial conditions or a load's onset, which decays).
    memory_budget : float or None
        Bytes the output and work arrays may take (default 4 GiB, see
        :func:`~powerline_control._validation.check_budget`).
    outputs : sequence of float or None
        Positions (m) where displacement is recorded; None (default) records every node. A
        few positions on a large mesh keep the output (n_outputs, n_t) small; ``Snapshots.x``
        then holds these positions.

    Returns
    -------
    Snapshots

    Raises
    ------
    InputError
        For invalid arguments.
    ModelError
        If the modal decomposition fails.

    Warns
    -----
    TruncationWarning
        When a load's frequency is at or above the Nyquist frequency, above the highest mode
        kept, or when the mesh does not resolve the load's wavelength
        (:meth:`~powerline_control.fem.LineModel.resolves`).

    Examples
    --------
    >>> from powerline_control import Span, LineModel, HarmonicForce
    >>> model = LineModel(Span.paper_lab(), n_elements=20)
    >>> snap = simulate(model, HarmonicForce(1.0, 12.0, 0.5), duration=1.0, dt=1e-3)
    >>> snap.displacement.shape
    (21, 1001)
    """
    memory_budget = check_budget_value("memory_budget", memory_budget)  # a guard: first
    if not isinstance(model, LineModel):
        raise InputError(f"The 'model' parameter must be a LineModel. Got {type(model).__name__}.")
    duration = check_real("duration", duration, low=0.0)
    dt = check_real("dt", dt, low=0.0)
    start_time = check_real("start_time", start_time)
    if dt > duration:
        raise InputError(
            f"The 'dt' parameter ({dt:g} s) must not exceed 'duration' ({duration:g} s)."
        )
    noise_std = check_real("noise_std", noise_std, low=0.0, low_inclusive=True)
    if noise_fraction is not None:
        noise_fraction = check_real("noise_fraction", noise_fraction, low=0.0, low_inclusive=True)
        if noise_std:
            raise InputError("Give either 'noise_std' or 'noise_fraction', not both.")
    if not isinstance(quasi_static, bool | np.bool_):
        raise InputError(
            f"The 'quasi_static' parameter must be True or False. Got {quasi_static!r}."
        )
    rng = check_rng(seed)
    forces = [f.bind(model) if hasattr(f, "bind") else f for f in _as_force_list(force)]
    for f in forces:
        if f.position is not None:
            check_real(
                "force position", f.position, low=0.0, low_inclusive=True, high=model.span.length
            )
    n_t = int(np.floor(duration / dt + 1e-9)) + 1
    nyquist = 0.5 / dt
    load_frequencies = [f for f in map(_sine_frequency, forces) if f is not None]
    top_frequencies = [f for f in map(_load_top_frequency, forces) if f is not None]
    if n_modes is None:
        # Large models: the modes the samples can show, but no more than the load can drive
        # dynamically (above ~4x its frequency a mode only responds quasi-statically, ~1/omega^2,
        # and the quasi-static correction below adds that part back).
        cutoff = min(nyquist, 4 * max(top_frequencies)) if top_frequencies else nyquist
        n_modes = model.default_mode_count(cutoff)
    else:
        n_modes = check_int("n_modes", n_modes, low=1, high=model.n_dofs)
    # Before anything of size n_t exists: the output (noise-free and measured), the rotating
    # phasors and the homogeneous part (kept modes x n_t, complex).
    if outputs is None:
        out_map, out_x = model.displacement_map(), model.node_positions
    else:
        out_x = check_array("outputs", outputs, ndim=1)
        for x in out_x:
            check_real("outputs", float(x), low=0.0, low_inclusive=True, high=model.span.length)
        out_map = model.displacement_map(out_x)
    n_out = out_x.size
    n_kept = 2 * min(n_modes, model.n_dofs)
    nbytes = 8.0 * n_t * (4 * n_out + 2 * n_kept + 8 * max(1, len(forces)))
    check_budget(
        f"simulate's {n_out} x {n_t} output", nbytes=nbytes, parameter="duration",
        value=duration,
        fix=f"shorten duration ({duration:g} s), increase dt ({dt:g} s) or record fewer "
        f"positions (outputs=[...], {n_out} now)",
        memory_budget=memory_budget,
    )
    t = dt * np.arange(n_t)
    basis = model.modes(n_modes)
    _warn_unresolved(load_frequencies, nyquist, basis.frequencies[-1])
    # A sine has a wavelength the mesh must resolve; a random load's bandwidth only bounds its
    # spectrum (what the mesh does not resolve there, the kept modes' frequencies say).
    for frequency in load_frequencies:
        if frequency < nyquist:
            model.check_resolution(frequency, what="load")

    complex_modes = _complex_modes_of(model, basis)
    q0 = _initial_modal_state(
        model, basis, initial_displacement, initial_velocity, initial_modes, initial_state
    )
    # Work in output space as early as possible: a harmonic load's particular solution is one
    # rotating phasor per node, so it never needs the (modes x samples) matrix. Every homogeneous
    # part (initial state, and what cancels each particular solution at t = 0) is collected in
    # one coefficient and costs one exponential matrix.
    gains = complex_modes.output_gains(out_map @ basis.shapes)  # (n_outputs, kept)
    homogeneous = complex_modes.project(q0)
    clean = np.zeros((n_out, t.size))
    final = np.zeros_like(homogeneous)  # complex modal state at the last sample
    inputs = []
    nodal = out_map
    truncated = quasi_static and basis.n_modes < model.n_dofs
    residual_state = [np.zeros(model.n_dofs), np.zeros(model.n_dofs)]
    for i, f in enumerate(forces):
        load = check_array(f"force[{i}].load_vector(model)", f.load_vector(model),
                           shape=(model.n_dofs,))
        forcing = complex_modes.input_gain(basis.shapes.T @ load)
        values = check_array(f"force[{i}].values(t)", f.values(start_time + t), shape=(t.size,))
        frequency = _sine_frequency(f)
        if frequency is not None:
            # The sine's phasor referred to the first sample: values(start_time + t) =
            # Re(phasor exp(i omega t)).
            omega = 2 * np.pi * frequency
            phasor = load_phasor(f, frequency) * np.exp(1j * omega * start_time)
        if truncated:
            shape = _residual_shape(model, basis, load, frequency)
            clean += np.outer(nodal @ shape, values)
            residual_state[0] += shape * values[-1]
            if frequency is not None:
                rate = float((1j * omega * phasor * np.exp(1j * omega * t[-1])).real)
            else:
                rate = (values[-1] - values[-2]) / dt if values.size > 1 else 0.0
            residual_state[1] += shape * rate
        if frequency is not None and _exact_harmonic_possible(complex_modes.eigenvalues, frequency):
            plus, minus = _harmonic_phasors(complex_modes.eigenvalues, forcing, phasor, omega)
            rotation = np.exp(1j * omega * t)
            clean += (
                np.outer(gains @ plus, rotation) + np.outer(gains @ minus, rotation.conj())
            ).real
            homogeneous = homogeneous - (plus + minus)
            final += plus * rotation[-1] + minus * rotation[-1].conj()
        else:
            response = _foh_response(complex_modes.eigenvalues, forcing, values, dt)
            clean += (gains @ response).real
            final += response[:, -1]
        inputs.append(values)
    clean += (gains @ (np.exp(np.outer(complex_modes.eigenvalues, t)) * homogeneous[:, None])).real
    final += np.exp(complex_modes.eigenvalues * t[-1]) * homogeneous
    if noise_fraction is not None:
        noise_std = noise_fraction * float(np.sqrt(np.mean(clean**2)))
    noisy = clean + noise_std * rng.standard_normal(clean.shape) if noise_std > 0 else clean.copy()
    # Read-only results: a caller editing one snapshot array must not change another's data.
    return Snapshots(
        t=read_only(start_time + t),
        dt=dt,
        x=read_only(np.array(out_x, dtype=float)),
        displacement=read_only(noisy),
        true_displacement=read_only(clean),
        final_state=tuple(read_only(part + extra) for part, extra in
                          zip(complex_modes.to_dofs(basis, final), residual_state, strict=True)),
        inputs=read_only(np.array(inputs) if inputs else np.zeros((0, t.size))),
        force_positions=tuple(f.position for f in forces),
        noise_std=noise_std,
        mode_frequencies=read_only(np.array(basis.frequencies)),
        supports=(str(model.bc[0]), str(model.bc[1])),
    )


def _residual_shape(model: LineModel, basis, load: np.ndarray, frequency: float | None
                    ) -> np.ndarray:
    """Quasi-static response (free DOFs, per unit time factor) of the modes not kept.

    :meth:`~powerline_control.fem.LineModel.residual_response`: for a sine the dynamic
    flexibility, exact for undamped dropped modes; otherwise (or exactly on a kept resonance,
    where the split is singular) the static one (dropped modes far above the load's band).
    """
    f = 0.0 if frequency is None else float(frequency)
    gaps = basis.omega**2 - (2 * np.pi * f) ** 2
    if f > 0.0 and np.min(np.abs(gaps)) < 1e-9 * basis.omega.max() ** 2:
        f = 0.0
    return model.residual_response(load, basis.shapes, basis.omega, f)


def _warn_unresolved(load_frequencies: Sequence[float], nyquist: float, top_mode: float) -> None:
    for frequency in load_frequencies:
        if frequency >= nyquist:
            warnings.warn(
                f"A load at {frequency:g} Hz is at or above the Nyquist frequency "
                f"{nyquist:g} Hz of dt: the samples alias it; reduce dt.",
                TruncationWarning,
                stacklevel=3,
            )
        if frequency > top_mode:
            warnings.warn(
                f"A load at {frequency:g} Hz lies above the highest mode kept "
                f"({top_mode:g} Hz): the truncated model cannot resolve it; keep more "
                "modes (n_modes).",
                TruncationWarning,
                stacklevel=3,
            )


@dataclass(frozen=True, eq=False)
class _ComplexModes:
    """Eigen-decomposition of the modal first-order system, scaled state s = [omega q; qdot].

    Scaling the displacement coordinates by omega makes the undamped system matrix
    [[0, Omega], [-Omega, -C]] normal (skew-symmetric), so its eigenvectors are well conditioned
    even across modes from 1 Hz to 100 kHz. Only one eigenvalue of each conjugate pair is kept;
    the real response is twice the real part.
    """

    eigenvalues: np.ndarray  # (n_kept,)
    right: np.ndarray  # (2r, n_kept) eigenvectors of the scaled system
    left: np.ndarray  # (n_kept, 2r) rows of the inverse eigenvector matrix
    weight: np.ndarray  # (n_kept,) 2 for a conjugate pair, 1 for a real eigenvalue
    omega: np.ndarray

    def project(self, q0: np.ndarray) -> np.ndarray:
        r = self.omega.size
        scaled = np.concatenate([self.omega * q0[:r], q0[r:]])
        return self.left @ scaled

    def input_gain(self, modal_load: np.ndarray) -> np.ndarray:
        return self.left[:, self.omega.size :] @ modal_load

    def to_dofs(self, basis, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Free-DOF displacement and velocity from the kept complex modal state."""
        r = self.omega.size
        scaled = ((self.right * self.weight) @ z).real
        return basis.shapes @ (scaled[:r] / self.omega), basis.shapes @ scaled[r:]

    def output_gains(self, nodal_shapes: np.ndarray) -> np.ndarray:
        """Map from kept complex modes to nodal displacement (real part taken by the caller)."""
        r = self.omega.size
        gains = (nodal_shapes / self.omega) @ self.right[:r]  # undo the omega scaling
        return gains * self.weight


# Complex modes per model and mode count: the general eigen-solve of a non-proportionally damped
# model (the robot's damper) is the dearest step of a short simulation, and continuing runs
# (closed loop) reuse it.
_COMPLEX_MODES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _complex_modes_of(model: LineModel, basis) -> _ComplexModes:
    per_model = _COMPLEX_MODES.setdefault(model, {})
    if basis.n_modes not in per_model:
        per_model[basis.n_modes] = _complex_modes(basis)
    return per_model[basis.n_modes]


@on_one_blas_thread   # small-matrix work
def _complex_modes(basis) -> _ComplexModes:
    r = basis.n_modes
    omega = basis.omega
    check_budget(f"The complex modes of {r} modes", nbytes=16.0 * 3 * (2 * r) ** 2,
                 parameter="n_modes", value=r, fix="keep fewer modes (n_modes)")
    system = np.block([[np.zeros((r, r)), np.diag(omega)], [-np.diag(omega), -basis.damping]])
    if np.count_nonzero(basis.damping - np.diag(np.diag(basis.damping))) == 0:
        # Proportional damping: each mode is an independent 2x2 block with closed-form eigen-pair.
        # lambda = -zeta w +/- sqrt(zeta^2 w^2 - w^2): a conjugate pair when underdamped, two
        # distinct real roots when overdamped (stiffness-proportional Rayleigh damping makes
        # high modes overdamped: physical, and not defective), one double root only at zeta = 1.
        zeta_w = np.diag(basis.damping) / 2
        root = np.sqrt((zeta_w**2 - omega**2).astype(complex))
        root = np.where(root.imag < 0, -root, root)       # the +i branch for underdamped modes
        critical = np.abs(zeta_w - omega) <= 1e-9 * omega
        if np.any(critical):
            raise ModelError(
                f"Mode(s) {np.flatnonzero(critical).tolist()} are critically damped "
                "(zeta = 1: a defective double eigenvalue); change the damping slightly."
            )
        first, second = -zeta_w + root, -zeta_w - root
        values_all = np.concatenate([first, second])
        vectors = np.zeros((2 * r, 2 * r), dtype=complex)
        inverse = np.zeros((2 * r, 2 * r), dtype=complex)
        idx = np.arange(r)
        # Each mode's 2 x 2 block [[w, w], [l1, l2]] has the closed-form inverse
        # [[l2, -w], [-l1, w]] / (w (l2 - l1)): no 2r x 2r solve.
        det = omega * (second - first)
        for block, lam in ((0, first), (1, second)):
            vectors[idx, block * r + idx] = omega
            vectors[r + idx, block * r + idx] = lam
        inverse[idx, idx], inverse[idx, r + idx] = second / det, -omega / det
        inverse[r + idx, idx], inverse[r + idx, r + idx] = -first / det, omega / det
    else:
        check_budget(f"The complex eigen-solve of {r} non-proportionally damped modes",
                     nbytes=16.0 * 4 * (2 * r) ** 2, flops=30.0 * (2 * r) ** 3,
                     parameter="n_modes", value=r, fix="keep fewer modes (n_modes)")
        values_all, vectors = scipy.linalg.eig(system)
        try:
            inverse = np.linalg.solve(vectors, np.eye(2 * r))
        except np.linalg.LinAlgError as exc:
            raise ModelError(
                "The modal system is defective (repeated, critically damped modes); "
                "change the damping slightly."
            ) from exc
    keep = values_all.imag > 0
    real = np.abs(values_all.imag) <= 1e-12 * np.abs(values_all).max()
    keep |= real
    weight = np.where(real[keep], 1.0, 2.0)
    return _ComplexModes(values_all[keep], vectors[:, keep], inverse[keep], weight, omega)


def _initial_modal_state(model, basis, displacement, velocity, modes, state) -> np.ndarray:
    r = basis.n_modes
    q = np.zeros(2 * r)
    mass = model.mass_matrix
    if state is not None:
        if not isinstance(state, tuple | list) or len(state) != 2:
            raise InputError(
                "The 'initial_state' parameter must be a (displacement, velocity) "
                f"pair over the free DOFs. Got {type(state).__name__}."
            )
        u0 = check_array("initial_state[0]", state[0], shape=(model.n_dofs,))
        v0 = check_array("initial_state[1]", state[1], shape=(model.n_dofs,))
        q[:r], q[r:] = basis.shapes.T @ (mass @ u0), basis.shapes.T @ (mass @ v0)
    if displacement is not None:
        q[:r] = basis.shapes.T @ (mass @ _initial_dofs(model, "initial_displacement", displacement))
    if velocity is not None:
        q[r:] = basis.shapes.T @ (mass @ _initial_dofs(model, "initial_velocity", velocity))
    if modes is not None and not isinstance(modes, dict):
        raise InputError(
            "The 'initial_modes' parameter must be None or a dict {mode index: amplitude (m)}. "
            f"Got {modes!r:.60} of type {type(modes).__name__}."
        )
    if modes:
        nodal = model.displacement_map() @ basis.shapes
        for index, amplitude in modes.items():
            index = check_int("initial_modes key", index, low=0, high=r - 1)
            amplitude = check_real("initial_modes value", amplitude)
            # the signed peak, exactly as LineModel.mode_shapes scales its shapes
            column = nodal[:, index]
            q[index] += amplitude / column[np.argmax(np.abs(column))]
    return q


def _exact_harmonic_possible(eigenvalues: np.ndarray, frequency: float) -> bool:
    """False when the load sits (numerically) on an undamped resonance: 1/(i w - lambda)."""
    omega = 2 * np.pi * frequency
    return bool(np.min(np.abs(1j * omega - eigenvalues)) > 1e-9 * omega)


def _harmonic_phasors(eigenvalues, forcing, phasor, omega) -> tuple[np.ndarray, np.ndarray]:
    """Particular solution of z' = lam z + g Re(P e^{iwt}) as plus e^{iwt} + minus e^{-iwt}.

    The response from rest is that minus exp(lam t) (plus + minus).
    """
    # Re(P e^{iwt}) = (P e^{iwt} + conj(P) e^{-iwt}) / 2
    plus = forcing * (0.5 * phasor) / (1j * omega - eigenvalues)
    minus = forcing * (0.5 * np.conj(phasor)) / (-1j * omega - eigenvalues)
    return plus, minus


def _foh_response(eigenvalues, forcing, values, dt) -> np.ndarray:
    """Exact response to a load linear between samples, from rest: one lfilter per mode."""
    lam_h = eigenvalues * dt
    decay = np.exp(lam_h)
    small = np.abs(lam_h) < 1e-6
    safe = np.where(small, 1.0, lam_h)
    # phi0 = int_0^h e^{lam(h-s)} ds,  phi1 = int_0^h e^{lam(h-s)} s/h ds (series for tiny lam h)
    phi0 = np.where(small, dt * (1 + lam_h / 2), (decay - 1) / safe * dt)
    phi1 = np.where(small, dt * (0.5 + lam_h / 6), (decay - 1 - lam_h) / safe**2 * dt)
    out = np.zeros((eigenvalues.size, values.size), dtype=complex)
    increments = values[:-1]
    nxt = values[1:]
    for k in range(eigenvalues.size):
        step_input = forcing[k] * ((phi0[k] - phi1[k]) * increments + phi1[k] * nxt)
        out[k, 1:] = scipy.signal.lfilter([1.0], [1.0, -decay[k]], step_input)
    return out
