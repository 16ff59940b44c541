"""Deprecated path: ``powerline_control.plotting`` moved to ``output.plotting``."""

import warnings as _warnings

from .output.captions import *  # noqa: F403
from .output.plotting import *  # noqa: F403

_warnings.warn("powerline_control.plotting is deprecated; import from "
               "powerline_control.output.plotting", DeprecationWarning, stacklevel=2)
