"""The line in time: simulate -> Snapshots (snapshots.py), the moving-robot plant (plant.py) and
the parked steady state (steady_state.py), both checked against the full FE with the robot.

``simulate`` lives in ``snapshots.py`` so that no module shares a public function's name (the
import system binds a submodule on its package, over a function of the same name).
"""

from .plant import ModalPlant
from .snapshots import Snapshots, simulate
from .steady_state import ParkedSteadyState, parked_steady_state

__all__ = ["ModalPlant", "ParkedSteadyState", "Snapshots", "parked_steady_state", "simulate"]
