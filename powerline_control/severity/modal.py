"""The energy balance's powers as the modal damping of the line's plant, and the steady
vibration they leave with the robot coupled to the line, as a limit cycle.

In lock-in the wind's lift follows the conductor's velocity: it is a negative damping whose
power at antinode amplitude Y is the power curve's P_w(Y); the conductor's self-damping is a
positive damping whose power is the self-damping law's P_c(Y). For a standing wave
y = Y sin(beta x) sin(omega t), a uniform viscous damping c = 2 zeta m omega per metre takes
zeta m omega^3 Y^2 / 2 per metre, so each power is a modal damping ratio

    zeta(Y) = 2 P(Y) / (m omega^3 Y^2)

(the mapping :func:`~powerline_control.severity.time_domain_check` uses).
:class:`AeolianDamping` applies it to the plant of :func:`aeolian_plant` (the line's modes near
the tone, the robot parked): the wind on the mode locked to the Strouhal frequency, the
self-damping on every mode at its own amplitude. The time-domain run
(:func:`~.aeolian_run.simulate_aeolian`), the self-limiting record and the closed loop's
self-limiting line step that plant; :func:`coupled_cycle` finds its steady state directly.

The energy balance's damper power, 1/2 Re Z omega^2 Y^2 phi^2 / L
(:func:`~powerline_control.severity.damper_power`), is first order: it assumes the damper leaves
the standing wave as it is. The robot's impedance on a real span is many times the line's wave
impedance sqrt(T m) (Drake 300 m with a 3 kg absorber: 12x), so it reshapes the wave where it
sits and takes far less power per unit amplitude than the formula says (the time-domain runs
settle 3-12x above the formula's amplitude). :func:`coupled_cycle` damps the plant with the
robot parked by the same powers, and the steady amplitude is the one at which the coupled mode
the wind feeds neither grows nor decays: its eigenvalue lies on the imaginary axis. Over one
cycle of that mode the wind's input equals what the self-damping and the robot take (for M, C, K
symmetric, u^H (lambda^2 M + lambda C + K) u = 0 at lambda = i omega leaves omega u^H C u = 0),
so this is the energy balance with the robot's power computed, not imposed. It needs one small
eigenproblem per trial amplitude, where the time-domain run integrates the approach to the same
state.
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
from ..excitation import DEFAULT_STROUHAL, HarmonicForce
from ..fem import MDR, AtAntinode, LineModel, damper_impedance
from ..line import Span
from ..simulation.plant import ModalPlant, default_modes
from ._common import MAX_WIND_SPEED
from .self_damping import FotiMartinelli
from .wind import SelfDampingLaw, _curve, _resolve_law, wind_power

# coupled_cycle is the balance's and coupled_balance's shared step, not a name of its own
__all__ = ["AeolianDamping", "CoupledBalance", "aeolian_damping", "aeolian_plant",
           "power_ratio"]

#: The wind's negative damping is evaluated at no less than this reduced amplitude Y/D: the
#: CIGRE cubic's constant term gives the wind a finite power at Y = 0 (which the energy balance
#: uses as it is), hence an infinite ratio zeta_w at rest.
LOWEST_REDUCED_AMPLITUDE = 1e-3

#: Modes kept on a long span: natural frequencies within this fraction of St V / D, with the
#: robot's Ritz vector for the rest (Drake 300 m, robot at an antinode: the amplitude moves
#: 0.7 % from +-10 % to the closed loop's 0.6-1.4 band).
MODE_BAND = 0.1

#: Largest negative damping ratio the wind is given: far below the curves' data (Y/D < 0.01)
#: the CIGRE cubic's constant term makes zeta_w grow as 1 / Y^2, past critical damping on a
#: light conductor at high frequency, where a damping ratio no longer describes a lift.
MAX_WIND_RATIO = 0.1

#: A band mode whose antinode amplitude is below this fraction of the conductor's diameter is
#: given no self-damping: its ratio grows as Y^(a - 2) with the laws' a > 2 (1e-5 of its value at
#: Y ~ D for Noiseux's 2.44), and at such amplitudes P_c / Y^2 is 0 / 0 once Y^2 underflows (a
#: mode the line has not yet fed, on a 372 m Condor span, stopped simulate_aeolian
#: with NaN).
QUIESCENT = 1e-12

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

#: The plant's samples per period (it is only diagonalised here, never stepped).
SAMPLES_PER_PERIOD = 32

#: Iterations of the shape allowed before the amplitude is refused as not converged.
MAX_SHAPE_ITERATIONS = 100


def power_ratio(power: float, mass: float, omega: float, amplitude: float) -> float:
    """zeta = 2 P / (m omega^3 Y^2): the modal damping ratio of a standing wave of antinode
    amplitude ``amplitude`` (m) at ``omega`` (rad/s) on a line of ``mass`` kg/m that takes (or,
    for the wind, gives) ``power`` W/m (the module doc).

    Examples
    --------
    >>> round(power_ratio(0.01, 1.628, 2 * math.pi * 19.7, 0.008), 7)   # Drake, 8 mm at 19.7 Hz
    0.0001012
    """
    return 2.0 * power / (mass * omega**3 * amplitude**2)


@dataclass(frozen=True, eq=False)
class AeolianDamping:
    """The self-limiting wind and the conductor's self-damping as the modal damping of a plant.

    Built by :func:`aeolian_damping` for a :class:`~powerline_control.simulation.plant.ModalPlant`
    (state z = (q, y, q', y'): the basis' coordinates, the robot's absorber if any, their
    rates). :meth:`matrix` turns the state into the line's modal damping (r, r): each band mode's
    self-damping 2 zeta_c omega at its own antinode amplitude, and the wind's negative
    -2 zeta_w omega on the locked mode at its own (zeta = 2 P / (m omega^3 Y^2), the module
    doc). :func:`simulate_aeolian` and the closed loop's self-limiting plant both call it: the
    one home of that mapping.

    Attributes
    ----------
    span : Span
        The line (conductor, tension, length).
    omega : ndarray
        The plant's band modes' natural circular frequencies, rad/s.
    peak : ndarray
        Each band mode's largest nodal displacement per unit modal coordinate (its antinode).
    locked : int
        Index (in the band) of the mode the wind locks into: the one nearest St V / D.
    n_q : int
        The plant's coordinates (the band, the Ritz vectors, the absorber).
    r : int
        The plant's basis size (band and Ritz vectors).
    law : SelfDampingLaw or FotiMartinelli
        The conductor's self-damping, resolved.
    wind_curve : str
        The power curve's name.
    turbulence_intensity : float
        Iv (the power curve's reduction).

    Examples
    --------
    >>> from powerline_control import LineModel, Span
    >>> from powerline_control.simulation.plant import ModalPlant
    >>> span = Span.at_rts_fraction(60.0, "drake", 0.2)
    >>> plant = ModalPlant(LineModel(span), None, 24, dt=1e-3)
    >>> damping = aeolian_damping(plant, span, 3.0)
    >>> z = damping.start_state(plant, 0.005)          # the locked mode at 5 mm
    >>> round(float(damping.amplitudes(z)[damping.locked]) * 1e3, 3)
    5.0
    >>> bool(damping.matrix(z)[damping.locked, damping.locked] < 0)   # the wind feeds it
    True
    """

    span: Span
    omega: np.ndarray = field(repr=False)
    peak: np.ndarray = field(repr=False)
    locked: int
    n_q: int
    r: int
    law: object = field(repr=False)
    wind_curve: str = "cigre"
    turbulence_intensity: float = 0.0

    @property
    def frequency(self) -> float:
        """The locked mode's natural frequency, Hz."""
        return float(self.omega[self.locked] / (2 * math.pi))

    @property
    def band(self) -> int:
        """The band's modes (the first ``band`` plant coordinates)."""
        return self.omega.size

    def amplitudes(self, z: np.ndarray) -> np.ndarray:
        """Each band mode's antinode amplitude from its energy, m (smooth where the robot's
        absorber exchanges energy with the line; exact for a free mode)."""
        q, v = z[: self.band], z[self.n_q : self.n_q + self.band]
        return self.peak * np.sqrt(q**2 + (v / self.omega) ** 2)

    def line_amplitude(self, z: np.ndarray) -> float | np.ndarray:
        """The antinode amplitude of one standing wave at the locked frequency carrying the
        band's whole vibration energy, E = m omega^2 Y^2 L / 4, m (one per row of a 2-D z)."""
        q, v = z[..., : self.band], z[..., self.n_q : self.n_q + self.band]
        energy = 0.5 * np.sum(v**2 + self.omega**2 * q**2, axis=-1)
        amplitude = np.sqrt(4 * energy / (self.span.conductor.mass_per_length
                                          * self.omega[self.locked] ** 2 * self.span.length))
        return float(amplitude) if np.ndim(amplitude) == 0 else amplitude

    def coefficients(self, z: np.ndarray) -> tuple[np.ndarray, float]:
        """(own, wind): each band mode's self-damping coefficient 2 zeta_c omega (band,) and the
        wind's -2 zeta_w omega on the locked mode (<= 0), 1/s, at the state's amplitudes."""
        y = self.amplitudes(z)
        cond = self.span.conductor
        mass = cond.mass_per_length
        own = np.zeros(self.band)
        for i in np.flatnonzero(y > QUIESCENT * cond.diameter):
            p_c = float(self.law.power(y[i], self.omega[i] / (2 * math.pi), self.span))
            own[i] = 2 * power_ratio(p_c, mass, self.omega[i], y[i]) * self.omega[i]
        curve = _curve(self.wind_curve)
        y_wind = min(max(y[self.locked], LOWEST_REDUCED_AMPLITUDE * cond.diameter),
                     curve.max_reduced_amplitude * cond.diameter)
        p_w = float(wind_power(y_wind, self.frequency, cond.diameter,
                               wind_curve=self.wind_curve,
                               turbulence_intensity=self.turbulence_intensity))
        omega = self.omega[self.locked]
        wind = -2 * min(power_ratio(p_w, mass, omega, y_wind), MAX_WIND_RATIO) * omega
        return own, wind

    def matrix(self, z: np.ndarray, coefficients: tuple | None = None) -> np.ndarray:
        """The line's modal damping (r, r) at state z (or of given :meth:`coefficients`)."""
        own, wind = self.coefficients(z) if coefficients is None else coefficients
        matrix = np.zeros((self.r, self.r))
        matrix[: self.band, : self.band] = np.diag(own)
        matrix[self.locked, self.locked] += wind
        return matrix

    def start_state(self, plant: ModalPlant, amplitude: float) -> np.ndarray:
        """The plant's state (2 n_q,) with the locked mode at antinode ``amplitude`` (m), at
        rest at its largest displacement, every other coordinate zero."""
        z = np.zeros(2 * plant.n_q)
        z[self.locked] = amplitude / self.peak[self.locked]
        return z


def aeolian_damping(plant: ModalPlant, span: Span, wind_speed: float, *,
                    strouhal: float = DEFAULT_STROUHAL, wind_curve: str = "cigre",
                    turbulence_intensity: float = 0.0,
                    self_damping: str | SelfDampingLaw | FotiMartinelli = "noiseux1991",
                    self_damping_k: float | None = None,
                    self_damping_exponents: Sequence[float] | None = None) -> AeolianDamping:
    """The self-limiting wind's and the self-damping's modal damping of ``plant``.

    The wind locks into the plant's band mode nearest St V / D; the self-damping law is resolved
    once (its argument checks, repeated for every mode at every block, took half a run).

    Parameters
    ----------
    plant : ModalPlant
        The line's modal plant (its first ``n_band`` coordinates are bare eigenmodes).
    span : Span
        The line.
    wind_speed : float
        m/s.
    strouhal, wind_curve, turbulence_intensity, self_damping, self_damping_k, \
self_damping_exponents
        As in :func:`aeolian_severity`.

    Returns
    -------
    AeolianDamping

    Examples
    --------
    >>> from powerline_control import LineModel, Span
    >>> from powerline_control.simulation.plant import ModalPlant
    >>> span = Span.at_rts_fraction(60.0, "drake", 0.2)
    >>> damping = aeolian_damping(ModalPlant(LineModel(span), None, 24, dt=1e-3), span, 3.0)
    >>> round(damping.frequency, 1)      # St V / D = 0.185 * 3 / 0.02814 = 19.7 Hz
    19.7
    """
    speed = check_real("wind_speed", wind_speed, low=0.0, high=MAX_WIND_SPEED)
    _curve(wind_curve)   # an unknown curve is refused here, not at the first block
    check_real("turbulence_intensity", turbulence_intensity, low=0.0, low_inclusive=True)
    band = plant.n_band
    omega = np.sqrt(plant.omega2[:band])
    shedding = strouhal * speed / span.conductor.diameter
    return AeolianDamping(
        span=span, omega=read_only(omega),
        peak=read_only(np.max(np.abs(plant.nodal[:, :band]), axis=0)),
        locked=int(np.argmin(np.abs(omega / (2 * math.pi) - shedding))), n_q=plant.n_q,
        r=plant.r, law=_resolve_law(self_damping, self_damping_k, self_damping_exponents),
        wind_curve=wind_curve, turbulence_intensity=float(turbulence_intensity))


def aeolian_plant(bare: LineModel, robot: MDR | None, shedding: float,
                  dt: float) -> tuple[ModalPlant, np.ndarray]:
    """The self-limiting wind's modal plant of the bare line with the robot parked, and its modes.

    The modes: every mode below 8x the shedding frequency on a short span (the plant's
    :func:`~powerline_control.simulation.plant.default_modes`), those within :data:`MODE_BAND`
    of it on a long one; with a robot, its point force's Ritz vector, which carries what the
    kept modes miss of the line's flexibility there. :func:`simulate_aeolian`, the
    self-limiting record (:func:`~.aeolian_record.simulate_self_limiting`) and the coupled
    balance (:func:`~.coupled.coupled_balance`) all build it here.

    Parameters
    ----------
    bare : LineModel
        The line without the robot.
    robot : MDR or None
        The robot, parked at its position.
    shedding : float
        The vortex-shedding frequency St V / D, Hz.
    dt : float
        The plant's sample interval, s.

    Returns
    -------
    (ModalPlant, ndarray)
        The plant and the 0-based indices of the bare modes in its band.

    Examples
    --------
    >>> from powerline_control import LineModel, Span
    >>> bare = LineModel(Span.at_rts_fraction(60.0, "drake", 0.2), bc="pinned")
    >>> plant, band = aeolian_plant(bare, None, 19.7, 1e-3)
    >>> plant.n_band == band.size == plant.r          # no robot: no Ritz vector
    True
    """
    span = bare.span
    modes = default_modes(span, bare, [shedding], 1.0 / (8 * shedding))
    if np.ndim(modes):
        # a long span: the modes near the tone (the plant's band is wider, for moving loads)
        estimate = span.pinned_frequencies(bare.n_dofs)
        near = np.flatnonzero(np.abs(estimate / shedding - 1) <= MODE_BAND)
        modes = near if near.size else modes
    loads = () if robot is None else (HarmonicForce(1.0, shedding, robot.position),)
    band = np.arange(modes) if np.ndim(modes) == 0 else np.asarray(modes)
    return ModalPlant(bare, robot, modes, dt=dt, loads=loads), band


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
        :func:`~.balance.aeolian_severity`'s amplitude for the same robot at the same position,
        with the first-order damper power, m (NaN from :func:`coupled_cycle`, which does not
        compute it).
    robot_impedance_ratio : float
        The robot's ``|Z|`` at the limit cycle's frequency over the line's wave impedance
        sqrt(T m): where it is small the first-order power holds.
    x, field_amplitude : ndarray
        Node positions, m, and the limit cycle's amplitude at each, m.

    Examples
    --------
    >>> from powerline_control import Span
    >>> from powerline_control.severity import coupled_balance
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
    robot_impedance_ratio: float
    x: np.ndarray = field(repr=False)
    field_amplitude: np.ndarray = field(repr=False)
    first_order_amplitude: float = math.nan


@dataclass(frozen=True, eq=False)
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


def coupled_robot(robot: object, parameter: str, fix: str) -> MDR | None:
    """The MDR a coupled balance parks (``robot``: an MDR, ``AtAntinode(MDR)`` with factor 1, or
    None), refused with an InputError naming ``parameter`` otherwise (``fix``: what else to
    use). Its position is checked by the caller, who knows the span."""
    device = robot.damper if isinstance(robot, AtAntinode) else robot
    factor = robot.factor if isinstance(robot, AtAntinode) else 1.0
    if device is not None and not isinstance(device, MDR) or factor != 1.0:
        raise InputError(
            f"The '{parameter}' parameter of the coupled balance must be an MDR, AtAntinode(MDR) "
            "with factor 1 (the robot at the antinode) or None: the coupled model parks the "
            "robot's masses, spring and dashpot on the FE line. Got "
            f"{type(device).__name__}" + (f" with factor {factor:g}" if factor != 1.0 else "")
            + f": {fix}.")
    return device


def coupled_cycle(span: Span, speed: float, robot, *, bc: str = "clamped",
                  n_elements: int | None = None, strouhal: float = DEFAULT_STROUHAL,
                  wind_curve: str = "cigre", turbulence_intensity: float = 0.0,
                  self_damping: str | SelfDampingLaw | FotiMartinelli = "noiseux1991",
                  self_damping_k: float | None = None,
                  self_damping_exponents: Sequence[float] | None = None) -> CoupledBalance:
    """The limit cycle of the line with the robot (an MDR parked, ``AtAntinode(MDR)`` at the
    locked mode's antinode nearest its position, or None) in the energy balance's powers: a
    :class:`CoupledBalance` without its first-order amplitude (NaN). Arguments as
    :func:`~.coupled.coupled_balance`'s, checked by the caller.

    Examples
    --------
    >>> from powerline_control import Span
    >>> cycle = coupled_cycle(Span.at_rts_fraction(60.0, "drake", 0.2), 3.0, None, bc="pinned")
    >>> cycle.status, round(cycle.amplitude * 1e3, 1)
    ('balanced', 8.6)
    """
    at_antinode = isinstance(robot, AtAntinode)
    device = robot.damper if at_antinode else robot
    powers = {"wind_curve": wind_curve, "turbulence_intensity": turbulence_intensity,
              "self_damping": self_damping, "self_damping_k": self_damping_k,
              "self_damping_exponents": self_damping_exponents}
    bare = LineModel(span, n_elements, bc=bc)
    shedding = strouhal * speed / span.conductor.diameter
    dt = 1.0 / (SAMPLES_PER_PERIOD * shedding)    # the plant's sampling: unused by eigenvalues
    if at_antinode:
        # the antinode is the bare band's (the same modes with or without the robot); the
        # robot's Ritz vector (the flexibility the band misses where it sits) is built there
        free, _ = aeolian_plant(bare, None, shedding, dt)
        locked = aeolian_damping(free, span, speed, strouhal=strouhal, **powers).locked
        device = dataclasses.replace(device,
                                     position=_antinode_near(free, locked, device.position))
    plant, band_modes = aeolian_plant(bare, device, shedding, dt)
    damping = aeolian_damping(plant, span, speed, strouhal=strouhal, **powers)
    position = None if device is None else float(device.position)
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
        / math.sqrt(span.tension * span.conductor.mass_per_length)
    return CoupledBalance(
        wind_speed=speed, status=status, amplitude=float(field_amplitude.max()),
        frequency=float(frequency), mode=int(band_modes[damping.locked]) + 1,
        robot_position=position,
        wind_power=float(p_wind), self_damping_power=float(p_self),
        robot_power=float(p_robot), energy_residual=float(residual),
        robot_impedance_ratio=float(ratio), x=read_only(bare.node_positions.copy()),
        field_amplitude=read_only(field_amplitude))
