"""The powerline-control command: run scenario studies of an overhead line from the shell.

Verbs (``powerline-control VERB --help`` for each)::

    demo         the paper's lab span end to end; report in ./powerline-demo/ (< 1 min)
    run          the whole chain on a scenario (file or shipped name, e.g. drake-300m)
    simulate     model and simulated sensor data
    identify     ... + DMD identification (Tikhonov-regularised)
    sensors      ... + optimal sensor layout against baselines
    estimate     ... + Kalman estimate of the whole span on held-out data
    plan         ... + antinodes and the robot's minimum-time move
    closed-loop  the robot driven to the antinode in closed loop, against it parked
    severity     aeolian severity by the energy balance (amplitude, clamp strain)
    study        a grid of scenario variants (--vary KEY=V1,V2 ...), a table of results
    report       run a scenario and write only its HTML report
    scenario     list the shipped scenarios, or print one as a commented TOML template

This module imports only the standard library at import time: ``--help`` and ``scenario`` stay
fast, and numpy, SciPy, python-control, cvxpy, CasADi and matplotlib load inside the verbs. The
numerical work runs under one BLAS thread (threadpoolctl, in the verb's scope only): its matrices
are small, and two contending threads on a 2-core machine made ``run`` 2.5x slower.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import json
import os
import sys
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError, PowerlineControlError

__all__ = ["main", "run_scenario", "EXIT_OK", "EXIT_NUMERICAL", "EXIT_USAGE", "EXIT_INTERRUPTED"]

#: Exit status: success.
EXIT_OK = 0
#: Exit status: numerical trouble (unstable or singular model, infeasible plan, solver failure).
EXIT_NUMERICAL = 1
#: Exit status: bad input or usage (scenario, arguments, output folder).
EXIT_USAGE = 2
#: Exit status: interrupted with Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130

#: Fraction of the simulated record used for identification; the rest tests the estimator.
TRAIN_FRACTION = 0.6
#: The file in an output folder that lists what this command wrote there (so a re-run may
#: replace those files and nothing else).
MANIFEST = ".powerline-control.json"

_UNITS = ("Units: SI throughout; positions in m from the left support, frequencies in Hz, times "
          "in s, displacements reported in mm, masses in kg, speeds in m/s.")
_EXIT_CODES = ("Exit codes: 0 success; 1 numerical trouble (unstable or singular model, "
               "infeasible plan, solver failure); 2 bad input or usage (scenario file, arguments, "
               "--out folder); 130 interrupted (Ctrl-C).")


# ----------------------------------------------------------------------------- console output

class _Console:
    """Where the command's text goes: summary to stdout, progress and messages to stderr."""

    def __init__(self, *, quiet: bool = False, as_json: bool = False, debug: bool = False):
        self.quiet = quiet
        self.as_json = as_json
        self.debug = debug

    def out(self, line: str = "") -> None:
        """A summary line (suppressed by --quiet and --json)."""
        if not (self.quiet or self.as_json):
            print(line, flush=True)

    def note(self, line: str) -> None:
        """A message on stderr (suppressed by --quiet)."""
        if not self.quiet:
            print(line, file=sys.stderr, flush=True)


class _Progress:
    """Stage progress on stderr: '[2/6] simulating ...', and the elapsed time while it works.

    On a terminal a tqdm bar shows the current stage and a ticking clock; otherwise (a log, a
    pipe) each stage is one line and a long stage adds a 'still ...' line every 15 s.
    """

    def __init__(self, console: _Console, n_stages: int):
        self.console = console
        self.n_stages = n_stages
        self.done = 0
        self.bar = None
        self.what = ""
        self.started = time.perf_counter()
        self._stop = threading.Event()
        self._thread = None
        self.enabled = not console.quiet

    def __enter__(self):
        if not self.enabled:
            return self
        if sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=self.n_stages, file=sys.stderr, unit="stage", leave=False,
                            bar_format="{n_fmt}/{total_fmt} stages [{elapsed}] {desc}",
                            dynamic_ncols=True, mininterval=0.5)
        # The longest stages run inside one library call: a thread keeps the clock ticking so a
        # user sees the command is alive.
        self._thread = threading.Thread(target=self._tick, daemon=True)
        self._thread.start()
        return self

    def _tick(self) -> None:
        interval = 1.0 if self.bar is not None else 15.0
        while not self._stop.wait(interval):
            with contextlib.suppress(Exception):
                if self.bar is not None:
                    self.bar.refresh()
                elif self.what and time.perf_counter() - self.started >= interval:
                    elapsed = time.perf_counter() - self.started
                    print(f"      ... still {self.what} ({elapsed:.0f} s)", file=sys.stderr,
                          flush=True)

    def stage(self, what: str) -> None:
        """Start the next stage, saying what it does."""
        if not self.enabled:
            return
        self.done += 1
        self.what = what
        self.started = time.perf_counter()
        line = f"[{self.done}/{self.n_stages}] {what}"
        if self.bar is not None:
            if self.done > 1:
                self.bar.update(1)
            self.bar.write(line, file=sys.stderr)
            self.bar.set_description_str(what[:60])
        else:
            print(line, file=sys.stderr, flush=True)

    def __exit__(self, *exc):
        self._stop.set()
        if self.bar is not None:
            self.bar.close()
        return False


# ----------------------------------------------------------------------------- the report

@dataclass
class _Figure:
    name: str
    draw: Callable
    caption: str


@dataclass
class _Report:
    """Sections of the printed summary and of the HTML report, and the headline numbers.

    A stage hands each figure over as a function that draws it, so figures cost nothing unless
    an output folder asks for them.
    """

    console: _Console
    sections: list = field(default_factory=list)
    numbers: dict = field(default_factory=dict)

    def section(self, title: str, rows: Sequence[tuple], *, intro: str = "",
                figures: Sequence[_Figure] = (), notes: Sequence[str] = ()) -> None:
        """Print a section and keep it for the report.

        ``rows`` are (label, value) or (label, value, explanation) tuples.
        """
        self.console.out(title)
        rows = [tuple(row) + ("",) * (3 - len(row)) for row in rows]
        for label, value, _ in rows:
            self.console.out(f"  {label:<42} {value}")
        self.sections.append({"title": title, "intro": intro, "rows": rows,
                              "figures": list(figures), "notes": list(notes)})


def _mm(value: float) -> str:
    return f"{1e3 * value:.4g} mm"


def _summarise_positions(positions: Sequence[float], unit: str = "m", limit: int = 8) -> str:
    """Positions in words: all of them when few, else count, range and typical spacing."""
    import numpy as np

    values = np.sort(np.asarray(positions, dtype=float))
    if values.size <= limit:
        return ", ".join(f"{v:.3g}" for v in values) + f" {unit}"
    spacing = float(np.median(np.diff(values)))
    return (f"{values.size} positions from {values[0]:.3g} to {values[-1]:.3g} {unit}, "
            f"typically {spacing:.3g} {unit} apart")


# ----------------------------------------------------------------------------- the stages

class _Study:
    """The chain of one scenario, stage by stage; each verb runs the stages it needs."""

    def __init__(self, scenario, report: _Report, progress: _Progress):
        self.scenario = scenario
        self.report = report
        self.progress = progress
        self.span = self.model = self.force = self.snap = self.train_snap = None
        self.design = None
        self.estimates = {}
        self.closed_loop = None
        self._tuned = None
        self.parked_choice = None

    # -- model
    def build_model(self):
        import numpy as np

        self.progress.stage("building the finite-element model")
        sc = self.scenario
        self.span = span = sc.span.build()
        self.model = model = sc.model.build(span)
        self.force = sc.forcing.build()
        frequencies = model.natural_frequencies(min(5, model.n_dofs))
        x = np.asarray(model.node_positions)
        h = np.diff(x)
        cond = span.conductor
        mesh = (f"{model.n_elements} Hermite cubic beam elements of {h.min():.3g} m"
                if np.ptp(h) < 1e-9 * h.max() else
                f"{model.n_elements} Hermite cubic beam elements, {h.min():.3g}-{h.max():.3g} m "
                "long (graded toward the supports)")
        wave_speed = float(np.sqrt(span.tension / cond.mass_per_length))
        self.report.section(
            "Span and model",
            [
                ("span", f"{span.length:g} m between supports, tension {span.tension:.4g} N",
                 "The paper's laboratory span (Table 1)" if sc.span.preset == "paper_lab" else
                 f"{sc.span.rts_fraction:.0%} of the conductor's rated tensile strength"),
                ("conductor", f"{cond.name}: {cond.mass_per_length:.4g} kg/m, EI "
                 f"{cond.ei:g} N m^2, diameter {1e3 * cond.diameter:g} mm"),
                ("wave speed sqrt(T/m)", f"{wave_speed:.4g} m/s"),
                ("model", f"{mesh}; {model.n_nodes} nodes, {model.n_dofs} degrees of freedom; "
                 f"{model.bc[0]} / {model.bc[1]} supports",
                 "A Galerkin model of the taut Euler-Bernoulli line: bending stiffness EI plus "
                 "the tension's geometric stiffness."),
                ("first natural frequencies", ", ".join(f"{f:.4g}" for f in frequencies) + " Hz"),
                ("load", sc.forcing.describe(span)),
            ],
        )
        self.report.numbers.update(
            scenario=sc.name, n_nodes=int(model.n_nodes), n_elements=int(model.n_elements),
            frequencies_hz=[float(f) for f in frequencies],
            load_frequency_hz=float(sc.forcing.load_frequency(span)))

    # -- data
    def simulate(self):
        import numpy as np

        from .simulate import simulate

        sim = self.scenario.simulation
        self.progress.stage(f"simulating {sim.duration:g} s of motion at dt = {sim.dt:g} s")
        start = time.perf_counter()
        snap = simulate(self.model, self.force, duration=sim.duration, dt=sim.dt,
                        noise_fraction=sim.noise_fraction, seed=sim.seed)
        self.snap = snap
        self.n_train = int(TRAIN_FRACTION * snap.t.size)
        shaker_row = self._simulate_identification_run()
        elapsed = time.perf_counter() - start
        tail = snap.true_displacement[:, -snap.t.size // 4:]
        use = (f"first {TRAIN_FRACTION:.0%} identify the model, the rest test it"
               if shaker_row is None else
               f"the last {1 - TRAIN_FRACTION:.0%} test the estimator (trained on the "
               "identification run below)")
        self.report.section(
            "Simulated data",
            [
                ("record", f"{snap.t.size} samples at dt = {snap.dt:g} s ({sim.duration:g} s); "
                 + use),
                *([] if shaker_row is None else [shaker_row]),
                ("modes kept", f"{snap.n_modes} of {self.model.n_dofs}"),
                ("RMS / peak displacement (last quarter)",
                 f"{_mm(np.sqrt(np.mean(tail**2)))} / {_mm(np.abs(tail).max())}"),
                ("sensor noise std", f"{_mm(snap.noise_std)} "
                 f"({sim.noise_fraction:.1%} of the RMS displacement)"),
                ("simulation time", f"{elapsed:.2f} s"),
            ],
        )

    def _simulate_identification_run(self):
        """The training record: the scenario's load plus a broadband shaker (None: no shaker).

        A harmonic load alone excites the span's other modes only through its start-up
        transient, so an estimator trained on it does not know them (design_estimator warns);
        the shaker makes the identification run persistently exciting. Its own seed keeps its
        noise and force independent of the test record's.
        """
        from .excitation import RandomForce
        from .simulate import simulate

        ident, sim = self.scenario.identification, self.scenario.simulation
        self.train_snap = self.snap
        if ident.shaker <= 0:
            return None
        position = 0.31 * self.span.length  # off the symmetry points: drives every low mode
        shaker = RandomForce(ident.shaker, position, ident.shaker_bandwidth, seed=sim.seed + 1)
        self.train_snap = simulate(self.model, [self.force, shaker],
                                   duration=self.n_train * sim.dt, dt=sim.dt,
                                   noise_fraction=sim.noise_fraction, seed=sim.seed + 1)
        return ("identification run",
                f"the scenario's load plus a broadband shaker ({ident.shaker:g} N std, up to "
                f"{ident.shaker_bandwidth:g} Hz, at {position:.4g} m), {self.n_train} samples "
                "(its own noise): it trains the estimator")

    # -- identification, sensors, filter: by the package's one recipe
    def design_estimator(self, *, choose_sensors: bool = True):
        """Identify the model, choose the sensors and build the filter (``design_estimator``).

        The recipe's decisions (delays, rank, alpha, criterion, measurement variance) live in
        ``powerline_control.recipe``; this verb passes the scenario's keys on to it.
        """
        self.progress.stage("identifying the model (the recipe's choices judged on held-out "
                            "data)")
        self.design = _design_estimator(self.scenario, self.train_snap, self.model,
                                        self.n_train, self.progress,
                                        choose_sensors=choose_sensors)
        self._report_identification()
        if choose_sensors:
            self._report_sensors()

    def _report_identification(self):
        d = self.design
        rows = [
            ("recipe", d.recipe),
            ("spectral radius / unstable eigenvalues",
             f"{d.dmd.spectral_radius:.6f} / {d.n_unstable}",
             "Largest |eigenvalue| of the identified one-step map. Below 1 the model is stable: "
             "a Kalman filter and python-control's dlqe accept it."),
            ("plain DMD (alpha = 0)", f"spectral radius {d.plain.spectral_radius:.6f}"
             + (" (ill-conditioned: it inverts round-off)" if d.plain_ill else ""),
             "The unregularised fit (the paper's eq. 11), for comparison."),
        ]
        self.report.section(
            "Identification", rows,
            intro="The recipe fits a linear one-step map to the training part of the record: "
            "time-delay Dynamic Mode Decomposition with Tikhonov regularisation (alpha pulls "
            "its eigenvalues inside the unit circle), or, for a narrowband record whose "
            "spectral lines explain it, one oscillator per line (the recipe line says which).",
            figures=[_Figure("eigenvalues", d.eigenvalue_figure,
                             "Eigenvalues of the identified map before (plain DMD, alpha = 0) and "
                             "after regularisation, with the unit circle. Look for points outside "
                             "the circle: those modes grow without bound; after regularisation "
                             "all should lie on or inside it.")])
        self.report.numbers.update(alpha=float(d.dmd.alpha),
                                   spectral_radius=float(d.dmd.spectral_radius))

    def _report_sensors(self):
        d = self.design
        x = self.snap.x
        rows = [("sensors", _summarise_positions([x[i] for i in d.sensors]) +
                 f" (nodes {', '.join(str(int(i)) for i in d.sensors)})", d.how)]
        if d.certificate_text:
            rows.append(("optimality certificate", d.certificate_text,
                         "The relaxation gives a bound no layout can beat; the gap says how far "
                         "the chosen layout can be from the best possible one, at most."))
        figures = []
        if d.count_curve is not None:
            figures.append(_Figure("sensor_count", d.count_figure,
                                   "How many sensors: the predicted steady-state estimation "
                                   "error against the number of sensors, each count optimised. "
                                   "Look for where the curve flattens: more sensors than that "
                                   "buy little."))
        for name, note in d.layout_notes.items():
            rows.append((f"baseline: {name}", _summarise_positions(
                [x[i] for i in d.layouts[name]]), note))
        self.report.section("Sensor placement", rows, figures=figures)
        self.report.numbers.update(sensors=[int(i) for i in d.sensors],
                                   sensor_positions_m=[float(x[i]) for i in d.sensors])

    # -- estimation
    def estimate(self):
        import numpy as np

        self.progress.stage("Kalman estimation of the whole span on held-out data")
        d = self.design
        snap = self.snap
        rows = []
        for name, nodes in d.layouts.items():
            self.estimates[name] = d.run_filter(nodes, snap, self.n_train)
        chosen = self.estimates["chosen"][1]
        explanation = ("RMS over the nodes without a sensor of (estimate - truth), divided by "
                       "the RMS displacement over the span, on data the model never saw.")
        for name, (_, accuracy) in self.estimates.items():
            rows.append((f"error at unmeasured nodes: {name}",
                         f"{100 * accuracy.relative_rms_error_unmeasured:.3g} % of RMS "
                         "displacement", explanation if name == "chosen" else
                         d.layout_notes.get(name, "")))
        truth = snap.true_displacement[:, self.n_train:]
        along = {name: np.sqrt(np.mean((est.field - truth) ** 2, axis=1))
                 / np.sqrt(np.mean(truth**2)) for name, (est, _) in self.estimates.items()}
        errors = {name: 100 * acc.relative_rms_error_unmeasured
                  for name, (_, acc) in self.estimates.items()}
        positions = {name: [snap.x[i] for i in nodes] for name, nodes in d.layouts.items()}
        self.report.section(
            "Estimation (Kalman filter on held-out data)", rows,
            intro="A steady-state Kalman filter on the identified model reconstructs the "
            "displacement of every node from the few measured ones.",
            figures=[
                _Figure("estimate", functools.partial(_estimate_figure, snap, self.n_train,
                                                      self.estimates["chosen"][0], d.sensors),
                        "Estimate (dashed) against the true displacement (solid) at three nodes "
                        "without a sensor, on held-out data. Look for the dashed line sitting "
                        "on the solid one after the first few periods."),
                _Figure("error_along_span", functools.partial(_error_figure, snap.x, along,
                                                              d.sensors),
                        "RMS estimation error at every node, as a fraction of the RMS "
                        "displacement over the span (%), for each layout; sensor positions "
                        "marked. Look for where each layout loses track of the line."),
                _Figure("layouts", functools.partial(_layout_figure, errors, positions,
                                                     float(snap.x[-1])),
                        "Layout against baselines. Left: RMS error at the unmeasured nodes (% "
                        "of RMS displacement) of the chosen layout and of the obvious ones. "
                        "Right: where each layout puts its sensors along the span (m). Look "
                        "for the chosen layout's bar being the lowest."),
            ])
        self.report.numbers.update(
            error_unmeasured=float(chosen.relative_rms_error_unmeasured),
            error_unmeasured_baselines={name: float(acc.relative_rms_error_unmeasured)
                                        for name, (_, acc) in self.estimates.items()})

    # -- antinodes and plan
    def plan(self):
        import numpy as np

        from .antinode import locate_antinodes, nearest_antinode
        from .closed_loop.policy import TRAVEL_FRACTION, choose_parked_position
        from .plan import RobotLimits, plan_motion

        self.progress.stage("locating antinodes and planning the robot's move")
        snap = self.snap
        estimate = self.estimates["chosen"][0]
        window = slice(-min(500, estimate.field.shape[1]), None)
        estimated = locate_antinodes(estimate.field[:, window], snap.x, dt=snap.dt)
        true = locate_antinodes(snap.true_displacement[:, self.n_train:][:, window], snap.x,
                                dt=snap.dt)
        robot = self.scenario.robot
        limits = RobotLimits(v_max=robot.v_max, a_max=robot.a_max)
        # The closed loop's own targeting rule on the estimated field (the robot is not on the
        # line in this record): the plan goes where the closed loop will.
        tuned, _ = self.tuned_robot()
        travel = float("inf")
        if robot.closed_loop > 0:
            travel = TRAVEL_FRACTION * (robot.closed_loop - self.closed_loop_timing()[1])
        # the whole held-out estimate: its resolution (1 / length) must tell the load's line
        # from a natural frequency's ringing next to it
        choice = choose_parked_position(self.model, estimate.field, snap.dt, tuned,
                                        robot.start, limits, travel_time=travel)
        self.parked_choice = choice
        target = nearest_antinode(estimated, choice.position)
        truth = nearest_antinode(true, choice.position)
        plan = plan_motion(robot.start, choice.position, limits, span_length=self.span.length)
        self.plan_result = plan
        envelope = np.abs(snap.true_displacement[:, self.n_train:]).max(axis=1)
        self.envelope = envelope
        self.antinodes = [a.position for a in estimated]
        self.report.section(
            "Antinodes and motion plan",
            [
                ("antinodes (estimated field)", _summarise_positions(self.antinodes)),
                ("target", f"{choice.position:.4g} m (predicted "
                 f"{100 * choice.gain:.0f} % less vibration than at the start)",
                 "The closed loop's rule: the predicted best parked position within reach "
                 "(the nearest of those within 3 % of the best), from the estimated field."),
                ("nearest antinode", f"{target.position:.4g} m (true field: "
                 f"{truth.position:.4g} m, {100 * abs(target.position - truth.position) / truth.loop_length:.2g} "  # noqa: E501
                 "% of a loop length apart)",
                 "The estimated antinode nearest the target, checked against the true field."),
                ("minimum-time move", f"{robot.start:g} m -> {choice.position:.4g} m in "
                 f"{plan.duration:.3g} s (v_max {robot.v_max:g} m/s, a_max "
                 f"{robot.a_max:g} m/s^2)"),
            ],
            figures=[
                _Figure("envelope", functools.partial(
                    _envelope_figure, snap.x, envelope, self.antinodes,
                    [snap.x[i] for i in self.design.sensors]),
                    "Vibration amplitude along the span (mm, largest |y| over the held-out "
                    "record) with the estimated antinodes and the sensors. Look for the "
                    "antinode marks on the envelope's peaks."),
                _Figure("robot_path", functools.partial(
                    _path_figure, snap.x, envelope, plan.t, plan.position, target.position,
                    None),
                    "The robot's planned path (position against time, bottom) under the "
                    "amplitude envelope (top), zoomed to where it travels. Look for the path "
                    "ending under an envelope peak."),
            ])
        self.report.numbers.update(target=float(choice.position),
                                   antinode=float(target.position),
                                   true_antinode=float(truth.position),
                                   n_antinodes=len(self.antinodes),
                                   move_duration=float(plan.duration))

    def tuned_robot(self):
        """The scenario's robot tuned to the load (computed once), and the tuning in words."""
        if self._tuned is None:
            frequency = self.scenario.forcing.load_frequency(self.span)
            self._tuned = _tuned_robot(self.scenario, self.model, frequency)
        return self._tuned

    def closed_loop_timing(self):
        """(dt, calibration) of the closed loop: the calibration (robot parked, the estimator
        identified) is a third of the run, at most 2 s, in whole 50 ms control periods."""
        dt = self.scenario.simulation.dt
        period = max(dt, round(0.05 / dt) * dt)
        calibration = max(1, round(min(2.0, self.scenario.robot.closed_loop / 3) / period))
        return dt, round(calibration * period / dt) * dt

    # -- closed loop
    def run_closed_loop(self, sensors=None):
        import numpy as np

        from .closed_loop import run_closed_loop
        from .plan import RobotLimits

        sc = self.scenario
        robot_cfg = sc.robot
        if robot_cfg.closed_loop <= 0:
            return
        self.progress.stage(f"closed loop: {robot_cfg.closed_loop:g} s of the robot chasing "
                            "the antinode, and the same run parked")
        robot, tuning_text = self.tuned_robot()
        if sensors is None:
            sensors = _default_closed_loop_sensors(sc, self.model)
        dt, calibration = self.closed_loop_timing()
        result = run_closed_loop(
            self.model, self.force, robot, RobotLimits(robot_cfg.v_max, robot_cfg.a_max),
            sensors=list(sensors), duration=robot_cfg.closed_loop,
            calibration=calibration, dt=dt, noise_fraction=sc.simulation.noise_fraction,
            seed=sc.simulation.seed)
        self.closed_loop = result
        final = float(result.robot_position[-1])
        steady = result.comparison("closed_loop").steady
        reduction = float(result.vibration_reduction)
        rtf = float(result.real_time_factor)
        rows = [
            ("robot", f"body {robot.body_mass:g} kg + absorber {robot.suspended_mass:g} kg, "
             f"{tuning_text}; starts at {robot.position:g} m"),
            ("where it ended", f"{final:.4g} m", _where_it_ended(result, final)),
            ("plan and closed loop", _plan_agreement(self.parked_choice, result, final),
             "The plan stage applies the closed loop's own targeting rule to the estimated "
             "field; the closed loop decides from its own sensors while it runs."),
            ("RMS displacement, steady state" if steady else "RMS displacement, settled window",
             f"{_mm(result.rms_closed_loop)} parked where it ended vs "
             f"{_mm(result.rms_baseline)} parked at its start",
             "The exact steady state under the load with the robot parked there."
             if steady else "Over the settled window (the load is not one sine)."),
            ("vibration reduction", f"{reduction:.2f}x",
             "RMS displacement over the span with the robot parked where it started, divided by "
             "the same with the robot where the closed loop left it (> 1: moving helps)."),
            ("decisions", "; ".join(f"{t:.3g} s: {what}" for t, what in result.decisions),
             "What the robot decided, and when."),
            ("estimator consistency",
             "no complete window" if result.estimator_consistency is None else
             ("consistent" if result.estimator_consistency.consistent else "INCONSISTENT")
             + " (windowed NIS of the Kalman filter over the run)",
             "The filter's model was identified with the robot parked at its start; once the "
             "robot damps the line it may no longer fit. The robot's targeting does not use "
             "that estimate (it fits the sensors' phasors on the line's modes)."),
            ("planner steps", f"{len(result.statuses)} ({result.statuses.count('safe_stop')} "
             "safe stops)"),
            ("real-time factor", f"{rtf:.2f}",
             "Simulated seconds per second of computing: above 1 the loop runs faster than "
             "the line moves, as a controller on the robot must."),
        ]
        window = getattr(result, "settled_window", None)
        if window is not None and window[1] > window[0]:
            rows.insert(2, ("settled window", f"{window[0]:.3g}-{window[1]:.3g} s"
                            + ("" if getattr(result, "settled", True) else
                               " (the robot did not settle: the last second)"),
                            "The window RMS (beside each steady state below) is over this "
                            "window, after the robot last arrived."))
        for comparison in getattr(result, "comparisons", ()):
            label = _COMPARISON_WORDS.get(comparison.name, comparison.name)
            where = "" if not np.isfinite(comparison.position) else \
                f" at {comparison.position:.4g} m"
            note = f"peak {_mm(comparison.peak)}"
            if comparison.steady:
                note += (f"; settled window {_mm(comparison.window_rms)}"
                         + (" (still ringing)" if comparison.transient else ""))
            rows.append((f"RMS: {label}", f"{_mm(comparison.rms)}{where}", note))
        self.report.section(
            "Closed loop (robot driven to the estimated antinode)", rows,
            figures=[
                _Figure("closed_loop", functools.partial(_closed_loop_figure, result),
                        "Top: the robot's position and its antinode target against time (the "
                        "grey line ends the calibration, robot parked). Bottom: RMS displacement "
                        "over the span, robot moving against parked (mm). Look for the moving "
                        "curve falling below the parked one once the robot arrives."),
                _Figure("closed_loop_path", functools.partial(_closed_loop_path_figure, result),
                        "The robot's path in the closed loop (position across, time down) over "
                        "the line's moving vibration envelope (colour: largest |y| over 0.1 s), "
                        "with its target. Look for the path settling where the colour is "
                        "brightest near it, and staying there."),
            ])
        self.report.numbers.update(vibration_reduction=reduction, final_robot_position=final,
                                   real_time_factor=rtf)

    # -- severity
    def severity(self):
        import numpy as np

        import powerline_control as plc

        sev_cfg = self.scenario.severity
        self.progress.stage("aeolian severity by the energy balance method")
        speeds = np.asarray(sev_cfg.wind_speeds, dtype=float)
        results = [plc.aeolian_severity(self.span, wind_speeds=speeds)]
        robot, _ = _tuned_robot(self.scenario, self.model,
                                self.scenario.forcing.load_frequency(self.span))
        results.append(plc.aeolian_severity(self.span, wind_speeds=speeds,
                                            dampers=[plc.AtAntinode(robot)]))
        robot_text = " With the robot: its absorber parked at the antinode of each wind speed."
        bare = results[0]
        rows = []
        for i, speed in enumerate(bare.wind_speed):
            text = (f"{bare.frequency[i]:.3g} Hz, loops {bare.loop_length[i]:.3g} m; antinode "
                    f"amplitude {_mm(bare.amplitude[i])}, clamp strain "
                    f"{1e6 * bare.strain_pp[i]:.3g} µε peak-to-peak")
            robot_result = results[1]
            text += (f"; with the robot {_mm(robot_result.amplitude[i])}, "
                     f"{1e6 * robot_result.strain_pp[i]:.3g} µε")
            rows.append((f"wind {speed:g} m/s", text))
        figures = [_Figure("severity", functools.partial(_severity_figure, results),
                           "Antinode amplitude (mm, zero to peak) and peak-to-peak bending "
                           "strain at the clamp (µε) against wind speed (m/s), from the energy "
                           "balance, without dampers and with the robot. Look for strains above "
                           "the endurance line: those winds fatigue the conductor.")]
        self.report.section(
            "Aeolian severity (energy balance)", rows,
            intro="For each wind speed the steady antinode amplitude is where the wind's power "
            "input equals the power the conductor's self-damping (and any damper) dissipates; "
            "the clamp strain follows from it (Poffenberger-Swart)." + robot_text,
            figures=figures,
            notes=["150 µε peak-to-peak is the endurance limit commonly used for ACSR "
                   "conductors (CIGRE / EPRI)."])
        self.report.numbers.update(severity=[
            {"wind_speed": float(bare.wind_speed[i]), "frequency_hz": float(bare.frequency[i]),
             "amplitude_m": float(bare.amplitude[i]), "loop_length_m": float(bare.loop_length[i]),
             "strain_pp": float(bare.strain_pp[i])} for i in range(bare.wind_speed.size)])


def _where_it_ended(result, final: float) -> str:
    """Why the robot ended where it did, in words, from what the closed loop recorded."""
    import numpy as np

    targets = np.asarray(result.target, dtype=float)
    targets = targets[np.isfinite(targets)]
    text = ("The robot steers to the parked position predicted to leave the line vibrating "
            "least, from the sensors' and its own measurements, and undoes a move after which "
            "the sensors measure more vibration.")
    if targets.size:
        text += f" Its last target was {targets[-1]:.4g} m."
    best = getattr(result, "best_position", float("nan"))
    loop = getattr(result, "loop_length", float("nan"))
    if np.isfinite(best) and np.isfinite(loop) and loop > 0:
        text += (f" The best parked position found by a steady-state scan is {best:.4g} m, "
                 f"{abs(final - best) / loop:.2g} loop lengths ({loop:.3g} m) from where it ended.")
    if not getattr(result, "settled", True):
        text += (" It had not settled when the run ended, so the numbers are over the last "
                 "second; a longer robot.closed_loop lets it arrive.")
    return text


_COMPARISON_WORDS = {
    "no_robot": "no robot on the line",
    "near_clamp": "robot parked near a clamp",
    "start": "robot parked where it started",
    "best": "robot parked at the best position",
    "closed_loop": "robot where the closed loop ended",
}


def _plan_agreement(choice, result, final: float) -> str:
    """Whether the plan's target and where the closed loop ended agree, in words."""
    if choice is None:
        return "no plan stage in this run"
    apart = abs(choice.position - final) / result.loop_length
    verdict = "agree" if apart <= 0.25 else "differ"
    return (f"{verdict}: the plan's target {choice.position:.4g} m, the closed loop ended at "
            f"{final:.4g} m ({apart:.2g} loop lengths apart)"
            + ("" if verdict == "agree" else
               "; the closed loop judged from its own run (see its decisions)"))


@dataclass
class _Design:
    """What the estimator recipe produced, and how to report it."""

    dmd: object
    plain: object
    plain_ill: bool
    paper: object
    n_unstable: int
    recipe: str
    sensors: list
    how: str
    certificate_text: str
    noise_var: float
    layouts: dict
    layout_notes: dict
    count_curve: object = None

    def run_filter(self, nodes, snap, n_train):
        from .estimate import KalmanFilter, estimation_accuracy

        held_out = slice(n_train, None)
        kf = KalmanFilter(self.dmd.to_statespace(measured=list(nodes)),
                          Q=self.dmd.residual_covariance, R=self.noise_var, steady_state=True,
                          field_map=self.dmd.field_map)
        estimate = kf.filter(snap.displacement[list(nodes), held_out])
        accuracy = estimation_accuracy(estimate.field, snap.true_displacement[:, held_out],
                                       measured=list(nodes),
                                       discard=min(200, (snap.t.size - n_train) // 4))
        return estimate, accuracy

    def eigenvalue_figure(self):
        return _plotting().plot_eigenvalues(
            {"plain DMD (alpha = 0)": self.plain.eigenvalues,
             f"regularised (alpha = {self.dmd.alpha:.2g})": self.dmd.eigenvalues})

    def count_figure(self):
        return _plotting().plot_sensor_count(*self.count_curve())


def _certificate_text(selection, k: int) -> str:
    if selection is None:
        return ""
    if selection.certificate == "exhaustive" or selection.gap == 0:
        return f"{selection.certificate}: proved the best of all layouts of {k} sensors"
    return (f"{selection.certificate}: the chosen layout's criterion is at most "
            f"{100 * selection.gap:.2g} % above the best possible layout of {k} sensors")


def _given_sensors(scenario, x):
    """The scenario's own sensors as node indices (None when they are to be chosen)."""
    import numpy as np

    est = scenario.estimation
    if est.sensors is not None:
        return sorted(int(i) for i in est.sensors), "from the scenario (node indices)"
    if est.sensor_positions is not None:
        return (sorted({int(np.argmin(np.abs(x - p))) for p in est.sensor_positions}),
                "from the scenario (positions, nearest nodes)")
    return None, ""


def _design_estimator(scenario, snap, model, n_train: int, progress, *, choose_sensors=True):
    """The estimator: identified model, sensors and noise model, by the package's recipe.

    ``powerline_control.design_estimator`` is the one recipe (delays, rank and alpha chosen from
    held-out data, sensors, filter): the command makes no recipe decision of its own; the
    scenario's identification keys, when set, are passed to it.
    """
    import numpy as np

    import powerline_control as plc

    from .identify import fit_dmd

    cfg = scenario.identification
    train = snap.displacement[:, :n_train]
    x = np.asarray(snap.x)
    n_nodes = x.size
    k = scenario.estimation.n_sensors
    # The supports never move: a sensor there would measure only noise.
    half = 0.5 * float(min(x[1] - x[0], x[-1] - x[-2]))
    supports = [(0.0, half), (x[-1] - half, x[-1])]
    given, how = _given_sensors(scenario, x)
    if given is None and not choose_sensors:
        given = list(np.linspace(0, n_nodes - 1, k + 2).round().astype(int)[1:-1])
        how = "evenly spaced (no optimisation in this verb)"
    count_curve = None
    if given is None:
        progress.stage(f"choosing {k} sensor positions (Kalman criterion)")
    options = {key: value for key, value in (("delays", cfg.delays), ("rank", cfg.rank))
               if value is not None}
    if cfg.alpha != "auto":
        options["alphas"] = [float(cfg.alpha)]
    design = plc.design_estimator(
        train, n_sensors=k, dt=snap.dt, noise_std=snap.noise_std or None, sensors=given,
        positions=x, forbidden=supports, seed=scenario.simulation.seed, **options)
    dmd = design.model
    sensors = [int(i) for i in design.sensors]
    selection = design.sensor_selection
    noise_var = float(design.noise_std) ** 2
    # The recipe's own account of what it chose (model, alpha, noise), in words.
    said = [line for line in design.summary().splitlines()[1:]
            if not line.startswith(("Sensors chosen", "Predicted steady-state"))]
    recipe = "the package's recipe (design_estimator). " + " ".join(said)
    if given is not None:
        sensors = list(given)
    elif selection is not None:
        how = "optimised (steady-state Kalman criterion)"
    if noise_var <= 0:
        # Noise-free data still needs a measurement variance for a well-posed Riccati
        # equation: assume sensors resolve 0.01 % of the RMS motion.
        noise_var = (1e-4 * float(np.sqrt(np.mean(snap.true_displacement**2)))) ** 2
    certificate = _certificate_text(selection, k) if given is None else ""
    if given is None and count_curve is None and n_nodes <= 201:
        candidates = dmd.to_statespace(measured=list(range(n_nodes)))
        # Several more selections: computed only if the report draws the figure.
        count_curve = functools.partial(_sensor_count_curve, candidates, dmd, noise_var, x,
                                        supports, k)
    paper = fit_dmd(train, snap.dt, alpha=0.1, delays=1)
    with warnings.catch_warnings(record=True) as caught:
        # On noise-free data plain DMD inverts round-off and says so; here that is the point.
        warnings.simplefilter("always")
        plain = fit_dmd(train, snap.dt, alpha=0.0, delays=1)
    layouts = {"chosen": sensors}
    notes = {}
    spread = list(np.linspace(0, n_nodes - 1, len(sensors) + 2).round().astype(int)[1:-1])
    if spread != sensors:
        layouts[f"evenly spaced ({len(sensors)})"] = spread
        notes[f"evenly spaced ({len(sensors)})"] = "The same number of sensors, evenly spaced."
    # The paper measured its first 10 states on 20 elements and its first 13 on 100 (Figs.
    # 7-8); node 0 sits on the support, so the first measured node is node 1.
    n_first = 10 if n_nodes == 21 else 13
    first = list(range(1, min(n_first, n_nodes - 2) + 1))
    covered = x[first[-1]]
    name = f"paper: first {len(first)} nodes"
    layouts[name] = first
    notes[name] = (f"The paper's layout (its first {n_first} states) covers only x <= "
                   f"{covered:.3g} m, {100 * covered / x[-1]:.2g} % of this {x[-1]:g} m span, "
                   f"with {len(first)} sensors instead of {len(sensors)}.")
    design = _Design(dmd=dmd, plain=plain, plain_ill=bool(caught), paper=paper,
                     n_unstable=int(dmd.stability_report(warn=False).n_unstable), recipe=recipe,
                     sensors=sensors, how=how, certificate_text=certificate,
                     noise_var=noise_var, layouts=layouts, layout_notes=notes,
                     count_curve=count_curve)
    return design


def _sensor_count_curve(candidates, dmd, noise_var, x, supports, k):
    """Predicted estimation error against the number of sensors (each count optimised)."""
    from .sensors import sensor_count_study

    counts = list(range(1, k + 3))
    study = sensor_count_study(candidates, counts, Q=dmd.residual_covariance, R=noise_var,
                               positions=x, forbidden=supports, n_steps=500)
    return (list(study.k), [float(v) for v in study.rms_error],
            [float(v) for v in study.simulated_rms_error])


def _tuned_robot(scenario, model, load_frequency: float):
    """The robot with its absorber tuned to the load's frequency; and the tuning in words."""
    import numpy as np

    import powerline_control as plc

    cfg = scenario.robot
    frequencies = np.asarray(model.natural_frequencies(min(400, model.n_dofs)))
    mode = int(np.argmin(np.abs(frequencies - load_frequency))) + 1
    # Tuned for where it will damp: the antinode of that mode nearest the start (the
    # modal mass seen at a node is infinite), then placed at its start.
    x = np.asarray(model.node_positions)
    shape = np.abs(model.mode_shapes(mode)[:, mode - 1])
    loop = model.span.length / mode
    near = np.abs(x - cfg.start) <= loop
    antinode = float(x[near][np.argmax(shape[near])]) if near.any() else cfg.start
    mdr = plc.tune_damper(model, mode, antinode, cfg.suspended_mass,
                          body_mass=cfg.body_mass)
    how = "Den Hartog"
    if cfg.damping_ratio > 0:
        # The scenario's own damping ratio, at the Den Hartog frequency.
        omega = np.sqrt(mdr.stiffness / mdr.suspended_mass)
        mdr = dataclasses.replace(mdr, damping=2 * cfg.damping_ratio * mdr.suspended_mass * omega)
        how = f"Den Hartog frequency, damping ratio {cfg.damping_ratio:g} from the scenario"
    mdr = dataclasses.replace(mdr, position=cfg.start)
    return mdr, (f"absorber tuned ({how}) to mode {mode} "
                 f"({frequencies[mode - 1]:.4g} Hz), the mode nearest the load's "
                 f"{load_frequency:.4g} Hz, for the antinode at {antinode:.4g} m")


def _default_closed_loop_sensors(scenario, model):
    import numpy as np

    x = np.asarray(model.node_positions)
    est = scenario.estimation
    if est.sensors is not None:
        return list(est.sensors)
    if est.sensor_positions is not None:
        return sorted({int(np.argmin(np.abs(x - p))) for p in est.sensor_positions})
    return list(np.linspace(0, x.size - 1, est.n_sensors + 2).round().astype(int)[1:-1])


# ----------------------------------------------------------------------------- figures

def _plotting():
    from . import plotting

    return plotting


def _estimate_figure(snap, n_train, estimate, sensors):
    import numpy as np

    spread = np.linspace(0, snap.x.size - 1, 5).astype(int)[1:-1]
    unmeasured = [int(i) for i in spread if i not in sensors] or [snap.x.size // 2]
    held_out = slice(n_train, None)
    t = snap.t[held_out]
    # Show at most the last 40 periods of the response so the curves stay readable.
    return _plotting().plot_estimate(t, snap.true_displacement[:, held_out], estimate.field,
                                     unmeasured, snap.x)


def _error_figure(x, along, sensors):
    return _plotting().plot_error_along_span(x, along, [x[i] for i in sensors])


def _envelope_figure(x, envelope, antinodes, sensors):
    return _plotting().plot_envelope(x, {"true amplitude": envelope},
                                     {"estimated antinodes": antinodes, "sensors": sensors})


def _path_figure(x, envelope, t, position, target, target_series):
    return _plotting().plot_plan_path(x, envelope, t, position, target=target,
                                      target_series=target_series)


def _closed_loop_path_figure(result):
    import numpy as np

    return _plotting().plot_plan_path(
        result.x, np.abs(result.baseline_displacement[:, result.t.size // 2:]).max(axis=1),
        result.t, result.robot_position, target_series=result.target)


def _closed_loop_figure(result):
    return _plotting().plot_closed_loop(result)


def _layout_figure(errors, positions, span_length):
    return _plotting().plot_layouts(errors, positions, span_length)


def _severity_figure(result):
    return _plotting().plot_severity(result)


# ----------------------------------------------------------------------------- outputs

class _Output:
    """An output folder checked before the run; it never overwrites files it did not write."""

    def __init__(self, path: Path | None, *, force: bool = False):
        self.path = path
        self.written: list[str] = []
        if path is None:
            return
        if path.exists() and not path.is_dir():
            raise InputError(f"--out {str(path)!r} is a file, not a folder. Give a folder "
                             "(it is created if missing).")
        if path.is_dir():
            ours = self._manifest()
            others = sorted(p.name for p in path.iterdir()
                            if p.name != MANIFEST and p.name not in ours)
            if others and not force:
                shown = ", ".join(others[:5]) + (", ..." if len(others) > 5 else "")
                raise InputError(
                    f"--out {str(path)!r} already holds files this command did not write "
                    f"({shown}). Give an empty or new folder, or add --force to write into it "
                    "anyway (files of the same name are replaced).")
        try:
            path.mkdir(parents=True, exist_ok=True)
            probe = path / ".powerline-control-write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as exc:
            raise InputError(f"--out {str(path)!r} is not a writable folder: "
                             f"{exc.strerror or exc}.") from None

    def _manifest(self) -> set[str]:
        try:
            return set(json.loads((self.path / MANIFEST).read_text())["files"])
        except (OSError, ValueError, KeyError, TypeError):
            return set()

    def file(self, name: str) -> Path:
        """The path of an output file, recorded in the manifest."""
        self.written.append(name)
        (self.path / MANIFEST).write_text(json.dumps(
            {"written_by": "powerline-control", "files": sorted(set(self.written)
                                                                | self._manifest())}))
        return self.path / name


def _write_outputs(out: _Output, study: _Study, report: _Report, *, full: bool = True) -> list:
    from . import __version__
    from .report import write_report
    from .scenario import scenario_to_toml

    scenario = study.scenario
    if full:
        out.file("scenario.toml").write_text(scenario_to_toml(scenario))
        if study.design is not None:
            from .io import save_model

            save_model(out.file("dmd_model.npz"), study.design.dmd)
        out.file("summary.json").write_text(json.dumps(report.numbers, indent=2, default=float))
    sections = []
    for section in report.sections:
        figures = []
        for figure in section["figures"]:
            fig = figure.draw()
            figures.append({"name": figure.name, "figure": fig, "caption": figure.caption})
        sections.append({**section, "figures": figures})
    write_report(out.file("report.html"), f"powerline_control: {scenario.name}", sections,
                 __version__, scenario_name=scenario.name,
                 scenario_description=scenario.scenario.description)
    return out.written


# ----------------------------------------------------------------------------- verbs

_STAGES = {
    "simulate": ("model", "simulate"),
    "identify": ("model", "simulate", "identify"),
    "sensors": ("model", "simulate", "identify", "sensors"),
    "estimate": ("model", "simulate", "identify", "sensors", "estimate"),
    "plan": ("model", "simulate", "identify", "sensors", "estimate", "plan"),
    "closed-loop": ("model", "closed_loop"),
    "severity": ("model", "severity"),
    "run": ("model", "simulate", "identify", "sensors", "estimate", "plan", "closed_loop",
            "severity"),
}


def _run_stages(study: _Study, stages: Sequence[str]) -> None:
    sc = study.scenario
    for stage in stages:
        if stage == "model":
            study.build_model()
        elif stage == "simulate":
            study.simulate()
        elif stage == "identify":
            study.design_estimator(choose_sensors="sensors" in stages)
        elif stage == "estimate":
            study.estimate()
        elif stage == "plan":
            study.plan()
        elif stage == "closed_loop":
            sensors = study.design.sensors if study.design is not None else None
            study.run_closed_loop(sensors)
        elif stage == "severity" and (sc.severity.enabled or stages == _STAGES["severity"]):
            study.severity()


def _count_stages(scenario, stages: Sequence[str]) -> int:
    n = 0
    for stage in stages:
        if stage == "sensors":
            chosen = scenario.estimation.sensors is not None or \
                scenario.estimation.sensor_positions is not None
            n += 0 if chosen else 1
        elif stage == "closed_loop":
            n += scenario.robot.closed_loop > 0
        elif stage == "severity":
            n += scenario.severity.enabled or stages == _STAGES["severity"]
        else:
            n += 1
    return n


def run_scenario(scenario, out: Path | None = None, echo=print, *, stages=None,
                 force: bool = False, quiet: bool = True) -> dict:
    """Run the chain on ``scenario`` and return its headline numbers.

    Stages: model -> simulation -> identification (DMD, alpha chosen on held-out data) ->
    sensor placement (or the scenario's sensors) -> Kalman estimation on held-out data, against
    the obvious layouts -> antinodes and minimum-time move -> closed loop -> severity (when the
    scenario enables it).

    Parameters
    ----------
    scenario : Scenario
        The study (see :func:`~powerline_control.config.load_scenario`).
    out : Path or None
        Folder for ``report.html`` (self-contained), ``summary.json``, the DMD model and the
        scenario; None writes nothing. It must be new, empty, or hold only files this command
        wrote (``force`` overrides).
    echo : callable
        Where the printed summary goes (``print`` by default); None prints nothing.
    stages : sequence of str or None
        The stages to run (default: all of ``run``).
    force : bool
        Write into a folder that holds other files.
    quiet : bool
        No progress bar (the default when called from Python).

    Returns
    -------
    dict
        The headline numbers, as printed.

    Examples
    --------
    >>> from powerline_control.config import load_scenario
    >>> small = load_scenario(text="[model]\\nn_elements = 20\\n[simulation]\\nduration = 2.0\\n"
    ...                            "[robot]\\nclosed_loop = 0")
    >>> run_scenario(small, echo=None)["n_nodes"]
    21
    """
    console = _Console(quiet=quiet)
    if echo is not None and echo is not print:
        console.out = echo
    elif echo is None:
        console.out = lambda line="": None
    output = _Output(out, force=force)
    stages = tuple(stages or _STAGES["run"])
    report = _Report(console)
    with _Progress(console, _count_stages(scenario, stages) + (out is not None)) as progress:
        study = _Study(scenario, report, progress)
        _run_stages(study, stages)
        if out is not None:
            progress.stage("drawing the figures and writing the report")
            _write_outputs(output, study, report)
    return report.numbers


def _load(console, name_or_path):
    from .scenario import load_scenario

    return load_scenario(name_or_path)


#: Environment variable: BLAS threads of the verbs (default 1; 0 leaves the libraries' own
#: choice, for benchmarks comparing the two).
BLAS_THREADS_VARIABLE = "POWERLINE_CONTROL_BLAS_THREADS"


@contextlib.contextmanager
def _numerics():
    """Import the numerical stack, then limit BLAS to one thread for the verb's scope."""
    import numpy  # noqa: F401  (load BLAS before limiting it)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    from . import closed_loop  # noqa: F401  (loads control, cvxpy, casadi: all BLAS users)

    raw = os.environ.get(BLAS_THREADS_VARIABLE, "1").strip()
    if not raw.isdigit():
        raise InputError(f"The environment variable {BLAS_THREADS_VARIABLE} must be a whole "
                         f"number of threads (0: no limit). Got {raw!r}.")
    threads = int(raw)
    if threads == 0:
        yield
        return
    with threadpool_limits(limits=threads):
        yield


def _browser() -> str | None:
    import shutil

    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


def _print_pdf(browser: str, html: Path, pdf: Path) -> None:
    """Print the report with headless Chromium (no network: the page fetches nothing)."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as profile:
        result = subprocess.run(
            [browser, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={profile}", "--no-pdf-header-footer",
             f"--print-to-pdf={pdf}", html.resolve().as_uri()],
            capture_output=True, text=True, timeout=300)
    if result.returncode != 0 or not pdf.is_file():
        raise InputError(f"Chromium could not print {html} to PDF (exit {result.returncode}).")


def _verb_stages(args, console: _Console, *, full: bool = True) -> int:
    scenario = _load(console, args.scenario)
    browser = None
    if getattr(args, "pdf", False):
        if not getattr(args, "out", None):
            raise InputError("--pdf needs --out (the folder the report is written to).")
        browser = _browser()
        if browser is None:
            raise InputError("--pdf needs Chromium (chromium, chromium-browser or "
                             "google-chrome on the PATH); report.html alone needs nothing.")
    output = _Output(args.out, force=args.force) if getattr(args, "out", None) else None
    stages = _STAGES[args.command]
    report = _Report(console)
    start = time.perf_counter()
    n_stages = _count_stages(scenario, stages) + (output is not None)
    with _numerics(), _Progress(console, n_stages) as progress:
        study = _Study(scenario, report, progress)
        _run_stages(study, stages)
        written = []
        if output is not None:
            progress.stage("drawing the figures and writing the report")
            written = _write_outputs(output, study, report, full=full)
            if browser is not None:
                _print_pdf(browser, output.path / "report.html", output.file("report.pdf"))
                written = output.written
    report.numbers["elapsed_s"] = round(time.perf_counter() - start, 2)
    _finish(console, report.numbers, output, written)
    return EXIT_OK


def _finish(console, numbers, output, written):
    if console.as_json:
        if output is not None:
            numbers = {**numbers, "out": str(output.path), "files": sorted(set(written))}
        print(json.dumps(numbers, indent=2, default=float))
        return
    if output is not None:
        console.out(f"Results written to {output.path}/ ({', '.join(sorted(set(written)))})")
    if console.quiet:
        headline = {k: numbers[k] for k in ("vibration_reduction", "error_unmeasured")
                    if k in numbers}
        print("Done." + "".join(f" {k} = {v:.3g}" for k, v in headline.items()))
    else:
        console.out(f"Done in {numbers.get('elapsed_s', 0):.1f} s.")


def _verb_demo(args, console: _Console) -> int:
    args.scenario = "paper-lab-20"
    args.command = "run"
    args.out = args.out or Path("powerline-demo")
    console.note(f"Demo: the paper's lab span end to end; report: {args.out}/report.html")
    return _verb_stages(args, console)


def _verb_report(args, console: _Console) -> int:
    args.command = "run"
    return _verb_stages(args, console, full=False)


def _verb_scenario(args, console: _Console) -> int:
    from .scenario import load_scenario, scenario_to_toml, shipped_scenarios

    if args.name is None:
        shipped = shipped_scenarios()
        if console.as_json:
            print(json.dumps(shipped, indent=2))
            return EXIT_OK
        print("Shipped scenarios (run one with: powerline-control run NAME; print it as a "
              "template with: powerline-control scenario NAME):")
        for name, description in shipped.items():
            print(f"  {name:<16} {description}")
        return EXIT_OK
    scenario = load_scenario(args.name)
    if console.as_json:
        print(json.dumps(dataclasses.asdict(scenario), indent=2))
    else:
        print(scenario_to_toml(scenario), end="")
    return EXIT_OK


def _parse_value(text: str):
    import tomllib

    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _study_point(scenario_text: str, **overrides) -> dict:
    """One point of a ``study``: the scenario with ``overrides`` (dotted keys), estimation only."""
    from .scenario import load_scenario

    # Grid keys are identifiers (section__key) so that any executor can pass them on.
    overrides = {key.replace("__", "."): value for key, value in overrides.items()}
    scenario = load_scenario(text=_override_toml(scenario_text, overrides), source="study")
    console = _Console(quiet=True)
    report = _Report(console)
    console.out = lambda line="": None
    with _numerics(), _Progress(console, 1) as progress:
        study = _Study(scenario, report, progress)
        _run_stages(study, _STAGES["estimate"])
    numbers = report.numbers
    return {"error_unmeasured": numbers["error_unmeasured"],
            "spectral_radius": numbers["spectral_radius"],
            "sensors": " ".join(str(i) for i in numbers.get("sensors", []))}


def _override_toml(text: str, overrides: dict) -> str:
    from .scenario import override_scenario_text

    return override_scenario_text(text, overrides)


def _verb_study(args, console: _Console) -> int:
    from .scenario import load_scenario, read_scenario_text

    text, source = read_scenario_text(args.scenario) if args.scenario else ("", "<default>")
    axes = {}
    for item in args.vary or ():
        key, sep, values = item.partition("=")
        if not sep or "." not in key or not values:
            raise InputError(f"--vary {item!r} must look like SECTION.KEY=V1,V2 (e.g. "
                             "estimation.n_sensors=2,3,4).")
        axes[key.strip()] = [_parse_value(v.strip()) for v in values.split(",")]
    if not axes:
        raise InputError("study needs at least one --vary SECTION.KEY=V1,V2 option.")
    from .studies import parameter_grid, run_study

    for point in parameter_grid(**axes):  # every variant is validated before anything runs
        load_scenario(text=_override_toml(text, point), source=f"{source} with {point}")
    grid = parameter_grid(**{key.replace(".", "__"): values for key, values in axes.items()})
    output = _Output(args.out, force=args.force) if args.out else None
    func = functools.partial(_study_point, text)
    console.note(f"Study: {len(grid)} variants of {source}")
    with _numerics():
        progress = not console.quiet
        if args.workers > 1:
            from concurrent.futures import ProcessPoolExecutor

            with ProcessPoolExecutor(args.workers) as pool:
                result = run_study(func, grid, pool, progress=progress,
                                   description="scenario variants")
        else:
            result = run_study(func, grid, progress=progress, description="scenario variants")
    rows = [{key.replace("__", "."): value for key, value in row.items()}
            for row in result.rows()]
    written = []
    if output is not None:
        import csv

        with output.file("study.csv").open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        output.file("study.json").write_text(json.dumps(rows, indent=2, default=float))
        written = output.written
    if console.as_json:
        print(json.dumps(rows, indent=2, default=float))
    else:
        keys = list(rows[0])
        console.out("  ".join(f"{k:>22}" for k in keys))
        for row in rows:
            console.out("  ".join(f"{row[k]:>22.4g}" if isinstance(row[k], float)
                                  else f"{row[k]!s:>22}" for k in keys))
        if written:
            console.out(f"Results written to {output.path}/ ({', '.join(written)})")
    return EXIT_OK


# ----------------------------------------------------------------------------- parser

class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the verb list's layout; the epilog paragraphs are wrapped by :func:`_epilog`."""


def _epilog(*paragraphs: str) -> str:
    import shutil
    import textwrap

    width = min(shutil.get_terminal_size((100, 24)).columns, 100) - 2
    return "\n".join(textwrap.fill(p, width=width) for p in paragraphs)


def _common(parser: argparse.ArgumentParser, suppress: bool) -> None:
    default = argparse.SUPPRESS if suppress else False
    group = parser.add_argument_group("output options")
    group.add_argument("--json", action="store_true", default=default,
                       help="print the results as one JSON object on stdout")
    group.add_argument("-q", "--quiet", action="store_true", default=default,
                       help="no progress or summary, only errors and the final line")
    group.add_argument("--debug", action="store_true", default=default,
                       help="show full tracebacks and every library warning")


def _build_parser() -> argparse.ArgumentParser:
    from . import __version__

    doc = __doc__.split("\n\n")
    parser = argparse.ArgumentParser(
        prog="powerline-control", formatter_class=_Formatter,
        description="Vibration of overhead power lines: model, simulate, identify (DMD), "
        "place sensors, estimate (Kalman), plan and run a mobile damping robot.",
        epilog=_epilog(_UNITS, _EXIT_CODES, "Scenario keys: docs/scenarios.md, or "
                       "'powerline-control scenario NAME' for a commented template."))
    parser.add_argument("--version", action="version", version=f"powerline-control {__version__}")
    _common(parser, suppress=False)
    verbs = parser.add_subparsers(dest="command", metavar="VERB", title="verbs",
                                  description=doc[1].split("::")[-1] if len(doc) > 1 else None)
    verbs.required = True

    def verb(name, help_text, *, scenario=True, out=True, out_required=False):
        sub = verbs.add_parser(name, help=help_text, description=help_text[0].upper()
                               + help_text[1:] + ".", epilog=_epilog(_UNITS, _EXIT_CODES),
                               formatter_class=_Formatter)
        if scenario:
            sub.add_argument("scenario", nargs="?", default=None,
                             help="a scenario TOML file, or the name of a shipped scenario "
                             "(list them with 'powerline-control scenario'); default: the "
                             "built-in scenario (the paper's lab span, 100 elements)")
        if out:
            sub.add_argument("--out", type=Path, default=None, required=out_required, metavar="DIR",
                             help="folder for the results (created if missing; must be empty "
                             "or hold only this command's files)")
            sub.add_argument("--force", action="store_true",
                             help="write into an --out folder that holds other files")
            sub.add_argument("--pdf", action="store_true",
                             help="also print report.html to report.pdf (needs Chromium)")
        _common(sub, suppress=True)
        return sub

    demo = verb("demo", "the paper's lab span end to end, report in ./powerline-demo/",
                scenario=False)
    demo.set_defaults(out=None)
    verb("run", "the whole chain on a scenario: model, data, DMD, sensors, Kalman "
         "estimate, antinodes, plan, closed loop")
    verb("simulate", "build the model and simulate the sensor data (displacements in mm)")
    verb("identify", "simulate, then identify a DMD model (eigenvalues, spectral radius)")
    verb("sensors", "identify, then choose the sensor positions (m) against baselines")
    verb("estimate", "choose sensors, then estimate the whole span with a Kalman filter")
    verb("plan", "estimate, then locate the antinodes (m) and plan the robot's move (s)")
    verb("closed-loop", "the robot driven to the antinode in closed loop, against parked")
    verb("severity", "aeolian severity: antinode amplitude (mm) and clamp strain against wind "
         "speed (m/s)")
    study = verb("study", "run variants of a scenario over a grid of keys; a table of results")
    study.add_argument("--vary", action="append", metavar="SECTION.KEY=V1,V2",
                       help="a scenario key and its values (repeat for a grid)")
    study.add_argument("--workers", type=int, default=1,
                       help="processes to run the variants on (default 1: serial)")
    verb("report", "run a scenario and write only its self-contained report.html",
         out_required=True)
    scen = verb("scenario", "list the shipped scenarios, or print one (or a file) as a "
                "commented TOML template", scenario=False, out=False)
    scen.add_argument("name", nargs="?", default=None,
                      help="a shipped scenario name or a TOML file")
    return parser


_VERBS = {"demo": _verb_demo, "report": _verb_report, "scenario": _verb_scenario,
          "study": _verb_study}


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"powerline-control: warning: {category.__name__}: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``powerline-control`` command; returns the exit status.

    Parameters
    ----------
    argv : sequence of str or None
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 1 on numerical trouble, 2 on bad input or usage, 130 on Ctrl-C.

    Examples
    --------
    >>> main(["scenario"])  # doctest: +ELLIPSIS
    Shipped scenarios ...
    0
    """
    parser = _build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help / --version (0) or a usage error (2)
        return int(exc.code or 0)
    for name in ("json", "quiet", "debug"):
        if not hasattr(args, name):
            setattr(args, name, False)
    console = _Console(quiet=args.quiet, as_json=args.json, debug=args.debug)
    handler = _VERBS.get(args.command, _verb_stages)
    try:
        with warnings.catch_warnings():
            if not args.debug:
                warnings.showwarning = _show_warning
                warnings.simplefilter("once")
            return handler(args, console)
    except KeyboardInterrupt:
        print("powerline-control: interrupted (Ctrl-C); stopped.", file=sys.stderr)
        return EXIT_INTERRUPTED
    except PowerlineControlError as exc:
        if args.debug:
            import traceback

            traceback.print_exc()
        message = " ".join(str(exc).split())
        code = EXIT_USAGE if isinstance(exc, InputError | ValueError) else EXIT_NUMERICAL
        kind = "error" if code == EXIT_USAGE else "numerical trouble"
        print(f"powerline-control: {kind}: {message}", file=sys.stderr)
        if args.json:
            print(json.dumps({"error": message, "exit_code": code}))
        return code
    except BrokenPipeError:  # e.g. piped into head
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115
        return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
