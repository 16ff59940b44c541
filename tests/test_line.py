"""Parameters and presets against published values (domain.md 2.6 and 3.3)."""

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.excitation import strouhal_frequency


def test_paper_lab_reads_table_one_mass_as_total():
    span = plc.Span.paper_lab()
    assert span.conductor.mass_per_length == pytest.approx(0.68 / 3.66)
    assert plc.Span.paper_lab("per_metre").conductor.mass_per_length == 0.68


def test_presets_have_sources_and_plausible_values():
    assert {"drake", "condor", "cardinal", "aster570"} <= set(plc.conductors)
    for name in plc.conductors:
        cond = plc.conductors[name]
        assert plc.conductors.source(name)
        # Aluminium-based conductors: mass per metre near 2100-3300 kg/m^3 times the area.
        density = cond.mass_per_length / (np.pi * cond.diameter**2 / 4)
        assert 1800 < density < 3400, name


def test_drake_everyday_tension_and_frequencies():
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.20)
    assert span.tension == pytest.approx(28020.0)
    # domain.md 3.3: f_pp for n = 1, 10, 50, 100, 200 (closed form with EI = 44.2; ours 44.0).
    f = span.pinned_frequencies(200)[[0, 9, 49, 99, 199]]
    np.testing.assert_allclose(f, [0.21865311, 2.18654979, 10.93501813, 21.88421259, 43.88165258],
                               rtol=2e-5)


@pytest.mark.parametrize(("speed", "expected"), [(0.5, 8.81), (1.0, 17.62), (7.0, 123.3)])
def test_strouhal_band_on_lab_cable(speed, expected):
    # domain.md 6, test case 4 (St = 0.185, d = 10.5 mm)
    assert strouhal_frequency(speed, 0.0105) == pytest.approx(expected, abs=0.05)


def test_span_without_stiffness_is_rejected():
    cond = plc.Conductor(mass_per_length=1.0, diameter=0.01, ei=0.0)
    with pytest.raises(plc.InputError, match="stiffness"):
        plc.Span(length=10.0, tension=0.0, conductor=cond)


def test_booleans_are_not_numbers():
    with pytest.raises(plc.InputError, match="length"):
        plc.Span(length=True, tension=1.0, conductor=plc.conductors["drake"])


def test_catalogue_behaves_as_a_mapping():
    assert "drake" in plc.conductors and "unobtainium" not in plc.conductors
    assert plc.conductors.get("unobtainium") is None
    with pytest.raises(KeyError):
        plc.conductors["unobtainium"]


# ------------------------------------------------------------------ physics limits
@pytest.mark.parametrize("fraction", [1.0, 1.5])
def test_tension_at_or_above_the_rated_strength_is_refused(fraction):
    drake = plc.conductors["drake"]
    # Old code accepted 150 % RTS, and catenary_check answered it.
    with pytest.raises(plc.InputError, match=r"'tension' parameter .* rated tensile strength"):
        plc.Span(300.0, fraction * drake.rated_strength, drake)
    with pytest.raises(plc.InputError, match="'fraction_of_rts'"):   # refused there already
        plc.Span.at_rts_fraction(300.0, "drake", fraction)
    plc.Span(300.0, 0.99 * drake.rated_strength, drake)   # below it: a (harsh) valid span
    plc.Span(300.0, 1e9, plc.Conductor(1.6, 0.028, 44.0))  # no rated strength known: no limit


@pytest.mark.parametrize("bad", ["20", True, 20 + 1j, float("nan"), 1e300])
def test_span_wavenumber_refuses_text_bools_complex_and_out_of_range(bad):
    # Old code: np.asarray("20", float) read the text as 20 Hz, and 1e300 Hz gave nan.
    with pytest.raises(plc.InputError, match="'frequency'"):
        plc.Span.paper_lab().loop_length(bad)


def test_loop_length_at_tiny_and_zero_frequency_is_the_string_limit():
    span = plc.Span.paper_lab()
    # c / (2 f), the string limit, to 1e-12: old code underflowed k^2 and divided by zero.
    c = span.wave_speed
    assert span.loop_length(1e-300) == pytest.approx(c / 2e-300, rel=1e-12)
    assert span.loop_length(0.0) == np.inf


def test_conductor_name_must_be_text():
    with pytest.raises(plc.InputError, match="'name'"):
        plc.Conductor(1.6, 0.028, 44.0, name=None)


def test_tension_at_temperature_refuses_temperatures_above_melting():
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    # Old code: 1e300 degC overflowed the cubic and returned nan.
    with pytest.raises(plc.InputError, match="'temperature'"):
        plc.tension_at_temperature(span, 1e300)
    with pytest.raises(plc.InputError, match="'reference_temperature'"):
        plc.tension_at_temperature(span, 20.0, reference_temperature=1e300)
