"""The line in time: simulate -> Snapshots, the moving-robot plant (plant.py; held_damping.py
when its damping follows its state) and the parked steady state, checked against the full FE.

``simulate`` lives in ``snapshots.py`` so that no module shares a public function's name (the
import system binds a submodule on its package, over a function of the same name).
"""

from .plant import ModalPlant
from .snapshots import Snapshots, simulate
from .steady_state import ParkedSteadyState, parked_steady_state

__all__ = ["ModalPlant", "ParkedSteadyState", "Snapshots", "parked_steady_state", "simulate"]
