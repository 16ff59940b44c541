"""Simulation against closed forms: free vibration, FOH vs exact harmonic, noise, warnings."""

import control as ct
import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import InputError, TruncationWarning

LAB = plc.Span.paper_lab()
MODEL20 = plc.LineModel(LAB, 20)


def test_free_vibration_of_one_mode_is_a_cosine():
    snap = plc.simulate(MODEL20, None, duration=1.0, dt=1e-3, initial_modes={1: 2e-3})
    f2 = MODEL20.natural_frequencies(2)[1]
    expected = np.outer(MODEL20.mode_shapes(2)[:, 1] * 2e-3, np.cos(2 * np.pi * f2 * snap.t))
    np.testing.assert_allclose(snap.displacement, expected, atol=1e-14)


def test_harmonic_closed_form_equals_first_order_hold_at_fine_steps():
    force = plc.HarmonicForce(1.0, 9.0, 1.1)
    exact = plc.simulate(MODEL20, force, duration=0.5, dt=2e-5).displacement
    # A RandomForce-like path (FOH) for the same sine: give the load without its frequency.
    class SampledSine:
        frequency = None
        position = 1.1

        def values(self, t):
            return force.values(t)

        def load_vector(self, model):
            return model.point_load(self.position)

    foh = plc.simulate(MODEL20, SampledSine(), duration=0.5, dt=2e-5).displacement
    # FOH interpolation error of a sine is (w h)^2 / 8 relative ~ 1.6e-6 here.
    assert np.abs(foh - exact).max() < 1e-5 * np.abs(exact).max()


def test_damped_free_decay_envelope():
    model = plc.LineModel(LAB, 20, damping=plc.ModalDamping(0.05))
    snap = plc.simulate(model, None, duration=2.0, dt=1e-3, initial_modes={0: 1e-3})
    f1 = model.natural_frequencies(1)[0]
    mid = snap.displacement[10]
    omega = 2 * np.pi * f1
    wd = omega * np.sqrt(1 - 0.05**2)
    # Exact single-degree-of-freedom free response from rest at unit displacement.
    expected = 1e-3 * np.exp(-0.05 * omega * snap.t) * (
        np.cos(wd * snap.t) + 0.05 / np.sqrt(1 - 0.05**2) * np.sin(wd * snap.t))
    np.testing.assert_allclose(mid, expected, atol=1e-12)


def test_noise_is_seeded_and_has_requested_size():
    force = plc.HarmonicForce(1.0, 12.0, 0.5)
    a = plc.simulate(MODEL20, force, 2.0, 1e-3, noise_fraction=0.01, seed=4)
    b = plc.simulate(MODEL20, force, 2.0, 1e-3, noise_fraction=0.01, seed=4)
    np.testing.assert_array_equal(a.displacement, b.displacement)
    rms = np.sqrt(np.mean(a.true_displacement**2))
    noise = a.displacement - a.true_displacement
    # 21 x 2001 samples: the sample std is within ~1 % of the true one.
    assert abs(noise.std() / (0.01 * rms) - 1) < 0.03
    assert a.noise_std == pytest.approx(0.01 * rms)


def test_pinned_support_rows_are_zero_without_noise():
    snap = plc.simulate(MODEL20, plc.HarmonicForce(1.0, 12.0, 0.5), 0.2, 1e-3)
    assert np.all(snap.displacement[[0, -1]] == 0.0)


def test_superposition_of_two_forces():
    f1, f2 = plc.HarmonicForce(1.0, 12.0, 0.5), plc.HarmonicForce(0.5, 30.0, 2.0)
    both = plc.simulate(MODEL20, [f1, f2], 0.5, 1e-3)
    parts = plc.simulate(MODEL20, f1, 0.5, 1e-3).displacement + \
        plc.simulate(MODEL20, f2, 0.5, 1e-3).displacement
    np.testing.assert_allclose(both.displacement, parts, atol=1e-15)
    assert both.inputs.shape == (2, both.t.size)
    with pytest.raises(InputError, match="inputs"):
        both.force  # noqa: B018


def test_aeolian_force_excites_the_loop_pattern():
    # 2.2 m/s on the 10.5 mm conductor sheds at St V / d = 38.8 Hz, close to mode 4 (37.5 Hz).
    force = plc.AeolianForce(wind_speed=2.2)
    model = plc.LineModel(LAB, 40, damping=plc.ModalDamping(0.01))
    snap = plc.simulate(model, force, duration=3.0, dt=5e-4)
    envelope = np.abs(snap.displacement[:, -2000:]).max(axis=1)
    peaks = np.flatnonzero((envelope[1:-1] > envelope[:-2]) & (envelope[1:-1] > envelope[2:])) + 1
    # Mode 4 has 4 loops with antinodes at (2k-1) L / 8.
    np.testing.assert_allclose(snap.x[peaks], (2 * np.arange(1, 5) - 1) * LAB.length / 8,
                               atol=LAB.length / 40)


def test_resonant_undamped_forcing_grows_linearly():
    f1 = MODEL20.natural_frequencies(1)[0]
    force = plc.HarmonicForce(1.0, float(f1), LAB.length / 2)
    snap = plc.simulate(MODEL20, force, duration=4.0, dt=1e-3)
    mid = np.abs(snap.displacement[10])
    early, late = mid[: mid.size // 4].max(), mid[-mid.size // 4:].max()
    # Exactly at resonance the amplitude grows as t: the last quarter is ~4x the first.
    assert 3.0 < late / early < 5.0


def test_warns_when_dt_cannot_resolve_the_load():
    with pytest.warns(TruncationWarning, match="Nyquist"):
        plc.simulate(MODEL20, plc.HarmonicForce(1.0, 600.0, 0.5), 0.1, 1e-3)


def test_warns_when_truncation_cannot_resolve_the_load():
    with pytest.warns(TruncationWarning, match="highest mode"):
        plc.simulate(MODEL20, plc.HarmonicForce(1.0, 40.0, 0.5), 0.1, 1e-4, n_modes=3)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(dt=0.0), "dt"),
        (dict(dt=-1e-3), "dt"),
        (dict(duration=float("nan")), "duration"),
        (dict(dt=2.0, duration=1.0), "dt"),
        (dict(noise_std=-1.0), "noise_std"),
        (dict(seed=-3), "seed"),
        (dict(initial_displacement=np.zeros(5)), "initial_displacement"),
        (dict(n_modes=1000), "n_modes"),
        (dict(force="sine"), "force"),
        (dict(force=plc.HarmonicForce(1.0, 10.0, 9.0)), "position"),
    ],
)
def test_bad_simulation_arguments(kwargs, name):
    args = {"force": plc.HarmonicForce(1.0, 10.0, 0.5), "duration": 0.1, "dt": 1e-3, **kwargs}
    with pytest.raises(InputError, match=name):
        plc.simulate(MODEL20, **args)


@pytest.mark.parametrize("force", [plc.HarmonicForce(1.0, 12.0, 0.5),
                                   plc.RandomForce(1.0, 0.5, 80.0, seed=2)])
def test_continuing_from_final_state_equals_one_long_run(force):
    model = plc.LineModel(LAB, 20, damping=plc.ModalDamping(0.01))
    whole = plc.simulate(model, force, duration=1.0, dt=1e-3)
    first = plc.simulate(model, force, duration=0.4, dt=1e-3)
    second = plc.simulate(model, force, duration=0.6, dt=1e-3, start_time=first.t[-1],
                          initial_state=first.final_state)
    joined = np.hstack([first.true_displacement, second.true_displacement[:, 1:]])
    # Same exact propagation split in two: agreement to round-off (the random load's spline is
    # evaluated at the same absolute times).
    np.testing.assert_allclose(joined, whole.true_displacement, atol=1e-12 * np.abs(joined).max())
    np.testing.assert_allclose(second.t, whole.t[400:], atol=1e-12)


def test_user_load_with_a_frequency_attribute_is_integrated_from_its_values():
    class SquareWave:
        """A 5 N square wave: it has a frequency, but it is no sine."""

        frequency = 12.0
        position = 0.5

        def values(self, t):
            return 5.0 * np.sign(np.sin(2 * np.pi * self.frequency * t))

        def load_vector(self, model):
            return model.point_load(self.position)

    model = plc.LineModel(LAB, 10)
    snap = plc.simulate(model, SquareWave(), duration=0.5, dt=1e-4)
    # The independent peer integrates the same sampled values (linear between samples).
    reference = ct.forced_response(model.to_statespace(force_positions=[0.5]), snap.t,
                                   SquareWave().values(snap.t)).outputs
    np.testing.assert_allclose(snap.displacement, reference, atol=1e-9 * np.abs(reference).max())


def test_load_without_position_is_a_clear_error():
    class Nowhere:
        def values(self, t):
            return np.ones_like(t)

        def load_vector(self, model):
            return model.point_load(1.0)

    with pytest.raises(InputError, match="position"):
        plc.simulate(MODEL20, Nowhere(), duration=0.1, dt=1e-3)


def test_random_force_rejects_generators_so_values_repeat():
    with pytest.raises(InputError, match="seed"):
        plc.RandomForce(1.0, 0.5, seed=np.random.default_rng(0))
    force = plc.RandomForce(1.0, 0.5, seed=3)
    t = np.linspace(0, 1, 7)
    np.testing.assert_array_equal(force.values(t), force.values(t))
