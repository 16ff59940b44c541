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
