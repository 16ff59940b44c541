"""The closed loop's simulated line in the self-limiting aeolian wind (``run_closed_loop(wind=)``).

With ``wind="fixed_lift"`` (the default) an :class:`~powerline_control.excitation.AeolianForce`
is a lift of fixed amplitude on a line with the model's fixed damping. With
``wind="self_limiting"`` (or a mapping of the physics' options) the same wind is the energy
balance's own physics, as in :func:`~powerline_control.severity.simulate_aeolian`: the wind's
power from the power curve at the locked mode's current amplitude, as a negative modal damping on
that mode, and the conductor's self-damping on every mode at its own amplitude, both recomputed
from the plant's state at every plant block by the one function that maps them
(:class:`~powerline_control.severity.AeolianDamping`). No lift is applied: the wind's only
action is that negative damping. The line starts vibrating at the energy balance's amplitude
without the robot (a line already vibrating when the robot starts), so a run shows the robot
bringing the amplitude down to its new steady level. Only the simulated truth changes: the
controller sees its sensors and its own records, as under the fixed lift.

The choice and its plant's wind have one home,
:mod:`powerline_control.severity.self_limiting` (the self-limiting record,
:func:`~powerline_control.severity.simulate_self_limiting`, uses them too); this module keeps
their names where the closed loop's readers look for them.
"""

from __future__ import annotations

from ..severity.self_limiting import (
    WIND_OPTIONS,
    WINDS,
    SelfLimitingWind,
    checked_wind,
    self_limiting_wind,
)

__all__ = ["WINDS", "WIND_OPTIONS", "SelfLimitingWind", "checked_wind", "self_limiting_wind"]
