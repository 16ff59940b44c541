"""Tones, phasors, spectral lines and peaks (powerline_control._spectral) against known signals.

The truth is independent of the module: closed-form sinusoids, the continuous Hann kernel's
closed form for the interpolation bias, the Cramer-Rao bound for a tone in white noise, and the
least-squares theory of a sine amplitude in white noise.
"""

import math

import numpy as np
import pytest

import powerline_control as plc
from powerline_control import _spectral as sp
from powerline_control.errors import InputError


def _hann_kernel(nu):
    """|DTFT| of a long Hann window at nu bins from its centre, up to a constant:
    sinc(nu) / (1 - nu^2), with its limit 1/2 at |nu| = 1."""
    nu = np.asarray(nu, dtype=float)
    edge = np.isclose(np.abs(nu), 1.0, rtol=0.0, atol=1e-12)
    safe = np.where(edge, 0.0, nu)
    return np.where(edge, 0.5, np.abs(np.sinc(safe) / (1.0 - safe**2)))


def _log_parabola_bias_bound(pad: int) -> float:
    """Largest error (original bins) of the 3-point log-parabola on the continuous Hann kernel,
    bins 1 / pad apart, over every position of the tone between two bins."""
    delta = np.linspace(-0.5, 0.5, 20001)            # tone position, padded bins from bin k
    left, mid, right = (np.log(_hann_kernel((j - delta) / pad)) for j in (-1, 0, 1))
    offset = 0.5 * (left - right) / (left - 2 * mid + right)
    return float(np.max(np.abs(offset - delta))) / pad


def _tone(n, cycles, phase=0.3, amplitude=1.0):
    return amplitude * np.sin(2 * np.pi * cycles / n * np.arange(n) + phase)


# ----------------------------------------------------------------------------- peaks
def test_log_parabola_bias_bound_is_the_documented_one():
    """The numbers the module quotes (0.016 bin without padding, 0.0016 with padding 2)."""
    assert _log_parabola_bias_bound(1) == pytest.approx(0.0160, abs=5e-5)
    assert _log_parabola_bias_bound(2) == pytest.approx(0.00163, abs=5e-6)


@pytest.mark.parametrize("pad", [1, 2, 4])
def test_dominant_frequency_bias_stays_within_the_hann_bound(pad):
    """A sweep of a tone across a bin: the error never exceeds the continuous kernel's bound plus
    the leakage of the tone's negative-frequency image, and reaches the bound (so the bound is
    what limits it, not something else)."""
    n = 1000
    cycles = 40.0 + np.linspace(0.0, 1.0, 41)
    errors = np.array([sp.dominant_frequency(_tone(n, m)[None, :], 1.0, pad=pad, min_fft=1)
                       - m / n for m in cycles]) * n       # in bins of 1 / n
    bound = _log_parabola_bias_bound(pad)
    # The image at 2 m bins perturbs the three log powers by at most 2 |W(2m)| / |W(0)|, the
    # sidelobe envelope 2 / (pi nu (nu^2 - 1)); the offset moves by at most that (the log
    # power's curvature at the peak exceeds 1 per bin^2). np.hanning is the symmetric window of
    # n - 1 intervals: its kernel is the continuous one stretched by n / (n - 1), which moves the
    # bias (~ pad^-3.3) by ~3.3 / n of itself.
    nu = 2 * cycles.min()
    leakage = 2.0 / (math.pi * nu * (nu**2 - 1))
    assert np.max(np.abs(errors)) <= bound * (1 + 4.0 / n) + leakage
    assert np.max(np.abs(errors)) >= 0.8 * bound


def test_padding_two_is_ten_times_closer_for_tones():
    """The closed loop's measurement, on tones at random positions: padding 2 cuts the worst
    error ~10x (the bounds' ratio, 0.016 / 0.0016)."""
    rng = np.random.default_rng(4)
    worst = {1: 0.0, 2: 0.0}
    for _ in range(100):
        n = int(rng.integers(200, 3000))
        cycles = rng.uniform(10.0, n / 4)
        signal = _tone(n, cycles, phase=rng.uniform(0, 2 * np.pi))[None, :]
        for pad in worst:
            error = abs(sp.dominant_frequency(signal, 1.0, pad=pad, min_fft=1) - cycles / n) * n
            worst[pad] = max(worst[pad], error)
    assert worst[1] / worst[2] > 8.0


def test_interpolated_peak_is_exact_on_a_gaussian_lobe():
    """A Gaussian's log is a parabola: the vertex is exact (round-off)."""
    k = np.arange(32)
    for centre in (10.0, 10.25, 10.5, 17.9):
        power = np.exp(-0.3 * (k - centre) ** 2)
        assert sp.interpolated_peak(power) == pytest.approx(centre, abs=1e-12)


def test_interpolated_peak_at_an_edge_or_next_to_an_empty_bin_is_the_bin():
    assert sp.interpolated_peak(np.array([3.0, 2.0, 1.0])) == 0.0
    assert sp.interpolated_peak(np.array([0.0, 5.0, 1.0])) == 1.0
    # log powers 0, 2 log 2, log 2: vertex offset (0 - log 2) / (2 (0 - 4 log 2 + log 2)) = 1/6
    assert sp.interpolated_peak(np.array([1.0, 4.0, 2.0, 1.0]), index=1) == pytest.approx(7 / 6)


def test_dominant_frequency_in_hertz_ignores_the_mean_and_sums_signals():
    dt = 2e-3
    t = np.arange(1500) * dt
    shape = np.array([[0.0], [0.3], [1.0], [-0.7]])
    signals = 5.0 + shape * np.sin(2 * np.pi * 23.7 * t)   # a large offset, one node at rest
    # 1500 samples at 2 ms: bins of 1/3 Hz, padded 2x; bias bound 0.0016 bin = 5e-4 Hz.
    assert sp.dominant_frequency(signals, dt) == pytest.approx(23.7, abs=6e-4)


@pytest.mark.parametrize("n", [1999, 1000, 997])
def test_dominant_frequency_is_that_of_the_brute_force_padded_periodogram(n):
    # Padded lengths 2 x 1999 and 2 x 997 have a large prime factor (the FFT goes through a
    # chirp z-transform), 2000 does not. Truth: the Hann periodogram as a direct DFT sum over
    # the padded bins, summed over the signals, its largest bin above DC and the documented
    # log-parabola through it; equal to round-off (the DFT sum's own error is ~1e-13).
    rng = np.random.default_rng(n)
    t = np.arange(n)
    signals = (np.outer([1.0, -0.4, 0.7], np.sin(2 * np.pi * 0.0613 * t + 0.2))
               + 0.8 * np.sin(2 * np.pi * 0.1377 * t) + 0.3 * rng.standard_normal((3, n)))
    n_fft = 2 * n
    windowed = (signals - signals.mean(axis=1, keepdims=True)) * np.hanning(n)
    bins = np.arange(n_fft // 2 + 1)
    power = np.sum(np.abs(windowed @ np.exp(-2j * np.pi * np.outer(t, bins) / n_fft)) ** 2,
                   axis=0)
    k = int(np.argmax(power[1:])) + 1
    left, mid, right = np.log(power[k - 1 : k + 2])
    expected = (k + 0.5 * (left - right) / (left - 2 * mid + right)) / n_fft
    assert sp.dominant_frequency(signals, 1.0) == pytest.approx(expected, rel=1e-12)


def test_the_stronger_of_two_tones_is_dominant():
    t = np.arange(4000) * 1e-3
    signals = np.vstack([np.sin(2 * np.pi * 11.0 * t) + 3.0 * np.sin(2 * np.pi * 31.3 * t)])
    # 4 s: bins of 0.25 Hz; the bound 0.0016 bin, 1e-3 Hz with room for the weak tone's sidelobe.
    assert sp.dominant_frequency(signals, 1e-3) == pytest.approx(31.3, abs=1e-3)


def test_dominant_frequency_in_noise_is_within_the_cramer_rao_scatter():
    """A tone of amplitude 0.5 in unit white noise, 20 seeds: the Cramer-Rao std of a frequency
    estimate is sqrt(12 / (a^2 n^3)) / (2 pi) cycles/sample; a Hann-windowed estimate is less
    efficient (its noise bandwidth is 1.5 bins, std ~1.5x), so the errors stay within 5x that."""
    n, amplitude, cycles = 2000, 0.5, 123.4
    crb = math.sqrt(12.0 / (amplitude**2 * n**3)) / (2 * math.pi)
    errors = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        signal = _tone(n, cycles, amplitude=amplitude) + rng.standard_normal(n)
        errors.append(sp.dominant_frequency(signal[None, :], 1.0) - cycles / n)
    errors = np.array(errors)
    bias = _log_parabola_bias_bound(2) / n
    assert np.max(np.abs(errors)) < bias + 5 * 1.5 * crb
    assert np.std(errors) > 0.5 * crb            # the noise does show: this is not a no-op


# ----------------------------------------------------------------------------- phasors
def test_phasor_of_a_sine_with_offset_is_exact():
    """a sin(w t + phi) + c = Re(A e^{i w t}) + c with A = -i a e^{i phi}, on any window length
    (not a whole number of periods) and absolute times."""
    t = 17.3 + np.arange(777) * 1e-3
    a, phi, c = np.array([[2.0], [0.5]]), np.array([[0.4], [-2.0]]), np.array([[3.0], [-1.0]])
    f = 9.1
    signals = a * np.sin(2 * np.pi * f * t + phi) + c
    fit = sp.fit_harmonic(signals, t, f)
    expected = (-1j * a * np.exp(1j * phi)).ravel()
    assert np.allclose(fit.phasors, expected, rtol=0, atol=1e-10)   # round-off of the lstsq
    assert np.allclose(fit.offsets, c.ravel(), rtol=0, atol=1e-10)
    assert np.all(fit.residual_variance < 1e-20)
    assert np.allclose(sp.fit_phasors(signals, t, f), expected, rtol=0, atol=1e-10)


def test_phasor_without_constant_matches_with_a_zero_mean_whole_period_record():
    t = np.arange(1000) * 1e-3                      # 10 periods of 10 Hz
    signals = np.vstack([np.cos(2 * np.pi * 10.0 * t + 1.0)])
    assert np.allclose(sp.fit_phasors(signals, t, 10.0, constant=False), np.exp(1j * 1.0),
                       atol=1e-12)
    assert np.all(sp.fit_harmonic(signals, t, 10.0, constant=False).offsets == 0.0)


def test_phasors_of_two_tones_each_within_their_leakage():
    """At each tone's frequency the other leaks into the fit by at most its amplitude times
    |sinc| of their separation, <= 1 / (pi df T) of it (here 1 / (pi 20))."""
    t = np.arange(2000) * 1e-3
    signals = np.vstack([2.0 * np.sin(2 * np.pi * 15.0 * t), 1.0 * np.cos(2 * np.pi * 25.0 * t)])
    both = signals.sum(axis=0, keepdims=True)
    leak = 1.0 / (math.pi * 10.0 * 2.0)
    assert abs(sp.fit_phasors(both, t, 15.0)[0] - (-2.0j)) <= 1.0 * leak
    assert abs(sp.fit_phasors(both, t, 25.0)[0] - 1.0) <= 2.0 * leak


def test_phasor_in_noise_is_within_its_least_squares_std():
    """White noise sigma gives each of the cos and sin coefficients a std of sigma sqrt(2 / n)
    (independent errors); 1000 signals in one call: the scatter matches, and the residual
    variance estimates sigma^2."""
    rng = np.random.default_rng(0)
    n, sigma = 1500, 0.2
    t = np.arange(n) * 1e-3
    truth = 0.8 * np.exp(0.6j)
    clean = (truth * np.exp(2j * np.pi * 12.0 * t)).real
    fit = sp.fit_harmonic(clean + sigma * rng.standard_normal((1000, n)), t, 12.0)
    errors = fit.phasors - truth
    expected_std = sigma * math.sqrt(2.0 / n)
    # The std of 1000 samples scatters by 1 / sqrt(2000) = 2.2 % of itself: 10 % is 4.5 of that.
    assert np.std(errors.real) == pytest.approx(expected_std, rel=0.10)
    assert np.std(errors.imag) == pytest.approx(expected_std, rel=0.10)
    assert abs(np.mean(errors)) < 4 * expected_std / math.sqrt(1000)
    # 1000 x 1497 degrees of freedom: the variance's scatter is 0.04 %.
    assert np.mean(fit.residual_variance) == pytest.approx(sigma**2, rel=0.005)


def test_load_phasor_of_the_package_loads():
    """HarmonicForce a sin(w t + phi): A = -i a e^{i phi}; a bound AeolianForce's unit sine:
    A = -i; a constant added to a load does not change it."""
    force = plc.HarmonicForce(amplitude=1.7, frequency=13.0, position=1.0, phase=2.2)
    assert sp.load_phasor(force, 13.0) == pytest.approx(-1.7j * np.exp(2.2j), abs=1e-13)
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=10)
    bound = plc.AeolianForce(wind_speed=1.5).bind(model)
    assert sp.load_phasor(bound, bound.frequency) == pytest.approx(-1j, abs=1e-13)

    class Offset:
        def values(self, t):
            return 4.0 + force.values(t)

    assert sp.load_phasor(Offset(), 13.0) == pytest.approx(sp.load_phasor(force, 13.0), abs=1e-13)


def test_load_phasor_agrees_with_fitting_the_load_on_a_long_record():
    force = plc.HarmonicForce(amplitude=0.9, frequency=7.5, position=1.0, phase=-0.3)
    t = 3.0 + np.arange(3333) * 1e-3
    fitted = sp.fit_phasors(force.values(t)[None, :], t, 7.5)[0]
    assert sp.load_phasor(force, 7.5) == pytest.approx(fitted, abs=1e-12)


# ----------------------------------------------------------------------------- lines
def test_spectral_lines_are_found_at_their_frequencies_and_nothing_else():
    """Three sinusoids (one 100x stronger, two 0.5 Hz apart, the weakest at half the noise std)
    in six coordinates with white noise: the extraction finds exactly them."""
    rng = np.random.default_rng(21)
    dt, n = 1e-3, 8000
    t = np.arange(n) * dt
    lines = [(7.3, 50.0), (19.1, 1.0), (19.6, 0.5)]   # (Hz, amplitude in noise std)
    shapes = rng.standard_normal((6, 3))
    shapes /= np.linalg.norm(shapes, axis=0)
    coords = sum(a * np.outer(shapes[:, i], np.sin(2 * np.pi * f * t + i))
                 for i, (f, a) in enumerate(lines)) + rng.standard_normal((6, n))
    freqs, found_shapes, residual = sp.extract_lines(coords, dt, 10)
    assert freqs.size == 3
    # Cramer-Rao: the weakest line's frequency std is sqrt(12 / (A^2 N^3)) / (2 pi dt) = 1.5 mHz;
    # 10 mHz is about 6 of them.
    assert np.allclose(freqs, [f for f, _ in lines], atol=0.01)
    for i in range(3):      # shapes up to sign; the weakest (SNR 0.5/sample) within a few %
        assert abs(float(found_shapes[:, i] @ shapes[:, i])) > 0.95
    # What is left is the noise: unit variance within the scatter of 48,000 samples.
    assert abs(float(np.mean(residual**2)) - 1.0) < 0.05


def test_noise_alone_has_no_lines_and_occupies_about_a_thousandth_of_the_bins():
    rng = np.random.default_rng(3)
    noise = rng.standard_normal((4, 6000))
    freqs, shapes, residual = sp.extract_lines(noise, 1e-3, 10)
    assert freqs.size == 0 and shapes.shape == (4, 0) and np.array_equal(residual, noise)
    # The level is the 0.1 % quantile of noise alone: 3000 bins, ~3 expected, 0.5 % is 15.
    assert sp.line_occupancy(noise, 1.0) < 0.005


def test_line_power_of_a_tone_on_and_off_the_grid():
    """|sum_n a cos(w n + phi) e^{-i w n}|^2 -> (a n / 2)^2 for a tone of many cycles, at its
    frequency whether or not that lies on an FFT bin."""
    n = 5000
    for cycles in (100.0, 100.37):
        signal = 0.6 * np.cos(2 * np.pi * cycles / n * np.arange(n) + 0.8)[None, :]
        # the negative-frequency image adds a cross term <= a^2 n / (2 pi 2 cycles / n) ~ 0.1 %
        assert sp.line_power(signal, cycles / n, 1.0) == pytest.approx((0.3 * n) ** 2, rel=2e-3)


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda: sp.dominant_frequency(np.full((2, 100), 3.0), 1e-3), "'signals'.*constant"),
        (lambda: sp.dominant_frequency(np.ones((1, 1)), 1e-3), "'signals'.*4 time samples"),
        (lambda: sp.dominant_frequency(np.ones(100), 1e-3), "'signals'.*2-d"),
        (lambda: sp.dominant_frequency(np.array([[0.0, 1.0, np.nan, 1.0, 0.0]]), 1e-3),
         "'signals'.*NaN"),
        (lambda: sp.dominant_frequency(np.ones((0, 10)), 1e-3), "'signals'"),
        (lambda: sp.dominant_frequency(np.eye(5), 0.0), "'dt'"),
        (lambda: sp.dominant_frequency(np.eye(5), 1.0, pad=0.5), "'pad'"),
        (lambda: sp.dominant_frequency(np.eye(5), 1.0, min_fft=0), "'min_fft'"),
        (lambda: sp.fit_phasors(np.ones((1, 1)), np.zeros(1), 5.0), "'signals'.*3 time samples"),
        (lambda: sp.fit_phasors(np.ones((1, 5)), np.arange(4.0), 5.0), "'t'"),
        (lambda: sp.fit_phasors(np.ones((1, 5)), [0, 1, np.nan, 3, 4], 5.0), "'t'.*NaN"),
        (lambda: sp.fit_phasors(np.ones((1, 5)), np.arange(5.0), 0.0), "'frequency'"),
        (lambda: sp.fit_phasors(np.ones((1, 5)), np.arange(5.0), 1.0, constant=1), "'constant'"),
        (lambda: sp.load_phasor(object(), 5.0), "'load'"),
        (lambda: sp.load_phasor(plc.HarmonicForce(1.0, 5.0, 1.0), -5.0), "'frequency'"),
        (lambda: sp.load_phasor(plc.HarmonicForce(1.0, 5.0, 1.0), 5.0, samples=2), "'samples'"),
        (lambda: sp.interpolated_peak(np.array([1.0, -2.0, 1.0])), "'power'"),
        (lambda: sp.interpolated_peak(np.ones(3), index=3), "'index'"),
        (lambda: sp.line_power(np.ones((1, 5)), np.nan, 1.0), "'frequency'"),
        (lambda: sp.line_occupancy(np.ones((1, 5)), 0.0), "'noise_std'"),
        (lambda: sp.extract_lines(np.ones((2, 50)), 1e-3, -1), "'max_lines'"),
    ],
)
def test_bad_input(call, words):
    with pytest.raises(InputError, match=words):
        call()
