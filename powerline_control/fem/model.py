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
from collections.abc import Sequence
from dataclasses import dataclass

import control as ct
import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._threads import on_one_blas_thread
from .._validation import (
    check_array,
    check_budget,
    check_budget_value,
    check_int,
    check_real,
    read_only,
)
from ..errors import InputError, ModelError, TruncationWarning
from ..line import Span
from .damper import MDR
from .mesh import (
    _ASSEMBLY_BYTES_PER_ELEMENT,
    SAMPLING_ELEMENTS_PER_LOOP,
    _Mesh,
    accuracy_elements_per_loop,
    clamp_error_estimate,
    parse_bc,
    physics_mesh,
)

__all__ = ["LineModel", "ModalDamping", "RayleighDamping", "ModalBasis", "DENSE_EIGEN_LIMIT"]

#: Up to this many free DOFs the eigenproblem is solved densely (all modes, exact); above it a
#: sparse shift-invert Lanczos solve returns the lowest modes only.
DENSE_EIGEN_LIMIT = 1200


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
        """Coefficients giving damping ratio ``ratio`` at two frequencies (Hz).

        Parameters
        ----------
        frequencies : (float, float)
            The two frequencies, Hz (> 0): Rayleigh damping has two coefficients, so one
            frequency does not fix them.
        ratio : float
            Damping ratio at both (>= 0).

        Returns
        -------
        RayleighDamping

        Examples
        --------
        >>> d = RayleighDamping.from_ratios((10.0, 30.0), 0.01)
        >>> round(d.stiffness_coefficient * 1e5, 4)
        7.9577
        """
        if (isinstance(frequencies, str | bytes)
                or not isinstance(frequencies, Sequence | np.ndarray)
                or np.ndim(frequencies) != 1 or len(frequencies) != 2):
            raise InputError(
                "The 'frequencies' parameter must be two frequencies (f1, f2), Hz: Rayleigh "
                "damping has two coefficients, fixed by the ratio at two frequencies. Got "
                f"{frequencies!r:.60}.")
        f1, f2 = (check_real("frequencies", f, low=0.0) for f in frequencies)
        zeta = check_real("ratio", ratio, low=0.0, low_inclusive=True)
        w1, w2 = 2 * np.pi * f1, 2 * np.pi * f2
        return cls(2 * zeta * w1 * w2 / (w1 + w2), 2 * zeta / (w1 + w2))


@dataclass(frozen=True, eq=False)
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


class LineModel(_Mesh):
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
        self.bc = parse_bc(bc)
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
        self._modes_cache: dict = {}   # n_modes -> ModalBasis; "dense": the full (omega^2, shapes)
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

    # ------------------------------------------------------------------ static / dynamic solves
    def solve_flexibility(self, load: np.ndarray, frequency: float = 0.0) -> np.ndarray:
        """(K - omega^2 M)^-1 load over the free DOFs, by a cached sparse LU factorisation.

        ``frequency`` 0 gives the static deflection K^-1 load (the mode-acceleration correction
        of :func:`~powerline_control.simulation.simulate` uses both).

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
    # few thousand), far slower with contending threads.
    @on_one_blas_thread
    def _solve_modes(self, n_modes: int) -> ModalBasis:
        n = self.n_dofs
        try:
            if n <= DENSE_EIGEN_LIMIT or n_modes >= n - 1:  # same rule as the budget above
                # All modes by divide and conquer, then the lowest: LAPACK's subset driver (gvx)
                # bounds each eigenvalue's error by eps * ||K||, which on a graded mesh is a
                # relative 1e-4 of f1 (clamped Drake 300 m, 75 m elements, SciPy 1.11; 3e-5 on
                # 1.17) where the full solve is within 3e-7 of the root finder; at most twice
                # the subset's time at the dense limit.
                # The full solve is kept: another mode count takes its first columns (the same
                # arrays as its own full solve) instead of solving again.
                if self._modes_cache.get("dense") is None:
                    self._modes_cache["dense"] = scipy.linalg.eigh(
                        self.stiffness_matrix.toarray(),
                        self.mass_matrix.toarray(),
                        driver="gvd",
                    )
                omega2, shapes = self._modes_cache["dense"]
                omega2, shapes = omega2[:n_modes], shapes[:, :n_modes]
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
