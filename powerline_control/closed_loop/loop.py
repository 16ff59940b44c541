"""run_closed_loop: sensors' phasors -> target -> motion -> the robot moves, and the verdict.

The target comes from the phasors of the sensors and of the robot's own motion at the load's
tone (the robot-free excited shape, :func:`.policy.kernel_shape`), predicted with the controller's
belief; the Kalman estimate is run alongside and judged (its innovation ratio, its consistency),
not steered by.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from .._spectral import dominant_frequency, extract_lines, fit_phasors
from .._threads import on_one_blas_thread
from .._validation import check_bool, check_choice, check_rng, checked_keywords, read_only
from ..errors import (
    BeliefContradictedWarning,
    ReachWarning,
    ShortfallWarning,
    TruncationWarning,
)
from ..fem import MDR, LineModel
from ..line import Span
from ..plan import RobotLimits, free_interval
from ..severity.self_limiting import checked_wind
from ..simulation.plant import damper_power, load_segments, nodal_field
from .aeolian_steady import aeolian_steady_state, checked_options, precheck
from .belief import Belief, BeliefTracker, believe, checked_nominal
from .evaluation import Settling, all_comparisons, settling_of
from .motion import Motion
from .policy import (
    Targeting,
    choose_target,
    kernel_shape,
    locked_wave,
    mode_spacing,
    obstacle_ends,
    pick_target,
    predicted_figure,
    predicted_sensors,
    quiet_from,
    reach_within,
    resolve_time,
    tone_wait,
    travel_budget,
)
from .policy_settings import PolicySettings
from .result import ClosedLoopResult
from .settings import UNSET_BC, UNSET_DAMPING, UNSET_ELEMENTS, Settings, checked_settings
from .simulated import (
    ESTIMATORS,
    Measurements,
    Records,
    advance_plant,
    build_line,
    rebuild_estimator,
    run_consistency,
    run_estimate,
)
from .simulated import calibrate as calibrate_estimator  # 'calibrate' is the span's option

#: Standard deviations of the calibrated tension by which the belief must differ from the
#: estimator's line before the estimator is rebuilt on it (:func:`_estimator_stale`).
ESTIMATOR_SIGMAS = 2.0
#: Relative half-width of the band of lines around the tone the span is calibrated on.
CALIBRATION_BAND = 0.2
# ------------------------------------------------------------------------------------ the run
# run_closed_loop tells the story of the run; these are its decision stages (the simulated line's
# are simulated.py's), in the order it calls them.


def _sensor_tone(seen: Measurements, lo: int, k: int, dt: float) -> float:
    """Dominant frequency of the sensors over samples lo..k, from the spectrum of their
    velocities (first differences: a weight 4 sin^2(omega dt / 2) ~ (omega dt)^2, bounded at
    Nyquist so noise is not amplified): the tone carrying the most vibration energy. By
    displacement the fundamental's start-up ringing (or the ringing the robot's own motion
    excites) can outweigh a load three times higher and send the robot after it."""
    return dominant_frequency(np.diff(seen.sensors[:, lo : k + 1], axis=1), dt)


def _observe(records: Records, seen: Measurements, settings: Settings, k: int) -> float:
    """The dominant frequency the sensors show up to sample k; logs it and the innovation ratio
    (the running estimator's recent one-step error over its value on its own record)."""
    lo = max(k + 1 - settings.window, 0)
    frequency = _sensor_tone(seen, max(k + 1 - settings.frequency_samples, 0), k, settings.dt)
    records.frequencies.append(frequency)
    records.innovation_ratio.append(
        float(np.sqrt(np.mean(records.innovation_power[lo + 1 : k + 1])))
        / max(records.estimators[-1].innovation_rms, 1e-300)
    )
    return frequency


def _bare_shape(seen: Measurements, belief: Belief, robot: MDR, x_r: float, lo: int, end: int,
                frequency: float, policy: PolicySettings) -> np.ndarray:
    """The robot-free excited shape (at the believed mesh's nodes) from the sensors' and the
    robot's own phasors on [lo, end]."""
    tt = seen.t[lo : end + 1]
    sensed = fit_phasors(seen.sensors[:, lo : end + 1], tt, frequency)
    at_robot = fit_phasors(seen.robot[None, lo : end + 1], tt, frequency)[0]
    return kernel_shape(belief.plant, belief.rows, sensed, robot, belief.inside(x_r), at_robot,
                         2 * np.pi * frequency, policy)


def _excited_shape(seen: Measurements, belief: Belief, robot: MDR, x_r: float, end: int,
                   frequency: float, window: int, record: int,
                   policy: PolicySettings) -> tuple[np.ndarray, float]:
    """W_bare over the last ``record`` samples (estimate phasor minus the robot's own reaction),
    and how unsteady the last ``window`` is: the relative difference of the shapes fitted on its
    two halves."""
    lo = max(end + 1 - window, 0)
    mid = (lo + end) // 2
    first = _bare_shape(seen, belief, robot, x_r, lo, mid, frequency, policy)
    second = _bare_shape(seen, belief, robot, x_r, mid, end, frequency, policy)
    scale = np.linalg.norm(first) + np.linalg.norm(second)
    unsteady = 2 * float(np.linalg.norm(first - second)) / max(scale, 1e-300)
    shape = _bare_shape(seen, belief, robot, x_r, max(end + 1 - record, 0), end, frequency,
                        policy)
    return shape, unsteady


#: Spectral lines a decision in the self-limiting wind reads from its record, and how near the
#: tone (in mode spacings) a line must lie to count as the locked mode's.
LOCKED_LINES, LOCKED_SPACINGS = 6, 1.5


def _record_lines(seen: Measurements, belief: Belief, end: int, tone: float,
                  record: int) -> list[tuple[float, np.ndarray]]:
    """(omega, the sensors' phasors) of the record's lines within LOCKED_SPACINGS mode
    spacings of the tone, over its last ``record`` samples (the tone alone if none is)."""
    lo = max(end + 1 - record, 0)
    signals, tt = seen.sensors[:, lo : end + 1], seen.t[lo : end + 1]
    found = extract_lines(signals, tt[1] - tt[0], LOCKED_LINES)[0]
    spacing = mode_spacing(belief.mode_frequencies, tone)
    near = [float(f) for f in found if abs(f - tone) <= LOCKED_SPACINGS * spacing] or [tone]
    return [(2 * np.pi * f, fit_phasors(signals, tt, f)) for f in near]


def _decision_tone(seen: Measurements, settings: Settings, targeting: Targeting, k: int,
                   excitation: tuple[float, float]) -> tuple[float, int]:
    """The tone a decision is made at, measured on the excitation's record (``excitation``: when
    it began and when it was seen, s; at least the change-detection window, at most
    ``policy.decision_tone_window`` s back), and how many samples the robot-free shape is fitted
    on: the part of that record since the robot stopped and the excitation was seen (at least
    one antinode window)."""
    dt = settings.dt
    begun, noticed = excitation
    tone_from = max(begun, k * dt - settings.policy.decision_tone_window)
    lo = max(min(int(np.ceil(tone_from / dt - 1e-9)), k + 1 - settings.frequency_samples), 0)
    shape_from = max(lo, *(int(np.ceil(time / dt - 1e-9)) for time in (targeting.last_moving,
                                                                          noticed)))
    return _sensor_tone(seen, lo, k, dt), max(k + 1 - shape_from, settings.window)


def _recalibrate(beliefs: BeliefTracker, records: Records, seen: Measurements, k: int,
                 tone: float) -> Belief:
    """The belief after calibrating on the record up to sample k (logged when it changes), on
    the lines around the ``tone`` (Hz): within CALIBRATION_BAND of it, or eight mode spacings
    where the modes lie further apart. The policy needs the wavelength at the tone; far lines
    add the modal band's edges (a long span's plant keeps 0.6-1.4x the tone) and the scaled
    model's largest errors."""
    spacing = mode_spacing(beliefs.belief.mode_frequencies, tone)
    width = max(CALIBRATION_BAND, 8 * spacing / tone)
    note = beliefs.update(seen, k, band=(max(tone * (1 - width), 0.0), tone * (1 + width)))
    if note is not None:
        records.decisions.append((float(seen.t[k]), note))
    return beliefs.belief


def _update_target(targeting: Targeting, motion: Motion, records: Records, seen: Measurements,
                   beliefs: BeliefTracker, robot: MDR, settings: Settings, k: int,
                   watched: float) -> None:
    """The policy at control step k: choose a first target, confirm it once the robot has
    settled, or choose anew after a wind change (module doc). It decides only with the robot at
    rest, so that every move is one rest-to-rest plan. ``watched``: the dominant frequency of the
    last change-detection window (what a wind change is detected on); a decision is made at the
    tone of the excitation's record (:func:`_decision_tone`). It reads the measurements
    (``seen``) and predicts with the belief, calibrated again before each decision
    (``beliefs``); ``records`` only logs what it decided."""
    t = seen.t
    belief = beliefs.belief
    policy = settings.policy
    if t[k] >= quiet_from(t[0], t[-1], policy):
        return
    robot_still = motion.at_rest
    targeting.update_clocks(t[k], robot_still, watched, settings.retarget_threshold)
    resolve = resolve_time(watched, belief.mode_frequencies, policy)
    retarget, confirm = targeting.due(t[k], robot_still, settings.window * settings.dt,
                                      settings.settle_margin, resolve)
    if not robot_still or not (retarget or confirm):
        return
    excitation = targeting.excitation(retarget, settings.frequency_samples * settings.dt)
    if retarget and tone_wait(t[k], excitation[0], resolve, t[-1], policy):
        return
    tone, shape_window = _decision_tone(seen, settings, targeting, k, excitation)
    shape, unsteady = _excited_shape(seen, belief, robot, motion.position, k, tone,
                                     settings.window, shape_window, policy)
    retarget, confirm, ended = targeting.gate_unsteady(retarget, confirm, unsteady, t[k])
    if ended is not None:
        records.decisions.append((float(t[k]), ended))
    if not (retarget or confirm):
        return
    if _recalibrate(beliefs, records, seen, k, tone) is not belief:   # the record moved it
        belief = beliefs.belief
        shape, unsteady = _excited_shape(seen, belief, robot, motion.position, k, tone,
                                         settings.window, shape_window, policy)
    if retarget and beliefs.waiting:
        if not records.decisions or not records.decisions[-1][1].startswith("hold"):
            records.decisions.append((float(t[k]), (
                "hold until the records tell the span's tension: a target predicted with the "
                "nominal span may lie loops from the best position")))
        return
    _check_prediction(records, seen, motion.position, k, tone, shape_window)
    if settings.objective == "antinode":
        shape = locked_wave(belief.plant, belief.rows, belief.inside(motion.position),
                            _record_lines(seen, belief, k, tone, shape_window))
    low, high = motion.bounds()
    reach = reach_within(settings.limits, travel_budget(t[k], t[0], t[-1], policy))
    choice = choose_target(shape, belief.plant, robot, 2 * np.pi * tone, belief.weights,
                           belief.inside(motion.position), *belief.within(low, high), reach,
                           obstacle_ends((low, high), settings.obstacles, settings.limits.length),
                           policy, settings.objective)
    records.predictions.append((float(t[k]), choice.grid, choice.predicted, read_only(shape),
                                tone))
    if retarget:
        note = _out_of_reach(choice, shape, belief, motion, robot, settings, 2 * np.pi * tone,
                             (reach, reach_within(settings.limits,
                                                  policy.travel_fraction * (t[-1] - t[k]))),
                             (low, high))
        if note is not None:
            records.decisions.append((float(t[k]), note))
    if retarget:
        records.retarget_times.append(float(t[k]))
        records.target_starts.append(k)
    measured = _sensed_power(seen, k, tone, settings.window)
    steady = unsteady <= policy.unsteady_limit
    contradictions = targeting.contradictions
    decision = targeting.check_measured(
        measured, choice.predicted_here, motion.position, retarget, steady, reach,
        reach_within(settings.limits, policy.travel_fraction * (t[-1] - t[k])))
    if targeting.contradictions > contradictions:
        records.contradictions.append((float(t[k]), decision))
    if decision is None:
        decision = targeting.accept(choice, motion.position, belief.loop_length(tone), watched,
                                    retarget, excitation)
    records.decisions.append((float(t[k]), decision))
    targeting.decided_at = float(t[k])
    # what the sensors should measure once the robot has settled at its goal: the next decision
    # checks the belief against it (:func:`_check_prediction`)
    at_goal, at_here = (predicted_sensors(shape, belief.plant, robot, 2 * np.pi * tone,
                                          belief.inside(x), belief.sensor_positions, belief.rows)
                        for x in (targeting.goal, motion.position))
    records.expected = (float(targeting.goal), tone, at_goal)
    targeting.remember(motion.position, measured, steady,
                       float(np.vdot(at_goal, at_goal).real)
                       / max(float(np.vdot(at_here, at_here).real), 1e-300))
    if targeting.goal != motion.goal:
        motion.send(targeting.goal, float(t[k]))


def _check_prediction(records: Records, seen: Measurements, here: float, k: int, tone: float,
                      window: int) -> None:
    """Compare the sensors' phasors over the last ``window`` samples with those the belief
    predicted for the robot parked here at the last decision (same tone within 1 %) and log the
    misfit of their shapes (sqrt(1 - MAC): the measured phasors against the best complex
    multiple of the predicted ones; ``ClosedLoopResult.misfits``). Logged, not acted on: once
    the robot damps the excited mode, the field left at the sensors is the small remainder of
    the modes around it, whose shape even the exact line predicts poorly (docs/closed_loop.md)."""
    if records.expected is None:
        return
    goal, expected_tone, predicted = records.expected
    if abs(here - goal) > 1e-6 or abs(tone - expected_tone) > 0.01 * expected_tone:
        return
    lo = max(k + 1 - window, 0)
    measured = fit_phasors(seen.sensors[:, lo : k + 1], seen.t[lo : k + 1], tone)
    # the shape, not the level: a line still building up from rest, or a load whose amplitude
    # changed, scales every phasor alike
    power = float(np.vdot(measured, measured).real) * float(np.vdot(predicted, predicted).real)
    agreement = abs(np.vdot(predicted, measured)) ** 2 / max(power, 1e-300)
    records.misfits.append((float(seen.t[k]), here, float(np.sqrt(max(1.0 - agreement, 0.0)))))


def _sensed_power(seen: Measurements, k: int, frequency: float, window: int) -> float:
    """Mean square amplitude the sensors measure at the load's frequency over the last window:
    the vibration the robot can check its moves against (what it measures, not predicts)."""
    lo = max(k + 1 - window, 0)
    sensed = fit_phasors(seen.sensors[:, lo : k + 1], seen.t[lo : k + 1], frequency)
    return float(np.mean(np.abs(sensed) ** 2))


def _out_of_reach(choice, shape: np.ndarray, belief: Belief, motion: Motion, robot: MDR,
                  settings: Settings, omega: float, reaches: tuple[float, float],
                  bounds: tuple[float, float]) -> str | None:
    """What keeps the robot from a position predicted clearly better (by ``min_gain``) than the
    best within reach, in words (None: nothing does). ``reaches``: the decision's reach and the
    limits' alone (half the rest of the run, without the quiet end). A ReachWarning when the
    limits let the robot reach less than ``reach_warning_loops`` (a quarter loop), or the
    obstacles hold it at the edge
    of its free interval; a far loop beyond the travel budget (on a long span, or late in the
    run) is only noted: few sensors rank far loops poorly, and the trip would cost most of the
    run. Predictions are the ``belief``'s, on its span; the free interval is the robot's
    (``motion``: where its body may go)."""
    policy = settings.policy
    half, length = settings.limits.length / 2, motion.span_length
    if bounds == (half, length - half):   # no obstacle: the choice's own prediction covers it
        anywhere = pick_target(choice.grid, choice.predicted, choice.predicted_here,
                               choice.position, settings=policy)
    else:
        anywhere = choose_target(shape, belief.plant, robot, omega, belief.weights,
                                 choice.position, *belief.within(half, length - half),
                                 settings=policy, objective=choice.objective)
    chosen, best = predicted_figure(choice.objective, shape, belief.plant, robot, omega,
                                    [choice.position, anywhere.position], belief.weights)
    if best >= (1 - policy.min_gain) * chosen:
        return None
    limits, gain = settings.limits, 100 * (1 - best / chosen)
    found = (f"{anywhere.position:.4g} m is predicted {gain:.0f} % better than "
             f"{choice.position:.4g} m")
    if not bounds[0] <= anywhere.position <= bounds[1]:
        if min(abs(choice.position - edge) for edge in bounds) > 1e-6:
            return None   # the best inside the free interval is a loop of its own
        warnings.warn(
            f"The robot cannot reach where it would damp best: {found}, but the 'obstacles' "
            f"{list(settings.obstacles)} confine the robot (length {limits.length:g} m) to "
            f"[{bounds[0]:.4g}, {bounds[1]:.4g}] m.", ReachWarning, stacklevel=4)
        return f"blocked by an obstacle: {found}"
    loop = belief.loop_length(omega / (2 * np.pi))
    reach, limits_reach = reaches
    if limits_reach < policy.reach_warning_loops * loop:
        least = ("a quarter loop" if policy.reach_warning_loops == 0.25 else
                 f"{policy.reach_warning_loops:g} loop")
        warnings.warn(
            f"The robot cannot reach where it would damp best: {found}, but the 'limits' "
            f"(v_max={limits.v_max:g} m/s, a_max={limits.a_max:g} m/s^2, j_max={limits.j_max}) "
            f"let it travel only {limits_reach:.3g} m ({least} is "
            f"{policy.reach_warning_loops * loop:.3g} m) "
            f"in half the rest of the {settings.duration:g} s run ('duration'): raise the "
            "limits or lengthen the run.", ReachWarning, stacklevel=4)
    return f"beyond the travel budget ({reach:.3g} m): {found}"


def _estimator_stale(records: Records, beliefs: BeliefTracker, estimated_on: Belief,
                     settings: Settings) -> str | None:
    """Why the "robot_input" estimator is rebuilt now, or None. "line": the belief's tension
    lies more than ESTIMATOR_SIGMAS of the calibration's uncertainty from that of the line the
    estimator models (``estimated_on``; within them the records cannot tell the two lines
    apart, and a rebuild would only trade one model error for another). "tone": the sensors'
    dominant tone has stood more than ``retarget_threshold`` (the policy's wind change) from
    the tone the model's load oscillates at over the last antinode window of control steps."""
    believed = beliefs.belief.span.tension
    if abs(believed - estimated_on.span.tension) > ESTIMATOR_SIGMAS * beliefs.believed_std:
        return "line"
    steps = max(int(np.ceil(settings.window / settings.steps_per_period)), 1)
    recent = np.asarray(records.frequencies[-steps:])
    tone = records.estimators[-1].input_model.tone
    if recent.size == steps and np.all(np.abs(recent - tone) > settings.retarget_threshold * tone):
        return "tone"
    return None


def _move_robot(motion: Motion, records: Records, t: np.ndarray, k: int, end: int) -> None:
    """The robot's motion over samples k+1..end, recorded (the planner's, limits held)."""
    position, velocity, status = motion.advance(t[k + 1 : end + 1], float(t[k]))
    records.statuses.append(status)
    records.position[k + 1 : end + 1] = position
    records.velocity[k + 1 : end + 1] = velocity
    records.target[k + 1 : end + 1] = motion.goal


def _later_half(settling: Settling, t: np.ndarray) -> Settling:
    """The settled window's later half: in the self-limiting wind the line's amplitude takes
    seconds to settle after the robot stops (the robot damps it down from the balance's
    amplitude, and the wind's ratio grows as it falls), so the window the robot's arrival
    starts still holds the decay."""
    start = 0.5 * (settling.window[0] + float(t[-1]))
    mask = t >= start - 1e-12
    return dataclasses.replace(settling, mask=mask, window=(float(t[mask][0]), float(t[-1])))


def _warn_unsettled(result: ClosedLoopResult, duration: float) -> None:
    """TruncationWarning when a placement's vibration in the self-limiting wind still changes
    by more than 10 % between the settled window's halves (``Comparison.transient``)."""
    ringing = [c.name for c in result.comparisons if c.transient]
    if ringing:
        start, end = result.settled_window
        warnings.warn(
            f"The 'duration' {duration:g} s is too short for the line to settle in the "
            f"self-limiting wind: over the settled window {start:.4g}-{end:.4g} s the vibration "
            f"of {ringing} changes by more than 10 % between its halves. Lengthen 'duration' "
            f"(e.g. to {2 * duration:g} s) so that the window starts after the amplitude has "
            "settled.", TruncationWarning, stacklevel=3)


# Thousands of small products per simulated second: one BLAS thread is several times faster than
# two contending ones. The limit applies inside this call only.
@checked_keywords
@on_one_blas_thread
def run_closed_loop(
    model: LineModel | Span,
    force: object,
    robot: MDR | None,
    limits: RobotLimits | None = None,
    *,
    sensors: Sequence[int],
    n_elements: int | None = UNSET_ELEMENTS,
    bc: object = UNSET_BC,
    damping: object = UNSET_DAMPING,
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
    nominal: Span | LineModel | None = None,
    calibrate: bool = True,
    settings: PolicySettings | None = None,
    aeolian_steady: bool | Mapping = False,
    estimator: str = "recipe",
    wind: str | Mapping = "fixed_lift",
) -> ClosedLoopResult:
    """Drive the damping robot to the antinode from sensor data and measure the vibration.

    Parameters
    ----------
    model : LineModel or Span
        The line: a :class:`~powerline_control.fem.LineModel` runs on its own mesh (graded
        toward clamps), supports and damping (a model built with ``mdr=`` also gives the robot);
        a :class:`~powerline_control.line.Span` is meshed with ``n_elements``, ``bc`` and
        ``damping``.
    force : load, list of loads, or list of (start_time, load)
        The excitation (e.g. :class:`~powerline_control.excitation.HarmonicForce`); a schedule
        ``[(0.0, load_a), (8.0, load_b)]`` switches loads at the given times (a wind change).
    robot : MDR or None
        The robot; ``robot.position`` is where it starts (and stays parked in the baseline).
        None: the robot the LineModel carries.
    limits : RobotLimits or None
        Speed, acceleration, jerk and body length (default v_max = 0.5 m/s, a_max = 1 m/s^2):
        every field holds at every sample (the motion is :mod:`~powerline_control.plan`'s), and
        the body stays inside the span and out of the obstacles
        (:func:`~powerline_control.plan.free_interval`).
    sensors : sequence of int
        Measured node indices (not at a pinned support, where the line never moves).
    n_elements : int or None
        With a Span: elements of the FE model whose modes play the real line (default 100;
        None: the mesh the physics chooses for the aeolian band, see
        :class:`~powerline_control.fem.LineModel`). Refused with a LineModel (it has its mesh).
    bc : str or (str, str)
        With a Span: supports (default ``"pinned"``).
    damping : None, ModalDamping or RayleighDamping
        With a Span: the line's own damping (none by default, as in the paper).
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
        Shortest record the excited shape is fitted on, s (it is fitted on everything since the
        robot stopped and the excitation began, at most 12 s), and the window whose two halves
        tell whether the line still beats.
    frequency_window : float
        Length of the window the dominant frequency is watched on for a wind change, s (its
        resolution is about 1 / window). The tone a target is chosen at is measured on the
        excitation's whole record, which resolves the load from the free modes beside it
        (``PolicySettings.decision_tone_window``; docs/closed_loop.md).
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
        Motion: each new goal a :func:`~powerline_control.plan.plan_motion` time-optimal move
        (the S-curve with a jerk limit), or the receding-horizon
        :class:`~powerline_control.plan.MotionPlanner`.
    planner_time_budget : float or None
        Wall-clock budget of one MPC step, s (``motion="mpc"`` only); None (default): the
        planner's iteration limits, so results do not depend on the machine's load.
    seed : int, Generator or None
        Sensor noise.
    nominal : Span, LineModel or None
        What the controller is told of the line (``model`` is the line simulated, the truth):
        the nominal span (catalogue conductor, length, supports, stringing tension), which may
        be several per cent off the truth. The policy predicts with it only (its modes, loop
        length and receptances, at the sensors' positions in metres); everything it sees of the
        truth is the sensors' and its own records. A Span is meshed as the simulated line is
        (the same number of equal elements, or the physics mesh for the same band, graded
        toward clamps), with its supports and ``belief.ASSUMED_DAMPING`` (a span says nothing
        of the line's damping); a LineModel brings its own mesh, supports and damping (a robot
        it carries is ignored: the robot is ``robot``). Its
        length must be the simulated span's within 1 %. None (default): the simulated line's
        own span, mesh and damping (the controller told the truth, and nothing to calibrate).
    calibrate : bool
        With a ``nominal``: after the calibration window and again at each decision of the
        policy, calibrate the span from the sensors' whole record so far
        (:func:`~powerline_control.identify.calibrate_span`, the nominal as prior) and predict
        with the calibrated span once its tension moves from the believed one by more than 0.1 %
        (``ClosedLoopResult.calibrations``; records of at least two cycles of the
        fundamental; once the robot has moved, the longest stretch it stood still in where
        the two disagree: ``settings.moved_record_z``). The robot holds at its start until a
        calibration tells the tension (one whose main peak holds less than 80 % of its
        posterior, or twice as uncertain as the one believed, moves nothing). False: the
        controller predicts with the nominal as told. (0.1 %, two cycles, 80 % and twice:
        ``settings.belief_tolerance``, ``min_cycles``, ``trusted_share``, ``less_certain``.)
    settings : PolicySettings or None
        The policy's settings (:class:`~powerline_control.closed_loop.PolicySettings`: each with
        its value, what it guards and the evidence for it). None (default): the tuned values.
    aeolian_steady : bool or mapping
        True: when the run's last load is an :class:`~powerline_control.excitation.AeolianForce`,
        judge the robot where the loop ended again in the self-limiting wind, in steady state:
        the energy balance's wind power at the current amplitude on the line damped by the
        conductor's self-damping (:func:`~powerline_control.severity.simulate_aeolian`), against
        no robot, a fixed damper at ``clamp_distance`` and the antinode
        (``ClosedLoopResult.aeolian_steady``; a few CPU seconds on a 300 m span). A mapping
        does the same with simulate_aeolian's physics options (``wind_curve``,
        ``self_damping``, ...). False (default): not judged.
    estimator : {"recipe", "robot_input"}
        The estimator's model. "recipe" (default): the recipe's
        (:func:`~powerline_control.recipe.design_estimator`), identified on the calibration
        window with the robot parked at its start and kept so while it moves. "robot_input":
        the bare line's modes (of the span the controller is told) with the robot's measured
        force on the line (its absorber's force and its body's inertia) as a known input at its
        current position, and the load as one oscillator per mode at the tone the sensors
        measured, rebuilt when a calibration moves the belief beyond twice its uncertainty
        from the estimator's line or the load's tone changes
        (``ClosedLoopResult.estimator_updates``; docs/closed_loop.md, "The robot in the
        estimator's model"). Either way ``ClosedLoopResult.estimator_consistency`` tests it
        over the whole run.
    wind : {"fixed_lift", "self_limiting"} or mapping
        What an :class:`~powerline_control.excitation.AeolianForce` does to the simulated line.
        "fixed_lift" (default): a lift of fixed amplitude on the line's own damping.
        "self_limiting": the energy balance's physics
        (:mod:`powerline_control.severity.self_limiting`): the wind's power from the
        power curve at the locked mode's current amplitude as a negative damping on it, and the
        conductor's self-damping on every mode at its own amplitude (the line's own damping is
        not used), recomputed at every plant block by the functions
        :func:`~powerline_control.severity.simulate_aeolian` calls; the line starts vibrating
        at the energy balance's amplitude without the robot. A mapping does the same with the
        physics' options (``wind_curve``, ``turbulence_intensity``, ``self_damping``,
        ``self_damping_k``, ``self_damping_exponents``). The comparisons are then over the
        settled window (no exact steady state of a sine); the controller is given nothing new.

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    InputError
        For invalid arguments: sensors outside the model or at a support, a calibration longer
        than the run or too short for the estimator's recipe, periods that are not multiples of
        ``dt``, a load at or above the Nyquist frequency of ``dt``, a force that puts no load on
        the line, a robot off the span, inside an obstacle, or heavier than the line can carry
        (more than 25 % of the span's mass, or a static slope W / 2T above 0.05 rad).
        An InputError names 'nominal' when it is not a Span or a LineModel, its length is
        more than 1 % off the simulated span's, or it does not reach a sensor.
    PowerlineControlError
        From the stages (identification, estimation, planning) when they report trouble.

    Warns
    -----
    ReachWarning
        When the limits and the run let the robot travel less than a quarter loop, or the
        obstacles keep it from the best predicted position.
    TruncationWarning
        When the mesh does not resolve a load's frequency.
    ShortfallWarning
        When the run ends worse than the robot parked at its start or than a fixed damper near
        the clamp, under its load or, with ``aeolian_steady``, in the self-limiting wind
        (``ClosedLoopResult.shortfalls``).
    TruncationWarning
        When the mesh does not resolve a load's frequency, or (``wind="self_limiting"``) when a
        placement's vibration still changes by more than 10 % between the settled window's
        halves: the run is too short to settle.

    Examples
    --------
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), 20, damping=plc.ModalDamping(0.01))
    >>> robot = plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1)
    >>> result = plc.run_closed_loop(model, plc.HarmonicForce(1.0, 24.0, 0.5), robot,
    ...                              sensors=[4, 9, 15], duration=6.0, calibration=1.0)
    >>> result.comparison("closed_loop").steady     # compared in exact steady state
    True
    >>> bool(result.vibration_reduction > 3)         # parked at the start / where it ended
    True
    """
    call_cpu = time.process_time()
    settings = checked_settings(
        model, robot, limits, sensors, n_elements=n_elements, bc=bc, damping=damping,
        duration=duration,
        calibration=calibration, dt=dt, control_period=control_period, plant_period=plant_period,
        noise_fraction=noise_fraction, delays=delays, estimator_rank=estimator_rank,
        antinode_window=antinode_window, frequency_window=frequency_window,
        retarget_threshold=retarget_threshold, settle_margin=settle_margin, obstacles=obstacles,
        motion=motion, planner_time_budget=planner_time_budget, policy=settings,
    )   # from here on 'settings' is the run's checked settings, the policy's in settings.policy
    robot, limits, policy = settings.robot, settings.limits, settings.policy
    span = settings.bare.span
    told = checked_nominal(nominal, settings.bare)
    calibrate = check_bool("calibrate", calibrate)
    estimator = check_choice("estimator", estimator, ESTIMATORS)
    rng = check_rng(seed)
    segments = load_segments(force, settings.duration)
    wind_options = checked_wind(wind, segments, settings.bare)
    if wind_options is not None:
        # In the self-limiting wind the best place is where the absorber reaches the locked
        # mode most: its antinode (docs/validation/closed_loop.md).
        settings = dataclasses.replace(settings, objective="antinode")
    steady_options = checked_options(aeolian_steady, segments[-1][1])
    if steady_options is not None:   # refused now, not after the run
        precheck(settings.bare, segments[-1][1][0], steady_options)

    # ---- the line, its loads, and the estimator calibrated with the robot parked at its start
    setup_start, setup_cpu = time.perf_counter(), time.process_time()
    line = build_line(robot, segments, settings, sensors, n_modes=n_modes,
                      clamp_distance=clamp_distance, wind=wind_options)
    calibrated = calibrate_estimator(line, robot, settings, rng,
                                     estimator=estimator,
                                     told=told if isinstance(told, LineModel) else None)
    n_cal, t = settings.n_cal, line.t
    records = Records.after_calibration(line, calibrated, robot, n_cal)
    # What the controller is told (the nominal span, meshed as the line is) and all it sees
    # (the measurements): it never reads the simulated line.
    seen = records.measurements(line)
    # the band the belief keeps: a controller told the truth knows its loads; one told a
    # nominal knows the tone its sensors measure in the calibration window
    measured_tone = _sensor_tone(seen, 0, n_cal - 1, settings.dt)
    band = line.load_frequencies if told is None else [measured_tone]
    belief = believe(settings.bare if told is None else told, like=settings.bare, robot=robot,
                     n_modes=n_modes, dt=settings.dt, sensor_positions=seen.sensor_positions,
                     frequencies=band)
    beliefs = BeliefTracker(belief, robot=robot, n_modes=n_modes, dt=settings.dt,
                            frequencies=band, calibrate=calibrate and told is not None,
                            settings=policy)

    # ---- the loop: every control period, estimate, choose a target, move (and simulate)
    plant_state = calibrated.start_states[n_cal - 1].copy()
    targeting = Targeting(settings=policy)
    motion_state = Motion.new(limits, span.length, settings.obstacles, robot.position,
                              settings.motion, settings.control_period,
                              settings.planner_time_budget)
    timings = {"setup": time.perf_counter() - setup_start,
               "setup cpu": time.process_time() - setup_cpu, "plant": 0.0, "plant update": 0.0,
               "filter": 0.0, "modes": line.plant.r, "estimator updates cpu": 0.0}
    estimated_on = belief
    wall_start, cpu_start = time.perf_counter(), time.process_time()
    k = n_cal - 1
    while k < t.size - 1:
        end = min(k + settings.steps_per_period, t.size - 1)
        frequency = _observe(records, seen, settings, k)
        if k == n_cal - 1:   # the calibration window's record: the first calibration
            _recalibrate(beliefs, records, seen, k, measured_tone)
        _update_target(targeting, motion_state, records, seen, beliefs, robot, settings, k,
                       frequency)
        stale = (_estimator_stale(records, beliefs, estimated_on, settings)
                 if estimator == "robot_input" else None)
        if stale is not None:
            tic = time.process_time()
            rebuild_estimator(records, beliefs.belief.bare, settings, k, calibrated.noise_std,
                              seen.sensor_positions, line.bare.node_positions,
                              new_load=stale == "tone")
            estimated_on = beliefs.belief
            records.estimator_updates.append((float(t[k]), stale))
            timings["estimator updates cpu"] += time.process_time() - tic
        _move_robot(motion_state, records, t, k, end)
        plant_state = advance_plant(plant_state, records, line, calibrated, rng, timings, k,
                                    end)
        k = end
    wall = time.perf_counter() - wall_start
    timings["loop cpu"] = time.process_time() - cpu_start
    timings["policy and motion"] = wall - timings["plant"] - timings["plant update"] - timings[
        "filter"]

    # ---- what happened, over a settled window, against the robot parked
    after_start, after_cpu = time.perf_counter(), time.process_time()
    frequencies = records.frequencies
    loop_length = float(span.loop_length(frequencies[-1])) if frequencies else float("nan")
    settling = settling_of(records, t, segments, n_cal, loop_length, settings.settle_margin)
    if wind_options is not None:
        settling = _later_half(settling, t)
    loop_power = damper_power(line.plant, robot, records.plant_states, records.position)
    travel_time = travel_budget(t[n_cal - 1], t[0], t[-1], policy)
    bounds = free_interval(robot.position, limits, span.length, settings.obstacles)
    displacement = nodal_field(line.plant, records.plant_states, line.residual, records.position)
    baseline = nodal_field(line.plant, calibrated.start_states, line.residual, robot.position)
    comparisons, scan = all_comparisons(line, robot, records, calibrated, settling.mask, limits,
                                        bounds, travel_time, segments[-1][1], loop_power,
                                        (displacement, baseline))
    scan_positions = scan.positions if scan is not None else np.zeros(0)
    scan_rms = scan.rms if scan is not None else np.zeros(0)
    best_position = scan.best_position if scan is not None else float("nan")
    estimated = run_estimate(records.estimators)
    timings["comparisons"] = time.perf_counter() - after_start
    timings["comparisons cpu"] = time.process_time() - after_cpu
    steady_wind, steady_cpu = None, time.process_time()
    if steady_options is not None:
        steady_wind = aeolian_steady_state(settings.bare, segments[-1][1][0], robot,
                                           float(records.position[-1]),
                                           clamp_distance=line.clamp_distance, **steady_options)
        timings["aeolian steady cpu"] = time.process_time() - steady_cpu
    if line.wind is not None:   # the self-limiting wind's exponentials, every run of the call
        timings["damping rebuilds"] = line.wind.held.rebuilds + line.wind.free_held.rebuilds
    timings["calibration cpu"] = beliefs.cpu
    timings["call cpu"] = time.process_time() - call_cpu
    result = ClosedLoopResult(
        t=read_only(t),
        x=read_only(line.bare.node_positions.copy()),
        displacement=read_only(displacement),
        baseline_displacement=read_only(baseline),
        estimated_field=read_only(estimated),
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
        decisions=tuple(records.decisions),
        estimator_consistency=run_consistency(records.estimators),
        estimator_updates=tuple(records.estimator_updates),
        span=span,
        nominal=span if told is None else belief.span,
        belief=beliefs.belief.span,
        calibrations=tuple(beliefs.calibrations),
        misfits=tuple(records.misfits),
        contradictions=tuple(records.contradictions),
        policy=policy,
        aeolian_steady=steady_wind,
        estimator=estimator,
        wind="fixed_lift" if wind_options is None else "self_limiting",
    )
    if wind_options is not None:
        _warn_unsettled(result, settings.duration)
    for when, text in result.contradictions:
        warnings.warn(f"The robot's measurements contradict its belief at {when:.4g} s: {text}.",
                      BeliefContradictedWarning, stacklevel=3)
    for text in result.shortfalls:
        warnings.warn(f"The closed loop falls short: {text}.", ShortfallWarning, stacklevel=3)
    return result
