"""Antinodes of a vibrating span: where a damper works best.

:func:`locate_antinodes` turns a displacement field along the span into its antinodes.  The field
is either a window of (estimated) displacements, shape (n_nodes, n_t), e.g. a Kalman filter's
output, or one mode shape, shape (n_nodes,), real or complex (e.g. a DMD mode).

For a window the amplitude envelope along the span is, by default, the amplitude of the dominant
harmonic at each node (a least-squares sine fit at the frequency of the largest peak of the summed
spectrum), which rejects broadband noise and the other modes; ``"rms"`` (RMS times sqrt 2) and
``"peak"`` (largest absolute value) are simpler alternatives.

The loop of an antinode extends between the neighbouring nodes of the vibration: zero crossings
of the (phase-aligned) signed shape where there is one, else minima of the envelope.  Each local
maximum of the envelope is then refined below the node spacing: by default a least-squares fit of
a sine with the loop's wavenumber over the middle of the loop (exact for a sinusoidal loop, the
shape of a taut string's, and averaging the noise of every sample there), or by interpolation
through the three samples around it (``"cosine"``, ``"parabolic"``).  The position uncertainty
propagates the estimator's variances to first order, assuming independent errors (see
:func:`locate_antinodes`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks

from ._validation import check_array, check_choice, check_real
from .errors import InputError

__all__ = ["Antinode", "locate_antinodes", "nearest_antinode", "largest_antinode"]


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
        Standard deviation of ``position``, m, from the variances given; None without them.
    amplitude_std : float or None
        Standard deviation of ``amplitude``, m; None without variances.
    index : int
        Index of the sample (node) nearest the antinode, the local maximum of the envelope.
    frequency : float or None
        Frequency of the dominant harmonic, Hz, for a window with ``dt`` given; else None.

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

    @property
    def loop_length(self) -> float:
        """Length of the loop, m (half a wavelength for a standing wave)."""
        return self.loop_end - self.loop_start


# ----------------------------------------------------------------------------------------------
# Envelopes
# ----------------------------------------------------------------------------------------------


def _dominant_harmonic(window: np.ndarray) -> tuple[np.ndarray, float]:
    """Complex amplitude per node at the dominant frequency, and that frequency in cycles/sample.

    The frequency is the largest peak of the node-summed Hann-windowed power spectrum, refined by
    a parabola through the log power of the three bins around it (near exact for a Hann window);
    the amplitudes come from a least-squares fit of cos, sin and a constant at that frequency.
    """
    n_t = window.shape[1]
    centred = window - window.mean(axis=1, keepdims=True)
    spectrum = np.fft.rfft(centred * np.hanning(n_t), axis=1)
    power = np.sum(np.abs(spectrum) ** 2, axis=0)
    power[0] = 0.0  # the mean is not a harmonic
    k = int(np.argmax(power))
    offset = 0.0
    if 0 < k < power.size - 1 and np.all(power[k - 1 : k + 2] > 0):
        left, mid, right = np.log(power[k - 1 : k + 2])
        curvature = left - 2 * mid + right
        if curvature < 0:
            offset = 0.5 * (left - right) / curvature
    frequency = (k + offset) / n_t
    phase = 2 * np.pi * frequency * np.arange(n_t)
    design = np.column_stack([np.cos(phase), np.sin(phase), np.ones(n_t)])
    coefficients, *_ = np.linalg.lstsq(design, window.T, rcond=None)
    return coefficients[0] - 1j * coefficients[1], frequency


def _align_phase(phasors: np.ndarray) -> np.ndarray:
    """Real shape from complex amplitudes: rotate by the phase that makes them most nearly real."""
    if not np.iscomplexobj(phasors):
        return phasors
    angle = 0.5 * np.angle(np.sum(phasors * phasors))
    return np.real(phasors * np.exp(-1j * angle))


# ----------------------------------------------------------------------------------------------
# Sub-sample interpolation
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


def _node_between(
    x: np.ndarray, envelope: np.ndarray, signed: np.ndarray | None, i: int, j: int
) -> float:
    """Position of the vibration node between samples i < j (two antinodes or an end)."""
    if signed is not None:
        s = signed[i : j + 1]
        crossings = np.nonzero(np.sign(s[:-1]) * np.sign(s[1:]) < 0)[0]
        exact = np.nonzero(s == 0)[0]
        if crossings.size + exact.size == 1:
            if exact.size:
                return float(x[i + exact[0]])
            return _zero_crossing(x, signed, i + int(crossings[0]))
    m = i + int(np.argmin(envelope[i : j + 1]))
    if 0 < m < x.size - 1 and i < m < j:
        y_left, y_mid, y_right = envelope[m - 1 : m + 2]
        rise = max(y_left, y_right) - y_mid
        h = 0.5 * (x[m + 1] - x[m - 1])
        if rise > 0:
            # Vertex of a "V" (|sin| near a node is V-shaped, not parabolic).
            return float(x[m] + h * (y_left - y_right) / (2 * rise))
    return float(x[m])


# ----------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------


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

    Parameters
    ----------
    field : array_like, shape (n_nodes, n_t) or (n_nodes,)
        A window of displacements (rows = positions ``x``, columns = time), or one mode shape,
        real or complex.  Rows that are identically zero (pinned supports) are fine.
    x : array_like, shape (n_nodes,)
        Positions of the rows, m, strictly increasing.
    envelope : {"harmonic", "rms", "peak"}
        Amplitude envelope of a window: amplitude of the dominant harmonic (default), RMS times
        sqrt(2), or the largest absolute value.  Ignored for a mode shape (its magnitude is used).
    variances : array_like, shape like ``field`` or (n_nodes,), optional
        Error variances of the field's entries (e.g. a Kalman filter's ``Estimate.variances`` for
        the displacement states), m^2.  For a window, the variance of each node's envelope is
        taken as ``2 * mean(variances) / n_t``, the variance of a sine amplitude fitted to ``n_t``
        samples with independent errors.  Estimation errors are correlated in time and between
        nodes, so the resulting standard deviations are optimistic lower bounds.
    interpolation : {"sine", "cosine", "parabolic"}
        Sub-sample refinement of each maximum.  ``"sine"`` (default): least-squares fit of a sine
        with the loop's wavenumber over the middle 60 % of the loop (exact for a sinusoidal loop;
        robust to noise, as it uses every sample there; falls back to ``"cosine"`` for loops of
        fewer than 3 samples).  ``"cosine"``: through the three samples around the maximum, exact
        for a sinusoid, needs equal spacing there (else falls back to the parabola).
        ``"parabolic"``: the parabola through those three samples.
    min_prominence : float
        Smallest prominence of a maximum, as a fraction of the largest envelope value, for it to
        count as an antinode (in (0, 1]); it rejects ripples from noise.
    dt : float, optional
        Sampling interval of the window, s, to report the dominant frequency in Hz.

    Returns
    -------
    list of Antinode
        Ordered by position along the span; empty if the field is identically zero.

    Raises
    ------
    InputError
        If shapes disagree, ``x`` is not strictly increasing, values are not finite, or an option
        is not one of the allowed values.

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
        signed, envelope_values, frequency = _window_envelope(data, envelope_kind, dt)
    else:
        signed = _align_phase(data)
        envelope_values = np.abs(data)

    node_variances = None
    if variances is not None:
        node_variances = _node_variances(variances, data.shape)

    peak_value = float(np.max(envelope_values))
    if peak_value == 0.0:
        return []
    peaks, _ = find_peaks(envelope_values, prominence=min_prominence * peak_value)
    antinodes = []
    bounds = [0] + [int(p) for p in peaks] + [n_nodes - 1]
    for n, peak in enumerate(peaks):
        loop_start = _node_between(positions, envelope_values, signed, bounds[n], peak)
        loop_end = _node_between(positions, envelope_values, signed, peak, bounds[n + 2])
        position, amplitude, position_std, amplitude_std = _refine_peak(
            positions, envelope_values, node_variances, int(peak), loop_start, loop_end,
            interpolation,
        )
        antinodes.append(
            Antinode(
                position=position,
                amplitude=amplitude,
                loop_start=loop_start,
                loop_end=loop_end,
                position_std=position_std,
                amplitude_std=amplitude_std,
                index=int(peak),
                frequency=frequency,
            )
        )
    return antinodes


# Fraction of the loop length left out at each end by the sine fit: near the nodes the envelope
# is small (poor signal to noise) and a real conductor's loop next to a support departs from a sine.
_FIT_MARGIN = 0.2


def _refine_peak(
    x: np.ndarray,
    envelope: np.ndarray,
    variances: np.ndarray | None,
    peak: int,
    loop_start: float,
    loop_end: float,
    method: str,
) -> tuple[float, float, float | None, float | None]:
    """Sub-sample position and amplitude of a maximum, with standard deviations if variances."""
    length = loop_end - loop_start
    inside = np.nonzero(
        (x >= loop_start + _FIT_MARGIN * length) & (x <= loop_end - _FIT_MARGIN * length)
    )[0]
    if method == "sine" and inside.size >= 3 and length > 0:
        return _sine_fit(x[inside], envelope[inside], None if variances is None else
                         variances[inside], np.pi / length, x[peak])
    interpolate = _INTERPOLATORS["cosine" if method == "sine" else method]
    xs, ys = x[peak - 1 : peak + 2], envelope[peak - 1 : peak + 2]
    position, amplitude = interpolate(xs, ys)
    if variances is None:
        return position, amplitude, None, None
    position_std, amplitude_std = _propagate(interpolate, xs, ys, variances[peak - 1 : peak + 2])
    return position, amplitude, position_std, amplitude_std


def _sine_fit(
    xs: np.ndarray, ys: np.ndarray, variances: np.ndarray | None, k: float, centre: float
) -> tuple[float, float, float | None, float | None]:
    """Least-squares fit of a cos(k u) + b sin(k u), u = x - centre, over the middle of a loop.

    The wavenumber comes from the loop length (pi / loop length).  The peak is at
    centre + atan2(b, a) / k with amplitude hypot(a, b): exact for a sinusoidal loop, and with
    noise it averages over all the samples of the loop's middle instead of three.  Standard
    deviations: the sandwich covariance of the unweighted least squares, propagated to first
    order.
    """
    u = k * (xs - centre)
    design = np.column_stack([np.cos(u), np.sin(u)])
    (a, b), *_ = np.linalg.lstsq(design, ys, rcond=None)
    amplitude = math.hypot(a, b)
    position = float(centre + math.atan2(b, a) / k)
    if variances is None:
        return position, amplitude, None, None
    gram = design.T @ design
    solve = np.linalg.solve(gram, design.T)  # (2, n): coefficients = solve @ ys
    covariance = (solve * variances) @ solve.T
    grad_position = np.array([-b, a]) / (k * amplitude**2)
    grad_amplitude = np.array([a, b]) / amplitude
    return (
        position,
        amplitude,
        float(np.sqrt(grad_position @ covariance @ grad_position)),
        float(np.sqrt(grad_amplitude @ covariance @ grad_amplitude)),
    )


def _window_envelope(
    window: np.ndarray, kind: str, dt: float | None
) -> tuple[np.ndarray | None, np.ndarray, float | None]:
    if kind == "harmonic":
        phasors, cycles_per_sample = _dominant_harmonic(window)
        frequency = cycles_per_sample / dt if dt is not None else None
        return _align_phase(phasors), np.abs(phasors), frequency
    centred = window - window.mean(axis=1, keepdims=True)
    if kind == "rms":
        return None, np.sqrt(2.0) * np.sqrt(np.mean(centred**2, axis=1)), None
    return None, np.max(np.abs(window), axis=1), None


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
    items = list(antinodes)
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
