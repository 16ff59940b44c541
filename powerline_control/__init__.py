"""powerline_control: vibration of overhead power lines, on top of python-control.

Data flows one way: model -> simulate -> identify -> estimate / sensors -> antinode -> plan ->
closed loop -> report / CLI.  See ``docs/`` and the README.
"""

# Public names load lazily (PEP 562): ``import powerline_control`` costs milliseconds and the
# ``powerline-control --help`` command never pays for numpy, SciPy, python-control, cvxpy or
# CasADi. Add a new export as a line of this table (module -> names), not as an eager import.
from .errors import (
    CalibrationWarning,
    EstimationError,
    EstimatorInconsistentWarning,
    ExcitationWarning,
    FileFormatError,
    IdentificationError,
    IllConditionedWarning,
    InputError,
    ModelError,
    ModelErrorRecordsWarning,
    PlanningError,
    PowerlineControlError,
    PresetNotFoundError,
    ReachWarning,
    SaturationWarning,
    SensorSelectionError,
    ShortfallWarning,
    TruncationWarning,
    UndetectableModeWarning,
    UnstableModelWarning,
)

_LAZY_EXPORTS = {
    "excitation": (
        "AeolianForce", "HarmonicForce", "RandomForce", "strouhal_frequency",
    ),
    "fem": (
        "MDR", "LineModel", "ModalBasis", "ModalDamping", "RayleighDamping",
    ),
    "line": (
        "Conductor", "Span", "conductors", "tension_at_temperature",
    ),
    "simulation": (
        "ParkedSteadyState", "Snapshots", "parked_steady_state", "simulate",
    ),
    "fem.damper": (
        "AtAntinode", "ImpedanceDamper", "damper_impedance", "den_hartog_optimum",
    ),
    "fem.tuning": (
        "tune_damper",
    ),
    "identify": (
        "AlphaCurve", "DampingReport", "DMDModel", "OnlineDMD", "OscillatorModel",
        "StabilityReport", "fit_dmd", "select_alpha", "SpanCalibration", "calibrate_span",
    ),
    "output.io": (
        "load_model", "save_model",
    ),
    "output.records": (
        "Record", "load_record", "save_record",
    ),
    "recipe": (
        "Coverage", "EstimatorDesign", "design_estimator",
    ),
    "severity.clamp_estimate": (
        "ClampStrainEstimate", "estimate_clamp_strain",
    ),
    "recipe.count": (
        "EstimatorCountStudy", "estimator_count_study",
    ),
    "estimate": (
        "Accuracy", "Consistency", "Estimate", "KalmanFilter", "estimation_accuracy",
        "filter_consistency",
    ),
    "estimate.result": (
        "Recovery", "recovery_time",
    ),
    "estimate.observability": (
        "ObservabilityReport", "SensorSetComparison", "analyze_observability",
        "compare_sensor_sets", "observability_gramian", "observability_rank",
        "steady_state_covariance",
    ),
    "sensors": (
        "Baseline", "SensorCountStudy", "SensorSelection", "select_sensors", "sensor_count_study",
    ),
    "antinode": (
        "Antinode", "largest_antinode", "locate_antinodes", "nearest_antinode",
    ),
    "plan": (
        "MotionPlanner", "MPCStep", "RobotLimits", "Trajectory", "free_interval", "plan_motion",
    ),
    "severity": (
        "SELF_DAMPING_LAWS", "WIND_POWER_CURVES", "CatenaryCheck", "RobotValue",
        "SelfDampingLaw", "SeverityResult", "TimeDomainCheck", "WindDistribution",
        "WindPowerCurve", "aeolian_severity", "catenary_check", "damper_power",
        "harmonic_mean_position", "loop_length",
        "robot_value", "self_damping_power", "standing_wave_shape", "time_domain_check",
        "turbulence_factor", "wind_power",
        # wind records, damage over a record, rainflow counting
        "FatigueOverRecord", "RainflowCount", "RecordDamage", "WindRecord", "fatigue_over_record",
        "rainflow_count", "rainflow_damage",
        # the physical self-damping model (Foti & Martinelli)
        "STRANDINGS", "FotiMartinelli", "StrandLayer", "StrandedBending", "stranded_bending",
    ),
    "closed_loop": (
        "Choice", "ClosedLoopResult", "choose_parked_position", "run_closed_loop",
    ),
    "studies": (
        "StudyResult", "parameter_grid", "point_seed", "run_study",
    ),
    "scenario": (
        "Scenario", "load_scenario", "shipped_scenarios",
    ),
    "scenario.pipeline": (
        "ScenarioResult", "run_scenario",
    ),
}
_MODULE_OF = {name: module for module, names in _LAZY_EXPORTS.items() for name in names}


def __getattr__(name: str):
    """Import a public name (or a submodule) on first use."""
    import importlib

    module = _MODULE_OF.get(name)
    if module is not None:
        value = getattr(importlib.import_module(f".{module}", __name__), name)
        globals()[name] = value
        return value
    try:
        return importlib.import_module(f".{name}", __name__)
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{name}":
            raise
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_MODULE_OF))


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
    "calibrate_span",
    "CalibrationWarning",
    "CatenaryCheck",
    "ClampStrainEstimate",
    "Choice",
    "choose_parked_position",
    "ClosedLoopResult",
    "compare_sensor_sets",
    "Conductor",
    "conductors",
    "Consistency",
    "Coverage",
    "damper_impedance",
    "damper_power",
    "DampingReport",
    "den_hartog_optimum",
    "design_estimator",
    "DMDModel",
    "Estimate",
    "estimate_clamp_strain",
    "estimation_accuracy",
    "estimator_count_study",
    "EstimatorCountStudy",
    "EstimationError",
    "EstimatorInconsistentWarning",
    "EstimatorDesign",
    "ExcitationWarning",
    "FileFormatError",
    "free_interval",
    "filter_consistency",
    "fit_dmd",
    "harmonic_mean_position",
    "HarmonicForce",
    "IdentificationError",
    "IllConditionedWarning",
    "ImpedanceDamper",
    "InputError",
    "KalmanFilter",
    "Recovery",
    "recovery_time",
    "largest_antinode",
    "LineModel",
    "load_model",
    "load_record",
    "load_scenario",
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
    "OscillatorModel",
    "parameter_grid",
    "parked_steady_state",
    "ParkedSteadyState",
    "plan_motion",
    "point_seed",
    "PlanningError",
    "PowerlineControlError",
    "PresetNotFoundError",
    "RandomForce",
    "RayleighDamping",
    "ReachWarning",
    "SaturationWarning",
    "ShortfallWarning",
    "SpanCalibration",
    "ModelErrorRecordsWarning",
    "robot_value",
    "RobotLimits",
    "RobotValue",
    "run_closed_loop",
    "Record",
    "run_scenario",
    "run_study",
    "save_model",
    "save_record",
    "Scenario",
    "ScenarioResult",
    "select_alpha",
    "select_sensors",
    "shipped_scenarios",
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
    "tune_damper",
    "turbulence_factor",
    "UndetectableModeWarning",
    "UnstableModelWarning",
    "wind_power",
    "WIND_POWER_CURVES",
    "WindDistribution",
    "WindPowerCurve",
    "tension_at_temperature",
    "FatigueOverRecord",
    "RainflowCount",
    "RecordDamage",
    "WindRecord",
    "fatigue_over_record",
    "rainflow_count",
    "rainflow_damage",
    "FotiMartinelli",
    "STRANDINGS",
    "StrandLayer",
    "StrandedBending",
    "stranded_bending",
]

__version__ = "0.1.0"
