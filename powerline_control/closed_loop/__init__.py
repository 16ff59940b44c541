"""The closed loop: the robot driven from a few sensors to where it damps best, and the verdict.

It calls the stages above it (estimator recipe, planner, the line's modes) and copies none.
"""

from .loop import run_closed_loop
from .result import ClosedLoopResult, Comparison

__all__ = ["ClosedLoopResult", "Comparison", "run_closed_loop"]
