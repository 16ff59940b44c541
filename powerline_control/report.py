"""Deprecated path: ``powerline_control.report`` moved to ``powerline_control.output.report``."""

import warnings as _warnings

from .output.report import *  # noqa: F403

_warnings.warn("powerline_control.report is deprecated; import from "
               "powerline_control.output.report", DeprecationWarning, stacklevel=2)
