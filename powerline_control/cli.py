"""The ``powerline-control`` command.

``powerline-control run [SCENARIO.toml] [--out DIR]`` runs the main job on a scenario (the
built-in default when none is given): model, simulation, identification, sensor placement,
estimation, antinode, motion plan and the closed loop, printing a summary and, with ``--out``,
writing figures, an HTML report, the identified model and the numbers as JSON.
``powerline-control scenario`` prints the default scenario as TOML to start a file from.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__, plotting
from .antinode import locate_antinodes, nearest_antinode
from .closed_loop import run_closed_loop
from .config import Scenario, load_scenario, scenario_to_toml
from .errors import InputError, PowerlineControlError
from .estimate import KalmanFilter, estimation_accuracy
from .fem import MDR
from .identify import fit_dmd, select_alpha
from .io import save_model
from .plan import RobotLimits, plan_motion
from .report import write_report
from .sensors import select_sensors
from .simulate import simulate

__all__ = ["main", "run_scenario"]

#: Fraction of the simulated record used for identification; the rest tests the estimator.
TRAIN_FRACTION = 0.6


@dataclass
class _Report:
    """Collects the printed lines, the report sections, their figures and the headline numbers.

    A stage hands each figure over as a function that draws it, so figures cost nothing unless
    an output folder asks for them.
    """

    echo: Callable[[str], object]
    sections: list = field(default_factory=list)
    figures: dict = field(default_factory=dict)
    numbers: dict = field(default_factory=dict)

    def section(self, title: str, rows: Sequence[tuple[str, str]], figures: dict | None = None):
        self.echo(title)
        for label, value in rows:
            self.echo(f"  {label:<40} {value}")
        self.figures.update(figures or {})
        self.sections.append({"title": title, "rows": rows, "figures": list(figures or {})})


def _mm(value: float) -> str:
    return f"{1e3 * value:.4g} mm"


def _stage_model(scenario: Scenario, report: _Report):
    span = scenario.span.build()
    model = scenario.model.build(span)
    frequencies = model.natural_frequencies(min(5, model.n_dofs))
    cond = span.conductor
    report.section(
        "Span and model",
        [
            ("length, tension", f"{span.length:g} m, {span.tension:g} N"),
            (
                "conductor",
                f"{cond.name}: m = {cond.mass_per_length:.4g} kg/m, EI = {cond.ei:g} N m^2, "
                f"d = {1e3 * cond.diameter:g} mm",
            ),
            (
                "model",
                f"{model.n_elements} elements, {model.n_nodes} nodes, {model.n_dofs} DOFs, "
                f"supports {model.bc[0]}/{model.bc[1]}",
            ),
            ("first natural frequencies", ", ".join(f"{f:.3f}" for f in frequencies) + " Hz"),
        ],
    )
    report.numbers.update(n_nodes=model.n_nodes, frequencies_hz=frequencies.tolist())
    return span, model


def _stage_data(scenario: Scenario, model, report: _Report):
    sim = scenario.simulation
    force = scenario.forcing.build()
    start = time.perf_counter()
    snap = simulate(
        model,
        force,
        duration=sim.duration,
        dt=sim.dt,
        noise_fraction=sim.noise_fraction,
        seed=sim.seed,
    )
    elapsed = time.perf_counter() - start
    envelope = np.abs(snap.true_displacement[:, -snap.t.size // 4 :]).max(axis=1)
    report.section(
        "Simulated data",
        [
            ("load", repr(force)),
            (
                "samples",
                f"{snap.t.size} at dt = {snap.dt:g} s ({snap.n_modes} modes kept, {elapsed:.2f} s)",
            ),
            (
                "RMS / peak displacement",
                f"{_mm(np.sqrt(np.mean(snap.true_displacement**2)))} / {_mm(envelope.max())}",
            ),
            ("sensor noise std", _mm(snap.noise_std)),
        ],
    )
    return force, snap


def _stage_identify(scenario: Scenario, snap, report: _Report):
    cfg = scenario.identification
    n_train = int(TRAIN_FRACTION * snap.t.size)
    train = snap.displacement[:, :n_train]
    if cfg.alpha == "auto":
        curve = select_alpha(train, snap.dt, delays=cfg.delays, rank=cfg.rank)
        alpha = curve.best_stable_alpha if curve.best_stable_alpha is not None else curve.best_alpha
        dmd = fit_dmd(
            train,
            snap.dt,
            alpha=alpha,
            delays=cfg.delays,
            rank=cfg.rank,
            alpha_mode=curve.alpha_mode,
        )
        chosen = f"{alpha:.3g} ({curve.alpha_mode}; = {dmd.alpha:.3g} absolute), by held-out error"
    else:
        dmd = fit_dmd(train, snap.dt, alpha=float(cfg.alpha), delays=cfg.delays, rank=cfg.rank)
        chosen = f"{dmd.alpha:.3g} (absolute, from the scenario)"
    paper = fit_dmd(train, snap.dt, alpha=0.1, delays=1)
    with warnings.catch_warnings(record=True) as caught:
        # On noise-free data plain DMD inverts round-off and says so; here that is the point.
        warnings.simplefilter("always")
        plain = fit_dmd(train, snap.dt, alpha=0.0, delays=1)
    plain_note = " (ill-conditioned: it inverts round-off)" if caught else ""
    report.section(
        "Identification (DMD)",
        [
            ("this run", f"delays = {cfg.delays}, rank = {cfg.rank or 'full'}, alpha = {chosen}"),
            (
                "spectral radius / unstable eigenvalues",
                f"{dmd.spectral_radius:.6f} / {dmd.stability_report(warn=False).n_unstable}",
            ),
            ("paper recipe (delays 1, alpha 0.1)", f"spectral radius {paper.spectral_radius:.6f}"),
            ("plain DMD (alpha 0)", f"spectral radius {plain.spectral_radius:.6f}{plain_note}"),
        ],
        figures={
            "eigenvalues.png": lambda: plotting.plot_eigenvalues(
                {"this run": dmd.eigenvalues, "paper recipe": paper.eigenvalues}
            )
        },
    )
    report.numbers.update(alpha=dmd.alpha, spectral_radius=dmd.spectral_radius)
    return dmd, n_train


def _stage_estimate(scenario: Scenario, dmd, snap, n_train: int, report: _Report):
    # Noise-free data still needs a measurement variance for a well-posed Riccati equation:
    # assume sensors resolve 0.01 % of the RMS motion.
    rms = float(np.sqrt(np.mean(snap.true_displacement**2)))
    noise_var = max(snap.noise_std**2, (1e-4 * rms) ** 2)
    candidates = dmd.to_statespace(measured=list(range(snap.x.size)))
    if scenario.estimation.sensors is not None:
        sensors = list(scenario.estimation.sensors)
        if max(sensors) >= snap.x.size:
            raise InputError(
                f"estimation.sensors names node {max(sensors)}, but the model has "
                f"{snap.x.size} nodes (0..{snap.x.size - 1})."
            )
        how = "from the scenario"
    else:
        # The supports never move: a sensor there would measure only noise.
        half_element = 0.5 * (snap.x[1] - snap.x[0])
        supports = [(0.0, half_element), (snap.x[-1] - half_element, snap.x[-1])]
        selection = select_sensors(
            candidates,
            k=scenario.estimation.n_sensors,
            criterion="kalman",
            Q=dmd.residual_covariance,
            R=noise_var,
            positions=snap.x,
            forbidden=supports,
        )
        sensors = list(selection.nodes)
        how = (
            f"optimised (Kalman criterion; {selection.certificate} certificate: at most "
            f"{100 * selection.gap:.2g} % from the best possible layout)"
        )
    held_out = slice(n_train, None)
    results = {}
    layouts = {"chosen": sensors, "paper (first 13 nodes)": list(range(min(13, snap.x.size)))}
    for name, nodes in layouts.items():
        kf = KalmanFilter(
            dmd.to_statespace(measured=nodes),
            Q=dmd.residual_covariance,
            R=noise_var,
            steady_state=True,
            field_map=dmd.field_map,
        )
        estimate = kf.filter(snap.displacement[nodes, held_out])
        accuracy = estimation_accuracy(
            estimate.field, snap.true_displacement[:, held_out], measured=nodes, discard=200
        )
        results[name] = (estimate, accuracy)
    chosen_accuracy = results["chosen"][1]
    paper_accuracy = results["paper (first 13 nodes)"][1]
    report.section(
        "Estimation (Kalman filter on held-out data)",
        [
            (
                "sensors",
                f"nodes {sensors} at x = {', '.join(f'{snap.x[i]:.2f}' for i in sensors)} m, {how}",
            ),
            (
                "RMS error, unmeasured nodes (chosen)",
                f"{100 * chosen_accuracy.relative_rms_error_unmeasured:.3g} % of RMS displacement",
            ),
            (
                "RMS error, unmeasured nodes (paper's 13)",
                f"{100 * paper_accuracy.relative_rms_error_unmeasured:.3g} % of RMS displacement",
            ),
        ],
        figures={"estimate.png": lambda: _estimate_figure(snap, n_train, results, sensors)},
    )
    report.numbers.update(
        sensors=sensors,
        error_unmeasured=chosen_accuracy.relative_rms_error_unmeasured,
        error_unmeasured_paper_layout=paper_accuracy.relative_rms_error_unmeasured,
    )
    return sensors, results["chosen"][0]


def _estimate_figure(snap, n_train: int, results: dict, sensors: list):
    """Estimate against truth at three unmeasured nodes (the paper's Figs. 7-8)."""
    spread = np.linspace(0, snap.x.size - 1, 5).astype(int)[1:-1]
    unmeasured = [i for i in spread if i not in sensors] or [snap.x.size // 2]
    held_out = slice(n_train, None)
    return plotting.plot_estimate(
        snap.t[held_out],
        snap.true_displacement[:, held_out],
        results["chosen"][0].field,
        unmeasured,
        snap.x,
    )


def _stage_antinode_and_plan(
    scenario: Scenario, span, snap, estimate, n_train, sensors, report: _Report
):
    window = slice(-min(500, estimate.field.shape[1]), None)
    estimated = locate_antinodes(estimate.field[:, window], snap.x, dt=snap.dt)
    true = locate_antinodes(snap.true_displacement[:, n_train:][:, window], snap.x, dt=snap.dt)
    robot = scenario.robot
    target = nearest_antinode(estimated, robot.start)
    truth = nearest_antinode(true, target.position)
    limits = RobotLimits(v_max=robot.v_max, a_max=robot.a_max)
    plan = plan_motion(robot.start, target.position, limits, span_length=span.length)
    report.section(
        "Antinode and motion plan",
        [
            ("antinodes (estimate)", ", ".join(f"{a.position:.3f}" for a in estimated) + " m"),
            (
                "nearest to the robot",
                f"{target.position:.3f} m (true field: {truth.position:.3f} m, "
                f"{100 * abs(target.position - truth.position) / truth.loop_length:.2g}"
                " % of the loop)",
            ),
            (
                "minimum-time move",
                f"{robot.start:g} m -> {target.position:.3f} m in "
                f"{plan.duration:.3f} s (v_max {robot.v_max:g} m/s, "
                f"a_max {robot.a_max:g} m/s^2)",
            ),
        ],
        figures={
            "envelope.png": lambda: plotting.plot_envelope(
                snap.x,
                {"true amplitude": np.abs(snap.true_displacement[:, n_train:]).max(axis=1)},
                {
                    "estimated antinodes": [a.position for a in estimated],
                    "sensors": [snap.x[i] for i in sensors],
                },
            )
        },
    )
    report.numbers.update(
        antinode=target.position, true_antinode=truth.position, move_duration=plan.duration
    )


def _stage_closed_loop(scenario: Scenario, span, model, force, report: _Report, sensors):
    robot_cfg = scenario.robot
    if robot_cfg.closed_loop <= 0:
        return
    load_frequency = getattr(force, "frequency", None) or model.natural_frequencies(1)[0]
    frequencies = model.natural_frequencies(min(20, model.n_dofs))
    tuned = float(frequencies[np.argmin(np.abs(frequencies - load_frequency))])
    robot = MDR.tuned(
        robot_cfg.start,
        robot_cfg.body_mass,
        robot_cfg.suspended_mass,
        tuned,
        robot_cfg.damping_ratio,
    )
    calibration = min(2.0, robot_cfg.closed_loop / 3)
    result = run_closed_loop(
        span,
        force,
        robot,
        RobotLimits(robot_cfg.v_max, robot_cfg.a_max),
        sensors=sensors,
        n_elements=model.n_elements,
        bc=model.bc,
        duration=robot_cfg.closed_loop,
        calibration=calibration,
        dt=scenario.simulation.dt,
        noise_fraction=scenario.simulation.noise_fraction,
        seed=scenario.simulation.seed,
    )
    report.section(
        "Closed loop (robot driven to the estimated antinode)",
        [
            (
                "robot",
                f"body {robot.body_mass:g} kg + absorber {robot.suspended_mass:g} kg tuned to "
                f"{tuned:.2f} Hz, starts at {robot.position:g} m",
            ),
            ("final position", f"{result.robot_position[-1]:.3f} m"),
            (
                "RMS displacement, last quarter",
                f"{_mm(result.rms_closed_loop)} moving vs {_mm(result.rms_baseline)} parked",
            ),
            ("vibration reduction", f"{result.vibration_reduction:.2f}x"),
            (
                "planner steps",
                f"{len(result.statuses)} ({result.statuses.count('safe_stop')} safe stops)",
            ),
            ("real-time factor", f"{result.real_time_factor:.2f}"),
        ],
        figures={"closed_loop.png": lambda: plotting.plot_closed_loop(result)},
    )
    report.numbers.update(
        vibration_reduction=result.vibration_reduction,
        final_robot_position=float(result.robot_position[-1]),
    )


def _write_outputs(out: Path, scenario: Scenario, report: _Report, dmd) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "scenario.toml").write_text(scenario_to_toml(scenario))
    save_model(out / "dmd_model.npz", dmd)
    for name, draw in report.figures.items():
        draw().savefig(out / name, dpi=110)
    write_report(out / "report.html", "powerline_control run", report.sections, __version__)
    (out / "summary.json").write_text(json.dumps(report.numbers, indent=2, default=float))


def run_scenario(scenario: Scenario, out: Path | None = None, echo=print) -> dict:
    """Run the main job on ``scenario`` and return its headline numbers.

    Stages: model -> simulation -> identification (DMD, alpha chosen on held-out data) ->
    sensor placement (or the scenario's sensors) -> Kalman estimation on held-out data, against
    the paper's first-13-nodes layout -> antinode and minimum-time move -> closed loop.

    Parameters
    ----------
    scenario : Scenario
        The study (see :func:`~powerline_control.config.load_scenario`).
    out : Path or None
        Folder for figures, ``report.html``, ``summary.json``, the DMD model and the scenario;
        None writes nothing.
    echo : callable
        Where the printed summary goes (``print`` by default).

    Returns
    -------
    dict
        The headline numbers, as printed.

    Examples
    --------
    >>> from powerline_control.config import load_scenario
    >>> small = load_scenario(text="[model]\\nn_elements = 20\\n[simulation]\\nduration = 2.0\\n"
    ...                            "[robot]\\nclosed_loop = 0")
    >>> run_scenario(small, echo=lambda line: None)["n_nodes"]
    21
    """
    report = _Report(echo)
    span, model = _stage_model(scenario, report)
    force, snap = _stage_data(scenario, model, report)
    dmd, n_train = _stage_identify(scenario, snap, report)
    sensors, estimate = _stage_estimate(scenario, dmd, snap, n_train, report)
    _stage_antinode_and_plan(scenario, span, snap, estimate, n_train, sensors, report)
    _stage_closed_loop(scenario, span, model, force, report, sensors)
    if out is not None:
        _write_outputs(out, scenario, report, dmd)
        echo(f"Results written to {out}/ (report.html, summary.json, figures, dmd_model.npz)")
    return report.numbers


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="powerline-control", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="run the main job on a scenario")
    run.add_argument(
        "scenario",
        nargs="?",
        type=Path,
        help="TOML scenario file (default: the built-in paper lab scenario)",
    )
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
        start = time.perf_counter()
        run_scenario(scenario, out=args.out)
        print(f"Done in {time.perf_counter() - start:.1f} s.")
    except PowerlineControlError as exc:
        print(f"powerline-control: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
