"""Tones, phasors, spectral lines and peaks: the package's one copy of each.

Every stage that reads a frequency or a complex amplitude off a record calls these functions:
the antinode finder (the dominant harmonic of a window), the estimator recipe (the spectral lines
of a narrowband record), severity (the amplitude of a simulated steady state), the simulation (the
phasor of a harmonic load) and the closed loop (the frequency and phasors its policy uses).

Conventions. Signals are arrays ``(n_signals, n_t)`` (design.md section 5). A phasor ``A`` of a
signal at frequency ``f`` is the complex amplitude with ``signal(t) ~ Re(A exp(i 2 pi f t))``, so
``|A|`` is the zero-to-peak amplitude and ``A = a - i b`` for ``a cos(w t) + b sin(w t)``. The
phase reference is ``t = 0`` of the times given: pass absolute times to compare phasors of
different windows, ``np.arange(n_t)`` (and a frequency in cycles per sample) to refer them to a
window's first sample. Spectra are one-sided periodograms of Hann-windowed signals summed over
the signals: a tone they share (a mode seen at several nodes) adds up whatever its phase in each.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.fft

from ._threads import on_one_blas_thread
from ._validation import check_array, check_bool, check_int, check_real, read_only
from .errors import InputError

__all__ = [
    "PhasorFit",
    "dominant_frequency",
    "extract_lines",
    "fit_harmonic",
    "fit_phasors",
    "interpolated_peak",
    "line_occupancy",
    "line_power",
    "load_phasor",
]

# Default zero padding of dominant_frequency: at least this many times the record's length and at
# least DEFAULT_MIN_FFT bins. The log-parabola through three Hann bins is biased by up to 0.016
# bin without padding and 0.0016 bin with padding 2 (the continuous Hann kernel, checked in
# tests/test_spectral.py); a phasor fitted at the estimate turns that error into amplitude and
# residual, and the FFT of twice the length costs next to nothing.
DEFAULT_PAD = 2.0
DEFAULT_MIN_FFT = 1024
# The fewest samples dominant_frequency accepts: a Hann window of n samples has n - 2 nonzero
# weights, and a peak with two neighbours needs two of them.
MIN_SAMPLES = 4
# Spectral lines: a new line is sought at least this many frequency bins (1 / record length) from
# the others (a Hann main lobe is two bins wide on each side).
_LINE_MASK_BINS = 2.0


# ---------------------------------------------------------------------------------- validation
def _check_signals(signals: object, min_samples: int, name: str = "signals") -> np.ndarray:
    data = check_array(name, signals, ndim=2)
    if data.shape[0] == 0:
        raise InputError(f"The '{name}' parameter must hold at least one signal (row). "
                         f"Got shape {data.shape}.")
    if data.shape[1] < min_samples:
        raise InputError(
            f"The '{name}' parameter must have at least {min_samples} time samples (columns); "
            f"got shape {data.shape}. Pass the signals as (n_signals, n_t)."
        )
    return data


def _check_dt(dt: object) -> float:
    return check_real("dt", dt, low=0.0)


# ---------------------------------------------------------------------------------- peaks
def _summed_periodogram(signals: np.ndarray, window: np.ndarray, n_fft: int) -> np.ndarray:
    """|rfft(signal * window, n_fft)|^2 summed over the signals: one-sided bins 0 .. n_fft // 2."""
    return np.sum(np.abs(_padded_rfft(signals * window, n_fft)) ** 2, axis=0)


def _padded_rfft(signals: np.ndarray, n_fft: int) -> np.ndarray:
    """rfft of the rows zero-padded to ``n_fft`` points, bins 0 .. n_fft // 2 (scipy.fft).

    A length with a large prime factor (2 x 1999 for the closed loop's 2 s of velocities at
    1 kHz) goes through the chirp z-transform as one convolution of a fast length with cached
    chirps: cheaper than pocketfft's own Bluestein, which also does the work for the padding
    zeros (benchmarks/bench_closed_loop.py; equal to 1.3e-15 of the largest bin).
    """
    n = signals.shape[1]
    if n < 2 or scipy.fft.next_fast_len(n_fft, real=True) == n_fft:
        return scipy.fft.rfft(signals, n_fft, axis=1)
    chirp, kernel, post = _chirp_tables(n, n_fft)
    size = kernel.size
    spectrum = scipy.fft.fft(signals * chirp, size, axis=1)
    return scipy.fft.ifft(spectrum * kernel, axis=1)[:, : post.size] * post


@functools.lru_cache(maxsize=8)
def _chirp_tables(n: int, n_fft: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chirp z-transform of ``n`` samples to bins 0 .. n_fft // 2 of an ``n_fft``-point DFT:
    X[k] = w^(k^2/2) sum_j (x[j] w^(j^2/2)) w^(-(k - j)^2/2) with w = exp(-2 pi i / n_fft).
    Returns the input chirp (n,), the FFT of the lag kernel over a fast length, and the output
    chirp (bins,). Squares are reduced mod 2 n_fft (exact integers) before the exponential."""
    bins = n_fft // 2 + 1

    def chirp(index: np.ndarray) -> np.ndarray:
        return np.exp(-1j * np.pi * ((index * index) % (2 * n_fft)) / n_fft)

    size = scipy.fft.next_fast_len(n + bins - 1)
    lags = np.zeros(size, dtype=complex)
    lags[:bins] = np.conj(chirp(np.arange(bins, dtype=np.int64)))
    lags[size - (n - 1) :] = np.conj(chirp(np.arange(n - 1, 0, -1, dtype=np.int64)))
    return (chirp(np.arange(n, dtype=np.int64)), read_only(scipy.fft.fft(lags)),
            chirp(np.arange(bins, dtype=np.int64)))


def _log_parabola_offset(power: np.ndarray, k: int) -> float:
    """Offset from bin k of the vertex of the parabola through the log power of bins k-1..k+1.

    Zero at either end of the spectrum, when a neighbour has no power (its log is not finite) or
    when the three points do not bend down (k is no local maximum).
    """
    if not 0 < k < power.size - 1 or not np.all(power[k - 1 : k + 2] > 0):
        return 0.0
    left, mid, right = np.log(power[k - 1 : k + 2])
    curvature = left - 2 * mid + right
    return 0.5 * (left - right) / curvature if curvature < 0 else 0.0


def interpolated_peak(power: object, index: object = None) -> float:
    """Fractional bin of a spectral peak: the vertex of a parabola through its log power.

    The main lobe of a Hann-windowed tone is close to a Gaussian, whose logarithm is exactly a
    parabola, so the vertex through the peak bin and its two neighbours is nearly unbiased: the
    bias is at most 0.016 bin for bins of the record's own resolution and 0.0016 bin for a
    spectrum zero-padded to twice the length (the continuous Hann kernel; the negative frequency
    of a real tone adds a leakage error that falls with the number of cycles in the record).

    Parameters
    ----------
    power : array_like, shape (n_bins,)
        Non-negative power per bin (e.g. a periodogram).
    index : int, optional
        Bin of the peak; by default the largest one.

    Returns
    -------
    float
        ``index`` plus the vertex offset; ``index`` itself at either end of the spectrum, next to
        an empty bin, or where the log power does not bend down.

    Raises
    ------
    InputError
        If ``power`` is not a finite non-negative 1-d array or ``index`` is not one of its bins.

    Examples
    --------
    >>> k = np.arange(16)
    >>> round(interpolated_peak(np.exp(-0.5 * (k - 6.3) ** 2)), 12)  # a Gaussian lobe: exact
    6.3
    """
    values = check_array("power", power, ndim=1)
    if values.size == 0 or np.any(values < 0):
        raise InputError("The 'power' parameter must be a non-empty array of non-negative "
                         "powers.")
    k = int(np.argmax(values)) if index is None else check_int("index", index, low=0,
                                                               high=values.size - 1)
    return float(k + _log_parabola_offset(values, k))


def dominant_frequency(signals: object, dt: object, *, pad: float = DEFAULT_PAD,
                       min_fft: int = DEFAULT_MIN_FFT, name: str = "signals") -> float:
    """Frequency of the largest peak of the signals' summed spectrum (Hann, zero-padded).

    Each signal's mean is removed (it is not a harmonic) and the DC bin ignored; the largest
    remaining bin of the summed Hann periodogram is refined by :func:`interpolated_peak`. One
    frequency for all signals: the nodes of a standing wave share their dominant frequency, and
    summing their power keeps a node near a vibration node from deciding it.

    Parameters
    ----------
    signals : array_like, shape (n_signals, n_t)
        Real signals sampled every ``dt``; at least 4 samples.
    dt : float
        Sampling interval, s (> 0); pass 1.0 for a frequency in cycles per sample.
    pad : float
        The FFT has at least ``pad * n_t`` points (>= 1). Padding 2 brings the interpolation's
        bias from 0.016 to 0.0016 bin of ``1 / (n_t dt)``: measured on tones, errors ~10x closer.
    min_fft : int
        The FFT has at least this many points (>= 1): short windows get finer bins.
    name : str
        What the caller calls ``signals`` (its own parameter), for the messages.

    Returns
    -------
    float
        Frequency, in the units of ``1 / dt``.

    Raises
    ------
    InputError
        If ``signals`` is not a finite 2-d array with at least 4 samples, every signal is
        constant (there is no tone to find), or ``dt``, ``pad`` or ``min_fft`` is out of range.

    Examples
    --------
    >>> t = np.arange(1000) * 1e-3
    >>> round(dominant_frequency(np.sin(2 * np.pi * 12.34 * t)[None, :], 1e-3), 2)
    12.34
    """
    data = _check_signals(signals, MIN_SAMPLES, name)
    dt = _check_dt(dt)
    pad = check_real("pad", pad, low=1.0, low_inclusive=True)
    min_fft = check_int("min_fft", min_fft, low=1)
    if np.all(data == data[:, :1]):
        raise InputError(
            f"The '{name}' parameter is constant in time: it has no dominant frequency. Pass a "
            "record that vibrates."
        )
    n = data.shape[1]
    n_fft = max(math.ceil(pad * n), min_fft)
    power = _summed_periodogram(data - data.mean(axis=1, keepdims=True), np.hanning(n), n_fft)
    power[0] = 0.0  # the mean's leakage through the window is not a harmonic
    k = int(np.argmax(power))
    return float((k + _log_parabola_offset(power, k)) / (n_fft * dt))


# ---------------------------------------------------------------------------------- phasors
@dataclass(frozen=True, eq=False)
class PhasorFit:
    """Least-squares harmonic of each signal at one frequency: see :func:`fit_harmonic`.

    Attributes
    ----------
    phasors : ndarray, shape (n_signals,), complex
        ``A`` with ``signal(t) ~ Re(A exp(i 2 pi f t)) + offset``.
    offsets : ndarray, shape (n_signals,)
        The fitted constant of each signal (zeros when the fit has none).
    residual_variance : ndarray, shape (n_signals,)
        Residual sum of squares over ``n_t`` minus the number of fitted parameters (2 or 3):
        the variance of what the harmonic does not explain (noise, other tones).
    """

    phasors: np.ndarray
    offsets: np.ndarray
    residual_variance: np.ndarray


def _harmonic_basis(t: np.ndarray, frequency: float, constant: bool) -> np.ndarray:
    w = 2 * np.pi * frequency
    columns = [np.cos(w * t), np.sin(w * t)] + ([np.ones_like(t)] if constant else [])
    return np.column_stack(columns)


def _check_fit(signals: object, t: object, frequency: object, constant: object
               ) -> tuple[np.ndarray, np.ndarray, float, bool]:
    constant = check_bool("constant", constant)
    data = _check_signals(signals, 3 if constant else 2)
    times = check_array("t", t, shape=(data.shape[1],))
    frequency = check_real("frequency", frequency, low=0.0)
    return data, times, frequency, constant


def fit_harmonic(signals: object, t: object, frequency: object, *, constant: bool = True
                 ) -> PhasorFit:
    """Least-squares ``signal ~ Re(A exp(i 2 pi f t)) + c`` per signal, with its residual.

    Fitting cos, sin (and a constant) at a known frequency is the maximum-likelihood amplitude of
    a tone in white noise; unlike one DFT bin it is exact on any window length (a window that is
    not a whole number of periods leaks nothing into it) and rejects the signal's mean.

    Parameters
    ----------
    signals : array_like, shape (n_signals, n_t)
        Real signals.
    t : array_like, shape (n_t,)
        Their sample times, s; ``t = 0`` is the phase reference of the phasors.
    frequency : float
        Hz (> 0), in the units of ``1 / t``.
    constant : bool
        Fit a constant too (default): a static offset, e.g. sag, must not bias the amplitude.
        Without it the fit is orthogonal to nothing but the tone (signals known to have no mean).

    Returns
    -------
    PhasorFit
        Phasors, offsets and residual variances.

    Raises
    ------
    InputError
        If the shapes disagree, values are not finite, there are fewer samples than fitted
        parameters, or ``frequency`` is not > 0.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 200)
    >>> fit = fit_harmonic(np.vstack([3.0 + 2.0 * np.sin(2 * np.pi * 5.0 * t)]), t, 5.0)
    >>> np.round(fit.phasors, 12), np.round(fit.offsets, 12)
    (array([0.-2.j]), array([3.]))
    """
    data, times, frequency, constant = _check_fit(signals, t, frequency, constant)
    basis = _harmonic_basis(times, frequency, constant)
    coefficients, *_ = np.linalg.lstsq(basis, data.T, rcond=None)
    residual = data.T - basis @ coefficients
    dof = max(times.size - basis.shape[1], 1)
    offsets = coefficients[2] if constant else np.zeros(data.shape[0])
    return PhasorFit(
        phasors=read_only(coefficients[0] - 1j * coefficients[1]),
        offsets=read_only(np.asarray(offsets, dtype=float)),
        residual_variance=read_only(np.sum(residual**2, axis=0) / dof),
    )


def fit_phasors(signals: object, t: object, frequency: object, *, constant: bool = True
                ) -> np.ndarray:
    """Phasors ``A`` of the signals at ``frequency``: ``signal ~ Re(A exp(i 2 pi f t)) + c``.

    The phasors of :func:`fit_harmonic`, for callers that need nothing else.

    Parameters
    ----------
    signals : array_like, shape (n_signals, n_t)
        Real signals.
    t : array_like, shape (n_t,)
        Their sample times, s (the phase reference is ``t = 0``).
    frequency : float
        Hz (> 0).
    constant : bool
        Fit a constant too (default).

    Returns
    -------
    ndarray, shape (n_signals,), complex
        One phasor per signal.

    Raises
    ------
    InputError
        As :func:`fit_harmonic`.

    Examples
    --------
    >>> t = np.arange(500) * 1e-3
    >>> y = np.vstack([np.cos(2 * np.pi * 8.0 * t), np.sin(2 * np.pi * 8.0 * t)])
    >>> np.round(fit_phasors(y, t, 8.0), 12) + 0j   # cos: A = 1; sin: A = -i (+ 0j: no -0)
    array([1.+0.j, 0.-1.j])
    """
    return fit_harmonic(signals, t, frequency, constant=constant).phasors


def load_phasor(load: object, frequency: object, *, samples: int = 64) -> complex:
    """Phasor ``A`` of a load's time function: ``load.values(t) = Re(A exp(i 2 pi f t))``.

    Fitted on one period from ``t = 0`` (absolute time), so it is the load's own phase: exact for
    a sine of that frequency (up to the ``samples / 2 - 1``-th harmonic nothing aliases onto it),
    and blind to a constant part; only the component at ``frequency`` of any other load.

    Parameters
    ----------
    load : object
        Anything with ``values(t) -> ndarray`` (e.g. a HarmonicForce or a bound AeolianForce).
    frequency : float
        Hz (> 0).
    samples : int
        Samples over the period (>= 3).

    Returns
    -------
    complex
        The phasor, in the units of ``load.values``.

    Raises
    ------
    InputError
        If ``frequency`` or ``samples`` is out of range, or the values are not a finite array
        of one value per time.

    Examples
    --------
    >>> from powerline_control import HarmonicForce
    >>> A = load_phasor(HarmonicForce(2.0, 5.0, 1.0, phase=0.5), 5.0)
    >>> round(abs(A), 12), round(float(np.angle(A)), 12)   # 2 sin(w t + 0.5): angle 0.5 - pi/2
    (2.0, -1.070796326795)
    """
    frequency = check_real("frequency", frequency, low=0.0)
    samples = check_int("samples", samples, low=3)
    if not callable(getattr(load, "values", None)):
        raise InputError("The 'load' parameter must have a values(t) method (a force). Got "
                         f"{type(load).__name__}.")
    tau = np.linspace(0.0, 1.0 / frequency, samples, endpoint=False)
    values = check_array("load.values(t)", load.values(tau), shape=(samples,))
    w = 2 * np.pi * frequency
    # Discrete orthogonality of cos and sin over whole periods: the least squares in closed form.
    return complex(2 * np.mean(values * np.cos(w * tau)), -2 * np.mean(values * np.sin(w * tau)))


# ---------------------------------------------------------------------------------- lines
def _noise_quantile(k: int, probability: float) -> float:
    """Level (over its mean) that a bin of k summed white-noise periodograms exceeds with the
    given probability: a Gamma(k, 1/k) quantile (scipy.special, no scipy.stats import)."""
    from scipy.special import gammainccinv

    return float(gammainccinv(k, probability)) / k


def line_occupancy(signals: object, noise_std: object) -> float:
    """Fraction of frequency bins where the signals' summed periodogram exceeds white noise.

    For orthonormal coordinates of a field (so that sensor noise of std ``noise_std`` gives each
    the same white spectrum, of known level), the level is set where noise alone exceeds it in
    0.1 % of bins: a record of a few spectral lines occupies few bins, a broadband one many.

    Parameters
    ----------
    signals : array_like, shape (n_signals, n_t)
        Real signals with white noise of the same std in each.
    noise_std : float
        That standard deviation (> 0), in the signals' units.

    Returns
    -------
    float
        Fraction in [0, 1] of the bins above DC.

    Raises
    ------
    InputError
        If ``signals`` is not a finite 2-d array of at least 2 samples or ``noise_std`` is not
        > 0.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> line_occupancy(rng.standard_normal((3, 4000)), 1.0) < 0.01   # noise alone: ~0.1 %
    True
    """
    data = _check_signals(signals, 2)
    noise = check_real("noise_std", noise_std, low=0.0)
    k, n = data.shape
    window = np.hanning(n)
    power = _summed_periodogram(data, window, n)
    level = k * noise**2 * float(np.sum(window**2)) * _noise_quantile(k, 1e-3)
    return float(np.mean(power[1:] > level))


def _line_power(signals: np.ndarray, frequency: float, dt: float) -> float:
    phase = np.exp(-2j * np.pi * frequency * dt * np.arange(signals.shape[1]))
    return float(np.sum(np.abs(signals @ phase) ** 2))


def line_power(signals: object, frequency: object, dt: object) -> float:
    """Summed squared DTFT of the signals at ``frequency``, without a window.

    For one tone of unknown frequency in white noise, common to all signals with any amplitudes
    and phases, this is the likelihood to maximise (the periodogram at any frequency, not only on
    the FFT grid); it also ranks lines by strength.

    Parameters
    ----------
    signals : array_like, shape (n_signals, n_t)
        Real signals sampled every ``dt``.
    frequency : float
        Hz (>= 0).
    dt : float
        Sampling interval, s (> 0).

    Returns
    -------
    float
        ``sum_j |sum_n x_j[n] exp(-i 2 pi f n dt)|^2``.

    Raises
    ------
    InputError
        If an argument is out of range or not finite.

    Examples
    --------
    >>> n = np.arange(100)
    >>> round(line_power(np.cos(2 * np.pi * 0.1 * n)[None, :], 0.1, 1.0), 6)  # (n / 2)^2
    2500.0
    """
    data = _check_signals(signals, 1)
    frequency = check_real("frequency", frequency, low=0.0, low_inclusive=True)
    return _line_power(data, frequency, _check_dt(dt))


def _line_fit(signals: np.ndarray, frequency: float, dt: float) -> np.ndarray:
    """Least-squares sinusoid at ``frequency`` in every signal (its samples, k x n)."""
    basis = _harmonic_basis(dt * np.arange(signals.shape[1]), frequency, constant=False)
    coefficients, *_ = np.linalg.lstsq(basis, signals.T, rcond=None)
    return (basis @ coefficients).T


def _refine_line(signals: np.ndarray, frequency: float, dt: float, width: float) -> float:
    """The frequency within +/- width that maximises the line's power (bounded scalar search)."""
    from scipy.optimize import minimize_scalar

    best = minimize_scalar(lambda f: -_line_power(signals, f, dt),
                           bounds=(max(frequency - width, 1e-12), frequency + width),
                           method="bounded", options={"xatol": 1e-9 / dt})
    return float(best.x)


def _split_line(res: np.ndarray, frequency: float, dt: float, bin_width: float,
                min_gain: float):
    """Two lines within a bin of ``frequency`` instead of one, if the data hold them.

    Joint least squares of two sinusoids (Nelder-Mead over both frequencies from a few
    starts). Accepted when it removes at least ``min_gain`` more energy than the one line and
    the two are distinct: returns ((f1, part1), (f2, part2)), else None.
    """
    from scipy.optimize import minimize

    t = np.arange(res.shape[1]) * dt

    total = float(np.sum(res**2))

    def parts_of(fs):
        design = np.column_stack([g(2 * np.pi * f * t) for f in fs for g in (np.cos, np.sin)])
        # Normal equations of the 4 regressors (small; lstsq copes when f1 -> f2).
        rhs = design.T @ res.T
        coef, *_ = np.linalg.lstsq(design.T @ design, rhs, rcond=1e-12)
        return design, coef, rhs

    def left(fs):
        _, coef, rhs = parts_of(fs)
        return total - float(np.sum(coef * rhs))

    single = float(np.sum((res - _line_fit(res, frequency, dt)) ** 2))
    best = None
    for half in (0.15, 0.45):
        start = np.array([frequency - half * bin_width, frequency + half * bin_width])
        out = minimize(left, start, method="Nelder-Mead",
                       options={"xatol": 1e-6 * bin_width, "fatol": 1e-12 * single,
                                "initial_simplex": [start, start + [0.1 * bin_width, 0.0],
                                                    start + [0.0, 0.1 * bin_width]],
                                "maxiter": 200})
        if best is None or out.fun < best.fun:
            best = out
    f1, f2 = sorted(float(v) for v in best.x)
    if single - best.fun < min_gain or f2 - f1 < 0.02 * bin_width or f1 <= 0:
        return None
    design, coef, _ = parts_of([f1, f2])
    return ((f1, (design[:, :2] @ coef[:2]).T), (f2, (design[:, 2:] @ coef[2:]).T))


# One BLAS thread: thousands of small (4 x n) @ (n x k) products (k ~ 24), far slower with
# contending threads than with one.
@on_one_blas_thread
def extract_lines(signals: object, dt: object, max_lines: object
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spectral lines common to the signals, strongest first, until the rest is noise-like.

    Each step takes the highest peak of the residual's summed (Hann, 4x zero-padded)
    periodogram outside the lines already found, refines its frequency by maximum likelihood
    (:func:`line_power` of the un-windowed residual), subtracts the least-squares sinusoid and
    re-fits the lines within a few bins of it (close lines bias each other). A leftover peak on
    a line already found is tried as two lines closer than the record resolves (a load near
    resonance beside the mode's own transient). It stops when the peak is below the level white
    noise exceeds in 1 % of records (relative to the periodogram's median, so no noise level is
    needed).

    Parameters
    ----------
    signals : array_like, shape (k, n)
        Real signals sampled every ``dt`` (e.g. orthonormal coordinates of a field).
    dt : float
        Sampling interval, s (> 0).
    max_lines : int
        The most lines to return (>= 0).

    Returns
    -------
    frequencies : ndarray, shape (r,)
        Hz, ascending.
    shapes : ndarray, shape (k, r)
        Unit vector of each line's amplitudes over the signals (its leading singular vector).
    residual : ndarray, shape (k, n)
        The signals minus every line.

    Raises
    ------
    InputError
        If ``signals`` is not a finite 2-d array of at least 4 samples, or ``dt`` or
        ``max_lines`` is out of range.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> t = np.arange(4000) * 1e-3
    >>> x = np.outer([1.0, 0.5], np.sin(2 * np.pi * 9.7 * t)) + rng.standard_normal((2, 4000))
    >>> frequencies, shapes, residual = extract_lines(x, 1e-3, 5)
    >>> np.round(frequencies, 2)
    array([9.7])
    """
    coords = _check_signals(signals, MIN_SAMPLES)
    dt = _check_dt(dt)
    max_lines = check_int("max_lines", max_lines, low=0)
    k, n = coords.shape
    res = coords.copy()
    nfft = 1 << int(math.ceil(math.log2(4 * n)))
    window = np.hanning(n)
    grid = np.fft.rfftfreq(nfft, dt)
    bin_width = 1.0 / (n * dt)
    threshold = _noise_quantile(k, 0.01 / n) / _noise_quantile(k, 0.5)
    found: list[float] = []
    parts: list[np.ndarray] = []
    tried: set[int] = set()      # lines already tested for an unresolved neighbour
    locked: set[int] = set()     # resolved pairs: re-fitting them one by one would merge them
    for _ in range(max_lines + 2 * len(tried) + 8):
        if len(found) >= max_lines:
            break
        power = _summed_periodogram(res, window, nfft)
        floor = float(np.median(power))
        power[grid < 2 * bin_width] = 0.0              # no line at DC or the record's length
        masked = power.copy()
        for f in found:
            masked[np.abs(grid - f) < _LINE_MASK_BINS * bin_width] = 0.0
        top = int(np.argmax(power))
        if power[top] > threshold * floor and masked[top] == 0.0:
            # The strongest leftover sits on a line already found: two lines closer than the
            # record resolves.
            j = int(np.argmin(np.abs(np.array(found) - grid[top])))
            if j not in tried:
                tried.add(j)
                # White-noise energy per sample summed over the signals (periodogram median).
                noise_energy = floor / float(np.sum(window**2))
                pair = _split_line(res + parts[j], found[j], dt, bin_width,
                                   min_gain=40.0 * k * noise_energy)
                if pair is not None:
                    (f1, p1), (f2, p2) = pair
                    res += parts[j] - p1 - p2
                    found[j], parts[j] = f1, p1
                    found.append(f2)
                    parts.append(p2)
                    locked.update({j, len(found) - 1})
                continue
        peak = int(np.argmax(masked))
        if not masked[peak] > threshold * floor:
            break
        f = _refine_line(res, float(grid[peak]), dt, bin_width)
        part = _line_fit(res, f, dt)
        res -= part
        found.append(f)
        parts.append(part)
        near = [j for j, g in enumerate(found) if abs(g - f) < 8 * bin_width and j not in locked]
        for _sweep in range(3):
            for j in near:
                res += parts[j]
                found[j] = _refine_line(res, found[j], dt, 0.5 * bin_width)
                parts[j] = _line_fit(res, found[j], dt)
                res -= parts[j]
    shapes = []
    for part in parts:
        u, _, _ = np.linalg.svd(part[:, : min(n, 4096)], full_matrices=False)
        shapes.append(u[:, 0])
    order = np.argsort(found)
    freqs = np.array(found)[order]
    shape_matrix = np.column_stack(shapes)[:, order] if shapes else np.zeros((k, 0))
    return freqs, shape_matrix, res
