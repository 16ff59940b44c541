"""The whole chain in closed loop: sensors -> Kalman estimate -> antinode -> MPC -> robot moves.

The span is simulated with the damping robot attached at its current position; the robot's
position is a slowly varying parameter (its speed is < 2 % of the wave speed, so the convective
moving-mass terms are neglected, as in the domain notes). Each control period:

1. the span (with the robot where it is) is propagated exactly over the period, from the state
   the previous period left (:func:`~powerline_control.simulate.simulate` with ``initial_state``),
   and the sensors read it with noise;
2. a Kalman filter on a DMD model identified during an initial calibration window (robot parked)
   estimates the whole field from the few sensors;
3. the antinode nearest the robot is located in the last window of estimates;
4. the receding-horizon planner steps the robot toward it within its limits.

The result compares the line's vibration with the robot parked where it started: the line
vibrates less when the robot sits at the antinode.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from ._validation import check_indices, check_int, check_real, check_rng
from .antinode import locate_antinodes, nearest_antinode
from .errors import InputError, PowerlineControlError
from .estimate import KalmanFilter
from .fem import MDR, LineModel
from .identify import fit_dmd, select_alpha
from .line import Span
from .plan import MotionPlanner, RobotLimits
from .simulate import simulate

__all__ = ["ClosedLoopResult", "run_closed_loop"]


@dataclass(frozen=True)
class ClosedLoopResult:
    """What happened in :func:`run_closed_loop`.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Sample times, s (calibration window included, starting at 0).
    x : ndarray, shape (n_nodes,)
        Node positions, m.
    displacement : ndarray, shape (n_nodes, n_t)
        True (noise-free) displacement with the robot under closed-loop control.
    baseline_displacement : ndarray, shape (n_nodes, n_t)
        True displacement with the robot parked at its start for the whole run.
    estimated_field : ndarray, shape (n_nodes, n_t)
        The Kalman filter's estimate of the field (NaN during calibration).
    robot_position, robot_velocity : ndarray, shape (n_t,)
        Robot state, m and m/s.
    target : ndarray, shape (n_t,)
        Antinode the robot was steering to (NaN before the first estimate).
    sensors : tuple of int
        Measured node indices.
    calibration_time : float
        Length of the initial window (robot parked) used to identify the estimator's model, s.
    statuses : tuple of str
        Planner status of every control step ("optimal", "safe_stop", ...).
    wall_time : float
        Wall-clock time of the loop (after calibration), s.

    Examples
    --------
    >>> import powerline_control as plc
    >>> result = run_closed_loop(plc.Span.paper_lab(), plc.HarmonicForce(1.0, 24.0, 0.5),
    ...                          plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1), n_elements=20,
    ...                          sensors=[4, 9, 15], duration=2.0, calibration=1.0)
    >>> result.displacement.shape, len(result.statuses)      # 20 control steps of 50 ms
    ((21, 2001), 20)
    >>> print(f"{result.rms_baseline / result.rms_closed_loop:.1f}")   # doctest: +SKIP
    1.3
    """

    t: np.ndarray
    x: np.ndarray
    displacement: np.ndarray
    baseline_displacement: np.ndarray
    estimated_field: np.ndarray
    robot_position: np.ndarray
    robot_velocity: np.ndarray
    target: np.ndarray
    sensors: tuple
    calibration_time: float
    statuses: tuple
    wall_time: float = field(repr=False)

    def _final_window(self, fraction: float = 0.25) -> slice:
        return slice(int(self.t.size * (1 - fraction)), None)

    @property
    def rms_closed_loop(self) -> float:
        """RMS displacement over the span in the last quarter of the run, m."""
        return float(np.sqrt(np.mean(self.displacement[:, self._final_window()] ** 2)))

    @property
    def rms_baseline(self) -> float:
        """The same with the robot parked at its start, m."""
        return float(np.sqrt(np.mean(self.baseline_displacement[:, self._final_window()] ** 2)))

    @property
    def vibration_reduction(self) -> float:
        """rms_baseline / rms_closed_loop: how many times less the line vibrates."""
        return self.rms_baseline / self.rms_closed_loop

    @property
    def real_time_factor(self) -> float:
        """Simulated loop time over its wall-clock time (> 1: faster than real time)."""
        return (self.t[-1] - self.calibration_time) / self.wall_time


class _ModelCache:
    """LineModels with the robot at positions rounded to ``resolution`` (modes reused)."""

    def __init__(self, span: Span, n_elements: int, bc: object, robot: MDR, resolution: float):
        self._args = (span, n_elements, bc)
        self._robot = robot
        self._resolution = resolution
        self._models: dict[int, LineModel] = {}

    def at(self, position: float) -> LineModel:
        key = int(round(position / self._resolution))
        if key not in self._models:
            span, n_elements, bc = self._args
            robot = dataclasses.replace(self._robot, position=key * self._resolution)
            self._models[key] = LineModel(span, n_elements, bc, mdr=robot)
        return self._models[key]


def _calibrated_filter(
    snap, sensors: Sequence[int], delays: int, noise_var: float
) -> tuple[KalmanFilter, np.ndarray]:
    """Steady-state Kalman filter on a DMD model of the calibration window (alpha from data)."""
    curve = select_alpha(snap.displacement, snap.dt, delays=delays)
    alpha = curve.best_stable_alpha if curve.best_stable_alpha is not None else curve.best_alpha
    dmd = fit_dmd(
        snap.displacement, snap.dt, alpha=alpha, delays=delays, alpha_mode=curve.alpha_mode
    )
    sys = dmd.to_statespace(measured=list(sensors))
    kf = KalmanFilter(
        sys, Q=dmd.residual_covariance, R=noise_var, steady_state=True, field_map=dmd.field_map
    )
    return kf, dmd.field_map


def _next_goal(
    window: np.ndarray, x: np.ndarray, dt: float, robot: float, previous: float
) -> float:
    """The antinode to steer to: first the one nearest the robot, then only small corrections.

    Once the robot damps its loop, that loop's motion is small, the model (identified with the
    robot parked) fits it less well, and the estimated pattern wanders; jumping to another loop
    would throw the approach away. So after the first choice the goal accepts only an antinode
    within a quarter loop of it (a gate), and otherwise stays.
    """
    try:
        antinodes = locate_antinodes(window, x, dt=dt)
    except PowerlineControlError:
        antinodes = []
    if np.isnan(previous):
        return nearest_antinode(antinodes, robot).position if antinodes else robot
    gated = [a for a in antinodes if abs(a.position - previous) < 0.25 * a.loop_length]
    return (
        min(gated, key=lambda a: abs(a.position - previous)).position if gated else float(previous)
    )


# Thousands of small (n ~ 100-400) products per simulated second: one BLAS thread is several
# times faster than two contending ones on a shared 2-core machine (measured: real-time factor
# 0.18 with the default threads, 0.69 with one). The limit applies inside this call only.
@threadpool_limits.wrap(limits=1, user_api="blas")
def run_closed_loop(
    span: Span,
    force: object,
    robot: MDR,
    limits: RobotLimits | None = None,
    *,
    sensors: Sequence[int],
    n_elements: int = 100,
    bc: object = "pinned",
    duration: float = 10.0,
    calibration: float = 2.0,
    dt: float = 1e-3,
    control_period: float = 0.05,
    noise_fraction: float = 0.01,
    delays: int = 2,
    antinode_window: float = 0.25,
    obstacles: Sequence[tuple[float, float]] = (),
    planner_time_budget: float = 1.0,
    seed: int | np.random.Generator | None = 0,
) -> ClosedLoopResult:
    """Drive the damping robot to the antinode from sensor data and measure the vibration.

    Parameters
    ----------
    span : Span
        The span.
    force : load
        The excitation (e.g. :class:`~powerline_control.excitation.HarmonicForce`).
    robot : MDR
        The robot; ``robot.position`` is where it starts (and stays parked in the baseline).
    limits : RobotLimits or None
        Speed and acceleration limits (default v_max = 0.5 m/s, a_max = 1 m/s^2).
    sensors : sequence of int
        Measured node indices.
    n_elements : int
        Elements of the FE model that plays the real line.
    bc : str or (str, str)
        Supports.
    duration : float
        Total simulated time, s, calibration included.
    calibration : float
        Initial window with the robot parked, used to identify the estimator's model, s.
    dt : float
        Sample interval, s.
    control_period : float
        Interval between planner steps, s (a multiple of ``dt``).
    noise_fraction : float
        Sensor noise as a fraction of the RMS displacement of the calibration window.
    delays : int
        Time delays of the DMD model (2 makes the displacement model exact for a linear line).
    antinode_window : float
        Length of the estimate window the antinode is located in, s.
    obstacles : sequence of (left, right)
        Intervals the robot may not enter or cross, m.
    planner_time_budget : float
        Wall-clock budget of one planner step, s. The default is generous because this is a
        simulation: a real-time budget (tens of ms) would make results depend on machine load.
    seed : int, Generator or None
        Sensor noise.

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    InputError
        For invalid arguments (e.g. sensors outside the model, a calibration longer than the run).
    PowerlineControlError
        From the stages (identification, estimation, planning) when they report trouble.

    Examples
    --------
    See :class:`ClosedLoopResult`.
    """
    if not isinstance(span, Span):
        raise InputError(f"The 'span' parameter must be a Span. Got {type(span).__name__}.")
    if not isinstance(robot, MDR):
        raise InputError(
            f"The 'robot' parameter must be an MDR (its position is the start). "
            f"Got {type(robot).__name__}."
        )
    limits = limits or RobotLimits(v_max=0.5, a_max=1.0)
    if not isinstance(limits, RobotLimits):
        raise InputError(
            f"The 'limits' parameter must be RobotLimits or None. Got {type(limits).__name__}."
        )
    duration = check_real("duration", duration, low=0.0)
    calibration = check_real(
        "calibration", calibration, low=0.0, high=duration, high_inclusive=False
    )
    dt = check_real("dt", dt, low=0.0)
    control_period = check_real("control_period", control_period, low=0.0)
    steps_per_period = int(round(control_period / dt))
    if steps_per_period < 1 or abs(steps_per_period * dt - control_period) > 1e-9:
        raise InputError(
            f"The 'control_period' parameter ({control_period:g} s) must be a "
            f"positive multiple of dt ({dt:g} s)."
        )
    n_elements = check_int("n_elements", n_elements, low=1)
    sensors = tuple(check_indices("sensors", sensors, n_elements + 1).tolist())
    rng = check_rng(seed)
    # The physics sees the robot's position rounded to 1 cm (0.3 % of the lab span, far below a
    # loop length): each new position costs an eigen-solve, and 1 cm moves nothing measurable.
    models = _ModelCache(span, n_elements, bc, robot, resolution=1e-2)

    parked = models.at(robot.position)
    baseline = simulate(parked, force, duration=duration, dt=dt)
    calib = simulate(
        parked, force, duration=calibration, dt=dt, noise_fraction=noise_fraction, seed=rng
    )
    noise_std = calib.noise_std
    kf, field_map = _calibrated_filter(calib, sensors, delays, noise_std**2)
    # Warm the filter on the calibration record so the loop starts from a converged estimate.
    warm = kf.filter(calib.displacement[list(sensors)], update_state=True)

    n_t = baseline.t.size
    n_cal = calib.t.size
    displacement = np.empty_like(baseline.true_displacement)
    displacement[:, :n_cal] = calib.true_displacement
    estimated = np.full_like(displacement, np.nan)
    estimated[:, :n_cal] = warm.field
    position = np.full(n_t, robot.position)
    velocity = np.zeros(n_t)
    target = np.full(n_t, np.nan)
    # The planner's horizon must outlast a full stop from top speed; twice that leaves room.
    braking = limits.v_max / limits.a_max
    horizon = max(40, int(np.ceil(2 * braking / control_period)))
    planner = MotionPlanner(
        limits,
        dt=control_period,
        horizon=horizon,
        span_length=span.length,
        obstacles=obstacles,
        time_budget=planner_time_budget,
    )
    statuses = []
    state, x_r, v_r = calib.final_state, robot.position, 0.0
    window = max(int(round(antinode_window / dt)), 2 * steps_per_period)
    start = time.perf_counter()
    k = n_cal - 1
    while k < n_t - 1:
        end = min(k + steps_per_period, n_t - 1)
        segment = simulate(
            models.at(x_r),
            force,
            duration=(end - k) * dt,
            dt=dt,
            start_time=baseline.t[k],
            initial_state=state,
        )
        state = segment.final_state
        noisy = segment.true_displacement[:, 1:] + noise_std * rng.standard_normal(
            (displacement.shape[0], end - k)
        )
        displacement[:, k + 1 : end + 1] = segment.true_displacement[:, 1:]
        for j in range(end - k):
            kf.step(noisy[list(sensors), j])
            estimated[:, k + 1 + j] = field_map @ kf.state
        recent = estimated[:, max(end + 1 - window, 0) : end + 1]
        goal = _next_goal(recent, baseline.x, dt, x_r, target[k])
        step = planner.step((x_r, v_r), goal)
        statuses.append(step.status)
        # The actuator saturates: the solver meets the limits only to its tolerance (~1e-8).
        period = (end - k) * dt
        accel = float(np.clip(step.acceleration, -limits.a_max, limits.a_max))
        accel = float(np.clip(accel, (-limits.v_max - v_r) / period, (limits.v_max - v_r) / period))
        # Integrate the commanded constant acceleration over the period, sample by sample.
        tau = dt * np.arange(1, end - k + 1)
        position[k + 1 : end + 1] = x_r + v_r * tau + 0.5 * accel * tau**2
        velocity[k + 1 : end + 1] = v_r + accel * tau
        target[k + 1 : end + 1] = goal
        x_r, v_r = float(position[end]), float(velocity[end])
        k = end
    wall = time.perf_counter() - start
    return ClosedLoopResult(
        t=baseline.t,
        x=baseline.x,
        displacement=displacement,
        baseline_displacement=baseline.true_displacement,
        estimated_field=estimated,
        robot_position=position,
        robot_velocity=velocity,
        target=target,
        sensors=sensors,
        calibration_time=float(calib.t[-1]),
        statuses=tuple(statuses),
        wall_time=wall,
    )
