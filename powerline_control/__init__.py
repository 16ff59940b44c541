"""powerline_control: vibration of overhead power lines, on top of python-control.

Data flows one way: model -> simulate -> identify -> estimate / sensors -> antinode -> plan ->
closed loop -> report / CLI.  See ``docs/`` and the README.
"""

# Public names load lazily (PEP 562): ``import powerline_control`` costs milliseconds and the
# ``powerline-control --help`` command never pays for numpy, SciPy, python-control, cvxpy or
# CasADi. Add a new export as a line of this table (module -> names), not as an eager import.
from .errors import (
    EstimationError,
    EstimatorInconsistentWarning,
    ExcitationWarning,
    FileFormatError,
    IdentificationError,
    IllConditionedWarning,
    InputError,
    PlanningError,
    PowerlineControlError,
    SensorSelectionError,
    TruncationWarning,
    UnstableModelWarning,
)

_LAZY_EXPORTS = {
    "excitation": (
        "AeolianForce", "HarmonicForce", "RandomForce",
    ),
    "fem": (
        "MDR", "LineModel", "ModalDamping", "RayleighDamping",
    ),
    "line": (
        "Conductor", "Span", "conductors", "tension_at_temperature",
    ),
    "simulation": (
        "Snapshots", "simulate",
    ),
    "fem.tuning": (
        "tune_damper",
    ),
    "identify": (
        "DMDModel", "OnlineDMD", "fit_dmd", "select_alpha", "SpanCalibration", "calibrate_span",
    ),
    "output.io": (
        "load_model", "save_model",
    ),
    "output.records": (
        "Record", "load_record", "save_record",
    ),
    "recipe": (
        "EstimatorDesign", "design_estimator",
    ),
    "estimate": (
        "Estimate", "KalmanFilter", "estimation_accuracy",
    ),
    "sensors": (
        "SensorSelection", "select_sensors",
    ),
    "antinode": (
        "Antinode", "locate_antinodes", "nearest_antinode",
    ),
    "plan": (
        "MotionPlanner", "RobotLimits", "Trajectory", "plan_motion",
    ),
    "severity": (
        "SeverityResult", "aeolian_severity", "FatigueOverRecord", "WindRecord",
        "fatigue_over_record",
    ),
    "closed_loop": (
        "ClosedLoopResult", "PolicySettings", "run_closed_loop",
    ),
    "studies": (
        "StudyResult", "parameter_grid", "run_study",
    ),
    "scenario": (
        "Scenario", "load_scenario",
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


# What a user imports daily: the names of docs' getting started and design.md section 3, the
# results they return and the errors to catch, sorted. Everything else is public in its
# subpackage, where the docs list it: plc.severity.robot_value, plc.estimate.analyze_observability,
# plc.errors.ReachWarning, plc.simulation.parked_steady_state, ...
__all__ = [
    "AeolianForce",
    "Antinode",
    "ClosedLoopResult",
    "Conductor",
    "DMDModel",
    "Estimate",
    "EstimationError",
    "EstimatorDesign",
    "EstimatorInconsistentWarning",
    "ExcitationWarning",
    "FatigueOverRecord",
    "FileFormatError",
    "HarmonicForce",
    "IdentificationError",
    "IllConditionedWarning",
    "InputError",
    "KalmanFilter",
    "LineModel",
    "MDR",
    "ModalDamping",
    "MotionPlanner",
    "OnlineDMD",
    "PlanningError",
    "PolicySettings",
    "PowerlineControlError",
    "RandomForce",
    "RayleighDamping",
    "Record",
    "RobotLimits",
    "Scenario",
    "ScenarioResult",
    "SensorSelection",
    "SensorSelectionError",
    "SeverityResult",
    "Snapshots",
    "Span",
    "SpanCalibration",
    "StudyResult",
    "Trajectory",
    "TruncationWarning",
    "UnstableModelWarning",
    "WindRecord",
    "aeolian_severity",
    "calibrate_span",
    "conductors",
    "design_estimator",
    "estimation_accuracy",
    "fatigue_over_record",
    "fit_dmd",
    "load_model",
    "load_record",
    "load_scenario",
    "locate_antinodes",
    "nearest_antinode",
    "parameter_grid",
    "plan_motion",
    "run_closed_loop",
    "run_scenario",
    "run_study",
    "save_model",
    "save_record",
    "select_alpha",
    "select_sensors",
    "simulate",
    "tension_at_temperature",
    "tune_damper",
]

__version__ = "0.1.0"
