"""Aeolian severity of a span by the energy balance method (EBM), and what a damper or the robot
is worth in clamp strain and fatigue.

The steady antinode amplitude ``Y`` (zero-to-peak) at each wind speed solves the power balance per
metre of span (CIGRE TB 273, IEEE PES-TR17, EPRI Orange Book)::

    P_wind(Y, f) = P_self(Y, f, T) + sum over dampers P_damper(Y, f)

with ``f = St V / D`` the Strouhal frequency, ``P_wind = f^3 D^4 F(Y/D)`` (a published wind power
curve), ``P_self = k Y^l f^m / T^n`` (an empirical self-damping law, T in kN) and
``P_damper = 1/2 Re Z(omega) omega^2 Y^2 phi(x_s)^2 / L`` (a damper of mechanical impedance Z at
``x_s``, where the standing wave has relative amplitude ``phi``). The clamp bending amplitude and
stress follow by Poffenberger-Swart (at x_b = 89 mm) and by the f * y_max formula; margins are taken
against the CIGRE/EPRI safe border line and the 150 microstrain peak-to-peak endurance strain.
``docs/severity.md`` derives every formula and lists the sources.

Test seam: ``_sbl_cycles``: the fatigue tests compose the expected damage (Miner's sum) from the
cycles to failure it gives; the safe border line itself is checked against its closed form
(tests/test_fatigue.py, tests/test_severity.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.interpolate
import scipy.optimize

from .._results import TabularResult, to_dataframe
from .._validation import (
    check_budget,
    check_choice,
    check_real,
    checked_keywords,
    read_only,
)
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL
from ..fem import MDR
from ..line import Span
from ._common import (
    ALUMINIUM_MODULUS,
    ENDURANCE_STRAIN_PP,
    OUTER_STRAND_DIAMETER,
    POFFENBERGER_SWART_DISTANCE,
    _check_span,
    _check_text,
    _check_wind_speeds,
)
from .dampers import (
    AtAntinode,
    ImpedanceDamper,
    _label_of,
    damper_power,
    loop_length,
    standing_wave_shape,
)
from .modal import LOWEST_REDUCED_AMPLITUDE, coupled_cycle, coupled_robot
from .self_damping import FotiMartinelli
from .wind import SelfDampingLaw, _curve, _resolve_law, turbulence_factor

__all__ = [
    "SeverityResult",
    "OUTER_STRAND_DIAMETER",
    "aeolian_severity",
]


# --------------------------------------------------------------------------- fatigue indicators
#: CIGRE/EPRI safe border line sigma_a = a N^b MPa (two branches): (N threshold, a1, b1, a2, b2).
#: From the EPRI Orange Book, as in dohl/damage.py.
SAFE_BORDER_LINES = {
    "multi": (1.56e7, 450.0, -0.20, 263.0, -0.17),
    "single": (2.0e7, 730.0, -0.20, 430.0, -0.17),
}


def _sbl_stress(cycles: float, layers: str) -> float:
    """Safe-border-line stress amplitude (Pa) at ``cycles``."""
    threshold, a1, b1, a2, b2 = SAFE_BORDER_LINES[layers]
    a, b = (a1, b1) if cycles <= threshold else (a2, b2)
    return a * cycles**b * 1e6


def _sbl_cycles(stress: np.ndarray, layers: str) -> np.ndarray:
    """Cycles to the safe border line at stress amplitude ``stress`` (Pa); inf at zero stress.

    The two published branches do not meet at the threshold; stresses in the gap get the
    threshold count.
    """
    threshold, a1, b1, a2, b2 = SAFE_BORDER_LINES[layers]
    s = np.maximum(np.asarray(stress, dtype=float) / 1e6, 1e-300)
    with np.errstate(over="ignore"):  # vanishing stress: infinitely many cycles, as intended
        first = (s / a1) ** (1 / b1)
        second = (s / a2) ** (1 / b2)
    cycles = np.where(first <= threshold, first, np.where(second >= threshold, second, threshold))
    return np.where(np.asarray(stress) > 0, cycles, np.inf)


# --------------------------------------------------------------------------- the energy balance
# One energy balance (a bracketed root solve in Python) costs ~3 ms, counted as ~1e7 flops so
# that WORK_BUDGET (1e12) allows ~1e5 speeds (minutes); each speed keeps ~16 float64 results.
_WORK_PER_SPEED = 1e7


def _check_severity_budget(n_speeds: int) -> None:
    check_budget("aeolian_severity's energy balances", nbytes=8.0 * 16 * n_speeds,
                 flops=_WORK_PER_SPEED * n_speeds, parameter="wind_speeds",
                 value=f"{n_speeds} speeds",
                 fix="pass fewer wind speeds (a few dozen resolve the 1-7 m/s band)")


def _check_dampers(dampers: object, span: Span) -> tuple:
    if isinstance(dampers, MDR | ImpedanceDamper | AtAntinode):
        dampers = (dampers,)
    if not isinstance(dampers, Sequence):
        raise InputError("The 'dampers' parameter must be a sequence of MDR, ImpedanceDamper or "
                         f"AtAntinode. Got {type(dampers).__name__}.")
    for i, damper in enumerate(dampers):
        if not isinstance(damper, MDR | ImpedanceDamper | AtAntinode):
            raise InputError(f"The 'dampers[{i}]' entry must be an MDR, ImpedanceDamper or "
                             f"AtAntinode. Got {type(damper).__name__}.")
        if not isinstance(damper, AtAntinode) and not 0 <= damper.position <= span.length:
            raise InputError(f"The 'dampers[{i}].position' must lie in [0, {span.length:g}] m "
                             f"(the span). Got {damper.position!r}.")
    return tuple(dampers)


@dataclass(frozen=True, eq=False)
class SeverityResult(TabularResult):
    """Energy-balance severity of one span and damper configuration, one entry per wind speed.

    Attributes
    ----------
    wind_speed : ndarray
        m/s.
    frequency : ndarray
        Strouhal frequency St V / D, Hz.
    mode : ndarray of int
        Number of the span mode nearest that frequency (round(L / loop length)).
    loop_length : ndarray
        Half wavelength of the taut beam, m.
    amplitude : ndarray
        Steady antinode amplitude Y, zero-to-peak, m (0 where no vibration builds up).
    balanced : ndarray of bool
        True where the balance has a root inside the wind curve's range.
    status : tuple of str
        Per wind speed: ``"balanced"``, ``"no vibration"`` (damping exceeds the wind power at
        every amplitude: Y = 0) or ``"above curve range"`` (the wind power still exceeds the
        damping at the curve's last point: Y is given as that bound and is a LOWER bound).
    wind_power, self_damping_power, damper_power : ndarray
        The three terms of the balance at ``amplitude``, W/m.
    bending_amplitude : ndarray
        Poffenberger-Swart Y_b: peak-to-peak displacement at x_b from the clamp, m.
    stress_ps, stress_fymax : ndarray
        Idealised stress amplitude (zero-to-peak) of the outer strand at the clamp, Pa, by
        Poffenberger-Swart and by the f y_max formula.
    strain_pp, strain_pp_fymax : ndarray
        Peak-to-peak bending strain at the clamp (2 sigma_a / E_a) by the two methods.
    sbl_margin : ndarray
        Safe-border-line stress at ``reference_cycles`` divided by ``stress_ps`` (> 1: below;
        +inf where the span does not vibrate).
    endurance_margin : ndarray
        ``endurance_strain_pp`` divided by ``strain_pp`` (> 1: below the endurance strain;
        +inf where the span does not vibrate).
    label : str
        Configuration name.
    damper_labels : tuple of str
        The dampers.
    parameters : dict
        The settings used (curve, law, St, bc, x_b, ...).

    Examples
    --------
    >>> from powerline_control import Span
    >>> sev = aeolian_severity(Span.at_rts_fraction(300.0, "drake", 0.2), [1.0, 3.0])
    >>> (sev.amplitude * 1e3).round(1)
    array([26.9,  8.5])
    >>> sorted(sev.table()[0])[:3]
    ['amplitude_mm', 'balanced', 'bending_amplitude_mm']
    """

    wind_speed: np.ndarray
    frequency: np.ndarray
    mode: np.ndarray
    loop_length: np.ndarray
    amplitude: np.ndarray
    balanced: np.ndarray
    status: tuple
    wind_power: np.ndarray
    self_damping_power: np.ndarray
    damper_power: np.ndarray
    bending_amplitude: np.ndarray
    stress_ps: np.ndarray
    stress_fymax: np.ndarray
    strain_pp: np.ndarray
    strain_pp_fymax: np.ndarray
    sbl_margin: np.ndarray
    endurance_margin: np.ndarray
    label: str = "no damper"
    damper_labels: tuple = ()
    parameters: dict = field(default_factory=dict, repr=False)

    def table(self, as_frame: bool = False):
        """Tidy rows, one per wind speed (display units: mm, microstrain, MPa).

        Parameters
        ----------
        as_frame : bool
            True returns a pandas DataFrame, as :meth:`to_dataframe` does (pandas must be
            installed); default a list of dicts.

        Returns
        -------
        list of dict or pandas.DataFrame

        Examples
        --------
        >>> from powerline_control import Span
        >>> rows = aeolian_severity(Span.at_rts_fraction(300.0, "drake", 0.2), [2.0]).table()
        >>> rows[0]["wind_speed"], rows[0]["configuration"]
        (2.0, 'no damper')
        """
        rows = []
        for i in range(self.wind_speed.size):
            rows.append({
                "configuration": self.label,
                "wind_speed": float(self.wind_speed[i]),
                "frequency_hz": float(self.frequency[i]),
                "mode": int(self.mode[i]),
                "loop_length_m": float(self.loop_length[i]),
                "amplitude_mm": float(self.amplitude[i] * 1e3),
                "balanced": bool(self.balanced[i]),
                "status": self.status[i],
                "bending_amplitude_mm": float(self.bending_amplitude[i] * 1e3),
                "stress_ps_mpa": float(self.stress_ps[i] / 1e6),
                "stress_fymax_mpa": float(self.stress_fymax[i] / 1e6),
                "strain_pp_microstrain": float(self.strain_pp[i] * 1e6),
                "strain_pp_fymax_microstrain": float(self.strain_pp_fymax[i] * 1e6),
                "sbl_margin": float(self.sbl_margin[i]),
                "endurance_margin": float(self.endurance_margin[i]),
            })
        return to_dataframe(rows, "SeverityResult") if as_frame else rows


def _clamp_stress(span: Span, frequency: float, amplitude: float, *, strand: float,
                  modulus: float, x_b: float) -> tuple[float, float, float]:
    """(Y_b peak-to-peak, sigma_a by Poffenberger-Swart, sigma_a by f y_max) at the clamp."""
    cond = span.conductor
    if cond.ei <= 0:
        raise InputError("Clamp stresses need conductor.ei > 0 (EI_min of the stranded "
                         "conductor).")
    y_xb = float(standing_wave_shape(span, frequency, min(x_b, span.length / 2), "clamped"))
    bending = 2.0 * abs(y_xb) * amplitude
    p = math.sqrt(span.tension / cond.ei)
    px = p * x_b
    # e^{-px} - 1 + px by its series where px is small, to keep its digits.
    denominator = math.expm1(-px) + px
    k_ps = modulus * strand * p**2 / (4.0 * denominator)
    sigma_fy = math.pi * strand * modulus * math.sqrt(cond.mass_per_length / cond.ei) \
        * frequency * amplitude
    return bending, k_ps * bending, sigma_fy


def _solve_balance(balance, y_high: float, scale: float, on_grid=None) -> tuple[float, str]:
    """Root of balance(y) = P_w - P_c - P_d on (0, y_high]: the first sign change on a
    logarithmic scan, polished by Brent's method. ``on_grid`` evaluates the same balance on an
    array at once (the scan, elementwise the same arithmetic as ``balance``)."""
    grid = np.geomspace(1e-9 * scale, y_high, 240)
    values = (np.array([balance(y) for y in grid]) if on_grid is None
              else np.asarray(on_grid(grid), dtype=float))
    if values[0] <= 0:
        return 0.0, "no vibration"
    negative = np.flatnonzero(values <= 0)
    if negative.size == 0:
        return float(y_high), "above curve range"
    j = int(negative[0])
    if values[j] == 0:
        return float(grid[j]), "balanced"
    root = scipy.optimize.brentq(balance, grid[j - 1], grid[j], xtol=1e-300,
                                 rtol=4 * np.finfo(float).eps, maxiter=500)
    return float(root), "balanced"


#: How a damper's power enters the balance (``aeolian_severity(damper_model=)``).
DAMPER_MODELS = ("first_order", "coupled")


@checked_keywords
def aeolian_severity(
    span: Span,
    wind_speeds: Sequence[float] | np.ndarray = np.arange(1.0, 8.0),  # noqa: B008 (read only)
    dampers: Sequence[MDR | ImpedanceDamper | AtAntinode] = (),
    *,
    strouhal: float = DEFAULT_STROUHAL,
    wind_curve: str = "cigre",
    turbulence_intensity: float = 0.0,
    self_damping: str | SelfDampingLaw | FotiMartinelli = "noiseux1991",
    self_damping_k: float | None = None,
    self_damping_exponents: Sequence[float] | None = None,
    bc: str = "clamped",
    outer_strand_diameter: float | None = None,
    outer_strand_modulus: float = ALUMINIUM_MODULUS,
    layers: str = "multi",
    x_b: float = POFFENBERGER_SWART_DISTANCE,
    endurance_strain_pp: float = ENDURANCE_STRAIN_PP,
    reference_cycles: float = 5e8,
    label: str | None = None,
    damper_model: str = "first_order",
) -> SeverityResult:
    """Steady aeolian vibration of a span by the energy balance, with clamp strain and margins.

    For each wind speed: the Strouhal frequency f = St V / D, the loop length and mode from the
    taut-beam dispersion m omega^2 = EI k^4 + T k^2, the antinode amplitude Y solving
    P_w(Y) = P_c(Y) + sum P_d(Y) (a bracketed root, Brent's method), then the clamp bending
    amplitude Y_b at x_b and the stress by Poffenberger-Swart and by f y_max, the
    safe-border-line margin and the endurance-strain margin.

    Parameters
    ----------
    span : Span
        Conductor, length and tension (tension below the rated strength).
    wind_speeds : sequence of float
        m/s, each > 0 (default 1..7).
    dampers : sequence of MDR, ImpedanceDamper or AtAntinode
        Devices on the span (default none).
    strouhal : float
        Strouhal number (default 0.185).
    wind_curve : str
        A name of :data:`WIND_POWER_CURVES` (default "cigre").
    turbulence_intensity : float
        Iv for :func:`turbulence_factor` (default 0).
    self_damping : str, SelfDampingLaw or FotiMartinelli
        A name of :data:`SELF_DAMPING_LAWS` (default "noiseux1991"; Lilien k from dohl,
        unverified), a law, or the physical model :class:`FotiMartinelli` (e.g.
        ``FotiMartinelli.from_conductor(span.conductor)``).
    self_damping_k : float or None
        User coefficient k.
    self_damping_exponents : (l, m, n) or None
        User exponents.
    bc : {"clamped", "pinned"}
        Supports, for the placement factor of dampers (the clamp stress always assumes a clamp).
    outer_strand_diameter : float or None
        Diameter of an outer strand, m; None takes the conductor's own
        (``Conductor.outer_strand_diameter``: every preset and the paper's lab conductor carry
        one; an error for a conductor without).
    outer_strand_modulus : float
        Young's modulus of the outer strands, Pa (default aluminium, 68.9 GPa).
    layers : {"multi", "single"}
        Safe border line of multilayer or single-layer ACSR.
    x_b : float
        Poffenberger-Swart distance from the last point of contact, m (default 0.089).
    endurance_strain_pp : float
        Allowed peak-to-peak bending strain (default 150e-6).
    reference_cycles : float
        Cycle count at which the safe border line gives the endurance stress for
        ``sbl_margin`` (default 5e8 [from memory: the usual "endurance" count]).
    label : str or None
        Configuration name (default: from the dampers).
    damper_model : {"first_order", "coupled"}
        How the robot's power enters the balance. "first_order" (default): the textbook
        ``1/2 Re Z omega^2 Y^2 phi^2 / L``, the standing wave left as it is (right when the
        damper's impedance is small against the line's wave impedance sqrt(T m)). "coupled":
        one MDR (or ``AtAntinode(MDR)``) coupled to the FE line, its power computed from the
        vibration it leaves (the coupled limit cycle at each wind speed; a real robot's
        impedance is several times sqrt(T m), and the first-order power then overstates what it
        takes several-fold). Where the first-order amplitude lies below 1e-3 D, under the power
        curves' data, the first-order balance is kept. (:func:`coupled_balance` gives one wind
        speed's coupled balance with its powers, frequency and field.)

    Returns
    -------
    SeverityResult

    Raises
    ------
    InputError
        For wind speeds <= 0, a damper outside the span, an unknown curve or law (the message
        lists the allowed names), a tension at or above the rated strength.

    Examples
    --------
    >>> from powerline_control import Span
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.25)
    >>> sev = aeolian_severity(span, [1.0, 7.0])
    >>> (sev.amplitude * 1e3).round(1), sev.mode.tolist()
    (array([27.7,  1.5]), [27, 188])
    """
    span = _check_span(span)
    if label is not None:
        _check_text("label", label)
    if isinstance(wind_speeds, np.ndarray):  # refuse before the finiteness checks copy it
        _check_severity_budget(wind_speeds.size)
    speeds = _check_wind_speeds(wind_speeds)
    _check_severity_budget(speeds.size)
    dampers = _check_dampers(dampers, span)
    damper_model = check_choice("damper_model", damper_model, DAMPER_MODELS)
    if damper_model == "coupled" and dampers:
        if len(dampers) != 1:
            raise InputError(
                "The 'dampers' parameter with damper_model='coupled' must hold one robot (the "
                f"coupled model parks one on the FE line). Got {len(dampers)}: "
                f"{[_label_of(d) for d in dampers]}; use damper_model='first_order'.")
        coupled_robot(dampers[0], "dampers", "use damper_model='first_order' for "
                      "ImpedanceDampers or a placement factor")
    st = check_real("strouhal", strouhal, low=0.01, low_inclusive=True, high=1.0)
    curve = _curve(wind_curve)
    law = _resolve_law(self_damping, self_damping_k, self_damping_exponents)
    bc = check_choice("bc", bc, ("clamped", "pinned"))
    layers = check_choice("layers", layers, tuple(SAFE_BORDER_LINES))
    # x_b from 0.1 mm: Poffenberger-Swart's K divides by e^{-p x_b} - 1 + p x_b ~ (p x_b)^2 / 2
    x_b = check_real("x_b", x_b, low=1e-4, low_inclusive=True, high=span.length / 2)
    modulus = check_real("outer_strand_modulus", outer_strand_modulus, low=0.0)
    endurance = check_real("endurance_strain_pp", endurance_strain_pp, low=0.0)
    reference_cycles = check_real("reference_cycles", reference_cycles, low=1.0)
    b = turbulence_factor(turbulence_intensity)
    cond = span.conductor
    if outer_strand_diameter is None:
        if cond.outer_strand_diameter is None:
            raise InputError(
                "The 'outer_strand_diameter' parameter is needed for conductor "
                f"{cond.name!r}, which does not carry one (Conductor(..., "
                "outer_strand_diameter=...)); the presets do: "
                f"{sorted(OUTER_STRAND_DIAMETER)}.")
        strand = cond.outer_strand_diameter
    else:
        strand = check_real("outer_strand_diameter", outer_strand_diameter, low=0.0,
                            high=cond.diameter)
    law.power(0.0, 1.0, span)  # a law without a tension exponent (or k) fails here, clearly
    d = cond.diameter
    y_high = curve.max_reduced_amplitude * d
    sigma_endurance = _sbl_stress(reference_cycles, layers)

    n = speeds.size
    out = {name: np.zeros(n) for name in (
        "frequency", "loop", "amplitude", "pw", "pc", "pd", "yb", "sps", "sfy")}
    modes = np.zeros(n, dtype=int)
    status = []
    for i, speed in enumerate(speeds):
        f = st * float(speed) / d
        loop = loop_length(span, f)
        # Damper coefficients: P_d = coefficient * Y^2, summed over the dampers.
        coefficient = sum(float(damper_power(dmp, span, 1.0, f, bc=bc)) for dmp in dampers)
        base = b * f**3 * d**4

        def balance(y, f=f, base=base, coefficient=coefficient):
            return float(base * curve.reduced_power(y / d) - law.power(y, f, span)
                         - coefficient * y * y)

        def on_grid(y, f=f, base=base, coefficient=coefficient):
            return base * curve.reduced_power(y / d) - law.power(y, f, span) \
                - coefficient * y * y

        y, state = _solve_balance(balance, y_high, d, on_grid)
        # the coupled line and robot; below the power curves' data its wind is capped as the
        # time-domain run's is, and there the first-order balance (an extrapolation either
        # way) is kept
        if damper_model == "coupled" and dampers and y >= LOWEST_REDUCED_AMPLITUDE * d:
            coupled = coupled_cycle(
                span, float(speed), dampers[0], bc=bc, strouhal=st, wind_curve=curve.name,
                turbulence_intensity=turbulence_intensity, self_damping=law)
            y, state = coupled.amplitude, coupled.status
            out["pw"][i], out["pc"][i] = coupled.wind_power, coupled.self_damping_power
            out["pd"][i] = coupled.robot_power
        else:
            out["pw"][i] = base * float(curve.reduced_power(y / d))
            out["pc"][i] = float(law.power(y, f, span))
            out["pd"][i] = coefficient * y * y
        status.append(state)
        yb, sps, sfy = _clamp_stress(span, f, y, strand=strand, modulus=modulus, x_b=x_b)
        out["frequency"][i], out["loop"][i], out["amplitude"][i] = f, loop, y
        out["yb"][i], out["sps"][i], out["sfy"][i] = yb, sps, sfy
        modes[i] = max(1, int(round(span.length / loop)))
    strain_pp = 2 * out["sps"] / modulus
    with np.errstate(divide="ignore"):
        sbl_margin = np.where(out["sps"] > 0, sigma_endurance / np.maximum(out["sps"], 1e-300),
                              np.inf)
        endurance_margin = np.where(strain_pp > 0, endurance / np.maximum(strain_pp, 1e-300),
                                    np.inf)
    labels = tuple(_label_of(dmp) for dmp in dampers)
    return SeverityResult(
        wind_speed=read_only(speeds.copy()), frequency=read_only(out["frequency"]),
        mode=read_only(modes), loop_length=read_only(out["loop"]),
        amplitude=read_only(out["amplitude"]),
        balanced=read_only(np.array([s == "balanced" for s in status])), status=tuple(status),
        wind_power=read_only(out["pw"]), self_damping_power=read_only(out["pc"]),
        damper_power=read_only(out["pd"]), bending_amplitude=read_only(out["yb"]),
        stress_ps=read_only(out["sps"]), stress_fymax=read_only(out["sfy"]),
        strain_pp=read_only(strain_pp), strain_pp_fymax=read_only(2 * out["sfy"] / modulus),
        sbl_margin=read_only(sbl_margin), endurance_margin=read_only(endurance_margin),
        label=label if label is not None else (" + ".join(labels) if labels else "no damper"),
        damper_labels=labels,
        parameters=dict(strouhal=st, wind_curve=curve.name, turbulence_factor=b,
                        self_damping=law.name, **_law_parameters(law, span), bc=bc, x_b=x_b,
                        outer_strand_diameter=strand, outer_strand_modulus=modulus,
                        layers=layers, endurance_strain_pp=endurance,
                        reference_cycles=reference_cycles, sbl_endurance_stress=sigma_endurance),
    )


def _law_parameters(law: SelfDampingLaw | FotiMartinelli, span: Span) -> dict:
    """The self-damping entries of ``SeverityResult.parameters``: a power law's exponents and
    k, or the physical model's EI_max and limit curvature at the span's tension."""
    if isinstance(law, FotiMartinelli):
        return dict(self_damping_exponents=None, self_damping_k=None,
                    self_damping_model=dict(ei_max=law.ei_max, regime=law.regime,
                                            limit_curvature=law.limit_curvature(span.tension)))
    return dict(self_damping_exponents=(law.l, law.m, law.n),
                self_damping_k=law.coefficient(span))
