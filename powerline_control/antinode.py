"""Antinodes of a vibrating span: where a damper works best.

:func:`locate_antinodes` turns a displacement field along the span into its antinodes.  The field
is either a window of (estimated) displacements, shape (n_nodes, n_t), e.g. a Kalman filter's
output, or one mode shape, shape (n_nodes,), real or complex (e.g. a DMD mode).

For a window the amplitude envelope along the span is, by default, the amplitude of the dominant
harmonic at each node (a least-squares sine fit at the frequency of the largest peak of the summed
spectrum), which rejects broadband noise and the other modes; ``"rms"`` (RMS times sqrt 2) and
``"peak"`` (largest absolute value) are simpler alternatives.

The loops are found from the field itself, before any maximum is looked at: their ends are the
vibration nodes, the zero crossings of the mode-like signed shape (the phase-aligned dominant
harmonic of a window, the phase-aligned mode shape).  Samples within a few noise standard
deviations of zero are "uncertain"; a node lies between two confidently signed samples of opposite
sign (one clean crossing: the exact zero of a sine through four samples or linear interpolation;
several noisy ones: the root of a least-squares line through them).  So a small loop between
resonances is a loop of its own and does not stretch its neighbours.  Each antinode is then
refined inside its own loop: by default a least-squares fit of ``a cos(k u) + b sin(k u)`` with the
wavenumber ``k`` fitted too (Gauss-Newton), over the samples of the loop above half its maximum
(exact for a sinusoidal loop of any length, e.g. a loop next to a point load or a support, which
is not half a wavelength long), or by interpolation through the three samples around the maximum
(``"cosine"``, ``"parabolic"``).  Every antinode has a position uncertainty: propagated to first
order from the variances given, or else from the estimated noise of the field (and the fit's
residual when the loop is not a sine), so it grows with the noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ._spectral import dominant_frequency, fit_harmonic
from ._validation import check_array, check_choice, check_real, checked_keywords
from .errors import InputError

__all__ = ["Antinode", "locate_antinodes", "nearest_antinode", "largest_antinode"]

# A sample is confidently signed (counts toward a loop, not toward a node) when its magnitude
# exceeds this many noise standard deviations: the chance that noise flips it is 6e-5 (Gaussian).
_NOISE_SIGMAS = 4.0
# Floor of that noise, relative to the largest |signed shape|: round-off of an exact field must not
# create loops.
_ROUND_OFF = 1e-9
# The sine fit of a loop uses the samples whose envelope is at least one of these fractions of the
# loop's largest sample, the widest whose residual the noise explains (0.5: the middle two thirds
# of a sinusoidal loop): near the nodes the envelope is small (poor signal to noise) and next to a
# load or a support the loop departs from a sine.
_FIT_LEVELS = (0.5, 0.7, 0.85, 0.95)


@dataclass(frozen=True)
class Antinode:
    """One antinode (loop maximum) of a vibration along the span.

    Attributes
    ----------
    position : float
        Position of the antinode, m from the left support (interpolated between nodes).
    amplitude : float
        Envelope amplitude at the antinode, m (zero-to-peak for ``"harmonic"`` / ``"rms"`` /
        ``"peak"`` envelopes; the mode shape's magnitude for a mode).
    loop_start, loop_end : float
        Ends of the loop (the neighbouring vibration nodes), m.
    position_std : float or None
        Standard deviation of ``position``, m: propagated from the variances given, else from the
        field's estimated noise (and the fit's residual); it grows with the noise.  None only for
        an ``Antinode`` built by hand.
    amplitude_std : float or None
        Standard deviation of ``amplitude``, m, likewise.
    index : int
        Index of the sample (node) nearest the antinode, the local maximum of the envelope.
    frequency : float or None
        Frequency of the dominant harmonic, Hz, for a window with ``dt`` given; else None.
    noise_std : float or None
        Estimated noise standard deviation of the envelope near the antinode, m (from the given
        variances when there are any; from the harmonic fit's residual for a window; from local
        quadratic fits along the span for a mode shape).
    fit_samples : int
        Number of samples the position was fitted to (3 for a three-point interpolation).
    uncertainty : str
        Where ``position_std`` comes from: ``"variances"`` (propagated from those given),
        ``"estimated"`` (from the field's estimated noise and the fit's residual) or ``"none"``
        (an ``Antinode`` built by hand without one).

    Examples
    --------
    >>> x = np.linspace(0.0, 3.0, 31)
    >>> first = locate_antinodes(np.sin(np.pi * x / 3.0), x)[0]
    >>> round(first.position, 6), round(first.amplitude, 6), round(first.loop_length, 6)
    (1.5, 1.0, 3.0)
    """

    position: float
    amplitude: float
    loop_start: float
    loop_end: float
    position_std: float | None
    amplitude_std: float | None
    index: int
    frequency: float | None = None
    noise_std: float | None = None
    fit_samples: int = 0
    uncertainty: str = "none"

    @property
    def loop_length(self) -> float:
        """Length of the loop, m (half a wavelength for a standing wave)."""
        return self.loop_end - self.loop_start


# ----------------------------------------------------------------------------------------------
# Envelopes and noise
# ----------------------------------------------------------------------------------------------


def _dominant_harmonic(window: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Complex amplitude per node at the dominant frequency, that frequency in cycles/sample, and
    the variance of each node's complex amplitude estimated from the fit's residual.

    The frequency is the largest peak of the node-summed spectrum (:mod:`._spectral`), zero-padded
    to at least twice the window and 1024 points: unpadded, its error of up to 0.016 bin leaves a
    residual of 1 % of the amplitude in a noise-free window, which counts as noise here, and makes
    a 1 % noise read as 1.44 %; padded, 0.03 % and 1.00 % (median over 400 tones). The amplitudes
    come from a least-squares fit of cos, sin and a constant at that frequency, referred to the
    window's first sample. The residual variance s^2 of a node gives its cos and sin coefficients
    a variance of about 2 s^2 / n_t (independent errors); whatever else is in the signal (other
    modes) counts as noise, which makes it an upper estimate.
    """
    n_t = window.shape[1]
    frequency = dominant_frequency(window, 1.0)
    fit = fit_harmonic(window, np.arange(n_t, dtype=float), frequency)
    return fit.phasors, frequency, 2.0 * fit.residual_variance / n_t


def _align_phase(phasors: np.ndarray) -> np.ndarray:
    """Real shape from complex amplitudes: rotate by the phase that makes them most nearly real."""
    if not np.iscomplexobj(phasors):
        return phasors
    angle = 0.5 * np.angle(np.sum(phasors * phasors))
    return np.real(phasors * np.exp(-1j * angle))


# Median of the chi-square distribution with one degree of freedom: turns a median of squared
# standardised residuals into a variance.
_CHI2_1_MEDIAN = 0.45493642311957283


def _spatial_noise(x: np.ndarray, y: np.ndarray) -> float:
    """Noise standard deviation of samples ``y(x)`` along the span (any spacing).

    Each interior sample is compared with the least-squares quartic through it and its three
    neighbours on each side (a parabola through five samples on short arrays).  The residual at
    the centre has variance s^2 (1 - leverage) for independent errors of variance s^2, and the
    median over the span (robust to the few windows at a kink or a support) gives s.  A smooth
    shape contributes its sixth-order Taylor term: for a sine with 14 samples per loop, 4e-6 of
    the amplitude (measured); with 3 samples per loop it reaches 4 % (such a field is not
    resolved well enough to tell its noise from its shape, and the uncertainty says so).
    """
    n = x.size
    if n < 5:
        return 0.0
    half, degree = (3, 4) if n >= 7 else (2, 2)
    centre = np.arange(half, n - half)
    windows = centre[:, None] + np.arange(-half, half + 1)
    u = x[windows] - x[centre][:, None]
    u = u / (u[:, -1] - u[:, 0])[:, None]
    design = np.stack([u**power for power in range(degree + 1)], axis=2)  # (m, 2 half + 1, d + 1)
    gram_inv = np.linalg.inv(np.transpose(design, (0, 2, 1)) @ design)
    coefficients = gram_inv @ (np.transpose(design, (0, 2, 1)) @ y[windows][:, :, None])
    residual = y[centre] - coefficients[:, 0, 0]  # the polynomial's value at the centre (u = 0)
    leverage = gram_inv[:, 0, 0]
    return float(np.sqrt(np.median(residual**2 / (1.0 - leverage)) / _CHI2_1_MEDIAN))


def _undersampled(signed: np.ndarray, threshold: np.ndarray) -> bool:
    """True when a shape flips sign between most neighbouring samples and none of it stands out
    of its noise estimate: loops of about two samples or fewer, whose nodes no threshold can
    find (a noisy shape of long loops keeps its sign between neighbours and is still read)."""
    if not np.all(np.abs(signed) <= threshold):
        return False
    real = signed.real[np.abs(signed) > _ROUND_OFF * np.max(np.abs(signed))]
    return real.size >= 3 and np.mean(np.sign(real[1:]) != np.sign(real[:-1])) > 0.5


# ----------------------------------------------------------------------------------------------
# Loops: ends from the zero crossings of the signed shape
# ----------------------------------------------------------------------------------------------


def _zero_crossing(x: np.ndarray, signed: np.ndarray, c: int) -> float:
    """Zero of the signed shape between samples c and c + 1.

    With equally spaced neighbours, a sinusoid through four samples (its wavenumber from the
    three-term identity y[m-1] + y[m+1] = 2 cos(k h) y[m], by least squares over the two inner
    triples) gives the exact zero of a sine; otherwise, or when that identity does not fit,
    linear interpolation.
    """
    y1, y2 = signed[c], signed[c + 1]
    h = x[c + 1] - x[c]
    linear = float(x[c] + h * y1 / (y1 - y2))
    if x.size < 4:
        return linear
    first = min(max(c - 1, 0), x.size - 4)  # four samples around the crossing, inside the array
    if not np.allclose(np.diff(x[first : first + 4]), h, rtol=1e-6):
        return linear
    w = signed[first : first + 4]
    cos_kh = ((w[0] + w[2]) * w[1] + (w[1] + w[3]) * w[2]) / (2 * (w[1] ** 2 + w[2] ** 2))
    if not 0.0 < cos_kh < 1.0:
        return linear
    kh = math.acos(cos_kh)
    # y1 = -A sin(k s), y2 = A sin(k (h - s)) for the zero at x[c] + s:
    ks = math.atan(-y1 * math.sin(kh) / (y2 - y1 * cos_kh))  # y1, y2 of opposite signs
    if not 0.0 <= ks <= kh:
        return linear
    return float(x[c] + ks / kh * h)


def _line_root(xs: np.ndarray, ys: np.ndarray) -> float:
    """Zero of the least-squares line through noisy samples around a node, kept within them."""
    slope, intercept = np.polyfit(xs - xs[0], ys, 1)
    if slope == 0.0 or slope * (ys[-1] - ys[0]) <= 0:
        return float(0.5 * (xs[0] + xs[-1]))
    return float(min(max(xs[0] - intercept / slope, xs[0]), xs[-1]))


def _vibration_nodes(x: np.ndarray, signed: np.ndarray, threshold: np.ndarray) -> list[float]:
    """Positions of the vibration nodes: where the signed shape changes sign beyond the noise.

    Samples with ``|signed| > threshold`` are confidently signed.  Between two consecutive ones
    of opposite sign lies one node: the single zero crossing there if the samples between change
    sign once (exact for a sine on an even grid), else (noise makes it cross several times) the
    root of the least-squares line through them.  Between two of the same sign whose samples in
    between do cross zero (a loop too small to rise above the noise), one node at the smallest
    magnitude: the neighbours end there.
    """
    confident = np.nonzero(np.abs(signed) > threshold)[0]
    nodes = []
    for i, j in zip(confident[:-1], confident[1:], strict=True):
        segment = signed[i : j + 1]
        changes = np.nonzero(np.sign(segment[:-1]) * np.sign(segment[1:]) < 0)[0]
        zeros = np.nonzero(segment == 0.0)[0]
        if np.sign(signed[i]) != np.sign(signed[j]):
            if changes.size == 1 and zeros.size == 0:
                nodes.append(_zero_crossing(x, signed, i + int(changes[0])))
            elif changes.size == 0 and zeros.size == 1:
                nodes.append(float(x[i + int(zeros[0])]))
            else:
                nodes.append(_line_root(x[i : j + 1], segment))
        elif changes.size or zeros.size:
            nodes.append(float(x[i + int(np.argmin(np.abs(segment)))]))
    return nodes


# ----------------------------------------------------------------------------------------------
# Sub-sample refinement inside a loop
# ----------------------------------------------------------------------------------------------


def _parabolic_peak(xs: np.ndarray, ys: np.ndarray) -> tuple[float, float]:
    """Vertex of the parabola through three points (any spacing)."""
    (x0, x1, x2), (y0, y1, y2) = xs, ys
    d01, d12, d02 = x0 - x1, x1 - x2, x0 - x2
    a = (d12 * (y0 - y1) - d01 * (y1 - y2)) / (d01 * d12 * d02)
    b = (y0 - y1) / d01 - a * (x0 + x1)
    if a >= 0:  # not a maximum (flat or noisy): keep the sample
        return float(x1), float(y1)
    vertex = -b / (2 * a)
    vertex = min(max(vertex, x0), x2)
    return float(vertex), float(y1 + (vertex - x1) * (b + a * (vertex + x1)))


def _cosine_peak(xs: np.ndarray, ys: np.ndarray) -> tuple[float, float]:
    """Peak of A cos(k (x - x0)) through three equally spaced samples (exact for that shape)."""
    h = xs[1] - xs[0]
    y_left, y_mid, y_right = ys
    if not math.isclose(xs[2] - xs[1], h, rel_tol=1e-6) or y_mid <= 0:
        return _parabolic_peak(xs, ys)
    cos_kh = (y_left + y_right) / (2 * y_mid)
    if not 0.0 < cos_kh < 1.0:  # flatter or sharper than any cosine: use the parabola
        return _parabolic_peak(xs, ys)
    k = math.acos(cos_kh) / h
    k_delta = math.atan((y_right - y_left) / (2 * y_mid * math.sin(k * h)))
    k_delta = min(max(k_delta, -k * h), k * h)
    return float(xs[1] + k_delta / k), float(y_mid / math.cos(k_delta))


_INTERPOLATORS: dict[str, Callable[[np.ndarray, np.ndarray], tuple[float, float]]] = {
    "cosine": _cosine_peak,
    "parabolic": _parabolic_peak,
}


def _propagate(
    interpolate: Callable[[np.ndarray, np.ndarray], tuple[float, float]],
    xs: np.ndarray,
    ys: np.ndarray,
    variances: np.ndarray,
) -> tuple[float, float]:
    """First-order standard deviations of (position, amplitude) from independent sample variances.

    The gradient of the interpolation formula is taken by central differences with a step small
    against the samples' spread.
    """
    step = 1e-6 * max(float(np.max(np.abs(ys))), np.finfo(float).tiny)
    grad = np.zeros((2, 3))
    for i in range(3):
        up, down = ys.copy(), ys.copy()
        up[i] += step
        down[i] -= step
        grad[:, i] = (np.array(interpolate(xs, up)) - np.array(interpolate(xs, down))) / (2 * step)
    std = np.sqrt(grad**2 @ variances)
    return float(std[0]), float(std[1])


@dataclass(frozen=True)
class _Fit:
    position: float
    amplitude: float
    position_std: float
    amplitude_std: float
    samples: int
    chi_square: float = 0.0


def _three_point(
    x: np.ndarray, envelope: np.ndarray, variances: np.ndarray, peak: int, method: str
) -> _Fit:
    """Interpolation through the maximum and its two neighbours (the sample at the span's ends)."""
    if peak == 0 or peak == x.size - 1:
        std = float(np.sqrt(variances[peak]))
        spacing = float(x[1] - x[0]) if peak == 0 else float(x[-1] - x[-2])
        return _Fit(float(x[peak]), float(envelope[peak]), spacing / math.sqrt(12.0), std, 1)
    interpolate = _INTERPOLATORS[method]
    xs, ys = x[peak - 1 : peak + 2], envelope[peak - 1 : peak + 2]
    position, amplitude = interpolate(xs, ys)
    position_std, amplitude_std = _propagate(interpolate, xs, ys, variances[peak - 1 : peak + 2])
    return _Fit(position, amplitude, position_std, amplitude_std, 3)


def _sine_parameters(
    u: np.ndarray, ys: np.ndarray, k0: float
) -> tuple[float, float, float] | None:
    """Least-squares a cos(k u) + b sin(k u) with the wavenumber k free (Gauss-Newton from k0).

    Returns (a, b, k), or None if the iteration leaves [k0 / 3, 3 k0] or does not settle (too few
    or too noisy samples to pin the wavenumber down).  For samples of a sine it converges to the
    exact parameters (quadratically: a few iterations).
    """
    k = k0
    design = np.column_stack([np.cos(k * u), np.sin(k * u)])
    (a, b), *_ = np.linalg.lstsq(design, ys, rcond=None)
    for _ in range(50):
        c, s = np.cos(k * u), np.sin(k * u)
        residual = ys - a * c - b * s
        jacobian = np.column_stack([c, s, u * (b * c - a * s)])
        step, *_ = np.linalg.lstsq(jacobian, residual, rcond=None)
        a, b, k = a + step[0], b + step[1], k + step[2]
        if not k0 / 3 <= k <= 3 * k0:
            return None
        # Converged when the steps are round-off for the position (1e-10 of the loop) and the
        # amplitude; with noise Gauss-Newton converges linearly, so the test is not 1e-16.
        if abs(step[2]) <= 1e-10 * k and abs(step[0]) + abs(step[1]) <= 1e-10 * math.hypot(a, b):
            return float(a), float(b), float(k)
    return None


def _sine_fit(
    xs: np.ndarray,
    ys: np.ndarray,
    variances: np.ndarray,
    k0: float,
    centre: float,
    inflate: bool,
) -> _Fit | None:
    """Fit of a sinusoidal loop; the peak is at centre + atan2(b, a) / k, amplitude hypot(a, b).

    Standard deviations: the sandwich covariance of the least squares at the solution (Jacobian
    in a, b, k) with the given sample variances, propagated to first order.  With ``inflate``
    (variances estimated, not given) the variances are raised to the fit's own residual variance
    when that is larger: a loop that is not a sine (next to a point load) is less certain.
    """
    u = xs - centre
    parameters = _sine_parameters(u, ys, k0) if xs.size >= 4 else None
    if parameters is None:  # the wavenumber from the loop's length
        design = np.column_stack([np.cos(k0 * u), np.sin(k0 * u)])
        (a, b), *_ = np.linalg.lstsq(design, ys, rcond=None)
        k, free = k0, False
    else:
        (a, b, k), free = parameters, True
    amplitude = math.hypot(a, b)
    if amplitude == 0.0:
        return None
    phase = math.atan2(b, a)
    position = centre + phase / k
    c, s = np.cos(k * u), np.sin(k * u)
    columns = [c, s] + ([u * (b * c - a * s)] if free else [])
    jacobian = np.column_stack(columns)
    residual = ys - a * c - b * s
    chi_square = float(np.sum(residual**2 / np.maximum(variances, np.finfo(float).tiny)))
    if inflate and xs.size > jacobian.shape[1]:
        misfit = float(residual @ residual) / (xs.size - jacobian.shape[1])
        variances = np.maximum(variances, misfit)
    solve = np.linalg.pinv(jacobian)  # (p, n): parameter changes = solve @ sample changes
    covariance = (solve * variances) @ solve.T
    grad_position = np.array([-b, a] + ([-phase / k] if free else [])) / np.array(
        [k * amplitude**2, k * amplitude**2] + ([k] if free else [])
    )
    grad_amplitude = np.array([a, b] + ([0.0] if free else [])) / amplitude
    return _Fit(
        float(position),
        amplitude,
        float(np.sqrt(max(grad_position @ covariance @ grad_position, 0.0))),
        float(np.sqrt(max(grad_amplitude @ covariance @ grad_amplitude, 0.0))),
        int(xs.size),
        chi_square,
    )


def _consistent_with_noise(fit: _Fit) -> bool:
    """Whether a fit's residual is what the noise alone would leave (chi-square within 3 sigma)."""
    dof = fit.samples - 3
    return dof > 0 and fit.chi_square <= dof + 3.0 * math.sqrt(2.0 * dof)


def _refine(
    x: np.ndarray,
    envelope: np.ndarray,
    variances: np.ndarray,
    inside: np.ndarray,
    peak: int,
    loop: tuple[float, float],
    method: str,
    inflate: bool,
) -> _Fit:
    """Position and amplitude of the maximum of one loop, with standard deviations.

    The sine fit starts with the samples above half the loop's maximum and narrows to those above
    0.7, 0.85 and 0.95 of it until its residual is consistent with the noise: a loop next to a
    point load or a clamp is a sine plus a term that decays away from there (over 1 / kappa, a
    few tenths of a metre on the lab span), which a wide fit would average into a biased peak.
    """
    if method == "sine":
        length = loop[1] - loop[0]
        fits: list[_Fit] = []
        for level in _FIT_LEVELS:
            selected = inside[envelope[inside] >= level * envelope[peak]]
            if selected.size < 3 or length <= 0 or (fits and selected.size < 4):
                break
            fit = _sine_fit(
                x[selected], envelope[selected], variances[selected], np.pi / length, x[peak],
                inflate,
            )
            if fit is None or not loop[0] <= fit.position <= loop[1]:
                break
            fits.append(fit)
        if fits:
            chosen = next((i for i, fit in enumerate(fits) if _consistent_with_noise(fit)),
                          len(fits) - 1)
            fit = fits[chosen]
            if inflate and chosen + 1 < len(fits):
                # Estimated uncertainty: add the shift to the next narrower fit, a measure of the
                # bias left by a loop that is not quite a sine (and of the noise: it grows).
                shift = abs(fits[chosen + 1].position - fit.position)
                fit = replace(fit, position_std=math.hypot(fit.position_std, shift))
            return fit
        method = "cosine"
    return _three_point(x, envelope, variances, peak, method)


# ----------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------


@checked_keywords
def locate_antinodes(
    field: np.ndarray,
    x: np.ndarray,
    *,
    envelope: str = "harmonic",
    variances: np.ndarray | None = None,
    interpolation: str = "sine",
    min_prominence: float = 0.1,
    dt: float | None = None,
) -> list[Antinode]:
    """Find every antinode of a displacement field along the span.

    The loops come first, from the field itself: their ends are the vibration nodes, the zero
    crossings of the phase-aligned signed shape (beyond the field's noise), so a small loop
    between two large ones keeps its own ends and its neighbours keep theirs.  Each loop's
    antinode is then fitted inside that loop.

    Parameters
    ----------
    field : array_like, shape (n_nodes, n_t) or (n_nodes,)
        A window of displacements (rows = positions ``x``, columns = time), or one mode shape,
        real or complex.  Rows that are identically zero (pinned supports) are fine.
    x : array_like, shape (n_nodes,)
        Positions of the rows, m, strictly increasing; any spacing (graded meshes are fine).
    envelope : {"harmonic", "rms", "peak"}
        Amplitude envelope of a window: amplitude of the dominant harmonic (default), RMS times
        sqrt(2), or the largest absolute value.  Ignored for a mode shape (its magnitude is used).
        The loop ends always come from the dominant harmonic's signed shape.
    variances : array_like, shape like ``field`` or (n_nodes,), optional
        Error variances of the field's entries (e.g. a Kalman filter's ``Estimate.variances`` for
        the displacement states), m^2.  For a window, the variance of each node's envelope is
        taken as ``2 * mean(variances) / n_t``, the variance of a sine amplitude fitted to ``n_t``
        samples with independent errors.  Estimation errors are correlated in time and between
        nodes, so the resulting standard deviations are optimistic lower bounds.  Without
        variances the noise is estimated from the field: from the residual of the harmonic fit
        at each node (window) or from local parabolas along the span (mode shape).
    interpolation : {"sine", "cosine", "parabolic"}
        Sub-sample refinement of each maximum.  ``"sine"`` (default): least-squares fit of
        ``a cos(k u) + b sin(k u)``, wavenumber ``k`` included, over the loop's samples above
        half its maximum (exact for a sinusoidal loop of any length; robust to noise, as it uses
        every sample there; falls back to ``"cosine"`` for fewer than 3 samples).  ``"cosine"``:
        through the three samples around the maximum, exact for a sinusoid, needs equal spacing
        there (else falls back to the parabola).  ``"parabolic"``: the parabola through them.
    min_prominence : float
        Smallest amplitude of a loop, as a fraction of the largest envelope value, for its
        antinode to be reported (in (0, 1]).  Smaller loops are still loops: they bound their
        neighbours, they are just not listed.  Nor is a loop whose largest sample is the first
        or last one (its maximum lies beyond the positions given).
    dt : float, optional
        Sampling interval of the window, s, to report the dominant frequency in Hz.

    Returns
    -------
    list of Antinode
        Ordered by position along the span; empty if the field is identically zero (a window:
        constant in time).

    Raises
    ------
    InputError
        If shapes disagree, ``x`` is not strictly increasing, values are not finite, an option
        is not one of the allowed values, or a shape (without ``variances``) flips sign between
        most neighbouring samples with no node above its noise: loops of about two samples or
        fewer, which the positions cannot resolve.

    Examples
    --------
    >>> x = np.linspace(0.0, 3.0, 31)
    >>> nodes = locate_antinodes(np.sin(2 * np.pi * x / 3.0), x)  # second mode of a 3 m span
    >>> [round(a.position, 6) for a in nodes]
    [0.75, 2.25]
    >>> [(round(a.loop_start, 6), round(a.loop_end, 6)) for a in nodes]
    [(0.0, 1.5), (1.5, 3.0)]
    """
    envelope_kind = check_choice("envelope", envelope, ("harmonic", "rms", "peak"))
    interpolation = check_choice("interpolation", interpolation, ("sine", *_INTERPOLATORS))
    min_prominence = check_real("min_prominence", min_prominence, low=0.0, high=1.0)
    is_complex = np.iscomplexobj(np.asarray(field))
    data = check_array("field", field, ndim=(1, 2), dtype=complex if is_complex else float)
    n_nodes = data.shape[0]
    if n_nodes < 3:
        raise InputError(
            f"The 'field' parameter must have at least 3 rows (positions). Got {n_nodes}."
        )
    positions = check_array("x", x, shape=(n_nodes,))
    if np.any(np.diff(positions) <= 0):
        raise InputError(
            "The 'x' parameter must be strictly increasing (positions along the span)."
        )
    if dt is not None:
        dt = check_real("dt", dt, low=0.0)

    given = variances is not None
    given_variance = _node_variances(variances, data.shape) if given else None

    frequency = None
    if data.ndim == 2:
        if is_complex:
            raise InputError(
                "The 'field' parameter must be real when it is a (n_nodes, n_t) window; complex "
                "values are allowed for a (n_nodes,) mode shape."
            )
        if data.shape[1] < 4:
            raise InputError(
                f"The 'field' parameter must have at least 4 time samples. Got {data.shape[1]}."
            )
        if np.all(data == data[:, :1]):  # nothing vibrates: no harmonic, no loop
            return []
        phasors, cycles_per_sample, phasor_variance = _dominant_harmonic(data)
        frequency = cycles_per_sample / dt if dt is not None else None
        signed = _align_phase(phasors)
        envelope_values = _window_envelope(data, envelope_kind, phasors)
        noise_variance = phasor_variance
    else:
        signed = _align_phase(data)
        envelope_values = np.abs(data)
        noise_variance = np.full(n_nodes, _spatial_noise(positions, signed) ** 2)

    if given:
        noise_variance = given_variance

    peak_value = float(np.max(envelope_values))
    if peak_value == 0.0:
        return []
    scale = float(np.max(np.abs(signed)))
    threshold = np.maximum(_NOISE_SIGMAS * np.sqrt(noise_variance), _ROUND_OFF * scale)
    if data.ndim == 1 and not given and _undersampled(signed, threshold):
        raise InputError(
            "The 'field' parameter (a shape) varies from sample to sample as much as its "
            f"amplitude (estimated noise {np.sqrt(noise_variance.max()) / scale:.0%} of it): "
            "either it is noise, or its loops are shorter than about 3 samples and the "
            f"positions 'x' ({n_nodes} of them) are too sparse for it. Sample it more finely, "
            "or give 'variances' if the noise is known."
        )
    # Loops from the nodes alone; if the signed shape is zero (a window whose dominant harmonic
    # vanishes), the envelope's span is one loop.
    bounds = [float(positions[0]), *_vibration_nodes(positions, signed, threshold),
              float(positions[-1])]
    antinodes = []
    for loop_start, loop_end in zip(bounds[:-1], bounds[1:], strict=True):
        inside = np.nonzero((positions >= loop_start) & (positions <= loop_end))[0]
        if inside.size == 0:
            continue
        peak = int(inside[np.argmax(envelope_values[inside])])
        if envelope_values[peak] < min_prominence * peak_value or envelope_values[peak] == 0.0:
            continue
        if peak in (0, n_nodes - 1):  # the loop's maximum lies beyond the sampled positions
            continue
        fit = _refine(
            positions, envelope_values, noise_variance, inside, peak, (loop_start, loop_end),
            interpolation, inflate=not given,
        )
        antinodes.append(
            Antinode(
                position=fit.position,
                amplitude=fit.amplitude,
                loop_start=loop_start,
                loop_end=loop_end,
                position_std=fit.position_std,
                amplitude_std=fit.amplitude_std,
                index=peak,
                frequency=frequency,
                noise_std=float(np.sqrt(noise_variance[peak])),
                fit_samples=fit.samples,
                uncertainty="variances" if given else "estimated",
            )
        )
    return antinodes


def _window_envelope(window: np.ndarray, kind: str, phasors: np.ndarray) -> np.ndarray:
    if kind == "harmonic":
        return np.abs(phasors)
    if kind == "rms":
        centred = window - window.mean(axis=1, keepdims=True)
        return np.sqrt(2.0) * np.sqrt(np.mean(centred**2, axis=1))
    return np.max(np.abs(window), axis=1)


def _node_variances(variances: object, shape: tuple[int, ...]) -> np.ndarray:
    values = check_array("variances", variances, ndim=(1, 2))
    if values.shape not in (shape, shape[:1]):
        raise InputError(
            f"The 'variances' parameter has the wrong shape: expected {shape} or {shape[:1]} "
            f"but found {values.shape}."
        )
    if np.any(values < 0):
        raise InputError("The 'variances' parameter must be non-negative.")
    if values.ndim == 2:
        # Amplitude of a sine fitted to n_t samples with independent errors of variance s^2:
        # variance 2 s^2 / n_t.
        return 2.0 * values.mean(axis=1) / values.shape[1]
    return values


def _check_antinodes(antinodes: Sequence[Antinode]) -> list[Antinode]:
    if isinstance(antinodes, Antinode):
        antinodes = [antinodes]
    try:
        items = list(antinodes)
    except TypeError:
        raise InputError("The 'antinodes' parameter must be a list of Antinode objects (from "
                         f"locate_antinodes). Got {type(antinodes).__name__}.") from None
    if not items:
        raise InputError(
            "The 'antinodes' parameter is empty: no antinode was found (is the field zero, or "
            "min_prominence too high?)."
        )
    for item in items:
        if not isinstance(item, Antinode):
            raise InputError(
                "The 'antinodes' parameter must hold Antinode objects. "
                f"Got {type(item).__name__}."
            )
    return items


@checked_keywords
def nearest_antinode(antinodes: Sequence[Antinode], position: float) -> Antinode:
    """The antinode closest to ``position`` (e.g. the robot's).

    Parameters
    ----------
    antinodes : sequence of Antinode
        As returned by :func:`locate_antinodes`; not empty.
    position : float
        Reference position, m.

    Returns
    -------
    Antinode
        The closest one (the left one on a tie).

    Raises
    ------
    InputError
        If ``antinodes`` is empty or ``position`` is not a finite number.

    Examples
    --------
    >>> x = np.linspace(0.0, 3.0, 31)
    >>> nodes = locate_antinodes(np.sin(3 * np.pi * x / 3.0), x)
    >>> [round(a.position, 6) for a in nodes]
    [0.5, 1.5, 2.5]
    >>> round(nearest_antinode(nodes, 2.2).position, 6)
    2.5
    """
    items = _check_antinodes(antinodes)
    position = check_real("position", position)
    return min(items, key=lambda a: abs(a.position - position))


def largest_antinode(antinodes: Sequence[Antinode]) -> Antinode:
    """The antinode with the largest amplitude (the first on a tie).

    Parameters
    ----------
    antinodes : sequence of Antinode
        As returned by :func:`locate_antinodes`; not empty.

    Returns
    -------
    Antinode
        The one with the largest ``amplitude``.

    Raises
    ------
    InputError
        If ``antinodes`` is empty.

    Examples
    --------
    >>> x = np.linspace(0.0, 3.0, 61)
    >>> field = np.sin(2 * np.pi * x / 3.0) + 0.3 * np.sin(np.pi * x / 3.0)  # mode 2 + some 1
    >>> [round(a.position, 1) for a in locate_antinodes(field, x)]
    [0.8, 2.3]
    >>> round(largest_antinode(locate_antinodes(field, x)).position, 1)
    0.8
    """
    items = _check_antinodes(antinodes)
    return max(items, key=lambda a: a.amplitude)
