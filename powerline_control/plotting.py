"""Matplotlib figures of the main results; each function returns a ``Figure``.

Figures are made with the object-oriented API on a fresh ``Figure`` (no pyplot state), so they
work headless and in threads.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_eigenvalues", "plot_estimate", "plot_envelope", "plot_closed_loop"]


def plot_eigenvalues(eigenvalue_sets: dict[str, np.ndarray]) -> Figure:
    """DMD eigenvalues in the complex plane with the unit circle (the paper's Figs. 4-5).

    Parameters
    ----------
    eigenvalue_sets : dict of str to ndarray
        Label -> complex eigenvalues.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = plot_eigenvalues({"A": np.exp(1j * np.linspace(0, 3, 5))})
    >>> len(fig.axes)
    1
    """
    fig = Figure(figsize=(5, 5))
    ax = fig.add_subplot()
    theta = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(theta), np.sin(theta), "k-", lw=0.8, label="unit circle")
    for (label, values), marker in zip(eigenvalue_sets.items(), "ox+s^", strict=False):
        values = np.asarray(values)
        ax.plot(values.real, values.imag, marker, ms=4, mfc="none", label=label)
    ax.set(xlabel="Re", ylabel="Im", aspect="equal")
    ax.legend(loc="upper left", fontsize=8)
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
    axes[0].legend(loc="upper right", fontsize=8)
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
    for (label, positions), style in zip(
        (markers or {}).items(), ("k:", "g--", "m-."), strict=False
    ):
        for i, position in enumerate(positions):
            ax.axvline(
                position, color=style[0], ls=style[1:], lw=1, label=label if i == 0 else None
            )
    ax.set(xlabel="x (m)", ylabel="amplitude (mm)")
    ax.legend(fontsize=8)
    fig.tight_layout()
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
    top.plot(result.t, result.target, "k:", label="antinode target")
    top.axvline(result.calibration_time, color="grey", lw=0.8)
    top.set_ylabel("x (m)")
    top.legend(fontsize=8)
    window = max(int(0.1 / max(result.t[1] - result.t[0], 1e-12)), 1)

    def moving_rms(field):
        power = np.mean(np.asarray(field) ** 2, axis=0)
        return np.sqrt(np.convolve(power, np.ones(window) / window, mode="same"))

    bottom.plot(result.t, 1e3 * moving_rms(result.baseline_displacement), label="robot parked")
    bottom.plot(result.t, 1e3 * moving_rms(result.displacement), label="closed loop")
    bottom.set(xlabel="t (s)", ylabel="RMS over span (mm)")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    return fig
