"""run_closed_loop's arguments, checked once in a fixed order (the first bad one is named)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._constants import GRAVITY  # standard gravity, one value for the package
from .._validation import check_budget, check_indices, check_int, check_real
from ..errors import InputError
from ..fem import MDR, LineModel
from ..line import Span
from ..plan import RobotLimits, check_obstacles, free_interval
from ..recipe.defaults import DEFAULT_DELAYS, check_record_work, shortest_record
from .policy_settings import PolicySettings, checked_policy

# A robot heavier than this fraction of the span's own mass is no longer a small attachment: the
# slowly-varying-parameter plant and the single-mode tuning are not credible beyond it.
MAX_ROBOT_MASS_RATIO = 0.25
# Static slope of the line under the robot's weight, W / (2 T) at midspan: beyond 0.05 rad the
# small-slope (linear taut-string) model of the line is not valid.
MAX_STATIC_SLOPE = 0.05

# ---------------------------------------------------------------------------------- validation
def _check_robot(span: Span, robot: MDR) -> None:
    if robot.position > span.length:
        raise InputError(
            f"The 'robot.position' parameter must lie on the span [0, {span.length:g}] m. "
            f"Got {robot.position:g}."
        )
    total = robot.body_mass + robot.suspended_mass
    span_mass = span.conductor.mass_per_length * span.length
    if total > MAX_ROBOT_MASS_RATIO * span_mass:
        raise InputError(
            f"The 'robot' is too heavy for this span: {total:g} kg against a span mass of "
            f"{span_mass:.3g} kg (allowed: at most {MAX_ROBOT_MASS_RATIO:g} of it, beyond which "
            "the robot is not a small attachment of the line)."
        )
    slope = GRAVITY * total / (2 * span.tension)
    if slope > MAX_STATIC_SLOPE:
        raise InputError(
            f"The 'robot' is too heavy for the tension: its weight {GRAVITY * total:.3g} N "
            f"bends the line by {slope:.3g} rad at midspan (W / 2T; allowed "
            f"<= {MAX_STATIC_SLOPE:g}, the small-slope limit of the linear line model)."
        )


def _check_multiple(name: str, value: float, dt: float) -> int:
    steps = int(round(value / dt))
    if steps < 1 or abs(steps * dt - value) > 1e-9 * max(1.0, value):
        raise InputError(
            f"The '{name}' parameter ({value:g} s) must be a positive multiple of dt ({dt:g} s)."
        )
    return steps


@dataclass(frozen=True)
class Settings:
    """run_closed_loop's options after checking, with the sample counts the run works in."""

    robot: MDR                  # the robot (its position is the start)
    limits: RobotLimits
    duration: float
    dt: float
    control_period: float
    steps_per_period: int       # samples per control step
    plant_steps: int | None     # samples per plant block (None: chosen once the plant is known)
    n_cal: int                  # samples of the calibration window (robot parked)
    noise_fraction: float
    planner_time_budget: float | None
    antinode_window: float
    frequency_window: float
    retarget_threshold: float
    settle_margin: float
    delays: int | None
    estimator_rank: int | None
    motion: str
    bare: LineModel             # the line the loop runs on (without the robot)
    obstacles: tuple
    policy: PolicySettings      # the policy's settings (run_closed_loop's 'settings')
    # What the policy judges a position by (policy.OBJECTIVES): the wind the user declares is
    # the engineer's knowledge of the line, not a reading of the simulated line.
    objective: str = "response"

    @property
    def n_samples(self) -> int:
        """Samples of the whole run (durations are floored to whole samples, as simulate does)."""
        return int(np.floor(self.duration / self.dt + 1e-9)) + 1

    @property
    def window(self) -> int:
        """Samples the excited shape is fitted on (at least two control periods)."""
        return max(int(round(self.antinode_window / self.dt)), 2 * self.steps_per_period)

    @property
    def frequency_samples(self) -> int:
        """Samples the dominant frequency is measured on (at least two control periods)."""
        return max(int(round(self.frequency_window / self.dt)), 2 * self.steps_per_period)


def checked_settings(model, robot, limits, sensors, *, n_elements, bc, damping, duration,
                      calibration, dt, control_period, plant_period, noise_fraction, delays,
                      estimator_rank, antinode_window, frequency_window, retarget_threshold,
                      settle_margin, obstacles, motion, planner_time_budget,
                      policy=None) -> Settings:
    """Every argument checked once, in a fixed order (the first bad one is the one reported)."""
    if not isinstance(model, Span | LineModel):
        raise InputError(
            f"The 'model' parameter must be a LineModel or a Span. Got {type(model).__name__}."
        )
    robot = _robot_of(model, robot)
    span = model.span if isinstance(model, LineModel) else model
    _check_robot(span, robot)
    limits = limits or RobotLimits(v_max=0.5, a_max=1.0)
    if not isinstance(limits, RobotLimits):
        raise InputError(
            f"The 'limits' parameter must be RobotLimits or None. Got {type(limits).__name__}."
        )
    duration, dt, control_period, steps_per_period, plant_steps, n_cal = _checked_sampling(
        duration, calibration, dt, control_period, plant_period
    )
    # < 1 as in scenarios (config): noise larger than the signal it measures is no experiment,
    # and 1e300 overflowed into a raw NumPy "infs or NaNs" error.
    noise_fraction = check_real("noise_fraction", noise_fraction, low=0.0, low_inclusive=True,
                                high=1.0, high_inclusive=False)
    if planner_time_budget is not None:  # checked even when motion="closed_form" ignores it
        planner_time_budget = check_real("planner_time_budget", planner_time_budget, low=0.0)
    antinode_window = check_real("antinode_window", antinode_window, low=0.0)
    frequency_window = check_real("frequency_window", frequency_window, low=0.0)
    retarget_threshold = check_real("retarget_threshold", retarget_threshold, low=0.0)
    settle_margin = check_real("settle_margin", settle_margin, low=0.0, low_inclusive=True)
    if delays is not None:
        delays = check_int("delays", delays, low=1)
    recipe_delays = DEFAULT_DELAYS if delays is None else delays
    needed = shortest_record(recipe_delays)
    if n_cal < needed:   # the estimator is identified on this record (design_estimator)
        raise InputError(
            f"The 'calibration' parameter ({calibration:g} s, {n_cal} samples of dt) is too "
            f"short: the estimator's recipe needs at least {needed} samples "
            f"(calibration >= {(needed - 1) * dt:.6g} s) with delays={recipe_delays}."
        )
    if estimator_rank is not None:
        estimator_rank = check_int("estimator_rank", estimator_rank, low=1)
    if motion not in ("closed_form", "mpc"):
        raise InputError(f"The 'motion' parameter must be 'closed_form' or 'mpc'. Got {motion!r}.")
    bare = _bare_model(model, sensors, duration, dt, n_elements=n_elements, bc=bc,
                       damping=damping, n_cal=n_cal, calibration=calibration)
    obstacles = tuple(_checked_obstacles(obstacles, robot, limits, span.length))
    policy = checked_policy(policy)
    return Settings(
        robot=robot, limits=limits, duration=duration, dt=dt, control_period=control_period,
        steps_per_period=steps_per_period, plant_steps=plant_steps, n_cal=n_cal,
        noise_fraction=noise_fraction, planner_time_budget=planner_time_budget,
        antinode_window=antinode_window, frequency_window=frequency_window,
        retarget_threshold=retarget_threshold, settle_margin=settle_margin, delays=delays,
        estimator_rank=estimator_rank, motion=motion, bare=bare, obstacles=obstacles,
        policy=policy,
    )


def _checked_sampling(duration, calibration, dt, control_period, plant_period):
    """(duration, dt, control_period, steps per control period, steps per plant block or None,
    calibration samples): the run's times, whose rates must divide dt."""
    duration = check_real("duration", duration, low=0.0)
    calibration = check_real(
        "calibration", calibration, low=0.0, high=duration, high_inclusive=False
    )
    dt = check_real("dt", dt, low=0.0)
    # A period longer than the run would never act (1e300 was accepted and ignored).
    control_period = check_real("control_period", control_period, low=0.0, high=duration)
    if plant_period is not None:
        plant_period = check_real("plant_period", plant_period, low=0.0, high=duration)
    steps_per_period = _check_multiple("control_period", control_period, dt)
    plant_steps = (
        _check_multiple("plant_period", plant_period, dt) if plant_period is not None else None
    )
    # Durations are sampled (floored to whole samples, as simulate does); rates must divide.
    n_cal = calibration_samples(calibration, dt)
    if n_cal < 3:
        raise InputError(
            f"The 'calibration' parameter ({calibration:g} s) must hold at least 2 samples of "
            f"dt ({dt:g} s)."
        )
    return duration, dt, control_period, steps_per_period, plant_steps, n_cal


def calibration_samples(calibration: float, dt: float) -> int:
    """Samples of a calibration window of ``calibration`` s (floored to whole samples of dt)."""
    return int(np.floor(calibration / dt + 1e-9)) + 1


# Marks an argument the caller did not give (a LineModel brings its own mesh, supports, damping).
class _Unset:
    """The default of an argument the caller left out (shown as what a Span gets)."""

    def __init__(self, shown: str):
        self.shown = shown

    def __repr__(self) -> str:
        return self.shown


UNSET_ELEMENTS, UNSET_BC, UNSET_DAMPING = (_Unset("100 (a Span)"), _Unset("'pinned' (a Span)"),
                                           _Unset("None (a Span)"))


def _robot_of(model, robot) -> MDR:
    """The robot: ``robot``, or the one a LineModel carries (they must not disagree)."""
    carried = model.mdr if isinstance(model, LineModel) else None
    if robot is None and carried is not None:
        return carried
    if not isinstance(robot, MDR):
        raise InputError(
            f"The 'robot' parameter must be an MDR (its position is the start). "
            f"Got {type(robot).__name__}."
        )
    if carried is not None and carried != robot:
        raise InputError(
            f"The 'robot' parameter ({robot}) differs from the robot the model carries "
            f"(model.mdr = {carried}): pass one of them (robot=None takes the model's)."
        )
    return robot


def _check_calibration_work(n_nodes: int, n_cal: int, calibration: float, model,
                            n_elements) -> None:
    """Refuse, before the calibration run is simulated, a mesh whose calibration record (every
    node, ``n_cal`` samples) the estimator's recipe would refuse after it: design_estimator's own
    estimate (recipe.defaults.check_record_work, ``2 n_nodes^2 n_cal`` flops), named in this
    function's terms (a 20 000-element Drake span with the robot: 9 s of simulation, then a
    refusal naming a 'snapshots' the caller never passed)."""
    if isinstance(model, LineModel):
        parameter, value, mesh = "model", f"a LineModel of {n_nodes} nodes", "a coarser model"
    else:
        parameter, value = "n_elements", (n_nodes - 1 if n_elements is None else n_elements)
        mesh = "a coarser mesh (fewer n_elements" + (
            ", or max_frequency on a LineModel)" if n_elements is None else ")")
    check_record_work(
        n_nodes, n_cal, what=f"run_closed_loop's estimator, identified on the calibration "
        f"record ({n_nodes} nodes x {n_cal} samples)", parameter=parameter, value=value,
        fix=f"use {mesh} or a shorter 'calibration' ({calibration:g} s now)")


def _bare_model(model, sensors, duration, dt, *, n_elements, bc, damping, n_cal,
                calibration) -> LineModel:
    """The line the loop runs on, without the robot: the LineModel given (its mesh, supports and
    damping), or one built from the Span; the run's memory and the calibration's work checked
    before it is built (after, for the mesh the physics chooses: n_elements=None)."""
    if isinstance(model, LineModel):
        given = {name: value for name, value in
                 (("n_elements", n_elements), ("bc", bc), ("damping", damping))
                 if not isinstance(value, _Unset)}
        if given:
            raise InputError(
                f"The {sorted(given)} parameter(s) apply to a Span; the LineModel given brings "
                "its own mesh, supports and damping. Leave them out or pass the Span."
            )
        n_nodes = model.n_nodes
    else:
        n_elements = 100 if isinstance(n_elements, _Unset) else n_elements
        if n_elements is not None:
            n_elements = check_int("n_elements", n_elements, low=2)
        n_nodes = None if n_elements is None else n_elements + 1
    if n_nodes is not None:  # the sensors early, before any model is built
        check_indices("sensors", sensors, n_nodes)
    # The loop records ~4 node histories and ~16 scalars per sample (and the parked comparisons):
    # refuse a duration / dt that cannot fit before anything is built (n_elements=None: >= 2 nodes).
    n_samples = int(np.floor(duration / dt + 1e-9)) + 1
    check_budget(f"run_closed_loop's {n_samples}-sample histories",
                 nbytes=8.0 * n_samples * (4 * (n_nodes or 2) + 16),
                 parameter="duration", value=duration,
                 fix=f"shorten duration ({duration:g} s), increase dt ({dt:g} s) or use a "
                     f"coarser mesh ({n_nodes} nodes"
                     + (f": n_elements={n_elements})" if isinstance(n_elements, int) else ")"))
    if len(set(sensors)) != len(sensors):
        raise InputError(f"The 'sensors' parameter must not repeat a node. Got {list(sensors)}.")
    if n_nodes is not None:
        _check_calibration_work(n_nodes, n_cal, calibration, model, n_elements)
    if isinstance(model, LineModel):
        return model.with_robot(None) if model.mdr is not None else model
    bare = LineModel(model, n_elements, "pinned" if isinstance(bc, _Unset) else bc,
                     damping=None if isinstance(damping, _Unset) else damping)
    if n_nodes is None:
        _check_calibration_work(bare.n_nodes, n_cal, calibration, model, n_elements)
    return bare


def _checked_obstacles(obstacles, robot: MDR, limits: RobotLimits,
                       span_length: float) -> list[tuple[float, float]]:
    """The obstacles read by the package's one rule (``plan.check_obstacles``), with the robot's
    body free at its start (``plan.free_interval``: inside the span, touching an obstacle at
    most)."""
    checked = check_obstacles(obstacles, span_length)
    try:
        free_interval(robot.position, limits, span_length, checked)
    except InputError as exc:
        raise InputError(f"The 'robot.position' or 'limits.length' parameter: {exc}") from exc
    return checked
