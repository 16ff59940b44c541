"""The energy balance with the line and the robot coupled: the steady vibration as a limit cycle.

The energy balance's damper power, 1/2 Re Z omega^2 Y^2 phi^2 / L
(:func:`~powerline_control.severity.damper_power`), is first order: it assumes the damper leaves
the standing wave as it is. The robot's impedance on a real span is many times the line's wave
impedance sqrt(T m) (Drake 300 m with a 3 kg absorber: 12x), so it reshapes the wave where it
sits and takes far less power per unit amplitude than the formula says (the time-domain runs of
:func:`~powerline_control.severity.simulate_aeolian` settle 3-12x above the formula's
amplitude). Here the same powers as the energy balance (the power curve's wind power on the
locked mode and the self-damping law on every mode, :class:`AeolianDamping`) damp the modal plant
of the line with the robot parked on it, and the steady amplitude is the one at which the
coupled mode the wind feeds neither grows nor decays: its eigenvalue lies on the imaginary axis.
Over one cycle of that mode the wind's input equals what the self-damping and the robot take
(for M, C, K symmetric, u^H (lambda^2 M + lambda C + K) u = 0 at lambda = i omega leaves
omega u^H C u = 0), so this is the energy balance with the robot's power computed, not imposed.
It needs one small eigenproblem per trial amplitude, where the time-domain run integrates the
approach to the same state.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize

from .._validation import check_real, read_only
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL
from ..fem import MDR, AtAntinode, damper_impedance
from ..line import Span
from ._common import MAX_WIND_SPEED, _check_span
from .aeolian_run import (
    LOWEST_REDUCED_AMPLITUDE,
    AeolianDamping,
    _aeolian_plant,
    aeolian_damping,
)
from .balance import aeolian_severity
from .self_damping import FotiMartinelli
from .wind import SelfDampingLaw, _curve

__all__ = ["CoupledBalance", "coupled_balance"]

#: A coupled mode counts as fed by the wind when the locked mode holds at least this share of
#: its band's modal amplitude: the undamped modes the wind leaves alone (no amplitude, so no
#: self-damping) sit on the imaginary axis too and must not be taken for the limit cycle.
FED_SHARE = 0.05

#: The limit cycle's shape is iterated (each mode's self-damping at its own amplitude) until no
#: band amplitude moves by more than this fraction of the locked one.
SHAPE_TOLERANCE = 1e-9

#: Ratio of consecutive locked amplitudes along the continuation from the lowest amplitude:
#: small enough that the mode followed changes little from one step to the next.
AMPLITUDE_STEP = 1.25

#: Iterations of the shape allowed before the amplitude is refused as not converged.
MAX_SHAPE_ITERATIONS = 100


@dataclass(frozen=True, eq=False)
class CoupledBalance:
    """The energy balance of a span with the robot coupled to it (see :func:`coupled_balance`).

    Attributes
    ----------
    wind_speed : float
        m/s.
    status : str
        "balanced"; "no vibration" (the self-damping and the robot take more than the wind gives
        at every amplitude: the line is still); or "above curve range" (the wind still wins at
        the power curve's largest amplitude).
    amplitude : float
        Steady antinode amplitude, zero-to-peak, m: the largest of the limit cycle's nodal
        amplitudes (0 without vibration).
    frequency : float
        The limit cycle's frequency, Hz (the coupled mode's; the bare locked mode's without a
        robot).
    mode : int
        The bare mode the wind locks into (1-based).
    robot_position : float or None
        Where the robot is parked, m.
    wind_power, self_damping_power, robot_power : float
        Mean powers over a cycle, W per metre of span: the wind's input, the conductor's
        self-damping (every mode at its own amplitude) and the robot's damper.
    energy_residual : float
        (wind - self-damping - robot) / wind: how exactly the root sits on the imaginary axis.
    first_order_amplitude : float
        :func:`aeolian_severity`'s amplitude for the same robot at the same position, with the
        first-order damper power, m.
    robot_impedance_ratio : float
        The robot's ``|Z|`` at the limit cycle's frequency over the line's wave impedance
        sqrt(T m): where it is small the first-order power holds.
    x, field_amplitude : ndarray
        Node positions, m, and the limit cycle's amplitude at each, m.

    Examples
    --------
    >>> from powerline_control import Span
    >>> balance = coupled_balance(Span.at_rts_fraction(60.0, "drake", 0.2), 3.0, bc="pinned")
    >>> balance.status, round(balance.amplitude * 1e3, 1)
    ('balanced', 8.6)
    """

    wind_speed: float
    status: str
    amplitude: float
    frequency: float
    mode: int
    robot_position: float | None
    wind_power: float
    self_damping_power: float
    robot_power: float
    energy_residual: float
    first_order_amplitude: float
    robot_impedance_ratio: float
    x: np.ndarray = field(repr=False)
    field_amplitude: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class _Cycle:
    """The coupled mode the wind feeds at one locked amplitude: eigenvalue and shape."""

    eigenvalue: complex
    shape: np.ndarray       # complex displacement amplitudes over the plant's coordinates
    own: np.ndarray         # each band mode's self-damping coefficient at its amplitude, 1/s
    wind: float             # the wind's (negative) coefficient on the locked mode, 1/s


def _cycle(plant, damping: AeolianDamping, position: float | None, locked_amplitude: float,
           follow: np.ndarray | None = None) -> _Cycle:
    """The coupled mode the wind feeds when the locked mode's antinode amplitude is
    ``locked_amplitude`` (m), every other band mode at the amplitude the mode's own shape gives
    it (iterated: each mode's self-damping depends on its amplitude).

    ``follow``: the shape of that mode at a nearby amplitude; the mode continued from it is the
    one most parallel to it. None (the lowest amplitude, where the wind outweighs every
    damping): the fastest-growing mode the wind feeds."""
    band, locked, n_q = damping.band, damping.locked, plant.n_q
    amplitudes = np.zeros(band)
    amplitudes[locked] = locked_amplitude
    if follow is not None:
        amplitudes = damping.peak * np.abs(follow[:band]) * (
            locked_amplitude / (damping.peak[locked] * abs(follow[locked])))
    for _ in range(MAX_SHAPE_ITERATIONS):
        z = np.zeros(2 * n_q)
        z[:band] = amplitudes / damping.peak
        own, wind = damping.coefficients(z)
        values, vectors = np.linalg.eig(
            plant.state_matrix(position, damping.matrix(z, (own, wind))))
        shapes = vectors[:n_q] / np.linalg.norm(vectors[:n_q], axis=0)
        if follow is None:
            share = np.abs(shapes[locked]) / np.maximum(
                np.linalg.norm(shapes[:band], axis=0), 1e-300)
            # an overdamped locked mode (real eigenvalues: far below the curves' data on a
            # light conductor) is fed too: its growth rate says whether the line vibrates
            fed = np.flatnonzero((values.imag >= 0) & (share >= FED_SHARE))
            k = int(fed[np.argmax(values.real[fed])])
        else:
            overlap = np.abs(np.conj(follow) @ shapes) / np.linalg.norm(follow)
            overlap[values.imag < 0] = -1.0
            k = int(np.argmax(overlap))
        shape = shapes[:, k] * (locked_amplitude / damping.peak[locked] / shapes[locked, k])
        follow = shape
        new = damping.peak * np.abs(shape[:band])
        if np.max(np.abs(new - amplitudes)) <= SHAPE_TOLERANCE * locked_amplitude:
            return _Cycle(complex(values[k]), shape, own, wind)
        amplitudes = new
    raise InputError(
        "coupled_balance: the limit cycle's shape did not converge in "
        f"{MAX_SHAPE_ITERATIONS} iterations at a locked amplitude of {locked_amplitude:.3g} m; "
        "use simulate_aeolian for this span and robot.")


def limit_cycle(plant, damping: AeolianDamping, position: float | None
                ) -> tuple[str, _Cycle | None]:
    """The status and the limit cycle: the mode the wind feeds, continued from the wind's
    lowest amplitude (:data:`LOWEST_REDUCED_AMPLITUDE` D) up the locked amplitude in steps of
    :data:`AMPLITUDE_STEP` until its growth rate changes sign, then the root between the two
    steps (Brent's method on the amplitude's logarithm, each trial continued from the lower
    step); "above curve range" when it still grows at the power curve's last amplitude."""
    diameter = damping.span.conductor.diameter
    low = LOWEST_REDUCED_AMPLITUDE * diameter
    high = _curve(damping.wind_curve).max_reduced_amplitude * diameter
    cycle = _cycle(plant, damping, position, low)
    if cycle.eigenvalue.real <= 0:
        return "no vibration", None
    amplitude = low
    while amplitude < high:
        upper = min(amplitude * AMPLITUDE_STEP, high)
        above = _cycle(plant, damping, position, upper, cycle.shape)
        if above.eigenvalue.real <= 0:
            break
        amplitude, cycle = upper, above
    else:
        return "above curve range", cycle
    below = cycle

    def growth(log_amplitude: float) -> float:
        return _cycle(plant, damping, position, math.exp(log_amplitude),
                      below.shape).eigenvalue.real

    root = scipy.optimize.brentq(growth, math.log(amplitude), math.log(upper), xtol=1e-12,
                                 rtol=1e-12)
    return "balanced", _cycle(plant, damping, position, math.exp(root), below.shape)


def cycle_field(plant, cycle: _Cycle | None) -> np.ndarray:
    """The limit cycle's amplitude at each node, m (zeros without one)."""
    if cycle is None:
        return np.zeros(plant.nodal.shape[0])
    return np.abs(plant.nodal @ cycle.shape[: plant.r])


def _antinode_near(plant, locked: int, position: float) -> float:
    """The antinode of the plant's band mode ``locked`` nearest ``position``, m: the largest
    |shape| between the nodes of that mode on either side (the FE shape functions between
    the mesh's nodes, so it is not held to the node grid)."""
    shape = plant.nodal[:, locked]
    x = plant.model.node_positions
    peaks = np.flatnonzero((np.abs(shape[1:-1]) >= np.abs(shape[:-2]))
                           & (np.abs(shape[1:-1]) >= np.abs(shape[2:]))) + 1
    nearest = int(peaks[np.argmin(np.abs(x[peaks] - position))])
    lo, hi = x[max(nearest - 1, 0)], x[min(nearest + 1, x.size - 1)]
    found = scipy.optimize.minimize_scalar(
        lambda s: -abs(float(plant.coupling(s)[locked])), bounds=(lo, hi), method="bounded",
        options={"xatol": 1e-6 * (hi - lo)})
    return float(found.x)


def _cycle_powers(plant, damping: AeolianDamping, position: float | None, cycle: _Cycle
                  ) -> tuple[float, float, float]:
    """Mean powers over one cycle of the limit cycle (W, over the whole span), each
    1/2 omega^2 u^H C u of its own part of the damping: the wind's input on the locked mode, the
    self-damping's on every band mode, the robot's dashpot."""
    u, omega = cycle.shape, abs(cycle.eigenvalue.imag)
    band = np.abs(u[: damping.band]) ** 2
    wind = -0.5 * omega**2 * cycle.wind * band[damping.locked]
    own = 0.5 * omega**2 * float(cycle.own @ band)
    _, robot_damping, _ = plant.matrices(position, np.zeros((plant.r, plant.r)))
    robot = 0.5 * omega**2 * float(np.real(np.conj(u) @ robot_damping @ u))
    return float(wind), own, robot


def coupled_balance(
    span: Span,
    wind_speed: float,
    robot: MDR | AtAntinode | None = None,
    *,
    bc: str = "clamped",
    n_elements: int | None = None,
    strouhal: float = DEFAULT_STROUHAL,
    wind_curve: str = "cigre",
    turbulence_intensity: float = 0.0,
    self_damping: str | SelfDampingLaw | FotiMartinelli = "noiseux1991",
    self_damping_k: float | None = None,
    self_damping_exponents: Sequence[float] | None = None,
) -> CoupledBalance:
    """The energy balance's steady amplitude with the robot coupled to the line.

    The plant is :func:`simulate_aeolian`'s (the FE line's modes near the tone, the robot's
    Ritz vector, the robot parked), damped by the energy balance's own powers at the vibration's
    amplitudes (:class:`AeolianDamping`). The steady amplitude is the locked mode's amplitude at
    which the coupled mode the wind feeds has a zero real part (Brent's method on its logarithm;
    at each trial the shape is iterated so that every mode's self-damping is at its own
    amplitude). That mode's shape gives the field, its frequency the vibration's, and its powers
    the balance (module doc).

    Parameters
    ----------
    span : Span
        The line.
    wind_speed : float
        m/s, in (0, 30].
    robot : MDR, AtAntinode or None
        An MDR is parked at its ``position``; ``AtAntinode(robot)`` at the antinode of the
        locked mode nearest the robot's position (its ``factor`` must be 1: the coupled model
        places the robot, it does not scale its power); None: the bare line.
    bc : {"clamped", "pinned"}
        Supports.
    n_elements : int or None
        FE mesh (None: the mesh that resolves the aeolian band).
    strouhal, wind_curve, turbulence_intensity, self_damping, self_damping_k, \
self_damping_exponents
        As in :func:`aeolian_severity`.

    Returns
    -------
    CoupledBalance

    Raises
    ------
    InputError
        For bad arguments, a robot that is not an MDR (an ``ImpedanceDamper`` has no FE model),
        or a limit cycle whose shape does not converge.

    Examples
    --------
    >>> from powerline_control import MDR, Span
    >>> from powerline_control.fem import AtAntinode
    >>> span = Span.at_rts_fraction(60.0, "drake", 0.2)
    >>> robot = MDR.tuned(30.0, 0.5, 0.3, frequency=19.7, damping_ratio=0.2)
    >>> balance = coupled_balance(span, 3.0, AtAntinode(robot), bc="pinned")
    >>> balance.amplitude > balance.first_order_amplitude    # the robot reshapes the wave
    True
    """
    span = _check_span(span)
    speed = check_real("wind_speed", wind_speed, low=0.0, high=MAX_WIND_SPEED)
    at_antinode = isinstance(robot, AtAntinode)
    device = robot.damper if at_antinode else robot
    if device is not None and not isinstance(device, MDR):
        raise InputError("The 'robot' parameter of coupled_balance must be an MDR, "
                         "AtAntinode(MDR) or None (the coupled model needs the robot's masses, "
                         f"spring and dashpot). Got {type(device).__name__}.")
    if at_antinode and robot.factor != 1.0:
        raise InputError("The 'robot' parameter of coupled_balance takes AtAntinode with "
                         f"factor 1 (the robot at the antinode). Got factor {robot.factor:g}: "
                         "park an MDR at the position you mean instead.")
    if device is not None and not 0 <= device.position <= span.length:
        raise InputError(f"The 'robot' position must lie in [0, {span.length:g}] m (the span). "
                         f"Got {device.position!r}.")
    powers = {"wind_curve": wind_curve, "turbulence_intensity": turbulence_intensity,
              "self_damping": self_damping, "self_damping_k": self_damping_k,
              "self_damping_exponents": self_damping_exponents}
    bare, plant, band_modes = _aeolian_plant(span, speed, device, bc=bc,
                                             n_elements=n_elements, strouhal=strouhal)
    damping = aeolian_damping(plant, span, speed, strouhal=strouhal, **powers)
    if at_antinode:
        # the band's modes do not depend on the robot; its Ritz vector (the line's flexibility
        # the band misses where it sits) does, so the plant is built again at the antinode
        device = dataclasses.replace(
            device, position=_antinode_near(plant, damping.locked, device.position))
        bare, plant, band_modes = _aeolian_plant(span, speed, device, bc=bc,
                                                 n_elements=n_elements, strouhal=strouhal)
        damping = aeolian_damping(plant, span, speed, strouhal=strouhal, **powers)
    position = None if device is None else float(device.position)
    first_order = aeolian_severity(
        span, [speed], () if device is None else (device,),
        strouhal=strouhal, bc=bc, **powers)

    cond = span.conductor

    mode = int(band_modes[damping.locked]) + 1
    status, cycle = limit_cycle(plant, damping, position)
    frequency = damping.frequency
    field_amplitude = np.zeros(bare.n_nodes)
    p_wind = p_self = p_robot = residual = 0.0
    if cycle is not None:
        frequency = abs(cycle.eigenvalue.imag) / (2 * math.pi)
        field_amplitude = cycle_field(plant, cycle)
        p_wind, p_self, p_robot = (
            value / span.length for value in _cycle_powers(plant, damping, position, cycle))
        residual = (p_wind - p_self - p_robot) / p_wind if p_wind > 0 else 0.0
    ratio = 0.0 if device is None else abs(damper_impedance(device, frequency)) \
        / math.sqrt(span.tension * cond.mass_per_length)
    return CoupledBalance(
        wind_speed=speed, status=status, amplitude=float(field_amplitude.max()),
        frequency=float(frequency), mode=mode, robot_position=position,
        wind_power=float(p_wind), self_damping_power=float(p_self),
        robot_power=float(p_robot), energy_residual=float(residual),
        first_order_amplitude=float(first_order.amplitude[0]),
        robot_impedance_ratio=float(ratio), x=read_only(bare.node_positions.copy()),
        field_amplitude=read_only(field_amplitude))
