"""The line calibrated from its records: :func:`calibrate_span` and its :class:`SpanCalibration`.

A robot is told the nominal span (catalogue conductor, length, supports, stringing tension); the
tension moves with the conductor's temperature by several per cent a day, and a conductor's
bending stiffness is known only to a factor. The record says which line it is: every spectral
line of the sensors' records (a load's tone, the free ringing of the modes beside it) is a
standing wave whose frequency and shape along the span the true tension and EI explain.

The calibration is Bayesian over a grid of (tension, EI): for each spectral line of frequency
``f`` and phasors ``u`` at the channels, the modal model of the nominal line scaled to the
candidate (tension, EI) predicts ``u ~ CN(0, s^2 Phi W Phi^T + sigma^2 I)``: ``Phi`` the modes'
displacements at the channels, ``W`` their power response at ``f`` (the modes within a few
bandwidths of ``f`` dominate; a bandwidth is the modal damping or the record's resolution
``1 / duration``, whichever is wider), ``s^2`` the unknown load's power (profiled out) and
``sigma^2`` the share of ``u`` the modal model is not trusted to explain (``shape_error``). With
enough channels (two more than the wave has shapes) on a taut line (bending a small part of the
stiffness at the line's wavenumber), each line is also explained by the steady field's own shape
at ``f``, the taut beam's standing wave of wavenumber ``k(T, EI)`` between
the supports, under a load distributed as the wave or a point load between two channels
(:func:`_wave_loglik`): where a forced tone sits between two modes, a few modes fit its shape at
many tensions, the wave at one; its likelihood is the mixture of both. A tension that puts
a mode of the right shape at every line scores high; one whose modes sit between the lines, or
whose shapes the channels contradict, scores low. The product over lines with a log-normal prior
around the nominal gives the posterior; its spread is the calibration's uncertainty, and a
posterior with several peaks (sensors that cannot tell one mode from its neighbour, one line
only) says so.

Scaling the model: on a fixed mesh the stiffness is ``K = T K_T + EI K_B`` (+ the robot's spring),
so the Rayleigh quotient of each nominal mode, ``omega^2 = T g + EI b + r``, gives its frequency at
any (T, EI) without a new eigen-solve; exact for pinned uniform spans (the shapes do not depend
on T or EI) and stationary (second order) elsewhere.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np

from .._constants import GRAVITY
from .._results import Result
from .._spectral import interpolated_peak
from .._validation import check_int, check_real, checked_keywords, read_only
from ..errors import CalibrationWarning, IdentificationError, InputError
from ..fem import MDR, LineModel
from ..fem.mesh import parse_bc
from ..line import Span

#: Share of a line's phasors the modal model is not trusted to explain (relative power): a few
#: per cent covers the leakage of neighbouring lines, the decay of free ringing over the record
#: and the modes the band leaves out. Smaller makes the channels' shape decide more sharply.
DEFAULT_SHAPE_ERROR = 0.05
#: A spectral peak is a line when it stands this many times above the local median of the
#: summed velocity spectrum (noise and leakage).
LINE_PROMINENCE = 10.0
#: A peak within LEAKAGE_BINS resolution bins of a line LEAKAGE_RATIO times stronger is its skirt.
LEAKAGE_BINS = 4.0
LEAKAGE_RATIO = 30.0
#: Accuracy of a free line's peak frequency, in units of the record's resolution 1 / duration.
PEAK_ACCURACY = 0.25
#: Half-power full width of a Hann-windowed steady tone, in units of 1 / duration.
HANN_HALF_POWER_WIDTH = 1.44
#: Relative accuracy of the scaled nominal model's frequencies (mesh, first-order scaling).
FREQUENCY_MODEL_ERROR = 2e-4
#: Modes (nearest in frequency) that make up a line's predicted shape covariance.
MODES_PER_LINE = 4
#: Grid of the bending stiffness, points across ``ei_range`` (log-spaced).
EI_POINTS = 25
#: Most tension grid points (the step follows the narrowest line's bandwidth).
MAX_TENSION_POINTS = 4000
#: Wavenumber step of the local-wave shape model, in radians of phase at the far support.
WAVE_PHASE_STEP = 0.02
#: The local wave (taut string plus bending in its wavenumber) leaves out the evanescent field
#: near supports and loads, of length sqrt(EI / T): it reads a line only where bending is at most
#: this share of its stiffness, EI k^2 / T (a real span's aeolian modes: 1e-4; the lab span: ~1).
WAVE_BENDING = 0.01
#: Share of a line's phasor power the local wave is not trusted to explain: the wave is exact for
#: a taut string between loads, up to the line's damping (a decay of a few per cent over a span).
WAVE_SHAPE_ERROR = 0.01
#: A line with at least this share of the strongest line's velocity power is a strong one (a
#: Hann window's leakage skirt lies 30 dB or more below its line); the local wave reads records
#: of at most WAVE_MAX_LINES strong lines.
STRONG_LINE = 1e-3
WAVE_MAX_LINES = 2
#: Share of the posterior allowed outside its main peak before the calibration says it cannot
#: tell between tensions.
AMBIGUOUS_MASS = 0.05


@dataclass(frozen=True, eq=False)
class SpanCalibration(Result):
    """The span a record explains: tension, bending stiffness and their uncertainty.

    Returned by :func:`calibrate_span`.

    Attributes
    ----------
    nominal : Span
        The span as told (catalogue conductor, length, stringing tension).
    span : Span
        The calibrated span: the nominal with the calibrated tension and EI.
    bc : (str, str)
        Supports.
    tension, tension_std : float
        Calibrated horizontal tension and its standard deviation, N.
    ei, ei_std : float
        Calibrated bending stiffness and its standard deviation, N m^2; when the record does not
        identify it (``ei_identified`` False) ``ei`` is the posterior mean, which stays close to
        the nominal, and ``ei_std`` is about the prior's width.
    ei_identified : bool
        Whether the record narrows EI to less than half the prior's width.
    sag, sag_std : float
        Mid-span sag m g L^2 / (8 T) the calibrated tension implies, and its standard deviation,
        m (level supports, catenary ~ parabola).
    line_frequencies : ndarray, shape (n_lines,)
        The spectral lines the calibration used, Hz.
    model_frequencies : ndarray, shape (n_lines,)
        The calibrated model's natural frequency nearest each line, Hz.
    mode_numbers : ndarray of int, shape (n_lines,)
        Which mode that is (1 = the fundamental) of the calibrated model.
    posterior_tension : ndarray, shape (n_grid, 2)
        The tension grid (N) and its marginal posterior density (per N), for plots.
    duration : float
        Length of the record, s.
    ambiguous : bool
        Whether several tensions explain the record (more than AMBIGUOUS_MASS of the posterior
        lies away from its main peak): ``tension`` is then the highest peak and
        ``tension_std`` covers the others, but the record does not say which is the line's.
    peak_share : float
        The posterior's mass in its main peak (1: one tension explains the record; an ambiguous
        calibration's odds that ``tension`` is the line's).
    warnings : tuple of str
        What the record could not tell (also raised as :class:`CalibrationWarning`).

    Examples
    --------
    >>> import powerline_control as plc
    >>> nominal = plc.Span.paper_lab()
    >>> truth = plc.LineModel(plc.Span(nominal.length, 1.04 * nominal.tension,
    ...                                nominal.conductor), 40, damping=plc.ModalDamping(0.005))
    >>> snap = plc.simulate(truth, plc.RandomForce(0.5, 1.1, bandwidth=150.0, seed=1),
    ...                     duration=10.0, dt=1e-3, noise_fraction=0.01, seed=2)
    >>> rec = plc.Record(snap.t, snap.x[[7, 16, 29]], snap.displacement[[7, 16, 29]])
    >>> cal = plc.calibrate_span(rec, nominal)
    >>> bool(abs(cal.tension - 1.04 * nominal.tension) < 3 * cal.tension_std)
    True
    """

    nominal: Span
    span: Span
    bc: tuple
    tension: float
    tension_std: float
    ei: float
    ei_std: float
    ei_identified: bool
    sag: float
    sag_std: float
    line_frequencies: np.ndarray
    model_frequencies: np.ndarray
    mode_numbers: np.ndarray
    posterior_tension: np.ndarray
    duration: float
    ambiguous: bool = False
    peak_share: float = 1.0
    warnings: tuple = ()

    @property
    def tension_change(self) -> float:
        """Calibrated tension relative to the nominal, minus one (0.03: 3 % above)."""
        return self.tension / self.nominal.tension - 1.0

    def summary(self) -> str:
        """The calibration in a few lines of text.

        Examples
        --------
        >>> import powerline_control as plc
        >>> nominal = plc.Span.paper_lab()
        >>> snap = plc.simulate(plc.LineModel(nominal, 40, damping=plc.ModalDamping(0.005)),
        ...                     plc.RandomForce(0.5, 1.1, bandwidth=150.0, seed=1),
        ...                     duration=10.0, dt=1e-3, noise_fraction=0.01, seed=2)
        >>> rec = plc.Record(snap.t, snap.x[[7, 16, 29]], snap.displacement[[7, 16, 29]])
        >>> print(plc.calibrate_span(rec, nominal).summary().splitlines()[0][:30])
        Calibrated span (3.66 m, pinne
        """
        bc = self.bc[0] if self.bc[0] == self.bc[1] else "/".join(self.bc)
        ei = (f"{self.ei:.4g} +- {self.ei_std:.2g} N m^2" if self.ei_identified
              else f"{self.ei:.4g} N m^2 (not identified by this record; nominal "
                   f"{self.nominal.conductor.ei:.4g})")
        text = [
            f"Calibrated span ({self.span.length:g} m, {bc}) from a {self.duration:.3g} s record",
            f"  tension   {self.tension:.6g} +- {self.tension_std:.2g} N "
            f"({100 * self.tension_change:+.2f} % from the nominal {self.nominal.tension:.6g} N)",
            f"  EI        {ei}",
            f"  sag       {self.sag:.4g} +- {self.sag_std:.2g} m",
            f"  lines     {_hz(self.line_frequencies)} Hz, explained by modes "
            + ", ".join(str(int(n)) for n in self.mode_numbers[:8])
            + " at " + ", ".join(f"{f:.4g}" for f in self.model_frequencies[:8]) + " Hz",
        ]
        text += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(text)


# ------------------------------------------------------------------------------ the record
def _record_arrays(record: object, length: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(positions, values with NaN gaps, dt) of a Record-like object, checked against the span."""
    missing = [name for name in ("t", "positions", "values", "dt") if not hasattr(record, name)]
    if missing:
        raise InputError(
            "The 'record' parameter must be a Record (powerline_control.Record or "
            f"load_record(...)): it has no {', '.join(missing)}. Got {type(record).__name__}."
        )
    if hasattr(record, "check_span"):
        record.check_span(length)
    positions = np.asarray(record.positions, dtype=float)
    values = np.asarray(record.values, dtype=float)
    if np.any(positions <= 0) or np.any(positions >= length):
        raise InputError(
            f"The 'record' has channels at {positions.tolist()} m, outside the nominal span "
            f"(0 < x < {length:g} m): is it a record of another span?"
        )
    dead = [i for i in range(values.shape[0]) if np.count_nonzero(np.isfinite(values[i])) < 8]
    if dead:
        raise InputError(
            f"The 'record' has no data in channel(s) {dead} (at {positions[dead].tolist()} m): "
            "every sample is missing. Drop those channels."
        )
    return positions, values, float(record.dt)


def _velocities(values: np.ndarray) -> np.ndarray:
    """The channels' first differences, missing samples (and the differences across them) as
    zero: they weight each line by ~(omega dt)^2, so the free ringing of high modes is not buried
    under the low ones."""
    valid = np.isfinite(values)
    centred = np.where(valid, values - np.nanmean(values, axis=1, keepdims=True), 0.0)
    return np.diff(centred, axis=1) * (valid[:, 1:] & valid[:, :-1])


def _find_lines(velocities: np.ndarray, dt: float, band: tuple[float, float], max_lines: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies, own widths (:func:`_own_width`) and noise (the local floor as a phasor's
    variance per channel) of the strongest peaks in ``band`` of the
    summed Hann periodogram of the velocities (4x zero-padded), Hz. A peak is a line when it
    stands LINE_PROMINENCE above the local median (over about 20 resolution bins) and is not the
    skirt of a line LEAKAGE_RATIO times stronger within LEAKAGE_BINS resolution bins (the
    window's sidelobes, and the slow modulation of a tone building up from rest)."""
    n = velocities.shape[1]
    n_fft = 4 * n
    power = np.sum(np.abs(np.fft.rfft(velocities * np.hanning(n), n_fft, axis=1)) ** 2, axis=0)
    freq = np.fft.rfftfreq(n_fft, dt)
    df, duration = freq[1], n * dt
    half = max(8, int(round(10.0 / (duration * df))))
    inside = np.flatnonzero((freq >= band[0]) & (freq <= band[1]))
    if inside.size < 3:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    lo, hi = max(inside[0] - half, 0), min(inside[-1] + half + 1, power.size)
    floor = np.median(np.lib.stride_tricks.sliding_window_view(
        np.pad(power[lo:hi], half, mode="edge"), 2 * half + 1), axis=1)
    peaks = [k for k in inside[1:-1]
             if power[k] >= power[k - 1] and power[k] > power[k + 1]
             and power[k] > LINE_PROMINENCE * floor[k - lo]]
    peaks.sort(key=lambda k: -power[k])
    chosen: list[tuple[float, int]] = []
    for k in peaks:
        f = freq[k] + df * (interpolated_peak(power, k) - k)
        if all(abs(f - g) >= 1.5 / duration
               and not (abs(f - g) < LEAKAGE_BINS / duration
                        and power[j] > LEAKAGE_RATIO * power[k]) for g, j in chosen):
            chosen.append((f, k))
        if len(chosen) == max_lines:
            break
    chosen.sort()
    # the floor as a phasor variance per channel: white noise of variance s^2 gives a Hann
    # periodogram of mean 3 n s^2 / 8 and a least-squares phasor of variance 4 s^2 / n; a
    # velocity's spectrum is the displacement's times 4 sin^2(pi f dt)
    p = velocities.shape[0]
    noise = np.array([floor[k - lo] / p / (4 * np.sin(np.pi * f * dt) ** 2) * 32 / (3 * n**2)
                      for f, k in chosen])
    return (np.array([f for f, _ in chosen]),
            np.array([_own_width(power, k, df, duration) for _, k in chosen]), noise)


def _own_width(power: np.ndarray, k: int, df: float, duration: float) -> float:
    """Half-power full width of the peak at bin ``k`` beyond the Hann window's own
    (HANN_HALF_POWER_WIDTH / duration), Hz: 2 zeta f for a damped mode, ~0 for a steady tone."""
    half = 0.5 * power[k]
    lo = k
    while lo > 0 and power[lo] > half:
        lo -= 1
    hi = k
    while hi < power.size - 1 and power[hi] > half:
        hi += 1
    width = (hi - lo) * df
    return float(np.sqrt(max(width**2 - (HANN_HALF_POWER_WIDTH / duration) ** 2, 0.0)))


def _phasors(values: np.ndarray, dt: float, frequencies: np.ndarray) -> np.ndarray:
    """Phasors (n_lines, n_channels) of every line in every channel, fitted jointly by least
    squares (with a constant) over each channel's valid samples, referred to the first sample,
    under a Hann taper: a line fitted alone, or untapered, takes in the leakage of a stronger
    one (a tone still building up from rest leaks far from its frequency)."""
    t = dt * np.arange(values.shape[1])
    phase = 2 * np.pi * np.outer(t, frequencies)
    taper = np.hanning(t.size)[:, None]
    basis = taper * np.hstack([np.cos(phase), np.sin(phase), np.ones((t.size, 1))])
    m = frequencies.size
    out = np.empty((m, values.shape[0]), dtype=complex)
    for i, channel in enumerate(values):
        ok = np.isfinite(channel)
        coef, *_ = np.linalg.lstsq(basis[ok], taper[ok, 0] * channel[ok], rcond=None)
        out[:, i] = coef[:m] - 1j * coef[m : 2 * m]
    return out


# ------------------------------------------------------------------------------- the model
@dataclass(frozen=True, eq=False)
class _ScaledModes:
    """The nominal model's modes as functions of (T, EI): omega^2 = T g + EI b + r."""

    g: np.ndarray          # (r,) per unit tension
    b: np.ndarray          # (r,) per unit EI
    rest: np.ndarray       # (r,) the robot's spring and what the first order leaves
    rows: np.ndarray       # (p, r) the modes' displacements at the channels
    zeta: np.ndarray       # (r,) modal damping ratio of the nominal model


def _nominal_model(nominal: object, bc: object, robot: MDR | None, top: float) -> LineModel:
    """The nominal LineModel (a Span meshed to resolve ``top`` Hz), with the parked robot."""
    if isinstance(nominal, LineModel):
        if bc is not None:
            raise InputError("The 'bc' parameter is for a nominal Span; a nominal LineModel "
                             f"has its supports {nominal.bc}. Got bc={bc!r}.")
        model = nominal
    elif isinstance(nominal, Span):
        model = LineModel(nominal, None, bc="pinned" if bc is None else bc,
                          max_frequency=top)
    else:
        raise InputError("The 'nominal' parameter must be a Span (with bc=) or a LineModel: the "
                         f"span the engineer was told. Got {type(nominal).__name__}.")
    if robot is not None:
        if not isinstance(robot, MDR):
            raise InputError(f"The 'robot' parameter must be an MDR or None. Got "
                             f"{type(robot).__name__}.")
        model = model.with_robot(robot)
    return model


def _scaled_modes(model: LineModel, positions: np.ndarray, top: float) -> _ScaledModes:
    basis = model.modes_below(top)
    shapes = np.asarray(basis.shapes)
    k_t, k_b = model.stiffness_parts()
    g = np.einsum("ir,ir->r", shapes, k_t @ shapes)
    b = np.einsum("ir,ir->r", shapes, k_b @ shapes)
    span = model.span
    rest = basis.omega**2 - span.tension * g - span.conductor.ei * b
    index, weights = model.shape_rows(positions)
    rows = np.einsum("pk,pkr->pr", weights, np.where(index[..., None] >= 0,
                                                      shapes[np.maximum(index, 0)], 0.0))
    damping = np.diag(np.asarray(basis.damping))
    zeta = damping / np.maximum(2 * basis.omega, 1e-300)
    return _ScaledModes(g=g, b=b, rest=rest, rows=rows, zeta=zeta)


def _wavenumber(tension: np.ndarray, ei: np.ndarray, mass: float, frequency: float
                ) -> np.ndarray:
    """The taut beam's wavenumber at ``frequency``: ``m omega^2 = EI k^4 + T k^2``, rad/m."""
    omega2 = (2 * np.pi * frequency) ** 2
    if np.all(ei == 0):
        return np.sqrt(mass * omega2 / tension) * np.ones_like(ei)
    return np.sqrt((np.sqrt(tension**2 + 4 * ei * mass * omega2) - tension) / (2 * ei))


def _wave_loglik(k_range: tuple[float, float], u: np.ndarray, sigma2: float,
                 positions: np.ndarray, length: float, robot_at: float | None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Log-likelihood of one line's phasors ``u`` under the steady field's own shape, on a grid
    of wavenumbers over ``k_range``: (grid, log-likelihood), to interpolate at any (T, EI).

    Between the supports, a steady field at the line's frequency solves ``EI w_xxxx - T w_xx =
    m omega^2 w`` with the load on the right: unloaded, a wave ``A sin(k x) + B cos(k x)`` (the
    evanescent part decays within ``sqrt(EI / T)``, a few centimetres, of a support or a load);
    a parked robot, a point load, adds its kink ``sin(k |x - x_r|)``; the field is zero at both
    supports. The load is one of two kinds, equally likely:

    - distributed as the wave itself (wind in lock-in): it adds ``x sin(k x)`` and
      ``x cos(k x)``;
    - a point load at an unknown position (a shaker, a forced tone between two modes): its kink
      lies between two channels (or beyond the outermost), each place equally likely, and the
      field is a wave from each support up to it, the two waves' amplitudes independent (the
      field's continuity at the unknown position is not imposed). Without it a forced tone
      between two modes, read by the distributed kind, is taken for the nearest mode whose
      shape fits the channels on the load's larger side, a tension several per cent off.

    The shape depends on (T, EI) only through ``k``: the grid is fine enough to resolve the
    phase at the far support (WAVE_PHASE_STEP)."""
    k_lo, k_hi = k_range
    n_k = int(np.clip(np.ceil(length * (k_hi - k_lo) / WAVE_PHASE_STEP), 2, 20_000))
    grid = np.linspace(k_lo, k_hi, n_k)
    x = np.concatenate([positions, [0.0, length]])
    phase = grid[:, None] * x                                             # (n_k, p + 2)
    sin, cos = np.sin(phase), np.cos(phase)
    robot = [] if robot_at is None else [np.sin(grid[:, None] * np.abs(x - robot_at))]
    distributed = [sin, cos, x / length * sin, x / length * cos, *robot]
    channels = np.sort(positions)
    cuts = np.concatenate([[0.5 * channels[0]], 0.5 * (channels[:-1] + channels[1:]),
                           [0.5 * (channels[-1] + length)]])
    kinds = [distributed] + [[sin * (x < cut), cos * (x < cut), sin * (x > cut),
                              cos * (x > cut), *robot] for cut in cuts]
    log_weights = np.log(np.concatenate([[0.5], np.full(cuts.size, 0.5 / cuts.size)]))
    loglik = [_profiled_shape_loglik(_zero_at_supports(np.stack(kind, axis=-1)), None, u,
                                     sigma2) for kind in kinds]
    return grid, np.logaddexp.reduce(np.stack(loglik) + log_weights[:, None], axis=0)


def _zero_at_supports(basis: np.ndarray) -> np.ndarray:
    """The combinations of ``basis`` (n_k, p + 2, q: the channels, then the two supports) that
    are zero at both supports, at the channels (n_k, p, q - 2): the null space of the supports'
    rows."""
    _, _, vt = np.linalg.svd(basis[:, -2:, :])
    return basis[:, :-2, :] @ np.swapaxes(vt[:, 2:, :], -1, -2)


def _profiled_shape_loglik(rows: np.ndarray, power: np.ndarray | None, u: np.ndarray,
                           sigma2: float) -> np.ndarray:
    """Log-likelihood of the phasors ``u`` under ``CN(0, s^2 R W R^T + sigma2 I)`` (``rows`` R:
    (..., p, m), ``power`` W: (..., m), None: the identity), the load's power ``s^2`` profiled
    on a log grid around the value that explains ``|u|^2``."""
    weighted = rows if power is None else rows * power[..., None, :]
    lam, vec = np.linalg.eigh(np.einsum("...pm,...qm->...pq", weighted, rows))
    lam = np.maximum(lam, 0.0)
    proj = np.abs(np.einsum("...pq,p->...q", vec, u.conj())) ** 2   # |v^T u|^2 per direction
    top = np.maximum(lam.max(axis=-1, keepdims=True), 1e-300)
    scales = float(np.vdot(u, u).real) / top[..., None] * np.logspace(-3, 1, 41)   # (..., 1, S)
    var = scales * lam[..., :, None] + sigma2                    # (..., p, S)
    return np.max(-np.sum(np.log(var) + proj[..., :, None] / var, axis=-2), axis=-1)


def _line_loglik(omega2: np.ndarray, modes: _ScaledModes, u: np.ndarray, frequency: float,
                 zeta_floor: float, sigma2: float, frequency_std: float,
                 wave_ll: np.ndarray | None) -> np.ndarray:
    """Log-likelihood of one line's phasors ``u`` at every grid point (``omega2``: (..., r);
    ``wave_ll``: :func:`_wave_loglik` on the same grid, or None), the load's power profiled
    out."""
    omega = 2 * np.pi * frequency
    kept = min(MODES_PER_LINE, omega2.shape[-1])
    nearest = np.argpartition(np.abs(omega2 - omega**2), kept - 1, axis=-1)[..., :kept]
    w2 = np.take_along_axis(omega2, nearest, axis=-1)
    zeta = np.maximum(modes.zeta[nearest], zeta_floor)
    wn = np.sqrt(np.maximum(w2, 0.0))
    power = 1.0 / ((w2 - omega**2) ** 2 + (2 * zeta * wn * omega) ** 2)
    rows = np.moveaxis(modes.rows[:, nearest], 0, -2)         # (..., p, m)
    # The shape: the modes nearest the line, each weighted by its response at f; with enough
    # channels (``wave_ll`` given), mixed with the steady field's own shape, the local standing
    # wave at f (sharper where a forced tone sits between two modes, whose shape a few modes fit
    # at many tensions; a load between the channels breaks the wave and falls back on the
    # modes).
    shape_ll = _profiled_shape_loglik(rows, power, u, sigma2)
    if wave_ll is not None:
        shape_ll = np.logaddexp(shape_ll, wave_ll) - np.log(2.0)
    # The line's frequency: a free ringing sits at a natural frequency (within the peak's
    # accuracy), a forced tone anywhere between two modes; the mixture of both.
    f_modes = wn / (2 * np.pi)
    offset = np.min(np.abs(f_modes - frequency), axis=-1)
    spacing = np.maximum(np.ptp(f_modes, axis=-1) / max(kept - 1, 1), 1e-9)
    resonant = np.exp(-0.5 * (offset / frequency_std) ** 2) / (np.sqrt(2 * np.pi)
                                                                 * frequency_std)
    return shape_ll + np.log(0.5 * resonant + 0.5 / spacing)


# ------------------------------------------------------------------------------- the answer
@checked_keywords
def calibrate_span(
    record: object,
    nominal: Span | LineModel,
    *,
    bc: object = None,
    robot: MDR | None = None,
    tension_range: tuple[float, float] = (0.7, 1.4),
    ei_range: tuple[float, float] = (0.25, 4.0),
    tension_prior: float = 0.10,
    ei_prior: float = 0.7,
    band: tuple[float, float] | None = None,
    max_lines: int = 8,
    shape_error: float = DEFAULT_SHAPE_ERROR,
) -> SpanCalibration:
    """The span's tension and bending stiffness from a record of its vibration, with their
    uncertainty.

    Every spectral line of the record (a load's tone, the free ringing of nearby modes) is
    explained by the nominal line's modes scaled to a candidate tension and EI: by its frequency
    and by its shape at the channels (module doc). The record may come from the field (any
    sensor positions, NaN gaps) or a simulation.

    Parameters
    ----------
    record : Record
        Displacements at a few positions along the span (:class:`~powerline_control.Record`,
        :func:`~powerline_control.load_record`): ``t``, ``positions`` (m), ``values``
        (n_channels, n_t) with NaN for missing samples, ``dt``. A channel may be the robot's
        own measurement of the line under it.
    nominal : Span or LineModel
        The span as told: catalogue conductor, length, supports (a LineModel's, or ``bc``) and
        the stringing tension. Its modal damping (a LineModel's) sets the lines' bandwidth where
        it is wider than the record's resolution.
    bc : str or (str, str), optional
        Supports of a nominal Span (default ``"pinned"``).
    robot : MDR or None
        A robot parked on the line during the record (at ``robot.position``): its mass and
        absorber shift the modes near it.
    tension_range : (float, float)
        Tensions considered, as multiples of the nominal (default 0.7 to 1.4).
    ei_range : (float, float)
        Bending stiffnesses considered, as multiples of the catalogue's (default 0.25 to 4).
    tension_prior : float
        Standard deviation of the log-normal prior on the tension (default 0.10: 10 %, a
        temperature swing of tens of degrees; at least 1e-4).
    ei_prior : float
        Standard deviation of the log-normal prior on EI (default 0.7: a stranded conductor's EI
        lies between its strands' and the solid section's; at least 1e-4).
    band : (float, float) or None
        Frequencies the lines are looked for in, Hz; default from half the nominal fundamental
        to 0.4 / dt.
    max_lines : int
        Most spectral lines used (the strongest).
    shape_error : float
        Share of a line's phasor power the modal model is not trusted to explain (default
        :data:`DEFAULT_SHAPE_ERROR`).

    Returns
    -------
    SpanCalibration

    Raises
    ------
    InputError
        For a record that is not one, with channels outside the nominal span or without data, too
        short to show one cycle of the fundamental, or invalid options.
    IdentificationError
        When the record shows no spectral line above its noise, or only a tension at the edge of
        ``tension_range`` explains it (the nominal conductor's mass or tension is far off).

    Warns
    -----
    CalibrationWarning
        When the record cannot tell the tension well: one line only, sensors within one loop, or
        several tensions explain it about equally (the result's std then covers them).

    Examples
    --------
    >>> import powerline_control as plc
    >>> nominal = plc.Span.paper_lab()
    >>> truth = plc.LineModel(plc.Span(nominal.length, 0.95 * nominal.tension,
    ...                                nominal.conductor), 40, damping=plc.ModalDamping(0.005))
    >>> snap = plc.simulate(truth, plc.RandomForce(0.5, 1.1, bandwidth=150.0, seed=3),
    ...                     duration=10.0, dt=1e-3, noise_fraction=0.01, seed=4)
    >>> rec = plc.Record(snap.t, snap.x[[5, 18, 31]], snap.displacement[[5, 18, 31]])
    >>> cal = plc.calibrate_span(rec, nominal)
    >>> bool(abs(cal.tension / truth.span.tension - 1) < 0.02)   # 5 % low, read within 2 %
    True
    """
    length = nominal.span.length if isinstance(nominal, LineModel) else getattr(
        nominal, "length", None)
    if length is None:
        raise InputError("The 'nominal' parameter must be a Span (with bc=) or a LineModel: the "
                         f"span the engineer was told. Got {type(nominal).__name__}.")
    if isinstance(nominal, Span) and bc is not None:
        parse_bc(bc)     # the supports checked (by name) before the record
    positions, values, dt = _record_arrays(record, length)
    t_lo, t_hi = _check_range("tension_range", tension_range)
    e_lo, e_hi = _check_range("ei_range", ei_range)
    # a prior narrower than 1e-4 (0.01 %) squares log-ratios past the float range
    tension_prior = check_real("tension_prior", tension_prior, low=1e-4, low_inclusive=True)
    ei_prior = check_real("ei_prior", ei_prior, low=1e-4, low_inclusive=True)
    max_lines = check_int("max_lines", max_lines, low=1, high=64)
    shape_error = check_real("shape_error", shape_error, low=0.0, high=1.0)
    span0 = nominal.span if isinstance(nominal, LineModel) else nominal
    duration = dt * (values.shape[1] - 1)
    fundamental = float(span0.pinned_frequencies(1)[0])
    if duration * fundamental < 1.0:
        raise InputError(
            f"The 'record' is too short to calibrate: {duration:.3g} s holds less than one "
            f"cycle of the nominal fundamental ({fundamental:.3g} Hz). Use a record of at least "
            f"{1 / fundamental:.3g} s (tens of seconds on a long span)."
        )
    band = _check_band(band, 0.5 * fundamental, 0.4 / dt)
    lines, widths, noise = _find_lines(_velocities(values), dt, band, max_lines)
    if lines.size == 0:
        raise IdentificationError(
            f"The 'record' shows no spectral line between {band[0]:.3g} and {band[1]:.3g} Hz "
            "above its noise: nothing vibrates that the "
            "calibration could explain. Record while the line vibrates (wind, a shaker, the "
            "robot's absorber), or longer."
        )
    top = float(lines.max()) * math.sqrt(max(1.0 / t_lo, 1.0 / e_lo)) * 1.05
    model = _nominal_model(nominal, bc, robot, top)
    modes = _scaled_modes(model, positions, top)
    tension0, ei0 = span0.tension, span0.conductor.ei
    mass = span0.conductor.mass_per_length
    robot_at = None if robot is None else float(robot.position)
    zeta_floors = 0.5 / (lines * duration)          # a line of a finite record: width ~ 1 / D
    step = float(min(zeta_floors.min(), 0.01))
    n_t = int(min(MAX_TENSION_POINTS, max(50, math.log(t_hi / t_lo) / step)))
    tau = np.geomspace(t_lo, t_hi, n_t)
    phasors = _phasors(values, dt, lines)
    # The local wave reads a record of one or two strong lines (a tone, in lock-in or forced
    # between modes), whose frequencies alone cannot tell the tension; a record of several lines
    # is told by the modes they sit on, and a wave would explain any of its lines as forced. Its
    # shapes span (basis - 2 support conditions) dimensions: it tells the wavelength only where
    # at least two channels are left over to contradict it.
    velocity_power = lines**2 * np.sum(np.abs(phasors) ** 2, axis=1)
    strong = int(np.sum(velocity_power >= STRONG_LINE * velocity_power.max()))
    wave_dims = (5 if robot is not None else 4) - 2
    use_wave = positions.size >= wave_dims + 2 and strong <= WAVE_MAX_LINES

    def wave(f: float, u: np.ndarray, variance: float) -> tuple | None:
        """The line's wave reading over every (T, EI) of the grids (None where the wave does
        not read it): the wavenumber falls with T and with EI."""
        k0 = float(_wavenumber(np.array(tension0), np.array(ei0), mass, f))
        if not (use_wave and ei0 * k0**2 < WAVE_BENDING * tension0):
            return None
        k_range = tuple(float(_wavenumber(np.array(tension0 * a), np.array(ei0 * b), mass, f))
                        for a, b in ((t_hi, e_hi), (t_lo, e_lo)))
        return _wave_loglik(k_range, u, WAVE_SHAPE_ERROR * float(np.vdot(u, u).real) / u.size
                            + variance, positions, length, robot_at)

    evidence = [(float(f), u, float(zeta_floor),
                 float(np.hypot(PEAK_ACCURACY / duration, 0.5 * width)
                       + FREQUENCY_MODEL_ERROR * f), float(variance),
                 wave(float(f), u, float(variance)))
                for f, u, zeta_floor, width, variance in zip(lines, phasors, zeta_floors, widths,
                                                             noise, strict=True)]

    def log_posterior(eta: np.ndarray) -> np.ndarray:
        omega2 = (tension0 * tau[:, None, None] * modes.g + ei0 * eta[None, :, None] * modes.b
                  + modes.rest)
        log_post = (-0.5 * (np.log(tau)[:, None] / tension_prior) ** 2
                    - 0.5 * (np.log(eta)[None, :] / ei_prior) ** 2)
        tension, ei = tension0 * tau[:, None], ei0 * eta[None, :]
        for f, u, zeta_floor, frequency_std, variance, wave_table in evidence:
            sigma2 = shape_error * float(np.vdot(u, u).real) / u.size + variance
            wave_ll = None if wave_table is None else np.interp(
                _wavenumber(tension, ei, mass, f), *wave_table)
            log_post = log_post + _line_loglik(omega2, modes, u, f, zeta_floor, sigma2,
                                               frequency_std, wave_ll)
        return log_post

    if ei0 > 0:
        eta = np.geomspace(e_lo, e_hi, EI_POINTS)
        log_post = log_posterior(eta)
        # a second, finer EI grid over the coarse posterior's support (+- one coarse step)
        p_eta = np.exp(log_post - log_post.max()).sum(axis=0)
        support = eta[p_eta > 1e-6 * p_eta.max()]
        ratio = eta[1] / eta[0]
        eta = np.geomspace(max(support.min() / ratio, e_lo), min(support.max() * ratio, e_hi),
                           EI_POINTS)
        log_post = log_posterior(eta)
    else:
        eta = np.ones(1)
        log_post = log_posterior(eta)
    return _summarise(log_post, tau, eta, span0, model, modes, lines, positions, duration,
                      (t_lo, t_hi), np.array([item[3] for item in evidence]), ei_prior)


def _check_range(name: str, value: object) -> tuple[float, float]:
    try:
        pair = np.asarray(value)
    except (TypeError, ValueError):
        pair = np.zeros(0)
    if pair.shape != (2,) or pair.dtype.kind not in "iuf":   # text and booleans are no numbers
        raise InputError(f"The '{name}' parameter must be a pair (low, high) of multiples of "
                         f"the nominal. Got {value!r}.")
    lo, hi = (float(v) for v in pair)
    if not (0 < lo < 1 < hi < 100):
        raise InputError(f"The '{name}' parameter must satisfy 0 < low < 1 < high < 100 "
                         f"(multiples of the nominal). Got {value!r}.")
    return lo, hi


def _check_band(band: object, default_lo: float, default_hi: float) -> tuple[float, float]:
    if band is None:
        return default_lo, default_hi
    try:
        lo, hi = (float(v) for v in band)   # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise InputError(f"The 'band' parameter must be a pair (low, high) of frequencies, Hz. "
                         f"Got {band!r}.") from None
    if not (0 <= lo < hi <= default_hi):
        raise InputError(f"The 'band' parameter must satisfy 0 <= low < high <= "
                         f"{default_hi:.4g} Hz (0.4 / dt). Got {band!r}.")
    return lo, hi


def _hz(frequencies: np.ndarray) -> str:
    """Up to six frequencies as text."""
    text = ", ".join(f"{f:.4g}" for f in frequencies[:6])
    return text + (f", ... ({frequencies.size} in all)" if frequencies.size > 6 else "")


def _other_peaks(density: np.ndarray, grid: np.ndarray, main: slice) -> str:
    """The strongest local maxima of ``density`` outside ``main``, as text."""
    inner = np.arange(1, density.size - 1)
    local = inner[(density[inner] >= density[inner - 1]) & (density[inner] > density[inner + 1])]
    local = [k for k in local if not main.start <= k < main.stop]
    local.sort(key=lambda k: -density[k])
    return ", ".join(f"{grid[k]:.6g} N" for k in local[:3]) or "the range's edges"


def _summarise(log_post, tau, eta, span0: Span, model: LineModel, modes: _ScaledModes,
               lines, positions, duration, tension_range, frequency_std,
               ei_prior: float) -> SpanCalibration:
    """The posterior's marginals, its peak, and the warnings the record earns."""
    post = np.exp(log_post - log_post.max())
    post /= post.sum()
    p_tau, p_eta = post.sum(axis=1), post.sum(axis=0)
    tension_grid = span0.tension * tau
    notes: list[str] = []
    peak = int(np.argmax(p_tau))
    if peak in (0, tau.size - 1):
        raise IdentificationError(
            f"The record is explained only by a tension at the edge of 'tension_range' "
            f"({tension_range[0]:g} to {tension_range[1]:g} x the nominal "
            f"{span0.tension:.6g} N): {tension_grid[peak]:.6g} N. The nominal conductor "
            "(its mass per length) or the stringing tension is far off; check them, or widen "
            "tension_range."
        )
    # the main peak: the contiguous run of the marginal above 1e-3 of its maximum
    above = p_tau > 1e-3 * p_tau[peak]
    lo = peak
    while lo > 0 and above[lo - 1]:
        lo -= 1
    hi = peak
    while hi < tau.size - 1 and above[hi + 1]:
        hi += 1
    outside = 1.0 - float(p_tau[lo : hi + 1].sum())
    main = slice(lo, hi + 1)
    if outside > AMBIGUOUS_MASS:
        others = _other_peaks(p_tau, tension_grid, main)
        notes.append(
            f"several tensions explain the record ({100 * outside:.0f} % of the posterior lies "
            f"away from {tension_grid[peak]:.6g} N, e.g. at {others}): the sensors cannot tell "
            "one mode from its neighbour. A longer record, a broadband excitation or sensors "
            "less than a loop apart would."
        )
        tension = float(tension_grid[peak])
    else:
        weights = p_tau[main] / p_tau[main].sum()
        tension = float(np.sum(weights * tension_grid[main]))
    mean = float(np.sum(p_tau * tension_grid))
    tension_std = float(np.sqrt(np.sum(p_tau * (tension_grid - mean) ** 2)
                                + (tension - mean) ** 2))
    # a grid step bounds what the posterior can resolve
    tension_std = max(tension_std, 0.5 * tension * float(np.log(tau[1] / tau[0])))
    ei0 = span0.conductor.ei
    ei_grid = ei0 * eta
    ei = float(np.exp(np.sum(p_eta * np.log(np.maximum(ei_grid, 1e-300))))) if ei0 > 0 else 0.0
    ei_std = float(np.sqrt(np.sum(p_eta * (ei_grid - ei) ** 2)))
    log_spread = float(np.sqrt(np.sum(p_eta * np.log(eta / (ei / max(ei0, 1e-300))) ** 2))) \
        if ei0 > 0 else 0.0
    ei_identified = ei0 > 0 and log_spread < 0.5 * ei_prior
    if lines.size == 1:
        notes.append(
            f"the record shows one spectral line only ({lines[0]:.4g} Hz): the tension rests on "
            "which mode the sensors' shape says it is. A longer record or a broadband "
            "excitation shows the free modes beside it."
        )
    loop = float(span0.loop_length(float(lines.max())))
    if np.ptp(positions) < loop:
        notes.append(
            f"every channel lies within one loop ({np.ptp(positions):.3g} m apart, a loop is "
            f"{loop:.3g} m at {lines.max():.4g} Hz): the shape cannot tell the mode. Spread "
            "the sensors over several loops."
        )
    conductor = replace(span0.conductor, ei=ei) if ei0 > 0 else span0.conductor
    span = Span(span0.length, tension, conductor)
    mass = span0.conductor.mass_per_length
    sag = mass * GRAVITY * span0.length**2 / (8 * tension)
    # the calibrated model's frequencies at the lines (Rayleigh scaling of the nominal modes)
    omega2 = tension * modes.g + ei * modes.b + modes.rest
    model_f = np.sqrt(np.maximum(omega2, 0.0)) / (2 * np.pi)
    order = np.argsort(model_f)
    nearest = np.array([int(np.argmin(np.abs(model_f[order] - f))) for f in lines])
    explained = np.abs(model_f[order][nearest] - lines) <= 3 * frequency_std
    if lines.size >= 3 and explained.sum() < lines.size / 3:
        # a forced tone may sit between modes, but most lines of a record are the line's own
        raise IdentificationError(
            f"The nominal span explains only {int(explained.sum())} of the record's "
            f"{lines.size} spectral lines ({_hz(lines)} Hz) at any "
            "tension within "
            f"'tension_range' ({tension_range[0]:g} to {tension_range[1]:g} x "
            f"{span0.tension:.6g} N): the nominal conductor (its mass per length), the "
            "stringing tension or the span length is far off, or the record is of another span. "
            "Check them, or widen tension_range."
        )
    for note in notes:
        warnings.warn(note[0].upper() + note[1:], CalibrationWarning, stacklevel=3)
    return SpanCalibration(
        nominal=span0, span=span, bc=tuple(model.bc),
        tension=tension, tension_std=tension_std, ei=ei, ei_std=ei_std,
        ei_identified=bool(ei_identified), sag=float(sag),
        sag_std=float(sag * tension_std / tension),
        line_frequencies=read_only(lines), model_frequencies=read_only(model_f[order][nearest]),
        mode_numbers=read_only(nearest + 1),
        posterior_tension=read_only(np.column_stack([tension_grid,
                                                     p_tau / np.gradient(tension_grid)])),
        duration=float(duration), ambiguous=bool(outside > AMBIGUOUS_MASS),
        peak_share=float(1.0 - outside),
        warnings=tuple(notes),
    )
