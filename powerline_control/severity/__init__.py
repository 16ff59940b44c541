"""Aeolian severity of a span: wind power, self-damping, the standing wave and its dampers, the
energy balance and clamp strain, wind climates and records, fatigue, the robot's value, checks.

Modules: wind, self_damping, dampers, balance, aeolian_run (the same powers in the time
domain), modal (those powers as the plant's modal damping, and the limit cycle with the robot
coupled), coupled (the balance with the robot coupled to the line), self_limiting (the
self-limiting wind as a simulated line's choice), aeolian_record (a record in that wind:
simulate's Snapshots), climate, checks, record, fatigue, and clamp_estimate (clamp strain from an
estimator's field, with its sigma).
``powerline_control.severity`` keeps every name the single module ``severity.py`` had.
"""

from ._common import (  # noqa: F401 (constants other modules and users import from here)
    AIR_DENSITY,
    ALUMINIUM_MODULUS,
    ENDURANCE_FAMILY,
    ENDURANCE_STRAIN_PP,
    GRAVITY,
    MAX_FREQUENCY,
    MAX_WIND_SPEED,
    POFFENBERGER_SWART_DISTANCE,
    SECONDS_PER_YEAR,
)
from .aeolian_record import *  # noqa: F403 (each module's public names: its __all__)
from .aeolian_record import __all__ as _aeolian_record_all
from .aeolian_run import *  # noqa: F403
from .aeolian_run import __all__ as _aeolian_run_all
from .balance import *  # noqa: F403
from .balance import SAFE_BORDER_LINES  # noqa: F401
from .balance import __all__ as _balance_all
from .checks import *  # noqa: F403
from .checks import __all__ as _checks_all
from .clamp_estimate import *  # noqa: F403
from .clamp_estimate import __all__ as _clamp_estimate_all
from .climate import *  # noqa: F403
from .climate import __all__ as _climate_all
from .coupled import *  # noqa: F403
from .coupled import __all__ as _coupled_all
from .dampers import *  # noqa: F403
from .dampers import __all__ as _dampers_all
from .fatigue import *  # noqa: F403
from .fatigue import __all__ as _fatigue_all
from .modal import *  # noqa: F403
from .modal import __all__ as _modal_all
from .record import *  # noqa: F403
from .record import __all__ as _record_all
from .self_damping import *  # noqa: F403
from .self_damping import __all__ as _self_damping_all
from .wind import *  # noqa: F403
from .wind import __all__ as _wind_all

__all__ = [*_wind_all, *_dampers_all, *_balance_all, *_climate_all, *_checks_all, *_record_all,
           *_fatigue_all, *_self_damping_all, *_clamp_estimate_all, *_aeolian_run_all,
           *_coupled_all, *_aeolian_record_all,
           *_modal_all]
