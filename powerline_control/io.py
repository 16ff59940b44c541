"""Deprecated path: ``powerline_control.io`` moved to ``powerline_control.output.io``."""

import warnings as _warnings

from .output.io import *  # noqa: F403
from .output.records import *  # noqa: F403

_warnings.warn("powerline_control.io is deprecated; import from powerline_control.output.io",
               DeprecationWarning, stacklevel=2)
