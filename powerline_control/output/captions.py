"""Captions generated from what a figure draws: panel count, colour map or not, axes, lines.

:func:`describe_figure` reads a matplotlib ``Figure`` back (panels, axis labels and directions,
line styles and labels, colour bars); :func:`figure_caption` writes the sentence the report puts
under it, so a caption cannot describe a figure other than the one it sits under.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure  # noqa: F401  (the doctests draw on one)

__all__ = ["describe_figure", "figure_caption"]


def _panels(fig) -> list:
    """The figure's data panels (colour bars excluded), top to bottom then left to right."""
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"
              and not hasattr(ax, "_colorbar")]
    return sorted(panels, key=lambda ax: (-round(ax.get_position().y1, 2),
                                          round(ax.get_position().x0, 2)))


def _colour_mapped(ax) -> bool:
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection

    for artist in [*ax.collections, *ax.images]:
        if isinstance(artist, ScalarMappable) and not isinstance(artist, LineCollection) \
                and artist.get_array() is not None and np.size(artist.get_array()) > 1:
            return True
    return False


def _categories(axis) -> list | None:
    """The category names of an axis labelled by fixed tick labels (a bar per row), else None.

    Blank names (a panel that shares another's rows) are kept as empty strings.
    """
    formatter = axis.get_major_formatter()
    locations = list(axis.get_ticklocs())
    names = [_plain(formatter(v, i)) for i, v in enumerate(locations)]
    if not names:
        return None
    if all(not name for name in names):
        return names

    def number(name: str) -> bool:
        try:
            float(name.replace("\N{MINUS SIGN}", "-").replace("$", "").replace("%", ""))
        except ValueError:
            return False
        return True

    # Any numeric name (a value axis) or a maths label (a log axis's 10^k) is not a category.
    return None if any(not name or number(name) or "$" in name for name in names) else names


def _plain(label: str) -> str:
    # A line break before a parenthesis (a unit on its own line) reads as a space.
    text = str(label).replace("\n(", " (").replace("\n", ", ")
    return " ".join(text.split())


_LINESTYLES = {"-": "solid", "--": "dashed", ":": "dotted", "-.": "dash-dot"}


def _style(handle) -> str:
    """How a legend entry is drawn, in words ("dashed", "markers", "" when unknown)."""
    from matplotlib.lines import Line2D

    if not isinstance(handle, Line2D):
        return ""
    line = _LINESTYLES.get(handle.get_linestyle(), "")
    marker = handle.get_marker()
    has_marker = marker not in (None, "", "None", " ")
    if line and has_marker:
        return f"({line}, markers)"
    if has_marker:
        return "(markers)"
    return f"({line})" if line and line != "solid" else ""


def describe_figure(fig) -> dict:
    """What a figure draws, read from the figure object: panels, axes, curves, colour.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.

    Returns
    -------
    dict
        ``n_panels``; ``panels``: per panel ``xlabel``, ``ylabel``, ``legend`` (labels),
        ``y_inverted``, ``x_inverted``, ``colour_map``, ``y_categories`` (the names of a
        vertical axis labelled by fixed tick labels, one per row, or None) and ``y_ticks``;
        ``colorbars``: their labels.

    Examples
    --------
    >>> fig = Figure()
    >>> ax = fig.add_subplot()
    >>> _ = ax.plot([0, 1], [0, 1], label="a")
    >>> _ = ax.set(xlabel="x (m)", ylabel="y (mm)")
    >>> _ = ax.legend()
    >>> describe_figure(fig)["panels"][0]["legend"]
    ['a']
    """
    panels = []
    ordered = _panels(fig)
    for ax in ordered:
        xlabel = ax.get_xlabel()
        if not xlabel:  # a shared axis is labelled once, under the bottom panel
            xlabel = next((other.get_xlabel() for other in ordered if other is not ax
                           and other.get_xlabel()
                           and ax.get_shared_x_axes().joined(ax, other)), "")
        legend = ax.get_legend()
        labels = []
        if legend:
            handles = getattr(legend, "legend_handles", None) or legend.legendHandles
            for text, handle in zip(legend.get_texts(), handles, strict=False):
                style = _style(handle)
                if _plain(text.get_text()):
                    labels.append(_plain(text.get_text()) + (f" {style}" if style else ""))
        panels.append({"xlabel": _plain(xlabel), "ylabel": _plain(ax.get_ylabel()),
                       "legend": labels, "y_inverted": bool(ax.yaxis_inverted()),
                       "x_inverted": bool(ax.xaxis_inverted()),
                       "colour_map": _colour_mapped(ax),
                       "y_categories": _categories(ax.yaxis),
                       "y_ticks": [float(v) for v in ax.get_yticks()]})
    bars = [_plain(ax.get_ylabel() or ax.get_xlabel()) for ax in fig.axes
            if ax.get_label() == "<colorbar>" or hasattr(ax, "_colorbar")]
    for legend in fig.legends:
        panels and panels[0]["legend"].extend(_plain(t.get_text()) for t in legend.get_texts())
    return {"n_panels": len(panels), "panels": panels, "colorbars": bars}


_WORDS = {1: "One panel", 2: "Two panels", 3: "Three panels", 4: "Four panels"}


def _where(i: int, n: int, panels: list) -> str:
    if n == 1:
        return ""
    side = len({round(p, 2) for p in panels}) > 1 if panels else False
    if side:
        return ("left", "right", "third", "fourth")[min(i, 3)]
    return ("top", "bottom")[i] if n == 2 else ("top", "middle", "bottom")[i] if n == 3 \
        else f"panel {i + 1}"


def _axes_text(i: int, panels: list, wheres: list) -> str:
    """'y against x' for panel i; a panel without a y label is described by its rows (its
    category tick labels, or the rows of the panel whose categories it shares)."""
    panel = panels[i]
    ylabel, xlabel = panel["ylabel"], panel["xlabel"]
    if ylabel:
        return f"{ylabel} against {xlabel}" if xlabel else ylabel
    what = xlabel or "the data"
    names = panel["y_categories"]
    if names and any(names):
        return f"{what} for each of " + ", ".join(name for name in names if name)
    if names is not None:   # blank row names: the rows of a panel with the same ticks
        for j, other in enumerate(panels):
            if j != i and other["y_categories"] and any(other["y_categories"]) \
                    and other["y_ticks"] == panel["y_ticks"]:
                return f"{what} for the same rows as the {wheres[j] or 'other'} panel"
        return f"{what}, one row per category"
    return f"the data against {xlabel}" if xlabel else "the data"


def figure_caption(fig, purpose: str, look_for: str = "") -> str:
    """A caption generated from what ``fig`` draws, then what it is for and what to look at.

    The generated part says how many panels there are, each panel's axes (vertical against
    horizontal), the curves its legend names, which way an inverted axis runs, and the colour
    scale when there is one (and says there is none otherwise only if asked by the figure).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    purpose : str
        One sentence: what the figure compares.
    look_for : str
        What to look for (prefixed by "Look for").

    Returns
    -------
    str

    Examples
    --------
    >>> fig = Figure()
    >>> top, bottom = fig.subplots(2, 1)
    >>> _ = top.set(xlabel="t (s)", ylabel="y (mm)"); _ = bottom.set(ylabel="x (m)")
    >>> figure_caption(fig, "Motion.", "the curves meeting")[:39]
    'Motion. Two panels: top, y (mm) against'

    A panel without a y label is described by its rows (bars named by tick labels):

    >>> fig = Figure()
    >>> left, right = fig.subplots(1, 2)
    >>> _ = left.barh([0, 1], [1.0, 2.0]); _ = left.set_yticks([0, 1], ["a", "b"])
    >>> _ = right.set_yticks([0, 1], ["", ""]); _ = left.set_xlabel("error (%)")
    >>> _ = right.set_xlabel("x (m)")
    >>> figure_caption(fig, "Layouts.")
    'Layouts. Two panels: left, error (%) for each of a, b; right, x (m) for the same rows as \
the left panel.'
    """
    facts = describe_figure(fig)
    n = facts["n_panels"]
    x0 = [ax.get_position().x0 for ax in _panels(fig)]
    parts = []
    for i, panel in enumerate(facts["panels"]):
        where = _where(i, n, x0)
        text = _axes_text(i, facts["panels"], [_where(j, n, x0) for j in range(n)])
        if panel["legend"]:
            text += " (" + ", ".join(panel["legend"]) + ")"
        # An unlabelled inverted axis lists categories top to bottom: nothing to say about it.
        if panel["y_inverted"] and panel["ylabel"]:
            text += f"; {panel['ylabel']} increases downward"
        if panel["x_inverted"] and panel["xlabel"]:
            text += f"; {panel['xlabel']} increases to the left"
        parts.append(f"{where}, {text}" if where else text)
    head = _WORDS.get(n, f"{n} panels")
    body = f"{head}: " + "; ".join(parts) + "." if n else ""
    colour = ""
    if facts["colorbars"]:
        colour = " Colour: " + ", ".join(facts["colorbars"]) + " (scale beside the panel)."
    text = " ".join(p for p in (purpose.strip(), body + colour) if p)
    if look_for:
        text += f" Look for {look_for.strip().rstrip('.')}."
    return text
