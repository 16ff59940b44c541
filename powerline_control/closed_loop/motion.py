"""How the robot moves to its goal: the planner's trajectories, followed sample by sample.

The motion is the planning stage's (:mod:`powerline_control.plan`), never a copy of it: with
``motion="closed_form"`` every new goal is a :func:`~powerline_control.plan.plan_motion` from the
robot's state (the exact time-optimal move, the S-curve with a jerk limit), sampled at the
plant's samples; with ``motion="mpc"`` the receding-horizon
:class:`~powerline_control.plan.MotionPlanner` gives one command per control period, integrated
exactly. Either way every :class:`~powerline_control.plan.RobotLimits` field holds (speed,
acceleration, jerk, and the body length kept inside the span and out of the obstacles by the one
free-interval rule, :func:`~powerline_control.plan.free_interval`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..plan import MotionPlanner, RobotLimits, Trajectory, free_interval, plan_motion


@dataclass(eq=False)
class Motion:
    """The robot's motion state and the plan it follows (a class with evolving state)."""

    limits: RobotLimits
    span_length: float
    obstacles: tuple
    planner: MotionPlanner | None   # None: closed-form trajectories
    position: float
    velocity: float = 0.0
    acceleration: float = 0.0
    goal: float = float("nan")      # where the policy sends the robot
    steer: float = float("nan")     # the goal inside the free interval
    trajectory: Trajectory | None = None
    trajectory_start: float = 0.0   # time the trajectory began, s

    @classmethod
    def new(cls, limits: RobotLimits, span_length: float, obstacles, position: float,
            motion: str, control_period: float, time_budget: float | None = None) -> Motion:
        """The robot at rest at ``position``, moving by ``motion`` ("closed_form" or "mpc";
        ``time_budget``: the MPC's wall-clock budget per step, None for iteration limits only)."""
        planner = None
        if motion == "mpc":
            braking = limits.v_max / limits.a_max + (
                0.0 if limits.j_max is None else limits.a_max / limits.j_max)
            planner = MotionPlanner(
                limits, dt=control_period,
                horizon=max(40, int(np.ceil(2 * braking / control_period)) + 1),
                span_length=span_length, obstacles=list(obstacles),
                **({} if time_budget is None else {"time_budget": time_budget}))
        return cls(limits, span_length, tuple(obstacles), planner, float(position))

    @property
    def at_rest(self) -> bool:
        """Still at its steer point (or with no goal yet): to round-off for a closed-form
        trajectory, within the receding-horizon planner's own tolerance for the MPC."""
        tolerance = 1e-9 if self.planner is None else self.planner.tolerance
        still = abs(self.velocity) <= tolerance and abs(self.acceleration) <= tolerance
        return still and (np.isnan(self.steer) or abs(self.position - self.steer) <= tolerance)

    def bounds(self) -> tuple[float, float]:
        """Where the robot's centre may go from where it is (plan's free-interval rule)."""
        return free_interval(self.position, self.limits, self.span_length, self.obstacles)

    def send(self, goal: float, now: float) -> None:
        """A new goal from the policy: plan the move now (clipped to the free interval)."""
        low, high = self.bounds()
        self.goal = float(goal)
        self.steer = float(np.clip(goal, low, high))
        if self.planner is None:
            self.trajectory = plan_motion(
                self.position, self.steer, self.limits, span_length=self.span_length,
                obstacles=list(self.obstacles), start_velocity=self.velocity)
            self.trajectory_start = now

    def advance(self, times: np.ndarray, now: float) -> tuple[np.ndarray, np.ndarray, str]:
        """Positions and velocities at ``times`` (after ``now``, one control period), and the
        period's status: "closed_form", "blocked" (the goal lies beyond an obstacle or a span
        end: the robot goes as far as it may), "hold" (no goal yet), or the MPC step's status."""
        if np.isnan(self.steer):
            n = times.size
            return np.full(n, self.position), np.zeros(n), "hold"
        if self.planner is None:
            position, velocity, acceleration = self.trajectory.sample(
                times - self.trajectory_start)
            # the polynomials meet a bound the body may touch to round-off only: not past it
            position = np.clip(position, *self.trajectory.bounds)
            status = "closed_form"
        else:
            position, velocity, acceleration, status = self._mpc_period(times, now)
        self.position = float(position[-1])
        self.velocity = float(velocity[-1])
        self.acceleration = float(acceleration[-1])
        if status in ("closed_form", "optimal", "at_target") and self.steer != self.goal:
            status = "blocked"
        return position, velocity, status

    def _mpc_period(self, times, now):
        """One receding-horizon command, integrated exactly over the period's samples."""
        state = (self.position, self.velocity) if self.limits.order == 2 else (
            self.position, self.velocity, self.acceleration)
        step = self.planner.step(state, self.steer)
        tau = times - now
        jerk = 0.0 if step.jerk is None else float(step.jerk)
        accel = float(step.acceleration) if step.jerk is None else self.acceleration
        position = self.position + self.velocity * tau + accel * tau**2 / 2 + jerk * tau**3 / 6
        velocity = self.velocity + accel * tau + jerk * tau**2 / 2
        # a double integrator's acceleration is its input, not a state: zero between commands
        acceleration = np.zeros(tau.shape) if step.jerk is None else accel + jerk * tau
        return position, velocity, acceleration, step.status
