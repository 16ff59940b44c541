"""Where the robot goes: the robot-free excited shape, the predicted best parked position.

Chasing the antinode of the field the robot is damping is unstable: the damped loop's maximum
moves away from the robot. The robot targets something its damping does not move. From the
sensors' and its own motion's phasors at the dominant frequency it removes its own reaction with
the bare line's receptance,

    W_bare(x) = W(x) - H(x, x_r; omega) D_r(omega) W_r,
    D_r = omega^2 m_b + omega^2 m_a (k + i omega c) / (k + i omega c - omega^2 m_a),

(the robot-free excited shape, fitted on the bare modes), which in steady state is the same
wherever the robot is; then it predicts the span's RMS with itself parked at every p,
``W_p = W_bare + H(., p) D_r W_bare(p) / (1 - H(p, p) D_r)``, and goes to the best it can reach
(docs/closed_loop.md). In the self-limiting wind it ranks the positions by the absorber's
coupling to that robot-free standing wave instead (:data:`OBJECTIVES`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from .._spectral import dominant_frequency, fit_phasors
from .._validation import check_array, check_bare_line, check_choice, check_real, read_only
from ..errors import InputError
from ..fem import MDR, LineModel
from ..plan import RobotLimits, free_interval
from ..simulation.plant import ModalPlant, default_modes, robot_dynamic_stiffness
from .policy_settings import PolicySettings, checked_policy

# Every number the policy decides by is a field of PolicySettings (policy_settings.py), with
# its value, what it guards and the evidence for it; the functions below take the settings and
# default to the tuned ones.
DEFAULT_POLICY = PolicySettings()


def kernel_shape(plant, sensor_rows, sensed, robot, x_r, at_robot, omega,
                 settings: PolicySettings = DEFAULT_POLICY):
    """Robot-free excited shape at every node from the sensors' and the robot's phasors.

    The robot's reaction ``D_r W_r`` is removed from every measurement with the bare line's
    receptance; the robot-free shape is then the posterior mean of a Gaussian prior over the bare
    modal amplitudes with variance ``1 / |omega_n^2 - omega^2 + i omega z_n|^2`` (what a load
    spread evenly over the modes would drive): near a resonance it is that mode, fitted; between
    two, the mix the few measurements support. The prior's damping floor and the fit's ridge are
    ``settings.prior_damping_floor`` and ``settings.prior_regularization``.
    """
    n_r = plant.coupling(x_r)
    rows = np.vstack([sensor_rows, n_r])  # (p + 1, r)
    values = np.append(sensed, at_robot)
    reaction = robot_dynamic_stiffness(robot, omega) * at_robot
    values = values - rows @ plant.modal_response(n_r, omega) * reaction
    # A floor of damping (0.1 %) keeps the prior finite on an undamped line at resonance.
    floor = 2 * settings.prior_damping_floor * np.sqrt(plant.omega2) * omega
    variance = 1.0 / (np.abs(plant.omega2 - omega**2) ** 2 + floor**2)
    gram = (rows * variance) @ rows.T
    gram = gram + settings.prior_regularization * np.trace(gram) / gram.shape[0] * np.eye(
        gram.shape[0])
    return (plant.nodal * variance) @ (rows.T @ np.linalg.solve(gram, values))


def predicted_rms(bare_shape, plant, robot, omega, positions, weights):
    """RMS over the span, in steady state, with the robot parked at each of ``positions``.

    With one point attachment the parked field follows from the robot-free one exactly:
    ``W_p = W_bare + H(., p) D_r W_p(p)`` and ``W_p(p) = W_bare(p) / (1 - H(p, p) D_r)``,
    so only the bare line's receptance is needed (no modal force is inverted from the estimate).
    The receptances of a block of positions are one matrix product.
    """
    positions = np.asarray(positions, dtype=float).ravel()
    out = np.empty(positions.size)
    if not positions.size:
        return out
    # blocks of 256 positions keep the (n_nodes, block) complex fields small on long spans
    for block in np.array_split(np.arange(positions.size), -(-positions.size // 256)):
        response, gain = _parked_reaction(bare_shape, plant, robot, omega, positions[block])
        fields = bare_shape[:, None] + (plant.nodal @ response) * gain
        out[block] = np.sqrt(0.5 * weights @ np.abs(fields) ** 2)
    return out


def _interpolated(shape: np.ndarray, x: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """A complex nodal shape at ``positions`` (linear between the nodes ``x``)."""
    return np.interp(positions, x, shape.real) + 1j * np.interp(positions, x, shape.imag)


def _parked_reaction(bare_shape, plant, robot, omega, positions):
    """(modal response to a unit force at each position (r, b), the robot's force there (b,)):
    the parked field is ``W_bare + nodal @ response * gain`` (:func:`predicted_rms`)."""
    reaction = robot_dynamic_stiffness(robot, omega)
    w_bare = _interpolated(bare_shape, plant.model.node_positions, positions)
    couplings = np.stack([plant.coupling(p) for p in positions], axis=1)  # (r, b)
    response = plant.modal_response(couplings, omega)
    at_robot = np.einsum("ij,ij->j", couplings, response)
    return response, reaction * w_bare / (1 - at_robot * reaction)


def predicted_sensors(bare_shape, plant, robot, omega, position, sensor_positions, sensor_rows):
    """The sensors' phasors predicted with the robot parked at ``position`` (the parked field of
    :func:`predicted_rms` at the sensors): what the robot checks a move against once the line
    has settled there."""
    response, gain = _parked_reaction(bare_shape, plant, robot, omega, np.array([position]))
    at_sensors = _interpolated(bare_shape, plant.model.node_positions,
                               np.asarray(sensor_positions, dtype=float))
    return at_sensors + (sensor_rows @ response)[:, 0] * gain[0]


@dataclass(frozen=True, eq=False)
class Choice:
    """The predicted best parked position within reach, and what it was chosen from.

    Attributes
    ----------
    position : float
        Where to park, m.
    grid : ndarray
        The candidate positions (the free interval), m.
    predicted : ndarray
        Predicted steady-state span RMS with the robot parked at each candidate, m (with
        ``objective="antinode"``: :func:`inverse_coupling`, dimensionless).
    predicted_here : float
        The same with the robot parked where it is.
    objective : str
        What the prediction is (:data:`OBJECTIVES`).

    Examples
    --------
    >>> import numpy as np
    >>> choice = Choice(0.6, np.array([0.6, 1.8]), np.array([2e-4, 3e-4]), 1e-3)
    >>> round(choice.gain, 2)
    0.8
    """

    position: float
    grid: np.ndarray = field(repr=False)
    predicted: np.ndarray = field(repr=False)
    predicted_here: float
    objective: str = "response"

    @property
    def gain(self) -> float:
        """Predicted relative drop of the figure by moving there (0: none): of the span's RMS,
        or (``objective="antinode"``) of the inverse coupling, 1 - |W_here|^2 / |W_there|^2."""
        there = (float(np.interp(self.position, self.grid, self.predicted))
                 if self.predicted.size else self.predicted_here)
        return 1.0 - min(there, self.predicted_here) / max(self.predicted_here, 1e-300)

    def gain_words(self, digits: int = 0) -> str:
        """The predicted gain in words, for the decision log.

        >>> Choice(0.6, np.array([0.6, 1.8]), np.array([1.0, 4.0]), 4.0, "antinode").gain_words()
        'the standing wave predicted 2x as large there'
        """
        if self.objective == "antinode":
            ratio = 1.0 / np.sqrt(max(1.0 - self.gain, 1e-300))
            return f"the standing wave predicted {ratio:.{digits + 2}g}x as large there"
        return f"predicted {100 * self.gain:.{digits}f} % lower"

    def short_of(self, bar: float) -> str:
        """Why a gain below ``bar`` (a fraction) does not move the robot, in words.

        >>> Choice(0.6, np.array([0.6, 1.8]), np.array([2e-4, 3e-4]), 2.1e-4).short_of(0.05)
        ' is only 4.8 % lower (< 5 %)'
        """
        if self.objective == "antinode":
            return f": {self.gain_words(1)}, a gain below {100 * bar:g} %"
        return f" is only {100 * self.gain:.1f} % lower (< {100 * bar:g} %)"


#: What a position is judged by. "response": the predicted steady span RMS under a load of
#: fixed amplitude (:func:`predicted_rms`). "antinode": in the self-limiting wind the locked
#: mode's amplitude is set by the power the line dissipates, and the robot's absorber dissipates
#: in proportion to the square of the standing wave's amplitude where it sits, so a position is
#: judged by :func:`inverse_coupling` (docs/validation/closed_loop.md, "The policy in the
#: self-limiting wind").
OBJECTIVES = ("response", "antinode")


def locked_wave(plant, rows, robot_position: float, lines) -> np.ndarray:
    """The bare mode the wind feeds, at the nodes, from the record's lines near the tone.

    ``lines``: (omega, the sensors' phasors) of each spectral line. A heavy robot shares the
    locked mode among line-and-robot modes a fraction of a mode spacing apart (the line, locked
    before it arrived, beats between them), so no one tone names the mode the wind feeds, nor
    does a wave fitted at one (its neighbours' receptance there is as large). Each line is the
    belief's coupled mode (with the robot at ``robot_position``) within a mode spacing of it whose
    shape at the sensors (``rows``: the plant's modes there) its phasors match best, scaled to
    them; the bare mode that carries most of their summed energy (by nodal amplitude) is the one
    they share: the locked mode."""
    values, vectors = np.linalg.eig(plant.state_matrix(robot_position))
    upper = np.flatnonzero(values.imag > 0)
    band = plant.nodal[:, : plant.n_band]
    peak = np.max(np.abs(band), axis=0)
    content = np.zeros(plant.n_band)
    spacing = mode_spacing(np.sort(values.imag[upper]), float(np.mean([o for o, _ in lines])))
    for omega, phasors in lines:
        # the coupled modes within a spacing of the line; the one whose shape at the sensors
        # the line's phasors match best (a calibration a fraction of a spacing off must not
        # hand the line to the neighbour)
        near = upper[np.abs(values.imag[upper] - omega) <= spacing]
        if near.size == 0:
            near = upper[[np.argmin(np.abs(values.imag[upper] - omega))]]
        shapes = rows @ vectors[: plant.r, near]
        fit = np.abs(np.conj(shapes).T @ phasors) / np.linalg.norm(shapes, axis=0)
        best = int(np.argmax(fit))
        mode, at_sensors = vectors[: plant.r, near[best]], shapes[:, best]
        scale = np.vdot(at_sensors, phasors) / np.vdot(at_sensors, at_sensors)
        content += np.abs(scale * mode[: plant.n_band] * peak) ** 2
    return band[:, int(np.argmax(content))]


def inverse_coupling(bare_shape, plant, positions) -> np.ndarray:
    """``(max |W_bare| / |W_bare(p)|)^2`` at each of ``positions``: 1 at the robot-free
    standing wave's largest antinode, growing towards its nodes. The robot's absorber takes
    energy from the locked mode in proportion to ``|W_bare(p)|^2``, so this is the inverse of its
    coupling to the wave relative to the best place (a figure to minimise like the span RMS)."""
    x = plant.model.node_positions
    peak = float(np.max(np.abs(bare_shape)))
    here = np.abs(_interpolated(bare_shape, x, np.asarray(positions, dtype=float)))
    return (peak / np.maximum(here, 1e-6 * peak)) ** 2   # a node: a million times the antinode


def predicted_figure(objective: str, bare_shape, plant, robot, omega, positions,
                     weights) -> np.ndarray:
    """The figure a position is judged by under ``objective`` (:data:`OBJECTIVES`), lower is
    better, at each of ``positions``."""
    if objective == "antinode":
        return inverse_coupling(bare_shape, plant, positions)
    return predicted_rms(bare_shape, plant, robot, omega, positions, weights)


def choose_target(bare_shape, plant, robot, omega, weights, robot_position, low, high,
                  reach=np.inf, obstacle_ends=(False, False),
                  settings: PolicySettings = DEFAULT_POLICY,
                  objective: str = "response") -> Choice:
    """The predicted best parked position within reach: among the local minima of the predicted
    figure (``objective``, :data:`OBJECTIVES`: the span RMS by default) no farther than
    ``reach`` from the robot, those within ``settings.near_optimal`` of the
    lowest of them, the one nearest the robot (when none is within reach, the lowest position
    within reach, on the way down to one; the robot's own position when the prediction has no
    minimum or nothing within reach is lower than where it is). When no minimum within reach
    pays for a move (``settings.min_gain``), the edge of the reach on the way down to a lower
    minimum beyond it is taken instead, if it lies lower. ``obstacle_ends``: whether an obstacle
    (not a support) bounds the interval [low, high] on each side. The candidates are
    ``max(settings.grid_per_node * n_nodes, settings.min_grid)`` positions of [low, high]."""
    grid = np.linspace(low, high, max(settings.grid_per_node * plant.model.n_nodes,
                                      settings.min_grid))
    predicted = predicted_figure(objective, bare_shape, plant, robot, omega, grid, weights)
    here = float(predicted_figure(objective, bare_shape, plant, robot, omega, [robot_position],
                                  weights)[0])
    choice = pick_target(grid, predicted, here, robot_position, reach, obstacle_ends, settings)
    return replace(choice, objective=objective)


def pick_target(grid: np.ndarray, predicted: np.ndarray, here: float, robot_position: float,
                reach: float = np.inf, obstacle_ends=(False, False),
                settings: PolicySettings = DEFAULT_POLICY) -> Choice:
    """:func:`choose_target`'s rule on a predicted RMS already computed on a uniform grid."""
    # The ends of the grid count as minima only where an obstacle bounds it: at a support the
    # robot does nothing (the line does not move there), so a "minimum" there is the prediction's
    # edge, not a place to damp from.
    minima = [i for i in range(grid.size)
              if (predicted[i] <= predicted[i - 1] if i > 0 else obstacle_ends[0])
              and (predicted[i] <= predicted[i + 1] if i < grid.size - 1 else obstacle_ends[1])]
    stay = Choice(robot_position, read_only(grid), read_only(predicted), here)
    if not minima:
        return stay
    within = np.abs(grid - robot_position) <= reach
    reachable = [i for i in minima if within[i]]
    if not reachable:
        # No minimum within reach: the best the robot can reach lies on the way down to one,
        # at the edge of its reach (or it stays). A support end is no such place (see above).
        allowed = within.copy()
        allowed[0] &= obstacle_ends[0]
        allowed[-1] &= obstacle_ends[1]
        candidates = np.flatnonzero(allowed & np.isfinite(predicted))
        if candidates.size == 0 or predicted[candidates].min() >= here:
            return stay
        best = candidates[np.argmin(predicted[candidates])]
        return Choice(float(grid[best]), read_only(grid), read_only(predicted), here)
    lowest = min(predicted[i] for i in reachable)
    good = [i for i in reachable if predicted[i] <= (1 + settings.near_optimal) * lowest]
    pick = min(good, key=lambda i: abs(grid[i] - robot_position))
    if predicted[pick] > (1 - settings.min_gain) * here:
        # No minimum within reach pays for a move: as when none is within reach, the best the
        # robot can reach may lie at the edge of its reach, on the way down to a lower minimum
        # beyond it.
        first, last = np.flatnonzero(within)[[0, -1]]
        edges = [edge for edge, inward, beyond in (
                     (first, min(first + 1, last), minima[0] < first),
                     (last, max(last - 1, first), minima[-1] > last))
                 if beyond and predicted[edge] < min(predicted[inward], predicted[pick])]
        if edges:
            edge = min(edges, key=lambda i: predicted[i])
            return Choice(float(grid[edge]), read_only(grid), read_only(predicted), here)
    if 0 < pick < grid.size - 1:
        # Parabola through the grid minimum and its neighbours (uniform grid).
        a, b, c = predicted[pick - 1 : pick + 2]
        denom = a - 2 * b + c
        offset = 0.5 * (a - c) / denom if denom > 0 else 0.0
        position = float(grid[pick] + offset * (grid[1] - grid[0]))
    else:
        position = float(grid[pick])
    # the parabola's vertex may lie up to half a grid step beyond the reach
    position = float(np.clip(position, robot_position - reach, robot_position + reach))
    return Choice(position, read_only(grid), read_only(predicted), here)


def choose_parked_position(model: LineModel, field: np.ndarray, dt: float, robot: MDR,
                           start: float, limits: RobotLimits, *, obstacles=(),
                           travel_time: float = np.inf,
                           settings: PolicySettings | None = None,
                           objective: str = "response") -> Choice:
    """Where the closed loop would send the robot, from a record of the robot-free field.

    The closed loop's own targeting rule (:func:`choose_target`) on a record with no robot on
    the line (e.g. a Kalman estimate of the whole span): its phasor at the dominant frequency is
    the robot-free excited shape, the steady-state span RMS with the robot parked at every
    position of its free interval is predicted from it, and the best within reach is chosen
    (the nearest of the positions within ``settings.near_optimal`` of the best, 3 % by
    default, when a move is worth it).

    Parameters
    ----------
    model : LineModel
        The line, without the robot.
    field : ndarray, shape (n_nodes, n_samples)
        Displacement record of every node (m), columns in time, at interval ``dt`` (s).
    dt : float
        Sample interval, s.
    robot : MDR
        The robot (its impedance sets the prediction).
    start : float
        Where the robot is, m.
    limits : RobotLimits
        Its limits: speed and acceleration set the reach, the body length the free interval.
    obstacles : sequence of (left, right)
        Intervals it may not enter or cross, m.
    travel_time : float
        Time the robot may spend travelling, s (``inf``: the whole free interval is in reach).
    settings : PolicySettings or None
        The policy's settings (None: the defaults, the closed loop's own).
    objective : str
        What a position is judged by (:data:`OBJECTIVES`): "response", the span RMS predicted
        under the field's load of fixed amplitude; "antinode", the robot's coupling to the
        field's standing wave, as the closed loop judges in the self-limiting wind
        (``run_closed_loop(wind="self_limiting")``), where the wind locks into one mode and the
        robot damps it most at its antinode.

    Returns
    -------
    Choice
        ``position`` (m), the candidate ``grid`` and its ``predicted`` RMS (m; with "antinode"
        :func:`inverse_coupling`), the prediction ``predicted_here`` at the start, and the
        predicted ``gain``.

    Examples
    --------
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=40, damping=plc.ModalDamping(0.01))
    >>> snap = plc.simulate(model, plc.HarmonicForce(1.0, 24.0, 0.5), duration=6.0, dt=1e-3)
    >>> robot = plc.tune_damper(model, 3, 1.83, 0.05, body_mass=0.02)
    >>> choice = choose_parked_position(model, snap.displacement[:, -2000:], snap.dt, robot,
    ...                                 1.2, plc.RobotLimits(0.5, 1.0))
    >>> round(choice.position, 1), round(choice.gain, 2)    # the loop at 0.58 m is the best
    (0.6, 0.83)
    >>> locked = choose_parked_position(model, snap.displacement[:, -2000:], snap.dt, robot,
    ...                                 1.2, plc.RobotLimits(0.5, 1.0), objective="antinode")
    >>> round(locked.position, 2)        # an antinode of the field's 3 loops (0.61, 1.83, 3.05)
    1.82
    """
    if not isinstance(model, LineModel):
        raise InputError(f"The 'model' parameter must be a LineModel. Got {type(model).__name__}.")
    settings = checked_policy(settings)
    objective = check_choice("objective", objective, OBJECTIVES)
    check_bare_line(model, "the robot is the 'robot' argument (the field is the line's without it)")
    if not isinstance(robot, MDR):
        raise InputError(f"The 'robot' parameter must be an MDR. Got {type(robot).__name__}.")
    if not isinstance(limits, RobotLimits):
        raise InputError(
            f"The 'limits' parameter must be a RobotLimits. Got {type(limits).__name__}.")
    start = check_real("start", start, low=0.0, high=model.span.length, low_inclusive=True)
    if not (isinstance(travel_time, float) and travel_time == np.inf):   # inf: all in reach
        travel_time = check_real("travel_time", travel_time, low=0.0, low_inclusive=True)
    dt = check_real("dt", dt, low=0.0)
    field = check_array("field", field, shape=(model.n_nodes, None))
    if field.shape[1] < 8:
        raise InputError(
            f"The 'field' parameter must hold at least 8 samples to measure a frequency. "
            f"Got {field.shape[1]}."
        )
    frequency = dominant_frequency(field, dt, name="field")
    if not frequency > 0.0:
        raise InputError("The 'field' parameter shows no vibration (no spectral peak above 0 Hz).")
    top = float(model.span.pinned_frequencies(model.n_dofs)[-1])
    if frequency > top:
        raise InputError(
            f"The 'dt' parameter ({dt:g} s) puts the field's dominant frequency at "
            f"{frequency:.4g} Hz, above the highest the model resolves (about {top:.4g} Hz): "
            "give the record's sample interval in seconds."
        )
    t = dt * np.arange(field.shape[1])
    shape = fit_phasors(field, t, frequency)
    plant = ModalPlant(model, robot, default_modes(model.span, model, [frequency], dt), dt)
    low, high = free_interval(start, limits, model.span.length, obstacles)
    return choose_target(shape, plant, robot, 2 * np.pi * frequency, model.span_weights, start,
                         low, high, reach_within(limits, travel_time),
                         obstacle_ends((low, high), obstacles, limits.length), settings,
                         objective)


def obstacle_ends(bounds: tuple[float, float], obstacles, body_length: float) -> tuple[bool, bool]:
    """Whether an obstacle (rather than a span end) sets each bound of a free interval."""
    half = body_length / 2
    return (any(abs(right + half - bounds[0]) < 1e-9 for _, right in obstacles),
            any(abs(left - half - bounds[1]) < 1e-9 for left, _ in obstacles))


def quiet_from(start: float, end: float, settings: PolicySettings = DEFAULT_POLICY) -> float:
    """When the part of a run [start, end] (s) without moves begins: its last
    ``settings.quiet_fraction``."""
    return start + (1 - settings.quiet_fraction) * (end - start)


def travel_budget(now: float, start: float, end: float,
                  settings: PolicySettings = DEFAULT_POLICY) -> float:
    """Time (s) a decision at ``now`` in a run [start, end] may spend travelling: half of what
    is left (``settings.travel_fraction``), and a move must end before the quiet end
    (:func:`quiet_from`)."""
    budget = min(settings.travel_fraction * (end - now), quiet_from(start, end, settings) - now)
    return max(budget, 0.0)


def tone_wait(now: float, begun: float, resolve: float, end: float,
              settings: PolicySettings = DEFAULT_POLICY) -> bool:
    """Whether a new target should wait for a longer record of the excitation that began at
    ``begun`` s: until it is ``resolve`` s long, but at most ``settings.tone_wait_fraction`` of
    what is left of the run (until ``end``) from that start, so that the robot keeps time to move
    and settle."""
    return now - begun < min(resolve, settings.tone_wait_fraction * (end - begun))


def resolve_time(frequency: float, mode_frequencies: np.ndarray,
                 settings: PolicySettings = DEFAULT_POLICY) -> float:
    """Record length (s) that resolves ``frequency`` from the modes beside it:
    ``settings.tone_resolution / spacing``, at most ``settings.max_tone_wait``."""
    spacing = mode_spacing(mode_frequencies, frequency)
    if not spacing > 0:   # two modes at one frequency: no record separates them
        return settings.max_tone_wait
    return min(settings.tone_resolution / spacing, settings.max_tone_wait)


def mode_spacing(mode_frequencies: np.ndarray, frequency: float) -> float:
    """Spacing of the modes (Hz, sorted) around ``frequency``: the gap of the pair bracketing
    it (the nearest pair at either end of the band)."""
    modes = np.asarray(mode_frequencies, dtype=float)
    if modes.size < 2:
        return np.inf
    i = int(np.clip(np.searchsorted(modes, frequency), 1, modes.size - 1))
    return float(modes[i] - modes[i - 1])


def reach_within(limits: RobotLimits, time_budget: float) -> float:
    """Longest rest-to-rest move within ``time_budget`` s under every limit (jerk included), m:
    the inverse of :meth:`RobotLimits.rest_to_rest_time`, which grows with the distance."""
    if time_budget <= 0:
        return 0.0
    if not np.isfinite(time_budget):
        return np.inf
    low, high = 0.0, limits.v_max * time_budget   # no move in time_budget goes farther
    for _ in range(60):                           # bisection to ~1e-18 of high
        middle = 0.5 * (low + high)
        low, high = (middle, high) if limits.rest_to_rest_time(middle) <= time_budget else (
            low, middle)
    return low


class Phase(Enum):
    """Where the targeting of one excitation stands (:class:`Targeting`).

    ``FIRST_TARGET`` -> ``CONFIRMING`` when a target is chosen (:meth:`Targeting.accept` of a new
    target); ``CONFIRMING`` -> ``CONFIRMING`` when a confirmation tries another loop, ->
    ``FINAL`` when it confirms the anchor's loop, runs out of loops, finds the line still
    beating (:meth:`Targeting.gate_unsteady`) or undoes a move (:meth:`Targeting.check_measured`).
    A wind change held long enough makes a new target due from any phase.
    """

    FIRST_TARGET = "first target"   # nothing chosen yet: the first decision is a new target
    CONFIRMING = "confirming"       # a target chosen: confirm it once the robot has settled
    FINAL = "final"                 # the choice is final until the frequency changes


@dataclass
class Targeting:
    """The policy's memory between control steps (see the module doc); ``settings``: the
    policy's :class:`~powerline_control.closed_loop.PolicySettings`."""

    settings: PolicySettings = DEFAULT_POLICY
    phase: Phase = Phase.FIRST_TARGET
    goal: float = np.nan                # where the robot is sent
    anchor: float = np.nan              # the choice the confirmation gate is anchored to
    loop: float = np.nan                # the loop length at the anchor, m
    anchor_frequency: float = np.nan    # the watched (last window's) tone when it was chosen
    pending_since: float | None = None  # when the frequency left the anchor's (a wind change)
    excitation_start: float = 0.0       # when the current excitation began (at the earliest)
    excitation_seen: float = 0.0        # ... and when it was seen (at the latest)
    still_since: float | None = None    # since when the robot is still at its steer point
    last_moving: float = 0.0            # when it was last seen moving (0: parked from the start)
    decided_at: float = -np.inf         # when the last decision was made
    choices: int = 0                    # loops tried for this excitation
    reference_power: float = np.nan     # what the sensors measured before this excitation's move
    reference_position: float = np.nan  # ... and where the robot was then
    reference_estimate: float = np.nan  # ... and the span RMS estimated there
    last_position: float = np.nan       # where the robot was at the last decision
    last_power: float = np.nan          # ... what the sensors measured there (steady windows)
    predicted_rise: float = np.nan      # ... and the rise of it the belief predicted at the goal
    contradictions: int = 0             # moves whose measured effect contradicted the belief

    def remember(self, here: float, power: float, steady: bool, predicted_rise: float) -> None:
        """Keep what a decision saw, for the next one to check the move against: the robot's
        position ``here``, the sensors' ``power`` measured there (only a ``steady`` window's is
        a reference) and ``predicted_rise``, the sensors' power the belief predicts with the
        robot parked at the goal over that with it parked here."""
        self.last_position = here
        self.last_power = power if steady else np.nan
        self.predicted_rise = predicted_rise

    def update_clocks(self, now: float, robot_still: bool, frequency: float,
                      threshold: float) -> None:
        """Track how long the robot has been still and the frequency away from the anchor's."""
        if not robot_still:
            self.still_since, self.last_moving = None, now
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
            settle_margin: float, resolve: float) -> tuple[bool, bool]:
        """(retarget, confirm): a first target or a wind change held for a window (at least
        ``settings.min_change_hold`` s) with the robot still; else, while confirming, a
        confirmation once the robot has been still for a window (and for
        ``settings.confirm_resolve`` of ``resolve``, the record that resolves the tone, s),
        counted from the last decision (``decided_at``) if that came later."""
        policy = self.settings
        retarget = self.phase is Phase.FIRST_TARGET or (
            self.pending_since is not None
            and now - self.pending_since >= max(window_time, policy.min_change_hold)
            and robot_still
        )
        # A confirmation reads a window recorded after the decision it confirms: after a hold
        # (the robot never moved) the window that decided it would only decide again, with the
        # refinement's smaller bar in place of the hold's.
        confirm = (
            not retarget
            and self.phase is Phase.CONFIRMING
            and self.still_since is not None
            and now - max(self.still_since, self.decided_at) >= max(
                window_time, settle_margin, policy.confirm_resolve * resolve)
        )
        return retarget, confirm

    def excitation(self, retarget: bool, change_window: float) -> tuple[float, float]:
        """(begun, seen), s: the record a decision's tone is measured on starts at ``begun``, its
        shape's no earlier than ``seen``. For a wind change, ``seen`` is when the watched tone
        left the anchor's and ``begun`` the start of that first window (``change_window`` s
        earlier); otherwise the current excitation's, kept by :meth:`accept`."""
        if retarget and self.pending_since is not None:
            return max(self.pending_since - change_window, 0.0), self.pending_since
        return self.excitation_start, self.excitation_seen

    def gate_unsteady(self, retarget: bool, confirm: bool, unsteady: float,
                      now: float) -> tuple[bool, bool, str | None]:
        """(retarget, confirm, why the search ended) once the window's unsteadiness is known;
        the last is None unless a still-beating window ends the search here."""
        since = self.pending_since if retarget else self.still_since
        waited = now - since if since is not None else 0.0
        policy = self.settings
        # A window that still beats with a decaying mode misleads the prediction: wait (up to
        # policy.max_wait s) for a steady one, except for the very first target.
        beating = unsteady > policy.unsteady_limit
        if beating and waited < policy.max_wait and self.phase is not Phase.FIRST_TARGET:
            return False, False, None
        if confirm and beating:
            # Still beating after max_wait s: its steady-state prediction is no better than
            # the anchor's (a long, lightly damped span rings for tens of seconds after the
            # robot arrives). Keep the goal and stop.
            self.phase = Phase.FINAL
            return retarget, False, (f"final at {self.goal:.4g} m: the line still beats "
                                     f"{waited:.3g} s after the robot stopped")
        return retarget, confirm, None

    def check_measured(self, power: float, estimate: float, here: float, retarget: bool,
                       steady: bool, reach: float = np.inf,
                       return_reach: float = np.inf) -> str | None:
        """Check a move against the run itself. ``power``: the sensors' mean square amplitude at
        the load frequency over the last window; ``estimate``: the span RMS with the robot
        where it is, estimated from that same window (``Choice.predicted_here``). At a new
        target both are the reference; at a confirmation, a robot whose move made both worse (by
        more than ``settings.worse_tolerance``) goes back to where it was and stays. Both, because
        either alone misleads: a few sensors can sit where the robot's move raised the
        vibration while the span's fell, and the estimate is the prediction that chose the
        move. A way back longer than ``reach`` (the travel budget left) is not taken: a return
        cut off by the end of the run is worse than either end. Before that, a move whose
        measured effect contradicts the belief's prediction (:meth:`_contradiction`) is undone
        within ``return_reach`` (the limits' reach in the travel share of the rest of the run,
        the quiet end included: the way back leads to a place measured better). Returns the
        decision in words when it overrides the prediction, else None."""
        if retarget:
            # Only a steady window is a reference: a line still building up its response from
            # rest (tens of seconds on a lightly damped long span) would make every later window
            # look worse, whatever the move did.
            self.reference_power = power if steady else np.nan
            self.reference_position, self.reference_estimate = here, estimate
            return None
        contradicted = self._contradiction(power, here, steady, return_reach)
        if contradicted is not None:
            return contradicted
        moved = 1e-6 < abs(here - self.reference_position) <= reach
        tolerance = self.settings.worse_tolerance
        worse = (power > (1 + tolerance) * self.reference_power
                 and estimate > (1 + tolerance) * self.reference_estimate)
        if moved and worse:
            self.goal = self.anchor = self.reference_position
            self.phase = Phase.FINAL
            return (f"return to {self.reference_position:.4g} m: at {here:.4g} m the sensors "
                    f"measure {100 * (power / self.reference_power - 1):.0f} % more vibration "
                    "and the span is estimated "
                    f"{100 * (estimate / self.reference_estimate - 1):.0f} % worse than before "
                    "the move")
        return None

    def _contradiction(self, power: float, here: float, steady: bool,
                       return_reach: float) -> str | None:
        """At a confirmation after a move: whether what the sensors measure contradicts what
        the belief predicted for it. The sensors' power rose more than
        ``settings.contradiction_rise`` times over the last decision's (both steady windows) and
        more than ``settings.contradiction_factor`` times the rise the belief predicted: the
        belief that chose the move is wrong here (a bending stiffness or tension off by more
        than its calibration says), and its next prediction is no better. The robot goes back
        to where it measured less, if it can within ``return_reach``, and the choice is final
        either way. Returns the decision in words (None: no contradiction)."""
        policy = self.settings
        rise = power / self.last_power if self.last_power > 0 else np.nan
        moved = abs(here - self.last_position) > 1e-6
        if not (moved and steady and rise > policy.contradiction_rise
                and rise > policy.contradiction_factor * self.predicted_rise):
            return None
        self.phase = Phase.FINAL
        self.contradictions += 1
        measured = (f"at {here:.4g} m the sensors measure {rise:.3g}x the vibration power "
                    f"they measured at {self.last_position:.4g} m, where the belief predicted "
                    f"{self.predicted_rise:.3g}x: the measurements contradict the belief")
        if abs(here - self.last_position) > return_reach:
            return (f"final at {here:.4g} m: {measured}, and the way back "
                    f"({abs(here - self.last_position):.3g} m) is longer than the rest of the "
                    f"run allows ({return_reach:.3g} m)")
        self.goal = self.anchor = self.last_position
        return f"return to {self.last_position:.4g} m: {measured}"

    def accept(self, choice: Choice, here: float, loop: float, frequency: float,
               retarget: bool, excitation: tuple[float, float] = (0.0, 0.0)) -> str:
        """Take the predicted best position as the goal (a new target, or a confirmation), or
        hold where the robot is (``here``) when moving is not predicted to pay; returns what was
        decided, in words (the result's decision log). A new target must be predicted to pay
        by ``settings.min_gain``; a confirmation may refine inside the anchor's loop (within
        ``settings.same_loop`` loops of it) or try another loop (at most ``settings.max_choices``
        per excitation). ``frequency``: the watched tone the anchor is
        kept against; ``excitation``: (begun, seen) of the excitation a new target is for."""
        policy = self.settings
        worth_moving = choice.gain >= policy.min_gain
        if retarget:
            self.excitation_start, self.excitation_seen = excitation
            self.anchor = self.goal = choice.position if worth_moving else here
            self.loop, self.anchor_frequency, self.pending_since = loop, frequency, None
            self.choices, self.phase = 1, Phase.CONFIRMING
            if worth_moving:
                return f"target {choice.position:.4g} m ({choice.gain_words()})"
            return (f"hold at {here:.4g} m: the best predicted position {choice.position:.4g} m"
                    f"{choice.short_of(policy.min_gain)}")
        if abs(choice.position - self.anchor) <= policy.same_loop * self.loop:
            # The same minimum, better estimated from a steady window: accept it (the
            # gate is anchored to the choice, it never moves with the goal) and stop; a
            # refinement predicted to gain less than refine_gain is not worth the move.
            self.phase = Phase.FINAL
            if choice.gain < policy.refine_gain:
                return (f"confirm {here:.4g} m (the refinement to {choice.position:.4g} m"
                        f"{choice.short_of(policy.refine_gain)})")
            self.goal = choice.position
            return f"confirm {choice.position:.4g} m (anchor {self.anchor:.4g} m)"
        if self.choices < policy.max_choices:
            # Another loop, predicted better (by more than near_optimal, or choose_target would
            # have kept the near one) from a steadier window: go there (still confirming).
            self.anchor, self.loop, self.goal = choice.position, loop, choice.position
            self.choices += 1
            return f"another loop: {choice.position:.4g} m ({choice.gain_words()})"
        self.phase = Phase.FINAL
        return (f"final at {self.goal:.4g} m (best {choice.position:.4g} m, "
                f"{choice.gain_words(1)})")
