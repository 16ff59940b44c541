"""The report's shared formatting: one unit per quantity (mm, per cent), positions with their
nodes, and the figure spec handed to the report writer.

Used by every section of the report (:mod:`.summary` and the ``summary_*`` modules) and by the
calibration verb (:mod:`.calibrate`); it imports nothing of the scenario, so the sections can
share it without importing one another.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["mm", "percent", "positions_text"]


def mm(value: float) -> str:
    """A displacement in millimetres, 4 significant digits (``0.01923 mm``)."""
    return f"{1e3 * value:.4g} mm"


def percent(fraction: float) -> str:
    """A fraction as per cent, 3 significant digits (``0.523 %``)."""
    return f"{100 * fraction:.3g} %"


def positions_text(positions: Sequence[float], nodes: Sequence[int] | None = None,
                   limit: int = 8) -> str:
    """Positions in metres (node indices beside them when given); long lists summarised."""
    import numpy as np

    values = np.asarray(positions, dtype=float)
    order = np.argsort(values, kind="stable")
    values = values[order]
    if values.size > limit:
        spacing = float(np.median(np.diff(values)))
        return (f"{values.size} positions from {values[0]:.3g} to {values[-1]:.3g} m, "
                f"typically {spacing:.3g} m apart")
    text = ", ".join(f"{v:.4g}" for v in values) + " m"
    if nodes is not None:
        ordered = [int(nodes[i]) for i in order]
        text += f" (nodes {', '.join(str(i) for i in ordered)})"
    return text


def _figure(name: str, draw, purpose: str, look_for: str) -> dict:
    return {"name": name, "draw": draw, "purpose": purpose, "look_for": look_for}


def _plotting():
    from ..output import plotting

    return plotting
