"""Short packets through the converged filter's closed loop in its modal form.

Once the gain is frozen every NaN-free sample is the linear recursion
``x[k] = F x[k-1] + G w[k]`` with ``F = (I - K C) A`` and the drivers ``w[k]`` (the measurement,
the previous input and, with a ``D``, the input). Stepped, each sample costs one ``n x n``
matrix-vector product and a Python iteration: for the closed loop's 204-state filter that was
most of ``KalmanFilter.step_block``'s time in 10-sample packets. With
``F = V diag(lambda) V^-1`` a packet of ``L`` samples costs one product for the modal drives,
an ``O(n L)`` scan and one product for the states (:class:`ModalPacket`); the modal state is
carried between packets, so nothing is solved per packet.

``_build_batch`` in ``_recursion`` evaluates long stretches of ``filter`` the same way with a
blocked Toeplitz scan; this form is the one for a few samples at a time (its per-call set-up is a
few microseconds, not a complex LU solve). Test seam: :meth:`ModalPacket.build` and
:meth:`ModalPacket.run` on a given recursion (tests/test_filter_packets.py).
"""

from __future__ import annotations

import numpy as np

# The modal form is used only when the eigenvector matrix of the closed loop is this well
# conditioned. Its states differ from the stepped loop's by up to about cond(V) * eps, relative
# (measured over 2000 samples of the closed loop's filters: 8.5e-11 at cond(V) = 3.7e5 with 204
# states, 9.4e-12 at 9.3e5 with 348), so 1e6 keeps that near 2e-10, well inside 1e-9; beyond it
# (near a Jordan block: nearly parallel eigenvectors) the stepped loop is kept. The family's
# closed-loop filters reach 9.3e5 (docs/validation/closed_loop.md).
MAX_CONDITION = 1e6
# The scan scales sample j's drive by lambda^-j and the running sum by lambda^k (one cumulative
# sum instead of a Python loop over samples); it is used while every |lambda|^(L-1) of the packet
# stays within these powers of ten of 1 (no overflow or underflow of the scaled terms), else
# the doubling scan, which only uses non-negative powers. Its tables are kept per packet length
# up to _SCALED_LENGTH samples (longer packets have few Python passes per sample anyway).
_SCALED_RANGE = 1e150
_SCALED_LENGTH = 64


def conjugate_modes(closed: np.ndarray, max_condition: float = MAX_CONDITION):
    """``(eigenvalues, vectors, real, upper)`` of ``closed``: its eigen-decomposition and the
    indices of its real eigenvalues and of the upper halves of its conjugate pairs; or None when
    the modal form would lose accuracy (the eigenvector matrix's condition number above
    ``max_condition``, or eigenvalues not in exact conjugate pairs)."""
    eigenvalues, vectors = np.linalg.eig(closed)
    if not np.all(np.isfinite(vectors)) or np.linalg.cond(vectors) > max_condition:
        return None
    real = np.flatnonzero(eigenvalues.imag == 0)
    upper = np.flatnonzero(eigenvalues.imag > 0)
    if real.size + 2 * upper.size != eigenvalues.size:
        return None
    return eigenvalues, vectors, real, upper


class ModalPacket:
    """The closed loop ``x[k] = F x[k-1] + G w[k]`` in modal coordinates, for short packets,
    with the outputs ``o[k] = O x[k-1] + H w[k]`` along.

    Modes are complex slots ``z`` (one per real eigenvalue and one per conjugate pair, the
    pair's other half being the conjugate), so a packet's modal states are one complex array
    whose ``float`` view is the real coordinates ``[Re z, Im z]`` interleaved, and
    ``x = lift @ real coordinates`` (``2 Re(v z)`` for a pair; a real mode's imaginary column is
    zero). Build with :meth:`build`; ``None`` there means the modal form would lose accuracy.
    """

    def __init__(self, eigenvalues: np.ndarray, vectors: np.ndarray, inverse: np.ndarray,
                 drive: np.ndarray, observe: np.ndarray, feedthrough: np.ndarray) -> None:
        self.eigenvalues = eigenvalues
        n, n_slots = vectors.shape
        is_real = eigenvalues.imag == 0
        scale = np.where(is_real, 1.0, 2.0)
        lift = np.empty((n, 2 * n_slots))
        lift[:, 0::2], lift[:, 1::2] = vectors.real * scale, -vectors.imag * scale
        lift[:, 1::2][:, is_real] = 0.0
        # Transposed, for (L, 2 slots) @ (2 slots, n): as fast as lift @ (2 slots, L) up to 300
        # states and 1.4x faster at 352 (once the lift outgrows the 1 MiB L2 cache, EPYC), and
        # the scan's output is its operand as it stands (no transposed copy).
        self.lift_t = np.ascontiguousarray(lift.T)
        self.observe_t = np.ascontiguousarray((observe @ lift).T)
        # real coordinates of V^-1 (rows Re, Im interleaved): z = (to_modal @ x).view(complex)
        to_modal = np.empty((2 * n_slots, inverse.shape[1]))
        to_modal[0::2], to_modal[1::2] = inverse.real, inverse.imag
        to_modal[1::2][is_real] = 0.0
        self.to_modal = to_modal
        # drivers (L, q) to [modal drives interleaved | H w] in one product
        modal_drive = inverse @ drive
        drive_t = np.empty((drive.shape[1], 2 * n_slots + feedthrough.shape[0]))
        drive_t[:, 0 : 2 * n_slots : 2] = modal_drive.real.T
        drive_t[:, 1 : 2 * n_slots : 2] = np.where(is_real, 0.0, modal_drive.imag.T)
        drive_t[:, 2 * n_slots :] = feedthrough.T
        self.drive_t = drive_t
        self.powers = [eigenvalues]   # lambda^(2^i) of the doubling scan, extended as needed
        self.scaled: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray] | None] = {}

    @classmethod
    def build(cls, closed: np.ndarray, drive: np.ndarray, observe: np.ndarray,
              feedthrough: np.ndarray, max_condition: float = MAX_CONDITION,
              ) -> ModalPacket | None:
        """The modal form of ``x[k] = closed x[k-1] + drive w[k]`` with the outputs
        ``o[k] = observe x[k-1] + feedthrough w[k]``, or None (keep the stepped loop).

        None when the eigenvector matrix's condition number exceeds ``max_condition`` (a
        defective or nearly defective ``closed``, whose modal round-off would exceed about 1e-9
        relative) or the eigenvalues do not come in exact conjugate pairs.
        """
        modes = conjugate_modes(closed, max_condition)
        if modes is None:
            return None
        eigenvalues, vectors, real, upper = modes
        keep = np.sort(np.concatenate([real, upper]))
        inverse = np.linalg.solve(vectors, np.eye(vectors.shape[0], dtype=complex))[keep]
        return cls(eigenvalues[keep], vectors[:, keep], inverse, drive, observe, feedthrough)

    def modal(self, x: np.ndarray) -> np.ndarray:
        """The modal state ``z`` (complex slots) of the state ``x``."""
        return (self.to_modal @ x).view(complex)

    def run(self, z0: np.ndarray, drivers_t: np.ndarray, seen0: np.ndarray,
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One packet from the modal state ``z0`` with drivers ``drivers_t`` ``(L, q)`` (time
        along rows) and ``seen0 = O x[-1]``.

        Returns the states ``(n, L)``, the modal states ``(L, slots)``, the outputs ``o``
        ``(r, L)`` and ``O x[L-1]`` (the next packet's ``seen0``).
        """
        n_slots = self.eigenvalues.size
        product = drivers_t @ self.drive_t
        drives = product[:, : 2 * n_slots].view(complex)
        drives[0] += self.eigenvalues * z0
        z = self._scan(drives)
        coordinates = z.view(float)   # (L, 2 slots), C order
        states = (coordinates @ self.lift_t).T   # (n, L), F order
        seen = (coordinates @ self.observe_t).T  # O x[k]
        outputs = product[:, 2 * n_slots :].T.copy()
        outputs[:, 0] += seen0
        outputs[:, 1:] += seen[:, :-1]
        return states, z, outputs, seen[:, -1]

    def _scan(self, drives: np.ndarray) -> np.ndarray:
        """``z[k] = lambda z[k-1] + drives[k]`` down the rows of ``drives`` ``(L, slots)``
        (``z[-1] = 0``): a new C-contiguous array.

        Scaled: ``z[k] = lambda^k sum_{j<=k} lambda^-j d[j]``, the sum one product with a
        triangle of ones (numpy's cumulative sum down a short axis took three times as long);
        its round-off is that of the sum (each term is ``lambda^(k-j) d[j]`` with ``k >= j``), so
        it needs only that the scaled terms neither overflow nor underflow (``_SCALED_RANGE``).
        Otherwise (a long packet, an eigenvalue near 0) a doubling scan: after the pass with
        shift ``s`` each ``z[k]`` holds ``sum_{j<2s} lambda^j d[k-j]``, ``ceil(log2 L)`` passes
        of non-negative powers.
        """
        length = drives.shape[0]
        if length not in self.scaled and length <= _SCALED_LENGTH:
            size = np.abs(self.eigenvalues)
            fits = (length == 1 or (size.min() ** (length - 1) >= 1 / _SCALED_RANGE
                                    and size.max() ** (length - 1) <= _SCALED_RANGE))
            up = self.eigenvalues[None, :] ** np.arange(length)[:, None]
            self.scaled[length] = (up, 1 / up, np.tril(np.ones((length, length)))) if fits \
                else None
        tables = self.scaled.get(length)
        if tables is not None:
            up, down, triangle = tables
            z = (triangle @ (drives * down).view(float)).view(complex)
            z *= up
            return z
        z = np.ascontiguousarray(drives)
        shift, i = 1, 0
        while shift < length:
            while len(self.powers) <= i:
                self.powers.append(self.powers[-1] * self.powers[-1])
            z[shift:] += self.powers[i] * z[:-shift]
            shift, i = 2 * shift, i + 1
        return z
