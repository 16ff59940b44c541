"""Tuning the robot's absorber to one mode of the line: :func:`tune_damper`.

The modal mass and stiffness the line shows at the attachment point come from the bare
:class:`~powerline_control.fem.LineModel`; Den Hartog's optimum
(:func:`~powerline_control.fem.damper.den_hartog_optimum`, derived in
:mod:`~powerline_control.fem.damper`) then gives the spring and the damper of the
:class:`~powerline_control.fem.MDR`.
"""

from __future__ import annotations

import numbers

import numpy as np

from .._validation import check_bare_line, check_int, check_real, checked_keywords
from ..errors import InputError
from .damper import MDR, den_hartog_optimum
from .model import LineModel

__all__ = ["tune_damper"]

# A position where the mode's displacement is below this fraction of its largest nodal value is
# a node: the effective mass there is (numerically) infinite and the absorber does nothing.
NODE_TOLERANCE = 1e-3



@checked_keywords
def tune_damper(
    model: LineModel, mode: int, position: float | None, mass: float, *, body_mass: float = 0.0
) -> MDR:
    """The robot with its suspended mass tuned to ``mode`` by Den Hartog's optimum at ``position``.

    The modal mass seen at the attachment point is ``M_n / phi_n(x)^2`` (mass-normalised shapes of
    the bare line ``model``); the body mass is added to it (it rides the line rigidly), the mode's
    frequency is lowered accordingly, and the spring and damper follow Den Hartog (1956)::

        mu = mass / (M_n / phi_n(x)^2 + body_mass)
        omega_b = omega_n / sqrt(1 + body_mass phi_n(x)^2 / M_n)
        k = mass (omega_b / (1 + mu))^2,   c = 2 mass omega_b sqrt(3 mu / (8 (1 + mu)^3))

    Parameters
    ----------
    model : LineModel
        The bare line (without a robot: the robot's own masses are accounted for here).
    mode : int
        Mode number, 1 = fundamental.
    position : float or None
        Attachment point, m from the left support (where the robot will damp: an antinode of the
        mode is best). None: the mode's largest antinode (the node of the mesh where the mode
        moves most), which is also the returned robot's position; a robot that starts elsewhere
        is ``dataclasses.replace(robot, position=start)``.
    mass : float
        Suspended (absorber) mass, kg (> 0).
    body_mass : float
        Mass of the robot's body riding the line, kg (>= 0).

    Returns
    -------
    MDR
        ``MDR(position, body_mass, mass, stiffness, damping)``.

    Raises
    ------
    InputError
        If ``mode`` is not a mode of the model, ``position`` lies outside the span or at a node of
        the mode (infinite effective mass: no absorber can be tuned there), or a mass is invalid.

    Examples
    --------
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    >>> robot = plc.tune_damper(model, mode=2, position=0.915, mass=0.04, body_mass=0.03)
    >>> round(robot.stiffness, 1), round(robot.damping, 3)
    (244.7, 1.197)
    >>> plc.tune_damper(model, mode=2, position=None, mass=0.04).position   # its antinode, L/4
    0.915
    """
    if not isinstance(model, LineModel):
        raise InputError(f"The 'model' parameter must be a LineModel. Got {type(model).__name__}.")
    if isinstance(mode, bool) or not isinstance(mode, numbers.Integral):
        raise InputError(f"The 'mode' parameter must be an integer >= 1. Got {mode!r}.")
    check_bare_line(model, "the robot's masses are accounted for by tune_damper")
    mode = check_int("mode", mode, low=1, high=model.n_dofs)
    mass = check_real("mass", mass, low=0.0)
    body_mass = check_real("body_mass", body_mass, low=0.0, low_inclusive=True)
    basis = model.modes(mode)
    shape = basis.shapes[:, mode - 1]
    nodal = model.displacement_map() @ shape
    peak = float(np.max(np.abs(nodal)))
    if position is None:
        # Equal antinodes (a symmetric span) tie to round-off: take the leftmost of them.
        largest = np.flatnonzero(np.abs(nodal) >= (1 - 1e-6) * peak)[0]
        position = float(model.node_positions[largest])
    position = check_real(
        "position", position, low=0.0, low_inclusive=True, high=model.span.length
    )
    phi = float(model.shape_vector(position) @ shape)
    if abs(phi) < NODE_TOLERANCE * peak:
        raise InputError(
            f"The 'position' parameter ({position:g} m) is at a node of mode {mode} "
            f"(|phi(x)| = {abs(phi):.3g}, {abs(phi) / peak:.2g} of its peak): the modal mass "
            "seen there is infinite and no absorber can be tuned to it. Choose a position away "
            "from the mode's nodes (an antinode is best)."
        )
    effective_mass = 1.0 / phi**2 + body_mass  # M_n = 1 (mass-normalised shapes)
    omega_b = float(basis.omega[mode - 1]) / np.sqrt(1.0 + body_mass * phi**2)
    mu = mass / effective_mass
    f_opt, zeta_opt = den_hartog_optimum(mu)
    return MDR(
        position,
        body_mass=body_mass,
        suspended_mass=mass,
        stiffness=mass * (f_opt * omega_b) ** 2,
        damping=2 * zeta_opt * mass * omega_b,
    )
