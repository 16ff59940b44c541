"""The ``powerline-control`` command.

``powerline-control run [SCENARIO.toml] [--out DIR]`` runs the main job on a scenario (the
built-in default when none is given) and prints a summary; ``powerline-control scenario`` prints
the default scenario as TOML to start a file from.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .config import Scenario, load_scenario, scenario_to_toml
from .errors import PowerlineControlError
from .simulate import simulate

__all__ = ["main", "run_scenario"]


def _line(label: str, value: str) -> str:
    return f"  {label:<34} {value}"


def run_scenario(scenario: Scenario, out: Path | None = None, echo=print) -> dict:
    """Run the main job on ``scenario``: model, simulation and the analysis chain.

    Parameters
    ----------
    scenario : Scenario
        The study (see :func:`~powerline_control.config.load_scenario`).
    out : Path or None
        Folder for the results (created if missing); None writes nothing.
    echo : callable
        Where the printed summary goes (``print`` by default).

    Returns
    -------
    dict
        The headline numbers, as printed.

    Examples
    --------
    >>> from powerline_control.config import load_scenario
    >>> summary = run_scenario(load_scenario(text="[model]\\nn_elements = 20\\n"
    ...                                      "[simulation]\\nduration = 1.0"), echo=lambda s: None)
    >>> summary["n_nodes"]
    21
    """
    summary: dict = {}
    span = scenario.span.build()
    model = scenario.model.build(span)
    start = time.perf_counter()
    frequencies = model.natural_frequencies(min(5, model.n_dofs))
    echo("Span")
    echo(_line("length, tension", f"{span.length:g} m, {span.tension:g} N"))
    echo(_line("conductor", f"{span.conductor.name}, m = {span.conductor.mass_per_length:.4g} "
                            f"kg/m, EI = {span.conductor.ei:g} N m^2, d = "
                            f"{1e3 * span.conductor.diameter:g} mm"))
    echo(_line("model", f"{model.n_elements} elements, {model.n_nodes} nodes, "
                        f"{model.n_dofs} DOFs, supports {model.bc}"))
    echo(_line("first natural frequencies (Hz)", ", ".join(f"{f:.3f}" for f in frequencies)))
    summary.update(n_nodes=model.n_nodes, frequencies=frequencies.tolist())

    force = scenario.forcing.build()
    sim = scenario.simulation
    snap = simulate(model, force, duration=sim.duration, dt=sim.dt,
                    noise_fraction=sim.noise_fraction, seed=sim.seed)
    elapsed = time.perf_counter() - start
    rms = float(np.sqrt(np.mean(snap.true_displacement**2)))
    peak_node = int(np.argmax(np.abs(snap.true_displacement).max(axis=1)))
    echo("Simulation")
    echo(_line("load", repr(force)))
    echo(_line("samples", f"{snap.t.size} at dt = {snap.dt:g} s ({snap.n_modes} modes kept)"))
    echo(_line("RMS / peak displacement", f"{1e3 * rms:.4g} mm / "
                                          f"{1e3 * np.abs(snap.true_displacement).max():.4g} mm"))
    echo(_line("largest motion at", f"x = {snap.x[peak_node]:.3f} m (node {peak_node})"))
    echo(_line("sensor noise std", f"{1e3 * snap.noise_std:.3g} mm"))
    echo(_line("model + simulation time", f"{elapsed:.2f} s"))
    summary.update(rms_displacement=rms, peak_position=float(snap.x[peak_node]))
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "scenario.toml").write_text(scenario_to_toml(scenario))
        echo(_line("results written to", str(out)))
    return summary


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="powerline-control", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="run the main job on a scenario")
    run.add_argument("scenario", nargs="?", type=Path,
                     help="TOML scenario file (default: the built-in paper lab scenario)")
    run.add_argument("--out", type=Path, default=None, help="folder for results and figures")
    commands.add_parser("scenario", help="print the default scenario as TOML")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``powerline-control`` command; returns the exit status.

    Parameters
    ----------
    argv : sequence of str or None
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 on bad input or a reported numerical failure.

    Examples
    --------
    >>> main(["scenario"])  # doctest: +ELLIPSIS
    # powerline_control scenario ...
    0
    """
    args = _build_parser().parse_args(argv)
    if args.command == "scenario":
        print(scenario_to_toml(load_scenario()), end="")
        return 0
    try:
        scenario = load_scenario(args.scenario)
        run_scenario(scenario, out=args.out)
    except PowerlineControlError as exc:
        print(f"powerline-control: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
