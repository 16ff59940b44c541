"""The self-limiting aeolian wind as a choice of a simulated line: ``wind="fixed_lift"`` or the
energy balance's own physics (``"self_limiting"``, or a mapping of its options).

With ``wind="fixed_lift"`` an :class:`~powerline_control.excitation.AeolianForce` is a lift of
fixed amplitude on a line with the model's fixed damping. With ``wind="self_limiting"`` the same
wind is the energy balance's physics, as in :func:`~.aeolian_run.simulate_aeolian`: the wind's
power from the power curve at the locked mode's current amplitude, as a negative modal damping
on that mode, and the conductor's self-damping on every band mode at its own amplitude, both
recomputed from the plant's state at every plant block by the one function that maps them
(:class:`~.modal.AeolianDamping`). No lift is applied: the wind's only action is that
negative damping. The closed loop (``run_closed_loop(wind=)``) and the self-limiting record
(:func:`~.aeolian_record.simulate_self_limiting`) check the choice here
(:func:`checked_wind`) and build their plants' wind here (:func:`self_limiting_wind`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..excitation import AeolianForce
from ..fem import LineModel
from ..line import Span
from ..simulation.held_damping import HeldDamping, run_held
from ..simulation.plant import ModalPlant
from .balance import aeolian_severity
from .modal import (
    LOWEST_REDUCED_AMPLITUDE,
    MAX_WIND_RATIO,
    AeolianDamping,
    aeolian_damping,
    power_ratio,
)

__all__ = ["WINDS", "WIND_OPTIONS", "SelfLimitingWind", "checked_wind", "known_options",
           "self_limiting_wind", "settling_balance"]

#: The aeolian loads of a simulated line: the lift of fixed amplitude on the model's damping,
#: or the energy balance's self-limiting physics.
WINDS = ("fixed_lift", "self_limiting")

#: The self-limiting physics' options a caller may set: the wind's power curve and the
#: conductor's self-damping law (:func:`~.balance.aeolian_severity`'s names). The span, the
#: supports, the mesh, the Strouhal number and the robot are the simulated line's own.
WIND_OPTIONS = ("wind_curve", "turbulence_intensity", "self_damping", "self_damping_k",
                "self_damping_exponents")


def known_options(parameter: str, value: Mapping, allowed: Sequence[str]) -> dict:
    """``value`` as a dict, refused with an InputError naming ``parameter`` when it names an
    option of the self-limiting physics outside ``allowed``.

    Examples
    --------
    >>> known_options("wind", {"wind_curve": "cigre"}, WIND_OPTIONS)
    {'wind_curve': 'cigre'}
    """
    unknown = [key for key in value if key not in allowed]
    if unknown:
        raise InputError(
            f"The '{parameter}' parameter names options {unknown} that the self-limiting "
            f"physics does not take here: allowed are {list(allowed)} (the span, supports, mesh "
            "and robot are the simulated line's own).")
    return dict(value)


def checked_wind(value: object, segments: list, model: LineModel) -> dict | None:
    """A simulated line's ``wind``: None for the fixed lift, else the self-limiting physics'
    options (a mapping: those; "self_limiting": none, the severity study's defaults), with the
    wind (``"wind"``) and the energy balance's amplitude of the line without a robot
    (``"amplitude"``, m). ``segments``: the run's loads, ``[(start time, [loads])]``. Refused:
    another name or option, a load that is not one AeolianForce for the whole run, supports
    that differ at the two ends, and a wind whose energy balance leaves the power curve's data
    or sustains no vibration, or lies too far below it for the simulated wind to hold
    (:func:`settling_balance`), before the run.

    Examples
    --------
    >>> from powerline_control import AeolianForce, LineModel, Span
    >>> model = LineModel(Span.at_rts_fraction(60.0, "drake", 0.2), bc="pinned")
    >>> checked_wind("fixed_lift", [(0.0, [AeolianForce(3.0)])], model) is None
    True
    >>> options = checked_wind("self_limiting", [(0.0, [AeolianForce(3.0)])], model)
    >>> round(options["amplitude"] * 1e3, 1)      # the energy balance's antinode amplitude, mm
    8.5
    """
    if isinstance(value, str):
        if value not in WINDS:
            raise InputError(f"The 'wind' parameter must be one of {list(WINDS)} or a mapping "
                             f"of the self-limiting physics' options {list(WIND_OPTIONS)}. Got "
                             f"{value!r}.")
        if value == "fixed_lift":
            return None
        options = {}
    elif isinstance(value, Mapping):
        options = known_options("wind", value, WIND_OPTIONS)
    else:
        raise InputError(f"The 'wind' parameter must be one of {list(WINDS)} or a mapping of "
                         f"the self-limiting physics' options {list(WIND_OPTIONS)}. Got "
                         f"{value!r:.60} of type {type(value).__name__}.")
    loads = [load for _, items in segments for load in items]
    if len(segments) != 1 or len(loads) != 1 or not isinstance(loads[0], AeolianForce):
        raise InputError(
            "The 'wind' parameter 'self_limiting' drives the line by one AeolianForce for the "
            "whole run (its wind speed and Strouhal number). Got "
            f"{[type(f).__name__ for f in loads]} in {len(segments)} segment(s): use "
            "wind='fixed_lift' for other loads or a schedule.")
    left, right = model.bc
    if left != right:
        raise InputError(
            "The 'wind' parameter 'self_limiting' needs the same support at both ends (the "
            f"energy balance takes 'clamped' or 'pinned'). Got bc={model.bc}.")
    wind = loads[0]
    physics = dict(options)
    amplitude, problem = settling_balance(model.span, wind, left, physics)
    if problem is not None:
        raise InputError(f"The 'force' wind speed {wind.wind_speed:g} m/s {problem}, or use "
                         "wind='fixed_lift'.")
    return {"wind": wind, "amplitude": amplitude, **physics}


def settling_balance(span: Span, wind: AeolianForce, bc: str,
                     physics: Mapping | None = None) -> tuple[float, str | None]:
    """(amplitude, problem): the energy balance's antinode amplitude (m) of ``span`` with no
    damper in ``wind`` on supports ``bc``, and why the self-limiting physics cannot settle a
    simulated line there (None when it can), in words that say what would work.

    It cannot past the power curve's data, where the wind sustains no vibration, and where the
    balance needs more of the wind than the simulated wind gives: a damping ratio above
    :data:`~.modal.MAX_WIND_RATIO` on the locked mode, or an amplitude below
    :data:`~.modal.LOWEST_REDUCED_AMPLITUDE` D. There the balance is held far below the power
    curve's data (by the CIGRE cubic's power at rest), and the simulated line decays far below it
    (Oxlip 40 m pinned at 1 m/s: the balance 1.4e-3 D needs a ratio of 0.53, and the line
    settles at 3e-5 D; at 40 % RTS, 3.2e-3 D needs 0.11 and the line settles 14 % low; the real
    conductors' balances need 1e-3). ``physics``: the power curve and self-damping options
    (:data:`WIND_OPTIONS`).

    Examples
    --------
    >>> from powerline_control import AeolianForce, Span
    >>> drake = Span.at_rts_fraction(40.0, "drake", 0.2)
    >>> amplitude, problem = settling_balance(drake, AeolianForce(3.0), "pinned")
    >>> round(amplitude * 1e3, 2), problem
    (8.52, None)
    >>> oxlip = Span.at_rts_fraction(40.0, "oxlip", 0.2)
    >>> print(settling_balance(oxlip, AeolianForce(1.0), "pinned")[1])
    sustains only 0.0151 mm on this span by the energy balance (0.0014 D), far below the \
'cigre' power curve's data: the balance needs a wind damping ratio of 0.53 on the locked mode, \
and the simulated wind gives at most 0.1, at no less than 0.001 D, so the simulated line would \
decay far below it; it is a vibration too small for the robot to damp: choose another wind speed
    """
    physics = dict(physics or {})
    balance = aeolian_severity(span, [wind.wind_speed], bc=bc, strouhal=wind.strouhal, **physics)
    status, amplitude = balance.status[0], float(balance.amplitude[0])
    curve = physics.get("wind_curve", "cigre")
    cond = span.conductor
    if status == "above curve range":
        return amplitude, (f"drives the span past the {curve!r} power curve's data: choose a "
                           "wind_curve whose data reach further (e.g. 'cigre') or a lower wind "
                           "speed")
    if status != "balanced" or not amplitude > 0:
        return 0.0, (f"sustains no vibration on this span (energy balance: {status!r}, the "
                     "conductor's self-damping takes more than the wind gives at every "
                     f"amplitude of the {curve!r} curve): there is nothing for the robot to "
                     "damp; choose another wind speed")
    wind_ratio = power_ratio(float(balance.wind_power[0]), cond.mass_per_length,
                             2 * math.pi * float(balance.frequency[0]), amplitude)
    if amplitude < LOWEST_REDUCED_AMPLITUDE * cond.diameter or wind_ratio > MAX_WIND_RATIO:
        return amplitude, (
            f"sustains only {amplitude * 1e3:.3g} mm on this span by the energy balance "
            f"({amplitude / cond.diameter:.2g} D), far below the {curve!r} power curve's data: "
            f"the balance needs a wind damping ratio of {wind_ratio:.2g} on the locked mode, "
            f"and the simulated wind gives at most {MAX_WIND_RATIO:g}, at no less than "
            f"{LOWEST_REDUCED_AMPLITUDE:g} D, so the simulated line would decay far below it; "
            "it is a vibration too small for the robot to damp: choose another wind speed")
    return amplitude, None


@dataclass(frozen=True, eq=False)
class SelfLimitingWind:
    """The line's self-limiting wind: the modal damping of the plant with and without the
    robot (held between blocks, :class:`~powerline_control.simulation.held_damping.HeldDamping`),
    and the energy balance's amplitude the line starts at."""

    damping: AeolianDamping     # the modal damping of the plant with the robot
    free_damping: AeolianDamping  # of the plant without it (the "no_robot" comparison)
    held: HeldDamping           # its map, held between blocks, with the robot
    free_held: HeldDamping      # without it
    amplitude: float            # the energy balance's antinode amplitude without the robot, m
    block: int                  # samples per plant block: the damping is evaluated at each start

    def start(self, free: bool = False) -> np.ndarray:
        """The state the line starts in: the locked mode at the balance's amplitude."""
        if free:
            return self.free_damping.start_state(self.free_held.plant, self.amplitude)
        return self.damping.start_state(self.held.plant, self.amplitude)

    def parked(self, x: float | None, n_t: int, free: bool = False,
               z0: np.ndarray | None = None) -> np.ndarray:
        """States (n_t, 2 n_q) of the whole run with the robot parked at x (``free``: the line
        without the robot), from ``z0`` (None: :meth:`start`)."""
        start = self.start(free) if z0 is None else z0
        return run_held(self.free_held if free else self.held, None if free else x,
                        start, n_t, block=self.block)


def self_limiting_wind(options: dict, plant: ModalPlant, free_plant: ModalPlant,
                       block: int) -> SelfLimitingWind:
    """The :class:`SelfLimitingWind` of :func:`checked_wind`'s options on the line's plants
    (with the robot and without it; the same plant twice for a line without one)."""
    physics = {k: v for k, v in options.items() if k in WIND_OPTIONS}
    wind = options["wind"]
    span = plant.model.span

    damping, free_damping = (aeolian_damping(p, span, wind.wind_speed, strouhal=wind.strouhal,
                                             **physics) for p in (plant, free_plant))
    return SelfLimitingWind(damping=damping, free_damping=free_damping,
                            held=HeldDamping(plant, damping.matrix),
                            free_held=HeldDamping(free_plant, free_damping.matrix),
                            amplitude=options["amplitude"], block=block)
