"""Physical self-damping: Foti & Martinelli's micro-slip / gross-slip model, and the bending
stiffness and limit curvature of a stranded conductor computed from its layers of wires.

References
----------
F. Foti, L. Martinelli, "Mechanical modeling of metallic strands subjected to tension, torsion
and bending", International Journal of Solids and Structures (2016),
doi:10.1016/j.ijsolstr.2016.04.034 (the layer-by-layer stick-slip bending of a strand).

F. Foti, L. Martinelli, "An enhanced unified model for the self-damping of stranded cables under
aeolian vibrations", Journal of Wind Engineering and Industrial Aerodynamics (2018),
doi:10.1016/j.jweia.2018.09.005 (the dissipated power, its eqs. 23-30).

A. Cloutier, "Stick-slip mechanical models for overhead electrical conductors in bending"
(2013), ch. 3: the friction-limited wire forces (capstan growth, non-symmetric pressure).

The equations were learnt from rte-france/pallas-dohl (``ebp.damping_power_foti``) and
rte-france/pallas-stranded-cable (``physical_tools``); the code here is written anew, and where
it departs from those peers (the wires' angular positions, the pairing of slip curvatures with
layers) the difference is said in :func:`stranded_bending`.

Test seam: ``_stranded_bending``: compared layer by layer with the peers' stranded-bending model
(tests/test_self_damping.py).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .._validation import check_array, check_choice, check_int, check_real
from ..errors import InputError
from ..line import Conductor, Span
from ._common import _check_amplitudes, _check_frequency, _check_span, _finite_power

__all__ = [
    "STRANDINGS",
    "StrandLayer",
    "StrandedBending",
    "stranded_bending",
    "FotiMartinelli",
]

#: Wire moduli of the presets, Pa (domain.md 2.6: the values the presets' EI_min use).
_E_AL, _E_ST, _E_ALLOY = 68.9e9, 206.8e9, 68.0e9
#: Largest friction coefficient accepted: wire-on-wire friction is 0.1-1 (Foti & Martinelli use
#: about 0.7 for aluminium); 5 has no physical meaning but keeps exp(lambda pi / 2) finite.
_MAX_FRICTION = 5.0


@dataclass(frozen=True)
class StrandLayer:
    """One layer of a stranded conductor: identical round wires laid helically.

    Parameters
    ----------
    wires : int
        Number of wires (>= 1; the core is a layer of one straight wire).
    wire_diameter : float
        Wire diameter, m (> 0, < 0.05).
    modulus : float
        Young's modulus of the wires, Pa (> 0).
    lay_ratio : float or None
        Lay length divided by the layer's mean diameter (2 R + d); None only for a single
        straight core wire. EN 50182 allows about 10-14 for outer aluminium layers, 10-16 for
        inner ones and 16-26 for the 6-wire steel layer of a 1+6 core.
    material : str
        Label (``"aluminium"``, ``"steel"``, ...).

    Examples
    --------
    >>> StrandLayer(16, 4.44e-3, 68.9e9, 12.0, "aluminium").wires
    16
    """

    wires: int
    wire_diameter: float
    modulus: float
    lay_ratio: float | None = None
    material: str = ""

    def __post_init__(self) -> None:
        check_int("wires", self.wires, low=1, high=200)
        object.__setattr__(self, "wire_diameter",
                           check_real("wire_diameter", self.wire_diameter, low=0.0, high=0.05))
        object.__setattr__(self, "modulus", check_real("modulus", self.modulus, low=0.0))
        if self.lay_ratio is None:
            if self.wires != 1:
                raise InputError(f"The 'lay_ratio' of a layer of {self.wires} wires must be a "
                                 "number (lay length / layer diameter, about 10-26); only a "
                                 "single straight core wire has none.")
        else:
            object.__setattr__(self, "lay_ratio",
                               check_real("lay_ratio", self.lay_ratio, low=1.0, high=1000.0))
        if not isinstance(self.material, str):
            raise InputError(f"The 'material' parameter must be a string. Got "
                             f"{self.material!r:.60}.")


def _layers(core: tuple[int, float, float], *rest: tuple[int, float, float, float, str]):
    return (StrandLayer(core[0], core[1], core[2], None, "steel" if core[2] > 1e11 else
                        "aluminium"),) + tuple(StrandLayer(*layer) for layer in rest)


#: Layers of the conductor presets, core outward. Stranding from domain.md 2.6 and
#: data/conductors.toml; lay ratios at the middle of the EN 50182 ranges (outer aluminium 12,
#: inner aluminium and alloy 13, the 6 steel wires of a 1+6 core 21), as
#: rte-france/pallas-stranded-cable sets them by default. ASTER570 uses 68 GPa alloy wires (the
#: modulus of its preset EI_min, from RTE's data).
STRANDINGS: dict[str, tuple[StrandLayer, ...]] = {
    "drake": _layers((1, 3.45e-3, _E_ST), (6, 3.45e-3, _E_ST, 21.0, "steel"),
                     (10, 4.44e-3, _E_AL, 13.0, "aluminium"),
                     (16, 4.44e-3, _E_AL, 12.0, "aluminium")),
    "condor": _layers((1, 3.08e-3, _E_ST), (6, 3.08e-3, _E_ST, 21.0, "steel"),
                      (12, 3.08e-3, _E_AL, 13.0, "aluminium"),
                      (18, 3.08e-3, _E_AL, 13.0, "aluminium"),
                      (24, 3.08e-3, _E_AL, 12.0, "aluminium")),
    "cardinal": _layers((1, 3.38e-3, _E_ST), (6, 3.38e-3, _E_ST, 21.0, "steel"),
                        (12, 3.38e-3, _E_AL, 13.0, "aluminium"),
                        (18, 3.38e-3, _E_AL, 13.0, "aluminium"),
                        (24, 3.38e-3, _E_AL, 12.0, "aluminium")),
    "aster570": _layers((1, 3.45e-3, _E_ALLOY), *[(n, 3.45e-3, _E_ALLOY, 13.0, "alloy")
                                                  for n in (6, 12, 18, 24)]),
    "oxlip": _layers((1, 3.50e-3, _E_AL), (6, 3.50e-3, _E_AL, 12.0, "aluminium")),
}


@dataclass(frozen=True, eq=False)
class StrandedBending:
    """The stick-slip bending law of a stranded conductor at one tension.

    Each helical layer sticks (stiffness ``layer_stick_stiffness``) until its wires slip at
    ``slip_curvature``, after which it carries the constant friction moment ``slip_moment``; the
    wires' own bending (``ei_min``) always acts. The bilinear equivalent (stiffness ``ei_max`` up
    to ``limit_curvature``, ``ei_min`` beyond, the same asymptote) is the one Foti & Martinelli's
    dissipation model takes.

    Attributes
    ----------
    tension : float
        N.
    ei_min, ei_max : float
        Bending stiffness with every wire slipping and with every wire stuck, N m^2.
    layer_stick_stiffness, slip_moment, slip_curvature : ndarray
        Per helical layer (core outward): stiffness the layer adds while stuck (N m^2), its
        residual friction moment once slipping (N m), slip curvature = moment / stiffness (1/m).
    incipient_slip_curvature, full_slip_curvature : ndarray
        Per helical layer: the curvature at which the first wire (at the neutral axis) and the
        last one (at the extreme fibre) start to slip, 1/m.
    wire_force : ndarray
        Axial force in one wire of each layer (core included), N.
    limit_curvature : float
        chi_0 of the bilinear equivalent, 1/m (sum of slip moments / sum of stick stiffnesses).

    Examples
    --------
    >>> from powerline_control import conductors
    >>> law = stranded_bending(conductors["drake"], 28e3)
    >>> law.slip_curvature.shape                  # the three helical layers of 1+6+10+16
    (3,)
    >>> bool(law.ei_min < law.ei_max)
    True
    """

    tension: float
    ei_min: float
    ei_max: float
    layer_stick_stiffness: np.ndarray
    slip_moment: np.ndarray
    slip_curvature: np.ndarray
    incipient_slip_curvature: np.ndarray
    full_slip_curvature: np.ndarray
    wire_force: np.ndarray
    limit_curvature: float

    def moment(self, curvature: np.ndarray | float) -> np.ndarray:
        """Bending moment on first loading, M(chi) = EI_min chi + sum min(B_i chi, M_i), N m.

        Parameters
        ----------
        curvature : float or ndarray
            chi, 1/m (>= 0).

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from powerline_control import conductors
        >>> law = stranded_bending(conductors["aster570"], 40e3)
        >>> round(float(law.moment(1e-3)) / 1e-3, 1) == round(law.ei_max, 1)   # all stuck
        True
        """
        chi = check_array("curvature", curvature)
        if np.any(chi < 0):
            raise InputError(f"The 'curvature' parameter must be >= 0 1/m. Got "
                             f"{float(chi.min()):g}.")
        stuck = np.minimum(np.multiply.outer(chi, self.layer_stick_stiffness), self.slip_moment)
        return self.ei_min * chi + stuck.sum(axis=-1)


def _check_friction(friction: object, n_contacts: int) -> np.ndarray:
    if isinstance(friction, numbers.Real) and not isinstance(friction, bool):
        values = np.full(n_contacts, check_real("friction", friction, low=0.0,
                                                high=_MAX_FRICTION))
    else:
        values = check_array("friction", friction, ndim=1)
        if values.size != n_contacts:
            raise InputError(f"The 'friction' parameter must be one number or one per contact "
                             f"between layers ({n_contacts}). Got {values.size} values.")
    bad = values[(values <= 0) | (values > _MAX_FRICTION)]
    if bad.size:
        raise InputError(f"The 'friction' parameter (wire-on-wire friction coefficient) must be "
                         f"> 0 and <= {_MAX_FRICTION:g} (typically 0.1-1). Got {bad[0]!r}.")
    return values


def _check_layers(conductor: object, layers: object) -> tuple[StrandLayer, ...]:
    if layers is None:
        if not isinstance(conductor, Conductor):
            raise InputError(f"The 'conductor' parameter must be a Conductor. Got "
                             f"{type(conductor).__name__}.")
        if conductor.name not in STRANDINGS:
            raise InputError(f"The 'layers' parameter is needed for conductor "
                             f"{conductor.name!r}: its stranding is known only for the presets "
                             f"{sorted(STRANDINGS)}.")
        return STRANDINGS[conductor.name]
    if not isinstance(layers, Sequence) or isinstance(layers, str) or len(layers) == 0:
        raise InputError("The 'layers' parameter must be a non-empty sequence of StrandLayer "
                         f"(core outward). Got {layers!r:.60}.")
    for i, layer in enumerate(layers):
        if not isinstance(layer, StrandLayer):
            raise InputError(f"The 'layers[{i}]' parameter must be a StrandLayer. Got "
                             f"{type(layer).__name__}.")
    if layers[0].lay_ratio is not None or layers[0].wires != 1:
        raise InputError("The 'layers[0]' parameter must be the straight core: one wire, "
                         f"lay_ratio None. Got {layers[0]!r}.")
    if len(layers) < 2:
        raise InputError("The 'layers' parameter must hold the core and at least one helical "
                         "layer (a single wire has no interwire slip). Got 1 layer.")
    return tuple(layers)


def stranded_bending(conductor: Conductor | None, tension: float, *,
                     friction: float | Sequence[float] = 0.7,
                     layers: Sequence[StrandLayer] | None = None) -> StrandedBending:
    """Stick-slip bending law of a stranded conductor from its layers (Foti & Martinelli 2016).

    Geometry: layer radii R_0 = 0, R_i = R_{i-1} + (d_{i-1} + d_i) / 2; lay angle
    tan a_i = 2 pi R_i / (lay_ratio_i (2 R_i + d_i)). Stiffness: EI_min = sum n E I cos a (the
    wires bending alone, Papailiou 1997), each layer adds B_i = n E A R^2 cos^3 a / 2 while
    stuck, EI_max = EI_min + sum B_i. Tension: wire strain eps cos^2 a with
    eps = T / sum(n E A cos^3 a).

    Slip: at full slip the axial force of a wire at angle theta from the neutral axis is limited
    by friction, dF_i/dtheta = mu_i sin a_i F_i + c_i sum_{k>i} (sin^2 a_k / r_k) F_k (capstan
    growth from its own tension and the pressure of the layers above, Cloutier 2013 eq. 3.19
    with Foti & Martinelli's combination c_i = r_i / sin a_i mu_i (1 + mu_{i+1} / (mu_i +
    mu_{i+1})), r the wire radius); the system is solved exactly as F(theta) = expm(M theta)
    F_w (on the compressed side, theta < 0, the same law makes the force fall as
    exp(-lambda |theta|)). The layer's friction moment is M_i = R_i cos a_i sum over its wires
    of (F_i(theta_w) - F_w) sin theta_w, with the wires equally spaced at phases
    phi_w = 2 pi (w + 1/2) / n and theta_w = arcsin(sin phi_w) their signed angle from the nearer
    crossing of the neutral axis; its slip curvature is M_i / B_i. The bilinear equivalent (same
    initial slope, same asymptote) has chi_0 = sum M_i / sum B_i.

    rte-france/pallas-stranded-cable computes the same stiffnesses to round-off, and the same
    slip limits with three different conventions: the capstan acts on the wire force projected
    on the cable axis (F cos a, so its slip curvatures are 2-3 % lower), the wires of each half
    layer sit at pi ((2 j - 1) / n - 1/2), j = 0 .. n/2 - 1 (not symmetric about the neutral
    axis), and every layer's friction moment takes the first helical layer's cos a. With those
    three choices this computation reproduces its slip curvatures and moments to 1e-13; without
    them the limit curvature is 7.4-7.5 % higher than the peer's (Cardinal and ASTER570 at
    40 kN), and the moment follows Foti & Martinelli's published moment-curvature curve of
    Cardinal (40 kN, friction 0.7) within 4 % from 0.015 1/m on (within 2 % from 0.06), where
    the peer's is up to 6 % low.

    Parameters
    ----------
    conductor : Conductor or None
        A preset (its stranding is :data:`STRANDINGS`), or None with ``layers``.
    tension : float
        N (> 0).
    friction : float or sequence of float
        Wire-on-wire friction coefficient, one value or one per contact between layers (core
        outward); > 0 (default 0.7, Foti & Martinelli's value for aluminium).
    layers : sequence of StrandLayer or None
        The stranding, core outward; default the preset's.

    Returns
    -------
    StrandedBending

    Raises
    ------
    InputError
        For a conductor without known stranding, a friction coefficient <= 0, fewer than two
        layers, a core that is not a single straight wire.

    Examples
    --------
    >>> from powerline_control import conductors
    >>> law = stranded_bending(conductors["aster570"], 40e3)
    >>> round(law.ei_max), round(law.ei_min, 2)      # RTE's ASTER570 data: 2155 and 28.28
    (2155, 28.28)
    """
    layers = _check_layers(conductor, layers)
    tension = check_real("tension", tension, low=0.0, high=1e7)
    mu = _check_friction(friction, len(layers) - 1)
    return _stranded_bending(layers, tension, mu)


def _stranded_bending(layers: tuple[StrandLayer, ...], tension: float, mu: np.ndarray,
                      conventions: str = "physical") -> StrandedBending:
    """The computation of :func:`stranded_bending` on checked arguments.

    ``conventions="strdcable"`` reproduces rte-france/pallas-stranded-cable's three choices
    (the capstan on the wire force projected on the cable axis, F cos a; its wire angles; the
    first helical layer's cos a in every friction moment), for the comparison test only.
    """
    peer = conventions == "strdcable"
    n = np.array([layer.wires for layer in layers], dtype=float)
    d = np.array([layer.wire_diameter for layer in layers])
    e = np.array([layer.modulus for layer in layers])
    radius = np.concatenate([[0.0], np.cumsum(0.5 * (d[:-1] + d[1:]))])
    ratio = np.array([np.nan] + [layer.lay_ratio for layer in layers[1:]])
    angle = np.zeros(len(layers))
    angle[1:] = np.arctan(2 * np.pi * radius[1:] / (ratio[1:] * (2 * radius[1:] + d[1:])))
    cos, sin = np.cos(angle), np.sin(angle)
    area, inertia = np.pi * d**2 / 4, np.pi * d**4 / 64
    ei_min = float(np.sum(n * e * inertia * cos))
    stick = 0.5 * n * e * area * radius**2 * cos**3
    strain = tension / float(np.sum(n * e * area * cos**3))
    rf = e * area * cos**2                      # d(wire force) / d(cable strain along the wire)
    force = rf * strain * (cos if peer else 1.0)
    # The friction-limited wire forces of the helical layers: dF/dtheta = K F (upper triangular).
    h = len(layers) - 1
    k = np.zeros((h, h))
    for i in range(h):
        layer = i + 1
        k[i, i] = mu[i] * sin[layer]
        if layer < h:  # pressed by the layers above
            combined = mu[i] * (1 + mu[i + 1] / (mu[i] + mu[i + 1]))
            c = 0.5 * d[layer] / sin[layer] * combined
            for j in range(i + 1, h):
                k[i, j] = c * sin[j + 1] ** 2 / (0.5 * d[j + 1])
    fw = force[1:]
    denominator = rf[1:] * radius[1:]
    incipient = (k @ fw) / denominator
    full = (scipy.linalg.expm(k * np.pi / 2) @ fw - fw) / denominator
    slip_moment = np.zeros(h)
    for i in range(h):
        wires = int(n[i + 1])
        if peer:
            theta = np.pi * ((2 * np.arange(wires // 2) - 1) / wires - 0.5)
            weight, cos_i = 2.0, cos[1]
        else:
            phase = 2 * np.pi * (np.arange(wires) + 0.5) / wires
            theta = np.arcsin(np.sin(phase))  # signed angle from the nearer neutral crossing
            weight, cos_i = 1.0, cos[i + 1]
        grown = np.array([scipy.linalg.expm(k * t)[i] @ fw for t in theta]) - fw[i]
        slip_moment[i] = weight * radius[i + 1] * cos_i * float(np.sum(grown * np.sin(theta)))
    b = stick[1:]
    return StrandedBending(
        tension=tension, ei_min=ei_min, ei_max=ei_min + float(b.sum()),
        layer_stick_stiffness=_frozen(b), slip_moment=_frozen(slip_moment),
        slip_curvature=_frozen(slip_moment / b), incipient_slip_curvature=_frozen(incipient),
        full_slip_curvature=_frozen(full), wire_force=_frozen(force),
        limit_curvature=float(slip_moment.sum() / b.sum()))


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


# --------------------------------------------------------------------------- the power
@dataclass(frozen=True)
class FotiMartinelli:
    """Foti & Martinelli's (2018) physical self-damping model of a stranded conductor.

    The cross-section dissipates, per cycle of curvature amplitude chi,
    D = (EI_max / 2) chi^3 / chi_0 while the wires micro-slip (chi <= chi_0) and
    D = (EI_max / 2) chi^2 in gross slip (chi > chi_0). Along a loop of the string wavelength
    lambda = sqrt(T / m) / f the curvature amplitude is chi_m |sin(2 pi x / lambda)| with
    chi_m = 4 pi^2 Y / lambda^2, so the power per metre is (the paper's eqs. 23-30)

        P = (f EI_max / pi) [chi_m^3 / chi_0 I3(phi) + chi_m^2 I2(phi)],
        phi = arcsin(min(1, chi_0 / chi_m)),
        I3 = 2/3 - cos phi + cos^3 phi / 3,  I2 = (pi/2 - phi) / 2 + sin(2 phi) / 4.

    Below the transition amplitude Y_t = chi_0 lambda^2 / (4 pi^2) the whole loop micro-slips
    and P = 2 f EI_max chi_m^3 / (3 pi chi_0) ~ Y^3 f^7 / T^3 (at fixed chi_0); far above it
    P -> f EI_max chi_m^2 / 4 ~ Y^2 f^5 / T^2. The limit curvature grows in proportion to the
    tension (every wire force does), chi_0 = ``limit_curvature_per_tension`` T.

    Parameters
    ----------
    ei_max : float
        Bending stiffness with all wires stuck, N m^2 (> 0).
    limit_curvature_per_tension : float
        chi_0 / T, 1/(m N) (> 0). RTE's ASTER570 data (rte-france/pallas-dohl) give
        chi_0 = 0.1407 T / RTS, i.e. 0.1407 / 185.3e3.
    regime : {"full", "micro", "gross"}
        ``"full"`` (the model), or one regime's law over the whole loop (for comparison).
    name : str
        Label in results.

    Examples
    --------
    >>> from powerline_control import Span
    >>> model = FotiMartinelli(2155.0, 0.1407 / 185.3e3)
    >>> span = Span.at_rts_fraction(300.0, "aster570", 0.2)
    >>> round(float(model.power(0.01, 20.0, span)) * 1e3, 2)    # mW/m
    97.5
    >>> round(model.transition_amplitude(20.0, span) * 1e3, 1)  # mm: Y/D = 1.35, so micro-slip
    42.0
    """

    ei_max: float
    limit_curvature_per_tension: float
    regime: str = "full"
    name: str = "foti_martinelli"

    def __post_init__(self) -> None:
        object.__setattr__(self, "ei_max", check_real("ei_max", self.ei_max, low=0.0,
                                                      high=1e6))
        object.__setattr__(self, "limit_curvature_per_tension",
                           check_real("limit_curvature_per_tension",
                                      self.limit_curvature_per_tension, low=0.0, high=1.0))
        check_choice("regime", self.regime, ("full", "micro", "gross"))
        if not isinstance(self.name, str) or not self.name:
            raise InputError(f"The 'name' parameter must be a non-empty string. Got "
                             f"{self.name!r:.60}.")

    @classmethod
    def from_conductor(cls, conductor: Conductor | None = None, *,
                       friction: float | Sequence[float] = 0.7,
                       layers: Sequence[StrandLayer] | None = None,
                       regime: str = "full") -> FotiMartinelli:
        """The model of a stranded conductor from its layers (:func:`stranded_bending`).

        EI_max and chi_0 / T do not depend on the tension (elastic wires: every wire force is
        proportional to it), so one evaluation at 10 kN serves every span.

        Parameters
        ----------
        conductor : Conductor or None
            A preset with a known stranding (:data:`STRANDINGS`), or None with ``layers``.
        friction : float or sequence of float
            Wire-on-wire friction coefficient (> 0; default 0.7).
        layers : sequence of StrandLayer or None
            The stranding, core outward (default: the preset's).
        regime : {"full", "micro", "gross"}
            As in the class.

        Returns
        -------
        FotiMartinelli

        Examples
        --------
        >>> from powerline_control import conductors
        >>> model = FotiMartinelli.from_conductor(conductors["drake"])
        >>> round(model.ei_max)
        1502
        """
        law = stranded_bending(conductor, 10e3, friction=friction, layers=layers)
        label = conductor.name if isinstance(conductor, Conductor) else "custom"
        return cls(law.ei_max, law.limit_curvature / law.tension, regime=regime,
                   name=f"foti_martinelli ({label})")

    def limit_curvature(self, tension: float) -> float:
        """chi_0 at ``tension`` (N), 1/m.

        Parameters
        ----------
        tension : float
            N (> 0).

        Returns
        -------
        float

        Examples
        --------
        >>> round(FotiMartinelli(2155.0, 1e-6).limit_curvature(40e3), 6)
        0.04
        """
        return self.limit_curvature_per_tension * check_real("tension", tension, low=0.0)

    def transition_amplitude(self, frequency: float, span: Span) -> float:
        """Antinode amplitude at which the loop's peak curvature reaches chi_0, m.

        Parameters
        ----------
        frequency : float
            Hz (> 0).
        span : Span
            Tension and mass per length.

        Returns
        -------
        float
            Y_t = chi_0 T / (4 pi^2 m f^2).

        Examples
        --------
        >>> from powerline_control import Span
        >>> span = Span.at_rts_fraction(300.0, "aster570", 0.2)
        >>> round(FotiMartinelli(2155.0, 1e-6).transition_amplitude(10.0, span), 4)
        0.2214
        """
        span = _check_span(span)
        frequency = _check_frequency(frequency)
        t, m = span.tension, span.conductor.mass_per_length
        return self.limit_curvature(t) * t / (4 * math.pi**2 * m * frequency**2)

    def power(self, amplitude: np.ndarray | float, frequency: float, span: Span) -> np.ndarray:
        """Self-damping power per metre at antinode amplitude ``amplitude``, W/m.

        Parameters
        ----------
        amplitude : float or ndarray
            Y, zero-to-peak, m (>= 0).
        frequency : float
            Hz (> 0).
        span : Span
            Tension and mass per length (the string wavelength, eq. 23).

        Returns
        -------
        ndarray
            The shape of ``amplitude``.

        Examples
        --------
        >>> from powerline_control import Span
        >>> span = Span.at_rts_fraction(300.0, "aster570", 0.2)
        >>> model = FotiMartinelli(2155.0, 0.1407 / 185.3e3)
        >>> p = model.power([0.001, 0.002], 20.0, span)     # micro-slip: cubic in Y
        >>> round(float(p[1] / p[0]), 12)
        8.0
        """
        span = _check_span(span)
        frequency = _check_frequency(frequency)
        y = _check_amplitudes(amplitude)
        t, m = span.tension, span.conductor.mass_per_length
        chi0 = self.limit_curvature(t)
        chi_m = 4 * math.pi**2 * y * m * frequency**2 / t
        scale = frequency * self.ei_max / math.pi
        if self.regime == "micro":
            return _finite_power(scale * (2 / 3) * chi_m**3 / chi0, "self-damping power")
        if self.regime == "gross":
            return _finite_power(scale * (math.pi / 4) * chi_m**2, "self-damping power")
        with np.errstate(divide="ignore"):
            phi = np.arcsin(np.minimum(1.0, np.where(chi_m > 0, chi0 / np.maximum(chi_m, 1e-300),
                                                     1.0)))
        c = np.cos(phi)
        i3 = 2 / 3 - c + c**3 / 3
        i2 = (math.pi / 2 - phi) / 2 + np.sin(2 * phi) / 4
        return _finite_power(scale * (chi_m**3 / chi0 * i3 + chi_m**2 * i2),
                             "self-damping power")
