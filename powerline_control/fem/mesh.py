"""Meshes of a span and what a mesh alone decides: element matrices, shape functions, assembly.

The mesh comes from the physics (:func:`physics_mesh`: elements per shortest loop of the band,
graded toward clamped supports over the bending boundary layer) or is uniform; its resolution is
judged by the leading frequency error of Hermite cubics (:func:`frequency_error_estimate`,
:func:`clamp_error_estimate`). :class:`_Mesh` is the part of
:class:`~powerline_control.fem.LineModel` that only needs the mesh and the supports: sizes and
DOF maps, resolution checks, the interpolation rows that couple points to the line, consistent
load vectors and the assembly of M, K and the robot's C.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse as sp

from .._validation import check_array, check_choice, check_real, read_only
from ..errors import InputError, TruncationWarning
from ..line import Span

__all__ = ["physics_mesh", "frequency_error_estimate", "accuracy_elements_per_loop",
           "aeolian_band_top", "clamp_error_estimate"]

_BOUNDARY_CONDITIONS = ("pinned", "clamped")

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


# The four line DOFs of an element, counted from its first: w_left, theta_left, w_right, theta_right
_ELEMENT_DOFS = np.arange(4)


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


def _hermite_at(xi: float, h: float) -> np.ndarray:
    """:func:`_hermite` at one local coordinate, shape (4,): the same formulas on floats, equal
    to the array form to round-off (a moving robot asks for one point thousands of times; the
    array form costs ten times more for a single point)."""
    xi2, xi3 = xi * xi, xi**3
    return np.array([1 - 3 * xi2 + 2 * xi3, h * (xi - 2 * xi2 + xi3), 3 * xi2 - 2 * xi3,
                     h * (-xi2 + xi3)])


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


def parse_bc(bc: object) -> tuple[str, str]:
    """The (left, right) supports of ``bc``: one name for both or a pair; unknown names refused."""
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


class _Mesh:
    """Mesh-only part of :class:`~powerline_control.fem.LineModel` (its base class).

    Reads what ``LineModel.__init__`` sets: ``span``, ``bc``, ``n_elements``, ``node_positions``,
    ``element_lengths``, ``frequency_tolerance``, ``mdr``, ``_n_line_dofs``, ``_free`` and
    ``_free_index``.
    """

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
        >>> from powerline_control import LineModel, Span
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
        >>> from powerline_control import LineModel, Span
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
        >>> from powerline_control import LineModel, Span
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

        For the CLI and :func:`~powerline_control.simulation.simulate`: the message names the
        frequency, the loop length, the element length and the element count that would work.

        Examples
        --------
        >>> from powerline_control import LineModel, Span
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
        h = float(self.element_lengths[element])
        xi = (x - float(self.node_positions[element])) / h
        return 2 * element + _ELEMENT_DOFS, _hermite_at(xi, h)

    def shape_entries(self, position: float) -> tuple[np.ndarray, np.ndarray]:
        """Sparse interpolation row: (free-DOF indices, weights) of the displacement at position.

        At most 4 entries: what couples a point (robot, sensor, load) to the line at O(1) cost
        on any mesh, ``row @ u == weights @ u[indices]``.

        Examples
        --------
        >>> from powerline_control import LineModel, Span
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
        >>> from powerline_control import LineModel, Span
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
        >>> from powerline_control import LineModel, Span
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
        index, weights = self.shape_rows(positions)
        keep = index >= 0
        rows = np.broadcast_to(np.arange(index.shape[0])[:, None], index.shape)
        return sp.csr_array((weights[keep], (rows[keep], index[keep])),
                            shape=(index.shape[0], self.n_dofs))

    def shape_rows(self, positions: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`shape_entries` of many positions at once, as (K, 4) arrays.

        Row k holds the free-DOF indices and weights of the displacement at ``positions[k]``
        (the four DOFs of its element in order); a DOF a support constrains has index -1 and
        weight 0. A few array operations instead of a Python call per position.

        Examples
        --------
        >>> from powerline_control import LineModel, Span
        >>> model = LineModel(Span.paper_lab(), n_elements=4)
        >>> index, weights = model.shape_rows([0.0, model.node_positions[1]])
        >>> index.tolist()                       # w_0 is pinned: -1
        [[-1, 0, 1, 2], [1, 2, 3, 4]]
        >>> weights[1].round(12).tolist()
        [1.0, 0.0, 0.0, 0.0]
        """
        positions = check_array("positions", positions, ndim=1)
        outside = np.flatnonzero((positions < 0.0) | (positions > self.span.length))
        if outside.size:
            raise InputError(
                f"The 'positions' parameter must lie on the span, 0 to {self.span.length:g} m. "
                f"Got {positions[outside[0]]!r} at index {int(outside[0])}."
            )
        element = np.clip(np.searchsorted(self.node_positions, positions, side="right") - 1, 0,
                          self.n_elements - 1)
        h = self.element_lengths[element]
        weights = _hermite((positions - self.node_positions[element]) / h, h)
        index = self._free_index[2 * element[:, None] + _ELEMENT_DOFS]
        return index, np.where(index >= 0, weights, 0.0)

    def point_load(self, position: float) -> np.ndarray:
        """Consistent load vector of a unit point force at ``position``, shape (n_dofs,)."""
        return self.shape_vector(position)

    def distributed_load(self, load_per_length: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Consistent load vector of a distributed load q(x) (N/m), by 4-point Gauss quadrature.

        Examples
        --------
        >>> from powerline_control import LineModel, Span
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
    def _assembled(self, element_matrices: np.ndarray) -> sp.csr_array:
        """The line's global matrix (every DOF, supports included) from per-element 4x4 ones."""
        dofs = 2 * np.arange(self.n_elements)[:, None] + np.arange(4)[None, :]  # (n_el, 4)
        rows = np.repeat(dofs, 4, axis=1).ravel()
        cols = np.tile(dofs, (1, 4)).ravel()
        n_total = self._n_total
        return sp.coo_array((element_matrices.ravel(), (rows, cols)),
                            shape=(n_total, n_total)).tocsr()

    def stiffness_parts(self) -> tuple[sp.csr_array, sp.csr_array]:
        """The line's stiffness per unit tension and per unit bending stiffness, over the free
        DOFs: ``K = T K_T + EI K_B`` (plus the robot's spring, which neither holds).

        The stiffness is linear in both on a fixed mesh, so a calibration can scale a model's
        modes to another tension or EI without assembling it again.

        Returns
        -------
        K_T, K_B : scipy.sparse.csr_array
            Per newton of tension, per N m^2 of EI.

        Examples
        --------
        >>> from powerline_control import LineModel, Span
        >>> model = LineModel(Span.paper_lab(), n_elements=10)
        >>> k_t, k_b = model.stiffness_parts()
        >>> span = model.span
        >>> bool(abs(span.tension * k_t + span.conductor.ei * k_b
        ...          - model.stiffness_matrix).max() < 1e-9)
        True
        """
        h, mass = self.element_lengths, self.span.conductor.mass_per_length
        free = self._free
        parts = []
        for ei, tension in ((0.0, 1.0), (1.0, 0.0)):
            k_e, _ = _element_matrices(h, ei, tension, mass)
            parts.append(self._assembled(k_e)[free][:, free].tocsr())
        return parts[0], parts[1]

    def _assemble(self) -> tuple[sp.csr_array, sp.csr_array, sp.csr_array]:
        cond = self.span.conductor
        k_e, m_e = _element_matrices(
            self.element_lengths, cond.ei, self.span.tension, cond.mass_per_length
        )
        n_total = self._n_total
        stiffness = self._assembled(k_e)
        mass = self._assembled(m_e)
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
