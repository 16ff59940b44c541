"""Conductor change-of-state data and tension_at_temperature."""

import math

import numpy as np
import pytest
import scipy.optimize

import powerline_control as plc

KGF = 9.80665  # N per kilogram-force (the textbook works in kg)


def test_textbook_example_chakrabarti_5_9():
    """Chakrabarti, Soni, Gupta & Bhatnagar, *A Textbook on Power System Engineering*, 2nd ed.
    (Dhanpat Rai), Part II ch. 5, Example 5.9 (p. 201), as transcribed by FOSSEE
    (Scilab-TBC-Uploads 3472/CH12/EX12.9): level span 300 m, conductor 226 mm^2, 19.53 mm,
    0.844 kg/m, ultimate strength 7950 kg, alpha 18.44e-6 /degC, E 9.32e3 kg/mm^2. Worst case
    -5 degC with 9.5 mm radial ice (915 kg/m^3) and 39 kg/m^2 wind on the iced diameter, at half
    the ultimate strength (3975 kg); erection at 45 degC in still air. Wanted: the erection
    tension.

    The book's change of state is the same parabolic cubic (in kg, with the half span l = S/2,
    T2^2 [T2 - T1 + a E (alpha dt + (w1 l / T1)^2 / 6)] = w2^2 l^2 a E / 6). Its exact positive
    root is 1644.78 kg; the book prints 1710 kg, 4.0 % higher (the FOSSEE transcription computes
    the root and then takes the printed value "directly from textbook"). The test checks our
    tension against the exact root of the book's equation, solved here independently with
    numpy.roots on the book's own coefficients in its own units, to 1e-9, and records the
    distance to the printed figure (within 4.1 %).
    """
    area, diameter, weight = 226.0, 1.953, 0.844                 # mm^2, cm, kg/m
    e_kg, alpha, span_length = 9.32e3, 18.44e-6, 300.0           # kg/mm^2, /degC, m
    ice = 915.0 * math.pi * 0.95 * (diameter + 0.95) * 1e-4        # kg/m
    wind = 39.0 * (diameter + 2 * 0.95) * 1e-2                     # kg/m
    w1 = math.hypot(weight + ice, wind)                            # 2.2219 kg/m
    t1 = 7950.0 / 2
    half = span_length / 2
    b = area * e_kg * (alpha * 50.0 + (w1 * half / t1) ** 2 / 6) - t1
    roots = np.roots([1.0, b, 0.0, -(weight**2 * half**2 * area * e_kg / 6)])
    book_root = max(r.real for r in roots if abs(r.imag) < 1e-9)   # kg
    assert book_root == pytest.approx(1644.78, abs=0.01)

    conductor = plc.Conductor(mass_per_length=weight, diameter=diameter / 100, ei=0.0,
                              rated_strength=7950.0 * KGF, area=area * 1e-6,
                              elastic_modulus=e_kg * KGF * 1e6, thermal_expansion=alpha)
    span = plc.Span(span_length, t1 * KGF, conductor)
    tension = plc.tension_at_temperature(span, 45.0, reference_temperature=-5.0,
                                         reference_load=w1 * KGF)
    assert tension / KGF == pytest.approx(book_root, rel=1e-9)
    assert abs(tension / KGF / 1710.0 - 1) < 0.041                # the printed answer


def _exact_catenary_tension(span, temperature, reference_temperature):
    """Independent truth: length compatibility of the exact catenary with Hooke's law on the
    mean tension and thermal strain, solved by Brent's method (no parabola, no cubic)."""
    cond = span.conductor
    w = cond.mass_per_length * KGF
    ea = cond.elastic_modulus * cond.area

    def arc(h):
        return 2 * h / w * math.sinh(w * span.length / (2 * h))

    def mean_tension(h):
        # mean of T = H cosh(w x / H) over the arc: (H S / 2 + H^2 sinh(w S / H) / (2 w)) / arc
        return (h * span.length / 2 + h**2 * math.sinh(w * span.length / h) / (2 * w)) / arc(h)

    h_ref = span.tension
    unstressed = arc(h_ref) / (1 + mean_tension(h_ref) / ea)

    def residual(h):
        free = unstressed * (1 + cond.thermal_expansion * (temperature - reference_temperature))
        return arc(h) - free * (1 + mean_tension(h) / ea)

    return scipy.optimize.brentq(residual, 0.2 * h_ref, 5 * h_ref, xtol=1e-9)


@pytest.mark.parametrize("preset", ["drake", "condor", "cardinal", "aster570"])
@pytest.mark.parametrize("temperature", [-20.0, 0.0, 40.0, 75.0])
def test_parabolic_change_of_state_matches_the_exact_catenary(preset, temperature):
    span = plc.Span.at_rts_fraction(300.0, preset, 0.20)
    exact = _exact_catenary_tension(span, temperature, 15.0)
    ours = plc.tension_at_temperature(span, temperature)
    # The parabola drops terms of order (sag / span)^2 = (w S / 8 H)^2 ~ 5e-4 at 300 m; the
    # tension change itself is a few kN, so 1e-3 of the tension is a real test of it.
    assert ours == pytest.approx(exact, rel=1e-3)
    assert (ours - span.tension) * (temperature - 15.0) < 0      # warmer: slacker


def test_no_temperature_change_returns_the_reference_tension():
    span = plc.Span.at_rts_fraction(400.0, "aster570", 0.2)
    assert plc.tension_at_temperature(span, 15.0) == pytest.approx(span.tension, rel=1e-14)
    assert plc.tension_at_temperature(span, 30.0, reference_temperature=30.0) == \
        pytest.approx(span.tension, rel=1e-14)


def test_array_in_array_out_and_every_preset_has_the_data():
    for name in plc.conductors:
        cond = plc.conductors[name]
        assert cond.area > 0 and cond.elastic_modulus > 0 and cond.thermal_expansion > 0
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    t = np.array([-10.0, 15.0, 35.0])
    out = plc.tension_at_temperature(span, t)
    assert out.shape == (3,)
    assert out[1] == pytest.approx(span.tension)
    assert out[0] > out[1] > out[2]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -300.0, "hot", True, np.array([[1.0]])])
def test_bad_temperatures_are_refused(bad):
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    with pytest.raises(plc.InputError, match="temperature"):
        plc.tension_at_temperature(span, bad)


def test_a_conductor_without_the_data_is_refused_naming_the_field():
    span = plc.Span(300.0, 28e3, plc.Conductor(1.628, 0.02814, 44.0, 140.1e3))
    with pytest.raises(plc.InputError, match="conductor.area"):
        plc.tension_at_temperature(span, 20.0)


def test_a_tension_reaching_the_rated_strength_is_refused():
    span = plc.Span.at_rts_fraction(300.0, "drake", 0.7)   # 98 kN at 15 degC, 147 kN at -50
    with pytest.raises(plc.InputError, match="rated strength"):
        plc.tension_at_temperature(span, -50.0)
