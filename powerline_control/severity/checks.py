"""Checks of the energy balance: against a time-domain simulation of the same span, and the
CIGRE TB 273 catenary-parameter criterion."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from .._spectral import fit_phasors
from .._validation import (
    check_forwarded_options,
    check_int,
    check_real,
    read_only,
)
from ..errors import InputError
from ..excitation import DEFAULT_STROUHAL, AeolianForce
from ..fem import DENSE_EIGEN_LIMIT, MDR, LineModel, ModalDamping
from ..line import Span
from ..simulation import simulate
from ._common import AIR_DENSITY, GRAVITY, MAX_WIND_SPEED, _check_span
from .balance import _check_dampers, aeolian_severity

__all__ = [
    "TimeDomainCheck",
    "CatenaryCheck",
    "TB273_UNDAMPED_LIMITS_FROM_MEMORY",
    "time_domain_check",
    "catenary_check",
]


# --------------------------------------------------------------------------- time-domain check
@dataclass(frozen=True, eq=False)
class TimeDomainCheck:
    """EBM antinode amplitude against a time-domain simulation of the same span.

    Attributes
    ----------
    wind_speed : float
        Wind speed whose Strouhal frequency equals the FE mode ``mode``'s frequency, m/s.
    frequency : float
        That frequency, Hz.
    mode : int
        FE mode number (1-based).
    ebm_amplitude : float
        Energy-balance amplitude, m.
    simulated_amplitude : float
        Steady antinode amplitude of the simulation (harmonic fit over the last periods), m.
    relative_error : float
        simulated / EBM - 1.
    damping_ratio : float
        Equivalent modal damping ratio zeta_eq = 2 P_c(Y) / (m omega^3 Y^2).
    lift_coefficient : float
        C_L of the aeolian load whose power at Y equals P_w(Y): q = 4 P_w / (omega Y).
    n_elements : int
        FE mesh of the simulation.
    clamp_time : ndarray or None
        Sample times of ``clamp_stress``, s (clamped supports only; None otherwise).
    clamp_stress : ndarray or None
        Clamp stress history, Pa: the simulated antinode displacement y(t) times the energy
        balance's sigma_a / Y (its clamp stress per metre of antinode amplitude; the FE mesh
        does not resolve the clamp's few-centimetre boundary layer, so the clamp displacement
        is not read from it). Eight periods at 64 samples per period, for a rainflow count
        (:func:`~powerline_control.severity.fatigue.rainflow_damage`).
    ebm_stress : float or None
        The energy balance's Poffenberger-Swart stress amplitude at the clamp, Pa.

    Examples
    --------
    >>> check = TimeDomainCheck(3.0, 19.8, 6, 8.4e-3, 8.3e-3, -0.012, 3e-4, 0.8, 40)
    >>> abs(check.relative_error) < 0.1
    True
    """

    wind_speed: float
    frequency: float
    mode: int
    ebm_amplitude: float
    simulated_amplitude: float
    relative_error: float
    damping_ratio: float
    lift_coefficient: float
    n_elements: int
    clamp_time: np.ndarray | None = field(default=None, repr=False)
    clamp_stress: np.ndarray | None = field(default=None, repr=False)
    ebm_stress: float | None = None


def time_domain_check(span: Span, wind_speed: float, *, n_elements: int, bc: str = "clamped",
                      damper: MDR | None = None, settle: float = 8.0,
                      samples_per_period: int = 16, **severity_options) -> TimeDomainCheck:
    """Check the EBM amplitude against a :func:`~powerline_control.simulation.simulate` run.

    The wind speed is moved to the one whose Strouhal frequency equals the nearest natural
    frequency of the FE model (lock-in: with a ``damper`` the frequency of the coupled, damped
    mode, from the eigenvalues of the model with the robot). The EBM gives Y, P_w(Y) and P_c(Y)
    (and P_d(Y) of the damper). The simulation uses a linear model with the same powers at that
    amplitude: for y = Y sin(beta x) sin(omega t), a viscous damping c = 2 zeta m omega per metre
    dissipates zeta m omega^3 Y^2 / 2 per metre, so zeta_eq = 2 P_c / (m omega^3 Y^2) (a
    :class:`~powerline_control.fem.ModalDamping`); a lift q sin(beta x) in phase with the
    velocity delivers q omega Y / 4 per metre, so q = 4 P_w / (omega Y) sets the
    :class:`~powerline_control.excitation.AeolianForce` lift coefficient. The damper, if any, is
    the FE model's own MDR (its power is not imposed: the FE computes it). The run starts from
    rest and lasts ``settle`` decay times; the amplitude is a least-squares harmonic fit at each
    node over the last 4 periods, maximised over the nodes.

    Parameters
    ----------
    span : Span
        A modest span (tens of metres) so the run is fast.
    wind_speed : float
        Approximate wind speed, m/s (> 0).
    n_elements : int
        FE mesh (explicit: the default mesh is physics' business).
    bc : {"clamped", "pinned"}
        Supports.
    damper : MDR or None
        A robot/damper attached to the FE model at its position (and to the EBM).
    settle : float
        Decay times to simulate before measuring, 1-50 (default 8: transient e^-8 of the
        start); refused when the settling run would exceed 1e6 samples (a very lightly damped
        mode: a very low wind speed).
    samples_per_period : int
        Samples per vibration period, 4-1024.
    **severity_options
        Passed to :func:`aeolian_severity` (not ``dampers``).

    Returns
    -------
    TimeDomainCheck

    Raises
    ------
    InputError
        For bad arguments, or no energy balance at the locked-in wind speed.

    Examples
    --------
    >>> from powerline_control import Span
    >>> check = time_domain_check(Span.at_rts_fraction(20.0, "drake", 0.2), 2.0, n_elements=40)
    >>> check.mode > 1
    True
    """
    severity_options = check_forwarded_options(
        time_domain_check, severity_options, aeolian_severity,
        set_here=("span", "wind_speeds", "dampers"),
        why="the wind speed is 'wind_speed', the damper is 'damper'")
    span = _check_span(span)
    speed = check_real("wind_speed", wind_speed, low=0.0, high=MAX_WIND_SPEED)
    n_elements = check_int("n_elements", n_elements, low=2)
    # settle: 1-50 decay times (e^-1 .. e^-50 of the start-up left); 4-1024 samples a period
    settle = check_real("settle", settle, low=1.0, low_inclusive=True, high=50.0)
    samples = check_int("samples_per_period", samples_per_period, low=4, high=1024)
    if damper is not None:
        _check_dampers((damper,), span)
        if not isinstance(damper, MDR):
            raise InputError("The 'damper' parameter of time_domain_check must be an MDR (the "
                             f"FE model carries it). Got {type(damper).__name__}.")
    strouhal = severity_options.get("strouhal", DEFAULT_STROUHAL)
    cond = span.conductor
    target = strouhal * speed / cond.diameter
    # Two DOFs per node less at most four at the supports: checked before the model is built,
    # so that a huge mesh is refused with this function's limit (not LineModel's budget, whose
    # memory_budget argument this function does not take).
    if 2 * (n_elements + 1) - 4 > DENSE_EIGEN_LIMIT:
        raise InputError(
            f"The 'n_elements' parameter ({n_elements}) gives at least {2 * n_elements - 2} DOFs; "
            f"the time-domain check solves all modes densely and accepts up to "
            f"{DENSE_EIGEN_LIMIT} DOFs (n_elements <= {(DENSE_EIGEN_LIMIT + 2) // 2}). Use a "
            "shorter span (tens of metres) or fewer elements.")
    bare = LineModel(span, n_elements=n_elements, bc=bc)
    if bare.n_dofs > DENSE_EIGEN_LIMIT:
        raise InputError(
            f"The 'n_elements' parameter ({n_elements}) gives {bare.n_dofs} DOFs; the time-domain "
            f"check solves all modes densely and accepts up to {DENSE_EIGEN_LIMIT} DOFs. Use a "
            "shorter span (tens of metres) or fewer elements.")
    n_modes = min(bare.n_dofs, max(10, int(3 * target / span.pinned_frequencies(1)[0]) + 5))
    frequencies = bare.natural_frequencies(n_modes)
    index = int(np.argmin(np.abs(frequencies - target)))
    f = float(frequencies[index])
    modal_decay = 0.0
    if damper is not None:
        coupled = LineModel(span, n_elements=n_elements, bc=bc, mdr=damper)
        eigenvalues = np.linalg.eigvals(coupled.to_statespace(n_modes=coupled.n_dofs).A)
        eigenvalues = eigenvalues[eigenvalues.imag > 0]
        nearest = eigenvalues[np.argmin(np.abs(eigenvalues.imag / (2 * math.pi) - f))]
        f = float(nearest.imag / (2 * math.pi))
        modal_decay = float(-nearest.real / abs(nearest))
    speed = f * cond.diameter / strouhal
    dampers = () if damper is None else (damper,)
    sev = aeolian_severity(span, [speed], dampers, bc=bc, **severity_options)
    y = float(sev.amplitude[0])
    if not sev.balanced[0] or y <= 0:
        raise InputError(f"No energy balance at {speed:g} m/s ({sev.status[0]}); choose another "
                         "wind speed.")
    omega = 2 * math.pi * f
    zeta = 2 * float(sev.self_damping_power[0]) / (cond.mass_per_length * omega**3 * y**2)
    q = 4 * float(sev.wind_power[0]) / (omega * y)
    lift = q / (0.5 * AIR_DENSITY * speed**2 * cond.diameter)
    # The settling run samples 4 times a period for settle / ((zeta + decay) omega) seconds:
    # refuse here, naming this function's arguments, when that is beyond any reasonable run.
    settling_samples = 4 * settle / (2 * math.pi * (zeta + modal_decay))
    if not math.isfinite(settling_samples) or settling_samples > 1e6:
        raise InputError(
            f"The 'wind_speed' ({speed:g} m/s after lock-in, mode {index + 1}) gives a damping "
            f"ratio of {zeta + modal_decay:.3g}: 'settle' = {settle:g} decay times would take "
            f"{settling_samples:.3g} samples (at most 1e6). Choose a higher wind speed (a "
            "higher mode, more damped) or a smaller settle.")
    model = LineModel(span, n_elements=n_elements, bc=bc, damping=ModalDamping(zeta), mdr=damper)
    force = AeolianForce(wind_speed=speed, strouhal=strouhal, lift_coefficient=lift,
                         air_density=AIR_DENSITY)
    period = 1.0 / f
    # The settling run only has to carry the state forward (harmonic loads are propagated in
    # closed form, exact at any sample interval), so it samples coarsely (Nyquist 2 f); the
    # measured tail continues from its final state at the fine interval.
    settling = simulate(model, force, duration=settle / ((zeta + modal_decay) * omega),
                        dt=period / 4)
    snap = simulate(model, force, duration=4 * period, dt=period / samples,
                    initial_state=settling.final_state, start_time=float(settling.t[-1]))
    # The steady response to a sine has no mean: the fit needs no constant.
    phasors = np.abs(fit_phasors(snap.true_displacement, snap.t, f, constant=False))
    simulated = float(np.max(phasors))
    clamp_time = clamp_stress = ebm_stress = None
    if bc == "clamped":
        # A stress history for a rainflow count: the simulated antinode displacement, on a fine
        # grid continuing the same steady state, times the energy balance's clamp stress per
        # metre of antinode amplitude (sigma_a / Y: the clamped standing wave's shape at x_b
        # and Poffenberger-Swart's K). The FE mesh does not resolve the clamp's boundary layer
        # (1/alpha, a few cm), so the clamp displacement itself is not read from it.
        antinode = float(snap.x[int(np.argmax(phasors))])
        history = simulate(model, force, duration=8 * period, dt=period / 64,
                           initial_state=settling.final_state,
                           start_time=float(settling.t[-1]), outputs=[antinode])
        clamp_time = read_only(np.asarray(history.t, dtype=float))
        clamp_stress = read_only(float(sev.stress_ps[0]) / y
                                 * np.asarray(history.true_displacement[0], dtype=float))
        ebm_stress = float(sev.stress_ps[0])
    return TimeDomainCheck(wind_speed=speed, frequency=f, mode=index + 1, ebm_amplitude=y,
                           simulated_amplitude=simulated, relative_error=simulated / y - 1,
                           damping_ratio=zeta, lift_coefficient=lift, n_elements=n_elements,
                           clamp_time=clamp_time, clamp_stress=clamp_stress,
                           ebm_stress=ebm_stress)


# --------------------------------------------------------------------------- TB 273 H/w
#: CIGRE TB 273 H/w limits (m) for single undamped conductors by terrain category 1-4.
#: FROM MEMORY (domain.md 2.5 marks them so): verify against TB 273 section 4 before relying on
#: them; pass ``limit=`` with the verified value.
TB273_UNDAMPED_LIMITS_FROM_MEMORY = {1: 1000.0, 2: 1125.0, 3: 1225.0, 4: 1425.0}


@dataclass(frozen=True)
class CatenaryCheck:
    """TB 273 catenary-parameter check H / w against a limit.

    Attributes
    ----------
    catenary_parameter : float
        H / w = T / (m g), m.
    limit : float
        The limit used, m.
    within_limit : bool
        True when H / w <= limit (no damper required by this criterion).
    source : str
        Where the limit comes from (user, or TB 273 from memory, unverified).

    Examples
    --------
    >>> CatenaryCheck(1755.0, 1000.0, False, "user").within_limit
    False
    """

    catenary_parameter: float
    limit: float
    within_limit: bool
    source: str


def catenary_check(span: Span, terrain: int = 1, limit: float | None = None) -> CatenaryCheck:
    """CIGRE TB 273 H/w check of an undamped single conductor.

    Parameters
    ----------
    span : Span
        H is the span's tension, w = m g.
    terrain : int
        Terrain category 1-4 for the built-in limits (FROM MEMORY, unverified against TB 273).
    limit : float or None
        A user-supplied limit, m, which takes precedence.

    Returns
    -------
    CatenaryCheck

    Raises
    ------
    InputError
        For a terrain category other than 1-4, a bad limit, or a tension at or above the
        conductor's rated strength.

    Examples
    --------
    >>> from powerline_control import Span
    >>> check = catenary_check(Span.at_rts_fraction(300.0, "drake", 0.2))
    >>> round(check.catenary_parameter), check.within_limit
    (1755, False)
    """
    span = _check_span(span)
    h_w = span.tension / (span.conductor.mass_per_length * GRAVITY)
    if limit is not None:
        value = check_real("limit", limit, low=0.0)
        source = "user-supplied limit"
    else:
        if isinstance(terrain, bool) or not isinstance(terrain, numbers.Integral) \
                or terrain not in TB273_UNDAMPED_LIMITS_FROM_MEMORY:
            raise InputError("The 'terrain' parameter must be a TB 273 terrain category 1, 2, "
                             f"3 or 4. Got {terrain!r}.")
        value = TB273_UNDAMPED_LIMITS_FROM_MEMORY[int(terrain)]
        source = (f"CIGRE TB 273, terrain category {terrain}, undamped single conductor: value "
                  "FROM MEMORY, unverified against TB 273 section 4")
    return CatenaryCheck(catenary_parameter=h_w, limit=value, within_limit=h_w <= value,
                         source=source)
