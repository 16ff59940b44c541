"""Scenarios: the TOML schema and files (config, files, template), the pipeline that runs one stage
by stage into a frozen ScenarioResult (truth, sensing, stages, pipeline, result), and its report.

Three parts: the schema (``_schema``, ``config``, ``toml_values``, ``truth``, ``files``,
``template``), the computation (``sensing``, ``sensor_count``, ``result``, ``stages``,
``pipeline``, ``calibrate``) and the presentation (``summary_format``, ``summary_truth``, the
``summary_*`` sections, ``summary``, ``summary_json``). The presentation reads a result's fields
and recomputes nothing (it imports neither ``result``, ``stages`` nor ``pipeline``);
:class:`ScenarioResult`'s ``sections``, ``to_dict`` and ``write_report`` call it when asked. No
modules import each other in a circle (``tests/test_architecture.py``).
"""

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
