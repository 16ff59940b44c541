"""Scenarios: the TOML schema and files (config, truth, files, template), and the pipeline that runs
one stage by stage (stages, sensing, pipeline) into a frozen ScenarioResult (result, summary*)."""

from .config import (
    EstimationConfig,
    ForcingConfig,
    IdentificationConfig,
    ModelConfig,
    RobotConfig,
    Scenario,
    ScenarioInfo,
    SeverityConfig,
    SimulationConfig,
    SpanConfig,
    check_severity_inputs,
    default_scenario,
)
from .files import load_scenario, override_scenario_text, read_scenario_text, shipped_scenarios
from .template import scenario_reference, scenario_to_toml
from .truth import TruthConfig, true_model, true_span

__all__ = [
    "EstimationConfig",
    "ForcingConfig",
    "IdentificationConfig",
    "ModelConfig",
    "RobotConfig",
    "Scenario",
    "ScenarioInfo",
    "SeverityConfig",
    "SimulationConfig",
    "SpanConfig",
    "TruthConfig",
    "check_severity_inputs",
    "default_scenario",
    "load_scenario",
    "override_scenario_text",
    "read_scenario_text",
    "scenario_reference",
    "scenario_to_toml",
    "shipped_scenarios",
    "true_model",
    "true_span",
]
