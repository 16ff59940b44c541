"""The line's finite-element model: LineModel and its damping (model.py), meshes and element
matrices (mesh.py), the robot MDR and the dampers' impedance (damper.py), its tuning (tuning.py).
"""

# The names imported "as" themselves are not in __all__ but are imported from
# powerline_control.fem by the package, tests and docs.
from .damper import MDR, den_hartog_optimum
from .damper import AtAntinode as AtAntinode  # the dampers' impedance: severity re-exports these
from .damper import ImpedanceDamper as ImpedanceDamper
from .damper import damper_impedance as damper_impedance
from .mesh import BENDING_ERROR_CONSTANT as BENDING_ERROR_CONSTANT
from .mesh import BOUNDARY_LAYER_REFINEMENT as BOUNDARY_LAYER_REFINEMENT
from .mesh import DEFAULT_WIND_SPEEDS as DEFAULT_WIND_SPEEDS
from .mesh import GRADING_RATIO as GRADING_RATIO
from .mesh import MIN_ELEMENTS_PER_LOOP as MIN_ELEMENTS_PER_LOOP
from .mesh import SAMPLING_ELEMENTS_PER_LOOP as SAMPLING_ELEMENTS_PER_LOOP
from .mesh import TENSION_ERROR_CONSTANT as TENSION_ERROR_CONSTANT
from .mesh import (
    accuracy_elements_per_loop,
    aeolian_band_top,
    frequency_error_estimate,
    physics_mesh,
)
from .mesh import clamp_error_estimate as clamp_error_estimate
from .model import DENSE_EIGEN_LIMIT as DENSE_EIGEN_LIMIT
from .model import LineModel, ModalBasis, ModalDamping, RayleighDamping
from .tuning import tune_damper

__all__ = ["LineModel", "MDR", "ModalDamping", "RayleighDamping", "ModalBasis", "physics_mesh",
           "frequency_error_estimate", "accuracy_elements_per_loop", "aeolian_band_top",
           "den_hartog_optimum", "tune_damper"]
