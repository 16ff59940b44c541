"""How the run went: when the robot settled, and the vibration of every placement compared."""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from .._validation import read_only
from ..errors import ModelError, TruncationWarning
from ..fem import MDR
from ..severity import envelope_settled
from ..simulation import ParkedSteadyState, parked_steady_state
from ..simulation.plant import (
    ModalPlant,
    damper_power,
    nodal_field,
    robot_correction,
    run_parked,
)
from .policy import reach_within
from .result import Comparison


def _steady(model, loads, robot: MDR | None, positions=None) -> ParkedSteadyState:
    """:func:`parked_steady_state`, without the mesh warning the run already gave (build_line)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TruncationWarning)
        return parked_steady_state(model, loads, robot, positions)


def arrival_index(position: np.ndarray, start: int, tolerance: float) -> int | None:
    """First index >= start after which the position stays within tolerance of its last value."""
    outside = np.flatnonzero(np.abs(position[start:] - position[-1]) > tolerance)
    if outside.size == 0:
        return start
    index = start + int(outside[-1]) + 1
    return index if index < position.size else None


@dataclass(frozen=True, eq=False)
class Settling:
    """When the robot arrived and stayed: per target, per load change, and the settled window."""

    settle_times: tuple
    follow_times: tuple
    settled: bool
    mask: np.ndarray            # (n_t,) the samples of the settled window
    window: tuple               # (start, end) of the settled window, s


def settling_of(records, t: np.ndarray, segments, n_cal: int, loop_length: float,
              settle_margin: float) -> Settling:
    """Arrival ("within 1 % of a loop of the final position, for good") after each target and
    each load change, and the settled window that starts ``settle_margin`` after the last."""
    position, target_starts, n_t = records.position, records.target_starts, t.size
    tolerance = 0.01 * loop_length
    settle_times = []
    bounds = target_starts[1:] + [n_t - 1] if target_starts else []   # no decision in the run
    for begin, stop in zip(target_starts, bounds, strict=True):
        arrival = arrival_index(position[: stop + 1], begin, tolerance)
        settle_times.append(float(t[arrival] - t[begin]) if arrival is not None else float("nan"))
    follow_times = []
    for change in (start for start, _ in segments[1:]):
        later = [i for i, begin in enumerate(target_starts) if t[begin] >= change]
        if not later:
            follow_times.append(float("nan"))
            continue
        begin, stop = target_starts[later[0]], bounds[later[0]]
        arrival = arrival_index(position[: stop + 1], begin, tolerance)
        follow_times.append(float(t[arrival] - change) if arrival is not None else float("nan"))
    last_begin = target_starts[-1] if target_starts else n_cal - 1
    arrival = arrival_index(position, last_begin, tolerance)
    window_start = t[arrival] + settle_margin if arrival is not None else np.inf
    settled = bool(window_start <= t[-1] - 1.0)
    if not settled:
        window_start = max(t[-1] - 1.0, 0.0)
    mask = t >= window_start - 1e-12
    return Settling(tuple(settle_times), tuple(follow_times), settled, mask,
                     (float(t[mask][0]), float(t[-1])))


# Window statistics are summed over blocks of samples of about this many field values (2 MB):
# the field of a fine mesh over a long window (tens of MB) is never formed whole.
_WINDOW_BLOCK_VALUES = 2**18


def window_comparison(name: str, position: float, states: np.ndarray, plant: ModalPlant,
                      power: np.ndarray, line, mask: np.ndarray,
                      recorded: tuple | None = None) -> Comparison:
    """The vibration of the plant's states over the settled window (``mask``), the robot
    parked at ``position``. ``recorded``: (field, path) of the run's own records, the field over
    the whole run with the robot's residual field along ``path`` (None: parked at ``position``
    already), reused instead of computed again."""
    columns = np.flatnonzero(mask)
    per_block = max(64, _WINDOW_BLOCK_VALUES // line.bare.n_nodes)
    sum_square, envelope = 0.0, np.zeros(line.bare.n_nodes)
    node_square = np.zeros(line.bare.n_nodes)
    for block in np.array_split(columns, -(-columns.size // per_block)):
        if recorded is None:
            field = nodal_field(plant, states[block], line.residual[:, block], position)
        else:
            field = recorded[0][:, block]
            along = None if recorded[1] is None else robot_correction(
                plant, states[block], recorded[1][block])
            if along is not None:   # the robot's residual field at position, not along path
                field -= along
                field += robot_correction(plant, states[block], position)
        sum_square += float(np.sum(line.weights @ field**2))
        node_square += np.sum(field**2, axis=1)
        np.maximum(envelope, np.max(np.abs(field), axis=1), out=envelope)
    rms = float(np.sqrt(sum_square / columns.size))
    return Comparison(name, float(position), rms, float(envelope.max()),
                      float(np.mean(power[mask])) if power.size else 0.0,
                      read_only(envelope),
                      amplitude=float(np.sqrt(2 * node_square.max() / columns.size)))


# A settled window whose RMS is farther than this from the steady state (or whose halves differ by
# this much) still rings: its time-domain RMS is flagged as transient.
TRANSIENT_TOLERANCE = 0.10


def reachable_positions(line, limits, start: float, bounds: tuple[float, float],
                        travel_time: float) -> np.ndarray:
    """The scan's positions: those the robot could reach from ``start`` inside ``bounds`` (its
    free interval) moving rest-to-rest for at most ``travel_time`` s, about 40 per loop of the
    last load's frequency (and 4 per element on short spans)."""
    reach = reach_within(limits, travel_time)
    low, high = max(bounds[0], start - reach), min(bounds[1], start + reach)
    frequency = line.harmonic[0]
    step = min(float(line.span.loop_length(frequency)) / 40, line.bare.element_length / 4)
    return np.linspace(low, high, max(int(np.ceil((high - low) / step)) + 1, 2))


def steady_scan(line, robot: MDR, loads, positions: np.ndarray) -> ParkedSteadyState:
    """The exact steady state along ``positions`` and refined around its minimum (41 points
    over the two grid steps either side)."""
    coarse = _steady(line.bare, loads, robot, positions)
    if positions.size < 3:
        return coarse
    i = int(np.argmin(coarse.rms))
    step = positions[1] - positions[0]
    fine = np.linspace(max(positions[i] - 2 * step, positions[0]),
                       min(positions[i] + 2 * step, positions[-1]), 41)
    refined = _steady(line.bare, loads, robot, fine)
    order = np.argsort(np.concatenate([positions, fine]), kind="stable")
    return ParkedSteadyState(
        frequency=coarse.frequency, positions=read_only(np.concatenate([positions, fine])[order]),
        x=coarse.x, field=read_only(np.concatenate([coarse.field, refined.field])[order]),
        rms=read_only(np.concatenate([coarse.rms, refined.rms])[order]),
        robot_displacement=read_only(np.concatenate(
            [coarse.robot_displacement, refined.robot_displacement])[order]),
        damper_power=read_only(np.concatenate([coarse.damper_power, refined.damper_power])[order]),
    )


def _steady_comparison(window: Comparison, state: ParkedSteadyState, index: int) -> Comparison:
    """``window``'s placement in exact steady state (state's position ``index``)."""
    envelope = np.abs(state.field[index])
    rms = float(state.rms[index])
    transient = abs(window.rms / rms - 1.0) > TRANSIENT_TOLERANCE if rms > 0 else False
    return Comparison(window.name, window.position, rms, float(envelope.max()),
                      float(state.damper_power[index]), read_only(envelope),
                      window_rms=window.rms, steady=True, transient=bool(transient),
                      amplitude=float(envelope.max()))


def _window_only(window: Comparison, line, states, plant, mask) -> Comparison:
    """A placement without a steady state: the window RMS, flagged when its halves differ (or,
    in the self-limiting wind, when the line's amplitude has not settled)."""
    index = np.flatnonzero(mask)
    halves = np.array_split(index, 2)
    rms = [float(np.sqrt(np.mean(line.weights @ nodal_field(
        plant, states[h], line.residual[:, h]) ** 2))) for h in halves if h.size]
    transient = len(rms) == 2 and abs(rms[0] - rms[1]) > TRANSIENT_TOLERANCE * max(rms)
    if line.wind is not None and not transient:
        transient = not _wind_settled(line, states, plant, index)
    return dataclasses.replace(window, window_rms=window.rms, transient=bool(transient))


def _wind_settled(line, states, plant, index: np.ndarray) -> bool:
    """Whether the line's amplitude in the self-limiting wind has settled over the samples
    ``index`` (within TRANSIENT_TOLERANCE): ``severity.envelope_settled`` (simulate_aeolian's
    test) on its energy amplitude at each plant block's start. The halves' test alone misses a
    slow approach: near the balance the net damping vanishes, and a robot off the antinode
    settles over minutes."""
    damping = line.wind.free_damping if plant is line.free_plant else line.wind.damping
    blocks = index[:: max(line.plant_steps, 1)]
    return envelope_settled(line.t[blocks], damping.line_amplitude(states[blocks]),
                            TRANSIENT_TOLERANCE, converging=True)


def all_comparisons(line, robot: MDR, records, calibration, mask: np.ndarray, limits,
                    bounds: tuple[float, float], travel_time: float, last_loads,
                    loop_power: np.ndarray, fields: tuple[np.ndarray, np.ndarray]
                    ) -> tuple[tuple, ParkedSteadyState | None]:
    """no robot, parked near a clamp, parked at the start, parked at the best position within
    reach, and where the closed loop ended: in exact steady state when the last load is one
    sine (with the settled window's RMS beside it), else over the settled window; and the
    steady-state scan the best position comes from (None without a sine). ``fields``: the
    run's field and the field parked at the start, whose windows are not computed again."""
    start_states, plant = calibration.start_states, line.plant
    n_t = line.t.size
    run_field, start_field = fields
    free_states = (run_parked(line.free_plant, None, line.modal_force, n_t) if line.wind is None
                   else line.wind.parked(None, n_t, free=True))
    windows = {
        "no_robot": (window_comparison("no_robot", np.nan, free_states, line.free_plant,
                                       np.zeros(n_t), line, mask), free_states, line.free_plant),
        "near_clamp": _parked_window("near_clamp", line.clamp_distance, line, robot, mask),
        "start": (window_comparison("start", robot.position, start_states, plant,
                                    damper_power(plant, robot, start_states, robot.position),
                                    line, mask, (start_field, None)), start_states, plant),
        # parked where it ended: the run's field, the robot's residual field moved there
        "closed_loop": (window_comparison("closed_loop", records.position[-1],
                                          records.plant_states, plant, loop_power, line, mask,
                                          (run_field, records.position)),
                        records.plant_states, plant),
    }
    if line.harmonic is None:
        best = Comparison("best", np.nan, np.nan, np.nan, np.nan,
                          read_only(np.zeros(line.bare.n_nodes)))
        out = {name: _window_only(c, line, states, p, mask)
               for name, (c, states, p) in windows.items()}
        return (out["no_robot"], out["near_clamp"], out["start"], best, out["closed_loop"]), None
    scan = steady_scan(line, robot, last_loads,
                       reachable_positions(line, limits, robot.position, bounds, travel_time))
    windows["best"] = _parked_window("best", scan.best_position, line, robot, mask)
    placed = _steady(
        line.bare, last_loads, robot,
        np.array([line.clamp_distance, robot.position, records.position[-1]]))
    out = {"near_clamp": _steady_comparison(windows["near_clamp"][0], placed, 0),
           "start": _steady_comparison(windows["start"][0], placed, 1),
           "closed_loop": _steady_comparison(windows["closed_loop"][0], placed, 2),
           "best": _steady_comparison(windows["best"][0], scan, int(np.argmin(scan.rms)))}
    try:
        out["no_robot"] = _steady_comparison(windows["no_robot"][0],
                                             _steady(line.bare, last_loads, None), 0)
    except ModelError:
        # An undamped bare line driven exactly at a natural frequency has no steady state.
        c, states, p = windows["no_robot"]
        out["no_robot"] = _window_only(c, line, states, p, mask)
    order = ("no_robot", "near_clamp", "start", "best", "closed_loop")
    return tuple(out[name] for name in order), scan


def _parked_window(name: str, x_park: float, line, robot: MDR, mask: np.ndarray):
    """(window comparison, states, plant) of the run with the robot parked at ``x_park``."""
    states = (run_parked(line.plant, x_park, line.modal_force, line.t.size)
              if line.wind is None else line.wind.parked(x_park, line.t.size))
    power = damper_power(line.plant, robot, states, x_park)
    return window_comparison(name, x_park, states, line.plant, power, line, mask), states, \
        line.plant
