"""A record of the line in the self-limiting aeolian wind: ``simulate``'s Snapshots, with the
energy balance's physics in place of a lift of fixed amplitude.

:func:`~powerline_control.simulation.simulate` drives an
:class:`~powerline_control.excitation.AeolianForce` as a lift of fixed amplitude on the model's
fixed damping, so its records never reach the amplitude at which the wind and the conductor
balance. :func:`simulate_self_limiting` records the line in the wind the closed loop runs in with
``run_closed_loop(wind="self_limiting")``: no lift, the wind's negative damping on the locked
mode and the conductor's self-damping on every band mode, at their amplitudes at each block's
start (:func:`~.self_limiting.self_limiting_wind`), on the plant
:func:`~.aeolian_run.simulate_aeolian` settles (:func:`~.modal.aeolian_plant`), the
model's robot parked where it is.

It lives here, beside the physics it runs, and not behind a ``wind=`` keyword of ``simulate``:
the simulation package sits above severity in the data flow (design.md section 2; severity's
time-domain runs use the simulation's plant), so ``simulate`` cannot reach the wind's power and
the self-damping laws without an import against that flow.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse

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
from ..errors import InputError
from ..fem import LineModel
from ..simulation import Snapshots
from ..simulation.plant import ModalPlant, nodal_field, robot_correction
from .modal import aeolian_plant
from .self_limiting import WIND_OPTIONS, checked_wind, self_limiting_wind

__all__ = ["simulate_self_limiting"]

#: Length of a block of samples over which the wind's and the self-damping's modal damping is
#: held (evaluated at the block's start), s: the closed loop's plant block, so a record and the
#: closed loop's line see the same wind; the amplitude's own time scale is seconds.
BLOCK_SECONDS = 0.01

#: ``simulate``'s options that have no meaning in the self-limiting wind, and why.
_REFUSED = {
    "initial_state": "a full FE state does not map onto the wind's modal plant (start from "
                     "initial_displacement / initial_velocity / initial_modes instead)",
    "n_modes": "the plant keeps the self-limiting wind's own modes (aeolian_plant: the modes "
               "below 8x the shedding frequency, or the band around it on a long span)",
    "quasi_static": "no load is applied, so no dropped mode responds quasi-statically",
}


@on_one_blas_thread   # small-matrix work: one sample at a time through a (2 n_q)-square map
@checked_keywords
def simulate_self_limiting(
    model: LineModel,
    force: object,
    duration: float = 10.0,
    dt: float = 1e-3,
    *,
    wind: str | dict = "self_limiting",
    noise_std: float = 0.0,
    noise_fraction: float | None = None,
    seed: int | np.random.Generator | None = None,
    initial_displacement: np.ndarray | Callable | None = None,
    initial_velocity: np.ndarray | Callable | None = None,
    initial_modes: dict[int, float] | None = None,
    initial_state: tuple | None = None,
    start_time: float = 0.0,
    n_modes: int | None = None,
    quasi_static: bool | None = None,
    memory_budget: float | None = None,
    outputs: Sequence[float] | np.ndarray | None = None,
) -> Snapshots:
    """Simulate displacement snapshots in the self-limiting aeolian wind.

    The same record as :func:`~powerline_control.simulation.simulate` (its arguments, its
    :class:`~powerline_control.simulation.Snapshots`) with the aeolian load as the energy
    balance's physics instead of a lift of fixed amplitude: the wind's power from the power curve
    at the locked mode's current amplitude as a negative damping on that mode (the bare line's
    mode nearest St V / D), the conductor's self-damping on every band mode at its own amplitude,
    evaluated at the start of each block of :data:`BLOCK_SECONDS` and held over it, on the
    modal plant of :func:`~powerline_control.severity.simulate_aeolian`
    (:func:`~powerline_control.severity.modal.aeolian_plant`), with the model's robot
    (``model.mdr``, if any) parked at its position. The model's own damping is not used: the
    self-damping law is the line's damping. Use it where a record must vibrate as a line in
    that wind does (e.g. the training record of an estimator that then runs in
    ``run_closed_loop(wind="self_limiting")``); ``simulate`` for any other load.

    Parameters
    ----------
    model : LineModel
        The span, the same support at both ends, with its robot (``mdr``) or without.
    force : AeolianForce
        The wind (its speed and Strouhal number); one, for the whole record.
    duration : float
        Simulated time, s (> 0); samples at 0, dt, ..., <= duration.
    dt : float
        Sample interval, s (> 0, below half the shedding period).
    wind : "self_limiting" or mapping
        The physics' options, as ``run_closed_loop``'s ``wind``: "self_limiting" (the severity
        study's defaults) or a mapping of ``wind_curve``, ``turbulence_intensity``,
        ``self_damping``, ``self_damping_k``, ``self_damping_exponents``
        (:func:`~powerline_control.severity.aeolian_severity`'s). "fixed_lift" is ``simulate``.
    noise_std, noise_fraction, seed
        Sensor noise, as in ``simulate``.
    initial_displacement, initial_velocity : array (n_nodes,), callable of x, or None
        Initial field at the nodes, fitted by least squares on the plant's basis (the robot's
        absorber starts level with the line under it).
    initial_modes : dict or None
        ``{mode index: amplitude (m)}``: the bare line's modes (0-based) at unit peak nodal
        displacement; only modes of the plant's basis.
    initial_state, n_modes, quasi_static
        ``simulate``'s; refused here (the message says why).
    start_time : float
        Time of the first sample, s (the wind is steady: it only labels ``t``).
    memory_budget : float or None
        Bytes the record may take (default 4 GiB).
    outputs : sequence of float or None
        Positions (m) where displacement is recorded; None (default) records every node.

    Returns
    -------
    Snapshots
        As ``simulate``'s, with: ``inputs`` an empty (0, n_t) array and ``force_positions`` an
        empty tuple (the wind applies no load: it is a damping); ``mode_frequencies`` the
        plant's coordinates' undamped frequencies (its band of bare modes, then the robot's
        Ritz vectors); ``final_state`` (displacement, velocity) over the model's free DOFs
        from the plant's basis (and the absorber), without the robot's correction outside it
        (a few % of the field near the robot): a start for ``simulate(initial_state=...)``.
        Without initial conditions the line starts with the locked mode at the energy
        balance's amplitude of the line without a robot, as the closed loop's line does: a
        bare line is in steady state from the first sample, one with a robot shows the decay
        to the robot's level.

    Raises
    ------
    InputError
        For invalid arguments, a load other than one AeolianForce, supports that differ at
        the two ends, a wind whose balance leaves the power curve's data or sustains no
        vibration, and ``simulate`` options that do not apply here.

    Warns
    -----
    TruncationWarning
        When the mesh does not resolve the shedding frequency's wavelength.

    Examples
    --------
    >>> import numpy as np
    >>> from powerline_control import AeolianForce, LineModel, Span, aeolian_severity
    >>> span = Span.at_rts_fraction(60.0, "drake", 0.2)
    >>> snap = simulate_self_limiting(LineModel(span, bc="pinned"), AeolianForce(3.0), 1.0,
    ...                               1e-3)
    >>> amplitude = np.sqrt(2 * np.mean(snap.displacement[:, -500:] ** 2, axis=1)).max()
    >>> balance = aeolian_severity(span, [3.0], bc="pinned").amplitude[0]
    >>> bool(abs(amplitude / balance - 1) < 0.02), snap.inputs.shape
    (True, (0, 1001))
    """
    memory_budget = check_budget_value("memory_budget", memory_budget)  # a guard: first
    if not isinstance(model, LineModel):
        raise InputError(f"The 'model' parameter must be a LineModel. Got {type(model).__name__}.")
    _refuse_simulate_options(initial_state=initial_state, n_modes=n_modes,
                             quasi_static=quasi_static)
    duration = check_real("duration", duration, low=0.0)
    dt = check_real("dt", dt, low=0.0)
    start_time = check_real("start_time", start_time)
    if dt > duration:
        raise InputError(
            f"The 'dt' parameter ({dt:g} s) must not exceed 'duration' ({duration:g} s).")
    noise_std = check_real("noise_std", noise_std, low=0.0, low_inclusive=True)
    if noise_fraction is not None:
        noise_fraction = check_real("noise_fraction", noise_fraction, low=0.0, low_inclusive=True)
        if noise_std:
            raise InputError("Give either 'noise_std' or 'noise_fraction', not both.")
    rng = check_rng(seed)
    options = checked_wind(wind, [(0.0, _loads(force))], model)
    if options is None:
        raise InputError(
            "The 'wind' parameter of simulate_self_limiting must be 'self_limiting' or a mapping "
            f"of the self-limiting physics' options {list(WIND_OPTIONS)}. Got 'fixed_lift': "
            "for the lift of fixed amplitude call simulate(model, force, ...).")
    aeolian = options["wind"]
    shedding = aeolian.strouhal * aeolian.wind_speed / model.span.conductor.diameter
    if shedding >= 0.5 / dt:
        raise InputError(
            f"The 'dt' parameter ({dt:g} s) cannot sample the wind's shedding frequency "
            f"{shedding:g} Hz: use dt < {0.5 / shedding:.6g} s.")
    model.check_resolution(shedding, what="load")
    out_x = _output_positions(model, outputs)
    n_t = int(np.floor(duration / dt + 1e-9)) + 1
    check_budget(
        f"simulate_self_limiting's {out_x.size} x {n_t} output", nbytes=8.0 * n_t * 3 * out_x.size,
        parameter="duration", value=duration,
        fix=f"shorten duration ({duration:g} s), increase dt ({dt:g} s) or record fewer "
        f"positions (outputs=[...], {out_x.size} now)", memory_budget=memory_budget)

    robot = model.mdr
    plant, band = aeolian_plant(model.with_robot(None), robot, shedding, dt)
    # the record has one line (the model's): the wind's "free" plant is the same one
    line = self_limiting_wind(options, plant, plant, block=max(1, round(BLOCK_SECONDS / dt)))
    position = None if robot is None else robot.position
    start = _initial_state(plant, band, position, initial_displacement, initial_velocity,
                           initial_modes)
    states = line.parked(position, n_t, z0=start)
    clean = _record(plant, states, position, outputs is not None, out_x)
    if noise_fraction is not None:
        noise_std = noise_fraction * float(np.sqrt(np.mean(clean**2)))
    noisy = clean + noise_std * rng.standard_normal(clean.shape) if noise_std > 0 else clean.copy()
    t = dt * np.arange(n_t)
    return Snapshots(
        t=read_only(start_time + t), dt=dt, x=read_only(out_x), displacement=read_only(noisy),
        true_displacement=read_only(clean),
        final_state=tuple(read_only(part) for part in _final_dofs(plant, states[-1])),
        inputs=read_only(np.zeros((0, n_t))), force_positions=(), noise_std=noise_std,
        mode_frequencies=read_only(np.sqrt(plant.omega2) / (2 * np.pi)),
        supports=(str(model.bc[0]), str(model.bc[1])))


def _refuse_simulate_options(**given) -> None:
    """``simulate``'s options that cannot apply in the self-limiting wind: refused when set."""
    for name, value in given.items():
        if value is not None:
            raise InputError(
                f"The '{name}' parameter has no meaning in the self-limiting wind: "
                f"{_REFUSED[name]}. Got {name}={value!r:.60}; leave it out (None), or call "
                "simulate(...) for the lift of fixed amplitude.")


def _loads(force: object) -> list:
    """The loads as a list (the self-limiting check refuses all but one AeolianForce)."""
    if force is None:
        return []
    return list(force) if isinstance(force, list | tuple) else [force]


def _output_positions(model: LineModel, outputs) -> np.ndarray:
    """Where the record is taken: the nodes, or the ``outputs`` positions, m."""
    if outputs is None:
        return np.array(model.node_positions, dtype=float)
    out_x = check_array("outputs", outputs, ndim=1)
    for x in out_x:
        check_real("outputs", float(x), low=0.0, low_inclusive=True, high=model.span.length)
    return np.array(out_x, dtype=float)


def _initial_state(plant: ModalPlant, band: np.ndarray, position: float | None, displacement,
                   velocity, modes) -> np.ndarray | None:
    """The plant's start (2 n_q,) from the initial field or modes; None when none is given (the
    wind's own start: the locked mode at the energy balance's amplitude)."""
    if displacement is None and velocity is None and not modes:
        if modes is not None and not isinstance(modes, dict):
            raise InputError(
                "The 'initial_modes' parameter must be None or a dict {mode index: amplitude "
                f"(m)}}. Got {modes!r:.60} of type {type(modes).__name__}.")
        return None
    z = np.zeros(2 * plant.n_q)
    for offset, name, value in ((0, "initial_displacement", displacement),
                                (plant.n_q, "initial_velocity", velocity)):
        if value is not None:
            z[offset : offset + plant.r] = _fitted(plant, name, value)
    if modes is not None:
        if not isinstance(modes, dict):
            raise InputError(
                "The 'initial_modes' parameter must be None or a dict {mode index: amplitude "
                f"(m)}}. Got {modes!r:.60} of type {type(modes).__name__}.")
        z[: plant.r] += _modal_start(plant, band, modes)
    if plant.absorber:
        # the absorber starts level with the line under it: its spring relaxed
        n = plant.coupling(position)
        z[plant.r] = n @ z[: plant.r]
        z[plant.n_q + plant.r] = n @ z[plant.n_q : plant.n_q + plant.r]
    return z


def _fitted(plant: ModalPlant, name: str, value) -> np.ndarray:
    """The basis' coordinates whose nodal field best fits ``value`` (least squares)."""
    x = plant.model.node_positions
    field = value(x) if callable(value) else value
    field = check_array(name if not callable(value) else f"{name}(x)", field,
                        shape=(plant.model.n_nodes,))
    return np.linalg.lstsq(plant.nodal, field, rcond=None)[0]


def _modal_start(plant: ModalPlant, band: np.ndarray, modes: dict) -> np.ndarray:
    """Coordinates of ``{bare mode index: amplitude at unit peak}`` on the plant's ``band`` (the
    bare modes its first coordinates are, 0-based)."""
    q = np.zeros(plant.r)
    for index, amplitude in modes.items():
        index = check_int("initial_modes key", index, low=0)
        amplitude = check_real("initial_modes value", amplitude)
        where = np.flatnonzero(band == index)
        if where.size == 0:
            raise InputError(
                f"The 'initial_modes' key {index} names a mode outside the self-limiting "
                f"wind's plant: it keeps the bare line's modes {band[0]}..{band[-1]} "
                "(0-based) around the shedding frequency.")
        column = plant.nodal[:, where[0]]
        q[where[0]] += amplitude / column[np.argmax(np.abs(column))]
    return q


def _record(plant: ModalPlant, states: np.ndarray, position: float | None, at_outputs: bool,
            out_x: np.ndarray) -> np.ndarray:
    """Displacement (n_out, n_t): the basis' field plus the robot's correction outside it
    (:func:`~powerline_control.simulation.plant.nodal_field`); at ``outputs`` positions the
    basis exactly and the correction interpolated linearly between the nodes."""
    if not at_outputs:
        return nodal_field(plant, states, 0.0, positions=position)
    field = plant.couplings(out_x) @ states[:, : plant.r].T
    correction = robot_correction(plant, states, position)
    if correction is not None:
        field += _interpolation(plant.model.node_positions, out_x) @ correction
    return field


def _interpolation(nodes: np.ndarray, x: np.ndarray) -> scipy.sparse.csr_array:
    """The (len(x), n_nodes) matrix of linear interpolation between the nodes."""
    right = np.clip(np.searchsorted(nodes, x, side="right"), 1, nodes.size - 1)
    left = right - 1
    weight = (x - nodes[left]) / (nodes[right] - nodes[left])
    rows = np.arange(x.size)
    return scipy.sparse.csr_array(
        (np.concatenate([1 - weight, weight]), (np.concatenate([rows, rows]),
                                                 np.concatenate([left, right]))),
        shape=(x.size, nodes.size))


def _final_dofs(plant: ModalPlant, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(displacement, velocity) over the model's free DOFs at the plant's state z: the basis'
    DOFs, then the robot's absorber (the model's last free DOF) if it has one."""
    parts = []
    for offset in (0, plant.n_q):
        dofs = plant.shapes @ z[offset : offset + plant.r]
        if plant.absorber:
            dofs = np.append(dofs, z[offset + plant.r])
        parts.append(dofs)
    return parts[0], parts[1]
