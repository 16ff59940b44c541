"""The exact steady state of the FE line under a sine with the robot parked, at many positions.

One factorisation of the bare line's dynamic stiffness and, per robot position, one solve and a
rank-one (Sherman-Morrison) update: the robot is attached at one point, so its dynamic stiffness
``D_r`` (force on the line per unit line displacement there) changes the bare receptance ``H`` by

    W_p = W_bare + H s_p D_r (s_p^T W_bare) / (1 - D_r s_p^T H s_p)

with ``s_p`` the shape-function row at the position ``p`` and ``W_bare = H f`` the bare line's
response. This is the truth the moving-robot plant is checked against.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._spectral import load_phasor
from .._validation import check_array, check_bare_line, read_only
from ..errors import InputError, ModelError
from ..fem import MDR, LineModel, ModalDamping, RayleighDamping, damper_impedance
from .plant import robot_dynamic_stiffness

# Modes a ModalDamping line keeps with their damping: those below this multiple of the load
# frequency. Above it a mode's damping changes its term 1 / (w_k^2 - w^2 + 2 i zeta w_k w) by
# less than 2 zeta / 3 relative (w_k >= 2 w), and that term is itself off resonance.
MODAL_DAMPING_BAND = 2.0
# Robot positions per multi-right-hand-side solve: (n_dofs, 256) complex is 8 MB on a 2000-element
# mesh.
_SOLVE_CHUNK = 256


@dataclass(frozen=True, eq=False)
class ParkedSteadyState:
    """The line's steady state under one sine with the robot parked at each of ``positions``.

    Attributes
    ----------
    frequency : float
        The load's frequency, Hz.
    positions : ndarray, shape (n_p,)
        Robot positions, m from the left support.
    x : ndarray, shape (n_nodes,)
        Node positions, m.
    field : ndarray, shape (n_p, n_nodes), complex
        Nodal amplitudes: displacement ``Re(field * exp(i omega t))``, m.
    rms : ndarray, shape (n_p,)
        Length-weighted RMS over the span and over time,
        ``sqrt(0.5 * sum(w |field|^2))`` with trapezoid weights ``w`` summing to 1, m.
    robot_displacement : ndarray, shape (n_p,), complex
        Amplitude of the line's displacement under the robot, m.
    damper_power : ndarray, shape (n_p,)
        Mean power dissipated in the robot's absorber, W (0 without a robot or absorber).

    Examples
    --------
    >>> import numpy as np
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), 40, damping=plc.ModalDamping(0.01))
    >>> robot = plc.tune_damper(model, 2, None, 0.04, body_mass=0.02)
    >>> force = plc.HarmonicForce(1.0, model.natural_frequencies(2)[1], 1.2)
    >>> state = plc.simulation.parked_steady_state(model, force, robot, np.linspace(0.1, 3.5, 35))
    >>> state.field.shape
    (35, 41)
    >>> bool(state.best_rms < state.rms.max())
    True
    """

    frequency: float
    positions: np.ndarray
    x: np.ndarray
    field: np.ndarray
    rms: np.ndarray
    robot_displacement: np.ndarray
    damper_power: np.ndarray

    @property
    def best_position(self) -> float:
        """The position (of those given) where the span RMS is least, m."""
        return float(self.positions[int(np.argmin(self.rms))])

    @property
    def best_rms(self) -> float:
        """The least span RMS over the positions given, m."""
        return float(np.min(self.rms))


def _harmonic_load(model: LineModel, force: object) -> tuple[float, np.ndarray]:
    """(frequency Hz, complex load amplitude over the free DOFs) of one sine or of sines of one
    frequency; anything else is refused naming 'force'."""
    items = list(force) if isinstance(force, list | tuple) else [force]
    if not items:
        raise InputError("The 'force' parameter must hold at least one harmonic load. Got [].")
    frequency, load = None, np.zeros(model.n_dofs, dtype=complex)
    for item in items:
        bound = item.bind(model) if hasattr(item, "bind") else item
        f = getattr(bound, "frequency", None)
        if not (hasattr(bound, "values") and hasattr(bound, "load_vector")) or not (
            isinstance(f, numbers.Real) and not isinstance(f, bool) and np.isfinite(f) and f > 0
        ):
            raise InputError(
                "The 'force' parameter must be a harmonic load (HarmonicForce, AeolianForce) or a "
                "list of them with one common frequency. Got "
                f"{type(item).__name__}{'' if f is None else f' at {f!r} Hz'}."
            )
        if frequency is None:
            frequency = float(f)
        elif not np.isclose(float(f), frequency, rtol=1e-9, atol=0.0):
            raise InputError(
                "The loads of the 'force' parameter must share one frequency (a steady state "
                f"has one). Got {frequency:g} Hz and {float(f):g} Hz."
            )
        if getattr(bound, "position", None) is not None:
            model._check_position("force position", bound.position)
        vector = check_array("force load vector", bound.load_vector(model), shape=(model.n_dofs,))
        load += load_phasor(bound, frequency) * vector
    return frequency, load


def _bare_receptance(model: LineModel, frequency: float):
    """v -> Z(omega)^-1 v for the bare line, by one sparse factorisation.

    None and Rayleigh damping: the sparse complex LU of K - omega^2 M + i omega C (exact).
    ModalDamping (defined mode by mode, so C is not a sparse matrix): the LU of
    K - omega^2 M + i omega alpha M with alpha = 2 zeta omega (mass-proportional damping, the
    load frequency's own ratio), corrected on the modes below ``MODAL_DAMPING_BAND`` times the
    frequency to their own damping (an exact rank-k correction: the modes are M-orthonormal).
    The modes above keep the mass-proportional damping, ratio zeta omega / omega_k < zeta / 2
    instead of their own: each of their terms, off resonance, changes by under 2 zeta / 3.
    (The undamped K - omega^2 M would be nearly singular on a resonance.)
    """
    omega = 2 * np.pi * frequency
    mass, stiffness = model.mass_matrix, model.stiffness_matrix
    damping = model.damping
    correction = None
    matrix = stiffness - omega**2 * mass
    if isinstance(damping, ModalDamping):
        basis = model.modes_below(MODAL_DAMPING_BAND * frequency)
        shapes, w = np.asarray(basis.shapes), np.asarray(basis.omega)
        ratio = float(damping.ratios(basis.n_modes)[-1])
        alpha = 2 * ratio * omega
        matrix = matrix + 1j * omega * alpha * mass
        gap = w**2 - omega**2
        correction = (shapes, 1.0 / (gap + 1j * omega * np.diag(basis.damping))
                      - 1.0 / (gap + 1j * omega * alpha))
    elif isinstance(damping, RayleighDamping):
        matrix = matrix + 1j * omega * (damping.mass_coefficient * mass
                                        + damping.stiffness_coefficient * stiffness)
    try:
        lu = spla.splu(sp.csc_matrix(matrix))
    except RuntimeError as exc:   # exactly singular: an undamped natural frequency
        lu = None
        cause = exc
    else:
        pivots = np.abs(lu.U.diagonal())
        cause = None
    # A pivot at round-off of the largest: the line is (numerically) undamped at one of its
    # natural frequencies, and the solve would return noise of size 1e16. (1e-12: SuperLU in
    # SciPy 1.17 leaves 2.3e-13 on the 20-element lab span exactly at its fundamental; an
    # undamped 839-element Drake span 0.01 % off its mode 90 keeps 8e-3.)
    if lu is None or not pivots.min() > 1e-12 * pivots.max():
        raise ModelError(
            f"The bare line's dynamic stiffness is singular at {frequency:g} Hz (an undamped "
            "natural frequency of the model): shift the frequency slightly or add damping."
        ) from cause
    if np.iscomplexobj(matrix.data):
        base = lu.solve
    else:
        def base(v):
            return lu.solve(np.ascontiguousarray(v.real)) + 1j * lu.solve(
                np.ascontiguousarray(v.imag))
    if correction is None:
        return base
    shapes, extra = correction
    # v: one vector (n_dofs,) or one per column (n_dofs, k)
    return lambda v: base(v) + shapes @ (extra.reshape(-1, *([1] * (v.ndim - 1)))
                                         * (shapes.T @ v))


def parked_steady_state(model: LineModel, force: object, robot: MDR | None,
                        positions: np.ndarray | None = None) -> ParkedSteadyState:
    """Exact steady state of the FE line under a sine with the robot parked at each position.

    Parameters
    ----------
    model : LineModel
        The bare line (mesh, supports, damping). Its ``mdr`` must be None: the robot is the
        ``robot`` argument (a model with a robot attached already is refused rather than
        silently counted twice or ignored).
    force : HarmonicForce, AeolianForce, or a list/tuple of them
        Harmonic loads of one common frequency (an AeolianForce is bound to ``model``).
    robot : MDR or None
        The robot (body mass and tuned absorber); None: the bare line.
    positions : array_like, shape (n_p,), or None
        Robot positions, m, inside [0, L]; None: ``robot.position``. Without a robot the
        result has one entry (position NaN) unless positions are given (each then the bare
        line).

    Returns
    -------
    ParkedSteadyState

    Raises
    ------
    InputError
        A model with a robot, a load that is not a sine or sines of different frequencies,
        positions off the span or not finite, a robot that is not an MDR.
    ModelError
        The bare line is singular at the load frequency (undamped, exactly at a natural
        frequency), or the line with the robot is (1 - D_r H(p, p) = 0).

    Warns
    -----
    TruncationWarning
        When the mesh does not resolve the load's frequency (its loops are too short for the
        elements): the steady state is the coarse model's, not the line's.

    Notes
    -----
    Exact for the FE model: the bare dynamic stiffness Z = K - omega^2 M + i omega C is
    factorised once (sparse LU) and each position costs one sparse solve, ``H s_p``, and the
    rank-one update of the module doc, with ``D_r = -i omega Z_r`` the robot's dynamic stiffness
    (:func:`~powerline_control.fem.damper_impedance`: body mass and absorber). For
    ``RayleighDamping`` C = a M + b K exactly. For ``ModalDamping`` (a ratio per mode, not a
    matrix) the modes below twice the load frequency carry their damping and the others are
    undamped (mode acceleration): each of those terms changes by under 2 zeta / 3 relative and
    they are off resonance. The damper power is ``0.5 Re(Z_r) omega^2 |W(p)|^2`` (the body mass
    is reactive).

    Examples
    --------
    >>> import numpy as np
    >>> import powerline_control as plc
    >>> span = plc.Span.paper_lab()
    >>> model = plc.LineModel(span, 60, damping=plc.ModalDamping(0.005))
    >>> f3 = model.natural_frequencies(3)[2]
    >>> robot = plc.tune_damper(model, 3, None, 0.04, body_mass=0.03)
    >>> force = plc.HarmonicForce(1.0, f3, 0.41 * span.length)
    >>> scan = plc.simulation.parked_steady_state(model, force, robot, np.linspace(0.05, 3.6, 72))
    >>> bare = plc.simulation.parked_steady_state(model, force, None)
    >>> bool(bare.rms[0] > 3 * scan.best_rms)       # the tuned robot at its best damps the mode
    True
    >>> bool(np.all(scan.damper_power >= 0))
    True
    """
    if not isinstance(model, LineModel):
        raise InputError(f"The 'model' parameter must be a LineModel. Got {type(model).__name__}.")
    check_bare_line(model, "the robot is the 'robot' argument")
    if robot is not None and not isinstance(robot, MDR):
        raise InputError(f"The 'robot' parameter must be an MDR or None. Got "
                         f"{type(robot).__name__}.")
    frequency, load = _harmonic_load(model, force)
    model.check_resolution(frequency, "load")   # TruncationWarning: the mesh cannot show it
    if positions is None:
        positions = np.array([robot.position if robot is not None else np.nan])
    else:
        positions = check_array("positions", positions, ndim=(0, 1)).reshape(-1)
        if positions.size == 0:
            raise InputError("The 'positions' parameter must hold at least one position.")
        off = positions[(positions < 0.0) | (positions > model.span.length)]
        if off.size:
            raise InputError(
                f"The 'positions' parameter must lie on the span [0, {model.span.length:g}] m. "
                f"Got {off.size} outside, e.g. {off[0]!r}."
            )
    omega = 2 * np.pi * frequency
    solve = _bare_receptance(model, frequency)
    bare = solve(load)
    nodal = model.displacement_map()
    bare_field = nodal @ bare
    if not np.all(np.isfinite(bare_field)):
        raise ModelError(f"The bare line's response at {frequency:g} Hz is not finite (an "
                         "undamped resonance): shift the frequency slightly or add damping.")
    n_p = positions.size
    field = np.empty((n_p, model.n_nodes), dtype=complex)
    at_robot = np.zeros(n_p, dtype=complex)
    power = np.zeros(n_p)
    dynamic = 0j if robot is None else robot_dynamic_stiffness(robot, omega)
    absorbing = 0.0 if robot is None else damper_impedance(robot, frequency).real
    bare_only = np.isnan(positions) if dynamic != 0 else np.ones(n_p, dtype=bool)
    field[bare_only] = bare_field
    for i in np.flatnonzero(bare_only & ~np.isnan(positions)):
        at_robot[i] = model.shape_vector(positions[i]) @ bare
    at_robot[np.isnan(positions)] = np.nan
    # The robot's positions in chunks: H s_p for a chunk is one solve with many right-hand sides
    # (and stays a few MB on fine meshes).
    placed = np.flatnonzero(~bare_only)
    for chunk in np.array_split(placed, -(-placed.size // _SOLVE_CHUNK)) if placed.size else []:
        index, weights = model.shape_rows(positions[chunk])
        rows = model.displacement_map(positions[chunk])
        columns = solve(rows.T.toarray().astype(complex))   # H s_p (Z symmetric: also s_p^T H)
        at_p = np.take_along_axis(columns, np.where(index >= 0, index, 0).T, axis=0).T
        denominator = 1.0 - dynamic * np.sum(weights * at_p, axis=1)
        bad = ~np.isfinite(denominator) | (np.abs(denominator) < 1e-12)
        if np.any(bad):
            p = positions[chunk][np.flatnonzero(bad)[0]]
            raise ModelError(f"The line with the robot at {p:g} m is singular at {frequency:g} "
                             "Hz (1 - D_r H(p, p) = 0); shift the frequency or add damping.")
        at_robot[chunk] = np.sum(weights * bare[np.where(index >= 0, index, 0)], axis=1) / (
            denominator)
        field[chunk] = bare_field + (nodal @ columns).T * (dynamic * at_robot[chunk])[:, None]
    power[~bare_only] = 0.5 * absorbing * omega**2 * np.abs(at_robot[~bare_only]) ** 2
    rms = np.sqrt(0.5 * (np.abs(field) ** 2) @ model.span_weights)
    return ParkedSteadyState(
        frequency=frequency, positions=read_only(positions.copy()),
        x=read_only(np.asarray(model.node_positions, dtype=float).copy()),
        field=read_only(field), rms=read_only(rms), robot_displacement=read_only(at_robot),
        damper_power=read_only(power),
    )
