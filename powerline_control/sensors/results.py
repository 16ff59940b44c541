"""The results of sensor selection: the chosen layout with its bound and certificate
(:class:`SensorSelection`), a baseline layout (:class:`Baseline`) and the sensor-count study
(:class:`SensorCountStudy`). Plain frozen records; nothing here computes a layout.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._results import Result
from .relaxation import _HEURISTIC


# ----------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class Baseline:
    """One comparison layout.

    Attributes
    ----------
    name : str
        ``"first-k"``, ``"evenly-spaced"``, ``"greedy"``, ``"qr-pivoting"``, ``"random-mean"``,
        ``"random-best"`` or ``"brute-force"``.
    nodes : tuple of int or None
        Candidate indices (None for the random mean).
    objective : float
        Exact criterion of the layout (``inf`` / ``-inf`` if the layout cannot estimate the state).

    Examples
    --------
    >>> Baseline("first-k", (0, 1, 2), 1.5e-6).nodes
    (0, 1, 2)
    """

    name: str
    nodes: tuple[int, ...] | None
    objective: float


@dataclass(frozen=True, eq=False)
class SensorSelection(Result):
    """Result of :func:`select_sensors`.

    Attributes
    ----------
    nodes : tuple of int
        Chosen candidate indices (outputs of ``sys``), ascending.
    positions : tuple of float or None
        Their positions in metres, when known.
    objective : float
        Exact criterion of ``nodes`` in physical units: for ``"kalman"`` the trace of the
        steady-state posterior covariance of the weighted states (m^2 for displacements), for
        ``"gramian"`` / ``"reconstruction"`` a log determinant, for ``"min-eig"`` an eigenvalue.
    bound : float
        Certificate: no layout satisfying the constraints does better than this (a lower bound
        for a minimised criterion, an upper bound for a maximised one). Equal to ``objective``
        when ``certificate`` is ``"exhaustive"``.
    gap : float
        Relative distance to the bound, >= 0, an upper bound on the distance to the best layout:
        ``(objective - bound) / objective`` for ``"kalman"``; ``(bound - objective) / bound`` for
        ``"min-eig"``; ``1 - exp(-(bound - objective) / d)`` for the log determinants (the gap in
        the geometric-mean eigenvalue ``det^(1/d)``, ``d`` the matrix size). 0 when
        ``certificate`` is ``"exhaustive"`` (the layout is proved optimal).
    weights : numpy.ndarray
        Relaxed weights ``z`` (read-only), one per candidate.
    criterion : str
        The criterion optimised.
    sense : str
        ``"minimize"`` or ``"maximize"``.
    k : int
        Number of sensors.
    baselines : Mapping[str, Baseline]
        Comparison layouts (they ignore the practical constraints: they are the obvious layouts
        a report compares against). ``"brute-force"`` (present when ``C(m, k)`` is small enough)
        does honour the constraints and is the true optimum.
    relaxation_value : float
        Optimal value of the relaxation as reported by the solver (physical units); NaN when
        every solver failed.
    solver : str
        cvxpy solver whose relaxation was used (``"none"`` when every installed conic solver
        failed on it).
    solver_status : str
        Its status (``"failed"`` when none succeeded).
    certificate : str
        What backs ``bound``, always checked rather than trusted:

        * ``"exhaustive"``: every feasible layout was evaluated on the exact criterion, so
          ``nodes`` is the optimum, ``bound`` equals ``objective`` and ``gap`` is 0. Used when
          ``C(m, k)`` is within ``brute_force_limit``, and also, when the relaxation failed on
          every solver and ``brute_force_limit=0``, within the default limit (100,000);
        * ``"convexity"``: the bound comes from the convexity inequality at the relaxed weights
          (the solver's, or a feasible point when every solver failed) with an exact linear
          program, valid whatever the solver's accuracy;
        * ``"solver"``: the solver's optimal value (valid up to its tolerance);
        * ``"none: heuristic"``: no bound could be computed; ``bound`` is the trivial one
          (0 for ``"kalman"``, ``inf`` for a maximised criterion) and ``gap`` is 1. The layout
          comes from greedy and swap searches on the exact criterion.
    n_exact_evaluations : int
        Exact criterion evaluations used (Riccati solves for ``"kalman"``).
    runtime : float
        Wall-clock seconds.
    solver_attempts : tuple of str
        What each solver tried did, in order (e.g. ``("CLARABEL: failed (...)", "SCS:
        optimal")``): the requested solver first, then the other installed conic solvers.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> import powerline_control as plc
    >>> sys = ct.ss(np.diag([0.9, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0)
    >>> sel = plc.select_sensors(sys, k=1, Q=np.eye(2), R=0.1)
    >>> sel.nodes, sel.criterion, sel.sense, sorted(sel.baselines)[:2]
    ((0,), 'kalman', 'minimize', ['brute-force', 'evenly-spaced'])
    """

    nodes: tuple[int, ...]
    positions: tuple[float, ...] | None
    objective: float
    bound: float
    gap: float
    weights: np.ndarray
    criterion: str
    sense: str
    k: int
    baselines: Mapping[str, Baseline]
    relaxation_value: float
    solver: str
    solver_status: str
    certificate: str
    n_exact_evaluations: int
    runtime: float
    solver_attempts: tuple[str, ...] = ()

    def summary(self) -> str:
        """A short markdown report: the layout, its certificate and the baselines.

        Returns
        -------
        str
            Markdown text.
        """
        better = "lower" if self.sense == "minimize" else "higher"
        pct = f"{100 * self.gap:.3g} %"
        # What the gap guarantees (see the ``gap`` attribute): a relative distance to the optimum.
        if self.certificate == "exhaustive":
            claim = ("proved optimal by exhaustive search over every feasible layout, within 0 % "
                     "of the best possible layout")
        elif self.certificate == _HEURISTIC:
            claim = ("not certified: no solver could bound the optimum, the layout comes from "
                     "greedy and swap searches on the exact criterion")
        elif self.sense == "minimize":
            claim = (f"certified: the best possible layout's objective lies within {pct} below "
                     "this one's")
        else:
            quantity = "objective" if self.criterion == "min-eig" else "det^(1/d)"
            claim = (f"certified: this layout's {quantity} lies within {pct} below the best "
                     "possible layout's")
        lines = [
            f"criterion {self.criterion!r} ({better} is better), k = {self.k}",
            f"nodes {list(self.nodes)}: objective {self.objective:.6g}, bound {self.bound:.6g}, "
            f"gap {pct}: {claim}",
            "",
            "| layout | objective |",
            "|---|---|",
        ]
        lines += [f"| {b.name} | {b.objective:.6g} |" for b in self.baselines.values()]
        return "\n".join(lines)


@dataclass(frozen=True, eq=False)
class SensorCountStudy:
    """Result of :func:`sensor_count_study`: the criterion and the RMS error against ``k``.

    Attributes
    ----------
    k : tuple of int
        Sensor counts studied.
    objective : numpy.ndarray
        Exact steady-state posterior trace of the optimised layout for each ``k``.
    rms_error : numpy.ndarray
        ``sqrt(objective / q)``: the predicted RMS estimation error per weighted state.
    simulated_rms_error : numpy.ndarray
        The RMS error of a steady-state Kalman filter on a seeded simulation of the model.
    layouts : tuple of tuple of int
        The optimised layout for each ``k``.
    target_error : float or None
        The RMS error asked for.
    smallest_k : int or None
        Smallest ``k`` whose predicted RMS error is at most ``target_error`` (None if none).

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> import powerline_control as plc
    >>> sys = ct.ss(np.diag([0.9, 0.5]), np.zeros((2, 0)), np.eye(2), np.zeros((2, 0)), 1.0)
    >>> study = plc.sensors.sensor_count_study(sys, [1, 2], Q=np.eye(2), R=0.1, target_error=1.0,
    ...                                n_steps=50)
    >>> study.smallest_k, study.layouts
    (1, ((0,), (0, 1)))
    """

    k: tuple[int, ...]
    objective: np.ndarray
    rms_error: np.ndarray
    simulated_rms_error: np.ndarray
    layouts: tuple[tuple[int, ...], ...]
    target_error: float | None
    smallest_k: int | None
