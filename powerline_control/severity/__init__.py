"""Aeolian severity: wind, self-damping, the energy balance, clamp strain and fatigue (balance),
wind records (record), damage over a record and rainflow counting (fatigue), the robot's value.

``powerline_control.severity`` keeps every name the single module ``severity.py`` had.
"""

from .balance import *  # noqa: F403 (the energy balance's public names, its __all__)
from .balance import (  # noqa: F401 (constants other modules and users import from here)
    ALUMINIUM_MODULUS,
    ENDURANCE_STRAIN_PP,
    GRAVITY,
    MAX_WIND_SPEED,
    POFFENBERGER_SWART_DISTANCE,
    SAFE_BORDER_LINES,
    SECONDS_PER_YEAR,
    _sbl_cycles,
    _sbl_stress,
)
from .balance import (
    __all__ as _balance_all,
)
from .fatigue import (
    FatigueOverRecord,
    RainflowCount,
    RecordDamage,
    fatigue_over_record,
    rainflow_count,
    rainflow_damage,
)
from .record import WindRecord

__all__ = [*_balance_all, "WindRecord", "FatigueOverRecord", "RainflowCount", "RecordDamage",
           "fatigue_over_record", "rainflow_count", "rainflow_damage"]
