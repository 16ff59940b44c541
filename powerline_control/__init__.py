"""powerline_control: vibration of overhead power lines, on top of python-control.

Data flows one way: model -> simulate -> identify -> estimate / sensors -> antinode -> plan ->
closed loop -> report / CLI.  See ``docs/`` and the README.
"""

from .errors import (
    EstimationError,
    FileFormatError,
    IdentificationError,
    IllConditionedWarning,
    InputError,
    ModelError,
    PlanningError,
    PowerlineControlError,
    PresetNotFoundError,
    SensorSelectionError,
    TruncationWarning,
    UnstableModelWarning,
)

# --- parameters and physics (line.py, fem.py, excitation.py, simulate.py) ---
from .excitation import AeolianForce, HarmonicForce, RandomForce, strouhal_frequency
from .fem import MDR, LineModel, ModalBasis, ModalDamping, RayleighDamping
from .line import Conductor, Span, conductors
from .simulate import Snapshots, simulate

# --- identification (identify.py) ---
from .identify import (
    AlphaCurve,
    DMDModel,
    OnlineDMD,
    StabilityReport,
    fit_dmd,
    select_alpha,
)
from .io import load_model, save_model

# --- observability and estimation (observability.py, estimate.py) ---
from .estimate import (
    Accuracy,
    Consistency,
    Estimate,
    KalmanFilter,
    estimation_accuracy,
    filter_consistency,
)
from .observability import (
    ObservabilityReport,
    SensorSetComparison,
    analyze_observability,
    compare_sensor_sets,
    observability_gramian,
    observability_rank,
    steady_state_covariance,
)

# --- sensor placement (sensors.py) ---
from .sensors import Baseline, SensorCountStudy, SensorSelection, select_sensors, sensor_count_study

# --- antinodes and motion planning (antinode.py, plan.py) ---
from .antinode import Antinode, largest_antinode, locate_antinodes, nearest_antinode
from .plan import MotionPlanner, MPCStep, RobotLimits, Trajectory, plan_motion

# --- the whole chain (closed_loop.py) ---
from .closed_loop import ClosedLoopResult, run_closed_loop
from .studies import StudyResult, parameter_grid, point_seed, run_study

__all__ = [
    "Accuracy",
    "AeolianForce",
    "AlphaCurve",
    "analyze_observability",
    "Antinode",
    "Baseline",
    "ClosedLoopResult",
    "compare_sensor_sets",
    "Conductor",
    "conductors",
    "Consistency",
    "DMDModel",
    "Estimate",
    "estimation_accuracy",
    "EstimationError",
    "FileFormatError",
    "filter_consistency",
    "fit_dmd",
    "HarmonicForce",
    "IdentificationError",
    "IllConditionedWarning",
    "InputError",
    "KalmanFilter",
    "largest_antinode",
    "LineModel",
    "load_model",
    "locate_antinodes",
    "MDR",
    "ModalBasis",
    "ModalDamping",
    "ModelError",
    "MotionPlanner",
    "MPCStep",
    "nearest_antinode",
    "observability_gramian",
    "observability_rank",
    "ObservabilityReport",
    "OnlineDMD",
    "parameter_grid",
    "plan_motion",
    "point_seed",
    "PlanningError",
    "PowerlineControlError",
    "PresetNotFoundError",
    "RandomForce",
    "RayleighDamping",
    "RobotLimits",
    "run_closed_loop",
    "run_study",
    "save_model",
    "select_alpha",
    "select_sensors",
    "sensor_count_study",
    "SensorCountStudy",
    "SensorSelection",
    "SensorSelectionError",
    "SensorSetComparison",
    "simulate",
    "Snapshots",
    "Span",
    "StabilityReport",
    "steady_state_covariance",
    "strouhal_frequency",
    "StudyResult",
    "Trajectory",
    "TruncationWarning",
    "UnstableModelWarning",
]

__version__ = "0.1.0"
