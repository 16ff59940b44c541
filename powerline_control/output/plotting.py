"""Matplotlib figures of the main results; each function returns a ``Figure``.

Figures are made with the object-oriented API on a fresh ``Figure`` (no pyplot state), so they
work headless and in threads.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.ticker
import numpy as np
from matplotlib.figure import Figure

__all__ = [
    "plot_eigenvalues",
    "plot_estimate",
    "plot_envelope",
    "plot_closed_loop",
    "plot_error_along_span",
    "plot_layouts",
    "plot_sensor_count",
    "plot_plan_path",
    "plot_fatigue_record",
]


def _legend_off_the_curves(ax, fontsize: float = 8) -> None:
    """The legend outside the axes, to their right: it never hides a curve."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=fontsize)


def plot_eigenvalues(eigenvalue_sets: dict[str, np.ndarray], emphasis: str | None = None
                     ) -> Figure:
    """DMD eigenvalues in the complex plane with the unit circle (the paper's Figs. 4-5).

    Parameters
    ----------
    eigenvalue_sets : dict of str to ndarray
        Label -> complex eigenvalues.
    emphasis : str or None
        The label of the set drawn on top, larger and opaque; the others small and light, so
        that a few dozen eigenvalues stay visible among hundreds.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = plot_eigenvalues({"A": np.exp(1j * np.linspace(0, 3, 5))})
    >>> len(fig.axes)
    1
    """
    # constrained layout keeps the axis labels inside the canvas (the "Im" label was clipped);
    # wide and low: the square axes and the legend beside them leave no empty band above
    fig = Figure(figsize=(7.0, 4.6), layout="constrained")
    ax = fig.add_subplot()
    theta = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(theta), np.sin(theta), "k-", lw=0.8, label="unit circle")
    for (label, values), marker in zip(eigenvalue_sets.items(), "ox+s^", strict=False):
        values = np.asarray(values)
        shown = {} if emphasis is None else (
            {"ms": 7, "mew": 1.8, "zorder": 4} if label == emphasis else
            {"ms": 3, "alpha": 0.45, "zorder": 2})
        ax.plot(values.real, values.imag, marker, **{"ms": 4, **shown}, mfc="none",
                label=label)
    ax.set(xlabel="Re λ", ylabel="Im λ", aspect="equal")
    _legend_off_the_curves(ax)
    return fig


def plot_estimate(
    t: np.ndarray, truth: np.ndarray, estimate: np.ndarray, nodes: Sequence[int], x: np.ndarray
) -> Figure:
    """Estimate against truth at a few (unmeasured) nodes (the paper's Figs. 7-8).

    Parameters
    ----------
    t : ndarray, shape (n_t,)
        Times, s.
    truth, estimate : ndarray, shape (n_nodes, n_t)
        True and estimated nodal displacements, m.
    nodes : sequence of int
        Nodes to draw.
    x : ndarray, shape (n_nodes,)
        Node positions, m.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> t = np.linspace(0, 1, 50)
    >>> field = np.outer(np.ones(3), np.sin(t))
    >>> len(plot_estimate(t, field, field, [0, 2], np.arange(3.0)).axes)
    2
    """
    fig = Figure(figsize=(8, 2 * len(nodes)))
    axes = fig.subplots(len(nodes), 1, sharex=True, squeeze=False)[:, 0]
    for ax, node in zip(axes, nodes, strict=True):
        ax.plot(t, 1e3 * truth[node], "k-", lw=1.0, label="truth")
        ax.plot(t, 1e3 * estimate[node], "r--", lw=1.0, label="estimate")
        ax.set_ylabel(f"x = {x[node]:.2f} m\ny (mm)")
    _legend_off_the_curves(axes[0])
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    return fig


def plot_envelope(
    x: np.ndarray,
    envelopes: dict[str, np.ndarray],
    markers: dict[str, Sequence[float]] | None = None,
) -> Figure:
    """Amplitude envelopes along the span, with antinodes or sensors marked.

    Parameters
    ----------
    x : ndarray, shape (n_nodes,)
        Node positions, m.
    envelopes : dict of str to ndarray
        Label -> amplitude at each node, m.
    markers : dict of str to sequence of float, optional
        Label -> positions to mark with vertical lines, m.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> x = np.linspace(0, 3, 31)
    >>> len(plot_envelope(x, {"mode 1": np.sin(np.pi * x / 3)}, {"antinode": [1.5]}).axes)
    1
    """
    fig = Figure(figsize=(8, 3.5))
    ax = fig.add_subplot()
    for label, values in envelopes.items():
        ax.plot(x, 1e3 * np.asarray(values), label=label)
    for row, ((label, positions), style) in enumerate(zip(
        (markers or {}).items(), ("k:", "g--", "m-."), strict=False
    )):
        if len(positions) > 30:
            # Dozens of vertical lines would hide the envelope: ticks along the top instead.
            ax.plot(positions, np.full(len(positions), 1.0 - 0.04 * row), "|", color=style[0],
                    ms=8, transform=ax.get_xaxis_transform(), label=label)
            continue
        for i, position in enumerate(positions):
            ax.axvline(
                position, color=style[0], ls=style[1:], lw=1, label=label if i == 0 else None
            )
    ax.set(xlabel="x (m)", ylabel="amplitude (mm)")
    _legend_off_the_curves(ax)
    fig.tight_layout()
    return fig


def plot_error_along_span(
    x: np.ndarray, errors: dict[str, np.ndarray], sensors: Sequence[float] = (),
    chosen: str | None = None,
) -> Figure:
    """RMS estimation error at every node, one curve per layout, with the sensors marked.

    Parameters
    ----------
    x : ndarray, shape (n_nodes,)
        Node positions, m.
    errors : dict of str to ndarray
        Layout name -> RMS error at each node as a fraction of the RMS displacement.
    sensors : sequence of float
        Positions of the chosen sensors, m.
    chosen : str or None
        The layout drawn on top, thicker; the others thin (on a long span their curves
        oscillate over every loop and would hide it).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> x = np.linspace(0, 3, 31)
    >>> len(plot_error_along_span(x, {"chosen": 0.01 * np.ones(31)}, [1.0]).axes)
    1
    """
    fig = Figure(figsize=(8, 3.5), layout="constrained")
    ax = fig.add_subplot()
    for label, values in errors.items():
        style = {} if chosen is None else (
            {"lw": 1.6, "zorder": 4} if label == chosen else {"lw": 0.7, "zorder": 2})
        ax.plot(x, 100 * np.asarray(values), label=label, **style)
    for i, position in enumerate(sensors):
        # black: the layouts' curves take the colour cycle (C2 is green), which has no black
        ax.axvline(position, color="k", ls="--", lw=1, label="chosen sensors" if i == 0 else None)
    ax.set(xlabel="x (m)", ylabel="RMS error (% of RMS displacement)")
    ax.set_yscale("log")
    _legend_off_the_curves(ax)
    return fig


def plot_layouts(
    errors: dict[str, float], positions: dict[str, Sequence[float]], span_length: float
) -> Figure:
    """Sensor layouts compared: their errors (bars) and where their sensors sit.

    Parameters
    ----------
    errors : dict of str to float
        Layout name -> RMS error at the unmeasured nodes, % of RMS displacement.
    positions : dict of str to sequence of float
        Layout name -> sensor positions, m.
    span_length : float
        m.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = plot_layouts({"chosen": 1.0, "first 3": 9.0}, {"chosen": [1, 2], "first 3": [0.1]},
    ...                    3.0)
    >>> len(fig.axes)
    2
    """
    fig = Figure(figsize=(9, 0.6 * len(errors) + 2), layout="constrained")
    left, right = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 2]})
    names = list(errors)
    rows = np.arange(len(names))
    values = np.asarray([errors[n] for n in names], dtype=float)
    left.barh(rows, values, color=["C0"] + ["C7"] * (len(names) - 1))
    left.set_yticks(rows, names, fontsize=8)
    left.invert_yaxis()
    if values.min() > 0 and values.max() / values.min() > 30:
        left.set_xscale("log")  # errors decades apart; a linear axis would hide the smallest
        left.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    left.set_xlim(right=values.max() * (3.0 if left.get_xscale() == "log" else 1.35))
    for row, value in zip(rows, values, strict=True):
        left.annotate(f"{value:.3g} %", (value, row), xytext=(3, 0), textcoords="offset points",
                      va="center", fontsize=8)
    left.set_xlabel("error at unmeasured nodes (%)")
    for row, name in zip(rows, names, strict=True):
        spot = np.asarray(positions[name], dtype=float)
        right.plot(spot, np.full(spot.size, row), "|", ms=12, mew=2)
        if spot.size > 2 and np.ptp(spot) < 0.03 * span_length:
            # many sensors in a few per cent of a long span draw one block: say what it holds
            right.annotate(f"{spot.size} sensors, {spot.min():.3g}-{spot.max():.3g} m",
                           (spot.max(), row), xytext=(6, 0), textcoords="offset points",
                           va="center", fontsize=8)
    right.set_yticks(rows, [""] * len(names))
    right.set_ylim(left.get_ylim())
    # a margin, so that a sensor at a support is not drawn on the frame
    right.set_xlim(-0.02 * span_length, 1.02 * span_length)
    right.set_xlabel("sensor position x (m)")
    return fig


def _plain_tick(value: float, _position=None) -> str:
    """A log axis' tick as a plain number (0.5, not 5x10^-1), labelled at 1, 2 and 5 only."""
    if value <= 0:
        return ""
    mantissa = value / 10.0 ** np.floor(np.log10(value) + 1e-9)
    return f"{value:g}" if any(abs(mantissa - m) < 1e-6 for m in (1, 2, 5)) else ""


def plot_sensor_count(
    k: Sequence[int], predicted: Sequence[float], simulated: Sequence[float] | None = None, *,
    percent: bool = False, labels: tuple[str, str] = ("predicted (Riccati)", "simulated"),
    ylabel: str | None = None, chosen: int | None = None,
) -> Figure:
    """How many sensors: the RMS estimation error against the number of sensors.

    Parameters
    ----------
    k : sequence of int
        Sensor counts.
    predicted : sequence of float
        Predicted steady-state RMS error, m (or % with ``percent``).
    simulated : sequence of float, optional
        The same measured on a simulation, m (or % with ``percent``).
    percent : bool
        The errors are percentages (drawn as given); otherwise metres, drawn in mm.
    labels : (str, str)
        Legend entries of the two curves.
    ylabel : str or None
        The vertical axis' label (default: "RMS estimation error (mm)", or "(%)").
    chosen : int or None
        A count to mark (e.g. the recipe's), with a vertical line.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> len(plot_sensor_count([1, 2, 3], [3e-4, 1e-4, 8e-5], [3.1e-4, 1e-4, 8e-5]).axes)
    1
    >>> ax = plot_sensor_count([1, 2], [5.0, 1.0], [6.0, 1.2], percent=True).axes[0]
    >>> ax.get_ylabel(), ax.get_lines()[0].get_ydata().tolist()
    ('RMS estimation error (%)', [5.0, 1.0])
    """
    scale = 1.0 if percent else 1e3
    fig = Figure(figsize=(7.5, 3.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(k, scale * np.asarray(predicted), "o-", label=labels[0])
    if simulated is not None:
        ax.plot(k, scale * np.asarray(simulated), "x--", label=labels[1])
    if chosen is not None:
        ax.axvline(chosen, color="k", ls=":", lw=1, label=f"{chosen} sensors (the recipe's)")
    default = "RMS estimation error (%)" if percent else "RMS estimation error (mm)"
    ax.set(xlabel="number of sensors", ylabel=ylabel or default)
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(_plain_tick))
    ax.yaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(_plain_tick))
    ax.set_xticks(list(k))
    _legend_off_the_curves(ax)
    return fig


def plot_plan_path(
    x: np.ndarray,
    envelope: np.ndarray,
    t: np.ndarray,
    position: np.ndarray,
    *,
    target: float | None = None,
    target_series: np.ndarray | None = None,
    antinode: float | None = None,
) -> Figure:
    """The robot's planned path (position against time) under the amplitude envelope.

    (For the closed loop's path over the moving envelope see :func:`plot_robot_path`.) The
    horizontal axis (x, m) is shared and zoomed to where the robot travels, a few loop
    lengths either side.

    Parameters
    ----------
    x : ndarray, shape (n_nodes,)
        Node positions, m.
    envelope : ndarray, shape (n_nodes,)
        Amplitude at each node, m.
    t, position : ndarray, shape (n_t,)
        Times (s) and robot positions (m).
    target : float, optional
        Where the robot is sent: the predicted best parked position, m.
    target_series : ndarray, shape (n_t,), optional
        The target at each time (closed loop), m.
    antinode : float, optional
        The estimated antinode nearest the target, m, marked beside it (the best parked position
        need not be an antinode).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> x = np.linspace(0, 3, 61)
    >>> t = np.linspace(0, 1, 11)
    >>> fig = plot_plan_path(x, np.abs(np.sin(3 * x)), t, 1.0 + 0.5 * t, target=1.5)
    >>> len(fig.axes)
    2
    """
    x = np.asarray(x, dtype=float)
    position = np.asarray(position, dtype=float)
    fig = Figure(figsize=(8, 5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [1, 2]})
    top.plot(x, 1e3 * np.asarray(envelope), "k-", lw=1)
    top.set_ylabel("amplitude (mm)")
    bottom.plot(position, t, "C0-", lw=1.5, label="robot")
    if target_series is not None:
        bottom.plot(target_series, t, "k:", lw=1, label="target")
    if target is not None:
        for ax in (top, bottom):
            ax.axvline(target, color="r", ls="--", lw=1)
        bottom.plot([], [], "r--", label="target (best parked position predicted)")
    if antinode is not None:
        for ax in (top, bottom):
            ax.axvline(antinode, color="0.45", ls=":", lw=1)
        bottom.plot([], [], ls=":", color="0.45", label="nearest estimated antinode")
    bottom.plot(position[0], t[0], "go", label="start")
    bottom.set(xlabel="x (m)", ylabel="t (s)")
    _legend_off_the_curves(bottom)
    marked = [v for v in (target, antinode) if v is not None]
    visited = np.concatenate([position[np.isfinite(position)], marked])
    reach = np.ptp(visited) if visited.size else 0.0
    margin = max(0.5 * reach, 0.05 * (x[-1] - x[0]) if x[-1] - x[0] < 20 else 5.0)
    low = max(x[0], visited.min() - margin) if visited.size else x[0]
    high = min(x[-1], visited.max() + margin) if visited.size else x[-1]
    bottom.set_xlim(low, high)
    return fig


def plot_closed_loop(result) -> Figure:
    """Robot position and target, and line vibration, with the robot moving versus parked.

    Parameters
    ----------
    result : ClosedLoopResult
        From :func:`~powerline_control.closed_loop.run_closed_loop`.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> t = np.linspace(0, 1, 11)
    >>> fake = SimpleNamespace(t=t, robot_position=t, target=t, calibration_time=0.2,
    ...                        displacement=np.ones((3, 11)),
    ...                        baseline_displacement=np.ones((3, 11)))
    >>> len(plot_closed_loop(fake).axes)
    2
    """
    fig = Figure(figsize=(8, 5))
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(result.t, result.robot_position, label="robot")
    top.plot(result.t, result.target, "k:", label="target (best parked position predicted)")
    top.axvline(result.calibration_time, color="grey", lw=0.8, label="end of calibration")
    top.set_ylabel("x (m)")
    _legend_off_the_curves(top)
    window = max(int(0.1 / max(result.t[1] - result.t[0], 1e-12)), 1)

    t = np.asarray(result.t)
    window = min(window, t.size)
    # Only full windows, at their centres: a window cut short at an end holds a fraction of a
    # period, whose mean square depends on the phase (the curves hooked at the last sample).
    centres = t[(window - 1) // 2: (window - 1) // 2 + t.size - window + 1]

    def moving_rms(field):
        power = np.mean(np.asarray(field) ** 2, axis=0)
        return np.sqrt(np.convolve(power, np.ones(window) / window, mode="valid"))

    bottom.plot(centres, 1e3 * moving_rms(result.baseline_displacement), label="robot parked")
    bottom.plot(centres, 1e3 * moving_rms(result.displacement), label="closed loop")
    bottom.set(xlabel="t (s)", ylabel="RMS over span (mm)")
    _legend_off_the_curves(bottom)
    fig.tight_layout()
    return fig


# ============================================================================ severity figures
# Energy-balance severity and the robot's value.

__all__ += ["plot_severity", "plot_robot_value"]


def plot_severity(result, ax=None, *, endurance: bool = True) -> Figure:
    """Antinode amplitude and clamp strain against wind speed, one line per configuration.

    Parameters
    ----------
    result : SeverityResult or sequence of SeverityResult
        From :func:`~powerline_control.severity.aeolian_severity` (e.g. no damper, a fixed
        damper, the robot at the antinode: ``robot_value(...).severities``).
    ax : None, Axes or pair of Axes
        None draws a new figure with two panels (amplitude, peak-to-peak strain); one Axes draws
        the amplitude only; a pair draws both into them.
    endurance : bool
        Draw the endurance strain of each result as a horizontal line.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from powerline_control import Span, aeolian_severity
    >>> sev = aeolian_severity(Span.at_rts_fraction(300.0, "drake", 0.2), [1.0, 2.0, 3.0])
    >>> len(plot_severity(sev).axes)
    2
    """
    results = [result] if hasattr(result, "amplitude") else list(result)
    if ax is None:
        fig = Figure(figsize=(8, 6))
        axes = list(fig.subplots(2, 1, sharex=True))
    elif hasattr(ax, "plot"):
        fig, axes = ax.figure, [ax]
    else:
        axes = list(ax)
        fig = axes[0].figure
    # Each configuration its own marker and line style, the first ones larger and open: a
    # configuration that changes nothing must not hide the one under it.
    styles = [("o", "-", 8, "none"), ("s", "--", 4, None), ("^", ":", 5, None),
              ("d", "-.", 5, None)]
    for i, res in enumerate(results):
        marker, dash, size, face = styles[i % len(styles)]
        line = axes[0].plot(res.wind_speed, 1e3 * res.amplitude, marker=marker, ls=dash,
                            ms=size, mfc=face, label=res.label)[0]
        unbalanced = ~np.asarray(res.balanced)
        if unbalanced.any():  # no balance in the curve's range: the value is a bound
            axes[0].plot(res.wind_speed[unbalanced], 1e3 * res.amplitude[unbalanced], "x",
                         color=line.get_color(), ms=9)
        if len(axes) > 1:
            axes[1].semilogy(res.wind_speed, 1e6 * np.maximum(res.strain_pp, 1e-12),
                             marker=marker, ls=dash, ms=size, mfc=face,
                             color=line.get_color(), label=res.label)
    axes[0].set(ylabel="antinode amplitude (mm, 0-pk)")
    _legend_off_the_curves(axes[0])
    if len(axes) > 1:
        if endurance and results:
            limit = results[0].parameters.get("endurance_strain_pp", 150e-6)
            axes[1].axhline(1e6 * limit, color="k", ls=":", lw=1, label="endurance limit")
        axes[1].set(ylabel="clamp bending strain (µε, pk-pk)")
        _legend_off_the_curves(axes[1])
    axes[-1].set_xlabel("wind speed (m/s)")
    fig.tight_layout()
    return fig


def plot_robot_value(value) -> Figure:
    """Fraction of time over the endurance strain and Miner's damage per year, per configuration.

    Parameters
    ----------
    value : RobotValue
        From :func:`~powerline_control.severity.robot_value`.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> fake = SimpleNamespace(configurations=("a", "b"), fraction_over_endurance=np.ones(2),
    ...                        fatigue_index=np.ones(2))
    >>> len(plot_robot_value(fake).axes)
    2
    """
    fig = Figure(figsize=(8, 3.5))
    left, right = fig.subplots(1, 2)
    names = list(value.configurations)
    left.bar(names, 100 * np.asarray(value.fraction_over_endurance), color="C0")
    left.set(ylabel="time over endurance strain (%)")
    right.bar(names, np.maximum(np.asarray(value.fatigue_index), 1e-30), color="C3")
    right.set(yscale="log", ylabel="Miner damage per year")
    for axis in (left, right):
        axis.tick_params(axis="x", labelrotation=15, labelsize=8)
    fig.tight_layout()
    return fig


#: How plot_fatigue_record names the configurations of a FatigueOverRecord.
FATIGUE_LABELS = {"no_damper": "no damper", "fixed_damper": "fixed damper", "robot": "robot"}


def plot_fatigue_record(life, *, bin_width: float = 0.5, days: float = 7.0) -> Figure:
    """Damage per year by wind-speed bin for each configuration, and the robot over a week.

    Top panel: Miner damage per year contributed by each bin of the wind speed normal to the
    line (``bin_width`` m/s over the record's aeolian band), one bar per configuration (no
    damper, fixed damper, robot); a configuration's bars add up to its ``damage_per_year``.
    Middle: that wind speed over the record's first ``days`` (the band shaded). Bottom: where
    the robot is parked at the end of each record over the same days, with the fixed damper's
    position.

    Parameters
    ----------
    life : FatigueOverRecord
        From :func:`~powerline_control.severity.fatigue_over_record`.
    bin_width : float
        Width of the wind-speed bins, m/s (default 0.5).
    days : float
        How much of the record's start the lower panels show, days (default 7: a week).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from powerline_control import Span, WindRecord, fatigue_over_record
    >>> span = Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> rec = WindRecord(np.arange(4) * 600.0, np.array([2.0, 3.0, 2.5, 0.5]),
    ...                  np.full(4, 90.0), np.full(4, 15.0))
    >>> fig = plot_fatigue_record(fatigue_over_record(span, rec))
    >>> [ax.get_ylabel() for ax in fig.axes]  # doctest: +NORMALIZE_WHITESPACE
    ['damage per year from the bin', 'normal wind (m/s)', 'position from the left support (m)']
    """
    low, high = life.parameters["band"]
    if not (isinstance(bin_width, int | float) and bin_width > 0):
        raise ValueError(f"The 'bin_width' parameter must be a positive speed in m/s. Got "
                         f"{bin_width!r}.")
    if not (isinstance(days, int | float) and days > 0):
        raise ValueError(f"The 'days' parameter must be a positive number of days. Got "
                         f"{days!r}.")
    edges = np.arange(low, high + 0.5 * bin_width, bin_width)
    if edges[-1] < high:
        edges = np.append(edges, high)
    centres = 0.5 * (edges[1:] + edges[:-1])
    speed = np.asarray(life.normal_speed)
    names = list(life.configurations)
    fig = Figure(figsize=(8, 8))
    top, middle, bottom = fig.subplots(3, 1, gridspec_kw={"height_ratios": (1.3, 1, 1)})
    width = 0.8 * bin_width / max(len(names), 1)
    # Every vibrating record in a bin: its speed was grouped into the band for the balance
    # (a record just outside by less than the grouping step vibrates), so the bars of a
    # configuration add up to its damage per year.
    vibrating = np.asarray(life.vibrating, dtype=bool)
    index = np.digitize(np.clip(speed[vibrating], edges[0], edges[-1]), edges[1:-1])
    for k, name in enumerate(names):
        damage = np.asarray(life[name].damage)[vibrating]
        per_bin = np.bincount(index, weights=damage, minlength=centres.size)
        top.bar(centres + (k - 0.5 * (len(names) - 1)) * width,
                np.maximum(per_bin / life.years, 1e-30), width,
                label=FATIGUE_LABELS.get(name, name))
    top.set(yscale="log", xlabel="wind speed normal to the line (m/s)",
            ylabel="damage per year from the bin")
    top.set_ylim(bottom=max(1e-12, top.get_ylim()[0]))
    top.legend(loc="upper right", fontsize=8)
    step = float(life.parameters["step"])
    t = np.arange(speed.size) * step / 86400.0
    shown = t < days
    middle.sharex(bottom)
    middle.plot(t[shown], speed[shown], lw=0.8)
    middle.axhspan(low, high, color="0.9", zorder=0)
    middle.set(ylabel="normal wind (m/s)")
    middle.tick_params(labelbottom=False)
    bottom.step(t[shown], np.asarray(life.robot_position)[shown], where="post", lw=0.8,
                label="robot")
    bottom.axhline(life.fixed_position, color="k", ls="--", lw=0.8, label="fixed damper")
    bottom.set(xlabel="time from the record's start (days)",
               ylabel="position from the left support (m)")
    bottom.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return fig

# ------------------------------------------------------------------ closed-loop figures
# (section owned by the closed-loop engineer; appended here so that cli/report can use them)
__all__ += ["plot_closed_loop_envelope", "plot_closed_loop_path"]  # noqa: PLE0605


def plot_closed_loop_envelope(result, ax=None) -> Figure:
    """Displacement envelope along the span over the settled window, before and after.

    One curve per comparison of the result (no robot, parked near the clamp, at the start, at
    the best position, closed loop) with the robot's final and best positions marked.

    Parameters
    ----------
    result : ClosedLoopResult
        From :func:`~powerline_control.closed_loop.run_closed_loop`.
    ax : matplotlib Axes or None
        Axes to draw on; a new figure when None.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> c = SimpleNamespace(name="closed_loop", position=1.0, rms=1e-3, envelope=np.ones(3))
    >>> fake = SimpleNamespace(x=np.arange(3.0), comparisons=(c,), settled_window=(1.0, 2.0),
    ...                        best_position=1.0)
    >>> len(plot_closed_loop_envelope(fake).axes)
    1
    """
    fig = Figure(figsize=(8, 4)) if ax is None else ax.figure
    ax = fig.subplots() if ax is None else ax
    styles = {"no_robot": "k-", "near_clamp": "C7--", "start": "C3-", "best": "C2:",
              "closed_loop": "C0-"}
    for c in result.comparisons:
        if np.all(np.isfinite(c.envelope)):
            label = f"{c.name.replace('_', ' ')} (rms {1e3 * c.rms:.3g} mm)"
            ax.plot(result.x, 1e3 * np.asarray(c.envelope), styles.get(c.name, "-"), label=label)
    final = [c for c in result.comparisons if c.name == "closed_loop"]
    if final:
        ax.axvline(final[0].position, color="C0", lw=0.8)
    if np.isfinite(result.best_position):
        ax.axvline(result.best_position, color="C2", lw=0.8, ls=":")
    t0, t1 = result.settled_window
    ax.set(xlabel="x (m)", ylabel="envelope (mm)",
           title=f"largest |w| over the settled window {t0:.1f}-{t1:.1f} s")
    _legend_off_the_curves(ax, fontsize=7)
    fig.tight_layout()
    return fig


def _zoom_on_the_path(ax, result, mesh, image) -> None:
    """An inset zoomed on the robot's path when it spans under 5 % of the span: a 0.7 m move on
    a 300 m axis is a vertical line with its target hidden under it."""
    x = np.asarray(result.x, dtype=float)
    path = np.asarray(result.robot_position, dtype=float)
    target = np.asarray(result.target, dtype=float)
    where = np.concatenate([path, target[np.isfinite(target)]])
    span = float(np.ptp(x))
    low, high = float(where.min()), float(where.max())
    if span <= 0 or high - low >= 0.05 * span:
        return
    loop = float(getattr(result, "loop_length", float("nan")))
    pad = max(high - low, loop if np.isfinite(loop) else 0.0, 0.005 * span)
    inset = ax.inset_axes([0.56, 0.56, 0.4, 0.4])
    inset.pcolormesh(*mesh, cmap=image.get_cmap(), norm=image.norm, shading="nearest",
                     rasterized=True)
    t = np.asarray(result.t)
    inset.plot(path, t, "c-", lw=1.5)
    inset.plot(target, t, ":", color="tab:green", lw=1.5)
    inset.set_xlim(low - pad, high + pad)
    inset.set_ylim(t[-1], t[0])
    inset.set_title("zoomed on the robot: x (m)", fontsize=7, color="w", pad=2)
    # white: the inset sits on the dark colour map
    inset.tick_params(labelsize=6, colors="w")
    ax.indicate_inset_zoom(inset, edgecolor="w")


def plot_closed_loop_path(result, ax=None) -> Figure:
    """The robot's path over the line's moving envelope (time down, position across).

    The colour is the largest |w| at each node over 0.1 s blocks; the robot's position and its
    target are drawn over it, with the retarget times marked.

    Parameters
    ----------
    result : ClosedLoopResult
        From :func:`~powerline_control.closed_loop.run_closed_loop`.
    ax : matplotlib Axes or None
        Axes to draw on; a new figure when None.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> t = np.linspace(0, 1, 201)
    >>> fake = SimpleNamespace(t=t, x=np.arange(4.0), displacement=np.ones((4, 201)),
    ...                        robot_position=np.ones(201), target=np.ones(201),
    ...                        retarget_times=(0.5,), calibration_time=0.2)
    >>> len(plot_closed_loop_path(fake).axes)
    2
    """
    fig = Figure(figsize=(6, 6)) if ax is None else ax.figure
    ax = fig.subplots() if ax is None else ax
    t = np.asarray(result.t)
    dt = t[1] - t[0]
    block = max(int(round(0.1 / dt)), 1)
    n_blocks = t.size // block
    field = np.abs(np.asarray(result.displacement)[:, : n_blocks * block])
    envelope = field.reshape(field.shape[0], n_blocks, block).max(axis=2)
    mesh = (result.x, t[: n_blocks * block : block] + 0.5 * block * dt, 1e3 * envelope.T)
    image = ax.pcolormesh(*mesh, shading="nearest", cmap="magma",
                          rasterized=True)  # one image in the SVG: no seams between cells
    fig.colorbar(image, ax=ax, label="envelope (mm)")
    ax.plot(result.robot_position, t, "c-", lw=1.5, label="robot")
    # green: visible on the colour map (magma has none) and in the legend's white box
    ax.plot(result.target, t, ":", color="tab:green", lw=1.5, label="target")
    for i, when in enumerate(result.retarget_times):
        # mid grey: visible on the dark colour map and in the legend's white box
        ax.axhline(when, color="0.6", lw=0.6, ls="--", label="new target chosen" if i == 0
                   else None)
    ax.axhline(result.calibration_time, color="grey", lw=1.0, label="end of calibration")
    ax.set(xlabel="x (m)", ylabel="t (s)")
    ax.invert_yaxis()
    _zoom_on_the_path(ax, result, mesh, image)
    # under the axes: the colour bar holds the right-hand side
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=7)
    fig.tight_layout()
    return fig
