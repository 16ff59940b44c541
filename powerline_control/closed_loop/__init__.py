"""The closed loop: the robot driven from a few sensors to where it damps best, and the verdict.

It calls the stages above it (estimator recipe, planner, the line's modes) and copies none.
"""

from ..simulation import ParkedSteadyState, parked_steady_state
from .aeolian_steady import AeolianSteady, aeolian_steady_state
from .loop import run_closed_loop
from .policy import Choice, choose_parked_position
from .policy_settings import PolicySettings
from .result import ClosedLoopResult, Comparison

__all__ = ["AeolianSteady", "Choice", "ClosedLoopResult", "Comparison", "ParkedSteadyState",
           "PolicySettings", "aeolian_steady_state", "choose_parked_position",
           "parked_steady_state", "run_closed_loop"]
