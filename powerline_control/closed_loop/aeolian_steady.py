"""The closed loop's placements judged again in the self-limiting aeolian wind.

The closed loop's plant drives the line with an
:class:`~powerline_control.excitation.AeolianForce`: a lift of fixed amplitude on a line with a
fixed modal damping. Its amplitudes compare the robot's positions under one load; they are not
where the line settles in that wind. With ``run_closed_loop(aeolian_steady=...)`` the run's
placements are judged again with the energy balance's own physics: the power curve's wind power
at the current amplitude and the conductor's self-damping, simulated until the amplitude settles
(:func:`~powerline_control.severity.simulate_aeolian`, the one home of that physics) on the line
simulated, with no robot, the robot parked near the clamp (a fixed damper), where it started,
where the closed loop ended, and at the antinode of the locked mode nearest there (where the
severity study parks it).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..excitation import AeolianForce
from ..fem import MDR, LineModel
from ..severity import AeolianRun, simulate_aeolian
from ..severity.self_limiting import WIND_OPTIONS, known_options, settling_balance

__all__ = ["AeolianSteady", "aeolian_steady_state"]

#: The options of :func:`~powerline_control.severity.simulate_aeolian` a caller may set: the
#: wind's power curve, the conductor's self-damping law, and how the runs settle. The span, the
#: supports, the mesh, the Strouhal number and the robot are the closed loop's own.
PHYSICS_OPTIONS = (*WIND_OPTIONS, "settle_tolerance", "max_duration")


@dataclass(frozen=True, eq=False)
class AeolianSteady:
    """The closed loop's placements in the self-limiting aeolian wind, in steady state.

    Each run is :func:`~powerline_control.severity.simulate_aeolian` on the line the closed loop
    simulated (its span, supports and mesh; the conductor's self-damping instead of the plant's
    modal damping) at the wind speed of the run's last load. Each carries its simulated steady
    amplitude (``amplitude``) and the energy balance's at the same wind and robot position
    (``balance_amplitude``: with the robot :func:`~powerline_control.severity.coupled_balance`'s,
    its power from the line and robot coupled; ``first_order_amplitude``:
    :func:`~powerline_control.severity.aeolian_severity`'s first-order damper power).

    Attributes
    ----------
    wind_speed : float
        m/s.
    no_robot : AeolianRun
        The line without the robot.
    near_clamp : AeolianRun
        The robot parked near the clamp, where a fixed damper sits (the closed loop's
        ``clamp_distance``).
    start : AeolianRun
        The robot parked where it started (had it never moved).
    closed_loop : AeolianRun
        The robot parked where the closed loop ended.
    at_antinode : AeolianRun
        The robot parked at the antinode of the locked mode (the bare line's mode nearest
        St V / D) nearest where the closed loop ended: where the severity study parks it.

    Examples
    --------
    >>> import powerline_control as plc
    >>> span = plc.Span.at_rts_fraction(30.0, "drake", 0.2)
    >>> model = plc.LineModel(span, bc="pinned")
    >>> robot = plc.tune_damper(model, 9, 15.0, 3.0, body_mass=5.0)
    >>> steady = aeolian_steady_state(model, plc.AeolianForce(3.0), robot, 15.2,
    ...                               clamp_distance=1.0)
    >>> round(steady.at_antinode.robot_position, 2)     # loops of 30 m / 9
    15.0
    >>> bool(steady.reduction > 10), bool(steady.clamp_reduction > 0.5)
    (True, True)
    >>> round(steady.start.robot_position, 2)     # where it started: tune_damper's position
    15.0
    """

    wind_speed: float
    no_robot: AeolianRun
    near_clamp: AeolianRun
    start: AeolianRun
    closed_loop: AeolianRun
    at_antinode: AeolianRun

    @property
    def reduction(self) -> float:
        """Steady amplitude without the robot over that with the robot where the loop ended."""
        return _ratio(self.no_robot.amplitude, self.closed_loop.amplitude)

    @property
    def clamp_reduction(self) -> float:
        """Steady amplitude with the robot parked near the clamp (a fixed damper) over that
        with the robot where the loop ended (> 1: the robot beats the fixed damper)."""
        return _ratio(self.near_clamp.amplitude, self.closed_loop.amplitude)

    @property
    def start_reduction(self) -> float:
        """Steady amplitude with the robot parked where it started over that with the robot
        where the loop ended (> 1: moving paid)."""
        return _ratio(self.start.amplitude, self.closed_loop.amplitude)

    @property
    def antinode_reduction(self) -> float:
        """Steady amplitude without the robot over that with the robot at the antinode (the
        severity study's placement, on this line)."""
        return _ratio(self.no_robot.amplitude, self.at_antinode.amplitude)

    @property
    def balance_reduction(self) -> float:
        """The energy balance's reduction at the same wind and position: its amplitude without
        the robot over its amplitude with the robot (coupled to the line) where the loop
        ended."""
        return _ratio(self.no_robot.balance_amplitude, self.closed_loop.balance_amplitude)

    @property
    def first_order_reduction(self) -> float:
        """The same with the textbook first-order damper power (the standing wave left as it
        is): what the energy balance says when it ignores the robot's reaction."""
        return _ratio(self.no_robot.first_order_amplitude,
                      self.closed_loop.first_order_amplitude)

    @property
    def settled(self) -> bool:
        """True when every run settled (see ``AeolianRun.settled``)."""
        return all(run.settled for run in self.runs)

    @property
    def runs(self) -> tuple:
        """(no_robot, near_clamp, start, closed_loop, at_antinode)."""
        return self.no_robot, self.near_clamp, self.start, self.closed_loop, self.at_antinode

    def summary(self) -> str:
        """A few lines: each placement's steady amplitude beside the energy balance's, and the
        reductions."""
        lines = [f"self-limiting wind {self.wind_speed:g} m/s (simulate_aeolian; energy "
                 "balance at the same position in brackets):"]
        names = ("no robot", "near clamp", "start", "closed loop", "at antinode")
        for name, run in zip(names, self.runs, strict=True):
            where = "" if run.robot_position is None else f" x = {run.robot_position:7.3f} m"
            lines.append(f"  {name:12s}{where:14s} amplitude {1e3 * run.amplitude:8.4f} mm "
                         f"({1e3 * run.balance_amplitude:.4f} mm)"
                         + ("" if run.settled else " not settled"))
        lines.append(f"  reduction {self.reduction:.3g}x against no robot, "
                     f"{self.clamp_reduction:.3g}x against the fixed damper near the clamp, "
                     f"{self.start_reduction:.3g}x against its start; "
                     f"at the antinode {self.antinode_reduction:.3g}x; the energy balance at "
                     f"the loop's position {self.balance_reduction:.3g}x")
        return "\n".join(lines)


def _ratio(numerator: float, denominator: float) -> float:
    return numerator / denominator if denominator > 0 else math.inf


def checked_options(value: object, wind: object) -> dict | None:
    """``run_closed_loop``'s ``aeolian_steady``: None when not asked (False), else the
    :func:`~powerline_control.severity.simulate_aeolian` options it names (True: none, the
    severity study's defaults). ``wind``: the run's last load segment, which must be one
    :class:`~powerline_control.excitation.AeolianForce` when the judgement is asked for."""
    if isinstance(value, bool | np.bool_):
        if not value:
            return None
        options = {}
    elif isinstance(value, Mapping):
        options = known_options("aeolian_steady", value, PHYSICS_OPTIONS)
    else:
        raise InputError(
            "The 'aeolian_steady' parameter must be True, False or a mapping of simulate_aeolian "
            f"options ({', '.join(PHYSICS_OPTIONS)}). Got {value!r:.60} of type "
            f"{type(value).__name__}.")
    if len(wind) != 1 or not isinstance(wind[0], AeolianForce):
        raise InputError(
            "The 'aeolian_steady' parameter judges the robot in the self-limiting wind of the "
            "run's last load, which must then be one AeolianForce (its wind speed and Strouhal "
            f"number). Got {[type(item).__name__ for item in wind]}: leave aeolian_steady "
            "False for other loads.")
    return options


def _supports(model: LineModel) -> str:
    left, right = model.bc
    if left != right:
        raise InputError(
            f"The 'aeolian_steady' judgement needs the same support at both ends (simulate_aeolian "
            f"takes 'clamped' or 'pinned'). Got bc={model.bc}.")
    return left


def _mesh(model: LineModel) -> int | None:
    """The elements simulate_aeolian meshes the span with to build ``model``'s mesh again: its
    count when the elements are equal (to round-off: ``LineModel(span, n)``, or a physics mesh
    without clamps), else None (the physics mesh, graded toward clamps, that
    ``LineModel(span)`` builds)."""
    equal = np.ptp(np.asarray(model.element_lengths)) <= 1e-12 * model.span.length
    return int(model.n_elements) if equal else None


def precheck(model: LineModel, wind: AeolianForce, options: dict) -> None:
    """The energy balance at the run's wind on its line: a wind the self-limiting physics cannot
    settle at (:func:`~powerline_control.severity.self_limiting.settling_balance`), a conductor
    without a rated strength for the self-damping law, an unknown curve or law, is refused
    before the run, not after it."""
    powers = {k: v for k, v in options.items() if k not in ("settle_tolerance", "max_duration")}
    _, problem = settling_balance(model.span, wind, _supports(model), powers)
    if problem is not None:
        raise InputError(
            f"The 'force' wind speed {wind.wind_speed:g} m/s {problem}, or leave aeolian_steady "
            "False (its judgement has no steady amplitude to find).")


def antinode_near(run: AeolianRun, position: float) -> float:
    """The antinode of a bare run's steady field nearest ``position``, m: the local maximum of
    its amplitude at the nodes, refined by the parabola through it and its two neighbours (the
    amplitude is a cosine there; nodes are a tenth of a loop apart or closer)."""
    amplitude, x = np.asarray(run.field_amplitude), np.asarray(run.x)
    inner = np.arange(1, x.size - 1)
    peaks = inner[(amplitude[inner] >= amplitude[inner - 1])
                  & (amplitude[inner] >= amplitude[inner + 1])
                  & (amplitude[inner] > 0.5 * amplitude.max())]
    if peaks.size == 0:   # a line that did not vibrate: no antinode to refine
        return float(position)
    i = int(peaks[np.argmin(np.abs(x[peaks] - position))])
    coefficients = np.polyfit(x[i - 1 : i + 2] - x[i], amplitude[i - 1 : i + 2], 2)
    shift = -coefficients[1] / (2 * coefficients[0]) if coefficients[0] < 0 else 0.0
    return float(np.clip(x[i] + shift, x[i - 1], x[i + 1]))


def aeolian_steady_state(model: LineModel, wind: AeolianForce, robot: MDR, position: float, *,
                         clamp_distance: float, **physics) -> AeolianSteady:
    """Judge the robot parked at ``position`` in the self-limiting wind, against no robot, a
    fixed damper near the clamp, the robot's start and the antinode.

    Five runs of :func:`~powerline_control.severity.simulate_aeolian` on ``model``'s span,
    supports and mesh, at ``wind``'s speed and Strouhal number, each until its amplitude settles:
    no robot; ``robot`` parked at ``clamp_distance``, where it starts (``robot.position``), at
    ``position``, and at the antinode of the locked mode nearest ``position`` (from the no-robot
    run's steady field).

    Parameters
    ----------
    model : LineModel
        The line (its damping is not used: the conductor's self-damping replaces it).
    wind : AeolianForce
        The wind (its lift coefficient is not used: the power curve replaces it).
    robot : MDR
        The robot, at its start.
    position : float
        Where the robot is judged, m.
    clamp_distance : float
        Where the fixed damper sits, m from the left support.
    **physics
        simulate_aeolian's options (:data:`PHYSICS_OPTIONS`): ``wind_curve``, ``self_damping``,
        ... (default: the severity study's).

    Returns
    -------
    AeolianSteady

    Raises
    ------
    InputError
        From simulate_aeolian (a wind beyond the power curve's data, a conductor without a rated
        strength for the self-damping law), or for supports that differ at the two ends.

    Examples
    --------
    >>> import powerline_control as plc
    >>> span = plc.Span.at_rts_fraction(30.0, "drake", 0.2)
    >>> model = plc.LineModel(span, bc="pinned")
    >>> robot = plc.tune_damper(model, 9, 15.0, 3.0, body_mass=5.0)
    >>> steady = aeolian_steady_state(model, plc.AeolianForce(3.0), robot, 15.0,
    ...                               clamp_distance=1.0)
    >>> steady.settled, round(steady.no_robot.amplitude / steady.no_robot.balance_amplitude, 2)
    (True, 1.0)
    """
    if not isinstance(model, LineModel):
        raise InputError(f"The 'model' parameter must be a LineModel. Got {type(model).__name__}.")
    if not isinstance(wind, AeolianForce):
        raise InputError("The 'wind' parameter must be an AeolianForce (its wind speed and "
                         f"Strouhal number). Got {type(wind).__name__}.")
    for name, value in (("position", position), ("clamp_distance", clamp_distance)):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) \
                or not 0 <= value <= model.span.length:
            raise InputError(f"The '{name}' parameter must lie on the span [0, "
                             f"{model.span.length:g}] m. Got {value!r}.")
    common = {"bc": _supports(model), "n_elements": _mesh(model), "strouhal": wind.strouhal,
              **physics}
    span, speed = model.span, wind.wind_speed

    def parked(x: float | None) -> AeolianRun:
        placed = None if x is None else dataclasses.replace(robot, position=float(x))
        return simulate_aeolian(span, speed, placed, **common)

    bare, ended = parked(None), parked(position)
    start = ended if robot.position == position else parked(robot.position)   # never moved
    return AeolianSteady(wind_speed=float(speed), no_robot=bare, near_clamp=parked(clamp_distance),
                         start=start, closed_loop=ended,
                         at_antinode=parked(antinode_near(bare, position)))
