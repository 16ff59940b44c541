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
    UndetectableModeWarning,
    UnstableModelWarning,
)

# --- parameters and physics (line.py, fem.py, excitation.py, simulate.py) ---
from .excitation import AeolianForce, HarmonicForce, RandomForce, strouhal_frequency
from .fem import MDR, LineModel, ModalBasis, ModalDamping, RayleighDamping
from .line import Conductor, Span, conductors
from .simulate import Snapshots, simulate
from .tuning import den_hartog_optimum, tune_damper

# --- identification (identify.py) ---
from .identify import (
    AlphaCurve,
    DampingReport,
    DMDModel,
    OnlineDMD,
    StabilityReport,
    fit_dmd,
    select_alpha,
)
from .io import load_model, save_model
from .recipe import EstimatorDesign, design_estimator

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

# --- aeolian severity by the energy balance (severity.py) ---
from .severity import (
    SELF_DAMPING_LAWS, WIND_POWER_CURVES, AtAntinode, CatenaryCheck, ImpedanceDamper, RobotValue,
    SelfDampingLaw, SeverityResult, TimeDomainCheck, WindDistribution, WindPowerCurve,
    aeolian_severity, catenary_check, damper_impedance, damper_power, harmonic_mean_position,
    loop_length, robot_value, self_damping_power, standing_wave_shape, time_domain_check,
    turbulence_factor, wind_power,
)

# --- the whole chain (closed_loop.py) ---
from .closed_loop import ClosedLoopResult, run_closed_loop
from .studies import StudyResult, parameter_grid, run_study

__all__ = [
    "Accuracy",
    "aeolian_severity",
    "AeolianForce",
    "AlphaCurve",
    "analyze_observability",
    "Antinode",
    "AtAntinode",
    "Baseline",
    "catenary_check",
    "CatenaryCheck",
    "ClosedLoopResult",
    "compare_sensor_sets",
    "Conductor",
    "conductors",
    "Consistency",
    "damper_impedance",
    "damper_power",
    "DampingReport",
    "design_estimator",
    "den_hartog_optimum",
    "DMDModel",
    "Estimate",
    "estimation_accuracy",
    "EstimationError",
    "EstimatorDesign",
    "FileFormatError",
    "filter_consistency",
    "fit_dmd",
    "harmonic_mean_position",
    "HarmonicForce",
    "IdentificationError",
    "IllConditionedWarning",
    "ImpedanceDamper",
    "InputError",
    "KalmanFilter",
    "largest_antinode",
    "LineModel",
    "load_model",
    "locate_antinodes",
    "loop_length",
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
    "PlanningError",
    "PowerlineControlError",
    "PresetNotFoundError",
    "RandomForce",
    "RayleighDamping",
    "robot_value",
    "RobotLimits",
    "RobotValue",
    "run_closed_loop",
    "run_study",
    "save_model",
    "select_alpha",
    "select_sensors",
    "SELF_DAMPING_LAWS",
    "self_damping_power",
    "SelfDampingLaw",
    "sensor_count_study",
    "SensorCountStudy",
    "SensorSelection",
    "SensorSelectionError",
    "SensorSetComparison",
    "SeverityResult",
    "simulate",
    "Snapshots",
    "Span",
    "StabilityReport",
    "standing_wave_shape",
    "steady_state_covariance",
    "strouhal_frequency",
    "StudyResult",
    "time_domain_check",
    "TimeDomainCheck",
    "Trajectory",
    "TruncationWarning",
    "turbulence_factor",
    "UndetectableModeWarning",
    "tune_damper",
    "UnstableModelWarning",
    "wind_power",
    "WIND_POWER_CURVES",
    "WindDistribution",
    "WindPowerCurve",
]

__version__ = "0.1.0"
