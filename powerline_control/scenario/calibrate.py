"""A scenario's span calibrated from a record: what ``powerline-control calibrate`` runs.

:func:`calibrate_scenario` reads the tension and the bending stiffness of the scenario's line,
with their uncertainty, from a record of its vibration
(:func:`~powerline_control.identify.calibrate_span`), against the span the engineer knows: the
scenario's nominal model (its ``[span]`` and ``[model]``: conductor, length, supports, the
stringing tension, the damping). The record is a measured one, or, without one, the scenario's
own record of its true line (its ``[truth]``), simulated by the pipeline's records stage (its
load, its duration, its noise; no identification run) and read at the scenario's sensors
(or evenly spaced ones): a check that the calibration finds the truth the scenario simulates.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from .._results import Result
from ..errors import InputError
from .config import Scenario
from .files import load_scenario  # noqa: F401 (doctests)

__all__ = ["ScenarioCalibration", "calibrate_scenario"]


@dataclass(frozen=True, eq=False)
class ScenarioCalibration(Result):
    """A scenario's span calibrated from a record, against its nominal span.

    Attributes
    ----------
    scenario : Scenario
        The scenario.
    calibration : SpanCalibration
        :func:`~powerline_control.identify.calibrate_span`'s result: the calibrated span, its
        tension, EI and sag with their standard deviations, the spectral lines it used.
    record : Record
        The record calibrated on (its channels on a support dropped).
    nominal : Span
        The scenario's nominal span (what the engineer knows).
    truth : Span or None
        The scenario's true span when the record was simulated from it (None for a measured
        record: its truth is unknown).
    how : str
        Where the record came from, in words.

    Examples
    --------
    See :func:`calibrate_scenario`.
    """

    scenario: Scenario
    calibration: Any = field(repr=False)
    record: Any = field(repr=False)
    nominal: Any
    truth: Any = None
    how: str = ""

    @property
    def simulated(self) -> bool:
        """Whether the record is the scenario's true line simulated (its truth known)."""
        return self.truth is not None

    def summary(self) -> str:
        """The calibration in words: the calibrated span, the nominal and, when known, the truth.

        Returns
        -------
        str
        """
        cal, nominal = self.calibration, self.nominal
        lines = [cal.summary(), f"Record: {self.how}",
                 f"Nominal span ({self.scenario.name}): {nominal.length:g} m, tension "
                 f"{nominal.tension:.6g} N, EI {nominal.conductor.ei:.4g} N m^2, "
                 f"{nominal.conductor.mass_per_length:.4g} kg/m ({nominal.conductor.name})"]
        if self.truth is not None:
            sigmas = abs(cal.tension - self.truth.tension) / max(cal.tension_std, 1e-300)
            lines.append(f"True line (simulated): tension {self.truth.tension:.6g} N, EI "
                         f"{self.truth.conductor.ei:.4g} N m^2; the calibrated tension is "
                         f"{sigmas:.2g} standard deviations from it")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The numbers as plain JSON types, units in the keys (``_n`` newtons, ``_n_m2`` N m^2,
        ``_m`` metres, ``_hz`` hertz, ``_s`` seconds, ``_percent`` per cent); :meth:`to_json`
        writes them as text.

        Returns
        -------
        dict
        """
        cal, nominal, truth = self.calibration, self.nominal, self.truth
        return {
            "scenario": self.scenario.name, "record_source": self.record.source,
            "record_simulated": self.simulated, "record": self.how,
            "duration_s": float(cal.duration),
            "channel_positions_m": [float(x) for x in self.record.positions],
            "nominal_tension_n": float(nominal.tension),
            "calibrated_tension_n": float(cal.tension),
            "calibrated_tension_std_n": float(cal.tension_std),
            "tension_change_percent": 100.0 * float(cal.tension_change),
            "nominal_ei_n_m2": float(nominal.conductor.ei),
            "calibrated_ei_n_m2": float(cal.ei), "calibrated_ei_std_n_m2": float(cal.ei_std),
            "ei_identified": bool(cal.ei_identified),
            "sag_m": float(cal.sag), "sag_std_m": float(cal.sag_std),
            "line_frequencies_hz": [float(f) for f in cal.line_frequencies],
            "model_frequencies_hz": [float(f) for f in cal.model_frequencies],
            "mode_numbers": [int(n) for n in cal.mode_numbers],
            "warnings": list(cal.warnings),
            "true_tension_n": None if truth is None else float(truth.tension),
            "true_ei_n_m2": None if truth is None else float(truth.conductor.ei),
        }


def calibrate_scenario(scenario: Scenario, record=None, *, progress=None) -> ScenarioCalibration:
    """Calibrate the scenario's span from ``record``, or from its true line simulated.

    Parameters
    ----------
    scenario : Scenario
        The scenario: its nominal model is the calibration's prior (supports and damping
        included).
    record : Record or None
        A measured record (:func:`~powerline_control.output.records.load_record`); its channels
        on a support are dropped, the others must lie inside the scenario's span. None: the
        scenario's record of its true line, simulated by the records stage (no identification
        run), at the scenario's sensors (node indices or positions), or ``n_sensors`` evenly
        spaced ones.
    progress : callable or None
        Called with a sentence as the work starts.

    Returns
    -------
    ScenarioCalibration

    Raises
    ------
    InputError
        A record that is not one, with a channel outside the scenario's span, a dead channel,
        or too short for the calibration.
    IdentificationError
        When the record shows no spectral line, or only a tension at the edge of the
        calibration's range explains it (a record of another line).

    Examples
    --------
    >>> cal = calibrate_scenario(load_scenario("paper-lab-20"))   # its truth: tension 3 % low
    >>> cal.simulated, round(cal.truth.tension, 2)
    (True, 383.15)
    >>> bool(abs(cal.calibration.tension - cal.truth.tension) < 2 * cal.calibration.tension_std)
    True
    """
    import numpy as np

    from ..identify import calibrate_span
    from ..output.records import Record
    from .pipeline import run_scenario
    from .sensing import scenario_sensors
    from .summary import positions_text

    if not isinstance(scenario, Scenario):
        raise InputError(f"The 'scenario' parameter must be a Scenario (load_scenario). Got "
                         f"{type(scenario).__name__}.")
    say = progress or (lambda text: None)
    if record is None:
        sim = scenario.simulation
        say(f"no record given: simulating {sim.duration:g} s of the scenario's true line "
            "(its load and noise) to calibrate from")
        quiet = dataclasses.replace(scenario, identification=dataclasses.replace(
            scenario.identification, shaker=0.0))   # the test record only
        made = run_scenario(quiet, stages=("model", "records"))
        snap = made.records.test
        nodes = scenario_sensors(scenario, snap.x)
        record = Record(snap.t, snap.x[nodes], snap.displacement[nodes],
                        f"simulated ({scenario.name}, its true line)",
                        truth=snap.true_displacement[nodes])
        load = scenario.forcing.describe(made.span, scenario.robot.wind)
        how = (f"simulated, since no --record was given: {sim.duration:g} s of the scenario's "
               f"true line under its load ({load}), sensors "
               f"at {positions_text(np.asarray(snap.x)[nodes], nodes)}, noise "
               f"{100 * sim.noise_fraction:g} % of the RMS displacement")
        nominal, truth = made.model, made.true_span
    else:
        if not isinstance(record, Record):
            raise InputError(f"The 'record' parameter must be a Record (load_record) or None. "
                             f"Got {type(record).__name__}.")
        nominal, truth = run_scenario(scenario, stages=("model",)).model, None
        length = nominal.span.length
        record = record.without_supports(length)
        record.check_span(length)
        how = (f"{record.source}: {record.values.shape[1]} samples at {1 / record.dt:.6g} Hz, "
               f"{record.values.shape[0]} channels at {positions_text(record.positions)}"
               + (f"; not used: the channels on a support at "
                  f"{positions_text(record.support_positions)}" if record.support_positions
                  else ""))
    say(f"calibrating the span from {record.values.shape[0]} channels, "
        f"{record.t[-1] - record.t[0]:.3g} s")
    calibration = calibrate_span(record, nominal)
    return ScenarioCalibration(scenario=scenario, calibration=calibration, record=record,
                               nominal=nominal.span, truth=truth, how=how)
