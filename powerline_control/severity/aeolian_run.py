"""The self-limiting aeolian vibration in the time domain: the energy balance's own powers.

In lock-in the wind's lift follows the conductor's velocity: it is a negative damping whose
power at antinode amplitude Y is the power curve's P_w(Y); the conductor's self-damping is a
positive damping whose power is the self-damping law's P_c(Y). For a standing wave
y = Y sin(beta x) sin(omega t), a uniform viscous damping c = 2 zeta m omega per metre takes
zeta m omega^3 Y^2 / 2 per metre, so each power is a modal damping ratio

    zeta(Y) = 2 P(Y) / (m omega^3 Y^2)

(the mapping :func:`~powerline_control.severity.time_domain_check` uses). The run integrates the
line's modes and the parked robot exactly (:class:`~powerline_control.simulation.plant.ModalPlant`)
over blocks short against the amplitude's own time scale, each block with the ratios of the
amplitudes at its start: the wind feeds the mode locked to the Strouhal frequency, self-damping
acts on every mode at its own amplitude, and the robot's damper is the FE robot's. The amplitude
settles where P_w = P_c + P_robot, as the energy balance says, without a lift coefficient or a
modal damping ratio chosen by hand.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy.integrate import trapezoid  # numpy >= 1.26 is allowed: np.trapezoid is 2.0's

from .._threads import on_one_blas_thread
from .._validation import check_real, read_only
from ..errors import InputError, TruncationWarning
from ..excitation import DEFAULT_STROUHAL, AeolianForce
from ..fem import MDR, LineModel, damper_impedance
from ..line import Span
from ._common import MAX_WIND_SPEED, _check_span
from .balance import _check_dampers, aeolian_severity
from .modal import (
    LOWEST_REDUCED_AMPLITUDE,
    aeolian_damping,
    aeolian_plant,
    cycle_field,
    limit_cycle,
)
from .self_damping import FotiMartinelli
from .self_limiting import settling_balance
from .wind import SelfDampingLaw, _curve

__all__ = ["AeolianRun", "envelope_settled", "simulate_aeolian"]

#: A line whose amplitude falls below this fraction of the wind's lowest amplitude has stopped
#: vibrating: the wind cannot sustain it (the energy balance's amplitude there comes from the
#: power curve's constant term, below the curves' data).
VANISHED = 1e-3

#: Blocks each of the settling test's three windows must hold: a few long blocks (a light
#: damping) say too little of the approach.
BLOCKS_PER_WINDOW = 10

#: Largest change of the amplitude-dependent damping's decay exponent over one block: each block
#: holds the ratios of its start, so it must be short against the amplitude's time scale.
BLOCK_EXPONENT = 0.05


@dataclass(frozen=True, eq=False)
class AeolianRun:
    """A self-limiting aeolian run (see :func:`simulate_aeolian`) against the energy balance.

    Attributes
    ----------
    wind_speed : float
        m/s.
    frequency : float
        Natural frequency of the locked-in mode (the bare line's mode nearest St V / D), Hz.
    mode : int
        That mode's number (1-based).
    amplitude : float
        Steady antinode amplitude, zero-to-peak, m: the largest of sqrt(2 mean y^2) over the
        nodes in the final window.
    balance_amplitude : float
        The energy balance's amplitude for the same span, wind and robot, m: without a robot
        :func:`aeolian_severity`'s; with one :func:`coupled_balance`'s (the robot's power from
        the line and robot coupled, on this run's plant).
    relative_error : float
        ``amplitude / balance_amplitude - 1``.
    settled : bool
        True when the amplitude's extrapolated remaining change is below ``settle_tolerance``,
        or when the vibration has died out (below :data:`VANISHED` times
        :data:`LOWEST_REDUCED_AMPLITUDE` D).
    t_envelope, envelope : ndarray
        Block start times, s, and the line's amplitude then, m: the antinode amplitude of one
        standing wave at ``frequency`` carrying the line's whole vibration energy.
    wind_power, self_damping_power, robot_power : float
        Powers measured in the final window, W per metre of span: the wind's input, the
        conductor's self-damping and the robot's damper.
    energy_residual : float
        (wind input - dissipation - energy gained) / wind input over the final window: the
        integration's energy conservation.
    robot_position : float or None
        Where the robot is parked, m (None without a robot).
    first_order_amplitude : float
        :func:`aeolian_severity`'s amplitude with the robot's first-order damper power,
        1/2 Re Z omega^2 Y^2 phi^2 / L, m (the bare balance's without a robot).
    robot_impedance_ratio : float
        ``|Z|`` of the robot at ``frequency`` over the line's wave impedance sqrt(T m) (0 without a
        robot): the first-order damper power assumes the robot leaves the standing wave as it
        is, which holds when this is small (well below 1).
    x : ndarray
        Node positions, m.
    field_amplitude : ndarray
        Steady amplitude at each node, m.
    unreachable : str or None
        Why the simulated wind cannot hold the bare line's energy balance
        (:func:`~powerline_control.severity.self_limiting.settling_balance`): the balance lies
        far below the power curve's data, where the simulated wind's damping ratio is capped,
        so ``amplitude`` settles far below ``balance_amplitude`` and ``relative_error`` measures
        that cap, not the integration. None when it can.

    Examples
    --------
    >>> from powerline_control import Span
    >>> run = simulate_aeolian(Span.at_rts_fraction(60.0, "drake", 0.2), 3.0)
    >>> run.settled, abs(run.relative_error) < 0.1
    (True, True)
    """

    wind_speed: float
    frequency: float
    mode: int
    amplitude: float
    balance_amplitude: float
    relative_error: float
    settled: bool
    t_envelope: np.ndarray = field(repr=False)
    envelope: np.ndarray = field(repr=False)
    wind_power: float = 0.0
    self_damping_power: float = 0.0
    robot_power: float = 0.0
    energy_residual: float = 0.0
    robot_position: float | None = None
    first_order_amplitude: float = 0.0
    robot_impedance_ratio: float = 0.0
    x: np.ndarray = field(default=None, repr=False)
    field_amplitude: np.ndarray = field(default=None, repr=False)
    unreachable: str | None = None


@on_one_blas_thread
def simulate_aeolian(
    span: Span,
    wind_speed: float,
    robot: MDR | None = None,
    *,
    bc: str = "clamped",
    n_elements: int | None = None,
    strouhal: float = DEFAULT_STROUHAL,
    wind_curve: str = "cigre",
    turbulence_intensity: float = 0.0,
    self_damping: str | SelfDampingLaw | FotiMartinelli = "noiseux1991",
    self_damping_k: float | None = None,
    self_damping_exponents: Sequence[float] | None = None,
    start_amplitude: float | None = None,
    settle_tolerance: float = 0.01,
    max_duration: float = 7200.0,
    samples_per_period: int = 32,
    window_periods: int = 20,
) -> AeolianRun:
    """Simulate aeolian vibration that settles by the energy balance's own powers.

    The wind and the self-damping are the functions the energy balance calls
    (:func:`wind_power`, :func:`self_damping_power`), applied as amplitude-dependent modal
    damping (the module doc gives the mapping); the robot parked at ``robot.position`` is the FE
    robot, so its power is computed, not imposed. Blocks of the exact linear flow are chained,
    each short enough that the amplitude-dependent ratios change its decay by at most
    :data:`BLOCK_EXPONENT`; the run stops when the amplitude's extrapolated remaining change
    (Aitken's, over the envelope's time means in three windows) is below ``settle_tolerance``, or at
    ``max_duration`` with a warning. A final window of ``window_periods`` periods sampled
    ``samples_per_period`` times a period measures the amplitude and the three powers.

    Parameters
    ----------
    span : Span
        The line.
    wind_speed : float
        m/s, in (0, 30].
    robot : MDR or None
        The robot, parked at its position (None: the bare line).
    bc : {"clamped", "pinned"}
        Supports.
    n_elements : int or None
        FE mesh (None: the mesh that resolves the aeolian band).
    strouhal, wind_curve, turbulence_intensity, self_damping, self_damping_k, \
self_damping_exponents
        As in :func:`aeolian_severity`.
    start_amplitude : float or None
        Antinode amplitude of the locked mode at the start, m (default: half the energy
        balance's amplitude without the robot, so the run approaches the steady state from
        below).
    settle_tolerance : float
        Relative distance to the steady amplitude at which the run stops, in (0, 0.5].
    max_duration : float
        Longest simulated time, s (> 0).
    samples_per_period : int
        Samples a period in the final window, 8-1024.
    window_periods : int
        Periods in the final window, 2-10000.

    Returns
    -------
    AeolianRun

    Raises
    ------
    InputError
        For bad arguments, a robot that is not an MDR, or a wind whose energy balance leaves the
        power curve's data (name another ``wind_curve``).

    Warns
    -----
    TruncationWarning
        When the run reaches ``max_duration`` before it settles (a very light damping: a low
        wind on a long span); the result then has ``settled=False``. And when the simulated
        wind cannot hold the energy balance at all (its reason in the result's
        ``unreachable``): the run then settles far below the balance.

    Examples
    --------
    >>> from powerline_control import Span
    >>> run = simulate_aeolian(Span.at_rts_fraction(60.0, "drake", 0.2), 3.0)
    >>> round(run.amplitude / run.balance_amplitude, 2)
    1.0
    """
    span = _check_span(span)
    speed = check_real("wind_speed", wind_speed, low=0.0, high=MAX_WIND_SPEED)
    if robot is not None and not isinstance(robot, MDR):
        raise InputError("The 'robot' parameter of simulate_aeolian must be an MDR or None. Got "
                         f"{type(robot).__name__}.")
    tolerance = check_real("settle_tolerance", settle_tolerance, low=0.0, high=0.5,
                           high_inclusive=True)
    max_duration = check_real("max_duration", max_duration, low=0.0)
    per_period = int(check_real("samples_per_period", samples_per_period, low=8,
                                low_inclusive=True, high=1024, high_inclusive=True))
    n_window = int(check_real("window_periods", window_periods, low=2, low_inclusive=True,
                              high=10000, high_inclusive=True))
    dampers = () if robot is None else (robot,)
    _check_dampers(dampers, span)
    powers = {"wind_curve": wind_curve, "turbulence_intensity": turbulence_intensity}
    law = {"self_damping": self_damping, "self_damping_k": self_damping_k,
           "self_damping_exponents": self_damping_exponents}
    balance = aeolian_severity(span, [speed], dampers, strouhal=strouhal, bc=bc, **powers, **law)
    if balance.status[0] == "above curve range":
        raise InputError(
            f"The 'wind_speed' {speed:g} m/s drives the span past the {wind_curve!r} power "
            f"curve's data (Y/D > {_curve(wind_curve).max_reduced_amplitude:g}): the steady "
            "amplitude is unknown. Choose a wind_curve whose data reach further.")
    _, unreachable = settling_balance(span, AeolianForce(speed, strouhal=strouhal), bc,
                                      {**powers, **law})
    if unreachable is not None:
        warnings.warn(f"simulate_aeolian: the wind at {speed:g} m/s {unreachable}.",
                      TruncationWarning, stacklevel=2)
    if start_amplitude is None:
        bare_balance = balance if robot is None else aeolian_severity(
            span, [speed], strouhal=strouhal, bc=bc, **powers, **law)
        start = 0.5 * float(bare_balance.amplitude[0])
        if start <= 0:
            start = LOWEST_REDUCED_AMPLITUDE * span.conductor.diameter
    else:
        start = check_real("start_amplitude", start_amplitude, low=0.0,
                           high=span.conductor.diameter * _curve(wind_curve).max_reduced_amplitude,
                           high_inclusive=True)

    cond = span.conductor
    shedding = strouhal * speed / cond.diameter
    bare = LineModel(span, n_elements, bc=bc)
    plant, band_modes = aeolian_plant(bare, robot, shedding, 1.0 / (per_period * shedding))
    # the wind's and the self-damping's modal damping at the state's amplitudes: the one home
    # of that mapping (the closed loop's self-limiting plant calls it too)
    damping = aeolian_damping(plant, span, speed, strouhal=strouhal, **powers, **law)
    locked, frequency = damping.locked, damping.frequency
    mode_number = int(band_modes[locked]) + 1
    reference = float(balance.amplitude[0])
    if robot is not None:
        # the balance with the robot: its power from the line and robot coupled, not the
        # first-order formula
        reference = float(cycle_field(plant, limit_cycle(plant, damping, robot.position)[1])
                          .max())
    position = None if robot is None else robot.position
    floor = LOWEST_REDUCED_AMPLITUDE * cond.diameter
    line_amplitude = damping.line_amplitude
    band, mass = damping.band, cond.mass_per_length

    def line_damping(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Modal damping (r, r) and its (own, wind) coefficients at the state's amplitudes."""
        own, wind = damping.coefficients(z)
        return damping.matrix(z, (own, wind)), own, wind

    z = damping.start_state(plant, start)
    # (time, amplitude) at each block's start, grown by doubling: the settling test reads the
    # whole history at every block, as arrays
    history, n = np.empty((2, 256)), 0
    t, settled, observed = 0.0, False, 0.0
    energy = plant.energy(z, position)
    while t < max_duration:
        if n == history.shape[1]:
            history = np.hstack([history, np.empty_like(history)])
        history[:, n] = t, line_amplitude(z)
        n += 1
        times, envelope = history[0, :n], history[1, :n]
        if envelope_settled(times, envelope, tolerance) or envelope[-1] < VANISHED * floor:
            settled = True
            break
        matrix, own, wind = line_damping(z)
        # the amplitude's own rate, 1/s: the ratios' and what the last block showed of the
        # total energy (the robot's damping is in the exact flow, but it moves the amplitudes
        # the ratios follow; the line's own energy alone beats with the absorber's)
        rate = max(abs(wind), float(own[locked]), 1e-12) / 2
        step = min(BLOCK_EXPONENT / max(rate, observed), max_duration - t)
        step = max(step, 1.0 / frequency)
        z = _flow(plant.state_matrix(position, matrix), step, z)
        t += step
        energy, before = plant.energy(z, position), energy
        observed = abs(math.log(max(energy, 1e-300) / max(before, 1e-300))) / (2 * step)
    if not settled:
        warnings.warn(
            f"simulate_aeolian: at {speed:g} m/s the amplitude had not settled within "
            f"'max_duration'={max_duration:g} s (last {envelope[-1]:.3g} m, energy balance "
            f"{float(balance.amplitude[0]):.3g} m): the damping is very light. Raise "
            "max_duration or start_amplitude nearer the balance.", TruncationWarning,
            stacklevel=2)

    # ---- the final window: amplitude and powers, sampled, the ratios held at its start
    matrix, own, wind = line_damping(z)
    dt = 1.0 / (per_period * frequency)
    phi = scipy.linalg.expm(plant.state_matrix(position, matrix) * dt)
    n_samples = per_period * n_window + 1
    states = np.empty((n_samples, z.size))
    states[0] = z
    for k in range(1, n_samples):
        states[k] = phi @ states[k - 1]
    velocities = states[:, plant.n_q:]
    _, robot_damping, _ = plant.matrices(position, np.zeros((plant.r, plant.r)))

    def mean_power(quadratic: np.ndarray) -> float:
        values = np.einsum("ki,ij,kj->k", velocities, quadratic, velocities)
        return float(trapezoid(values, dx=dt) / (dt * (n_samples - 1)))

    own_matrix = np.zeros((plant.n_q, plant.n_q))
    own_matrix[:band, :band] = np.diag(own)
    wind_matrix = np.zeros((plant.n_q, plant.n_q))
    wind_matrix[locked, locked] = -wind
    p_wind, p_self = mean_power(wind_matrix), mean_power(own_matrix)
    p_robot = mean_power(robot_damping)
    gained = (plant.energy(states[-1], position) - plant.energy(states[0], position)) \
        / (dt * (n_samples - 1))
    residual = (p_wind - p_self - p_robot - gained) / p_wind if p_wind > 0 else 0.0
    field_amplitude = np.sqrt(2 * np.mean((states[:, :plant.r] @ plant.nodal.T) ** 2, axis=0))
    amplitude = float(field_amplitude.max())
    return AeolianRun(
        wind_speed=speed, frequency=frequency, mode=mode_number,
        amplitude=amplitude, balance_amplitude=reference,
        relative_error=amplitude / reference - 1 if reference > 0 else math.inf,
        settled=settled, t_envelope=read_only(times.copy()),
        envelope=read_only(envelope.copy()), wind_power=p_wind / span.length,
        self_damping_power=p_self / span.length, robot_power=p_robot / span.length,
        energy_residual=float(residual), robot_position=position,
        first_order_amplitude=float(balance.amplitude[0]),
        robot_impedance_ratio=0.0 if robot is None else abs(damper_impedance(robot, frequency))
        / math.sqrt(span.tension * mass), x=read_only(bare.node_positions.copy()),
        field_amplitude=read_only(field_amplitude), unreachable=unreachable)


def _flow(a: np.ndarray, duration: float, z: np.ndarray) -> np.ndarray:
    """exp(A duration) z through A's eigenvectors: one eigen-solve, where expm of a block many
    periods long needs many squarings of the whole matrix."""
    eigenvalues, vectors = np.linalg.eig(a)
    return np.real(vectors @ (np.exp(eigenvalues * duration) * np.linalg.solve(vectors, z)))


def envelope_settled(times: np.ndarray, envelope: np.ndarray, tolerance: float, *,
                     converging: bool = False) -> bool:
    """Whether an amplitude history has settled: Aitken's extrapolation of its approach.

    The envelope's time means over the last three quarters of the history, in three equal
    windows, extrapolated as a geometric approach to the steady amplitude: settled when the
    remaining change, relative to the last mean, is at most ``tolerance`` (and both windows'
    changes are too). Means, not samples: where the robot's absorber exchanges energy with the
    line, the amplitude at one instant carries the beat. Each window needs
    :data:`BLOCKS_PER_WINDOW` samples.

    Parameters
    ----------
    times : ndarray
        Ascending sample times, s.
    envelope : ndarray
        The amplitude at those times.
    tolerance : float
        Largest relative remaining change of a settled history.
    converging : bool
        Also require a settled look over the history itself: a second window that changes as
        much as the first, or more (an accelerating fall, where the extrapolation means
        nothing), by more than a tenth of ``tolerance``, or a change over the three windows
        of more than a quarter of ``tolerance`` (a history short against the approach's time
        scale sees a nearly straight fall, whose extrapolation understates what remains),
        has not settled; one that moves by less than a hundredth of ``tolerance`` over the
        three windows has (a drift that slow defeats the extrapolation, which divides by the
        difference of two nearly equal changes). False (simulate_aeolian's runs, which stop at
        the first block that settles, with the whole approach in view): the extrapolation
        alone.

    Returns
    -------
    bool

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0.0, 20.0, 201)
    >>> envelope_settled(t, 1 + np.exp(-t), 0.01), envelope_settled(t, 1 + np.exp(-t / 20), 0.01)
    (True, False)
    """
    if envelope.size < 3 * BLOCKS_PER_WINDOW:
        return False
    t, y = times, envelope
    edges = t[0] + (t[-1] - t[0]) * np.array([0.25, 0.5, 0.75, 1.0])
    means = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = (t >= lo) & (t <= hi)
        if np.count_nonzero(inside) < BLOCKS_PER_WINDOW:
            return False
        means.append(float(trapezoid(y[inside], t[inside]) / (t[inside][-1] - t[inside][0])))
    y1, y2, y3 = means
    if y3 <= 0:
        return False
    d1, d2 = y2 - y1, y3 - y2
    if converging:
        if abs(y3 - y1) <= 0.01 * tolerance * y3:
            return True
        if (abs(d2) >= abs(d1) and abs(d2) > 0.1 * tolerance * y3) \
                or abs(y3 - y1) > 0.25 * tolerance * y3:
            return False
    if max(abs(d1), abs(d2)) > tolerance * y3:   # both windows still: no fast transient left
        return False
    denominator = d2 - d1
    remaining = d2 if denominator == 0 else -d2 * d2 / denominator
    return abs(remaining) <= tolerance * y3
