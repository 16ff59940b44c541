"""calibrate_span: the span's tension and EI from a record, against closed forms and a held-out
family of simulated lines that are not the nominal one."""

from __future__ import annotations

import dataclasses
import warnings

import calibration_family as family
import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import CalibrationWarning, IdentificationError, InputError


def _pinned_frequencies(span: plc.Span, n: np.ndarray) -> np.ndarray:
    """Closed form of a pinned taut Euler-Bernoulli beam (design.md 4.1), Hz."""
    cond = span.conductor
    k = n * np.pi / span.length
    return np.sqrt((span.tension * k**2 + cond.ei * k**4) / cond.mass_per_length) / (2 * np.pi)


def _free_decay_record(truth: plc.Span, modes, positions, duration=30.0, dt=0.005, zeta=0.002,
                       noise=0.01, seed=0) -> plc.Record:
    """Free ringing of the pinned modes ``modes`` (sin(n pi x / L) shapes, closed-form
    frequencies), random amplitudes and phases, white sensor noise (a share of the RMS)."""
    rng = np.random.default_rng(seed)
    t = dt * np.arange(int(round(duration / dt)) + 1)
    x = np.asarray(positions, dtype=float)
    modes = np.asarray(modes)
    f = _pinned_frequencies(truth, modes)
    amplitude = rng.uniform(0.5, 1.5, modes.size) * 1e-3
    phase = rng.uniform(0, 2 * np.pi, modes.size)
    shapes = np.sin(np.outer(x, modes) * np.pi / truth.length)                  # (p, m)
    decay = np.exp(-zeta * 2 * np.pi * np.outer(f, t))                          # (m, n_t)
    values = shapes @ (amplitude[:, None] * decay
                       * np.cos(2 * np.pi * np.outer(f, t) + phase[:, None]))
    values += noise * values.std() * rng.standard_normal(values.shape)
    return plc.Record(t, x, values, source="closed-form free decay")


NOMINAL = plc.Span(200.0, 28_000.0, plc.conductors["drake"])


def test_free_decay_of_a_pinned_span_gives_its_tension_within_its_uncertainty():
    # The record is written from the closed form, not the FE model: the calibration's scaled
    # FE modes must reproduce the pinned frequencies (FE error ~1e-5 on this mesh) and read the
    # tension off them. 14 free lines over 30 s: the tension is fixed to ~0.05 %.
    truth = plc.Span(200.0, 1.06 * NOMINAL.tension, NOMINAL.conductor)
    record = _free_decay_record(truth, np.arange(30, 44), [23.0, 61.7, 118.2, 171.4])
    cal = plc.calibrate_span(record, NOMINAL)
    assert abs(cal.tension - truth.tension) <= 2 * cal.tension_std
    assert abs(cal.tension / truth.tension - 1) < 2e-3
    assert cal.tension_std / cal.tension < 5e-3
    assert not cal.warnings
    # every line is explained by the mode it is, at the closed-form frequency
    assert set(cal.mode_numbers) <= set(range(30, 44))
    np.testing.assert_allclose(cal.model_frequencies,
                               _pinned_frequencies(truth, cal.mode_numbers), rtol=2e-4)
    # the sag of a parabola m g L^2 / 8 T, and its std by the same relative share
    mass = NOMINAL.conductor.mass_per_length
    assert cal.sag == pytest.approx(mass * 9.80665 * 200.0**2 / (8 * cal.tension), rel=1e-12)
    assert cal.sag_std / cal.sag == pytest.approx(cal.tension_std / cal.tension, rel=1e-12)
    assert cal.span.tension == cal.tension and cal.span.length == NOMINAL.length


def test_bending_stiffness_is_identified_where_the_dispersion_shows_it():
    # A stiff short span: mode n's frequency carries EI (n pi / L)^4 against T (n pi / L)^2,
    # about 20 % at mode 8; the record over modes 2-9 separates the two.
    rod = dataclasses.replace(NOMINAL.conductor, ei=2000.0)
    nominal = plc.Span(20.0, 3000.0, rod)
    truth = plc.Span(20.0, 0.93 * nominal.tension, dataclasses.replace(rod, ei=2600.0))
    record = _free_decay_record(truth, np.arange(2, 10), [2.3, 7.9, 13.1, 17.2], dt=0.002,
                                duration=20.0)
    cal = plc.calibrate_span(record, nominal)
    assert cal.ei_identified
    assert abs(cal.ei - 2600.0) <= 2 * cal.ei_std and cal.ei_std / cal.ei < 0.1
    assert abs(cal.tension - truth.tension) <= 2 * cal.tension_std


def _lock_in_shape(x, k, length):
    """Wind in lock-in forcing a pinned string with the wave of its own wavenumber, sin(k x):
    the closed form of w'' + k^2 w = -sin(k x), w(0) = w(L) = 0."""
    return -(length / (2 * k)) / np.tan(k * length) * np.sin(k * x) + x / (2 * k) * np.cos(k * x)


def _shaker_shape(x, k, length, load_at=200.0):
    """A point load at ``load_at`` (between the last two sensors): the string's Green's
    function, w'' + k^2 w = -delta(x - a), w(0) = w(L) = 0. The load bends the field there, so
    the wave of a distributed load fits only a mode's wavelength."""
    return np.where(x < load_at, np.sin(k * x) * np.sin(k * (length - load_at)),
                    np.sin(k * load_at) * np.sin(k * (length - x))) / (k * np.sin(k * length))


@pytest.mark.parametrize("shape_of", [_lock_in_shape, _shaker_shape])
def test_a_tone_forced_between_two_modes_is_read_from_its_wavelength(shape_of):
    # One line, no free ringing: a 300 m pinned string forced at 36.3 fundamentals (between
    # modes 36 and 37), in lock-in or by a shaker. Its frequency puts no mode on the line; only
    # the shape at the sensors (the wavelength) tells the tension. Nearest-mode readings are
    # 1.7 % (mode 36) and 3.9 % (37) off.
    length = 300.0
    nominal = plc.Span(length, 28_000.0, NOMINAL.conductor)
    truth = 0.95 * nominal.tension
    speed = np.sqrt(truth / NOMINAL.conductor.mass_per_length)
    frequency = 36.3 * speed / (2 * length)
    k = 2 * np.pi * frequency / speed
    x = np.array([23.0, 61.0, 97.5, 152.0, 241.0])
    t = 0.01 * np.arange(3001)
    values = np.outer(shape_of(x, k, length), np.sin(2 * np.pi * frequency * t))
    values += 0.01 * values.std() * np.random.default_rng(0).standard_normal(values.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CalibrationWarning)    # one line: it says so
        cal = plc.calibrate_span(plc.Record(t, x, values), nominal)
    assert abs(cal.tension - truth) <= 2 * cal.tension_std
    assert abs(cal.tension / truth - 1) < 0.01 and cal.tension_std / truth < 0.01
    assert not cal.ambiguous and cal.peak_share > 0.95


def test_nan_gaps_leave_the_calibration_as_it_was():
    truth = plc.Span(200.0, 0.95 * NOMINAL.tension, NOMINAL.conductor)
    record = _free_decay_record(truth, np.arange(30, 40), [23.0, 61.7, 118.2, 171.4])
    values = np.array(record.values)
    rng = np.random.default_rng(3)
    values[rng.random(values.shape) < 0.05] = np.nan      # 5 % of the samples missing
    gappy = plc.Record(record.t, record.positions, values)
    cal = plc.calibrate_span(gappy, NOMINAL)
    assert abs(cal.tension - truth.tension) <= 2 * cal.tension_std
    assert abs(cal.tension / truth.tension - 1) < 3e-3


# Six held-out records of the family (every kind of load, both supports, the lab span and real
# spans); the full family of 40 runs in benchmarks/bench_calibrate.py. Seeds 11 and 23 take
# 35-70 s each (long real-span records): they run with the slow tests, outside CI.
HELD_OUT_FAST = (1, 3, 5, 13)
HELD_OUT_SLOW = (11, 23)


@pytest.mark.parametrize("seed", [
    *HELD_OUT_FAST, *(pytest.param(seed, marks=pytest.mark.slow) for seed in HELD_OUT_SLOW)])
def test_held_out_records_are_calibrated_within_two_sigma(seed):
    case = family.case(seed)
    assert seed % 2 == 1   # held out: the calibration's settings were tuned on even seeds
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CalibrationWarning)
        cal = plc.calibrate_span(case.record, case.nominal, bc=case.bc)
    # The record shows T / m: against the catalogue's mass the tension it implies is the
    # truth's tension times m_catalogue / m_true.
    seen = case.truth.tension * (case.nominal.conductor.mass_per_length
                                 / case.truth.conductor.mass_per_length)
    assert abs(cal.tension - seen) <= 2.5 * cal.tension_std, case.label


# ------------------------------------------------------------------------------- bad input
def _record(truth=NOMINAL, **kw):
    return _free_decay_record(truth, np.arange(30, 40), [23.0, 61.7, 118.2, 171.4], **kw)


def test_a_record_too_short_for_one_cycle_is_refused():
    nominal = plc.Span(400.0, 20_000.0, NOMINAL.conductor)   # fundamental 0.14 Hz
    record = _free_decay_record(NOMINAL, [30], [50.0, 120.0], duration=5.0)
    with pytest.raises(InputError, match="too short to calibrate.*at least"):
        plc.calibrate_span(record, nominal)


def test_a_record_of_another_span_is_refused():
    record = _record()
    with pytest.raises(InputError, match="outside the span|another span"):
        plc.calibrate_span(record, plc.Span(150.0, 28_000.0, NOMINAL.conductor))


def test_a_conductor_far_off_the_catalogue_is_named():
    # the catalogue's mass 30 % low: only a tension 30 % off explains the lines
    wrong = dataclasses.replace(NOMINAL.conductor,
                                mass_per_length=0.6 * NOMINAL.conductor.mass_per_length)
    with pytest.raises(IdentificationError, match="mass per length|tension_range"):
        plc.calibrate_span(_record(), plc.Span(200.0, 28_000.0, wrong))


def test_one_line_and_sensors_within_a_loop_warn_and_widen_the_uncertainty():
    truth = plc.Span(200.0, 1.04 * NOMINAL.tension, NOMINAL.conductor)
    one_line = _free_decay_record(truth, [35], [100.0, 101.0, 102.0], zeta=0.0)
    with pytest.warns(CalibrationWarning) as caught:
        cal = plc.calibrate_span(one_line, NOMINAL)
    text = " ".join(str(w.message) for w in caught)
    assert "one spectral line" in text and "within one loop" in text
    # one line and one loop cannot tell mode 35 from its neighbours (2.9 % apart in tension):
    # the uncertainty says so
    assert cal.tension_std / cal.tension > 0.02
    assert abs(cal.tension - truth.tension) <= 2 * cal.tension_std


def test_a_silent_record_is_refused():
    t = 0.005 * np.arange(6001)
    rng = np.random.default_rng(0)
    record = plc.Record(t, [50.0, 100.0], 1e-6 * rng.standard_normal((2, t.size)))
    with pytest.raises(IdentificationError, match="no spectral line"):
        plc.calibrate_span(record, NOMINAL)


@pytest.mark.parametrize("kwargs, match", [
    ({"tension_range": (1.1, 1.4)}, "tension_range"),
    ({"ei_range": "wide"}, "ei_range"),
    ({"max_lines": 0}, "max_lines"),
    ({"band": (5.0, 1e4)}, "band"),
    ({"bc": "clamped", "nominal": "model"}, "bc"),
    ({"bc": "hinged"}, "'bc'"),
    ({"bc": "hinged", "record": "short"}, "'bc'"),      # named before the record is read
])
def test_invalid_options_are_named(kwargs, match):
    nominal = kwargs.pop("nominal", None)
    nominal = plc.LineModel(NOMINAL, 200) if nominal == "model" else NOMINAL
    record = _record(duration=0.5) if kwargs.pop("record", None) == "short" else _record()
    with pytest.raises(InputError, match=match):
        plc.calibrate_span(record, nominal, **kwargs)


def test_a_nominal_that_is_not_a_span_is_named():
    with pytest.raises(InputError, match="'nominal'"):
        plc.calibrate_span(_record(), 28_000.0)
    with pytest.raises(InputError, match="'record'"):
        plc.calibrate_span(np.zeros((2, 100)), NOMINAL)
