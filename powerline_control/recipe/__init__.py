"""The estimator recipe: design_estimator identifies a model (time-delay DMD, or one oscillator
per spectral line of a narrowband record), chooses the sensors and builds the filter.

Modules: design (the public entry), record, dmd, modal, sensing, results, coverage, count,
defaults. ``powerline_control.recipe`` keeps every name the single module ``recipe.py`` had.
"""

from .count import EstimatorCountStudy, estimator_count_study
from .coverage import Coverage
from .design import design_estimator
from .results import AlphaSweep, EstimatorDesign, ExcitationReport

__all__ = ["AlphaSweep", "Coverage", "EstimatorCountStudy", "EstimatorDesign", "ExcitationReport",
           "design_estimator", "estimator_count_study"]
