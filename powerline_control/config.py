"""Deprecated path: ``powerline_control.config`` moved to ``powerline_control.scenario``.

The schema and its loading live in :mod:`powerline_control.scenario.config`, the commented
template in :mod:`powerline_control.scenario.template`.
"""

import warnings as _warnings

from .scenario.config import (  # noqa: F401  (re-exported)
    MAX_ELEMENTS,
    MAX_SAMPLES,
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
from .scenario.files import (  # noqa: F401  (re-exported)
    load_scenario,
    override_scenario_text,
    read_scenario_text,
    shipped_scenarios,
)
from .scenario.template import scenario_reference, scenario_to_toml  # noqa: F401
from .scenario.truth import TruthConfig, true_model, true_span  # noqa: F401  (re-exported)

__all__ = [
    "Scenario",
    "load_scenario",
    "scenario_to_toml",
    "default_scenario",
    "shipped_scenarios",
    "scenario_reference",
    "check_severity_inputs",
    "read_scenario_text",
    "override_scenario_text",
]

_warnings.warn("powerline_control.config is deprecated; import from powerline_control.scenario",
               DeprecationWarning, stacklevel=2)
