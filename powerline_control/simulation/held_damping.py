"""The unforced modal plant whose line damping follows its state (the self-limiting wind).

A :class:`~powerline_control.simulation.plant.ModalPlant` driven by no load but by a damping
that depends on its amplitudes (the wind's negative damping and the conductor's self-damping,
:class:`~powerline_control.severity.AeolianDamping`): each block of samples holds the damping
of its start and steps the exact flow, expm(A dt); the exponential is kept while the damping
stays close to the one it was built with (:class:`HeldDamping`).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

__all__ = ["DAMPING_HOLD", "HeldDamping", "run_held", "step_unforced"]

#: A held discretisation of a state-dependent line damping is rebuilt once the damping the
#: state asks for differs from the held one by more than this fraction of its largest entry:
#: the growth rate it misses is then below 1e-3 of the wind's (a steady line is not rebuilt at
#: every block; a decaying one is, as a moving robot is).
DAMPING_HOLD = 1e-3


class HeldDamping:
    """The one-sample map of an unforced plant whose line damping follows its state.

    ``damping(z)`` gives the line's modal damping (r, r) at state z (e.g. the self-limiting
    wind's, :class:`~powerline_control.severity.AeolianDamping`); :meth:`transition` evaluates
    it at a block's start and returns expm(A dt) of the plant with the robot at x and that
    damping, built again only when x moved or the damping moved by more than ``tolerance`` of
    its largest entry (:data:`DAMPING_HOLD`). ``rebuilds`` counts the exponentials.

    Examples
    --------
    >>> import numpy as np
    >>> from powerline_control import LineModel, Span
    >>> from powerline_control.simulation.plant import ModalPlant
    >>> plant = ModalPlant(LineModel(Span.paper_lab(), 20), None, 4, dt=1e-3)
    >>> held = HeldDamping(plant, lambda z: 0.1 * np.eye(plant.r))
    >>> z = np.zeros(2 * plant.n_q); z[0] = 1e-3
    >>> states = run_held(held, None, z, 100, block=10)
    >>> held.rebuilds      # the damping never moved: one exponential
    1
    """

    def __init__(self, plant, damping, tolerance: float = DAMPING_HOLD):
        self.plant, self.damping, self.tolerance = plant, damping, tolerance
        self.rebuilds = 0
        self._held: tuple | None = None   # (x, damping matrix, phi)

    @property
    def matrix(self) -> np.ndarray | None:
        """The line damping of the map last returned (None before the first)."""
        return None if self._held is None else self._held[1]

    def transition(self, x: float | None, z: np.ndarray) -> np.ndarray:
        """Phi = expm(A dt) of the plant with the robot at x and the damping of state z."""
        wanted = self.damping(z)
        if self._held is not None:
            x_held, held, phi = self._held
            scale = float(np.max(np.abs(wanted)))
            if x_held == x and float(np.max(np.abs(wanted - held))) <= self.tolerance * scale:
                return phi
        phi = scipy.linalg.expm(self.plant.state_matrix(x, wanted) * self.plant.dt)
        self._held = (x, wanted, phi)
        self.rebuilds += 1
        return phi


def run_held(held: HeldDamping, x: float | None, z0: np.ndarray, n_t: int, *,
             block: int) -> np.ndarray:
    """States (n_t, 2 n_q) of the unforced plant parked at x (None: no robot) from z0, its
    state-dependent damping evaluated every ``block`` samples at the block's start
    (:class:`HeldDamping`)."""
    states = np.empty((n_t, z0.size))
    states[0] = z0
    j = 0
    while j < n_t - 1:
        end = min(j + block, n_t - 1)
        step_unforced(held.transition(x, states[j]), states, j, end)
        j = end
    return states


def step_unforced(phi: np.ndarray, states: np.ndarray, j: int, end: int) -> None:
    """states[k + 1] = phi states[k] for k = j..end-1, in place (states[j] given)."""
    for k in range(j, end):
        states[k + 1] = phi @ states[k]
