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

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import control as ct
import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ._validation import check_array, check_choice, check_int, check_real, read_only
from .errors import InputError, ModelError
from .line import Span

__all__ = ["LineModel", "MDR", "ModalDamping", "RayleighDamping", "ModalBasis"]

_BOUNDARY_CONDITIONS = ("pinned", "clamped")
#: Up to this many free DOFs the eigenproblem is solved densely (all modes, exact); above it a
#: sparse shift-invert Lanczos solve returns the lowest modes only.
DENSE_EIGEN_LIMIT = 1200


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


def _hermite(xi: np.ndarray, h: float) -> np.ndarray:
    """Hermite cubic shape functions N1..N4 at local coordinates xi in [0, 1], shape (..., 4)."""
    return np.stack(
        [
            1 - 3 * xi**2 + 2 * xi**3,
            h * (xi - 2 * xi**2 + xi**3),
            3 * xi**2 - 2 * xi**3,
            h * (-(xi**2) + xi**3),
        ],
        axis=-1,
    )


def _element_matrices(h: float, ei: float, tension: float, mass: float):
    """Stiffness (bending + tension) and consistent mass of one element, DOFs [w1 t1 w2 t2]."""
    k_bend = (
        ei
        / h**3
        * np.array(
            [
                [12, 6 * h, -12, 6 * h],
                [6 * h, 4 * h**2, -6 * h, 2 * h**2],
                [-12, -6 * h, 12, -6 * h],
                [6 * h, 2 * h**2, -6 * h, 4 * h**2],
            ]
        )
    )
    k_tens = (
        tension
        / (30 * h)
        * np.array(
            [
                [36, 3 * h, -36, 3 * h],
                [3 * h, 4 * h**2, -3 * h, -(h**2)],
                [-36, -3 * h, 36, -3 * h],
                [3 * h, -(h**2), -3 * h, 4 * h**2],
            ]
        )
    )
    m_cons = (
        mass
        * h
        / 420
        * np.array(
            [
                [156, 22 * h, 54, -13 * h],
                [22 * h, 4 * h**2, 13 * h, -3 * h**2],
                [54, 13 * h, 156, -22 * h],
                [-13 * h, -3 * h**2, -22 * h, 4 * h**2],
            ]
        )
    )
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
    n_elements : int
        Number of equal elements (>= 1); nodes sit at x_j = j L / n_elements.
    bc : {"pinned", "clamped"} or (left, right)
        Support conditions.
    damping : None, ModalDamping or RayleighDamping
        Structural damping; none by default, as in the paper.
    mdr : MDR or None
        The damping robot, attached at any position through the shape functions.

    Attributes
    ----------
    span, n_elements, bc, damping, mdr
        The parameters above (``bc`` as a (left, right) pair).
    node_positions : ndarray, shape (n_nodes,)
        Node coordinates, m.
    mass_matrix, stiffness_matrix, damper_matrix : scipy.sparse.csr_array
        M, K and the discrete dampers' C (the robot's) over the free DOFs.

    Examples
    --------
    >>> from powerline_control import Span
    >>> model = LineModel(Span.paper_lab(), n_elements=20)
    >>> model.n_nodes, model.n_dofs
    (21, 40)
    >>> model.natural_frequencies(3).round(2)
    array([ 6.53, 14.39, 24.53])
    """

    def __init__(
        self,
        span: Span,
        n_elements: int = 100,
        bc: object = "pinned",
        damping: ModalDamping | RayleighDamping | None = None,
        mdr: MDR | None = None,
    ):
        if not isinstance(span, Span):
            raise InputError(f"The 'span' parameter must be a Span. Got {type(span).__name__}.")
        self.span = span
        self.n_elements = check_int("n_elements", n_elements, low=1)
        self.bc = _parse_bc(bc)
        if damping is not None and not isinstance(damping, ModalDamping | RayleighDamping):
            raise InputError(
                "The 'damping' parameter must be None, ModalDamping or "
                f"RayleighDamping. Got {type(damping).__name__}."
            )
        self.damping = damping
        if mdr is not None:
            if not isinstance(mdr, MDR):
                raise InputError(f"The 'mdr' parameter must be an MDR. Got {type(mdr).__name__}.")
            self._check_position("mdr.position", mdr.position)
        self.mdr = mdr
        self.element_length = span.length / self.n_elements
        self.node_positions = np.linspace(0.0, span.length, self.n_elements + 1)
        self._n_line_dofs = 2 * (self.n_elements + 1)
        self._free = self._free_dofs()
        self._modes_cache: dict[int, ModalBasis] = {}
        if self._free.size == 0:
            raise InputError(
                f"The 'n_elements' parameter must be >= 2 for supports {self.bc}: "
                f"{self.n_elements} element(s) leave no free degree of freedom."
            )
        self.mass_matrix, self.stiffness_matrix, self.damper_matrix = self._assemble()

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
        return np.array([d for d in range(n_total) if d not in fixed])

    def _check_position(self, name: str, position: object) -> float:
        return check_real(name, position, low=0.0, low_inclusive=True, high=self.span.length)

    def shape_vector(self, position: float) -> np.ndarray:
        """Interpolation row: displacement at ``position`` = row @ (free DOFs), shape (n_dofs,).

        Examples
        --------
        >>> from powerline_control import Span
        >>> model = LineModel(Span.paper_lab(), n_elements=4)
        >>> model.shape_vector(model.node_positions[1])[:3]   # free DOFs: theta_0, w_1, theta_1
        array([0., 1., 0.])
        """
        x = self._check_position("position", position)
        h = self.element_length
        element = min(int(x // h), self.n_elements - 1)
        row = np.zeros(self._n_total)
        row[2 * element : 2 * element + 4] = _hermite(np.array((x - element * h) / h), h)
        return row[self._free]

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
            col_of_global = {g: i for i, g in enumerate(self._free)}
            rows, cols = [], []
            for j in range(self.n_nodes):
                if 2 * j in col_of_global:
                    rows.append(j)
                    cols.append(col_of_global[2 * j])
            return sp.csr_array(
                (np.ones(len(rows)), (rows, cols)), shape=(self.n_nodes, self.n_dofs)
            )
        positions = check_array("positions", positions, ndim=1)
        return sp.csr_array(
            np.vstack([self.shape_vector(x) for x in positions])
            if positions.size
            else np.zeros((0, self.n_dofs))
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
        h = self.element_length
        starts = self.node_positions[:-1]
        x = starts[:, None] + h * xi[None, :]  # (n_el, 4)
        q = np.asarray(load_per_length(x), dtype=float)
        element_loads = np.einsum("eg,gk,g->ek", q, _hermite(xi, h), gauss_w * h / 2)
        full = np.zeros(self._n_total)
        for k in range(4):
            np.add.at(full, 2 * np.arange(self.n_elements) + k, element_loads[:, k])
        return full[self._free]

    # ------------------------------------------------------------------ assembly
    def _assemble(self) -> tuple[sp.csr_array, sp.csr_array, sp.csr_array]:
        cond = self.span.conductor
        k_e, m_e = _element_matrices(
            self.element_length, cond.ei, self.span.tension, cond.mass_per_length
        )
        dofs = 2 * np.arange(self.n_elements)[:, None] + np.arange(4)[None, :]  # (n_el, 4)
        rows = np.repeat(dofs, 4, axis=1).ravel()
        cols = np.tile(dofs, (1, 4)).ravel()
        n_total = self._n_total
        stiffness = sp.coo_array(
            (np.tile(k_e.ravel(), self.n_elements), (rows, cols)), shape=(n_total, n_total)
        ).tocsr()
        mass = sp.coo_array(
            (np.tile(m_e.ravel(), self.n_elements), (rows, cols)), shape=(n_total, n_total)
        ).tocsr()
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
        """Body mass m_r N N^T on the line; spring and damper k, c [[N N^T, -N], [-N^T, 1]]."""
        robot = self.mdr
        h = self.element_length
        element = min(int(robot.position // h), self.n_elements - 1)
        n_vec = np.zeros(n_total)
        n_vec[2 * element : 2 * element + 4] = _hermite(
            np.array((robot.position - element * h) / h), h
        )
        if robot.has_absorber:
            n_vec[-1] = -1.0  # relative displacement y(x_r) - y_d
        body = np.zeros(n_total)
        body[: self._n_line_dofs] = n_vec[: self._n_line_dofs]
        mass = mass + robot.body_mass * sp.csr_array(np.outer(body, body))
        if robot.has_absorber:
            coupling = sp.csr_array(np.outer(n_vec, n_vec))
            stiffness = stiffness + robot.stiffness * coupling
            damper = damper + robot.damping * coupling
            absorber = np.zeros((n_total, n_total))
            absorber[-1, -1] = robot.suspended_mass
            mass = mass + sp.csr_array(absorber)
        return mass, stiffness, damper

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
        # The model is immutable after __init__, so each mode count is solved once per model;
        # the arrays are read-only so no caller can change what the next one gets.
        if n_modes not in self._modes_cache:
            self._modes_cache[n_modes] = self._solve_modes(n_modes)
        return self._modes_cache[n_modes]

    def _solve_modes(self, n_modes: int) -> ModalBasis:
        n = self.n_dofs
        try:
            if n <= DENSE_EIGEN_LIMIT or n_modes >= n - 1:
                omega2, shapes = scipy.linalg.eigh(
                    self.stiffness_matrix.toarray(),
                    self.mass_matrix.toarray(),
                    subset_by_index=(0, n_modes - 1),
                )
            else:
                omega2, shapes = spla.eigsh(
                    self.stiffness_matrix.tocsc(),
                    k=n_modes,
                    M=self.mass_matrix.tocsc(),
                    sigma=0.0,
                    which="LM",
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
        # Normalise to unit modal mass (eigsh does not guarantee it) and a positive first entry
        # of largest magnitude, so shapes are reproducible.
        modal_mass = np.einsum("ik,ik->k", shapes, self.mass_matrix @ shapes)
        shapes = shapes / np.sqrt(modal_mass)
        signs = np.sign(shapes[np.argmax(np.abs(shapes), axis=0), np.arange(n_modes)])
        shapes = shapes * signs
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

    def natural_frequencies(self, n_modes: int = 10) -> np.ndarray:
        """Undamped natural frequencies, Hz, ascending, shape (n_modes,).

        Examples
        --------
        >>> from powerline_control import Span
        >>> LineModel(Span.paper_lab(), n_elements=20).natural_frequencies(2).round(3)
        array([ 6.534, 14.388])
        """
        return self.modes(n_modes).frequencies

    def mode_shapes(self, n_modes: int = 10) -> np.ndarray:
        """Mode shapes as nodal displacements, shape (n_nodes, n_modes), unit max displacement.

        Examples
        --------
        >>> from powerline_control import Span
        >>> shapes = LineModel(Span.paper_lab(), n_elements=20).mode_shapes(1)
        >>> float(shapes[10, 0])        # midspan of mode 1
        1.0
        """
        nodal = self.displacement_map() @ self.modes(n_modes).shapes
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
        positions = [self._check_position("force_positions", x) for x in force_positions]
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
