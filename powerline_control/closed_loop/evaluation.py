"""How the run went: when the robot settled, and the vibration of every placement compared."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import read_only
from ..fem import MDR
from .plant import ModalPlant, damper_power, nodal_field, phasor_of, run_parked
from .result import Comparison


def arrival_index(position: np.ndarray, start: int, tolerance: float) -> int | None:
    """First index >= start after which the position stays within tolerance of its last value."""
    outside = np.flatnonzero(np.abs(position[start:] - position[-1]) > tolerance)
    if outside.size == 0:
        return start
    index = start + int(outside[-1]) + 1
    return index if index < position.size else None



@dataclass(frozen=True)
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
    bounds = target_starts[1:] + [n_t - 1]
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



def window_comparison(name: str, position: float, states: np.ndarray, plant: ModalPlant,
                power: np.ndarray, line, mask: np.ndarray) -> Comparison:
    """The vibration of the plant's states over the settled window (``mask``)."""
    field_window = nodal_field(plant, states[mask], line.residual[:, mask], position)
    rms = float(np.sqrt(np.mean(line.weights @ field_window**2)))
    envelope = np.max(np.abs(field_window), axis=1)
    return Comparison(name, float(position), rms, float(envelope.max()),
                      float(np.mean(power[mask])) if power.size else 0.0,
                      read_only(envelope))


def parked_comparison(name: str, x_park: float | None, line, robot: MDR,
                       mask: np.ndarray) -> Comparison:
    """The whole run with the robot parked at ``x_park`` (None: no robot on the line)."""
    n_t = line.t.size
    if x_park is None:
        states = run_parked(line.free_plant, None, line.modal_force, n_t)
        return window_comparison(name, np.nan, states, line.free_plant, np.zeros(n_t), line, mask)
    states = run_parked(line.plant, x_park, line.modal_force, n_t)
    power = damper_power(line.plant, robot, states, x_park)
    return window_comparison(name, x_park, states, line.plant, power, line, mask)


def steady_rms(line, x: float, omega: float, modal_amplitude: np.ndarray,
                static_amplitude: np.ndarray) -> float:
    """RMS over the span in steady state under a sine (its modal and residual amplitudes) with
    the robot parked at x."""
    plant = line.plant
    amplitude = plant.steady_state(x, omega, modal_amplitude)
    shape = plant.nodal @ amplitude[: plant.r] + static_amplitude
    return float(np.sqrt(0.5 * line.weights @ np.abs(shape) ** 2))


def steady_state_scan(line) -> tuple[np.ndarray, np.ndarray, float]:
    """(positions, RMS, best position): the steady state with the robot parked along the span
    under the last harmonic load, a coarse grid and a fine one around its minimum (empty and
    NaN when that load is not one sine)."""
    if line.harmonic is None:
        return np.zeros(0), np.zeros(0), float("nan")
    span_length = line.span.length
    scan_frequency, parts = line.harmonic
    omega = 2 * np.pi * scan_frequency
    modal_amplitude = sum(g * phasor_of(load, scan_frequency) for load, g, _ in parts)
    static_amplitude = sum(s * phasor_of(load, scan_frequency) for load, _, s in parts)
    loads = (omega, modal_amplitude, static_amplitude)
    coarse = np.linspace(0.0, span_length, 4 * line.bare.n_elements + 1)[1:-1]
    coarse_rms = np.array([steady_rms(line, x, *loads) for x in coarse])
    i = int(np.argmin(coarse_rms))
    step = coarse[1] - coarse[0]
    fine = np.linspace(max(coarse[i] - 2 * step, 1e-9),
                       min(coarse[i] + 2 * step, span_length - 1e-9), 41)
    fine_rms = np.array([steady_rms(line, x, *loads) for x in fine])
    positions = np.concatenate([coarse, fine])
    order = np.argsort(positions)
    return (positions[order], np.concatenate([coarse_rms, fine_rms])[order],
            float(fine[int(np.argmin(fine_rms))]))


def all_comparisons(line, robot: MDR, records, calibration,
                 mask: np.ndarray, best_position: float, loop_power: np.ndarray) -> tuple:
    """no robot, parked near a clamp, parked at the start, parked at the best position, and the
    closed loop, over the same settled window."""
    start_states, plant = calibration.start_states, line.plant
    return (
        parked_comparison("no_robot", None, line, robot, mask),
        parked_comparison("near_clamp", line.clamp_distance, line, robot, mask),
        window_comparison("start", robot.position, start_states, plant,
                    damper_power(plant, robot, start_states, robot.position), line, mask),
        parked_comparison("best", best_position, line, robot, mask)
        if not np.isnan(best_position)
        else Comparison("best", np.nan, np.nan, np.nan, np.nan,
                        read_only(np.zeros(line.bare.n_nodes))),
        window_comparison("closed_loop", records.position[-1], records.plant_states, plant,
                    loop_power, line, mask),
    )


# Thousands of small products per simulated second: one BLAS thread is several times faster than
