"""Loads against closed forms: the consistent aeolian load on a graded mesh, and bad input."""

import numpy as np
import pytest
from scipy.integrate import quad

import powerline_control as plc
from powerline_control.errors import InputError

DRAKE = plc.Span.at_rts_fraction(300.0, "drake", 0.20)


def test_aeolian_load_on_graded_mesh_does_the_virtual_work_of_the_lift():
    # The consistent load F satisfies F . u = integral q(x) v(x) dx for any field v the elements
    # represent exactly: Hermite cubics carry v = x^2 (L - x) (zero slope at the clamped left end,
    # zero at the pinned right end) exactly on any mesh, graded or not.
    model = plc.LineModel(DRAKE, bc=("clamped", "pinned"), max_frequency=10.0)
    assert np.ptp(model.element_lengths) > 0.5 * model.element_length    # graded at x = 0
    force = plc.AeolianForce(wind_speed=1.7)
    bound = force.bind(model)
    length = DRAKE.length
    x = model.node_positions
    full = np.zeros(model._n_total)
    full[0::2], full[1::2] = x**2 * (length - x), 2 * x * length - 3 * x**2
    u = full[model._free]
    q = force.lift_per_length(DRAKE.conductor)
    k = bound.wavenumber
    exact = quad(lambda s: q * np.sin(k * s) * s**2 * (length - s), 0, length, limit=2000)[0]
    # 4-point Gauss is exact to degree 7; sin(kx) times a cubic on ~4 elements per loop: ~1e-9
    assert bound.load @ u == pytest.approx(exact, rel=1e-7)
    # the wavenumber is the taut-beam dispersion root (domain 2.3)
    cond, t, w = DRAKE.conductor, DRAKE.tension, 2 * np.pi * bound.frequency
    assert cond.ei * k**4 + t * k**2 == pytest.approx(cond.mass_per_length * w**2, rel=1e-12)


def test_uncorrelated_aeolian_lift_is_uniform():
    model = plc.LineModel(plc.Span.paper_lab(), 12)
    bound = plc.AeolianForce(2.0, correlated=False).bind(model)
    expected = model.distributed_load(lambda x: np.full_like(x, 1.0))
    q = plc.AeolianForce(2.0).lift_per_length(model.span.conductor)
    np.testing.assert_allclose(bound.load, q * expected, rtol=1e-13, atol=1e-15 * q)


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: plc.AeolianForce(3.0, correlated="no"), "correlated"),
        (lambda: plc.AeolianForce(3.0, correlated=0), "correlated"),
        (lambda: plc.AeolianForce(3.0, correlated=None), "correlated"),
        (lambda: plc.AeolianForce(float("nan")), "wind_speed"),
        (lambda: plc.AeolianForce(3.0, lift_coefficient=-0.3), "lift_coefficient"),
        (lambda: plc.AeolianForce(3.0, air_density=0.0), "air_density"),
        (lambda: plc.RandomForce(1.0, 0.5, bandwidth=1e9).values(np.array([0.0, 100.0])),
         "bandwidth"),
        (lambda: plc.RandomForce(1.0, 0.5, bandwidth=float("inf")), "bandwidth"),
        (lambda: plc.RandomForce(1.0, 0.5).values(np.array([0.0, np.nan])), "t"),
        (lambda: plc.HarmonicForce(1.0, 10.0, float("nan")), "position"),
        (lambda: plc.HarmonicForce(1.0, 10.0, 0.5, phase=np.inf), "phase"),
    ],
)
def test_bad_load_arguments_name_the_parameter(make, name):
    with pytest.raises(InputError, match=name):
        make()


@pytest.mark.parametrize("position", [1.0, float("nan"), "mid", True])
def test_aeolian_force_has_no_point_of_application(position):
    # Old code kept any position (even nan) and ignored it: the lift is distributed.
    with pytest.raises(InputError, match="'position' parameter of an AeolianForce"):
        plc.AeolianForce(3.0, position=position)
