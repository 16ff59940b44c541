"""Deprecated path: the absorber's tuning lives in :mod:`powerline_control.fem` (fem/damper.py).

Kept for one release so old imports keep working; importing it warns.
"""

import warnings

from .fem import (
    MDR,
    LineModel,
    ModalBasis,
    ModalDamping,
    RayleighDamping,
    accuracy_elements_per_loop,
    aeolian_band_top,
    den_hartog_optimum,
    frequency_error_estimate,
    physics_mesh,
    tune_damper,
)
from .fem.damper import NODE_TOLERANCE

__all__ = ["den_hartog_optimum", "tune_damper", "NODE_TOLERANCE", "LineModel", "MDR",
           "ModalDamping", "RayleighDamping", "ModalBasis", "physics_mesh",
           "frequency_error_estimate", "accuracy_elements_per_loop", "aeolian_band_top"]

warnings.warn("powerline_control.tuning is deprecated; import from powerline_control.fem",
              DeprecationWarning, stacklevel=2)
