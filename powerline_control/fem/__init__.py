"""The line's finite-element model: LineModel, its meshes and element matrices, and the robot
(MDR) with the tuning of its absorber.
"""

# The names imported "as" themselves are not in __all__ but are imported from
# powerline_control.fem by the package, tests and docs.
from .model import BENDING_ERROR_CONSTANT as BENDING_ERROR_CONSTANT
from .model import BOUNDARY_LAYER_REFINEMENT as BOUNDARY_LAYER_REFINEMENT
from .model import DEFAULT_WIND_SPEEDS as DEFAULT_WIND_SPEEDS
from .model import DENSE_EIGEN_LIMIT as DENSE_EIGEN_LIMIT
from .model import GRADING_RATIO as GRADING_RATIO
from .model import (
    MDR,
    LineModel,
    ModalBasis,
    ModalDamping,
    RayleighDamping,
    accuracy_elements_per_loop,
    aeolian_band_top,
    frequency_error_estimate,
    physics_mesh,
)
from .model import MIN_ELEMENTS_PER_LOOP as MIN_ELEMENTS_PER_LOOP
from .model import SAMPLING_ELEMENTS_PER_LOOP as SAMPLING_ELEMENTS_PER_LOOP
from .model import TENSION_ERROR_CONSTANT as TENSION_ERROR_CONSTANT
from .model import clamp_error_estimate as clamp_error_estimate

__all__ = ["LineModel", "MDR", "ModalDamping", "RayleighDamping", "ModalBasis", "physics_mesh",
           "frequency_error_estimate", "accuracy_elements_per_loop", "aeolian_band_top"]
