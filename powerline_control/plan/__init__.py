"""Motion of the mobile damping robot along the span: its limits, the free space between obstacles,
closed-form time-optimal moves, one CasADi plan (plan_motion) and the receding-horizon planner."""

from .closed_form import Trajectory, _time_optimal_pieces  # noqa: F401  (benchmarks use it)
from .free_space import check_obstacles, free_interval
from .limits import RobotLimits
from .mpc import MotionPlanner, MPCStep
from .nlp import plan_motion

__all__ = ["RobotLimits", "Trajectory", "check_obstacles", "free_interval", "plan_motion",
           "MotionPlanner", "MPCStep"]
