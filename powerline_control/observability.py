"""Deprecated path of :mod:`powerline_control.estimate` (observability now lives there).

Kept for one release so that old imports keep working; it warns on import.
"""

import warnings

from . import estimate as _home
from .estimate import *  # noqa: F403 - the same names, from their new home

__all__ = list(_home.__all__)

warnings.warn(
    "powerline_control.observability is deprecated; import from powerline_control.estimate",
    DeprecationWarning, stacklevel=2)
