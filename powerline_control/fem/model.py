"""Galerkin finite-element model of a taut Euler-Bernoulli span, with an optional damping robot.

The span obeys ``m y_tt + c y_t + EI y'''' - T y'' = F(x, t) - (F1 + F2) delta(x - x_r)`` (the
paper's eq. 1 prints ``+ T y''``, a sign typo: with it tension would soften the line). Hermite
cubic elements carry displacement ``w`` and slope ``theta`` at each node; the mass matrix is the
consistent one, the stiffness is bending plus the tension ("geometric") stiffness. Point loads and
the robot enter through the element shape functions, so neither needs to sit on a node.

Degrees of freedom are numbered ``[w_0, theta_0, w_1, theta_1, ..., w_n, theta_n, (y_d)]``: the
optional last one is the robot's suspended mass. Supports remove ``w`` (pinned) or ``w`` and
``theta`` (clamped). Every matrix the class exposes is over the *free* DOFs.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import control as ct
import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from .._validation import (
    check_array,
    check_budget,
    check_budget_value,
    check_choice,
    check_int,
    check_real,
    read_only,
)
from ..errors import InputError, ModelError, TruncationWarning
from ..line import Span

__all__ = ["LineModel", "MDR", "ModalDamping", "RayleighDamping", "ModalBasis", "physics_mesh",
           "frequency_error_estimate", "accuracy_elements_per_loop", "aeolian_band_top"]

_BOUNDARY_CONDITIONS = ("pinned", "clamped")
#: Up to this many free DOFs the eigenproblem is solved densely (all modes, exact); above it a
#: sparse shift-invert Lanczos solve returns the lowest modes only.
DENSE_EIGEN_LIMIT = 1200

# ---- mesh from physics (docs/model.md, "Mesh from physics")
#: Leading frequency error of Hermite cubics with consistent mass, measured on the Bloch waves of a
#: uniform mesh (tests/test_fem.py checks both constants): a bending wave of wavenumber k on
#: elements of length h has omega_h / omega - 1 = (k h)^4 / 1440, a tension (string) wave
#: (k h)^6 / 60480. A taut beam mixes them in the ratio of its two stiffness terms.
BENDING_ERROR_CONSTANT = 1.0 / 1440.0
TENSION_ERROR_CONSTANT = 1.0 / 60480.0
#: Default aeolian band: wind 1-7 m/s (laminar wind; domain notes 2.1) at Strouhal 0.185.
DEFAULT_WIND_SPEEDS = (1.0, 7.0)
#: Elements per shortest loop of the default mesh for *sampling*: with 4 elements per loop every
#: antinode lies within loop / 8 of a node, so the nodal snapshots show each loop at >= 92 %
#: (cos(pi / 8)) of its peak, and antinodes and sensors can be read from nodes.
SAMPLING_ELEMENTS_PER_LOOP = 4.0
#: Below 2 elements per loop (4 nodes per wavelength) the nodes alias the loop pattern: a load at
#: such a frequency is reported as unresolved.
MIN_ELEMENTS_PER_LOOP = 2.0
#: Growth ratio of consecutive elements in the graded layer at a clamp.
GRADING_RATIO = 1.2
#: How much finer than the shortest loop the clamp's boundary layer is resolved.
BOUNDARY_LAYER_REFINEMENT = 4.0
#: Bytes per element of assembly (COO triplets and CSR copies of K and M): for budget checks.
_ASSEMBLY_BYTES_PER_ELEMENT = 2500


def accuracy_elements_per_loop(tolerance: float) -> float:
    """Elements per loop that keep the frequency error of Hermite cubics below ``tolerance``.

    From the h^4 bending error (the slower of the two): (k h)^4 / 1440 <= tolerance with
    k h = pi / N gives N = pi / (1440 tolerance)^(1/4); 1.61 elements per loop for 1 %.
    Tension-dominated (real) spans converge as h^6 and do better than this bound.

    Examples
    --------
    >>> round(accuracy_elements_per_loop(0.01), 2)
    1.61
    """
    tol = check_real("frequency_tolerance", tolerance, low=0.0, high=0.1)
    return float(np.pi / (tol / BENDING_ERROR_CONSTANT) ** 0.25)


def frequency_error_estimate(span: Span, frequency: float, element_length: float) -> float:
    """Estimated relative FE frequency error at ``frequency`` on elements of ``element_length``.

    The stiffness-weighted sum of the bending (k h)^4 / 1440 and tension (k h)^6 / 60480 errors,
    k from the dispersion relation (a leading-order estimate, accurate for k h below ~2).

    Examples
    --------
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.20)
    >>> print(f"{frequency_error_estimate(span, 20.0, 3.0):.1e}")    # 100 elements
    9.3e-03
    """
    k = span.wavenumber(frequency)
    kh = k * element_length
    bend = span.conductor.ei * k**4
    tens = span.tension * k**2
    total = bend + tens
    if total == 0:
        return 0.0
    return float((bend * BENDING_ERROR_CONSTANT * kh**4 + tens * TENSION_ERROR_CONSTANT * kh**6)
                 / total)


# The clamp error of a uniform mesh, measured (Drake at 20 % RTS, 50 m and 300 m, clamped, 20 to
# 3000 elements, against the graded physics mesh at 1e-4): every mode reads high by the same
# fraction, (h / L) g(h / delta), with g a function of the element length over the boundary
# layer delta = sqrt(EI / T) alone (the two spans agree to 0.01 in g): the first element, too
# long to bend within delta, clamps the slope over a length that grows with h.
_CLAMP_ERROR_RATIO = np.array([0.0, 2.5, 3.15, 6.3, 7.6, 12.6, 19.0, 25.0, 38.0, 63.0, 76.0, 1e9])
_CLAMP_ERROR_G = np.array([0.0, 0.0, 0.02, 0.064, 0.08, 0.12, 0.148, 0.168, 0.188, 0.208, 0.211,
                           0.22])


def clamp_error_estimate(span: Span, element_length: float, n_clamped: int = 2) -> float:
    """Relative frequency error (reading high) of a uniform mesh at ``n_clamped`` clamped ends.

    A clamp's bending boundary layer ``delta = sqrt(EI / T)`` needs elements shorter than a few
    ``delta``; longer ones stiffen every mode by about ``0.11 n_clamped h / L`` (measured; see
    the table above). Zero for a tensionless beam (no layer) or no clamp.

    Examples
    --------
    >>> drake = Span.at_rts_fraction(300.0, "drake", 0.20)
    >>> print(f"{clamp_error_estimate(drake, 15.0):.4f}")   # 20 elements: measured 0.0117
    0.0106
    >>> clamp_error_estimate(Span.paper_lab(), 0.366)        # 10 elements, h ~ delta: resolved
    0.0
    """
    if n_clamped == 0 or span.tension == 0.0:
        return 0.0
    ratio = element_length / span.boundary_layer
    g = float(np.interp(ratio, _CLAMP_ERROR_RATIO, _CLAMP_ERROR_G))
    return n_clamped / 2 * g * element_length / span.length


def aeolian_band_top(span: Span, wind_speeds=DEFAULT_WIND_SPEEDS, strouhal: float = 0.185
                     ) -> float:
    """Highest vortex-shedding frequency St V_max / d of the wind band on the span, Hz.

    Examples
    --------
    >>> round(aeolian_band_top(Span.at_rts_fraction(300.0, "drake", 0.20)), 2)
    46.02
    """
    return strouhal * max(wind_speeds) / span.conductor.diameter


def physics_mesh(span: Span, bc: tuple[str, str], max_frequency: float,
                 elements_per_loop: float) -> np.ndarray:
    """Node positions (m) resolving waves up to ``max_frequency`` Hz, graded toward clamps.

    Interior elements are at most ``loop_length(max_frequency) / elements_per_loop`` long. At a
    clamped support the bending boundary layer ``delta = sqrt(EI / T)`` is resolved like the
    shortest loop: the first element is ``delta * pi / (4 elements_per_loop)`` long (4x finer
    in k h for exp(-x / delta) than for sin(k x); :data:`BOUNDARY_LAYER_REFINEMENT`), and sizes
    grow by :data:`GRADING_RATIO` up to the interior size. Every size scales with
    1 / elements_per_loop, so refinement keeps the mesh's shape and the error falls at the
    interior rate.

    Examples
    --------
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.20)
    >>> x = physics_mesh(span, ("clamped", "clamped"), 46.0, 4.0)
    >>> x.size - 1, round(float(x[1]), 4), round(float(np.diff(x).max()), 3)
    (871, 0.0078, 0.358)
    """
    length = span.length
    # at least 4 interior elements, so a band below the first mode still gets a usable model
    interior = min(float(span.loop_length(max_frequency)) / elements_per_loop, length / 4)
    # The clamp's layer exp(-x / delta) is resolved 4x finer than the shortest loop
    # (k h = pi / (4 N)): measured, coarser first elements let the clamp's error (which converges
    # pre-asymptotically, ~h^3.3) dominate the low modes; 4x keeps it below the interior's at a
    # cost of ~8 elements per clamp.
    first = span.boundary_layer * np.pi / (BOUNDARY_LAYER_REFINEMENT * elements_per_loop)
    layers = []
    for side in bc:
        sizes: list[float] = []
        # (a string, EI = 0, has no layer: delta = 0 and no grading; a graded layer never takes
        # more than a quarter of the span)
        if side == "clamped" and 0.0 < first and first * GRADING_RATIO < interior:
            size, total = first, 0.0
            while size < interior and total + size <= length / 4:
                sizes.append(size)
                total += size
                size *= GRADING_RATIO
        layers.append(np.array(sizes))
    graded = sum(float(layer.sum()) for layer in layers)
    n_interior = max(1, int(np.ceil((length - graded) / interior)))
    widths = np.concatenate([layers[0], np.full(n_interior, (length - graded) / n_interior),
                             layers[1][::-1]])
    edges = np.concatenate([[0.0], np.cumsum(widths)])
    edges[-1] = length
    return edges


@dataclass(frozen=True)
class MDR:
    """The mobile damping robot as in the paper's eqs. (3)-(6).

    A body of mass ``body_mass`` rides the line at ``position`` (the paper's F1 = m ÿ(x_r)); a
    suspended mass ``suspended_mass`` hangs from it on a spring ``stiffness`` and a damper
    ``damping`` (F2 = k (y - y_d) + c (ẏ - ẏ_d), m_d ÿ_d = F2 ... sign as in the paper's eq. 6).

    Parameters
    ----------
    position : float
        Distance from the left support, m.
    body_mass : float
        Mass rigidly attached to the line, kg (>= 0).
    suspended_mass : float
        Tuned mass, kg (>= 0; 0 means no absorber, only the body).
    stiffness : float
        Suspension spring, N/m (> 0 when ``suspended_mass`` > 0).
    damping : float
        Suspension damper, N s/m (>= 0).

    Examples
    --------
    >>> robot = MDR.tuned(position=0.915, body_mass=0.05, suspended_mass=0.02, frequency=6.5)
    >>> round(robot.stiffness, 2)
    33.36
    """

    position: float
    body_mass: float = 0.0
    suspended_mass: float = 0.0
    stiffness: float = 0.0
    damping: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "position", check_real("position", self.position, low=0.0, low_inclusive=True)
        )
        for name in ("body_mass", "suspended_mass", "stiffness", "damping"):
            object.__setattr__(
                self, name, check_real(name, getattr(self, name), low=0.0, low_inclusive=True)
            )
        if self.suspended_mass > 0 and self.stiffness == 0:
            raise InputError(
                "The 'stiffness' parameter of MDR must be > 0 when suspended_mass > 0 "
                "(a free suspended mass has a zero-frequency rigid mode). Got 0.0."
            )

    @classmethod
    def tuned(
        cls,
        position: float,
        body_mass: float,
        suspended_mass: float,
        frequency: float,
        damping_ratio: float = 0.0,
    ) -> MDR:
        """An MDR whose suspended mass is tuned to ``frequency`` (Hz) with a damping ratio.

        Examples
        --------
        >>> round(MDR.tuned(1.0, 0.0, 0.01, frequency=10.0, damping_ratio=0.05).damping, 4)
        0.0628
        """
        omega = 2 * np.pi * check_real("frequency", frequency, low=0.0)
        ratio = check_real("damping_ratio", damping_ratio, low=0.0, low_inclusive=True)
        mass = check_real("suspended_mass", suspended_mass, low=0.0)
        if not np.isfinite(mass * omega * omega):  # frequency ~1e300 Hz: stiffness overflows
            raise InputError(f"The 'frequency' parameter ({frequency!r} Hz) makes the absorber "
                             "stiffness overflow; give the tuning frequency in Hz.")
        return cls(position, body_mass, mass, mass * omega**2, 2 * ratio * mass * omega)

    @property
    def has_absorber(self) -> bool:
        """True when the robot carries a suspended mass (an extra DOF)."""
        return self.suspended_mass > 0


@dataclass(frozen=True)
class ModalDamping:
    """The same viscous damping ratio in every mode (or one ratio per mode).

    Parameters
    ----------
    ratio : float or sequence of float
        Damping ratio zeta in [0, 1): one for all modes, or one per mode (lowest first).

    Examples
    --------
    >>> ModalDamping(0.01).ratio
    0.01
    """

    ratio: float | Sequence[float]

    def __post_init__(self) -> None:
        if np.ndim(self.ratio) == 0:
            check_real(
                "ratio", self.ratio, low=0.0, low_inclusive=True, high=1.0, high_inclusive=False
            )
        else:
            ratios = check_array("ratio", self.ratio, ndim=1)
            if np.any(ratios < 0) or np.any(ratios >= 1):
                raise InputError(
                    "Every entry of 'ratio' must lie in [0, 1). Got "
                    f"min {ratios.min():g}, max {ratios.max():g}."
                )
            object.__setattr__(self, "ratio", tuple(float(r) for r in ratios))

    def ratios(self, n_modes: int) -> np.ndarray:
        """Damping ratio of each of the first ``n_modes`` modes."""
        if np.ndim(self.ratio) == 0:
            return np.full(n_modes, float(self.ratio))
        ratios = np.asarray(self.ratio, dtype=float)
        if ratios.size < n_modes:
            raise InputError(
                f"ModalDamping has {ratios.size} ratios but {n_modes} modes are "
                "used; give one ratio per mode or a single ratio."
            )
        return ratios[:n_modes]


@dataclass(frozen=True)
class RayleighDamping:
    """Rayleigh damping C = mass_coefficient M + stiffness_coefficient K.

    Parameters
    ----------
    mass_coefficient : float
        Coefficient of M, 1/s (>= 0).
    stiffness_coefficient : float
        Coefficient of K, s (>= 0).

    Examples
    --------
    >>> d = RayleighDamping.from_ratios((5.0, 50.0), 0.01)
    >>> bool(d.mass_coefficient > 0 and d.stiffness_coefficient > 0)
    True
    """

    mass_coefficient: float = 0.0
    stiffness_coefficient: float = 0.0

    def __post_init__(self) -> None:
        check_real("mass_coefficient", self.mass_coefficient, low=0.0, low_inclusive=True)
        check_real("stiffness_coefficient", self.stiffness_coefficient, low=0.0, low_inclusive=True)

    @classmethod
    def from_ratios(cls, frequencies: tuple[float, float], ratio: float) -> RayleighDamping:
        """Coefficients giving damping ratio ``ratio`` at two frequencies (Hz)."""
        f1, f2 = (check_real("frequencies", f, low=0.0) for f in frequencies)
        zeta = check_real("ratio", ratio, low=0.0, low_inclusive=True)
        w1, w2 = 2 * np.pi * f1, 2 * np.pi * f2
        return cls(2 * zeta * w1 * w2 / (w1 + w2), 2 * zeta / (w1 + w2))


@dataclass(frozen=True)
class ModalBasis:
    """The lowest undamped modes of a :class:`LineModel`.

    Attributes
    ----------
    omega : ndarray, shape (r,)
        Natural angular frequencies, rad/s, ascending.
    shapes : ndarray, shape (n_free, r)
        Mode shapes over the free DOFs, mass-normalised (shapes.T M shapes = I).
    damping : ndarray, shape (r, r)
        Modal damping matrix shapes.T C shapes (diagonal unless the robot's damper makes the
        damping non-proportional).

    Examples
    --------
    >>> from powerline_control import Span, LineModel
    >>> basis = LineModel(Span.paper_lab(), n_elements=20).modes(2)
    >>> basis.shapes.shape, basis.n_modes
    ((40, 2), 2)
    """

    omega: np.ndarray
    shapes: np.ndarray
    damping: np.ndarray

    @property
    def frequencies(self) -> np.ndarray:
        """Natural frequencies, Hz."""
        return self.omega / (2 * np.pi)

    @property
    def n_modes(self) -> int:
        """Number of modes kept."""
        return self.omega.size


def _hermite(xi: np.ndarray, h: float | np.ndarray) -> np.ndarray:
    """Hermite cubic shape functions N1..N4 at local coordinates xi in [0, 1], shape (..., 4).

    ``h`` (element length) broadcasts against ``xi``.
    """
    xi, h = np.broadcast_arrays(np.asarray(xi, dtype=float), np.asarray(h, dtype=float))
    return np.stack(
        [
            1 - 3 * xi**2 + 2 * xi**3,
            h * (xi - 2 * xi**2 + xi**3),
            3 * xi**2 - 2 * xi**3,
            h * (-(xi**2) + xi**3),
        ],
        axis=-1,
    )


def _element_matrices(h: np.ndarray, ei: float, tension: float, mass: float):
    """Stiffness (bending + tension) and consistent mass of elements of lengths ``h``.

    DOFs [w1 t1 w2 t2]; returns two arrays of shape (n_elements, 4, 4).
    """
    h = np.asarray(h, dtype=float)[:, None, None]
    one = np.ones_like(h)

    def pattern(rows):
        return np.block([[entry for entry in row] for row in rows])

    k_bend = ei / h**3 * pattern([
        [12 * one, 6 * h, -12 * one, 6 * h],
        [6 * h, 4 * h**2, -6 * h, 2 * h**2],
        [-12 * one, -6 * h, 12 * one, -6 * h],
        [6 * h, 2 * h**2, -6 * h, 4 * h**2],
    ])
    k_tens = tension / (30 * h) * pattern([
        [36 * one, 3 * h, -36 * one, 3 * h],
        [3 * h, 4 * h**2, -3 * h, -(h**2)],
        [-36 * one, -3 * h, 36 * one, -3 * h],
        [3 * h, -(h**2), -3 * h, 4 * h**2],
    ])
    m_cons = mass * h / 420 * pattern([
        [156 * one, 22 * h, 54 * one, -13 * h],
        [22 * h, 4 * h**2, 13 * h, -3 * h**2],
        [54 * one, 13 * h, 156 * one, -22 * h],
        [-13 * h, -3 * h**2, -22 * h, 4 * h**2],
    ])
    return k_bend + k_tens, m_cons


def _parse_bc(bc: object) -> tuple[str, str]:
    if isinstance(bc, str):
        check_choice("bc", bc, _BOUNDARY_CONDITIONS)
        return bc, bc
    if isinstance(bc, tuple | list) and len(bc) == 2:
        return (
            check_choice("bc[0] (left support)", bc[0], _BOUNDARY_CONDITIONS),
            check_choice("bc[1] (right support)", bc[1], _BOUNDARY_CONDITIONS),
        )
    raise InputError(
        "The 'bc' parameter must be 'pinned', 'clamped' or a (left, right) pair of "
        f"them. Got {bc!r} instead."
    )


class LineModel:
    """Galerkin finite-element model of a span (Hermite cubic elements, sparse matrices).

    Parameters
    ----------
    span : Span
        Length, tension and conductor.
    n_elements : int or None
        None (default): the mesh comes from the physics (:func:`physics_mesh`): it resolves the
        aeolian band of the span (wind ``wind_speeds`` at Strouhal ``strouhal``, or waves up to
        ``max_frequency``) with ``elements_per_loop`` elements per shortest loop, graded toward
        clamped supports over the boundary layer sqrt(EI / T); nodes are then NOT uniform. An
        integer gives that many equal elements.
    bc : {"pinned", "clamped"} or (left, right)
        Support conditions.
    damping : None, ModalDamping or RayleighDamping
        Structural damping; none by default, as in the paper.
    mdr : MDR or None
        The damping robot, attached at any position through the shape functions.
    max_frequency : float or None
        Highest frequency (Hz) the mesh must resolve; default: the top of the aeolian band.
    wind_speeds : (float, float) or None
        Wind band, m/s (default (1, 7)); sets the band top St V_max / d.
    strouhal : float or None
        Strouhal number (default 0.185).
    elements_per_loop : float or None
        Elements per shortest loop; default the larger of the accuracy bound
        (:func:`accuracy_elements_per_loop`, 1.6 for 1 %) and
        :data:`SAMPLING_ELEMENTS_PER_LOOP` (4).
    frequency_tolerance : float
        Relative frequency accuracy the mesh must reach up to the band top (default 0.01).
    memory_budget : float or None
        Bytes the assembly may use (default ``_validation.MEMORY_BUDGET_BYTES``).

    Attributes
    ----------
    span, n_elements, bc, damping, mdr
        The parameters above (``bc`` as a (left, right) pair).
    node_positions : ndarray, shape (n_nodes,)
        Node coordinates, m (use these; never j * L / n_elements).
    element_lengths : ndarray, shape (n_elements,)
        Length of each element, m.
    max_frequency : float
        The band top the mesh was designed for (or checked against), Hz.
    mass_matrix, stiffness_matrix, damper_matrix : scipy.sparse.csr_array
        M, K and the discrete dampers' C (the robot's) over the free DOFs.

    Warns
    -----
    TruncationWarning
        When ``n_elements`` is given together with a band (``max_frequency`` or
        ``wind_speeds``) that the mesh does not resolve.

    Examples
    --------
    >>> from powerline_control import Span
    >>> model = LineModel(Span.paper_lab(), n_elements=20)
    >>> model.n_nodes, model.n_dofs
    (21, 40)
    >>> model.natural_frequencies(3).round(2)
    array([ 6.53, 14.39, 24.53])
    >>> LineModel(Span.at_rts_fraction(300.0, "drake", 0.20)).n_elements    # physics mesh
    839
    """

    def __init__(
        self,
        span: Span,
        n_elements: int | None = None,
        bc: object = "pinned",
        damping: ModalDamping | RayleighDamping | None = None,
        mdr: MDR | None = None,
        *,
        max_frequency: float | None = None,
        wind_speeds: tuple[float, float] | None = None,
        strouhal: float | None = None,
        elements_per_loop: float | None = None,
        frequency_tolerance: float = 0.01,
        memory_budget: float | None = None,
    ):
        memory_budget = check_budget_value("memory_budget", memory_budget)  # a guard: first
        if not isinstance(span, Span):
            raise InputError(f"The 'span' parameter must be a Span. Got {type(span).__name__}.")
        self.span = span
        self.bc = _parse_bc(bc)
        if damping is not None and not isinstance(damping, ModalDamping | RayleighDamping):
            raise InputError(
                "The 'damping' parameter must be None, ModalDamping or "
                f"RayleighDamping. Got {type(damping).__name__}."
            )
        self.damping = damping
        self.frequency_tolerance = check_real(
            "frequency_tolerance", frequency_tolerance, low=0.0, high=0.1
        )
        band_given = max_frequency is not None or wind_speeds is not None
        self.max_frequency = self._band_top(max_frequency, wind_speeds, strouhal)
        if elements_per_loop is None:
            per_loop = max(accuracy_elements_per_loop(self.frequency_tolerance),
                           SAMPLING_ELEMENTS_PER_LOOP)
        else:
            per_loop = check_real("elements_per_loop", elements_per_loop, low=0.5, high=1e4)
        if n_elements is None:
            # Budget first: the mesh is built from the band, so a huge band is refused before
            # any array of that size exists.
            estimate = span.length / (float(span.loop_length(self.max_frequency)) / per_loop)
            check_budget("The physics mesh", nbytes=estimate * _ASSEMBLY_BYTES_PER_ELEMENT,
                         parameter="max_frequency", value=self.max_frequency,
                         fix="lower max_frequency or the wind band, or give n_elements",
                         memory_budget=memory_budget)
            self.node_positions = read_only(
                physics_mesh(span, self.bc, self.max_frequency, per_loop))
            self.n_elements = self.node_positions.size - 1
        else:
            self.n_elements = check_int("n_elements", n_elements, low=1)
            check_budget("Assembling the line model",
                         nbytes=self.n_elements * _ASSEMBLY_BYTES_PER_ELEMENT,
                         parameter="n_elements", value=self.n_elements,
                         fix="use fewer elements (n_elements=None picks what the band needs)",
                         memory_budget=memory_budget)
            self.node_positions = read_only(np.linspace(0.0, span.length, self.n_elements + 1))
        if n_elements is None:
            self.element_lengths = read_only(np.diff(self.node_positions))
        else:
            # exactly L / n (np.diff of the nodes differs in the last bit from element to element)
            uniform = np.full(self.n_elements, span.length / self.n_elements)
            self.element_lengths = read_only(uniform)
        if mdr is not None:
            if not isinstance(mdr, MDR):
                raise InputError(f"The 'mdr' parameter must be an MDR. Got {type(mdr).__name__}.")
            self._check_position("mdr.position", mdr.position)
        self.mdr = mdr
        self._n_line_dofs = 2 * (self.n_elements + 1)
        self._free = self._free_dofs()
        # global DOF -> free index (-1 where a support removes it): O(1) shape rows.
        self._free_index = np.full(self._n_total, -1, dtype=np.int64)
        self._free_index[self._free] = np.arange(self._free.size)
        self._modes_cache: dict[int, ModalBasis] = {}
        self._factor_cache: dict[float, object] = {}
        if self._free.size == 0:
            raise InputError(
                f"The 'n_elements' parameter must be >= 2 for supports {self.bc}: "
                f"{self.n_elements} element(s) leave no free degree of freedom."
            )
        self.mass_matrix, self.stiffness_matrix, self.damper_matrix = self._assemble()
        n_clamped = sum(side == "clamped" for side in self.bc)
        clamp_error = (clamp_error_estimate(span, self.element_length, n_clamped)
                       if n_elements is not None else 0.0)
        if clamp_error > self.frequency_tolerance:
            warnings.warn(
                f"The uniform mesh of 'n_elements'={self.n_elements} does not resolve the "
                f"bending boundary layer at the clamp (sqrt(EI/T) = {span.boundary_layer:.3g} m, "
                f"elements {self.element_length:.3g} m): frequencies and responses read about "
                f"{100 * clamp_error:.2g} % high, over frequency_tolerance="
                f"{self.frequency_tolerance:g}. Use n_elements=None (a mesh graded toward the "
                "clamps) or more elements.",
                TruncationWarning,
                stacklevel=2,
            )
        if n_elements is not None and band_given and not self.resolves(self.max_frequency):
            needed = LineModel._needed_elements(span, self.max_frequency, per_loop)
            warnings.warn(
                f"The mesh of 'n_elements'={self.n_elements} does not resolve the requested band "
                f"up to {self.max_frequency:.4g} Hz (loop "
                f"{span.loop_length(self.max_frequency):.3g} m, elements up to "
                f"{self.element_length:.3g} m; it resolves up to "
                f"{self.max_resolved_frequency:.4g} Hz). Use about {needed} elements or "
                "n_elements=None.",
                TruncationWarning,
                stacklevel=2,
            )

    def with_robot(self, mdr: MDR | None) -> LineModel:
        """The same line (mesh, supports, damping) with ``mdr`` attached instead (None: bare).

        Parameters
        ----------
        mdr : MDR or None
            The robot, at ``mdr.position``, or None for the bare line.

        Returns
        -------
        LineModel
            A new model; this one is unchanged.

        Examples
        --------
        >>> from powerline_control import Span
        >>> model = LineModel(Span.paper_lab(), n_elements=20)
        >>> loaded = model.with_robot(MDR(position=1.2, body_mass=0.05))
        >>> loaded.mdr.position, model.mdr is None, loaded.n_nodes == model.n_nodes
        (1.2, True, True)
        """
        if mdr is not None:
            if not isinstance(mdr, MDR):
                raise InputError(f"The 'mdr' parameter must be an MDR. Got {type(mdr).__name__}.")
            self._check_position("mdr.position", mdr.position)
        other = copy.copy(self)
        other.mdr = mdr
        # the absorber adds a DOF: the free set, its index and every cache are the new model's
        other._free = other._free_dofs()
        other._free_index = np.full(other._n_total, -1, dtype=np.int64)
        other._free_index[other._free] = np.arange(other._free.size)
        other._modes_cache, other._factor_cache = {}, {}
        other.mass_matrix, other.stiffness_matrix, other.damper_matrix = other._assemble()
        return other

    def _band_top(self, max_frequency, wind_speeds, strouhal) -> float:
        if max_frequency is not None:
            if wind_speeds is not None or strouhal is not None:
                raise InputError(
                    "Give either 'max_frequency' or the wind band ('wind_speeds', 'strouhal'), "
                    "not both."
                )
            return check_real("max_frequency", max_frequency, low=0.0, high=1e6)
        speeds = DEFAULT_WIND_SPEEDS if wind_speeds is None else wind_speeds
        if isinstance(speeds, str) or np.ndim(speeds) != 1 or len(speeds) != 2:
            raise InputError(
                "The 'wind_speeds' parameter must be a (low, high) pair of wind speeds in m/s. "
                f"Got {speeds!r}."
            )
        low = check_real("wind_speeds[0]", speeds[0], low=0.0)
        high = check_real("wind_speeds[1]", speeds[1], low=low, low_inclusive=True, high=100.0)
        st = check_real("strouhal", 0.185 if strouhal is None else strouhal, low=0.0, high=1.0)
        return aeolian_band_top(self.span, (low, high), st)

    @staticmethod
    def _needed_elements(span: Span, frequency: float, per_loop: float) -> int:
        return int(np.ceil(span.length * per_loop / float(span.loop_length(frequency))))

    # ------------------------------------------------------------------ sizes and DOF maps
    @property
    def n_nodes(self) -> int:
        """Number of nodes, ``n_elements + 1`` (supports included)."""
        return self.n_elements + 1

    @property
    def n_dofs(self) -> int:
        """Number of free DOFs (line DOFs after supports, plus the suspended mass if any)."""
        return self._free.size

    @property
    def span_weights(self) -> np.ndarray:
        """Trapezoid weights of the nodes, summing to 1: ``span_weights @ f`` is the
        length-weighted mean over the span of nodal values ``f`` (graded meshes included), so
        ``sqrt(span_weights @ y**2)`` is the span RMS of a displacement ``y``.

        Examples
        --------
        >>> from powerline_control import Span
        >>> LineModel(Span.paper_lab(), n_elements=4).span_weights
        array([0.125, 0.25 , 0.25 , 0.25 , 0.125])
        """
        x = self.node_positions
        weights = np.zeros_like(x)
        weights[1:] += 0.5 * np.diff(x)
        weights[:-1] += 0.5 * np.diff(x)
        return read_only(weights / weights.sum())

    @property
    def element_length(self) -> float:
        """Length of the longest element, m (all of them on a uniform mesh)."""
        return float(self.element_lengths.max())

    @property
    def _n_total(self) -> int:
        """All DOFs before supports are applied: the line's plus the absorber's."""
        return self._n_line_dofs + (1 if self.mdr is not None and self.mdr.has_absorber else 0)

    def _free_dofs(self) -> np.ndarray:
        n_total = self._n_total
        fixed = set()
        for side, node in zip(self.bc, (0, self.n_elements), strict=True):
            fixed.add(2 * node)
            if side == "clamped":
                fixed.add(2 * node + 1)
        return np.array([d for d in range(n_total) if d not in fixed], dtype=np.int64)

    def _check_position(self, name: str, position: object) -> float:
        return check_real(name, position, low=0.0, low_inclusive=True, high=self.span.length)

    # ------------------------------------------------------------------ mesh resolution
    def frequency_error(self, frequency: float) -> float:
        """Estimated relative error of the model's frequencies near ``frequency`` Hz.

        :func:`frequency_error_estimate` on the longest element (the interior of a graded mesh).

        Examples
        --------
        >>> from powerline_control import Span
        >>> print(f"{LineModel(Span.paper_lab(), 20).frequency_error(24.5):.0e}")
        1e-05
        """
        f = check_real("frequency", frequency, low=0.0, low_inclusive=True)
        return frequency_error_estimate(self.span, f, self.element_length)

    def resolves(self, frequency: float) -> bool:
        """True when the mesh resolves waves at ``frequency`` Hz.

        Resolved means at least :data:`MIN_ELEMENTS_PER_LOOP` elements per loop (so nodes do not
        alias the loop pattern) and an estimated frequency error within
        ``frequency_tolerance``.

        Examples
        --------
        >>> from powerline_control import Span
        >>> drake = Span.at_rts_fraction(300.0, "drake", 0.20)
        >>> LineModel(drake, 100).resolves(19.7), LineModel(drake).resolves(19.7)
        (False, True)
        """
        f = check_real("frequency", frequency, low=0.0, low_inclusive=True)
        if f == 0.0:
            return True
        per_loop = float(self.span.loop_length(f)) / self.element_length
        return bool(per_loop >= MIN_ELEMENTS_PER_LOOP
                    and self.frequency_error(f) <= self.frequency_tolerance)

    @property
    def max_resolved_frequency(self) -> float:
        """Highest frequency (Hz) the mesh resolves in the sense of :meth:`resolves`."""
        h = self.element_length
        k_hi = np.pi / (MIN_ELEMENTS_PER_LOOP * h)
        f_hi = float(self.span.frequency_of_wavenumber(k_hi))
        if self.frequency_error(f_hi) <= self.frequency_tolerance:
            return f_hi
        lo, hi = 0.0, f_hi
        for _ in range(60):   # bisection: the error estimate grows monotonically with f
            mid = 0.5 * (lo + hi)
            ok = self.frequency_error(mid) <= self.frequency_tolerance
            lo, hi = (mid, hi) if ok else (lo, mid)
        return lo

    def check_resolution(self, frequency: float, what: str = "load") -> bool:
        """Warn (TruncationWarning) when the mesh does not resolve ``frequency``; return resolves.

        For the CLI and :func:`~powerline_control.simulate.simulate`: the message names the
        frequency, the loop length, the element length and the element count that would work.

        Examples
        --------
        >>> from powerline_control import Span
        >>> LineModel(Span.paper_lab(), 20).check_resolution(24.5)
        True
        """
        if self.resolves(frequency):
            return True
        per_loop = max(accuracy_elements_per_loop(self.frequency_tolerance), MIN_ELEMENTS_PER_LOOP)
        needed = self._needed_elements(self.span, frequency, per_loop)
        warnings.warn(
            f"The {what} at {frequency:.4g} Hz has loops {self.span.loop_length(frequency):.3g} m"
            f" long, not resolved by elements up to {self.element_length:.3g} m (the mesh "
            f"resolves up to {self.max_resolved_frequency:.4g} Hz): use at least {needed} "
            "elements ('n_elements'), or n_elements=None with max_frequency.",
            TruncationWarning,
            stacklevel=3,
        )
        return False

    # ------------------------------------------------------------------ shape functions
    def _element_of(self, x: float) -> int:
        """Index of the element containing ``x`` (the last one for x = L)."""
        element = int(np.searchsorted(self.node_positions, x, side="right")) - 1
        return min(max(element, 0), self.n_elements - 1)

    def _line_entries(self, x: float) -> tuple[np.ndarray, np.ndarray]:
        """Global line DOFs and Hermite values of the displacement at ``x`` (4 entries)."""
        element = self._element_of(x)
        h = self.element_lengths[element]
        xi = (x - self.node_positions[element]) / h
        return 2 * element + np.arange(4), _hermite(np.array(xi), h)

    def shape_entries(self, position: float) -> tuple[np.ndarray, np.ndarray]:
        """Sparse interpolation row: (free-DOF indices, weights) of the displacement at position.

        At most 4 entries: what couples a point (robot, sensor, load) to the line at O(1) cost
        on any mesh, ``row @ u == weights @ u[indices]``.

        Examples
        --------
        >>> from powerline_control import Span
        >>> model = LineModel(Span.paper_lab(), n_elements=4)
        >>> idx, w = model.shape_entries(model.node_positions[1])
        >>> idx.tolist(), w.round(12).tolist()      # w_1, theta_1, w_2, theta_2
        ([1, 2, 3, 4], [1.0, 0.0, 0.0, 0.0])
        """
        x = self._check_position("position", position)
        dofs, values = self._line_entries(x)
        index = self._free_index[dofs]
        keep = index >= 0
        return index[keep], values[keep]

    def shape_vector(self, position: float) -> np.ndarray:
        """Interpolation row: displacement at ``position`` = row @ (free DOFs), shape (n_dofs,).

        Builds one dense vector with at most 4 non-zeros (see :meth:`shape_entries` for the
        sparse form).

        Examples
        --------
        >>> from powerline_control import Span
        >>> model = LineModel(Span.paper_lab(), n_elements=4)
        >>> model.shape_vector(model.node_positions[1])[:3]   # free DOFs: theta_0, w_1, theta_1
        array([0., 1., 0.])
        """
        index, values = self.shape_entries(position)
        row = np.zeros(self.n_dofs)
        row[index] = values
        return row

    def displacement_map(
        self, positions: Sequence[float] | np.ndarray | None = None
    ) -> sp.csr_array:
        """Sparse map from free DOFs to displacement at ``positions`` (default: every node).

        Rows of constrained support nodes are zero. Shape (n_positions, n_dofs).

        Examples
        --------
        >>> from powerline_control import Span
        >>> LineModel(Span.paper_lab(), n_elements=20).displacement_map().shape
        (21, 40)
        """
        if positions is None:
            # Node j's displacement is the global DOF 2j; constrained ones give empty rows.
            cols = self._free_index[2 * np.arange(self.n_nodes)]
            rows = np.flatnonzero(cols >= 0)
            return sp.csr_array(
                (np.ones(rows.size), (rows, cols[rows])), shape=(self.n_nodes, self.n_dofs)
            )
        positions = check_array("positions", positions, ndim=1)
        rows, cols, vals = [], [], []
        for i, x in enumerate(positions):
            index, values = self.shape_entries(x)
            rows.append(np.full(index.size, i))
            cols.append(index)
            vals.append(values)
        if not positions.size:
            return sp.csr_array((0, self.n_dofs))
        return sp.csr_array(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(positions.size, self.n_dofs),
        )

    def point_load(self, position: float) -> np.ndarray:
        """Consistent load vector of a unit point force at ``position``, shape (n_dofs,)."""
        return self.shape_vector(position)

    def distributed_load(self, load_per_length: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Consistent load vector of a distributed load q(x) (N/m), by 4-point Gauss quadrature.

        Examples
        --------
        >>> from powerline_control import Span
        >>> model = LineModel(Span.paper_lab(), n_elements=10)
        >>> # A uniform 1 N/m load: the w entries sum to the total load on the free nodes.
        >>> bool(abs(model.distributed_load(lambda x: np.ones_like(x)).sum()) > 0)
        True
        """
        gauss_x, gauss_w = np.polynomial.legendre.leggauss(4)
        xi = (gauss_x + 1) / 2
        h = self.element_lengths[:, None]                      # (n_el, 1)
        x = self.node_positions[:-1, None] + h * xi[None, :]  # (n_el, 4)
        q = check_array("load_per_length(x)", np.broadcast_to(
            np.asarray(load_per_length(x), dtype=float), x.shape))
        shapes = _hermite(xi[None, :], h)                      # (n_el, 4 points, 4 functions)
        element_loads = np.einsum("eg,egk,eg->ek", q, shapes, gauss_w[None, :] * h / 2)
        full = np.zeros(self._n_total)
        for k in range(4):
            np.add.at(full, 2 * np.arange(self.n_elements) + k, element_loads[:, k])
        return full[self._free]

    # ------------------------------------------------------------------ assembly
    def _assemble(self) -> tuple[sp.csr_array, sp.csr_array, sp.csr_array]:
        cond = self.span.conductor
        k_e, m_e = _element_matrices(
            self.element_lengths, cond.ei, self.span.tension, cond.mass_per_length
        )
        dofs = 2 * np.arange(self.n_elements)[:, None] + np.arange(4)[None, :]  # (n_el, 4)
        rows = np.repeat(dofs, 4, axis=1).ravel()
        cols = np.tile(dofs, (1, 4)).ravel()
        n_total = self._n_total
        stiffness = sp.coo_array((k_e.ravel(), (rows, cols)), shape=(n_total, n_total)).tocsr()
        mass = sp.coo_array((m_e.ravel(), (rows, cols)), shape=(n_total, n_total)).tocsr()
        damper = sp.csr_array((n_total, n_total))
        if self.mdr is not None:
            mass, stiffness, damper = self._attach_mdr(mass, stiffness, damper, n_total)
        free = self._free
        return (
            mass[free][:, free].tocsr(),
            stiffness[free][:, free].tocsr(),
            damper[free][:, free].tocsr(),
        )

    def _attach_mdr(self, mass, stiffness, damper, n_total):
        """Body mass m_r N N^T on the line; spring and damper k, c [[N N^T, -N], [-N^T, 1]].

        All sparse (at most 5 x 5 non-zeros), so a robot costs nothing on a large mesh.
        """
        robot = self.mdr
        dofs, values = self._line_entries(robot.position)

        def outer(index, vals):
            return sp.coo_array(
                (np.outer(vals, vals).ravel(), (np.repeat(index, index.size),
                                                np.tile(index, index.size))),
                shape=(n_total, n_total),
            ).tocsr()

        mass = mass + robot.body_mass * outer(dofs, values)
        if robot.has_absorber:
            # relative displacement y(x_r) - y_d
            index = np.append(dofs, n_total - 1)
            coupling = outer(index, np.append(values, -1.0))
            stiffness = stiffness + robot.stiffness * coupling
            damper = damper + robot.damping * coupling
            mass = mass + sp.coo_array(([robot.suspended_mass], ([n_total - 1], [n_total - 1])),
                                       shape=(n_total, n_total)).tocsr()
        return mass, stiffness, damper

    # ------------------------------------------------------------------ static / dynamic solves
    def solve_flexibility(self, load: np.ndarray, frequency: float = 0.0) -> np.ndarray:
        """(K - omega^2 M)^-1 load over the free DOFs, by a cached sparse LU factorisation.

        ``frequency`` 0 gives the static deflection K^-1 load (the mode-acceleration correction
        of :func:`~powerline_control.simulate.simulate` uses both).

        Examples
        --------
        >>> from powerline_control import Span
        >>> model = LineModel(Span.paper_lab(), n_elements=20)
        >>> u = model.solve_flexibility(model.point_load(1.83))
        >>> bool(np.allclose(model.stiffness_matrix @ u, model.point_load(1.83)))
        True
        """
        f = check_real("frequency", frequency, low=0.0, low_inclusive=True)
        load = check_array("load", load, shape=(self.n_dofs,))
        if f not in self._factor_cache:
            if len(self._factor_cache) > 8:
                self._factor_cache.clear()
            matrix = self.stiffness_matrix - (2 * np.pi * f) ** 2 * self.mass_matrix
            try:
                self._factor_cache[f] = spla.splu(sp.csc_matrix(matrix))
            except RuntimeError as exc:  # exactly singular: the frequency is an FE eigenvalue
                raise ModelError(
                    f"K - omega^2 M is singular at {f:g} Hz (a natural frequency of the model); "
                    "shift the frequency slightly."
                ) from exc
        solution = self._factor_cache[f].solve(load)
        if not np.all(np.isfinite(solution)):
            raise ModelError(f"The flexibility solve at {f:g} Hz is not finite (singular K).")
        return solution

    def residual_response(self, load: np.ndarray, shapes: np.ndarray, omega: np.ndarray,
                          frequency: float = 0.0) -> np.ndarray:
        """Response to ``load`` at ``frequency`` Hz of every mode except ``shapes``.

        Mode acceleration (residual flexibility): ``(K - w^2 M)^-1 load - sum_k phi_k phi_k^T
        load / (omega_k^2 - w^2)`` over the given mass-normalised modes, exact for the undamped
        modes left out. ``frequency`` 0 gives the static residual, right only for modes left
        out that lie far *above* the load; modes left out *below* a sine respond with
        ``1 / (omega_k^2 - w^2) < 0``, which only the dynamic form gives.

        Parameters
        ----------
        load : ndarray, shape (n_dofs,)
            Load over the free DOFs (per unit time factor).
        shapes : ndarray, shape (n_dofs, r)
            The mass-normalised modes accounted for elsewhere (any subset of the model's).
        omega : ndarray, shape (r,)
            Their natural frequencies, rad/s.
        frequency : float
            Load frequency, Hz (not a frequency of ``shapes``).

        Returns
        -------
        ndarray, shape (n_dofs,)

        Examples
        --------
        >>> from powerline_control import Span
        >>> model = LineModel(Span.paper_lab(), n_elements=20)
        >>> basis = model.modes(40)              # every mode: nothing is left out
        >>> load = model.point_load(1.1)
        >>> r = model.residual_response(load, basis.shapes, basis.omega, 9.0)
        >>> bool(np.abs(r).max() < 1e-9 * np.abs(model.solve_flexibility(load)).max())
        True
        """
        full = self.solve_flexibility(load, frequency)
        gaps = np.asarray(omega, dtype=float) ** 2 - (2 * np.pi * float(frequency)) ** 2
        return full - shapes @ ((shapes.T @ load) / gaps)

    # ------------------------------------------------------------------ modal analysis
    def modes(self, n_modes: int | None = None) -> ModalBasis:
        """The lowest ``n_modes`` undamped modes (all modes if None and the model is small).

        Dense ``scipy.linalg.eigh`` up to :data:`DENSE_EIGEN_LIMIT` free DOFs; above it a sparse
        shift-invert Lanczos solve (``eigsh`` with sigma = 0: K is positive definite for a span
        with tension or bending stiffness and at least one support).

        Returns
        -------
        ModalBasis

        Raises
        ------
        InputError
            If ``n_modes`` is not an integer in [1, n_dofs], or None on a large model.
        ModelError
            If the eigen-solve fails.

        Examples
        --------
        >>> from powerline_control import Span
        >>> basis = LineModel(Span.paper_lab(), n_elements=20).modes(3)
        >>> basis.frequencies.round(2)
        array([ 6.53, 14.39, 24.53])
        """
        n = self.n_dofs
        if n_modes is None:
            if n > DENSE_EIGEN_LIMIT:
                raise InputError(
                    f"The 'n_modes' parameter is required for a model with {n} "
                    f"DOFs (> {DENSE_EIGEN_LIMIT}); ask for the modes you need."
                )
            n_modes = n
        n_modes = check_int("n_modes", n_modes, low=1, high=n)
        dense = n <= DENSE_EIGEN_LIMIT or n_modes >= n - 1
        # Dense: K, M and the eigenvectors as n x n; sparse: the Lanczos basis (ncv = 2k + 1)
        # and the returned shapes. Work: n^3 dense, n ncv^2 for the Lanczos restarts.
        nbytes = 8.0 * (3 * n * n if dense else n * (3 * n_modes + 1) + 200 * n)
        flops = 10.0 * n**3 if dense else 20.0 * n * (2 * n_modes + 1) ** 2
        check_budget(f"The eigen-solve for {n_modes} modes of {n} DOFs", nbytes=nbytes,
                     flops=flops, parameter="n_modes", value=n_modes,
                     fix="ask for fewer modes (n_modes) or use a coarser mesh")
        # The model is immutable after __init__, so each mode count is solved once per model;
        # the arrays are read-only so no caller can change what the next one gets.
        if n_modes not in self._modes_cache:
            self._modes_cache[n_modes] = self._solve_modes(n_modes)
        return self._modes_cache[n_modes]

    # One BLAS thread: the eigen-solves are small-matrix work (ARPACK's restarts, eigh of a
    # few thousand), measured 10x slower with two contending threads on a shared 2-core machine.
    @threadpool_limits.wrap(limits=1, user_api="blas")
    def _solve_modes(self, n_modes: int) -> ModalBasis:
        n = self.n_dofs
        try:
            if n <= DENSE_EIGEN_LIMIT or n_modes >= n - 1:  # same rule as the budget above
                omega2, shapes = scipy.linalg.eigh(
                    self.stiffness_matrix.toarray(),
                    self.mass_matrix.toarray(),
                    subset_by_index=(0, n_modes - 1),
                )
            else:
                # A fixed start vector: without one ARPACK draws a fresh random start, and two
                # identical runs then differ at round-off (1e-11 on Drake 300 m). Random, not
                # ones: on a symmetric span ones is orthogonal to every antisymmetric mode.
                start = np.random.default_rng(0).standard_normal(n)
                omega2, shapes = spla.eigsh(
                    self.stiffness_matrix.tocsc(),
                    k=n_modes,
                    M=self.mass_matrix.tocsc(),
                    sigma=0.0,
                    which="LM",
                    v0=start,
                )
                order = np.argsort(omega2)
                omega2, shapes = omega2[order], shapes[:, order]
        except (np.linalg.LinAlgError, RuntimeError, spla.ArpackError) as exc:
            raise ModelError(f"The eigen-solve for {n_modes} modes failed: {exc}") from exc
        if omega2[0] <= 0:
            raise ModelError(
                f"The stiffness matrix is not positive definite (lowest omega^2 = "
                f"{omega2[0]:.3g}); check tension, EI and supports."
            )
        # Normalise to unit modal mass (eigsh does not guarantee it) and a sign that survives
        # round-off: the leftmost nodal displacement of at least half the peak is positive (the
        # largest entry alone is ambiguous: symmetric modes have equal peaks).
        modal_mass = np.einsum("ik,ik->k", shapes, self.mass_matrix @ shapes)
        shapes = shapes / np.sqrt(modal_mass)
        nodal = self.displacement_map() @ shapes
        if self.mdr is not None and self.mdr.has_absorber:
            nodal = np.vstack([nodal, shapes[-1:]])     # a mode of the absorber alone
        big = np.abs(nodal) >= 0.5 * np.abs(nodal).max(axis=0)
        signs = np.sign(nodal[np.argmax(big, axis=0), np.arange(n_modes)])
        shapes = shapes * np.where(signs == 0, 1.0, signs)
        omega = np.sqrt(omega2)
        return ModalBasis(omega=read_only(omega), shapes=read_only(shapes),
                          damping=read_only(self._modal_damping(omega, shapes)))

    def _modal_damping(self, omega: np.ndarray, shapes: np.ndarray) -> np.ndarray:
        damping = shapes.T @ (self.damper_matrix @ shapes)
        if isinstance(self.damping, ModalDamping):
            damping = damping + np.diag(2 * self.damping.ratios(omega.size) * omega)
        elif isinstance(self.damping, RayleighDamping):
            damping = damping + np.diag(
                self.damping.mass_coefficient + self.damping.stiffness_coefficient * omega**2
            )
        return damping

    def modes_below(self, max_frequency: float) -> ModalBasis:
        """Every mode with natural frequency <= ``max_frequency`` Hz (at least one).

        The count is estimated from the pinned closed form (no extra eigen-solve) and widened
        until the highest mode returned lies above the limit.

        Examples
        --------
        >>> from powerline_control import Span
        >>> LineModel(Span.paper_lab(), n_elements=20).modes_below(30.0).frequencies.round(2)
        array([ 6.53, 14.39, 24.53])
        """
        f = check_real("max_frequency", max_frequency, low=0.0)
        n = self.n_dofs
        count = min(n, self.default_mode_count(f))
        while True:
            basis = self.modes(count)
            if basis.frequencies[-1] > f or count == n:
                break
            count = min(n, 2 * count)
        keep = max(1, int(np.count_nonzero(basis.frequencies <= f)))
        if keep == basis.n_modes:
            return basis
        return ModalBasis(omega=read_only(basis.omega[:keep]),
                          shapes=read_only(basis.shapes[:, :keep]),
                          damping=read_only(basis.damping[:keep, :keep]))

    def natural_frequencies(self, n_modes: int = 10) -> np.ndarray:
        """Undamped natural frequencies, Hz, ascending, shape (n_modes,).

        Examples
        --------
        >>> from powerline_control import Span
        >>> LineModel(Span.paper_lab(), n_elements=20).natural_frequencies(2).round(3)
        array([ 6.534, 14.388])
        """
        # an int (modes(None) means every mode; here None would be a silent "all")
        return self.modes(check_int("n_modes", n_modes, low=1)).frequencies

    def mode_shapes(self, n_modes: int = 10) -> np.ndarray:
        """Mode shapes as nodal displacements, shape (n_nodes, n_modes), unit max displacement.

        Examples
        --------
        >>> from powerline_control import Span
        >>> shapes = LineModel(Span.paper_lab(), n_elements=20).mode_shapes(1)
        >>> float(shapes[10, 0])        # midspan of mode 1
        1.0
        """
        nodal = self.displacement_map() @ self.modes(check_int("n_modes", n_modes, low=1)).shapes
        peak = nodal[np.argmax(np.abs(nodal), axis=0), np.arange(nodal.shape[1])]
        return nodal / peak

    # ------------------------------------------------------------------ state space
    def default_mode_count(self, max_frequency: float) -> int:
        """How many modes lie below ``max_frequency`` Hz (all of them for a small model).

        Uses the pinned closed form as a count estimate plus a margin, so no eigen-solve is spent
        to decide how many modes to solve for.
        """
        if self.n_dofs <= DENSE_EIGEN_LIMIT:
            return self.n_dofs
        below = int(np.count_nonzero(self.span.pinned_frequencies(self.n_dofs) <= max_frequency))
        return int(min(self.n_dofs - 2, below + 10))

    def to_statespace(
        self,
        dt: float | None = None,
        force_positions: Sequence[float] = (),
        outputs: Sequence[float] | np.ndarray | None = None,
        n_modes: int | None = None,
    ) -> ct.StateSpace:
        """Export to a ``control.StateSpace`` in modal coordinates.

        States are ``[q_1..q_r, qdot_1..qdot_r]`` (mass-normalised modal coordinates), so the poles
        are ``-zeta_n omega_n +/- i omega_n sqrt(1 - zeta_n^2)`` of the modal analysis; with all
        modes kept the model is exact, with fewer it is a modal truncation.

        Parameters
        ----------
        dt : float or None
            None for continuous time; otherwise the sample time of an exact zero-order-hold
            discretisation.
        force_positions : sequence of float
            Positions (m) of point forces, one input each (named ``F0, F1, ...``).
        outputs : sequence of float or None
            Positions (m) where displacement is measured (outputs ``y0, y1, ...``); None gives
            every node (outputs ``w0..wN``, node j at ``node_positions[j]``).
        n_modes : int or None
            Modes to keep; None keeps all (small models) or those below 1 kHz.

        Returns
        -------
        control.StateSpace

        Examples
        --------
        >>> from powerline_control import Span
        >>> sys = LineModel(Span.paper_lab(), n_elements=10).to_statespace(force_positions=[0.5])
        >>> sys.nstates, sys.ninputs, sys.noutputs
        (40, 1, 11)
        """
        if n_modes is None:
            n_modes = self.default_mode_count(1000.0)
        basis = self.modes(n_modes)
        r = basis.n_modes
        a = np.block([[np.zeros((r, r)), np.eye(r)], [-np.diag(basis.omega**2), -basis.damping]])
        if isinstance(force_positions, str) or np.ndim(force_positions) != 1 and not (
                isinstance(force_positions, Sequence) and len(force_positions) == 0):
            raise InputError(
                "The 'force_positions' parameter must be a sequence of positions in m (e.g. "
                f"[1.3]). Got {force_positions!r}."
            )
        positions = [self._check_position("force_positions", x) for x in force_positions]
        if outputs is not None:   # named as the caller knows them (displacement_map's 'positions')
            outputs = check_array("outputs", outputs, ndim=1)
            for x in outputs:
                self._check_position("outputs", float(x))
        loads = (
            np.column_stack([self.point_load(x) for x in positions])
            if positions
            else np.zeros((self.n_dofs, 0))
        )
        b = np.vstack([np.zeros((r, len(positions))), basis.shapes.T @ loads])
        out_map = self.displacement_map(outputs)
        c = np.hstack([out_map @ basis.shapes, np.zeros((out_map.shape[0], r))])
        d = np.zeros((c.shape[0], b.shape[1]))
        names = dict(
            states=[f"q{k + 1}" for k in range(r)] + [f"qdot{k + 1}" for k in range(r)],
            # python-control signal names may not contain '.', so positions go in the docstring:
            # input i is the force at force_positions[i], output j the displacement at outputs[j].
            inputs=[f"F{i}" for i in range(len(positions))],
            outputs=[f"w{j}" for j in range(self.n_nodes)]
            if outputs is None
            else [f"y{j}" for j in range(len(outputs))],
        )
        sys = ct.ss(a, b, c, d, **names)
        if dt is None:
            return sys
        dt = check_real("dt", dt, low=0.0)
        ad = scipy.linalg.expm(a * dt)
        # ZOH input matrix: integral_0^dt expm(A s) ds B, through the augmented exponential.
        aug = np.zeros((2 * r + b.shape[1], 2 * r + b.shape[1]))
        aug[: 2 * r, : 2 * r] = a * dt
        aug[: 2 * r, 2 * r :] = b * dt
        bd = scipy.linalg.expm(aug)[: 2 * r, 2 * r :]
        if not np.all(np.isfinite(ad)):
            warnings.warn(
                "The discretisation overflowed; use fewer modes or a smaller dt.", stacklevel=2
            )
        return ct.ss(ad, bd, c, d, dt, **names)
