"""Motion planning of the mobile damping robot: its limits, the free space between obstacles,
closed-form time-optimal moves, the CasADi nonlinear programs and the receding-horizon planner."""

from .nlp import (  # noqa: F401
    MotionPlanner,
    MPCStep,
    RobotLimits,
    Trajectory,
    _time_optimal_pieces,
    free_interval,
    plan_motion,
)

__all__ = ["RobotLimits", "Trajectory", "free_interval", "plan_motion", "MotionPlanner", "MPCStep"]
